// `oegw status`: what the running gateway sees, over its control socket (cli/status_command.hpp).
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::cli {

void register_status(CLI::App& app);

}  // namespace oegw::cli
