// The bus scan core (subdevices/bus_scan.hpp) on a simulated clock: probe scheduling and time-outs,
// what a node's answers become, heartbeats, LSS identify non-configured and fastscan (against the
// protocol core's LssSlave), and the family named from the reference documents' identities.
#include "subdevices/bus_scan.hpp"

#include <gtest/gtest.h>

#include <deque>
#include <map>
#include <set>

#include "canopen/305/lss_slave.hpp"
#include "subdevices/family_identity.hpp"

namespace oegw::subdevices {
namespace {

using namespace std::chrono_literals;
using canopen::lss::Address;

// An SDO server reduced to expedited uploads (CiA 301 §7.2.4.3.6): answers 43h with the 4-byte
// value of (index, sub), or aborts 0602 0000h ("object does not exist") / 0609 0011h.
struct FakeNode {
  std::uint8_t id;
  std::map<std::pair<std::uint16_t, std::uint8_t>, std::uint32_t> objects;
  std::set<std::pair<std::uint16_t, std::uint8_t>> silent = {};  // requests left unanswered
  std::optional<CanFrame> answer(const CanFrame& f) const {
    if (f.id != 0x600u + id || f.data[0] != 0x40) return std::nullopt;
    if (silent.count({static_cast<std::uint16_t>(f.data[1] | (f.data[2] << 8)), f.data[3]})) return std::nullopt;
    const std::uint16_t index = static_cast<std::uint16_t>(f.data[1] | (f.data[2] << 8));
    const std::uint8_t sub = f.data[3];
    CanFrame r(0x580u + id, {0x43, f.data[1], f.data[2], sub, 0, 0, 0, 0});
    const auto it = objects.find({index, sub});
    std::uint32_t v = 0;
    if (it == objects.end()) {
      r.data[0] = 0x80;
      v = objects.count({index, 0}) || objects.count({index, 1}) ? 0x06090011 : 0x06020000;
    } else {
      v = it->second;
    }
    canopen::put_u32(&r.data[4], v);
    return r;
  }
};

struct Harness {
  ScanConfig cfg;
  std::vector<FakeNode> nodes;
  std::vector<std::unique_ptr<canopen::LssSlave>> lss;
  std::vector<std::pair<TimePoint, CanFrame>> sent;  // every frame the scanner sent, with its time
  std::deque<CanFrame> to_bus, to_scanner;
  TimePoint now{};
  std::unique_ptr<BusScanner> scanner;
  std::vector<ScanProgress> progress;

  explicit Harness(ScanConfig c) : cfg(c) {}

  void add_lss(const Address& a) {
    lss.push_back(std::make_unique<canopen::LssSlave>(
        a, NodeId::unconfigured_id(), 3, [this](const CanFrame& f) { to_scanner.push_back(f); },
        canopen::LssSlave::Callbacks{}));
  }

  void deliver() {
    while (!to_bus.empty() || !to_scanner.empty()) {
      while (!to_bus.empty()) {
        const CanFrame f = to_bus.front();
        to_bus.pop_front();
        for (const auto& n : nodes)
          if (auto r = n.answer(f)) to_scanner.push_back(*r);
        for (auto& s : lss) s->on_frame(f, now);
      }
      while (!to_scanner.empty()) {
        const CanFrame f = to_scanner.front();
        to_scanner.pop_front();
        scanner->on_frame(f, now);
      }
    }
  }

  // Runs until the scan is done, moving time only to the scanner's deadlines; false if it never
  // ends. `heard` frames are put on the bus at their times.
  bool run(std::vector<std::pair<TimePoint, CanFrame>> heard = {}) {
    scanner = std::make_unique<BusScanner>(
        [this](const CanFrame& f) {
          sent.emplace_back(now, f);
          to_bus.push_back(f);
        },
        cfg);
    scanner->on_progress = [this](const ScanProgress& p) { progress.push_back(p); };
    scanner->start(now);
    for (int guard = 0; guard < 100000; ++guard) {
      deliver();
      if (scanner->done()) return true;
      auto t = scanner->next_deadline();
      if (!heard.empty() && (!t || heard.front().first <= *t)) {
        now = std::max(now, heard.front().first);
        scanner->on_frame(heard.front().second, now);
        heard.erase(heard.begin());
        continue;
      }
      if (!t) return false;
      now = std::max(now, *t);
      scanner->advance(now);
    }
    return false;
  }

