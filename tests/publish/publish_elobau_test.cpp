// End to end on the virtual bus (simulated clock): the simulated elobau grip booted and watched by
// the network manager with the real driver; joystick.1 = {x: grip.x, y: grip.y, buttons:
// grip.buttons[1..6] (the grip's 2100h:01h default 63)} published through the schedule to DDS and
// LCM at once, read by the example subscribers in two other processes — every sample checked on
// both, through the grip's heartbeat stopping (status offline, neutral values). Then indicator
// commands over DDS and over LCM light the grip's LEDs (indicators.1 = grip.leds[1..4]).
//
// The FE feed here is a stand-in for the mapping layer (not in this branch): it takes the raw
// driver values (the grip's percent) without scaling.
#include <gtest/gtest.h>
#include <lcm/lcm.h>
#include <poll.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "canopen/master.hpp"
#include "dds/dds.h"
#include "dds_command_writer.hpp"
#include "oegw.h"
#include "oegw/indicator_command_t.hpp"
#include "publish/dds_publisher.hpp"
#include "publish/lcm_publisher.hpp"
#include "publish/publish_schedule.hpp"
#include "subdevices/device_spec.hpp"
#include "subdevices/network_manager.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "tests/integration/virtual_network.hpp"
#include "tests/publish/child_process.hpp"
#include "tests/publish/private_network.hpp"
#include "tests/publish/subscriber_lines.hpp"

using namespace oegw::canopen;
using namespace oegw::subdevices;
using namespace std::chrono_literals;

namespace oegw::gateway {
namespace {

using test::line_of;
using test::without_rx;
std::int64_t us(TimePoint t) { return t.time_since_epoch().count(); }

// Publishes to DDS and LCM, then waits until both subscribers printed the sample (they keep the
// last sample per instance: one in flight at a time) and checks it.
struct BothTransports : Publisher {
  publish::DdsPublisher& dds;
  publish::LcmPublisher& lcm;
  test::ChildProcess& dds_sub;
  test::ChildProcess& lcm_sub;
  std::vector<JoystickSample> sent;
  BothTransports(publish::DdsPublisher& d, publish::LcmPublisher& l, test::ChildProcess& ds, test::ChildProcess& ls)
      : dds(d), lcm(l), dds_sub(ds), lcm_sub(ls) {}
  void publish(const JoystickSample& s) override {
    sent.push_back(s);
    dds.publish(s);
    lcm.publish(s);
    for (auto* sub : {&dds_sub, &lcm_sub}) {
      auto l = sub->read_line(10s);
      ASSERT_TRUE(l.has_value()) << (sub == &dds_sub ? "DDS" : "LCM") << ": sample seq " << s.h.seq << " not received";
      EXPECT_EQ(without_rx(*l), line_of(s)) << (sub == &dds_sub ? "DDS" : "LCM");
    }
  }
  void publish(const PedalSample&) override {}
  void publish(const WheelSample&) override {}
  void publish(const EncoderSample&) override {}
  void publish(const ButtonClusterSample&) override {}
  void publish(const GatewayStatus&) override {}
};

class GripToDdsAndLcm : public ::testing::Test {
 protected:
  GripToDdsAndLcm() : bench_(net_.sink("sims")) {}
  void SetUp() override {
    std::string error;
    auto spec = parse_device_spec("elobau-mfg:0x11", error);
    ASSERT_TRUE(spec) << error;
    ASSERT_TRUE(bench_.add(*spec, error)) << error;
    auto driver = make_driver(spec->family, spec->node, net_.sink("gateway"), spec->options, error);
    ASSERT_TRUE(driver) << error;
    grip_ = driver.get();
    NodeSettings s;
    s.name = "grip";
    s.node = spec->node;
    s.heartbeat_ms = 100;
    ASSERT_TRUE(network_.add(s, std::move(driver)));
    net_.attach("sims", bench_);
    net_.attach("gateway", network_);
    sim_name_ = bench_.names().at(0);
  }

