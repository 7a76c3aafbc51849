// LSS slave and master (CiA 305). Worked frames from the Novotechnik manual
// (004_965670f51e9c840d, chapter 6 "LSS / Layer Setting Service", §6.1 node-ID, §6.2 bit rate,
// §6.3 store configuration) and the elobau manual (000_499d7da4c768c72f, §7 "Baud rate /
// Node-ID": default node-ID 0x11, default 250 kbit/s, LSS-configurable).
#include "canopen/305/lss_fastscan.hpp"
#include "canopen/305/lss_master.hpp"
#include "canopen/305/lss_slave.hpp"
#include "canopen/305/lss_slowscan.hpp"

#include <gtest/gtest.h>

#include <vector>

#include "canopen/301/nmt_slave.hpp"

using namespace oegw::canopen;

namespace {

TimePoint at_ms(int ms) { return TimePoint{} + std::chrono::milliseconds(ms); }

// Novotechnik §6: the LSS address of the worked example (vendor 0x182 Novotechnik, product
// 0x0BE0, revision 0x00010003, serial 0x12345678).
constexpr lss::Address kNovotechnik{0x00000182, 0x00000BE0, 0x00010003, 0x12345678};

CanFrame m(std::initializer_list<std::uint8_t> b) { return CanFrame(0x7E5, b); }
CanFrame s(std::initializer_list<std::uint8_t> b) { return CanFrame(0x7E4, b); }

struct SlaveFixture : ::testing::Test {
  std::vector<CanFrame> sent;
  std::vector<NodeId> pending_ids;
  std::vector<std::uint8_t> pending_rates;
  std::vector<std::pair<std::uint8_t, Duration>> activations;
  std::vector<std::pair<NodeId, std::uint8_t>> stored;
  std::uint8_t store_result = 0;
  int nmt_starts = 0;
  std::unique_ptr<LssSlave> slave;

