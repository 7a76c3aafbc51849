// The daemon's sub-commands: oegw check, oegw eds, oegw run.
#pragma once

#include <string>

namespace oegw::gateway {

// Validates FILE and prints the upstream layout; 0 if valid, 1 with every error otherwise.
int run_check(const std::string& file);
// Writes the EDS of the upstream device FILE configures to `out` ("-" = standard output).
int run_eds(const std::string& file, const std::string& out);
// The daemon: upstream and downstream on the SocketCAN interfaces FILE names, until SIGTERM.
int run_gateway(const std::string& file);

}  // namespace oegw::gateway
