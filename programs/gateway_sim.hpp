// `oegw sim FILE`: the user's own mapping file, live, with no hardware. Every sub-device the file
// names is simulated (subdevices/sim: the families' simulators, a cia401 node from its EDS) on
// the in-process buses, with the built-in host controller upstream, the live table, DDS/LCM
// publishing as the file configures it and the control socket (`oegw status`, `oegw ctl`) on a
// private path. A scripted operator moves every input; a fault script (--script) or commands on
// standard input pull cables, reboot devices, raise errors and check what the gateway shows.
// --vcan UP,DOWN puts both buses on SocketCAN interfaces as well, for candump and other hosts.
// docs/guides/simulate.md is the guide; the script's words are listed there.
#pragma once

#include <string>

namespace oegw::programs {

class SimStory;

struct GatewaySimOptions {
  std::string file;     // the mapping file
  double seconds = 0;   // how long; 0: until SIGINT/SIGTERM (--fast: until the script's end + 1 s)
  bool fast = false;    // the simulated clock: deterministic, as fast as the machine goes
  bool motion = true;   // the operator moves every input from the start (script: `motion off`)
  bool publish = true;  // publish as the file's publish section says
  bool frames = false;  // print every frame of both buses in candump's log format
  std::string script;   // a file of "SECONDS COMMAND" lines; "" = none
  std::string vcan;     // "UP,DOWN": both buses also on these SocketCAN interfaces; "" = none
  // A folder made by scripts/make-dds-security.sh: DDS Security for the sim's participant with the
  // set's gateway identity (docs/guides/secure-dds.md); a set the library refuses stops the run
  // (exit 2: it would publish in the clear). "" = as the file says.
  std::string dds_security;
};

// Exit status (gateway/programs.hpp exit_code): 0 done, every `expect` met; 1 the mapping file
// or the script refused (every error printed, nothing started), or an `expect` or a command
// failed; 2 cannot start (a --vcan interface missing or not CAN, a --dds-security set refused).
// With a story (sim_story.hpp, `oegw demo`): its banner, steps, checks and summary, its exit status.
int run_gateway_sim(const GatewaySimOptions& options, SimStory* story = nullptr);

}  // namespace oegw::programs
