#include "subdevices/driver.hpp"

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
}

void Driver::update(std::size_t index, std::int64_t value, SignalStatus status, TimePoint now) {
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

std::optional<std::string> DriverOptions::get(std::string_view key) const {
  for (const auto& [k, v] : values)
    if (k == key) return v;
  return std::nullopt;
}

}  // namespace oegw::subdevices
