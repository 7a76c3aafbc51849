// `oegw check FILE`: validates a mapping file and prints the upstream layout (gateway/programs.hpp run_check).
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::cli {

void register_check(CLI::App& app);

}  // namespace oegw::cli
