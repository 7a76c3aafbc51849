// When to publish an FE sample, independent of the transport: on change, and again every
// `period` while nothing changes — so a reader can tell a still joystick (same values, seq still
// rising) from a dead gateway (nothing arrives; DDS readers also see the deadline missed).
// Assigns the per-instance sequence numbers. Driven by the caller's clock (µs, CLOCK_MONOTONIC in
// the gateway, a simulated one in the tests); it never reads a clock itself.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <utility>
#include <variant>

#include "gateway/fe_samples.hpp"

namespace oegw::publish {

enum class FeKind : std::uint8_t { Joystick, Pedal, Wheel, Encoder, ButtonCluster };

class PublishSchedule {
 public:
  // period_us > 0: the longest time between two samples of one FE instance.
  PublishSchedule(gateway::Publisher& out, std::int64_t period_us);

  // The FE's current value (status and source timestamp included; seq is ignored). Published
  // now if it differs from the last published one (values or status) or the FE is new.
  void update(const gateway::JoystickSample& s, std::int64_t now_us);
  void update(const gateway::PedalSample& s, std::int64_t now_us);
  void update(const gateway::WheelSample& s, std::int64_t now_us);
  void update(const gateway::EncoderSample& s, std::int64_t now_us);
  void update(const gateway::ButtonClusterSample& s, std::int64_t now_us);

  // Republishes (new seq, same values and source timestamp) every FE whose last sample is
  // `period` old or older.
  void tick(std::int64_t now_us);
  // When tick() next has work (the earliest due time), or nullopt with no FE known yet.
  [[nodiscard]] std::optional<std::int64_t> next_due() const;

  [[nodiscard]] std::int64_t period_us() const { return period_us_; }
  [[nodiscard]] std::uint64_t published() const { return published_; }

 private:
  using Sample = gateway::FeSample;
  struct Entry {
    Sample last;
    std::int64_t last_sent_us = 0;
  };
  template <class S>
  void update_impl(FeKind kind, const S& s, std::int64_t now_us);
  void send(Entry& e, std::int64_t now_us);

  gateway::Publisher& out_;
  std::int64_t period_us_;
  std::map<std::pair<FeKind, std::uint8_t>, Entry> entries_;
  std::uint64_t published_ = 0;
};

}  // namespace oegw::publish