  [[nodiscard]] std::size_t sdo_requests_at(TimePoint t) const {
    std::size_t n = 0;
    for (const auto& [at, f] : sent) n += at == t && f.id > 0x600 && f.id < 0x680 && f.data[0] == 0x40;
    return n;
  }
};

ScanConfig quiet(std::size_t parallel) {
  ScanConfig c;
  c.parallel = parallel;
  c.listen = 0ms;
  c.lss = false;
  return c;
}

TEST(BusScan, ProbesAtMostParallelNodeIdsAtOnceAndEachTimesOutOnItsOwn) {
  Harness h(quiet(8));
  ASSERT_TRUE(h.run());
  // 127 silent node-IDs, 8 at a time, 100 ms each: 16 rounds, not 127 × 100 ms.
  EXPECT_EQ(h.now, TimePoint{} + 1600ms);
  EXPECT_EQ(h.sdo_requests_at(TimePoint{}), 8u);
  EXPECT_EQ(h.sdo_requests_at(TimePoint{} + 100ms), 8u);
  EXPECT_EQ(h.sdo_requests_at(TimePoint{} + 1500ms), 127u - 15 * 8);
  EXPECT_TRUE(h.scanner->result().nodes.empty());
  ASSERT_FALSE(h.progress.empty());
  EXPECT_EQ(h.progress.back().probed, 127u);
  EXPECT_EQ(h.progress.back().total, 127u);
  EXPECT_EQ(h.progress.back().found, 0u);
}

TEST(BusScan, AllNodeIdsAtOnceTakeOneTimeOut) {
  ScanConfig c = quiet(127);
  c.sdo_timeout = 30ms;
  Harness h(c);
  ASSERT_TRUE(h.run());
  EXPECT_EQ(h.now, TimePoint{} + 30ms);
  EXPECT_EQ(h.sdo_requests_at(TimePoint{}), 127u);
}

TEST(BusScan, ANodeThatAnswersIsReadAndFreesItsSlotAtOnce) {
  // Novotechnik object table: 1000h 00020196h, 1018h/1 00000182h, /2 0BB9h (MC1-2800).
  Harness h(quiet(1));
  h.cfg.first = 5;
  h.cfg.last = 7;
  h.nodes.push_back({5,
                     {{{0x1000, 0}, 0x00020196},
                      {{0x1018, 1}, 0x182},
                      {{0x1018, 2}, 0x0BB9},
                      {{0x1018, 3}, 0x10003},
                      {{0x1018, 4}, 123456789},
                      {{0x1017, 0}, 50}}});
  ASSERT_TRUE(h.run());
  // Node 5 answered at once; 6 and 7 each waited for one time-out.
  EXPECT_EQ(h.now, TimePoint{} + 200ms);
  const ScanResult r = h.scanner->result();
  ASSERT_EQ(r.nodes.size(), 1u);
  const ScannedNode& n = r.nodes[0];
  EXPECT_EQ(n.node, NodeId{5});
  EXPECT_TRUE(n.answered_sdo);
  EXPECT_EQ(n.identity.device_type, 0x00020196u);
  EXPECT_EQ(n.identity.vendor_id, 0x182u);
  EXPECT_EQ(n.identity.product_code, 0x0BB9u);
  EXPECT_EQ(n.identity.revision, 0x10003u);
  EXPECT_EQ(n.identity.serial, 123456789u);
  EXPECT_EQ(n.producer_heartbeat_ms, 50);
  EXPECT_EQ(n.family.family, "novotechnik-406");
}

TEST(BusScan, AnAbortLeavesOneValueUnknownAndTheReadGoesOn) {
  // CO4013A: 1018h sub-index 0 = 3, no serial number; 1017h absent here too.
  Harness h(quiet(8));
  h.cfg.last = 10;
  h.nodes.push_back(
      {3, {{{0x1000, 0}, 0x01070191}, {{0x1018, 1}, 0x58}, {{0x1018, 2}, 0x01040131}, {{0x1018, 3}, 0x00010002}}});
  ASSERT_TRUE(h.run());
  const ScanResult r = h.scanner->result();
  ASSERT_EQ(r.nodes.size(), 1u);
  EXPECT_EQ(r.nodes[0].identity.revision, 0x00010002u);
  EXPECT_FALSE(r.nodes[0].identity.serial);
  EXPECT_FALSE(r.nodes[0].producer_heartbeat_ms);
  EXPECT_EQ(r.nodes[0].family.family, "mcb402");
}

TEST(BusScan, ALaterTimeOutLeavesOneValueUnknownAndTheReadGoesOn) {
  // A busy node misses 1018h:01 and :02 but answers the rest: it is found, without vendor and
  // product (so no family from them), the later reads made.
  Harness h(quiet(1));
  h.cfg.first = h.cfg.last = 3;
  h.nodes.push_back(
      {3, {{{0x1000, 0}, 0x01070191}, {{0x1018, 3}, 0x00010002}, {{0x1017, 0}, 100}}, {{0x1018, 1}, {0x1018, 2}}});
  ASSERT_TRUE(h.run());
  EXPECT_EQ(h.now, TimePoint{} + 200ms);  // two time-outs
  const ScanResult r = h.scanner->result();
  ASSERT_EQ(r.nodes.size(), 1u);
  EXPECT_EQ(r.nodes[0].identity.device_type, 0x01070191u);
  EXPECT_FALSE(r.nodes[0].identity.vendor_id);
  EXPECT_EQ(r.nodes[0].identity.revision, 0x00010002u);
  EXPECT_EQ(r.nodes[0].producer_heartbeat_ms, 100);
}

TEST(BusScan, ANodeThatAnswersNoSdoIsFoundByItsHeartbeat) {
  Harness h(quiet(127));
  h.cfg.listen = 500ms;
  // Node 42h is stopped (state 04h: no SDO) and beats every 200 ms; node 43h boots.
  ASSERT_TRUE(h.run({{TimePoint{} + 10ms, CanFrame(0x742, {0x04})},
                     {TimePoint{} + 20ms, CanFrame(0x743, {0x00})},
                     {TimePoint{} + 210ms, CanFrame(0x742, {0x04})},
                     {TimePoint{} + 410ms, CanFrame(0x742, {0x04})}}));
  EXPECT_EQ(h.now, TimePoint{} + 500ms);  // the listening time, not the probes', ends it
  const ScanResult r = h.scanner->result();
  ASSERT_EQ(r.nodes.size(), 2u);
  EXPECT_EQ(r.nodes[0].node, NodeId{0x42});
  EXPECT_FALSE(r.nodes[0].answered_sdo);
  EXPECT_TRUE(r.nodes[0].heard);
  EXPECT_EQ(r.nodes[0].state, canopen::NmtState::Stopped);
  EXPECT_EQ(r.nodes[0].heartbeat_period, canopen::Duration(200ms));
  EXPECT_EQ(r.nodes[0].family.family, "");
  EXPECT_TRUE(r.nodes[1].booted);
  EXPECT_FALSE(r.nodes[1].heartbeat_period);
}

TEST(BusScan, WithoutNodesWithoutNodeIdLssEndsAfterOneTimeOut) {
  ScanConfig c = quiet(127);
  c.lss = true;
  c.sdo_timeout = 10ms;
  Harness h(c);
  ASSERT_TRUE(h.run());
  EXPECT_EQ(h.now, TimePoint{} + 10ms + 25ms);
  EXPECT_FALSE(h.scanner->result().unconfigured);
  ASSERT_FALSE(h.sent.empty());
  EXPECT_EQ(h.sent.back().second, CanFrame(0x7E5, {0x4C, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_TRUE(h.progress.back().lss);
}

TEST(BusScan, FastscanReadsTheLssAddressOfANodeWithoutNodeIdAndLeavesItWaiting) {
  ScanConfig c = quiet(127);
  c.lss = true;
  c.sdo_timeout = 10ms;
  Harness h(c);
  // The Novotechnik document's LSS example address (§6: vendor 0182h, product 0BB9h).
  const Address a{0x182, 0x0BB9, 0x00010003, 0x12345678};
  h.add_lss(a);
  ASSERT_TRUE(h.run());
  const ScanResult r = h.scanner->result();
  EXPECT_TRUE(r.unconfigured);
  ASSERT_TRUE(r.unconfigured_address) << r.lss_note;
  EXPECT_EQ(*r.unconfigured_address, a);
  EXPECT_EQ(h.lss[0]->mode(), canopen::lss::Mode::Waiting);
  EXPECT_TRUE(r.nodes.empty());
  // Reset, 4 × 31 bit steps, 4 confirmations (+ one retry per part whose bit 0 is 1), the switch back.
  std::size_t fastscans = 0;
  for (const auto& [t, f] : h.sent) fastscans += f.id == 0x7E5 && f.data[0] == 0x51;
  EXPECT_EQ(fastscans, 1u + 4 * 31 + 4 + 2);  // product 0BB9h and revision 00010003h end in bit 1
  EXPECT_EQ(h.sent.back().second, CanFrame(0x7E5, {0x04, 0, 0, 0, 0, 0, 0, 0}));
}

TEST(BusScan, FastscanAmongTwoNodesWithoutNodeIdReadsOneWholeAddress) {
  ScanConfig c = quiet(127);
  c.lss = true;
  c.sdo_timeout = 10ms;
  Harness h(c);
  const Address a{0xB4, 0x00010003, 0, 7}, b{0xB4, 0x00010003, 0, 6};
  h.add_lss(a);
  h.add_lss(b);
  ASSERT_TRUE(h.run());
  const ScanResult r = h.scanner->result();
  ASSERT_TRUE(r.unconfigured_address) << r.lss_note;
  // Bit 0 is tried as 0 first: the node with serial 6.
  EXPECT_EQ(*r.unconfigured_address, b);
  EXPECT_EQ(h.lss[0]->mode(), canopen::lss::Mode::Waiting);
  EXPECT_EQ(h.lss[1]->mode(), canopen::lss::Mode::Waiting);
}

TEST(FamilyIdentity, NamesEachFamilyFromItsDocumentsIdentity) {
  // elobau MFG 34xG/36xG object table: 1000h 00000000h, 1018h:01 000000B4h, :02 00010003h.
  EXPECT_EQ(name_family({.device_type = 0, .vendor_id = 0xB4, .product_code = 0x00010003}).family, "elobau-mfg");
  // CO4013A: 1018h vendor 58h, product 01040131h; 1000h 01070191h in operation mode A4.
  EXPECT_EQ(name_family({.device_type = 0x01070191, .vendor_id = 0x58, .product_code = 0x01040131}).family, "mcb402");
  // ... in mode A0 (01050191h) still the board, with a doubt in the reason.
  const FamilyMatch a0 = name_family({.device_type = 0x01050191, .vendor_id = 0x58, .product_code = 0x01040131});
  EXPECT_EQ(a0.family, "mcb402");
  EXPECT_NE(a0.reason.find("operation mode A4"), std::string::npos) << a0.reason;
  // Novotechnik: 1000h 00020196h (DS406), 1018h/1 00000182h, any product (0BD5h MZ1-2200).
  EXPECT_EQ(name_family({.device_type = 0x00020196, .vendor_id = 0x182, .product_code = 0x0BD5}).family,
            "novotechnik-406");
  // Another frenzel + berg product with CiA 401 device type: the generic driver.
  EXPECT_EQ(name_family({.device_type = 0x00050191, .vendor_id = 0x58, .product_code = 0x1234}).family, "cia401");
  EXPECT_EQ(name_family({.device_type = 0x000F0191}).family, "cia401");
  // Novotechnik's vendor without its encoder profile, a CiA 406 encoder of another vendor, nothing read.
  EXPECT_EQ(name_family({.device_type = 0x00010192, .vendor_id = 0x182}).family, "");
  EXPECT_EQ(name_family({.device_type = 0x00020196, .vendor_id = 0x999}).family, "");
  const FamilyMatch none = name_family({});
  EXPECT_EQ(none.family, "");
  EXPECT_NE(none.reason.find("not read"), std::string::npos);
}

}  // namespace
}  // namespace oegw::subdevices
