#include "canopen/io/clock.hpp"

#include <time.h>

#include <stdexcept>

namespace oegw::canopen::io {

TimePoint time_point_from_monotonic(long long seconds, long long nanoseconds) {
  return TimePoint{Duration{seconds * 1'000'000LL + nanoseconds / 1'000LL}};
}

TimePoint SteadyClock::now() const {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return time_point_from_monotonic(ts.tv_sec, ts.tv_nsec);
}

bool SimulatedClock::set(TimePoint t) {
  if (t < now_) return false;
  now_ = t;
  return true;
}

void SimulatedClock::advance(Duration d) {
  if (d < Duration::zero()) throw std::invalid_argument("SimulatedClock::advance: negative duration");
  now_ += d;
}

}  // namespace oegw::canopen::io
