// NMT slave/master (CiA 301 §7.2.8, §7.3.2). Vectors from the elobau MFG 34xG/36xG manual
// (000_499d7da4c768c72f, §6 "Network Management", §11 "Heartbeat": boot-up/heartbeat is
// 700h+node-ID carrying the NMT state; default node-ID 0x11).
#include "canopen/301/nmt_master.hpp"
#include "canopen/301/nmt_slave.hpp"

#include <gtest/gtest.h>

#include <vector>

using namespace oegw::canopen;

namespace {

TimePoint at_ms(int ms) { return TimePoint{} + std::chrono::milliseconds(ms); }

struct NmtFixture : ::testing::Test {
  std::vector<CanFrame> sent;
  std::vector<NmtState> states;
  std::vector<bool> resets;
  NmtSlave nmt{NodeId{0x11}, [this](const CanFrame& f) { sent.push_back(f); }};

  void SetUp() override {
    nmt.on_state_change([this](NmtState s) { states.push_back(s); });
    nmt.on_reset([this](bool comm) { resets.push_back(comm); });
  }
  bool feed(std::initializer_list<std::uint8_t> bytes, int ms = 0) {
    return nmt.on_frame(CanFrame(cob::kNmt, bytes), at_ms(ms));
  }
};

// elobau §6 / §11: after power-on the node sends its boot-up 0x711 `00` (default node 0x11)
// and is pre-operational.
TEST_F(NmtFixture, BootUpFrameThenPreOperational) {
  EXPECT_EQ(nmt.state(), NmtState::Initialisation);
  nmt.start(at_ms(0));
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], CanFrame(0x711, {0x00}));
  EXPECT_EQ(nmt.state(), NmtState::PreOperational);
  EXPECT_EQ(states, (std::vector<NmtState>{NmtState::Initialisation, NmtState::PreOperational}));
}

// elobau §6.1.1–6.1.3: start, stop, enter pre-operational.
TEST_F(NmtFixture, StartStopPreOpAddressedAndBroadcast) {
  nmt.start(at_ms(0));
  EXPECT_TRUE(feed({0x01, 0x11}, 1));
  EXPECT_EQ(nmt.state(), NmtState::Operational);
  EXPECT_EQ(nmt.last_transition(), at_ms(1));
  EXPECT_TRUE(feed({0x02, 0x00}, 2));  // node 0 = all
  EXPECT_EQ(nmt.state(), NmtState::Stopped);
  EXPECT_TRUE(feed({0x01, 0x12}, 3));  // another node
  EXPECT_EQ(nmt.state(), NmtState::Stopped);
  EXPECT_EQ(nmt.stats().other_node, 1u);
  EXPECT_TRUE(feed({0x80, 0x11}, 4));
  EXPECT_EQ(nmt.state(), NmtState::PreOperational);
  EXPECT_TRUE(feed({0x80, 0x11}, 5));  // no change, no callback
  EXPECT_EQ(states.back(), NmtState::PreOperational);
  EXPECT_EQ(states.size(), 5u);  // Init, PreOp, Op, Stopped, PreOp
  EXPECT_EQ(nmt.stats().commands, 4u);
  EXPECT_EQ(sent.size(), 1u);  // only the boot-up
}

// elobau §6.1.4/§6.1.5: reset node / reset communication go through Initialisation, tell the
// owner which kind of reset (so it restores the right objects) and boot up again.
TEST_F(NmtFixture, ResetsCallOwnerThenBootUpAgain) {
  nmt.start(at_ms(0));
  feed({0x01, 0x11});
  nmt.on_reset([this](bool comm) {
    resets.push_back(comm);
    EXPECT_EQ(nmt.state(), NmtState::Initialisation);
    EXPECT_EQ(sent.size(), 1u + resets.size() - 1);  // boot-up not sent yet
  });
  feed({0x82, 0x11});
  EXPECT_EQ(resets, (std::vector<bool>{true}));
  EXPECT_EQ(nmt.state(), NmtState::PreOperational);
  ASSERT_EQ(sent.size(), 2u);
  EXPECT_EQ(sent[1], CanFrame(0x711, {0x00}));
  feed({0x81, 0x00});
  EXPECT_EQ(resets, (std::vector<bool>{true, false}));
  ASSERT_EQ(sent.size(), 3u);
  EXPECT_EQ(sent[2], CanFrame(0x711, {0x00}));
}

