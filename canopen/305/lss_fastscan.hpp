// LSS fastscan (CiA 305 §8.4.4), the master's side: reads the LSS address of one slave without a
// node-ID through an LssMaster, step by step, and leaves that slave in LSS configuration mode
// (the last step selects it). Shared by `oegw scan` (subdevices/bus_scan.hpp, which switches the
// node back to waiting) and `oegw ctl`'s `_lss_fastscan` (subdevices/network_manager.hpp, which
// leaves it selected for `lss_set_node`, as CANopenNode's and lely's gateways do).
//
// The steps: a reset step (BitChecked 80h) that every slave without node-ID answers; then, for
// each part of the address (vendor, product, revision, serial), bits 31..1 are decided by asking
// whether any node has the bit 0 (silence: it is 1), and bit 0 is confirmed with LSSNext set to
// the next part, which moves only the nodes that match the whole part on (a silent confirmation
// is tried once more with bit 0 set). At most 1 + 4 × 32 + 4 steps, each lasting the step
// time-out.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "canopen/305/lss.hpp"
#include "canopen/305/lss_master.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

class LssFastscan {
 public:
  enum class Outcome : std::uint8_t {
    Found,      // `address` read; that slave is in LSS configuration mode
    NoAnswer,   // nobody answered the reset step: no slave without node-ID (or no fastscan support)
    Lost,       // the node answered the reset step but was lost on the way
    Cancelled,  // cancel() was called
  };
  struct Result {
    Outcome outcome = Outcome::NoAnswer;
    std::optional<lss::Address> address;
    std::string note;  // why no address, in words
  };
  using Callback = std::function<void(const Result&)>;

  // Steps that fastscan() runs at most (for a caller's overall wait).
  static constexpr unsigned kMaxSteps = 1 + 4 * 32 + 4;

  explicit LssFastscan(LssMaster& master) : master_(master) {}
  LssFastscan(const LssFastscan&) = delete;
  LssFastscan& operator=(const LssFastscan&) = delete;

  // Starts a scan; `step_timeout` empty: the LssMaster's own time-out. A scan still running is
  // cancelled first. `done` is called once.
  void start(TimePoint now, Callback done, std::optional<Duration> step_timeout = std::nullopt);
  // Ends a running scan: `done` gets Cancelled with `why`; the step on the wire (if any) ends
  // without effect, no further step is sent.
  void cancel(const std::string& why);
  [[nodiscard]] bool running() const { return static_cast<bool>(done_); }

 private:
  void step(TimePoint now);
  void finish(Result r);
  // The LssMaster callback of a step of this scan; ignored once the scan has ended.
  LssMaster::Callback guard(std::function<void(const LssMaster::Result&)> f);

  LssMaster& master_;
  Callback done_;
  std::optional<Duration> timeout_;
  std::uint64_t generation_ = 0;
  std::uint8_t sub_ = 0;  // the part of the address (0..3)
  int bit_ = 31;          // the next bit to decide
  bool retry_ = false;
  std::uint32_t value_[4] = {};
};

}  // namespace oegw::canopen
