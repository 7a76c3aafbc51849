// make_simulator: a family name (as in configuration files and driver names) -> its simulator.
#pragma once

#include <memory>
#include <string>

#include "subdevices/device_spec.hpp"
#include "subdevices/sim/simulated_device.hpp"

namespace oegw::subdevices::sim {

// Options understood: every family "heartbeat_ms" (1017h default) and "store" (parameter file);
// cia401 "eds" (required); the corners of each family where its document permits several
// readings (docs/design/device-documents.md#corners-every-reading-a-document-permits): mcb402
// "wiring" (the bit of 6000h:03 each push button BP1..BP7 is wired to, "1/2/3/4/5/7/6"; default the
// table's right-end reading), "clear_after_break" (0000h | none), "power_on_1001h" (11h | 00h);
// elobau-mfg "tpdo" (change | timer), "saved" (yes | no), "buttons" / "buttons_9_16"
// (2100h:01h/02h, default 63 / 0); novotechnik-406 "error_register_size" (1 | 2), "emcy_behaviour"
// (2104h 0..3), "has_6020h" (yes | no), "work_area_emcy" (enum | bits), "load" (defaults | stored).
// nullptr with `error` for an unknown family, option or value.
std::unique_ptr<SimulatedDevice> make_simulator(const DeviceSpec& spec, FrameSink sink, std::string& error);

}  // namespace oegw::subdevices::sim
