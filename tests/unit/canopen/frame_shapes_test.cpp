// Robustness: the NMT slave, LSS slave and LSS master fed every frame shape — DLC 0..8, every
// command byte, RTR, random payloads from a fixed seed. Nothing may crash, the state must stay
// one of the defined ones and follow a reference model, and every frame sent must be a
// well-formed answer to what came in (CiA 301 §7.2.8.3.1: NMT = 000h DLC 2; CiA 305: every LSS
// frame is 8 bytes).
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "canopen/301/heartbeat.hpp"
#include "canopen/301/nmt_slave.hpp"
#include "canopen/305/lss_master.hpp"
#include "canopen/305/lss_slave.hpp"

using namespace oegw::canopen;

namespace {

TimePoint at_ms(int ms) { return TimePoint{} + std::chrono::milliseconds(ms); }

CanFrame make(std::uint32_t id, std::uint8_t dlc, const std::array<std::uint8_t, 8>& data, bool rtr = false) {
  CanFrame f;
  f.id = id;
  f.dlc = dlc;
  f.rtr = rtr;
  f.data = data;
  return f;
}

bool valid_state(NmtState s) {
  return s == NmtState::Initialisation || s == NmtState::Stopped || s == NmtState::Operational ||
         s == NmtState::PreOperational;
}

// The NMT reference model: what the state must be after `f`.
NmtState model_nmt(NmtState s, const CanFrame& f, std::uint8_t own) {
  if (f.id != 0 || f.rtr || f.dlc != 2) return s;
  if (f.data[1] != 0 && f.data[1] != own) return s;
  switch (f.data[0]) {
    case 0x01: return NmtState::Operational;
    case 0x02: return NmtState::Stopped;
    case 0x80:
    case 0x81:
    case 0x82: return NmtState::PreOperational;  // resets end in pre-operational again
    default: return s;
  }
}

struct NmtHarness {
  std::vector<CanFrame> sent;
  int resets = 0;
  NmtSlave nmt{NodeId{0x11}, [this](const CanFrame& f) { sent.push_back(f); }};
  NmtHarness() {
    nmt.on_reset([this](bool) { ++resets; });
    nmt.start(at_ms(0));
    sent.clear();
  }
  void feed_and_check(const CanFrame& f) {
    const NmtState before = nmt.state();
    const int resets_before = resets;
    const std::size_t sent_before = sent.size();
    const auto malformed_before = nmt.stats().malformed;
    const bool mine = nmt.on_frame(f, at_ms(1));
    ASSERT_EQ(mine, f.id == 0 && !f.extended);
    ASSERT_TRUE(valid_state(nmt.state()));
    ASSERT_EQ(nmt.state(), model_nmt(before, f, 0x11)) << f.to_string();
    const bool is_reset = f.id == 0 && !f.rtr && f.dlc == 2 && (f.data[1] == 0 || f.data[1] == 0x11) &&
                          (f.data[0] == 0x81 || f.data[0] == 0x82);
    ASSERT_EQ(resets - resets_before, is_reset ? 1 : 0) << f.to_string();
    ASSERT_EQ(sent.size() - sent_before, is_reset ? 1u : 0u) << f.to_string();
    if (is_reset) {
      ASSERT_EQ(sent.back(), CanFrame(0x711, {0x00}));
    }
    const bool malformed = f.id == 0 && (f.rtr || f.dlc != 2);
    ASSERT_EQ(nmt.stats().malformed - malformed_before, malformed ? 1u : 0u);
  }
};

TEST(FrameShapes, NmtEveryDlcEveryCommandByte) {
  NmtHarness h;
  int frames = 0;
  for (std::uint8_t dlc = 0; dlc <= 8; ++dlc) {
    for (int cs = 0; cs < 256; ++cs) {
      for (std::uint8_t node : {0x00, 0x11, 0x12, 0x7F, 0xFF}) {
        std::array<std::uint8_t, 8> d{static_cast<std::uint8_t>(cs), node, 0xAA, 0x55, 0, 0, 0, 0};
        h.feed_and_check(make(0x000, dlc, d));
        h.feed_and_check(make(0x000, dlc, d, true));
        ++frames;
      }
    }
  }
  EXPECT_EQ(frames, 9 * 256 * 5);
  // Only DLC 2 frames are commands: 5 valid specifiers x {0, own} nodes.
  EXPECT_EQ(h.nmt.stats().commands, 10u);
  EXPECT_EQ(h.nmt.stats().malformed, 2u * 8 * 256 * 5 + 256 * 5);  // RTR at every DLC + data DLC != 2
  EXPECT_EQ(h.resets, 4);
}

TEST(FrameShapes, NmtRandomFramesFixedSeed) {
  NmtHarness h;
  std::mt19937 rng(852);
  std::uniform_int_distribution<int> byte(0, 255);
  const std::uint32_t ids[] = {0x000, 0x000, 0x000, 0x001, 0x711, 0x7E5, 0x080};
  for (int i = 0; i < 20000; ++i) {
    std::array<std::uint8_t, 8> d{};
    for (auto& b : d) b = static_cast<std::uint8_t>(byte(rng));
    if (i % 3 == 0) d[1] = (i % 2) ? 0x11 : 0x00;  // make a share of them addressed to us
    if (i % 5 == 0) d[0] = static_cast<std::uint8_t>((i / 5) % 2 ? 0x01 : 0x82);
    const auto dlc = static_cast<std::uint8_t>(byte(rng) % 9);
    h.feed_and_check(make(ids[static_cast<std::size_t>(byte(rng)) % std::size(ids)], dlc, d, byte(rng) < 8));
    if (::testing::Test::HasFatalFailure()) return;
  }
  EXPECT_GT(h.nmt.stats().commands, 0u);
  EXPECT_GT(h.resets, 0);
}

// ------------------------------------------------------------------ LSS slave

constexpr lss::Address kAddr{0x00000182, 0x00000BE0, 0x00010003, 0x12345678};

std::optional<std::uint8_t> expected_answer(std::uint8_t cs) {
  switch (cs) {
    case 0x11:
    case 0x13:
    case 0x17:
    case 0x5A:
    case 0x5B:
    case 0x5C:
    case 0x5D:
    case 0x5E: return cs;
    case 0x43: return 0x44;
    case 0x4B: return 0x4F;
    case 0x4C: return 0x50;
    default: return std::nullopt;
  }
}

struct LssHarness {
  std::vector<CanFrame> sent;
  LssSlave slave;
  explicit LssHarness(NodeId id)
      : slave(
            kAddr, id, 3, [this](const CanFrame& f) { sent.push_back(f); },
            LssSlave::Callbacks{.on_pending_node_id = {},
                                .on_pending_bit_timing = {},
                                .on_activate_bit_timing = {},
                                .on_store = [](NodeId, std::uint8_t) { return std::uint8_t{0}; },
                                .on_start_nmt = {}}) {}

