// The publishing schedule with a simulated clock: on change, periodic while still, seq numbers.
#include "publish/publish_schedule.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace oegw::gateway {
namespace {

struct Recorder : Publisher {
  std::vector<JoystickSample> joy;
  std::vector<PedalSample> pedal;
  std::vector<WheelSample> wheel;
  std::vector<EncoderSample> enc;
  std::vector<ButtonClusterSample> btn;
  void publish(const JoystickSample& s) override { joy.push_back(s); }
  void publish(const PedalSample& s) override { pedal.push_back(s); }
  void publish(const WheelSample& s) override { wheel.push_back(s); }
  void publish(const EncoderSample& s) override { enc.push_back(s); }
  void publish(const ButtonClusterSample& s) override { btn.push_back(s); }
  void publish(const GatewayStatus&) override {}
};

JoystickSample joy(std::uint8_t inst, std::int16_t x, FeStatus st = FeStatus::Valid, std::int64_t ts = 0) {
  JoystickSample s;
  s.h.instance = inst;
  s.h.status = st;
  s.h.timestamp_us = ts;
  s.x = x;
  return s;
}

TEST(PublishSchedule, FirstValueIsPublishedAtOnceWithSeqOne) {
  Recorder r;
  publish::PublishSchedule sched(r, 100'000);
  sched.update(joy(1, 10, FeStatus::Valid, 5), 1000);
  ASSERT_EQ(r.joy.size(), 1u);
  EXPECT_EQ(r.joy[0].h.seq, 1u);
  EXPECT_EQ(r.joy[0].x, 10);
  EXPECT_EQ(r.joy[0].h.timestamp_us, 5);
  EXPECT_EQ(sched.next_due(), 101'000);
}

TEST(PublishSchedule, SameValuesAreNotRepublishedBeforeThePeriod) {
  Recorder r;
  publish::PublishSchedule sched(r, 100'000);
  sched.update(joy(1, 10), 0);
  sched.update(joy(1, 10, FeStatus::Valid, 50), 50'000);  // a new frame, same value: no change
  sched.tick(99'999);
  EXPECT_EQ(r.joy.size(), 1u);
}

TEST(PublishSchedule, AChangeIsPublishedImmediatelyAndRestartsThePeriod) {
  Recorder r;
  publish::PublishSchedule sched(r, 100'000);
  sched.update(joy(1, 10), 0);
  sched.update(joy(1, 11), 30'000);
  ASSERT_EQ(r.joy.size(), 2u);
  EXPECT_EQ(r.joy[1].x, 11);
  EXPECT_EQ(r.joy[1].h.seq, 2u);
  EXPECT_EQ(sched.next_due(), 130'000);
  sched.tick(129'999);
  EXPECT_EQ(r.joy.size(), 2u);
  sched.tick(130'000);
  ASSERT_EQ(r.joy.size(), 3u);
  EXPECT_EQ(r.joy[2].x, 11);
  EXPECT_EQ(r.joy[2].h.seq, 3u);
}

TEST(PublishSchedule, AStillJoystickKeepsComingWithRisingSeqAndItsSourceTimestamp) {
  Recorder r;
  publish::PublishSchedule sched(r, 100'000);
  sched.update(joy(2, -7, FeStatus::Valid, 42), 0);
  for (std::int64_t t = 100'000; t <= 1'000'000; t += 100'000) sched.tick(t);
  ASSERT_EQ(r.joy.size(), 11u);
  for (std::uint32_t i = 0; i < r.joy.size(); ++i) {
    EXPECT_EQ(r.joy[i].h.seq, i + 1);
    EXPECT_EQ(r.joy[i].x, -7);
    EXPECT_EQ(r.joy[i].h.timestamp_us, 42);  // the value is as old as its frame
  }
}

TEST(PublishSchedule, AStatusChangeIsAChange) {
  Recorder r;
  publish::PublishSchedule sched(r, 100'000);
  sched.update(joy(1, 0), 0);
  sched.update(joy(1, 0, FeStatus::Offline), 10);
  ASSERT_EQ(r.joy.size(), 2u);
  EXPECT_EQ(r.joy[1].h.status, FeStatus::Offline);
}

TEST(PublishSchedule, InstancesAndKindsHaveTheirOwnSeqAndPeriod) {
  Recorder r;
  publish::PublishSchedule sched(r, 100'000);
  sched.update(joy(1, 1), 0);
  sched.update(joy(2, 1), 50'000);
  PedalSample p;
  p.h.instance = 1;
  p.position = 3;
  sched.update(p, 60'000);
  WheelSample w;
  sched.update(w, 60'000);
  EncoderSample e;
  sched.update(e, 60'000);
  ButtonClusterSample b;
  b.switches = 1ULL << 63;
  sched.update(b, 60'000);
  EXPECT_EQ(r.joy[0].h.seq, 1u);
  EXPECT_EQ(r.joy[1].h.seq, 1u);
  EXPECT_EQ(r.pedal.at(0).h.seq, 1u);
  sched.tick(100'000);  // only joystick 1 is due
  ASSERT_EQ(r.joy.size(), 3u);
  EXPECT_EQ(r.joy[2].h.instance, 1);
  EXPECT_EQ(r.joy[2].h.seq, 2u);
  EXPECT_EQ(r.pedal.size(), 1u);
  sched.tick(160'000);
  EXPECT_EQ(r.joy.size(), 4u);  // joystick 2
  EXPECT_EQ(r.pedal.size(), 2u);
  EXPECT_EQ(r.wheel.size(), 2u);
  EXPECT_EQ(r.enc.size(), 2u);
  ASSERT_EQ(r.btn.size(), 2u);
  EXPECT_EQ(r.btn[1].switches, 1ULL << 63);
  EXPECT_EQ(sched.published(), 12u);
}

TEST(PublishSchedule, NothingKnownNothingDue) {
  Recorder r;
  publish::PublishSchedule sched(r, 1000);
  EXPECT_FALSE(sched.next_due().has_value());
  sched.tick(1'000'000);
  EXPECT_TRUE(r.joy.empty());
}

TEST(PublishSchedule, PeriodMustBePositive) {
  Recorder r;
  EXPECT_THROW(publish::PublishSchedule(r, 0), std::invalid_argument);
}

}  // namespace
}  // namespace oegw::gateway
