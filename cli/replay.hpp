// `oegw replay`: the gateway re-run on a recording (cli/replay_command.hpp).
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::cli {

void register_replay(CLI::App& app);

}  // namespace oegw::cli
