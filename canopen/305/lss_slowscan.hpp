// LSS slowscan, the master's side (lely's `_lss_slowscan`, CiA 309-3 gateways): finds one slave
// whose LSS address lies in a range — vendor-ID and product code exact, revision number and
// serial number within low..high — by a binary search with "identify remote slave" (CiA 305
// §8.4.3.6, cs 46h..4Bh, every slave in the range answers 4Fh), then selects it with "switch state
// selective" (§8.4.2.2, 40h..43h, answered 44h), leaving it in LSS configuration mode.
//
// The steps: the whole range first (silence: nobody there); then the revision range is halved
// until one value is left (the lower half answered: keep it, else the upper half), then the
// serial range the same way with that revision; at most 1 + 32 + 32 identify steps and one
// switch. Each identify step lasts the whole step time-out (LssMaster::identify_remote_slave's
// whole_window), so a second slave's late answer is not taken for the next step's. Slaves do not
// need to be without node-ID: slowscan finds any slave in the range (as lely's does).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "canopen/305/lss.hpp"
#include "canopen/305/lss_master.hpp"
#include "canopen/305/lss_scan_run.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

// NoAnswer: nobody in the range answered; Lost: the switch to the address found was not
// answered (the slave left the bus).
class LssSlowscan : public LssScanRun {
 public:
  static constexpr unsigned kMaxSteps = 1 + 32 + 32 + 1;

  explicit LssSlowscan(LssMaster& master) : LssScanRun(master) {}

  // Starts a scan of `range`; `step_timeout` empty: the LssMaster's own time-out. A scan still
  // running is cancelled first. `done` is called once.
  void start(const lss::AddressRange& range, TimePoint now, Callback done,
             std::optional<Duration> step_timeout = std::nullopt);

 private:
  void step(TimePoint now);

  Duration timeout_{};
  lss::AddressRange range_{};
};

}  // namespace oegw::canopen
