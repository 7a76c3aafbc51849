// `oegw eds FILE`: the EDS of the upstream device a mapping file configures (gateway/programs.hpp run_eds).
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::cli {

void register_eds(CLI::App& app);

}  // namespace oegw::cli
