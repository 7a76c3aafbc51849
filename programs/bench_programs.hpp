// Bench programs on SocketCAN: `oegw-sim` (simulated sub-devices) and `oegw master` (the
// downstream network manager with drivers, printing what it sees). They let the gateway's
// downstream side be tried on vcan or a real bus without hardware.
#pragma once

#include <string>
#include <vector>

namespace oegw::programs {

struct SimOptions {
  std::string interface;
  std::vector<std::string> devices;  // "family:node[:key=value,...]"
  bool motion = false;               // sweep axes and press buttons
  bool commands = false;             // read commands from standard input
};
int run_sim(const SimOptions& options);

struct MasterOptions {
  std::string interface;
  std::vector<std::string> devices;
  unsigned heartbeat_ms = 100;
  double until_operational = 0;  // > 0: exit 0 once every node is operational, 1 after this many seconds
  bool signals = true;           // print signal changes
};
int run_master(const MasterOptions& options);

}  // namespace oegw::programs
