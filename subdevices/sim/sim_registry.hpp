// make_simulator: a family name (as in configuration files and driver names) -> its simulator.
#pragma once

#include <memory>
#include <string>

#include "subdevices/device_spec.hpp"
#include "subdevices/sim/simulated_device.hpp"

namespace oegw::subdevices::sim {

// Options understood: cia401 "eds" (required); mcb402 "wiring" (the bit of 6000h:03 each push
// button BP1..BP7 is wired to, "1/2/3/4/5/7/6"; default the document's table as printed); every
// family "heartbeat_ms" (1017h default) and "store" (parameter file). nullptr with `error` for an unknown family or option.
std::unique_ptr<SimulatedDevice> make_simulator(const DeviceSpec& spec, FrameSink sink, std::string& error);

}  // namespace oegw::subdevices::sim
