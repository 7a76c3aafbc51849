#include "gateway/service_notify.hpp"

#include <systemd/sd-daemon.h>

#include <algorithm>
#include <cstdint>

#include <fmt/format.h>

#include "gateway/gateway.hpp"

namespace oegw::gateway {

using canopen::Duration;
using canopen::TimePoint;

void SystemdNotifier::notify(const std::string& state) {
  // 0 without NOTIFY_SOCKET, negative when the socket refuses: the daemon runs on either way
  // (systemd then times the start out, which is its report).
  (void)sd_notify(0, state.c_str());
}

std::optional<Duration> systemd_watchdog_timeout() {
  std::uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) <= 0 || usec == 0) return std::nullopt;
  return Duration(static_cast<Duration::rep>(usec));
}

std::string status_line(const ServiceState& s) {
  std::size_t up = 0;
  std::string others;
  for (const auto& [name, state] : s.subdevices) {
    if (state == subdevices::NodeState::Operational) {
      ++up;
      continue;
    }
    others += fmt::format("{}{} {}", others.empty() ? "" : ", ", name, subdevices::to_string(state));
  }
  std::string out = fmt::format("upstream {}, node {:02X}h; {}/{} sub-devices operational",
                                canopen::to_string(s.upstream), s.node_id, up, s.subdevices.size());
  if (!others.empty()) out += "; " + others;
  for (const auto& d : s.degraded) out += "; " + d;
  return out;
}

ServiceState service_state(Gateway& gw) {
  ServiceState s;
  s.upstream = gw.upstream().node().state();
  s.node_id = gw.upstream().node().node_id().value();
  for (const auto& name : gw.downstream().names()) s.subdevices.emplace_back(name, gw.downstream().state(name));
  return s;
}

namespace {
constexpr Duration kStatusPoll = std::chrono::seconds(1);
}

ServiceNotify::ServiceNotify(Notifier& out, std::optional<Duration> watchdog) : out_(out) {
  if (watchdog && watchdog->count() > 1) ping_every_ = *watchdog / 2;  // sd_watchdog_enabled(3): half
}

Duration ServiceNotify::poll_period() const { return ping_every_ ? std::min(*ping_every_, kStatusPoll) : kStatusPoll; }

void ServiceNotify::update(TimePoint now, const ServiceState& state) {
  if (stopping_) return;
  if (!ready_ && state.upstream != canopen::NmtState::Initialisation) {
    ready_ = true;
    out_.notify("READY=1");
  }
  send_status(state);
  if (!ping_every_) return;
  if (!next_ping_ || now >= *next_ping_) {
    out_.notify("WATCHDOG=1");
    // From now, not from the missed due time: a late loop pings once, not a burst.
    next_ping_ = now + *ping_every_;
  }
}

void ServiceNotify::reloading(TimePoint monotonic) {
  if (stopping_) return;
  const auto us = std::chrono::duration_cast<std::chrono::microseconds>(monotonic.time_since_epoch()).count();
  out_.notify(fmt::format("RELOADING=1\nMONOTONIC_USEC={}", us));
}

void ServiceNotify::reloaded(const std::string& note, const ServiceState& state) {
  if (stopping_) return;
  note_ = note;
  out_.notify("READY=1");
  send_status(state);
}

void ServiceNotify::send_status(const ServiceState& state) {
  if (const std::string line = status_line(state) + (note_.empty() ? "" : "; " + note_); line != status_) {
    status_ = line;
    out_.notify("STATUS=" + line);
  }
}

void ServiceNotify::stopping() {
  if (stopping_) return;
  stopping_ = true;
  out_.notify("STOPPING=1");
}

}  // namespace oegw::gateway
