// `oegw ctl`: CiA 309-3 ASCII commands into the running gateway (cli/ctl_command.hpp).
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::cli {

void register_ctl(CLI::App& app);

}  // namespace oegw::cli
