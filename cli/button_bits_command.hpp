// `oegw signals mcb402 --find-button-bits -i IF --node N`: reads an MCB-402's button wiring off
// the board on a CAN interface (subdevices/mcb402_commissioning.hpp: the prompts, one button after
// the other) and prints the mapping file's `button_bits` line. Directly on the bus: with the
// gateway running the board's TPDO1 is on the bus already; a board alone is NMT-started.
#pragma once

#include <string>

namespace oegw::cli {

struct FindButtonBitsOptions {
  std::string interface;  // the sub-devices' bus (e.g. can1)
  int node = 0x03;        // the board's node-ID (its CN3 jumpers)
  double timeout_s = 60;  // per button
};

// 0: found (the `button_bits:` line on standard output, the prompts before it); 1: no press seen
// in time, or the loop was interrupted; 2: the interface cannot be opened.
int run_find_button_bits(const FindButtonBitsOptions& options);

}  // namespace oegw::cli
