// `oegw run FILE`: the daemon (gateway/programs.hpp run_gateway).
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::cli {

void register_run(CLI::App& app);

}  // namespace oegw::cli
