// Clocks for the I/O side. Services never read a clock ("sans I/O"); the event loop does, through
// this interface, so that tests can substitute a SimulatedClock and run without sleeping.
#pragma once

#include <optional>

#include "canopen/types.hpp"

namespace oegw::canopen::io {

class Clock {
 public:
  virtual ~Clock() = default;
  [[nodiscard]] virtual TimePoint now() const = 0;
};

// CLOCK_MONOTONIC, microsecond resolution. TimePoint's epoch is the steady_clock epoch, which on
// Linux/libstdc++ is CLOCK_MONOTONIC's, so values are comparable with timerfd deadlines.
class SteadyClock final : public Clock {
 public:
  [[nodiscard]] TimePoint now() const override;
};

// The event loop's real-time clock: CLOCK_MONOTONIC, read once per wake-up. Between hold() and
// release() now() returns the reading hold() took, so every callback of one wake-up (the frame's
// receiver, the timers due, the services they drive) sees the same instant and a translated frame
// costs one clock read, not one per caller. Outside a
// hold it reads the clock.
class WakeClock final : public Clock {
 public:
  [[nodiscard]] TimePoint now() const override { return held_ ? *held_ : steady_.now(); }
  void hold() { held_ = steady_.now(); }
  void release() { held_.reset(); }
  [[nodiscard]] bool held() const { return held_.has_value(); }

 private:
  SteadyClock steady_;
  std::optional<TimePoint> held_;
};

// A clock that only moves when told to. Time never goes backwards: set() to an earlier time is
// refused (returns false) so a test cannot accidentally violate steady-clock semantics.
class SimulatedClock final : public Clock {
 public:
  explicit SimulatedClock(TimePoint start = TimePoint{}) : now_(start) {}
  [[nodiscard]] TimePoint now() const override { return now_; }
  bool set(TimePoint t);
  void advance(Duration d);

 private:
  TimePoint now_;
};

// Converts a `struct timespec`-style monotonic reading (seconds + nanoseconds) to a TimePoint,
// truncating to microseconds.
[[nodiscard]] TimePoint time_point_from_monotonic(long long seconds, long long nanoseconds);

}  // namespace oegw::canopen::io
