// The steady-state load a mapping file implies on each bus, as `oegw check` prints it
// (docs/reference/mapping-file.md#bus-load-oegw-check; measured: docs/developer/performance.md).
// Steady state means the inputs held still: what is then on the buses is periodic, and fixed by the
// configuration:
//   downstream  SYNC (080h, 0 bytes) every sync_period_ms; each sub-device's heartbeat (700h +
//               node-ID, 1 byte) every heartbeat_ms; each TPDO of each sub-device as its boot
//               configures it (Driver::expected_tpdos: the driver's configuration() and the
//               mapping file's `sdo` writes over the device's defaults) - type 254/255 with an
//               event timer T: one every T (CiA 301 §7.5.2.35), synchronous type n = 1..240:
//               one every n SYNCs;
//   upstream    the gateway's heartbeat every upstream.heartbeat_ms. The CiA 852 default PDOs
//               are all disabled at power-on (§12.1, event timer 0): once the host enables them
//               they go on change only.
// A frame whose bits are known counts with its exact length (canopen/frame_bits.hpp: its stuff
// bits, its CRC, intermission included): SYNC, and a heartbeat at the longest of its three states
// (05h, 7Fh, 04h). A PDO, whose data varies, counts with its worst-case length (the most stuff
// bits its data length allows). So the prediction is an upper bound of the steady state, and
// tight where nothing varies (the upstream bus carries only the gateway's heartbeat). What goes on change (a PDO
// without event timer, a moved input's extra PDOs, the gateway's RPDOs to the devices' outputs, EMCYs, SDO) is listed,
// with the most an inhibit time allows where there is one, but not counted. The publish period paces DDS/LCM, not CAN.
// The host's own frames (its heartbeat, its RPDOs) are not in the file either. Above kBusLoadWarnPercent `oegw check`
// warns: a bus loaded more than that leaves too little room for the change-driven frames, the boot's SDO traffic and an
// error frame's retransmission (CiA's usual design rule keeps a CAN bus well below saturation; 70 % is this project's
// line).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "mapping/config.hpp"

namespace oegw::gateway {

inline constexpr double kBusLoadWarnPercent = 70.0;

// One periodic frame stream.
struct BusStream {
  std::string what;  // "right_grip TPDO 191h, 8 bytes, event timer 100 ms"
  std::uint32_t cob_id = 0;
  std::uint8_t length = 0;  // data bytes
  double per_second = 0;
  std::uint32_t bits = 0;  // its length on the wire: exact, else the worst case
  bool exact = false;      // its frames are known bit for bit (SYNC, heartbeat)
  [[nodiscard]] double bits_per_second() const { return per_second * bits; }
};

struct BusLoad {
  std::uint32_t bit_rate = 0;
  std::vector<BusStream> periodic;
  std::vector<std::string> on_change;  // what goes on change, not counted
  [[nodiscard]] double frames_per_second() const;
  [[nodiscard]] double bits_per_second() const;
  [[nodiscard]] double percent() const;  // of the bit rate
};

struct BusLoadPrediction {
  BusLoad upstream, downstream;
};

// Throws std::runtime_error for a sub-device whose driver cannot be built (load_config has
// already refused such a file).
[[nodiscard]] BusLoadPrediction predict_bus_load(const mapping::Config& config);

// `oegw check`'s lines for one bus: "downstream 250000 bit/s: 12.3 % (123.0 frames/s, ...)",
// then one line per stream and per change-driven frame; `warning: ...` above the threshold.
[[nodiscard]] std::string describe_bus_load(const BusLoad& load, const std::string& name);
// The `warning: ...` line of describe_bus_load() alone ("" at or below the threshold): what
// `oegw check --quiet` prints of the bus load.
[[nodiscard]] std::string bus_load_warning(const BusLoad& load, const std::string& name);

}  // namespace oegw::gateway