  // joystick.1 from the grip's signals; the status is the worst of them.
  JoystickSample joystick() const {
    JoystickSample j;
    j.h.instance = 1;
    const auto& x = grip_->value(*grip_->find_signal("x"));
    const auto& y = grip_->value(*grip_->find_signal("y"));
    j.x = static_cast<std::int16_t>(x.value);
    j.y = static_cast<std::int16_t>(y.value);
    auto worst = std::max(x.status, y.status);
    TimePoint ts = std::max(x.timestamp, y.timestamp);
    for (int b = 1; b <= 6; ++b) {
      const auto& v = grip_->value(*grip_->find_signal("buttons[" + std::to_string(b) + "]"));
      if (v.value != 0) j.buttons = static_cast<std::uint8_t>(j.buttons | (1u << (b - 1)));
      worst = std::max(worst, v.status);
      ts = std::max(ts, v.timestamp);
    }
    j.h.status = static_cast<FeStatus>(static_cast<int>(worst));  // same order as SignalStatus
    j.h.timestamp_us = us(ts);
    return j;
  }
  // Runs the simulated time in 10 ms steps, feeding and ticking the schedule.
  void run(publish::PublishSchedule& sched, Duration d) {
    const TimePoint end = net_.now() + d;
    while (net_.now() < end) {
      net_.run_for(10ms);
      sched.update(joystick(), us(net_.now()));
      sched.tick(us(net_.now()));
    }
  }
  std::string sim(const std::string& cmd) { return bench_.command(sim_name_ + " " + cmd, net_.now()); }
  std::int64_t led(int i) {
    auto v = bench_.device(sim_name_)->output("leds[" + std::to_string(i) + "]");
    return v ? *v : -1;
  }

