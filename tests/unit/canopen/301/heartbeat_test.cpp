// Heartbeat producer/consumer (CiA 301 §7.2.8.3.2.2, 1016h/1017h). Message layout from the
// elobau MFG manual (000_499d7da4c768c72f, §11.1 "Heartbeat Message": COB-ID 700h+node-ID,
// byte 0 = NMT state) and the Novotechnik manual (004_965670f51e9c840d, §4.1: 1017h
// "Producer heartbeat time", UNSIGNED16 rw, 0 = disabled, period in ms).
#include "canopen/301/heartbeat.hpp"

#include <gtest/gtest.h>

#include <vector>

#include "canopen/301/nmt_slave.hpp"

using namespace oegw::canopen;

namespace {

TimePoint at_ms(int ms) { return TimePoint{} + std::chrono::milliseconds(ms); }

struct ProducerFixture : ::testing::Test {
  ObjectDictionary od;
  std::vector<CanFrame> sent;
  std::unique_ptr<HeartbeatProducer> hb;
  void SetUp() override {
    install_heartbeat_producer_objects(od, 100);
    hb = std::make_unique<HeartbeatProducer>(od, NodeId{0x11}, [this](const CanFrame& f) { sent.push_back(f); });
  }
  // Drives the producer as an event loop would: to each deadline up to `until`.
  void run_until(int ms) {
    while (auto d = hb->next_deadline()) {
      if (*d > at_ms(ms)) break;
      hb->advance(*d);
    }
  }
};

TEST_F(ProducerFixture, SilentUntilStartedThenEveryPeriod) {
  EXPECT_FALSE(hb->next_deadline());
  hb->start(NmtState::PreOperational, NodeId{0x11}, at_ms(0));
  EXPECT_EQ(hb->next_deadline(), at_ms(100));
  hb->advance(at_ms(99));
  EXPECT_TRUE(sent.empty());
  hb->advance(at_ms(100));
  ASSERT_EQ(sent.size(), 1u);
  // elobau §11.1: 0x711, byte 0 = NMT state (7Fh pre-operational).
  EXPECT_EQ(sent[0], CanFrame(0x711, {0x7F}));
  hb->set_state(NmtState::Operational);
  run_until(300);
  ASSERT_EQ(sent.size(), 3u);
  EXPECT_EQ(sent[2], CanFrame(0x711, {0x05}));
  hb->set_state(NmtState::Stopped);
  run_until(400);
  EXPECT_EQ(sent.back(), CanFrame(0x711, {0x04}));
}

// Novotechnik §4.1 1017h: 0 disables; a change takes effect immediately.
TEST_F(ProducerFixture, Change1017TakesEffectImmediately) {
  hb->start(NmtState::PreOperational, NodeId{0x11}, at_ms(0));
  run_until(100);
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(od.set<std::uint16_t>(0x1017, 0, 0, Origin::Sdo), SdoAbortCode::None);
  EXPECT_FALSE(hb->next_deadline());
  run_until(1000);
  EXPECT_EQ(sent.size(), 1u);
  // Re-enabled at t=1000 with 50 ms: counted from the last heartbeat (t=100) -> already due.
  EXPECT_EQ(od.set<std::uint16_t>(0x1017, 0, 50, Origin::Sdo), SdoAbortCode::None);
  EXPECT_EQ(hb->next_deadline(), at_ms(150));
  hb->advance(at_ms(1000));
  EXPECT_EQ(sent.size(), 2u);
  EXPECT_EQ(hb->next_deadline(), at_ms(1050));
  // Lengthened to 1000 ms at t=1010: next at 1000 + 1000, not at 1050.
  EXPECT_EQ(od.set<std::uint16_t>(0x1017, 0, 1000, Origin::Sdo), SdoAbortCode::None);
  EXPECT_EQ(hb->next_deadline(), at_ms(2000));
}

TEST_F(ProducerFixture, FollowsNmtSlaveThroughReset) {
  NmtSlave nmt(NodeId{0x11}, [this](const CanFrame& f) { sent.push_back(f); });
  nmt.on_state_change([&](NmtState s) {
    if (s == NmtState::Initialisation) hb->stop();
    else if (!hb->running()) hb->start(s, nmt.node_id(), nmt.last_transition());
    else hb->set_state(s);
  });
  nmt.start(at_ms(0));
  EXPECT_EQ(sent.back(), CanFrame(0x711, {0x00}));  // boot-up
  nmt.on_frame(CanFrame(0, {0x01, 0x11}), at_ms(30));
  run_until(100);
  EXPECT_EQ(sent.back(), CanFrame(0x711, {0x05}));
  nmt.set_pending_node_id(NodeId{0x12});
  nmt.on_frame(CanFrame(0, {0x82, 0x00}), at_ms(150));
  EXPECT_EQ(sent.back(), CanFrame(0x712, {0x00}));  // boot-up with the new node-ID
  EXPECT_EQ(hb->next_deadline(), at_ms(250));
  run_until(250);
  EXPECT_EQ(sent.back(), CanFrame(0x712, {0x7F}));
}

struct ConsumerFixture : ::testing::Test {
  ObjectDictionary od;
  std::unique_ptr<HeartbeatConsumer> hc;
  std::vector<NodeId> timeouts, boots;
  std::vector<std::pair<NodeId, NmtState>> states;
  void SetUp() override {
    install_heartbeat_consumer_objects(od, 3);
    hc = std::make_unique<HeartbeatConsumer>(od);
    hc->on_timeout([this](NodeId n) { timeouts.push_back(n); });
    hc->on_boot([this](NodeId n) { boots.push_back(n); });
    hc->on_state([this](NodeId n, NmtState s) { states.emplace_back(n, s); });
  }
  SdoAbortCode set_entry(std::uint8_t sub, std::uint8_t node, std::uint16_t ms) {
    return od.set<std::uint32_t>(0x1016, sub, heartbeat_consumer_entry(NodeId{node}, ms), Origin::Sdo);
  }
  bool hb(std::uint8_t node, std::uint8_t state, int ms) {
    return hc->on_frame(CanFrame(0x700u + node, {state}), at_ms(ms));
  }
};

TEST_F(ConsumerFixture, MonitoringStartsAtFirstHeartbeatTimeoutExactlyAtLastPlusTime) {
  ASSERT_EQ(set_entry(1, 0x11, 150), SdoAbortCode::None);
  EXPECT_EQ(od.get<std::uint32_t>(0x1016, 1), 0x00110096u);
  EXPECT_EQ(hc->status(NodeId{0x11}), HeartbeatConsumer::Status::Waiting);
  EXPECT_FALSE(hc->next_deadline());
  hc->advance(at_ms(10'000));  // nothing heard yet: no timeout
  EXPECT_TRUE(timeouts.empty());
  EXPECT_FALSE(hb(0x12, 0x05, 0));  // not monitored
  EXPECT_TRUE(hb(0x11, 0x7F, 1000));
  EXPECT_EQ(hc->next_deadline(), at_ms(1150));
  EXPECT_TRUE(hb(0x11, 0x05, 1100));
  EXPECT_EQ(hc->next_deadline(), at_ms(1250));
  hc->advance(at_ms(1250) - Duration{1});
  EXPECT_TRUE(timeouts.empty());
  hc->advance(at_ms(1250));
  EXPECT_EQ(timeouts, (std::vector<NodeId>{NodeId{0x11}}));
  EXPECT_EQ(hc->status(NodeId{0x11}), HeartbeatConsumer::Status::TimedOut);
  hc->advance(at_ms(5000));  // reported once
  EXPECT_EQ(timeouts.size(), 1u);
  EXPECT_FALSE(hc->next_deadline());
  EXPECT_TRUE(hb(0x11, 0x05, 6000));  // resumes
  EXPECT_EQ(hc->status(NodeId{0x11}), HeartbeatConsumer::Status::Active);
  EXPECT_EQ(hc->last_state(NodeId{0x11}), NmtState::Operational);
  ASSERT_EQ(states.size(), 2u);
  EXPECT_EQ(states[0], std::make_pair(NodeId{0x11}, NmtState::PreOperational));
  EXPECT_EQ(states[1], std::make_pair(NodeId{0x11}, NmtState::Operational));
}

TEST_F(ConsumerFixture, BootUpReportedAndSuspendsMonitoring) {
  ASSERT_EQ(set_entry(2, 0x05, 100), SdoAbortCode::None);
  hb(0x05, 0x05, 0);
  EXPECT_TRUE(hb(0x05, 0x00, 50));
  EXPECT_EQ(boots, (std::vector<NodeId>{NodeId{5}}));
  EXPECT_EQ(hc->status(NodeId{5}), HeartbeatConsumer::Status::Waiting);
  hc->advance(at_ms(500));
  EXPECT_TRUE(timeouts.empty());
  hb(0x05, 0x7F, 550);
  hc->advance(at_ms(650));
  EXPECT_EQ(timeouts, (std::vector<NodeId>{NodeId{5}}));
}

TEST_F(ConsumerFixture, DuplicateNodeRefusedWith06040043) {
  ASSERT_EQ(set_entry(1, 0x11, 150), SdoAbortCode::None);
  EXPECT_EQ(set_entry(2, 0x11, 200), SdoAbortCode::ParameterIncompatibility);
  EXPECT_EQ(od.get<std::uint32_t>(0x1016, 2), 0u);
  EXPECT_EQ(set_entry(2, 0x11, 0), SdoAbortCode::None);    // time 0: unused, allowed
  EXPECT_EQ(set_entry(1, 0x11, 300), SdoAbortCode::None);  // rewriting the same entry
  EXPECT_EQ(set_entry(3, 0x12, 300), SdoAbortCode::None);
}

TEST_F(ConsumerFixture, TwoNodesEarliestDeadlineAndReconfiguration) {
  set_entry(1, 1, 100);
  set_entry(2, 2, 40);
  hb(1, 0x05, 0);
  hb(2, 0x05, 0);
  EXPECT_EQ(hc->next_deadline(), at_ms(40));
  hc->advance(at_ms(40));
  EXPECT_EQ(timeouts, (std::vector<NodeId>{NodeId{2}}));
  EXPECT_EQ(hc->next_deadline(), at_ms(100));
  set_entry(1, 1, 0);  // switched off: no longer monitored
  EXPECT_EQ(hc->status(NodeId{1}), HeartbeatConsumer::Status::Unused);
  hc->advance(at_ms(1000));
  EXPECT_EQ(timeouts.size(), 1u);
}

TEST_F(ConsumerFixture, MalformedHeartbeatsIgnored) {
  set_entry(1, 3, 100);
  hb(3, 0x05, 0);
  EXPECT_TRUE(hc->on_frame(CanFrame(0x703, {0x05, 0x00}), at_ms(50)));  // DLC 2
  EXPECT_TRUE(hc->on_frame(CanFrame(0x703, {}), at_ms(50)));
  EXPECT_TRUE(hb(3, 0x33, 50));                                       // not a state
  EXPECT_FALSE(hc->on_frame(CanFrame::remote(0x703, 1), at_ms(50)));  // node guarding RTR
  EXPECT_EQ(hc->invalid_frames(), 3u);
  hc->advance(at_ms(100));
  EXPECT_EQ(timeouts.size(), 1u);  // none of them refreshed the timer
}

TEST_F(ConsumerFixture, ReloadAfterResetToDefaults) {
  set_entry(1, 3, 100);
  hb(3, 0x05, 0);
  od.reset_to_defaults(0x1000, 0x1FFF);
  hc->reload();
  EXPECT_EQ(hc->status(NodeId{3}), HeartbeatConsumer::Status::Unused);
  EXPECT_FALSE(hc->next_deadline());
}

// next_deadline() is kept between changes (it is asked after every frame of the bus): every
// change of an entry must end it — a heartbeat, a time-out, a 1016h write, a reload — even one
// made after a callback that asked for it with the entry half written.
TEST_F(ConsumerFixture, DeadlineFollowsEveryChangeOfAnEntry) {
  set_entry(1, 1, 100);
  set_entry(2, 2, 300);
  std::vector<std::optional<TimePoint>> asked;
  hc->on_timeout([&](NodeId n) {
    timeouts.push_back(n);
    asked.push_back(hc->next_deadline());
  });
  hb(1, 0x05, 0);
  EXPECT_EQ(hc->next_deadline(), at_ms(100));
  hb(2, 0x05, 50);
  EXPECT_EQ(hc->next_deadline(), at_ms(100));
  hb(1, 0x05, 80);  // a heartbeat moves its node's deadline
  EXPECT_EQ(hc->next_deadline(), at_ms(180));
  hc->advance(at_ms(179));  // before the kept deadline: nothing due
  EXPECT_TRUE(timeouts.empty());
  // Node 1's heartbeat after its time: the time-out is reported first (and its callback asks
  // while node 1 is timed out), then monitoring resumes from this heartbeat.
  hb(1, 0x05, 200);
  EXPECT_EQ(timeouts, (std::vector<NodeId>{NodeId{1}}));
  ASSERT_EQ(asked.size(), 1u);
  EXPECT_EQ(asked[0], at_ms(350));  // node 2 only, as it was when asked
  EXPECT_EQ(hc->next_deadline(), at_ms(300));
  hc->advance(at_ms(300));  // node 1 times out; the callback sees node 2 only
  EXPECT_EQ(timeouts.size(), 2u);
  EXPECT_EQ(asked.back(), at_ms(350));
  EXPECT_EQ(hc->next_deadline(), at_ms(350));
  set_entry(2, 2, 500);  // reconfigured: waits for its first heartbeat again
  EXPECT_EQ(hc->status(NodeId{2}), HeartbeatConsumer::Status::Waiting);
  EXPECT_FALSE(hc->next_deadline());
  hc->advance(at_ms(10'000));
  EXPECT_EQ(timeouts.size(), 2u);
  hb(2, 0x05, 10'000);
  EXPECT_EQ(hc->next_deadline(), at_ms(10'500));
  od.reset_to_defaults(0x1000, 0x1FFF);  // without observers: only the reload tells
  hc->reload();
  EXPECT_FALSE(hc->next_deadline());
}

TEST_F(ConsumerFixture, DuplicateFromUncheckedLoadMonitoredOnce) {
  // Values put in place without hooks (as a stored-parameter load does).
  ASSERT_EQ(set_entry(2, 7, 30), SdoAbortCode::None);  // stale entry for node 7 before the load
  od.find(0x1016, 1)->value = encode<std::uint32_t>(heartbeat_consumer_entry(NodeId{7}, 100));
  od.find(0x1016, 2)->value = encode<std::uint32_t>(heartbeat_consumer_entry(NodeId{7}, 50));
  hc->reload();
  hb(7, 0x05, 0);
  EXPECT_EQ(hc->next_deadline(), at_ms(100));
  hc->advance(at_ms(1000));
  EXPECT_EQ(timeouts, (std::vector<NodeId>{NodeId{7}}));
}

}  // namespace
