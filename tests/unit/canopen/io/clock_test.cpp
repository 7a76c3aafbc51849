#include "canopen/io/clock.hpp"

#include <gtest/gtest.h>
#include <time.h>

#include <chrono>

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;

namespace {

TEST(SimulatedClock, StartsWhereToldAndMovesOnlyWhenTold) {
  SimulatedClock clock(TimePoint{5s});
  EXPECT_EQ(clock.now(), TimePoint{5s});
  EXPECT_EQ(clock.now(), TimePoint{5s});
  clock.advance(250us);
  EXPECT_EQ(clock.now(), TimePoint{5s + 250us});
  EXPECT_TRUE(clock.set(TimePoint{7s}));
  EXPECT_EQ(clock.now(), TimePoint{7s});
}

TEST(SimulatedClock, RefusesToGoBackwards) {
  SimulatedClock clock(TimePoint{10s});
  EXPECT_FALSE(clock.set(TimePoint{9s}));
  EXPECT_EQ(clock.now(), TimePoint{10s});
  EXPECT_TRUE(clock.set(TimePoint{10s}));  // standing still is fine
  EXPECT_THROW(clock.advance(-1us), std::invalid_argument);
  EXPECT_EQ(clock.now(), TimePoint{10s});
}

TEST(SimulatedClock, UsableThroughTheInterface) {
  SimulatedClock sim;
  const Clock& clock = sim;
  sim.advance(3ms);
  EXPECT_EQ(clock.now(), TimePoint{3ms});
}

TEST(SteadyClock, MatchesClockMonotonicAndNeverGoesBack) {
  SteadyClock clock;
  timespec before{};
  ::clock_gettime(CLOCK_MONOTONIC, &before);
  const TimePoint a = clock.now();
  const TimePoint b = clock.now();
  timespec after{};
  ::clock_gettime(CLOCK_MONOTONIC, &after);
  EXPECT_LE(a, b);
  EXPECT_GE(a, time_point_from_monotonic(before.tv_sec, before.tv_nsec));
  EXPECT_LE(b, time_point_from_monotonic(after.tv_sec, after.tv_nsec));
  // Same epoch as std::chrono::steady_clock (libstdc++ uses CLOCK_MONOTONIC), so timerfd
  // deadlines computed from either agree to well within a second.
  const auto std_now = std::chrono::time_point_cast<Duration>(std::chrono::steady_clock::now());
  EXPECT_LT(std_now - clock.now(), 1s);
  EXPECT_GT(std_now - clock.now(), -1s);
}

TEST(TimePointFromMonotonic, TruncatesNanosecondsToMicroseconds) {
  EXPECT_EQ(time_point_from_monotonic(2, 1'999), TimePoint{2s + 1us});
  EXPECT_EQ(time_point_from_monotonic(0, 999'999'999), TimePoint{999'999us});
}

}  // namespace
