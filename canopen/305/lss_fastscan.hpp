// LSS fastscan (CiA 305 §8.4.4), the master's side: reads the LSS address of one slave without a
// node-ID through an LssMaster, step by step, and leaves that slave in LSS configuration mode
// (the last step selects it). Shared by `oegw scan` (subdevices/bus_scan.hpp, which switches the
// node back to waiting) and `oegw ctl`'s `_lss_fastscan` (subdevices/network_manager.hpp, which
// leaves it selected for `lss_set_node`, as CANopenNode's and lely's gateways do).
//
// The steps: a reset step (BitChecked 80h) that every slave without node-ID answers; then, for
// each part of the address (vendor, product, revision, serial), bits 31..1 not known in advance (Known) are decided by
// asking whether any node has the bit 0 (silence: it is 1), and bit 0 is confirmed with LSSNext set to the next part,
// which moves only the nodes that match the whole part on (a silent confirmation is tried once more with bit 0 set). At
// most 1 + 4 × 32 + 4 steps, each lasting the step time-out.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "canopen/305/lss.hpp"
#include "canopen/305/lss_master.hpp"
#include "canopen/305/lss_scan_run.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

// Bits of the address the caller already knows (lely's `_lss_fastscan` with values and masks):
// a bit set in `mask` is taken from `value` without asking. Fastscan compares the bits
// BitChecked..31 of a part, so a known bit is simply not asked: the steps after it compare it
// (a node that differs falls silent), and bit 0's confirmation checks the whole part. A known
// bit 0 is confirmed once, not tried the other way.
struct LssFastscanKnown {
  lss::Address value{};
  std::array<std::uint32_t, 4> mask{};  // vendor, product, revision, serial
};

// NoAnswer: nobody answered the reset step (no slave without node-ID, or no fastscan support).
class LssFastscan : public LssScanRun {
 public:
  // Steps that fastscan() runs at most (for a caller's overall wait).
  static constexpr unsigned kMaxSteps = 1 + 4 * 32 + 4;

  explicit LssFastscan(LssMaster& master) : LssScanRun(master) {}

  using Known = LssFastscanKnown;
  // Starts a scan; `step_timeout` empty: the LssMaster's own time-out. A scan still running is
  // cancelled first. `done` is called once.
  void start(TimePoint now, Callback done, std::optional<Duration> step_timeout = std::nullopt, Known known = {});

 private:
  void step(TimePoint now);

  std::optional<Duration> timeout_;
  std::uint8_t sub_ = 0;  // the part of the address (0..3)
  int bit_ = 31;          // the next bit to decide
  bool retry_ = false;
  std::uint32_t value_[4] = {};
  Known known_{};
};

}  // namespace oegw::canopen