TEST_F(NmtFixture, PendingNodeIdBecomesActiveAtResetCommunication) {
  nmt.start(at_ms(0));
  nmt.set_pending_node_id(NodeId{0x20});
  EXPECT_EQ(nmt.node_id(), NodeId{0x11});
  feed({0x01, 0x20});  // not yet addressed by the new ID
  EXPECT_EQ(nmt.state(), NmtState::PreOperational);
  feed({0x82, 0x11});
  EXPECT_EQ(nmt.node_id(), NodeId{0x20});
  EXPECT_EQ(sent.back(), CanFrame(0x720, {0x00}));
  feed({0x01, 0x20});
  EXPECT_EQ(nmt.state(), NmtState::Operational);
}

TEST_F(NmtFixture, MalformedFramesAreCountedAndIgnored) {
  nmt.start(at_ms(0));
  EXPECT_TRUE(feed({0x01}));
  EXPECT_TRUE(feed({0x01, 0x11, 0x00}));
  EXPECT_TRUE(feed({}));
  EXPECT_TRUE(nmt.on_frame(CanFrame::remote(0x000, 2), at_ms(0)));
  EXPECT_TRUE(feed({0x03, 0x11}));  // unknown command specifier
  EXPECT_EQ(nmt.state(), NmtState::PreOperational);
  EXPECT_EQ(nmt.stats().malformed, 4u);
  EXPECT_EQ(nmt.stats().unknown_command, 1u);
  EXPECT_FALSE(nmt.on_frame(CanFrame(0x001, {0x01, 0x11}), at_ms(0)));
  EXPECT_FALSE(nmt.next_deadline().has_value());
}

TEST(NmtSlave, UnconfiguredNodeStaysInInitialisation) {
  std::vector<CanFrame> sent;
  NmtSlave nmt(NodeId::unconfigured_id(), [&](const CanFrame& f) { sent.push_back(f); });
  nmt.start(at_ms(0));
  EXPECT_TRUE(sent.empty());
  nmt.on_frame(CanFrame(0, {0x01, 0x00}), at_ms(1));
  EXPECT_EQ(nmt.state(), NmtState::Initialisation);
  nmt.set_pending_node_id(NodeId{5});
  nmt.reset(true, at_ms(2));
  EXPECT_EQ(nmt.state(), NmtState::PreOperational);
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], CanFrame(0x705, {0x00}));
}

TEST(NmtMaster, SendsCommandsToOneNodeOrAll) {
  std::vector<CanFrame> sent;
  NmtMaster m([&](const CanFrame& f) { sent.push_back(f); });
  EXPECT_TRUE(m.start(NodeId{0x11}));
  EXPECT_TRUE(m.stop(NmtMaster::kAllNodes));
  EXPECT_TRUE(m.enter_pre_operational(NodeId{1}));
  EXPECT_TRUE(m.reset_node(NodeId{127}));
  EXPECT_TRUE(m.reset_communication(NmtMaster::kAllNodes));
  EXPECT_FALSE(m.start(NodeId{128}));
  ASSERT_EQ(sent.size(), 5u);
  EXPECT_EQ(sent[0], CanFrame(0x000, {0x01, 0x11}));
  EXPECT_EQ(sent[1], CanFrame(0x000, {0x02, 0x00}));
  EXPECT_EQ(sent[2], CanFrame(0x000, {0x80, 0x01}));
  EXPECT_EQ(sent[3], CanFrame(0x000, {0x81, 0x7F}));
  EXPECT_EQ(sent[4], CanFrame(0x000, {0x82, 0x00}));
}

TEST(NmtMasterSlave, MasterDrivesSlave) {
  std::vector<CanFrame> bus;
  NmtSlave nmt(NodeId{3}, [&](const CanFrame& f) { bus.push_back(f); });
  NmtMaster m([&](const CanFrame& f) { nmt.on_frame(f, at_ms(0)); });
  nmt.start(at_ms(0));
  m.start(NodeId{3});
  EXPECT_EQ(nmt.state(), NmtState::Operational);
  m.stop(NmtMaster::kAllNodes);
  EXPECT_EQ(nmt.state(), NmtState::Stopped);
  m.reset_communication(NodeId{3});
  EXPECT_EQ(nmt.state(), NmtState::PreOperational);
  EXPECT_EQ(bus.size(), 2u);
}

}  // namespace