  void feed_and_check(const CanFrame& f) {
    const lss::Mode before = slave.mode();
    const std::size_t sent_before = sent.size();
    const bool mine = slave.on_frame(f, at_ms(0));
    ASSERT_EQ(mine, f.id == 0x7E5 && !f.extended);
    ASSERT_TRUE(slave.mode() == lss::Mode::Waiting || slave.mode() == lss::Mode::Configuration);
    ASSERT_TRUE(slave.pending_node_id().valid() || slave.pending_node_id().unconfigured());
    ASSERT_TRUE(lss::standard_bit_rate_kbit(slave.pending_bit_timing()).has_value());
    const std::size_t answers = sent.size() - sent_before;
    ASSERT_LE(answers, 1u) << f.to_string();
    const bool well_formed = mine && !f.rtr && f.dlc == 8;
    if (!well_formed) {
      ASSERT_EQ(answers, 0u) << f.to_string();
      ASSERT_EQ(slave.mode(), before);
      return;
    }
    if (answers == 1) {
      const CanFrame& a = sent.back();
      ASSERT_EQ(a.id, 0x7E4u);
      ASSERT_EQ(a.dlc, 8);
      ASSERT_FALSE(a.rtr);
      ASSERT_EQ(expected_answer(f.data[0]), a.data[0]) << f.to_string() << " -> " << a.to_string();
      // Configuration-only services answer only in configuration mode.
      if (f.data[0] == 0x11 || f.data[0] == 0x13 || f.data[0] == 0x17 || (f.data[0] >= 0x5A && f.data[0] <= 0x5E)) {
        ASSERT_EQ(before, lss::Mode::Configuration);
      }
    } else if (before == lss::Mode::Configuration) {
      // In configuration mode these always answer.
      const std::uint8_t cs = f.data[0];
      ASSERT_FALSE(cs == 0x11 || cs == 0x13 || cs == 0x17 || (cs >= 0x5A && cs <= 0x5E)) << f.to_string();
    }
    if (slave.mode() != before) {
      // Only switch state global or the last switch-selective frame change the mode.
      ASSERT_TRUE(f.data[0] == 0x04 || (f.data[0] == 0x43 && slave.mode() == lss::Mode::Configuration));
    }
  }
};

TEST(FrameShapes, LssEveryDlcEveryCommandByteInBothModes) {
  for (const NodeId id : {NodeId{0x11}, NodeId::unconfigured_id()}) {
    LssHarness h(id);
    for (const std::uint8_t mode : {0x00, 0x01}) {
      for (std::uint8_t dlc = 0; dlc <= 8; ++dlc) {
        for (int cs = 0; cs < 256; ++cs) {
          if (cs == 0x04) continue;  // keep the mode under test; 04h is exercised below
          h.feed_and_check(make(0x7E5, 8, {0x04, mode, 0, 0, 0, 0, 0, 0}));
          ASSERT_EQ(static_cast<std::uint8_t>(h.slave.mode()), mode);
          h.feed_and_check(make(0x7E5, dlc, {static_cast<std::uint8_t>(cs), 0x05, 0x02, 0, 0, 0, 0, 0}));
          h.feed_and_check(make(0x7E5, dlc, {static_cast<std::uint8_t>(cs), 0x05, 0x02, 0, 0, 0, 0, 0}, true));
          if (::testing::Test::HasFatalFailure()) return;
        }
      }
    }
    // Every 04h payload byte: only 0 and 1 are modes.
    for (int b = 0; b < 256; ++b) {
      const lss::Mode before = h.slave.mode();
      h.feed_and_check(make(0x7E5, 8, {0x04, static_cast<std::uint8_t>(b), 0, 0, 0, 0, 0, 0}));
      if (b > 1) EXPECT_EQ(h.slave.mode(), before);
      else EXPECT_EQ(static_cast<int>(h.slave.mode()), b);
    }
    // After all that: 11h with node 5 was accepted (configuration mode, DLC 8); 13h came with
    // table selector 05h, which no slave supports (only table 0), so the bit timing is unchanged.
    EXPECT_EQ(h.slave.pending_node_id(), NodeId{5});
    EXPECT_EQ(h.slave.pending_bit_timing(), 3);
    EXPECT_GT(h.slave.stats().malformed, 0u);
    EXPECT_GT(h.slave.stats().unknown, 0u);
  }
}

TEST(FrameShapes, LssRandomFramesFixedSeed) {
  LssHarness h(NodeId{0x11});
  std::mt19937 rng(305);
  std::uniform_int_distribution<int> byte(0, 255);
  const std::uint8_t interesting[] = {0x04, 0x11, 0x13, 0x15, 0x17, 0x40, 0x41, 0x42, 0x43,
                                      0x46, 0x4B, 0x4C, 0x5A, 0x5E, 0x51, 0x00, 0xFF};
  for (int i = 0; i < 20000; ++i) {
    std::array<std::uint8_t, 8> d{};
    for (auto& b : d) b = static_cast<std::uint8_t>(byte(rng));
    if (i % 2 == 0) d[0] = interesting[static_cast<std::size_t>(byte(rng)) % std::size(interesting)];
    if (d[0] == 0x04 && i % 4 == 0) d[1] = static_cast<std::uint8_t>(i % 8 == 0);
    const auto dlc = static_cast<std::uint8_t>(i % 3 == 0 ? 8 : byte(rng) % 9);
    const std::uint32_t id = (i % 7 == 0) ? 0x7E4u : 0x7E5u;
    h.feed_and_check(make(id, dlc, d, byte(rng) < 4));
    if (::testing::Test::HasFatalFailure()) return;
  }
  EXPECT_GT(h.sent.size(), 0u);
}

// The LSS master must ignore whatever answers come in, whatever their shape, and still run its
// queue to the end (each request completes exactly once).
TEST(FrameShapes, LssMasterSurvivesGarbageAnswers) {
  std::vector<CanFrame> sent;
  LssMaster master([&](const CanFrame& f) { sent.push_back(f); }, std::chrono::milliseconds(10));
  int completed = 0;
  auto cb = [&](const LssMaster::Result&) { ++completed; };
  for (int i = 0; i < 50; ++i) master.inquire(LssMaster::Inquiry::Serial, at_ms(0), cb);
  master.configure_node_id(NodeId{4}, at_ms(0), cb);
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> byte(0, 255);
  int t = 0;
  for (int i = 0; i < 20000 && !master.idle(); ++i) {
    std::array<std::uint8_t, 8> d{};
    for (auto& b : d) b = static_cast<std::uint8_t>(byte(rng));
    const auto dlc = static_cast<std::uint8_t>(byte(rng) % 9);
    const bool mine = master.on_frame(make(i % 5 == 0 ? 0x7E5 : 0x7E4, dlc, d), at_ms(t));
    EXPECT_EQ(mine, i % 5 != 0);
    if (i % 10 == 0) master.advance(at_ms(t += 3));
  }
  EXPECT_TRUE(master.idle());
  EXPECT_EQ(completed, 51);
  for (const CanFrame& f : sent) {
    EXPECT_EQ(f.id, 0x7E5u);
    EXPECT_EQ(f.dlc, 8);
  }
}

// Heartbeat consumer: every DLC and state byte from a monitored node.
TEST(FrameShapes, HeartbeatConsumerEveryShape) {
  ObjectDictionary od;
  install_heartbeat_consumer_objects(od, 1);
  ASSERT_EQ(od.set<std::uint32_t>(0x1016, 1, heartbeat_consumer_entry(NodeId{9}, 100)), SdoAbortCode::None);
  HeartbeatConsumer hc(od);
  int states = 0;
  int boots = 0;
  hc.on_state([&](NodeId n, NmtState s) {
    EXPECT_EQ(n, NodeId{9});
    EXPECT_TRUE(valid_state(s));
    ++states;
  });
  hc.on_boot([&](NodeId) { ++boots; });
  for (std::uint8_t dlc = 0; dlc <= 8; ++dlc)
    for (int b = 0; b < 256; ++b)
      hc.on_frame(make(0x709, dlc, {static_cast<std::uint8_t>(b), 0, 0, 0, 0, 0, 0, 0}), at_ms(0));
  EXPECT_EQ(boots, 1);
  EXPECT_EQ(states, 3);  // 04, 05, 7F with DLC 1 (each a change)
  EXPECT_EQ(hc.invalid_frames(), 9u * 256 - 4);
  EXPECT_EQ(hc.last_state(NodeId{9}), NmtState::PreOperational);
}

}  // namespace
