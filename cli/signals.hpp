// `oegw signals [DRIVER]`: the drivers' signals and options, and an MCB-402's button wiring (cli/signals_command.hpp,
// cli/button_bits_command.hpp).
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::cli {

void register_signals(CLI::App& app);

}  // namespace oegw::cli
