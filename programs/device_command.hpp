// `oegw device -i IF`: the protocol core's demo device on SocketCAN (programs/core_demo.hpp).
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::programs {

void register_device(CLI::App& app);

}  // namespace oegw::programs
