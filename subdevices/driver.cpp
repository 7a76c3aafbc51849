#include "subdevices/driver.hpp"

#include <algorithm>

namespace oegw::subdevices {

std::string_view to_string(SignalStatus s) {
  switch (s) {
    case SignalStatus::Valid: return "valid";
    case SignalStatus::Error: return "error";
    case SignalStatus::NotAvailable: return "not available";
    case SignalStatus::Stale: return "stale";
    case SignalStatus::Offline: return "offline";
  }
  return "unknown";
}

std::string_view to_string(SignalKind k) {
  switch (k) {
    case SignalKind::Axis: return "axis";
    case SignalKind::Button: return "button";
    case SignalKind::Position: return "position";
    case SignalKind::Speed: return "speed";
    case SignalKind::Digital: return "digital";
    case SignalKind::Analog: return "analog";
    case SignalKind::Output: return "output";
  }
  return "unknown";
}

std::optional<std::size_t> Driver::find_signal(std::string_view name) const {
  const auto& s = signals();
  for (std::size_t i = 0; i < s.size(); ++i)
    if (s[i].name == name) return i;
  return std::nullopt;
}

void Driver::init(NodeId node, FrameSink sink, std::size_t signal_count) {
  node_ = node;
  sink_ = std::move(sink);
  values_.assign(signal_count, SignalValue{});
  rebuild_deadlines();
}

void Driver::update(std::size_t index, std::int64_t value, SignalStatus status, TimePoint now) {
  // A value whose carrier PDO is overdue stays Stale, whatever frame republishes it.
  if (status == SignalStatus::Valid && index < fresh_at_.size() && fresh_at_[index] && deadline_[index].count() != 0 &&
      now >= *fresh_at_[index] + deadline_[index])
    status = SignalStatus::Stale;
  SignalValue& v = values_.at(index);
  if (v.value == value && v.status == status) {
    v.timestamp = now;
    return;
  }
  v = SignalValue{value, status, now};
  if (on_change) on_change(index, v);
}

void Driver::on_online(TimePoint /*now*/) {}

void Driver::on_offline(TimePoint now) {
  const auto& s = signals();
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i].output()) continue;
    update(i, s[i].neutral, SignalStatus::Offline, now);
  }
}

void Driver::end_outputs(TimePoint now) {
  if (output_batch_ > 0 && --output_batch_ == 0) flush_outputs(now);
}

void Driver::set_carriers(std::vector<Carrier> carriers) {
  carriers_ = std::move(carriers);
  rebuild_deadlines();
}

void Driver::apply_boot_writes(const std::vector<SdoWrite>& writes) {
  refresh_carriers();
  for (const SdoWrite& w : writes) {
    for (Carrier& c : carriers_) {
      if (w.index != c.comm_index || w.data.empty()) continue;
      if (w.sub == 5 && w.data.size() >= 2) c.event_timer_ms = static_cast<std::uint16_t>(w.data[0] | (w.data[1] << 8));
      if (w.sub == 2) c.transmission_type = w.data[0];
    }
  }
  rebuild_deadlines();
}

void Driver::set_pdo_timeout(Duration timeout) {
  pdo_timeout_ = timeout;
  rebuild_deadlines();
}

void Driver::pdo_received(std::uint32_t can_id, TimePoint now) {
  auto refresh = [&](std::size_t i) {
    if (i >= deadline_.size() || deadline_[i].count() == 0) return;
    const auto at = stale_at(i);
    if (at && now >= *at && values_[i].status == SignalStatus::Valid) update(i, values_[i].value, SignalStatus::Stale, now);
    fresh_at_[i] = now;
  };
  if (carriers_.empty()) {  // pdo_timeout_ms on a driver without carriers: every input
    for (const std::size_t i : with_deadline_) refresh(i);
    return;
  }
  for (const Carrier& c : carriers_)
    if (c.cob_id == can_id)
      for (const std::size_t i : c.signals) refresh(i);
}

void Driver::rebuild_deadlines() {
  deadline_.assign(values_.size(), Duration{0});
  fresh_at_.resize(values_.size());
  for (const Carrier& c : carriers_) {
    Duration d = pdo_timeout_;
    if (d.count() == 0 && c.event_timer_ms != 0 && c.transmission_type >= 254)
      d = std::chrono::milliseconds(c.event_timer_ms) * kMissedPeriods;
    for (const std::size_t i : c.signals)
      if (i < deadline_.size() && (deadline_[i].count() == 0 || (d.count() != 0 && d < deadline_[i]))) deadline_[i] = d;
  }
  // A driver that declares no carriers: pdo_timeout_ms covers every input signal.
  if (carriers_.empty() && pdo_timeout_.count() != 0) {
    const auto& info = signals();
    for (std::size_t i = 0; i < deadline_.size() && i < info.size(); ++i)
      if (!info[i].output()) deadline_[i] = pdo_timeout_;
  }
  with_deadline_.clear();
  for (std::size_t i = 0; i < deadline_.size(); ++i)
    if (deadline_[i].count() != 0) with_deadline_.push_back(i);
}

Duration Driver::freshness(std::size_t index) const {
  return index < deadline_.size() ? deadline_[index] : Duration{0};
}

Duration Driver::longest_freshness() const {
  Duration d{0};
  for (const std::size_t i : with_deadline_) d = std::max(d, deadline_[i]);
  return d;
}

std::optional<TimePoint> Driver::stale_at(std::size_t i) const {
  const SignalValue& v = values_[i];
  if (v.status == SignalStatus::Valid) return (fresh_at_[i] ? *fresh_at_[i] : v.timestamp) + deadline_[i];
  // Never had a PDO while the node is alive: counted from the proof of life (or from when the
  // signal went offline, if later).
  if (v.status == SignalStatus::Offline && alive_since_) return std::max(*alive_since_, v.timestamp) + deadline_[i];
  return std::nullopt;
}

void Driver::advance(TimePoint now) {
  for (const std::size_t i : with_deadline_) {
    const auto at = stale_at(i);
    if (at && now >= *at) update(i, values_[i].value, SignalStatus::Stale, now);
  }
}

bool Driver::all_stale() const {
  if (with_deadline_.empty()) return false;
  return std::all_of(with_deadline_.begin(), with_deadline_.end(),
                     [this](std::size_t i) { return values_[i].status == SignalStatus::Stale; });
}

std::optional<TimePoint> Driver::next_deadline() const {
  std::optional<TimePoint> best;
  for (const std::size_t i : with_deadline_) {
    const auto at = stale_at(i);
    if (at && (!best || *at < *best)) best = at;
  }
  return best;
}

std::optional<std::string> DriverOptions::get(std::string_view key) const {
  for (const auto& [k, v] : values)
    if (k == key) return v;
  return std::nullopt;
}

}  // namespace oegw::subdevices
