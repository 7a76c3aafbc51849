// What `oegw run` tells systemd (sd_notify(3), the unit's Type=notify and WatchdogSec=):
//   READY=1     once both buses are open and the upstream device is pre-operational or beyond
//   STATUS=...  the upstream NMT state, the sub-devices' states and what runs degraded (a
//               publishing transport down), each time that text changes
//   WATCHDOG=1  from the event loop, every half of WATCHDOG_USEC (sd_watchdog_enabled(3)), so a
//               loop that is stuck stops pinging and systemd restarts the daemon
//   RELOADING=1 at SIGHUP, with MONOTONIC_USEC= (systemd 253's Type=notify-reload pairs reload
//               cycles by it; Debian 12's systemd 252 ignores it), then READY=1 once the reload is
//               over, applied or refused (docs/guides/install.md#reloading-the-mapping-file)
//   STOPPING=1  at SIGTERM/SIGINT
// Without NOTIFY_SOCKET (not started by systemd) nothing is sent and nothing fails.
//
// ServiceNotify decides what to send and when, on the times it is given; the messages go to a
// Notifier, which is systemd's socket in the daemon and a recorder in the tests.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "canopen/types.hpp"
#include "subdevices/network_manager.hpp"

namespace oegw::gateway {

class Notifier {
 public:
  virtual ~Notifier() = default;
  // One sd_notify state line: "READY=1", "STATUS=...", "WATCHDOG=1", "STOPPING=1".
  virtual void notify(const std::string& state) = 0;
};

// sd_notify(0, state): a no-op when NOTIFY_SOCKET is unset.
class SystemdNotifier final : public Notifier {
 public:
  void notify(const std::string& state) override;
};

// The watchdog time-out systemd set for this process (WATCHDOG_USEC, checked against
// WATCHDOG_PID by sd_watchdog_enabled(3)); nullopt without one.
[[nodiscard]] std::optional<canopen::Duration> systemd_watchdog_timeout();

// What the STATUS= line reports.
struct ServiceState {
  canopen::NmtState upstream = canopen::NmtState::Initialisation;
  std::uint8_t node_id = 0;
  std::vector<std::pair<std::string, subdevices::NodeState>> subdevices;  // in the mapping file's order
  std::vector<std::string> degraded;  // a part that runs without what it needs: "lcm down: <reason>"
};
// "upstream operational, node 20h; 3/3 sub-devices operational", or with the others named:
// "upstream pre-operational, node 20h; 1/3 sub-devices operational; pedal missing, cluster configuring",
// then each degraded part: "...; lcm down: <reason>".
[[nodiscard]] std::string status_line(const ServiceState& s);
class Gateway;
// The gateway's state now: its upstream device's, each sub-device's.
[[nodiscard]] ServiceState service_state(Gateway& gw);

class ServiceNotify {
 public:
  // `watchdog`: the time-out systemd enforces; WATCHDOG=1 is sent every half of it.
  ServiceNotify(Notifier& out, std::optional<canopen::Duration> watchdog);

  // How often update() is to be called: often enough for the watchdog, and for the STATUS line
  // to follow the sub-devices within a second.
  [[nodiscard]] canopen::Duration poll_period() const;
  // READY=1 the first time the upstream device is past initialisation; STATUS= when the text
  // differs from the last one sent; WATCHDOG=1 when half the time-out has passed since the last.
  void update(canopen::TimePoint now, const ServiceState& state);
  // RELOADING=1 and MONOTONIC_USEC=`monotonic` (CLOCK_MONOTONIC, the event loop's clock).
  void reloading(canopen::TimePoint monotonic);
  // READY=1 again; `note` (empty: none) ends every STATUS= line from now on, e.g. "last reload
  // refused: 2 errors (journal)", and is sent at once.
  void reloaded(const std::string& note, const ServiceState& state);
  // STOPPING=1, once.
  void stopping();

  [[nodiscard]] bool ready() const { return ready_; }

 private:
  Notifier& out_;
  std::optional<canopen::Duration> ping_every_;  // half the watchdog time-out
  std::optional<canopen::TimePoint> next_ping_;
  bool ready_ = false;
  bool stopping_ = false;
  // STATUS= when its text (with the note) differs from the last one sent.
  void send_status(const ServiceState& state);
  std::string status_;
  std::string note_;  // the last reload's, appended to STATUS=
};

}  // namespace oegw::gateway
