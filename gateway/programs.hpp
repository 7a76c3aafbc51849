// The gateway's own sub-commands: oegw check, oegw eds, oegw run, oegw demo.
#pragma once

#include <string>

namespace oegw::gateway {

// Validates FILE and prints the upstream layout; 0 if valid, 1 with every error otherwise.
int run_check(const std::string& file);
// Writes the EDS of the upstream device FILE configures to `out` ("-" = standard output).
int run_eds(const std::string& file, const std::string& out);
// The daemon: upstream and downstream on the SocketCAN interfaces FILE names, until SIGTERM.
int run_gateway(const std::string& file);

struct GatewayDemoOptions {
  double seconds = 6.0;  // how long the operator moves the joysticks before the faults
  bool frames = false;    // print every frame of both buses
  bool fast = false;      // simulated clock: deterministic, as fast as the machine goes
  bool publish = true;    // publish as demo.yaml says (DDS loopback, LCM ttl=0); commands come back
};
// The embedded demo: gateway + simulated cab devices + a built-in host, on the virtual bus.
int run_gateway_demo(const GatewayDemoOptions& options);

}  // namespace oegw::gateway