  oegw::testing::VirtualNetwork net_;
  sim::SimBench bench_;
  ObjectDictionary od_;
  Master master_{od_, net_.sink("gateway"), MasterConfig{.heartbeat_entries = 8, .sdo_timeout = 200ms}};
  NetworkManager network_{master_};
  Driver* grip_ = nullptr;
  std::string sim_name_;
  std::string tag_ = std::to_string(::getpid());
};

TEST_F(GripToDdsAndLcm, SubscribersSeeTheJoystickMoveAndGoOfflineWhenItsHeartbeatStops) {
  publish::DdsSettings ds;
  ds.partition = "oegw-e2e-" + tag_;
  ds.period_us = 100'000;
  publish::DdsPublisher dds(ds);
  publish::LcmSettings ls;
  ls.channel_prefix = "E" + tag_ + "_";
  publish::LcmPublisher lcm(ls);
  test::ChildProcess dds_sub({OEGW_DDS_SUBSCRIBER, "--timeout", "60", "--partition", ds.partition});
  test::ChildProcess lcm_sub(
      {OEGW_LCM_SUBSCRIBER, "--timeout", "60", "--channel", ls.channel_prefix + "JOYSTICK_[0-9]+"});
  ASSERT_EQ(dds_sub.read_line(10s), "ready");
  ASSERT_EQ(lcm_sub.read_line(10s), "ready");
  const auto wall_end = std::chrono::steady_clock::now() + 10s;
  while (dds.joystick_readers() == 0 && std::chrono::steady_clock::now() < wall_end) test::ChildProcess::pause_ms(5);
  ASSERT_GE(dds.joystick_readers(), 1u);

  BothTransports both(dds, lcm, dds_sub, lcm_sub);
  publish::PublishSchedule sched(both, ds.period_us);
  bench_.start(net_.now());
  network_.start(net_.now());
  run(sched, 3s);
  ASSERT_EQ(network_.state("grip"), NodeState::Operational);
  ASSERT_FALSE(both.sent.empty());
  EXPECT_EQ(both.sent.back().h.status, FeStatus::Valid);

  ASSERT_EQ(sim("x 40"), "ok " + sim_name_ + " x = 40");
  run(sched, 200ms);
  ASSERT_EQ(sim("buttons[2] 1"), "ok " + sim_name_ + " buttons[2] = 1");
  ASSERT_EQ(sim("y -25"), "ok " + sim_name_ + " y = -25");
  run(sched, 300ms);  // also: still for 200 ms, republished every 100 ms
  EXPECT_EQ(both.sent.back().x, 40);
  EXPECT_EQ(both.sent.back().y, -25);
  EXPECT_EQ(both.sent.back().buttons, 0x02);
  EXPECT_EQ(both.sent.back().h.status, FeStatus::Valid);
  const std::size_t before_loss = both.sent.size();

  ASSERT_EQ(sim("heartbeat off"), "ok " + sim_name_ + " heartbeat off");
  run(sched, 400ms);
  EXPECT_EQ(network_.state("grip"), NodeState::Missing);
  ASSERT_GT(both.sent.size(), before_loss);
  const JoystickSample& last = both.sent.back();
  EXPECT_EQ(last.h.status, FeStatus::Offline);
  EXPECT_EQ(last.x, 0) << "offline: neutral";
  EXPECT_EQ(last.y, 0);
  EXPECT_EQ(last.buttons, 0);
  for (std::size_t i = 0; i < both.sent.size(); ++i) EXPECT_EQ(both.sent[i].h.seq, i + 1) << "seq without gaps";
  std::printf("published %zu joystick samples, each received by both subscribers\n", both.sent.size());
}

TEST_F(GripToDdsAndLcm, IndicatorCommandsOverDdsAndLcmLightTheGripsLeds) {
  publish::DdsSettings ds;
  ds.partition = "oegw-e2e-cmd-" + tag_;
  publish::DdsPublisher dds(ds);
  publish::LcmSettings ls;
  ls.channel_prefix = "F" + tag_ + "_";
  publish::LcmPublisher lcm(ls);
  // indicators.1 = grip.leds[1..4]; one rule when two write: the last command wins.
  const auto apply = [this](const IndicatorCommand& c) {
    if (c.instance != 1) return;
    for (int i = 1; i <= 4; ++i)
      grip_->set_output(*grip_->find_signal("leds[" + std::to_string(i) + "]"), (c.indicators >> (i - 1)) & 1,
                        net_.now());
  };
  dds.on_indicator_command = apply;
  lcm.on_indicator_command = apply;

  bench_.start(net_.now());
  network_.start(net_.now());
  net_.run_for(3s);
  ASSERT_EQ(network_.state("grip"), NodeState::Operational);
  EXPECT_EQ(led(1), 0);

  // The gateway's loop: wait on the publisher's fd, poll(), let the bus carry the RPDO.
  const auto wait_led = [&](Publisher& p, int i, std::int64_t want) {
    const auto end = std::chrono::steady_clock::now() + 10s;
    while (std::chrono::steady_clock::now() < end) {
      pollfd f{p.fd(), POLLIN, 0};
      if (::poll(&f, 1, 5) > 0) p.poll();
      net_.run_for(20ms);
      if (led(i) == want) return true;
    }
    return false;
  };

  // DDS: the machine application's writer.
  {
    const test::DdsIndicatorWriter writer(ds.domain, ds.partition);
    ASSERT_TRUE(writer.ready()) << "the DDS command reader never matched";
    ASSERT_TRUE(writer.write(1, 0b0101));
    ASSERT_TRUE(wait_led(dds, 1, 1)) << "DDS command did not light LED 1";
    EXPECT_EQ(led(2), 0);
    EXPECT_EQ(led(3), 1);
    EXPECT_EQ(led(4), 0);
  }

  // LCM: the same, last writer wins.
  lcm_t* app = lcm_create(ls.url.c_str());
  ASSERT_NE(app, nullptr);
  oegw::indicator_command_t lc;
  lc.instance = 1;
  lc.indicators = 0b1010;
  std::vector<std::uint8_t> buf(static_cast<std::size_t>(lc.getEncodedSize()));
  lc.encode(buf.data(), 0, static_cast<int>(buf.size()));
  const std::string ch = ls.channel_prefix + "INDICATORS_1";
  lcm_publish(app, ch.c_str(), buf.data(), static_cast<unsigned>(buf.size()));
  ASSERT_TRUE(wait_led(lcm, 2, 1)) << "LCM command did not light LED 2";
  EXPECT_EQ(led(1), 0);
  EXPECT_EQ(led(3), 0);
  EXPECT_EQ(led(4), 1);
  lcm_destroy(app);
}

}  // namespace
}  // namespace oegw::gateway

int main(int argc, char** argv) {
  oegw::test::enter_private_network();  // lo only, for this process and the subscribers
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
