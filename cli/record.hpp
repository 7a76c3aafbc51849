// `oegw record keep`: keeps the running gateway's recording window (cli/replay_command.hpp).
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::cli {

void register_record(CLI::App& app);

}  // namespace oegw::cli
