// SDO pacing: the requests of several SDO clients sharing one bus (a master's clients toward its
// nodes) started no closer together than a gap, so their traffic takes at most a share of the
// bus however fast the servers answer.
//
// Why: SDO COB-IDs (580h/600h + node) win arbitration over every heartbeat and boot-up (700h +
// node) (CiA 301 §7.3.5: the lower identifier wins). A master that starts each next request the
// moment the answer arrives keeps the bus busy with SDO for as long as it configures, and a
// server answering within microseconds makes that 100 % of the bus: the other nodes' heartbeats
// wait behind it, and a heartbeat consumer (CiA 301 §7.2.8.3.2.2) takes them for lost. Pacing
// leaves the rest of the bus to everything else; the gap is chosen from the bit rate.
//
// Sans I/O: try_start(now) says whether a request may start now (and takes the slot), next_free()
// when one may.
#pragma once

#include <cstdint>

#include "canopen/types.hpp"

namespace oegw::canopen {

class StateWriter;  // canopen/state.hpp
class StateReader;

class SdoPacer {
 public:
  // gap 0: no pacing (every request may start at once).
  explicit SdoPacer(Duration gap = Duration{0}) : gap_(gap) {}

  // The gap that keeps SDO request/answer pairs of 8-byte frames (the longest SDO frame, at its
  // worst-case bit stuffing: canopen/frame_bits.hpp) within `share` (0..1] of a bus at
  // `bit_rate` bit/s. 0 for share 0 or bit rate 0 (no pacing).
  [[nodiscard]] static Duration gap_for(std::uint32_t bit_rate, double share);

  [[nodiscard]] Duration gap() const { return gap_; }
  [[nodiscard]] bool paced() const { return gap_ > Duration{0}; }
  // True if a request may start at `now`; then the next may start `gap` later. `waited`: this
  // request was refused before (its start counts as delayed).
  bool try_start(TimePoint now, bool waited = false);
  // The earliest time a request may start.
  [[nodiscard]] TimePoint next_free() const { return next_free_; }
  // Requests that started after waiting for the gap (try_start's `waited`), each counted once.
  [[nodiscard]] std::uint64_t delayed_starts() const { return delayed_starts_; }

  // Run-time state (canopen/state.hpp): when the next request may start, the count. The gap is
  // configuration. Throws StateError.
  void export_state(StateWriter& w) const;
  void import_state(const StateReader& r);

 private:
  Duration gap_;
  TimePoint next_free_{};
  std::uint64_t delayed_starts_ = 0;
};

}  // namespace oegw::canopen
