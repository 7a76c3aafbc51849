#include "publish/publish_schedule.hpp"

#include <stdexcept>

namespace oegw::publish {

namespace {
// Same published content: status and values. seq and the source timestamp do not count — a new
// frame with the same values is not a change.
bool same(const gateway::SampleHeader& a, const gateway::SampleHeader& b) { return a.status == b.status; }
bool same(const gateway::JoystickSample& a, const gateway::JoystickSample& b) {
  return same(a.h, b.h) && a.x == b.x && a.y == b.y && a.z == b.z && a.buttons == b.buttons && a.memory == b.memory;
}
bool same(const gateway::PedalSample& a, const gateway::PedalSample& b) {
  return same(a.h, b.h) && a.position == b.position && a.memory == b.memory;
}
bool same(const gateway::WheelSample& a, const gateway::WheelSample& b) {
  return same(a.h, b.h) && a.position == b.position;
}
bool same(const gateway::EncoderSample& a, const gateway::EncoderSample& b) {
  return same(a.h, b.h) && a.position == b.position;
}
bool same(const gateway::ButtonClusterSample& a, const gateway::ButtonClusterSample& b) {
  return same(a.h, b.h) && a.switches == b.switches;
}
}  // namespace

PublishSchedule::PublishSchedule(gateway::Publisher& out, std::int64_t period_us) : out_(out), period_us_(period_us) {
  if (period_us <= 0) throw std::invalid_argument("publish period must be > 0");
}

template <class S>
void PublishSchedule::update_impl(FeKind kind, const S& s, std::int64_t now_us) {
  auto key = std::make_pair(kind, s.h.instance);
  auto it = entries_.find(key);
  if (it == entries_.end()) {
    it = entries_.emplace(key, Entry{s, now_us}).first;
    std::get<S>(it->second.last).h.seq = 0;
    send(it->second, now_us);
    return;
  }
  S& last = std::get<S>(it->second.last);
  const bool changed = !same(last, s);
  const std::uint32_t seq = last.h.seq;
  last = s;
  last.h.seq = seq;
  if (changed) send(it->second, now_us);
}

void PublishSchedule::send(Entry& e, std::int64_t now_us) {
  e.last_sent_us = now_us;
  ++published_;
  std::visit(
      [this](auto& s) {
        ++s.h.seq;
        out_.publish(s);
      },
      e.last);
}

void PublishSchedule::update(const gateway::JoystickSample& s, std::int64_t now_us) {
  update_impl(FeKind::Joystick, s, now_us);
}
void PublishSchedule::update(const gateway::PedalSample& s, std::int64_t now_us) {
  update_impl(FeKind::Pedal, s, now_us);
}
void PublishSchedule::update(const gateway::WheelSample& s, std::int64_t now_us) {
  update_impl(FeKind::Wheel, s, now_us);
}
void PublishSchedule::update(const gateway::EncoderSample& s, std::int64_t now_us) {
  update_impl(FeKind::Encoder, s, now_us);
}
void PublishSchedule::update(const gateway::ButtonClusterSample& s, std::int64_t now_us) {
  update_impl(FeKind::ButtonCluster, s, now_us);
}

void PublishSchedule::tick(std::int64_t now_us) {
  for (auto& [key, e] : entries_) {
    if (now_us - e.last_sent_us >= period_us_) send(e, now_us);
  }
}

std::optional<std::int64_t> PublishSchedule::next_due() const {
  std::optional<std::int64_t> due;
  for (const auto& [key, e] : entries_) {
    const std::int64_t t = e.last_sent_us + period_us_;
    if (!due || t < *due) due = t;
  }
  return due;
}

}  // namespace oegw::publish
