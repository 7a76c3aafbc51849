// Clocks for the I/O side. Services never read a clock ("sans I/O"); the event loop does, through
// this interface, so that tests can substitute a SimulatedClock and run without sleeping.
#pragma once

#include "canopen/types.hpp"

namespace oegw::canopen {

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

}  // namespace oegw::canopen
