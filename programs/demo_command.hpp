// `oegw demo` (the default with no command): the embedded demo (programs/gateway_demo.hpp).
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::programs {

void register_demo(CLI::App& app);

}  // namespace oegw::programs
