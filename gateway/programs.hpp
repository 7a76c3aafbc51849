// The daemon's sub-commands: oegw check, oegw eds, oegw run.
#pragma once

#include <string>

#include "cli/exit_codes.hpp"

namespace oegw::gateway {

// The exit codes of every oegw command: one table, cli/exit_codes.hpp (the daemon exits with them).
namespace exit_code = cli::exit_code;

// Validates FILE and prints the upstream layout; 0 if valid, 1 with every error otherwise.
// What this machine lacks for it (mapping/deployment.hpp machine_errors, publish.dds.security's
// files) is printed as warnings in a section of its own, or, `here` (`oegw check --here`: checked
// on the machine it is for), refused as `oegw run` refuses it.
// `quiet` (`oegw check --quiet`): of a valid file only "FILE: valid" and the warnings, for scripts
// and commissioning logs; errors and exit codes as without it.
int run_check(const std::string& file, bool quiet = false, bool here = false);
// Writes the EDS of the upstream device FILE configures to `out` ("-" = standard output).
int run_eds(const std::string& file, const std::string& out);
// The daemon: upstream and downstream on the SocketCAN interfaces FILE names, until SIGTERM.
// FILE loaded and checked, the bit rates set, both interfaces opened, then serve_gateway()
// (gateway/serve_gateway.hpp).
int run_gateway(const std::string& file);

}  // namespace oegw::gateway
