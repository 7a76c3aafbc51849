// `oegw demo`: the gateway with simulated cab devices and a built-in host, on the virtual bus.
#pragma once

#include <string>

namespace oegw::programs {

struct GatewayDemoOptions {
  double seconds = 6.0;  // how long the operator moves the joysticks before the faults
  bool frames = false;   // print every frame of both buses
  bool fast = false;     // simulated clock: deterministic, as fast as the machine goes
  bool publish = true;   // publish as demo.yaml says (DDS loopback, LCM ttl=0); commands come back
  // A folder made by scripts/make-dds-security.sh (--partition oegw-demo): DDS Security for the
  // demo's participant with the set's gateway identity (docs/guides/secure-dds.md); "" = none.
  std::string dds_security;
  std::string vcan;  // "UP,DOWN": both buses also on these SocketCAN interfaces (oegw sim --vcan); "" = none
};
// The embedded demo: gateway + simulated cab devices + a built-in host, on the virtual bus.
int run_gateway_demo(const GatewayDemoOptions& options);

}  // namespace oegw::programs