  void make(NodeId id, std::uint16_t supported = 0x01DF, bool with_store = true) {
    LssSlave::Callbacks cb;
    cb.on_pending_node_id = [this](NodeId n) { pending_ids.push_back(n); };
    cb.on_pending_bit_timing = [this](std::uint8_t i) { pending_rates.push_back(i); };
    cb.on_activate_bit_timing = [this](std::uint8_t i, Duration d) { activations.emplace_back(i, d); };
    if (with_store)
      cb.on_store = [this](NodeId n, std::uint8_t i) {
        stored.emplace_back(n, i);
        return store_result;
      };
    cb.on_start_nmt = [this] { ++nmt_starts; };
    slave = std::make_unique<LssSlave>(
        kNovotechnik, id, 3, [this](const CanFrame& f) { sent.push_back(f); }, std::move(cb), supported);
  }
  void SetUp() override { make(NodeId{0x11}); }
  bool feed(const CanFrame& f) { return slave->on_frame(f, at_ms(0)); }
};

// Novotechnik §6 "Switch Mode Selective" worked frames: 40h..43h on 7E5h, answer 44h on 7E4h.
TEST_F(SlaveFixture, NovotechnikSwitchModeSelective) {
  EXPECT_TRUE(feed(m({0x40, 0x82, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00})));
  EXPECT_TRUE(feed(m({0x41, 0xE0, 0x0B, 0x00, 0x00, 0x00, 0x00, 0x00})));
  EXPECT_TRUE(feed(m({0x42, 0x03, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00})));
  EXPECT_TRUE(sent.empty());
  EXPECT_EQ(slave->mode(), lss::Mode::Waiting);
  EXPECT_TRUE(feed(m({0x43, 0x78, 0x56, 0x34, 0x12, 0x00, 0x00, 0x00})));
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], s({0x44, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(slave->mode(), lss::Mode::Configuration);
}

TEST_F(SlaveFixture, SelectiveMismatchOrWrongOrderDoesNotSwitch) {
  feed(m({0x40, 0x82, 0x01, 0, 0, 0, 0, 0}));
  feed(m({0x41, 0xE0, 0x0B, 0, 0, 0, 0, 0}));
  feed(m({0x42, 0x03, 0x00, 0x01, 0, 0, 0, 0}));
  feed(m({0x43, 0x79, 0x56, 0x34, 0x12, 0, 0, 0}));  // other serial
  feed(m({0x41, 0xE0, 0x0B, 0, 0, 0, 0, 0}));        // product without vendor first
  feed(m({0x42, 0x03, 0x00, 0x01, 0, 0, 0, 0}));
  feed(m({0x43, 0x78, 0x56, 0x34, 0x12, 0, 0, 0}));
  EXPECT_TRUE(sent.empty());
  EXPECT_EQ(slave->mode(), lss::Mode::Waiting);
}

// Novotechnik §6 "Switch Mode Global": 7E5h 04 01 -> configuration (no answer); 04 00 (which
// the manual's first table mislabels as the NMT "stopped" command) -> back to waiting.
TEST_F(SlaveFixture, NovotechnikSwitchModeGlobal) {
  feed(m({0x04, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(slave->mode(), lss::Mode::Configuration);
  feed(m({0x04, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(slave->mode(), lss::Mode::Waiting);
  EXPECT_TRUE(sent.empty());
  EXPECT_EQ(nmt_starts, 0);  // it had a node-ID already
}

// Novotechnik §6.1: 7E5h 11 NID -> 7E4h 11 Err; Err 0 ok, 1 node-ID out of range (1..127).
TEST_F(SlaveFixture, NovotechnikConfigureNodeId) {
  feed(m({0x11, 0x20, 0, 0, 0, 0, 0, 0}));  // in waiting mode: ignored
  EXPECT_TRUE(sent.empty());
  feed(m({0x04, 0x01, 0, 0, 0, 0, 0, 0}));
  feed(m({0x11, 0x20, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}));
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], s({0x11, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(slave->pending_node_id(), NodeId{0x20});
  EXPECT_EQ(slave->active_node_id(), NodeId{0x11});  // effective at reset communication
  feed(m({0x11, 0x80, 0, 0, 0, 0, 0, 0}));
  feed(m({0x11, 0x00, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(sent[1], s({0x11, 0x01, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(sent[2], s({0x11, 0x01, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(slave->pending_node_id(), NodeId{0x20});
  EXPECT_EQ(pending_ids, (std::vector<NodeId>{NodeId{0x20}}));
  // Inquire node-ID (5Eh) answers the active one.
  feed(m({0x5E, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(sent[3], s({0x5E, 0x11, 0, 0, 0, 0, 0, 0}));
}

// Novotechnik §6.2: 7E5h 13 00 <table index> -> 7E4h 13 Err; table 0: 0=1000k, 1=800k,
// 2=500k, 3=250k, 4=125k, 6=50k. Err 1 = bit timing not supported.
TEST_F(SlaveFixture, NovotechnikConfigureBitTiming) {
  make(NodeId{0x11}, 0x005F);  // Novotechnik §6.2 lists 0,1,2,3,4,6 only
  feed(m({0x04, 0x01, 0, 0, 0, 0, 0, 0}));
  feed(m({0x13, 0x00, 0x04, 0x00, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(sent.back(), s({0x13, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(slave->pending_bit_timing(), 4);
  feed(m({0x13, 0x00, 0x07, 0, 0, 0, 0, 0}));  // 20k: not on this device
  EXPECT_EQ(sent.back(), s({0x13, 0x01, 0, 0, 0, 0, 0, 0}));
  feed(m({0x13, 0x00, 0x05, 0, 0, 0, 0, 0}));  // reserved index
  EXPECT_EQ(sent.back(), s({0x13, 0x01, 0, 0, 0, 0, 0, 0}));
  feed(m({0x13, 0x01, 0x02, 0, 0, 0, 0, 0}));  // table selector 1: not supported
  EXPECT_EQ(sent.back(), s({0x13, 0x01, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(slave->pending_bit_timing(), 4);
  EXPECT_EQ(pending_rates, (std::vector<std::uint8_t>{4}));
  // Activate bit timing 15h with a 200 ms switch delay: no answer, the owner switches.
  feed(m({0x15, 0xC8, 0x00, 0, 0, 0, 0, 0}));
  EXPECT_EQ(sent.size(), 4u);
  ASSERT_EQ(activations.size(), 1u);
  EXPECT_EQ(activations[0].first, 4);
  EXPECT_EQ(activations[0].second, std::chrono::milliseconds(200));
}

TEST(LssBitTiming, StandardTable) {
  EXPECT_EQ(lss::standard_bit_rate_kbit(0), 1000);
  EXPECT_EQ(lss::standard_bit_rate_kbit(1), 800);
  EXPECT_EQ(lss::standard_bit_rate_kbit(2), 500);
  EXPECT_EQ(lss::standard_bit_rate_kbit(3), 250);
  EXPECT_EQ(lss::standard_bit_rate_kbit(4), 125);
  EXPECT_FALSE(lss::standard_bit_rate_kbit(5));
  EXPECT_EQ(lss::standard_bit_rate_kbit(6), 50);
  EXPECT_EQ(lss::standard_bit_rate_kbit(7), 20);
  EXPECT_EQ(lss::standard_bit_rate_kbit(8), 10);
  EXPECT_FALSE(lss::standard_bit_rate_kbit(9));
}

// Novotechnik §6.3: 7E5h 17 -> 7E4h 17 Err; Err 0 ok, 2 storage media access error.
TEST_F(SlaveFixture, NovotechnikStoreConfiguration) {
  feed(m({0x04, 0x01, 0, 0, 0, 0, 0, 0}));
  feed(m({0x11, 0x22, 0, 0, 0, 0, 0, 0}));
  feed(m({0x17, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(sent.back(), s({0x17, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}));
  ASSERT_EQ(stored.size(), 1u);
  EXPECT_EQ(stored[0], std::make_pair(NodeId{0x22}, std::uint8_t{3}));
  store_result = 2;
  feed(m({0x17, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(sent.back(), s({0x17, 0x02, 0, 0, 0, 0, 0, 0}));
  make(NodeId{0x11}, 0x01DF, false);  // no storage: error 1 "not supported"
  feed(m({0x04, 0x01, 0, 0, 0, 0, 0, 0}));
  feed(m({0x17, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(sent.back(), s({0x17, 0x01, 0, 0, 0, 0, 0, 0}));
}

TEST_F(SlaveFixture, InquireIdentity) {
  feed(m({0x5A, 0, 0, 0, 0, 0, 0, 0}));  // waiting: no answer
  EXPECT_TRUE(sent.empty());
  feed(m({0x04, 0x01, 0, 0, 0, 0, 0, 0}));
  feed(m({0x5A, 0, 0, 0, 0, 0, 0, 0}));
  feed(m({0x5B, 0, 0, 0, 0, 0, 0, 0}));
  feed(m({0x5C, 0, 0, 0, 0, 0, 0, 0}));
  feed(m({0x5D, 0, 0, 0, 0, 0, 0, 0}));
  ASSERT_EQ(sent.size(), 4u);
  EXPECT_EQ(sent[0], s({0x5A, 0x82, 0x01, 0x00, 0x00, 0, 0, 0}));
  EXPECT_EQ(sent[1], s({0x5B, 0xE0, 0x0B, 0x00, 0x00, 0, 0, 0}));
  EXPECT_EQ(sent[2], s({0x5C, 0x03, 0x00, 0x01, 0x00, 0, 0, 0}));
  EXPECT_EQ(sent[3], s({0x5D, 0x78, 0x56, 0x34, 0x12, 0, 0, 0}));
}

TEST_F(SlaveFixture, IdentifyRemoteSlaveByRange) {
  auto ident = [&](std::uint32_t rl, std::uint32_t rh, std::uint32_t sl, std::uint32_t sh) {
    const std::uint32_t v[6] = {0x182, 0x0BE0, rl, rh, sl, sh};
    for (std::uint8_t i = 0; i < 6; ++i) {
      CanFrame f = m({static_cast<std::uint8_t>(0x46 + i), 0, 0, 0, 0, 0, 0, 0});
      put_u32(&f.data[1], v[i]);
      feed(f);
    }
  };
  ident(0x00010000, 0x0001FFFF, 0x12340000, 0x1234FFFF);
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], s({0x4F, 0, 0, 0, 0, 0, 0, 0}));
  ident(0x00020000, 0x0002FFFF, 0, 0xFFFFFFFF);  // revision outside
  ident(0, 0xFFFFFFFF, 0x12345679, 0xFFFFFFFF);  // serial outside
  EXPECT_EQ(sent.size(), 1u);
}

TEST_F(SlaveFixture, UnconfiguredSlaveIdentifiesAndStartsNmtAfterConfiguration) {
  make(NodeId::unconfigured_id());
  feed(m({0x4C, 0, 0, 0, 0, 0, 0, 0}));
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], s({0x50, 0, 0, 0, 0, 0, 0, 0}));
  feed(m({0x04, 0x01, 0, 0, 0, 0, 0, 0}));
  feed(m({0x11, 0x11, 0, 0, 0, 0, 0, 0}));
  feed(m({0x4C, 0, 0, 0, 0, 0, 0, 0}));  // has a pending node-ID now: silent
  EXPECT_EQ(sent.size(), 2u);
  feed(m({0x04, 0x00, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(nmt_starts, 1);
}

// CiA 305 §8.4.4 fastscan, the slave's side, on the Novotechnik example address: only a waiting
// slave without node-ID takes part; 80h resets and is answered; a step is answered when the
// bits BitChecked..31 of the part at LSSSub match; bit 0 with LSSNext < LSSSub selects it.
TEST_F(SlaveFixture, FastscanOnlyANodeWithoutNodeIdAnswers) {
  feed(m({0x51, 0, 0, 0, 0, 0x80, 0, 0}));
  EXPECT_TRUE(sent.empty());  // node-ID 11h: not part of fastscan
  make(NodeId::unconfigured_id());
  feed(m({0x51, 0, 0, 0, 0, 0x80, 0, 0}));
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], s({0x4F, 0, 0, 0, 0, 0, 0, 0}));
  // Vendor 00000182h: bits 31..9 are 0 (answered), bit 8 asked as 0 is not its value (silent).
  feed(m({0x51, 0, 0, 0, 0, 9, 0, 0}));
  EXPECT_EQ(sent.size(), 2u);
  feed(m({0x51, 0, 0, 0, 0, 8, 0, 0}));
  EXPECT_EQ(sent.size(), 2u);
  // The whole vendor-ID at bit 0, LSSNext 1: answered, the slave moves on to the product code.
  feed(m({0x51, 0x82, 0x01, 0, 0, 0, 0, 1}));
  EXPECT_EQ(sent.size(), 3u);
  feed(m({0x51, 0x82, 0x01, 0, 0, 0, 0, 1}));  // not at the vendor-ID any more: silent
  EXPECT_EQ(sent.size(), 3u);
  feed(m({0x51, 0xE0, 0x0B, 0, 0, 0, 1, 2}));
  feed(m({0x51, 0x03, 0x00, 0x01, 0x00, 0, 2, 3}));
  EXPECT_EQ(slave->mode(), lss::Mode::Waiting);
  feed(m({0x51, 0x78, 0x56, 0x34, 0x12, 0, 3, 0}));  // the serial, LSSNext 0 < 3: selected
  EXPECT_EQ(sent.size(), 6u);
  EXPECT_EQ(slave->mode(), lss::Mode::Configuration);
  feed(m({0x51, 0, 0, 0, 0, 0x80, 0, 0}));  // in configuration mode: not part of fastscan
  EXPECT_EQ(sent.size(), 6u);
  feed(m({0x04, 0x00, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(nmt_starts, 0);               // back to waiting without a node-ID: NMT does not start
  feed(m({0x51, 0, 0, 0, 0, 32, 0, 0}));  // BitChecked 32: out of range
  feed(m({0x51, 0, 0, 0, 0, 0, 4, 0}));   // LSSSub 4: out of range
  EXPECT_EQ(sent.size(), 6u);
  EXPECT_EQ(slave->stats().malformed, 2u);
}

TEST_F(SlaveFixture, MalformedFramesCounted) {
  feed(m({0x04, 0x01}));
  feed(m({0x04, 0x01, 0, 0, 0, 0, 0, 0, 0}));  // >8 bytes: CanFrame keeps 8 -> well formed
  EXPECT_EQ(slave->mode(), lss::Mode::Configuration);
  feed(m({0x04, 0x00, 0, 0, 0, 0, 0}));  // DLC 7
  EXPECT_TRUE(slave->on_frame(CanFrame::remote(0x7E5, 8), at_ms(0)));
  EXPECT_FALSE(slave->on_frame(CanFrame(0x7E4, {0x04, 0x00, 0, 0, 0, 0, 0, 0}), at_ms(0)));
  EXPECT_EQ(slave->mode(), lss::Mode::Configuration);
  EXPECT_EQ(slave->stats().malformed, 3u);
  feed(m({0x99, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(slave->stats().unknown, 1u);
}

// The full path: LSS sets node-ID 0x20 while the node runs as 0x11 (elobau default); the new
// ID appears only after NMT reset communication (CiA 305), with a boot-up on 0x720.
TEST(LssWithNmt, NodeIdTakesEffectAtResetCommunication) {
  std::vector<CanFrame> bus;
  NmtSlave nmt(NodeId{0x11}, [&](const CanFrame& f) { bus.push_back(f); });
  LssSlave::Callbacks cb;
  cb.on_pending_node_id = [&](NodeId n) { nmt.set_pending_node_id(n); };
  LssSlave lss_slave(
      kNovotechnik, NodeId{0x11}, 3, [&](const CanFrame& f) { bus.push_back(f); }, cb);
  nmt.on_reset([&](bool) { lss_slave.set_active_node_id(nmt.pending_node_id()); });
  nmt.start(at_ms(0));
  lss_slave.on_frame(m({0x04, 0x01, 0, 0, 0, 0, 0, 0}), at_ms(1));
  lss_slave.on_frame(m({0x11, 0x20, 0, 0, 0, 0, 0, 0}), at_ms(2));
  lss_slave.on_frame(m({0x04, 0x00, 0, 0, 0, 0, 0, 0}), at_ms(3));
  EXPECT_EQ(nmt.node_id(), NodeId{0x11});
  nmt.on_frame(CanFrame(0, {0x82, 0x11}), at_ms(4));
  EXPECT_EQ(nmt.node_id(), NodeId{0x20});
  EXPECT_EQ(lss_slave.active_node_id(), NodeId{0x20});
  EXPECT_EQ(bus.back(), CanFrame(0x720, {0x00}));
}

// ------------------------------------------------------------------ master

struct MasterFixture : ::testing::Test {
  std::vector<CanFrame> sent;
  std::vector<LssMaster::Result> results;
  LssMaster master{[this](const CanFrame& f) { sent.push_back(f); }, std::chrono::milliseconds(100)};
  LssMaster::Callback record() {
    return [this](const LssMaster::Result& r) { results.push_back(r); };
  }
};

// The master emits exactly the Novotechnik §6 worked frames.
TEST_F(MasterFixture, SendsNovotechnikFrames) {
  master.switch_state_selective(kNovotechnik, at_ms(0), record());
  ASSERT_EQ(sent.size(), 4u);
  EXPECT_EQ(sent[0], m({0x40, 0x82, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(sent[1], m({0x41, 0xE0, 0x0B, 0x00, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(sent[2], m({0x42, 0x03, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(sent[3], m({0x43, 0x78, 0x56, 0x34, 0x12, 0x00, 0x00, 0x00}));
  master.configure_node_id(NodeId{0x20}, at_ms(0), record());
  EXPECT_EQ(sent.size(), 4u);  // queued behind the selective switch
  EXPECT_TRUE(master.on_frame(s({0x44, 0, 0, 0, 0, 0, 0, 0}), at_ms(5)));
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].status, LssMaster::Status::Ok);
  ASSERT_EQ(sent.size(), 5u);
  EXPECT_EQ(sent[4], m({0x11, 0x20, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(master.next_deadline(), at_ms(105));  // timeout counted from when it was sent
  master.on_frame(s({0x11, 0x01, 0, 0, 0, 0, 0, 0}), at_ms(10));
  EXPECT_EQ(results[1].status, LssMaster::Status::Refused);
  EXPECT_EQ(results[1].error, 1);
  master.configure_bit_timing(3, at_ms(20), record());
  EXPECT_EQ(sent.back(), m({0x13, 0x00, 0x03, 0, 0, 0, 0, 0}));
  master.on_frame(s({0x13, 0x00, 0, 0, 0, 0, 0, 0}), at_ms(21));
  master.store_configuration(at_ms(22), record());
  EXPECT_EQ(sent.back(), m({0x17, 0, 0, 0, 0, 0, 0, 0}));
  master.on_frame(s({0x17, 0x02, 0, 0, 0, 0, 0, 0}), at_ms(23));
  EXPECT_EQ(results[3].status, LssMaster::Status::Refused);
  EXPECT_EQ(results[3].error, 2);
  master.switch_state_global(lss::Mode::Configuration, at_ms(24), record());
  EXPECT_EQ(sent.back(), m({0x04, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(results.size(), 5u);  // no answer expected: done when sent
  master.activate_bit_timing(200, at_ms(25), record());
  EXPECT_EQ(sent.back(), m({0x15, 0xC8, 0x00, 0, 0, 0, 0, 0}));
  EXPECT_TRUE(master.idle());
}

TEST_F(MasterFixture, TimeoutThenNextRequestRuns) {
  master.inquire(LssMaster::Inquiry::NodeId, at_ms(0), record());
  master.inquire(LssMaster::Inquiry::Vendor, at_ms(0), record());
  EXPECT_EQ(master.pending(), 2u);
  master.advance(at_ms(99));
  EXPECT_TRUE(results.empty());
  master.advance(at_ms(100));
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].status, LssMaster::Status::Timeout);
  EXPECT_EQ(sent.back(), m({0x5A, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_TRUE(master.on_frame(s({0x5E, 0x11, 0, 0, 0, 0, 0, 0}), at_ms(101)));  // stale answer: dropped
  EXPECT_EQ(results.size(), 1u);
  master.on_frame(s({0x5A, 0x82, 0x01, 0, 0, 0, 0, 0}), at_ms(102));
  ASSERT_EQ(results.size(), 2u);
  EXPECT_EQ(results[1].value, 0x182u);
  EXPECT_FALSE(master.next_deadline());
  EXPECT_FALSE(master.on_frame(m({0x5A, 0, 0, 0, 0, 0, 0, 0}), at_ms(103)));
}

TEST_F(MasterFixture, IdentifySilenceMeansNoAnswer) {
  master.identify_non_configured(at_ms(0), record());
  master.advance(at_ms(100));
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].status, LssMaster::Status::NoAnswer);
}

// A fastscan step lasts its whole timeout: several slaves may answer, and a late answer must
// not complete the next step.
TEST_F(MasterFixture, FastscanStepCollectsAnswersUntilTheTimeout) {
  master.fastscan(0x00000182, 8, 0, 0, at_ms(0), record());
  EXPECT_EQ(sent.back(), m({0x51, 0x82, 0x01, 0, 0, 8, 0, 0}));
  master.fastscan(0x00000182, 7, 0, 0, at_ms(0), record());
  master.on_frame(s({0x4F, 0, 0, 0, 0, 0, 0, 0}), at_ms(1));
  master.on_frame(s({0x4F, 0, 0, 0, 0, 0, 0, 0}), at_ms(2));
  EXPECT_TRUE(results.empty());
  master.advance(at_ms(100));
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].status, LssMaster::Status::Ok);
  EXPECT_EQ(sent.back(), m({0x51, 0x82, 0x01, 0, 0, 7, 0, 0}));
  master.advance(at_ms(200));
  ASSERT_EQ(results.size(), 2u);
  EXPECT_EQ(results[1].status, LssMaster::Status::NoAnswer);
}

// Master and slave wired back to back through the whole Novotechnik sequence.
TEST(LssMasterSlave, ConfigureThroughBothEnds) {
  std::vector<CanFrame> to_master;
  LssSlave::Callbacks cb;
  std::optional<std::pair<NodeId, std::uint8_t>> persisted;
  cb.on_store = [&](NodeId n, std::uint8_t i) {
    persisted = {n, i};
    return std::uint8_t{0};
  };
  LssSlave slave(
      kNovotechnik, NodeId{0x7F}, 3, [&](const CanFrame& f) { to_master.push_back(f); }, cb);
  LssMaster master([&](const CanFrame& f) { slave.on_frame(f, at_ms(0)); });
  auto deliver = [&] {
    while (!to_master.empty()) {
      const CanFrame f = to_master.front();
      to_master.erase(to_master.begin());
      master.on_frame(f, at_ms(1));
    }
  };
  std::vector<LssMaster::Status> st;
  std::uint32_t node = 0;
  auto rec = [&](const LssMaster::Result& r) { st.push_back(r.status); };
  master.switch_state_selective(kNovotechnik, at_ms(0), rec);
  master.configure_node_id(NodeId{0x11}, at_ms(0), rec);
  master.configure_bit_timing(4, at_ms(0), rec);
  master.store_configuration(at_ms(0), rec);
  master.inquire(LssMaster::Inquiry::NodeId, at_ms(0), [&](const LssMaster::Result& r) { node = r.value; });
  master.switch_state_global(lss::Mode::Waiting, at_ms(0), rec);
  for (int i = 0; i < 10 && !master.idle(); ++i) deliver();
  EXPECT_TRUE(master.idle());
  EXPECT_EQ(st, std::vector<LssMaster::Status>(5, LssMaster::Status::Ok));
  ASSERT_TRUE(persisted);
  EXPECT_EQ(persisted->first, NodeId{0x11});
  EXPECT_EQ(persisted->second, 4);
  EXPECT_EQ(node, 0x7Fu);  // still the active one
  EXPECT_EQ(slave.mode(), lss::Mode::Waiting);
}

// ------------------------------------------------------------------ fastscan (master side)

// LssFastscan through an LssMaster against LssSlave (the independent slave side), on a simulated
// clock: the slave's answers reach the master 1 ms after each request, each step lasts the step
// time-out.
struct FastscanBench {
  std::vector<CanFrame> wire;  // every frame, both directions, in order
  std::vector<CanFrame> to_master;
  std::vector<std::unique_ptr<LssSlave>> slaves;
  TimePoint now{};
  LssMaster master{[this](const CanFrame& f) {
                     wire.push_back(f);
                     for (auto& sl : slaves) sl->on_frame(f, now);
                   },
                   std::chrono::milliseconds(10)};
  LssFastscan fastscan{master};
  LssSlowscan slowscan{master};
  void add(const lss::Address& a, NodeId id) {
    slaves.push_back(std::make_unique<LssSlave>(a, id, 3, [this](const CanFrame& f) {
      wire.push_back(f);
      to_master.push_back(f);
    }));
  }
  void run() {
    for (int i = 0; i < 1000 && !master.idle(); ++i) {
      const auto answers = std::exchange(to_master, {});
      for (const auto& f : answers) master.on_frame(f, now + std::chrono::milliseconds(1));
      if (const auto d = master.next_deadline()) {
        now = *d;
        master.advance(now);
      }
    }
  }
  std::size_t count(std::uint8_t cs) const {
    return static_cast<std::size_t>(
        std::count_if(wire.begin(), wire.end(), [cs](const CanFrame& f) { return f.id == 0x7E5 && f.data[0] == cs; }));
  }
};

// CiA 305 §8.4.4 frame by frame: the reset step 51h with BitChecked 80h, then per part bits 31..1
// (IDNumber so far, BitChecked, LSSSub = LSSNext = the part), bit 0 with LSSNext the next part; every
// matching step answered 4Fh on 7E4h. The slave ends selected (LSS configuration mode).
TEST(LssFastscanTest, ReadsTheAddressOfTheNodeWithoutNodeIdAndLeavesItSelected) {
  FastscanBench b;
  b.add(kNovotechnik, NodeId::unconfigured_id());
  b.add({0x182, 0x0BE0, 0x00010003, 0x1}, NodeId{0x11});  // has a node-ID: takes no part
  std::optional<LssFastscan::Result> got;
  b.fastscan.start(b.now, [&](const LssFastscan::Result& r) { got = r; });
  EXPECT_TRUE(b.fastscan.running());
  ASSERT_FALSE(b.wire.empty());
  EXPECT_EQ(b.wire[0], m({0x51, 0, 0, 0, 0, 0x80, 0, 0}));
  EXPECT_EQ(b.master.next_deadline(), at_ms(10));
  b.run();
  ASSERT_TRUE(got);
  EXPECT_EQ(got->outcome, LssFastscan::Outcome::Found) << got->note;
  EXPECT_EQ(got->address, kNovotechnik);
  EXPECT_FALSE(b.fastscan.running());
  EXPECT_EQ(b.slaves[0]->mode(), lss::Mode::Configuration);
  EXPECT_EQ(b.slaves[1]->mode(), lss::Mode::Waiting);
  // The second step: vendor part, bit 31 asked with IDNumber 0 (answered: the bit is 0).
  EXPECT_EQ(b.wire[1], s({0x4F, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(b.wire[2], m({0x51, 0, 0, 0, 0, 31, 0, 0}));
  EXPECT_EQ(b.wire[3], s({0x4F, 0, 0, 0, 0, 0, 0, 0}));
  // The last step: the serial confirmed with LSSNext 0.
  const auto last = std::find_if(b.wire.rbegin(), b.wire.rend(), [](const CanFrame& f) { return f.id == 0x7E5; });
  EXPECT_EQ(*last, m({0x51, 0x78, 0x56, 0x34, 0x12, 0, 3, 0}));
  // 1 reset + 4 × 31 bits + 4 confirmations, and one retry of bit 0 per part that ends in 1
  // (product 0BE0h and serial 12345678h end in 0, vendor 182h in 0, revision 00010003h in 1).
  EXPECT_EQ(b.count(0x51), 1u + 4 * 31 + 4 + 1);
  EXPECT_LE(b.count(0x51), std::size_t{LssFastscan::kMaxSteps});
}

TEST(LssFastscanTest, NoNodeWithoutNodeIdNoAnswerAfterOneStep) {
  FastscanBench b;
  b.add(kNovotechnik, NodeId{0x11});
  std::optional<LssFastscan::Result> got;
  b.fastscan.start(
      b.now, [&](const LssFastscan::Result& r) { got = r; }, std::chrono::milliseconds(250));
  EXPECT_EQ(b.master.next_deadline(), at_ms(250));  // the step's own time-out
  b.run();
  ASSERT_TRUE(got);
  EXPECT_EQ(got->outcome, LssFastscan::Outcome::NoAnswer);
  EXPECT_FALSE(got->address);
  EXPECT_EQ(b.count(0x51), 1u);
  EXPECT_EQ(b.now, at_ms(250));
}

TEST(LssFastscanTest, CancelEndsItAndSendsNoFurtherStep) {
  FastscanBench b;
  b.add(kNovotechnik, NodeId::unconfigured_id());
  std::vector<LssFastscan::Result> got;
  b.fastscan.start(b.now, [&](const LssFastscan::Result& r) { got.push_back(r); });
  b.fastscan.cancel("the gateway needs the LSS master");
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].outcome, LssFastscan::Outcome::Cancelled);
  EXPECT_EQ(got[0].note, "the gateway needs the LSS master");
  b.run();  // the reset step on the wire ends; nothing follows it
  EXPECT_EQ(got.size(), 1u);
  EXPECT_EQ(b.count(0x51), 1u);
  EXPECT_TRUE(b.master.idle());
}

// lely's `_lss_fastscan` with values and masks (its test session: "0 0xffff0000 0 0xffffffff ..."):
// known bits are not asked. Vendor 182h with its upper 16 bits known (0): bits 15..1 asked, bit 0
// confirmed; product, revision and serial wholly known: only their confirmations.
TEST(LssFastscanTest, KnownBitsAreNotAsked) {
  FastscanBench b;
  b.add(kNovotechnik, NodeId::unconfigured_id());
  std::optional<LssFastscan::Result> got;
  LssFastscan::Known known{{0, kNovotechnik.product, kNovotechnik.revision, kNovotechnik.serial},
                           {0xFFFF0000, 0xFFFFFFFF, 0xFFFFFFFF, 0xFFFFFFFF}};
  b.fastscan.start(
      b.now, [&](const LssFastscan::Result& r) { got = r; }, std::nullopt, known);
  b.run();
  ASSERT_TRUE(got);
  EXPECT_EQ(got->outcome, LssFastscan::Outcome::Found) << got->note;
  EXPECT_EQ(got->address, kNovotechnik);
  EXPECT_EQ(b.count(0x51), 1u + 15 + 1 + 3);
  EXPECT_EQ(b.slaves[0]->mode(), lss::Mode::Configuration);
  // The product's confirmation: the whole known value, BitChecked 0, LSSSub 1, LSSNext 2.
  EXPECT_NE(std::find(b.wire.begin(), b.wire.end(), m({0x51, 0xE0, 0x0B, 0, 0, 0, 1, 2})), b.wire.end());
}

TEST(LssFastscanTest, KnownBitsNobodyHasEndWithoutAddress) {
  FastscanBench b;
  b.add(kNovotechnik, NodeId::unconfigured_id());
  std::optional<LssFastscan::Result> got;
  LssFastscan::Known known{{0, 0, 0, 0x0BAD}, {0, 0, 0, 0xFFFFFFFF}};  // a serial it does not have
  b.fastscan.start(
      b.now, [&](const LssFastscan::Result& r) { got = r; }, std::nullopt, known);
  b.run();
  ASSERT_TRUE(got);
  EXPECT_EQ(got->outcome, LssFastscan::Outcome::Lost);
  EXPECT_EQ(got->note, "LSS fastscan: no node without node-ID has the known bits of the serial number");
  EXPECT_EQ(b.slaves[0]->mode(), lss::Mode::Waiting);
}

// lely's `_lss_slowscan`: identify remote slave (46h..4Bh) over halves of the revision, then the
// serial range, the lower half first; then switch state selective (40h..43h, answered 44h).
// Two slaves in the range (a node-ID does not matter): the lower address is found and selected.
TEST(LssSlowscanTest, FindsTheLowerAddressInTheRangeAndSelectsIt) {
  FastscanBench b;
  const lss::Address high{0x182, 0x0BE0, 0x00010003, 0x12345678}, low{0x182, 0x0BE0, 0x00010003, 0x1};
  b.add(high, NodeId::unconfigured_id());
  b.add(low, NodeId{0x11});
  std::optional<LssSlowscan::Result> got;
  b.slowscan.start({0x182, 0x0BE0, 0, 0xFFFFFFFF, 0, 0xFFFFFFFF}, b.now,
                   [&](const LssSlowscan::Result& r) { got = r; });
  // The first step: the whole range (CiA 305 §8.4.3.6: vendor, product, revision low/high, serial low/high).
  ASSERT_GE(b.wire.size(), 6u);
  EXPECT_EQ(b.wire[0], m({0x46, 0x82, 0x01, 0, 0, 0, 0, 0}));
  EXPECT_EQ(b.wire[3], m({0x49, 0xFF, 0xFF, 0xFF, 0xFF, 0, 0, 0}));
  b.run();
  ASSERT_TRUE(got);
  EXPECT_EQ(got->outcome, LssSlowscan::Outcome::Found) << got->note;
  EXPECT_EQ(got->address, low);
  EXPECT_EQ(b.slaves[1]->mode(), lss::Mode::Configuration);
  EXPECT_EQ(b.slaves[0]->mode(), lss::Mode::Waiting);
  EXPECT_EQ(b.count(0x46), 1u + 32 + 32);
  EXPECT_EQ(b.count(0x40), 1u);
  EXPECT_LE(b.count(0x46) + b.count(0x40), std::size_t{LssSlowscan::kMaxSteps});
  // Every identify step lasted its whole time-out (10 ms): a late answer is not the next step's.
  EXPECT_GE(b.now, at_ms(65 * 10));
}

TEST(LssSlowscanTest, NobodyInTheRangeNoAnswerAfterOneStep) {
  FastscanBench b;
  b.add(kNovotechnik, NodeId::unconfigured_id());
  std::optional<LssSlowscan::Result> got;
  b.slowscan.start({0x360, 0, 0, 0, 0, 0}, b.now, [&](const LssSlowscan::Result& r) { got = r; });
  b.run();
  ASSERT_TRUE(got);
  EXPECT_EQ(got->outcome, LssSlowscan::Outcome::NoAnswer);
  EXPECT_EQ(b.count(0x46), 1u);
  EXPECT_EQ(b.count(0x40), 0u);
}

}  // namespace
