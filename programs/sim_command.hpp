// `oegw sim FILE`: a mapping file on a simulated cab (programs/gateway_sim.hpp).
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::programs {

void register_sim(CLI::App& app);

}  // namespace oegw::programs
