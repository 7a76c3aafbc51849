// `oegw core-demo`: the protocol core's demo (programs/core_demo.hpp).
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::programs {

void register_core_demo(CLI::App& app);

}  // namespace oegw::programs
