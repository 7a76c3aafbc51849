// `oegw master -i IF SPEC...`: the downstream network manager alone (programs/bench_programs.hpp).
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::programs {

void register_master(CLI::App& app);

}  // namespace oegw::programs
