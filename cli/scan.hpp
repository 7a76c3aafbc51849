// `oegw scan`: every node on the downstream bus and a draft mapping file (cli/scan_command.hpp).
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::cli {

void register_scan(CLI::App& app);

}  // namespace oegw::cli
