// The Node (CiA 301 slave + CiA 305 LSS slave) frame by frame: a manual TimePoint, a vector sink,
// no bus. Each test feeds frames with rx() and checks exactly what the node sent.
#include "canopen/node.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "node_test_support.hpp"

namespace oegw::canopen {
namespace {

using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

constexpr NodeId kId{0x20};

Bytes bytes(const CanFrame& f) { return Bytes(f.data.begin(), f.data.begin() + f.dlc); }

std::string read_text(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

class NodeTest : public ::testing::Test {
 protected:
  NodeTest() {
    dir_ = std::filesystem::temp_directory_path() / ("oegw-node-test-" + std::to_string(::getpid()) + "-" +
                                                     ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    build_od(od);
  }
  ~NodeTest() override { std::filesystem::remove_all(dir_); }

  static void build_od(ObjectDictionary& d) { test_support::build_application_od(d, kId); }

  NodeConfig config() const {
    NodeConfig c;
    c.node_id = kId;
    c.device_type = 0x000F0191;
    c.device_name = "oegw node";
    c.identity = {.vendor = 0x1234, .product = 0x852, .revision = 0x10002, .serial = 42};
    c.heartbeat_ms = 100;
    c.heartbeat_consumers = 2;
    c.store_path = store_path();
    return c;
  }
  std::filesystem::path store_path() const { return dir_ / "params.txt"; }
  // The store file's entries (none, and a failure, when it does not parse).
  ParameterStore::Entries stored_entries() const {
    std::string error;
    auto entries = ParameterStore::parse(read_text(store_path()), error);
    EXPECT_TRUE(entries) << error;
    return entries.value_or(ParameterStore::Entries{});
  }

  void make(NodeConfig c) {
    node.reset();
    node = std::make_unique<Node>(od, std::move(c), [this](const CanFrame& f) { out.push_back(f); });
  }
  void make() { make(config()); }
  ParameterStore::LoadResult start() {
    out.clear();
    return node->start(now);
  }

  // Advances the clock to `t` and lets the node run its timers.
  void at(TimePoint t) {
    now = t;
    node->advance(now);
  }
  void after(Duration d) { at(now + d); }

  std::vector<CanFrame> rx(const CanFrame& f) {
    out.clear();
    node->on_frame(f, now);
    node->advance(now);
    return out;
  }
  std::vector<CanFrame> rx(std::uint32_t id, std::initializer_list<std::uint8_t> b) { return rx(CanFrame(id, b)); }
  std::vector<CanFrame> nmt(std::uint8_t cs, std::uint8_t target = 0) { return rx(0x000, {cs, target}); }
  std::vector<CanFrame> lss(std::initializer_list<std::uint8_t> b) {
    Bytes v(b);
    v.resize(8, 0);
    return rx(CanFrame(cob::kLssMaster, std::span<const std::uint8_t>(v)));
  }

  // Expedited SDO upload/download on the node's current default SDO COB-IDs.
  std::vector<CanFrame> sdo_read(std::uint16_t index, std::uint8_t sub, NodeId id = kId) {
    return rx(cob::kSdoRx + id.value(),
              {0x40, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0});
  }
  std::vector<CanFrame> sdo_write(std::uint16_t index, std::uint8_t sub, const Bytes& data, NodeId id = kId) {
    const auto cs = static_cast<std::uint8_t>(0x23 | ((4 - data.size()) << 2));
    Bytes f{cs, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0};
    std::copy(data.begin(), data.end(), f.begin() + 4);
    return rx(CanFrame(cob::kSdoRx + id.value(), std::span<const std::uint8_t>(f)));
  }
  // Writes and expects the download response 60h.
  void sdo_ok(std::uint16_t index, std::uint8_t sub, const Bytes& data, NodeId id = kId) {
    const auto r = sdo_write(index, sub, data, id);
    ASSERT_EQ(r.size(), 1u) << std::hex << index << ":" << int(sub);
    EXPECT_EQ(r[0].id, cob::kSdoTx + id.value());
    EXPECT_EQ(bytes(r[0]),
              (Bytes{0x60, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0}))
        << std::hex << index << ":" << int(sub);
  }
  static Bytes u32(std::uint32_t v) { return encode<std::uint32_t>(v); }
  static Bytes u16(std::uint16_t v) { return encode<std::uint16_t>(v); }

  std::filesystem::path dir_;
  ObjectDictionary od;
  std::vector<CanFrame> out;
  TimePoint now{std::chrono::seconds(100)};
  std::unique_ptr<Node> node;
};

// ------------------------------------------------------------------ lifetime (regression)

// A Node destroyed while its ObjectDictionary lives used to leave OD observers and write hooks
// capturing the dead services: the next write was undefined behaviour (seen as a hang). Every
// service now holds its registrations and releases them in its destructor.
TEST_F(NodeTest, RebuiltOnSameDictionaryLeavesNoDanglingCallbacks) {
  make();
  start();
  const std::size_t observers = od.observer_count();
  const std::size_t hooks_1005 = od.find(0x1005)->write_hook_count();
  const std::size_t hooks_1016 = od.find(0x1016)->write_hook_count();
  const std::size_t hooks_1a00 = od.find(0x1A00)->write_hook_count();
  EXPECT_GT(observers, 0u);
  sdo_ok(0x1017, 0, u16(50));
  for (int round = 0; round < 3; ++round) {
    node.reset();
    EXPECT_EQ(od.observer_count(), 0u);
    EXPECT_EQ(od.find(0x1005)->write_hook_count(), 0u);
    EXPECT_EQ(od.find(0x1016)->write_hook_count(), 0u);
    EXPECT_EQ(od.find(0x1A00)->write_hook_count(), 0u);
    // Writes with no node on the dictionary touch nothing dead.
    EXPECT_EQ(od.set<std::uint16_t>(0x1017, 0, 20), SdoAbortCode::None);
    EXPECT_EQ(od.set<std::uint8_t>(0x6000, 1, 3), SdoAbortCode::None);

    make();
    start();
    EXPECT_EQ(od.observer_count(), observers);
    EXPECT_EQ(od.find(0x1005)->write_hook_count(), hooks_1005);
    EXPECT_EQ(od.find(0x1016)->write_hook_count(), hooks_1016);
    EXPECT_EQ(od.find(0x1A00)->write_hook_count(), hooks_1a00);

    sdo_ok(0x1017, 0, u16(50));
    EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 50u);
    sdo_ok(0x1016, 1, u32(heartbeat_consumer_entry(NodeId{5}, 200)));
    // The duplicate check of the (one) live consumer hook still refuses a second entry for 5.
    const auto dup = sdo_write(0x1016, 2, u32(heartbeat_consumer_entry(NodeId{5}, 300)));
    ASSERT_EQ(dup.size(), 1u);
    EXPECT_EQ(dup[0].data[0], 0x80);
    EXPECT_EQ(get_u32(dup[0].data.data() + 4), static_cast<std::uint32_t>(SdoAbortCode::ParameterIncompatibility));
    sdo_ok(0x1005, 0, u32(0x40000080));  // become SYNC producer
    // TPDO1 remapping, CiA 301 §7.5.2.36 procedure: invalidate, sub 0 = 0, entries, sub 0 = n.
    sdo_ok(0x1800, 1, u32(CobId::kInvalidBit | (cob::kTpdo1 + kId.value())));
    sdo_ok(0x1A00, 0, {0});
    sdo_ok(0x1A00, 1, u32(pdo_map(0x6000, 2, 8)));
    sdo_ok(0x1A00, 0, {1});
    sdo_ok(0x1800, 1, u32(cob::kTpdo1 + kId.value()));
    EXPECT_EQ(node->pdo().tpdo(1)->dlc(), 1u);
    // Back to the defaults for the next round (reset node).
    nmt(0x81, kId.value());
  }
}

// ------------------------------------------------------------------ boot-up and identity

// CiA 301 §7.3.2.2.2 / §7.2.8.3.2.2: boot-up 700h+id with 00h, then heartbeats every 1017h ms
// with the NMT state (7Fh pre-operational), the first one period after the boot-up.
TEST_F(NodeTest, BootUpThenHeartbeatAtProducerTime) {
  make();
  const TimePoint t0 = now;
  const auto r = start();
  EXPECT_TRUE(r.ok);
  EXPECT_FALSE(r.file_present);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0x720u);
  EXPECT_EQ(bytes(out[0]), Bytes{0x00});
  EXPECT_EQ(node->state(), NmtState::PreOperational);
  EXPECT_EQ(node->next_deadline(), t0 + 100ms);

  out.clear();
  at(t0 + 99ms);
  EXPECT_TRUE(out.empty());
  at(t0 + 100ms);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0x720u);
  EXPECT_EQ(bytes(out[0]), Bytes{0x7F});
  out.clear();
  at(t0 + 200ms);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(bytes(out[0]), Bytes{0x7F});
}

TEST_F(NodeTest, IdentityObjectsReadableViaSdo) {
  make();
  start();
  auto expect_upload = [&](std::uint16_t index, std::uint8_t sub, Bytes response) {
    const auto r = sdo_read(index, sub);
    ASSERT_EQ(r.size(), 1u);
    EXPECT_EQ(r[0].id, 0x5A0u);
    EXPECT_EQ(bytes(r[0]), response) << std::hex << index << ":" << int(sub);
  };
  // 1000h device type 000F0191h: expedited, 4 bytes (cs 43h).
  expect_upload(0x1000, 0, {0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x0F, 0x00});
  // 1018h identity: sub 0 = 4 (cs 4Fh, 1 byte), then vendor, product, revision, serial.
  expect_upload(0x1018, 0, {0x4F, 0x18, 0x10, 0x00, 0x04, 0x00, 0x00, 0x00});
  expect_upload(0x1018, 1, {0x43, 0x18, 0x10, 0x01, 0x34, 0x12, 0x00, 0x00});
  expect_upload(0x1018, 2, {0x43, 0x18, 0x10, 0x02, 0x52, 0x08, 0x00, 0x00});
  expect_upload(0x1018, 3, {0x43, 0x18, 0x10, 0x03, 0x02, 0x00, 0x01, 0x00});
  expect_upload(0x1018, 4, {0x43, 0x18, 0x10, 0x04, 0x2A, 0x00, 0x00, 0x00});
  // 1008h "oegw node" (9 bytes): segmented upload, initiate with size indicated (cs 41h).
  expect_upload(0x1008, 0, {0x41, 0x08, 0x10, 0x00, 0x09, 0x00, 0x00, 0x00});
  auto seg = rx(0x620, {0x60, 0, 0, 0, 0, 0, 0, 0});
  ASSERT_EQ(seg.size(), 1u);
  EXPECT_EQ(bytes(seg[0]), (Bytes{0x00, 'o', 'e', 'g', 'w', ' ', 'n', 'o'}));
  seg = rx(0x620, {0x70, 0, 0, 0, 0, 0, 0, 0});
  ASSERT_EQ(seg.size(), 1u);
  // toggle 1, n = 5 unused bytes, c = 1 (last): 10h | 0Ah | 01h.
  EXPECT_EQ(bytes(seg[0]), (Bytes{0x1B, 'd', 'e', 0, 0, 0, 0, 0}));
  // 1000h is const: a download is refused with 0601 0002h.
  const auto w = sdo_write(0x1000, 0, u32(1));
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(bytes(w[0]), (Bytes{0x80, 0x00, 0x10, 0x00, 0x02, 0x00, 0x01, 0x06}));
}

// ------------------------------------------------------------------ NMT gating

// CiA 301 §7.3.2.2.1, Table 47: which services run in which NMT state.
TEST_F(NodeTest, NmtStateGatesServices) {
  make();
  start();
  const TimePoint t0 = now;

  // Stopped: no SDO answer, no EMCY, no PDO; heartbeat with 04h; NMT still served.
  EXPECT_TRUE(nmt(0x02, kId.value()).empty());
  EXPECT_EQ(node->state(), NmtState::Stopped);
  EXPECT_TRUE(sdo_read(0x1000, 0).empty());
  out.clear();
  EXPECT_TRUE(node->emcy().raise(0x5000, 0x00, now));
  node->advance(now);
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(od.set<std::uint8_t>(0x6000, 1, 0x11), SdoAbortCode::None);
  node->advance(now);
  EXPECT_TRUE(out.empty());
  EXPECT_TRUE(rx(0x220, {0x33}).empty());
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0u);
  at(t0 + 100ms);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0x720u);
  EXPECT_EQ(bytes(out[0]), Bytes{0x04});
  EXPECT_TRUE(node->emcy().clear(0x5000, now));

  // Pre-operational: SDO yes, PDO no; heartbeat 7Fh.
  nmt(0x80, 0);
  EXPECT_EQ(node->state(), NmtState::PreOperational);
  auto r = sdo_read(0x1000, 0);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x5A0u);
  out.clear();
  EXPECT_EQ(od.set<std::uint8_t>(0x6000, 1, 0x12), SdoAbortCode::None);
  node->advance(now);
  EXPECT_TRUE(out.empty());
  EXPECT_TRUE(rx(0x220, {0x33}).empty());
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0u);
  out.clear();
  at(t0 + 200ms);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(bytes(out[0]), Bytes{0x7F});

  // Operational: entering it sends the event-driven TPDO1 once; changes and RPDOs are served.
  r = nmt(0x01, kId.value());
  EXPECT_EQ(node->state(), NmtState::Operational);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x1A0u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x12, 0x00}));
  out.clear();
  EXPECT_EQ(od.set<std::uint8_t>(0x6000, 2, 0x34), SdoAbortCode::None);
  node->advance(now);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0x1A0u);
  EXPECT_EQ(bytes(out[0]), (Bytes{0x12, 0x34}));
  EXPECT_TRUE(rx(0x220, {0x33}).empty());
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0x33u);
  r = sdo_read(0x1000, 0);
  ASSERT_EQ(r.size(), 1u);
  out.clear();
  at(t0 + 300ms);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(bytes(out[0]), Bytes{0x05});

  // Back to stopped: PDO silent again.
  nmt(0x02, 0);
  out.clear();
  EXPECT_EQ(od.set<std::uint8_t>(0x6000, 2, 0x35), SdoAbortCode::None);
  node->advance(now);
  EXPECT_TRUE(out.empty());
}

// ------------------------------------------------------------------ resets and stored values

// CiA 301 §7.3.2.2.2: reset communication restores 1000h–1FFFh, reset node (application) the
// whole dictionary; stored values (1010h, §7.5.2.13) are re-applied after either.
TEST_F(NodeTest, ResetCommunicationAndResetNodeWithStoredValues) {
  make();
  start();
  // Store 1017h = 300 (communication group, 1010h:02) and 2000h:00 = 0x55 and 6200h:01 = 9
  // (all parameters, 1010h:01), then change them again.
  sdo_ok(0x1017, 0, u16(300));
  sdo_ok(0x6200, 1, {9});
  sdo_ok(0x2000, 0, u16(0x55));
  sdo_ok(0x1010, 1, u32(ParameterStore::kSaveSignature));
  ASSERT_TRUE(std::filesystem::exists(store_path()));
  sdo_ok(0x1017, 0, u16(500));
  sdo_ok(0x1016, 1, u32(heartbeat_consumer_entry(NodeId{5}, 200)));
  sdo_ok(0x6200, 1, {7});
  sdo_ok(0x2000, 0, u16(0x66));
  const auto ro = sdo_write(0x6000, 1, {0});  // read-only to SDO (0601 0002h); set locally
  ASSERT_EQ(ro.size(), 1u);
  EXPECT_EQ(ro[0].data[0], 0x80);
  EXPECT_EQ(od.set<std::uint8_t>(0x6000, 1, 0x42), SdoAbortCode::None);  // not stored (ro)

  // Reset communication: comm objects back to default then stored; application untouched.
  auto r = nmt(0x82, kId.value());
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x720u);
  EXPECT_EQ(bytes(r[0]), Bytes{0x00});
  EXPECT_EQ(node->state(), NmtState::PreOperational);
  EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 300u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1016, 1), 0u);
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 7u);
  EXPECT_EQ(od.get<std::uint16_t>(0x2000, 0), 0x66u);
  EXPECT_EQ(od.get<std::uint8_t>(0x6000, 1), 0x42u);
  // The heartbeat follows the restored 1017h.
  const TimePoint t1 = now;
  out.clear();
  at(t1 + 299ms);
  EXPECT_TRUE(out.empty());
  at(t1 + 300ms);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(bytes(out[0]), Bytes{0x7F});

  // Reset node: everything back to default, then every stored value.
  sdo_ok(0x1017, 0, u16(500));
  r = nmt(0x81, 0);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(bytes(r[0]), Bytes{0x00});
  EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 300u);
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 9u);
  EXPECT_EQ(od.get<std::uint16_t>(0x2000, 0), 0x55u);
  EXPECT_EQ(od.get<std::uint8_t>(0x6000, 1), 0u);

  // Restore defaults (1011h:01 "load") then reset node: factory values.
  sdo_ok(0x1011, 1, u32(ParameterStore::kLoadSignature));
  nmt(0x81, 0);
  EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 100u);
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0u);
  EXPECT_EQ(od.get<std::uint16_t>(0x2000, 0), 7u);
}

// ------------------------------------------------------------------ LSS through the Node

// CiA 305: configure node-ID 21h, store it, and activate it with NMT reset communication.
TEST_F(NodeTest, LssConfiguresStoresAndActivatesNodeId) {
  make();
  start();
  EXPECT_TRUE(lss({0x04, 0x01}).empty());  // switch state global: configuration
  auto r = lss({0x11, 0x21});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x7E4u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x11, 0x00, 0, 0, 0, 0, 0, 0}));
  r = lss({0x17});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x17, 0x00, 0, 0, 0, 0, 0, 0}));
  std::filesystem::path lss_file = store_path();
  lss_file += ".lss";
  ASSERT_TRUE(std::filesystem::exists(lss_file));
  {
    std::ifstream in(lss_file);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(text, "node_id=33\nbit_timing=3\n");
  }
  // Written atomically: no temporary left beside it.
  for (const auto& e : std::filesystem::directory_iterator(dir_)) EXPECT_TRUE(e.path() == lss_file) << e.path();
  EXPECT_TRUE(lss({0x04, 0x00}).empty());  // back to waiting
  // Still 20h until reset communication (CiA 305: the new node-ID is pending).
  EXPECT_EQ(node->node_id(), kId);
  EXPECT_EQ(sdo_read(0x1000, 0).size(), 1u);

  r = nmt(0x82, kId.value());
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x721u);
  EXPECT_EQ(bytes(r[0]), Bytes{0x00});
  EXPECT_EQ(node->node_id(), NodeId{0x21});
  EXPECT_TRUE(sdo_read(0x1000, 0, kId).empty());
  r = sdo_read(0x1000, 0, NodeId{0x21});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x5A1u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1200, 1), 0x621u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1200, 2), 0x5A1u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1800, 1), 0x1A1u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1801, 1), 0x2A1u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1400, 1), 0x221u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1014, 0), 0xA1u);
  out.clear();
  EXPECT_TRUE(node->emcy().raise(0x5000, 0x00, now));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0xA1u);
  EXPECT_TRUE(node->emcy().clear(0x5000, now));
  nmt(0x01, 0x21);
  EXPECT_EQ(node->state(), NmtState::Operational);
  out.clear();
  EXPECT_EQ(od.set<std::uint8_t>(0x6000, 1, 0x01), SdoAbortCode::None);
  node->advance(now);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0x1A1u);
  // Heartbeats on 721h.
  out.clear();
  after(100ms);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0x721u);

  // Power cycle: a new Node (fresh dictionary) on the same store comes up as 21h.
  node.reset();
  ObjectDictionary od2;
  build_od(od2);
  Node second(od2, config(), [this](const CanFrame& f) { out.push_back(f); });
  out.clear();
  EXPECT_TRUE(second.start(now).ok);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0x721u);
  EXPECT_EQ(second.node_id(), NodeId{0x21});
  EXPECT_EQ(second.lss().active_node_id(), NodeId{0x21});
  EXPECT_EQ(od2.get<std::uint32_t>(0x1200, 1), 0x621u);
  EXPECT_EQ(od2.get<std::uint32_t>(0x1800, 1), 0x1A1u);
  EXPECT_EQ(od2.get<std::uint32_t>(0x1801, 1), 0x2A1u);
  EXPECT_EQ(od2.get<std::uint32_t>(0x1400, 1), 0x221u);
  EXPECT_EQ(od2.get<std::uint32_t>(0x1014, 0), 0xA1u);
  out.clear();
  second.on_frame(CanFrame(0x621, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), now);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0x5A1u);
  EXPECT_EQ(bytes(out[0]), (Bytes{0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x0F, 0x00}));
}

// ------------------------------------------------------------------ LSS bit timing (CiA 305)

// Configure bit timing takes exactly the table-0 indexes of NodeConfig::supported_bit_timings
// (here CiA 852 §6.2's 1000, 500, 250, 125 kbit/s): error 1 for every other index and table.
TEST_F(NodeTest, LssConfigureBitTimingTakesOnlyTheSupportedRates) {
  NodeConfig c = config();
  c.supported_bit_timings = (1u << 0) | (1u << 2) | (1u << 3) | (1u << 4);
  make(c);
  start();
  EXPECT_TRUE(lss({0x04, 0x01}).empty());
  for (std::uint8_t index = 0; index < 16; ++index) {
    const bool supported = index == 0 || index == 2 || index == 3 || index == 4;
    const auto r = lss({0x13, 0x00, index});
    ASSERT_EQ(r.size(), 1u) << int(index);
    EXPECT_EQ(bytes(r[0]), (Bytes{0x13, static_cast<std::uint8_t>(supported ? 0 : 1), 0, 0, 0, 0, 0, 0}))
        << "index " << int(index);
  }
  // Table selector 1 (manufacturer-specific) is not supported either.
  EXPECT_EQ(bytes(lss({0x13, 0x01, 0x03})[0]), (Bytes{0x13, 0x01, 0, 0, 0, 0, 0, 0}));
  // The last index taken is the pending one.
  EXPECT_EQ(node->lss().pending_bit_timing(), 4u);
}

// Activate bit timing with switch delay 300 ms: nothing leaves the node (heartbeat every 100 ms,
// EMCY, LSS answers) for 2 x 300 ms; the switch callback comes at 300 ms with the pending index;
// then the heartbeat resumes on its own timing.
TEST_F(NodeTest, LssActivateBitTimingIsSilentForTwiceTheSwitchDelayAndSwitchesInBetween) {
  make();
  start();
  std::vector<std::pair<TimePoint, std::uint8_t>> switches;
  node->on_bit_timing_switch = [&](std::uint8_t index) { switches.emplace_back(now, index); };
  EXPECT_TRUE(lss({0x04, 0x01}).empty());
  ASSERT_EQ(lss({0x13, 0x00, 0x04}).size(), 1u);  // 125 kbit/s
  const TimePoint t0 = now;
  EXPECT_TRUE(lss({0x15, 0x2C, 0x01}).empty());  // 012Ch = 300 ms
  EXPECT_TRUE(node->bit_timing_silent());
  EXPECT_EQ(node->next_deadline(), t0 + 100ms);  // the heartbeat's: it keeps its timing
  out.clear();
  // Everything the node would send while silent is dropped.
  EXPECT_TRUE(lss({0x5E}).empty());                    // inquire node-ID: no answer
  EXPECT_TRUE(node->emcy().raise(0x5000, 0x00, now));  // EMCY: not sent
  for (int ms = 10; ms < 300; ms += 10) at(t0 + std::chrono::milliseconds(ms));
  EXPECT_TRUE(out.empty());
  EXPECT_TRUE(switches.empty());
  at(t0 + 300ms);
  ASSERT_EQ(switches.size(), 1u);
  EXPECT_EQ(switches[0].first, t0 + 300ms);
  EXPECT_EQ(switches[0].second, 4u);
  EXPECT_EQ(node->bit_timing_index(), 4u);
  for (int ms = 310; ms < 600; ms += 10) at(t0 + std::chrono::milliseconds(ms));
  EXPECT_TRUE(out.empty());
  EXPECT_TRUE(node->bit_timing_silent());
  at(t0 + 600ms);
  EXPECT_FALSE(node->bit_timing_silent());
  EXPECT_EQ(switches.size(), 1u);
  // The heartbeat due at 600 ms is the first frame again.
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0x720u);
  EXPECT_EQ(bytes(out[0]), Bytes{0x7F});
  out.clear();
  at(t0 + 700ms);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(bytes(out[0]), Bytes{0x7F});
  // LSS answers again.
  const auto r = lss({0x5E});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x5E, 0x20, 0, 0, 0, 0, 0, 0}));
}

// Switch delay 0: the switch happens at once and the node is not silent afterwards.
TEST_F(NodeTest, LssActivateBitTimingWithoutDelaySwitchesAtOnce) {
  make();
  start();
  std::vector<std::uint8_t> switches;
  node->on_bit_timing_switch = [&](std::uint8_t index) { switches.push_back(index); };
  EXPECT_TRUE(lss({0x04, 0x01}).empty());
  ASSERT_EQ(lss({0x13, 0x00, 0x02}).size(), 1u);
  EXPECT_TRUE(lss({0x15, 0x00, 0x00}).empty());
  EXPECT_EQ(switches, std::vector<std::uint8_t>{2});
  EXPECT_FALSE(node->bit_timing_silent());
  EXPECT_EQ(lss({0x5E}).size(), 1u);
}

// Store configuration keeps the configured bit timing; at the next power-on it is the node's
// (bit_timing_index) and the pending one of its LSS slave, whatever NodeConfig says.
TEST_F(NodeTest, LssStoredBitTimingIsAppliedAtStart) {
  make();
  start();
  EXPECT_TRUE(lss({0x04, 0x01}).empty());
  ASSERT_EQ(bytes(lss({0x13, 0x00, 0x04})[0]), (Bytes{0x13, 0, 0, 0, 0, 0, 0, 0}));
  ASSERT_EQ(bytes(lss({0x17})[0]), (Bytes{0x17, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(node->bit_timing_index(), 3u);  // stored, not activated
  node.reset();
  ObjectDictionary od2;
  build_od(od2);
  Node again(od2, config(), [](const CanFrame&) {});
  EXPECT_EQ(again.bit_timing_index(), 3u);  // NodeConfig's until power-on
  again.start(now);
  EXPECT_EQ(again.bit_timing_index(), 4u);
  EXPECT_EQ(again.lss().pending_bit_timing(), 4u);
}

// ------------------------------------------------------------------ LSS node-ID FFh (CiA 305)

TEST_F(NodeTest, LssNodeIdFfhLeavesTheNodeUnconfiguredAndSilentButForLss) {
  make();
  start();
  EXPECT_TRUE(lss({0x04, 0x01}).empty());  // 7E5#04 01: configuration
  auto r = lss({0x11, 0xFF});              // 7E5#11 FF
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x7E4u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x11, 0x00, 0, 0, 0, 0, 0, 0}));  // 7E4#11 00
  EXPECT_TRUE(lss({0x04, 0x00}).empty());                         // 7E5#04 00: waiting; the node stays at 20h (active)
  EXPECT_EQ(node->state(), NmtState::PreOperational);
  EXPECT_TRUE(nmt(0x82, 0x00).empty());  // 000#82 00: no boot-up
  EXPECT_EQ(node->state(), NmtState::Initialisation);
  EXPECT_TRUE(node->node_id().unconfigured());
  EXPECT_TRUE(node->lss().active_node_id().unconfigured());
  // Silent: no heartbeat, no SDO answer, no EMCY.
  out.clear();
  after(1s);
  EXPECT_TRUE(out.empty());
  EXPECT_TRUE(sdo_read(0x1000, 0).empty());
  out.clear();
  (void)node->emcy().raise(0x5000, 0x00, now);
  EXPECT_TRUE(out.empty());
  (void)node->emcy().clear(0x5000, now);
  // NMT commands addressed to it (all nodes, its old ID, FFh) do nothing while unconfigured.
  for (const std::uint8_t cs : {0x01, 0x02, 0x80, 0x81, 0x82})
    for (const std::uint8_t target : {0x00, 0x20, 0xFF}) {
      EXPECT_TRUE(nmt(cs, target).empty()) << int(cs) << " " << int(target);
      EXPECT_EQ(node->state(), NmtState::Initialisation);
    }
  // LSS is served: identify non-configured remote slave 7E5#4C -> 7E4#50.
  r = lss({0x4C});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x7E4u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x50, 0, 0, 0, 0, 0, 0, 0}));
}

// CiA 305's recovery: switch state selective (the 1018h address), configure node-ID, switch
// state global waiting -> the node starts with the new node-ID; NMT then works as usual.
TEST_F(NodeTest, LssRecoversAnUnconfiguredNodeBySelectiveSwitchAndNewNodeId) {
  make();
  start();
  lss({0x04, 0x01});
  lss({0x11, 0xFF});
  lss({0x04, 0x00});
  nmt(0x82, 0x00);
  ASSERT_EQ(node->state(), NmtState::Initialisation);
  // Switch state selective on 1018h:01..04 = 1234h, 852h, 10002h, 42: 7E4#44.
  EXPECT_TRUE(lss({0x40, 0x34, 0x12, 0x00, 0x00}).empty());
  EXPECT_TRUE(lss({0x41, 0x52, 0x08, 0x00, 0x00}).empty());
  EXPECT_TRUE(lss({0x42, 0x02, 0x00, 0x01, 0x00}).empty());
  auto r = lss({0x43, 42, 0x00, 0x00, 0x00});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x44, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(node->lss().mode(), lss::Mode::Configuration);
  // Inquire node-ID: still FFh (active).
  r = lss({0x5E});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x5E, 0xFF, 0, 0, 0, 0, 0, 0}));
  r = lss({0x11, 0x21});  // configure node-ID 21h
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x11, 0x00, 0, 0, 0, 0, 0, 0}));
  EXPECT_TRUE(lss({0x4C}).empty());  // a node-ID is pending: no longer "non-configured"
  EXPECT_EQ(node->state(), NmtState::Initialisation);
  // Switch state global waiting: NMT starts, boot-up 721#00.
  r = lss({0x04, 0x00});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x721u);
  EXPECT_EQ(bytes(r[0]), Bytes{0x00});
  EXPECT_EQ(node->state(), NmtState::PreOperational);
  EXPECT_EQ(node->node_id(), NodeId{0x21});
  EXPECT_EQ(node->lss().active_node_id(), NodeId{0x21});
  EXPECT_TRUE(lss({0x4C}).empty());
  // The COB-ID defaults moved from 20h (the last valid node-ID) to 21h.
  EXPECT_EQ(od.get<std::uint32_t>(0x1200, 1), 0x621u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1200, 2), 0x5A1u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1800, 1), 0x1A1u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1801, 1), 0x2A1u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1400, 1), 0x221u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1014, 0), 0xA1u);
  EXPECT_TRUE(sdo_read(0x1000, 0, kId).empty());
  r = sdo_read(0x1000, 0, NodeId{0x21});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x5A1u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x0F, 0x00}));
  out.clear();
  after(100ms);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0x721u);
  EXPECT_EQ(bytes(out[0]), Bytes{0x7F});
  // NMT: start, reset communication, reset node behave, with boot-ups on 721h.
  for (const CanFrame& f : nmt(0x01, 0x21)) EXPECT_EQ(f.id, 0x1A1u);  // TPDO 1 on entering operational
  EXPECT_EQ(node->state(), NmtState::Operational);
  EXPECT_TRUE(nmt(0x02, 0x20).empty());  // its old node-ID: not addressed any more
  EXPECT_EQ(node->state(), NmtState::Operational);
  r = nmt(0x82, 0x21);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x721u);
  EXPECT_EQ(node->state(), NmtState::PreOperational);
  r = nmt(0x81, 0x00);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x721u);
  EXPECT_EQ(bytes(r[0]), Bytes{0x00});
  EXPECT_EQ(node->node_id(), NodeId{0x21});
  EXPECT_EQ(od.get<std::uint32_t>(0x1800, 1), 0x1A1u);
}

// The same recovery by switch state global, back to the original node-ID; a later LSS change
// moves the COB-IDs on from there.
TEST_F(NodeTest, LssRecoversAnUnconfiguredNodeByGlobalSwitch) {
  make();
  start();
  lss({0x04, 0x01});
  lss({0x11, 0xFF});
  lss({0x04, 0x00});
  nmt(0x82, 0x00);
  ASSERT_EQ(node->state(), NmtState::Initialisation);
  EXPECT_TRUE(lss({0x04, 0x01}).empty());
  auto r = lss({0x11, 0x20});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x11, 0x00, 0, 0, 0, 0, 0, 0}));
  r = lss({0x04, 0x00});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x720u);
  EXPECT_EQ(node->state(), NmtState::PreOperational);
  EXPECT_EQ(od.get<std::uint32_t>(0x1800, 1), 0x1A0u);
  EXPECT_EQ(sdo_read(0x1000, 0).size(), 1u);
  // A configured node switched to waiting does not restart (only an unconfigured one does).
  lss({0x04, 0x01});
  lss({0x11, 0x22});
  EXPECT_TRUE(lss({0x04, 0x00}).empty());
  EXPECT_EQ(node->node_id(), kId);
  r = nmt(0x82, 0x20);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x722u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1800, 1), 0x1A2u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1200, 1), 0x622u);
}

// ------------------------------------------------------------------ corrupt parameter file

TEST_F(NodeTest, CorruptParameterFileIsReportedAndNodeRunsOnDefaults) {
  // A file whose first entries are intact but whose last one was altered after the CRC was
  // computed: the whole file is refused, nothing applied.
  std::string text = ParameterStore::serialize({{{0x1017, 0}, {0x2C, 0x01}}, {{0x6200, 1}, {0x09}}});
  const auto pos = text.find("6200 01 09");
  ASSERT_NE(pos, std::string::npos);
  text[pos + 9] = '8';
  {
    std::ofstream f(store_path(), std::ios::binary);
    f << text;
  }
  make();
  const TimePoint t0 = now;
  const auto r = start();
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(r.file_present);
  EXPECT_EQ(r.applied, 0u);
  EXPECT_FALSE(r.error.empty());
  // Boots anyway, then EMCY 6000h "generic software error" (CiA 852 Table 37): it runs on defaults.
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].id, 0x720u);
  EXPECT_EQ(out[1].id, 0xA0u);
  EXPECT_EQ(bytes(out[1]), (Bytes{0x00, 0x60, 0x01, 0, 0, 0, 0, 0}));
  EXPECT_TRUE(node->emcy().active(0x6000));
  EXPECT_EQ(node->state(), NmtState::PreOperational);
  EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 100u);
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0u);
  out.clear();
  at(t0 + 100ms);  // heartbeat on the default period
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(bytes(out[0]), Bytes{0x7F});
  // And the same on reset node, which restarts the errors (CiA 301 §7.3.2.2.1): the store it
  // loads again is still corrupt, so 6000h is raised anew after the boot-up.
  auto r2 = nmt(0x81, 0);
  ASSERT_EQ(r2.size(), 2u);
  EXPECT_EQ(r2[0].id, 0x720u);
  EXPECT_EQ(bytes(r2[1]), (Bytes{0x00, 0x60, 0x01, 0, 0, 0, 0, 0}));
  EXPECT_TRUE(node->emcy().active(0x6000));
  EXPECT_EQ(od.get<std::uint8_t>(0x1001, 0), 0x01u);
  EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 100u);
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0u);
  // The host saves (1010h:01 "save"): the file is intact again, and the next reset ends 6000h.
  sdo_ok(0x1010, 1, u32(ParameterStore::kSaveSignature));
  r2 = nmt(0x82, 0);
  ASSERT_EQ(r2.size(), 2u);
  EXPECT_EQ(r2[0].id, 0x720u);
  EXPECT_EQ(r2[1].id, 0xA0u);
  EXPECT_EQ(bytes(r2[1]), (Bytes{0x00, 0x00, 0x00, 0, 0, 0, 0, 0}));
  EXPECT_FALSE(node->emcy().active(0x6000));
}

// ------------------------------------------------------------------ a store that fails safe

// The SDO abort frame for `code` on index:sub (CiA 301 §7.2.4.3.17).
Bytes abort_frame(std::uint16_t index, std::uint8_t sub, std::uint32_t code) {
  Bytes b{0x80, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub};
  const Bytes c = encode<std::uint32_t>(code);
  b.insert(b.end(), c.begin(), c.end());
  return b;
}

// An unreadable store (here: a folder where the file should be; as another user it is
// "Permission denied", storage_test) is no "no store": the node boots on defaults, EMCY 6000h
// (CiA 852 Table 37 "generic software error"; CiA 301 §7.5.2.2: 1001h bit 0, generic, as no
// other bit names software) goes up, and a save of one group, which would keep the unreadable
// others by rewriting the file with its own group only, is refused with 0606 0000h.
TEST_F(NodeTest, UnreadableStoreRunsOnDefaultsWithEmcy6000AndRefusesAPartialSave) {
  std::filesystem::create_directory(store_path());
  make();
  const auto r = start();
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("is not a regular file"), std::string::npos) << r.error;
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].id, 0x720u);
  EXPECT_EQ(out[1].id, 0xA0u);
  EXPECT_EQ(bytes(out[1]), (Bytes{0x00, 0x60, 0x01, 0, 0, 0, 0, 0}));
  for (const std::uint8_t sub : {2, 3}) {
    const auto w = sdo_write(0x1010, sub, u32(ParameterStore::kSaveSignature));
    ASSERT_EQ(w.size(), 1u);
    EXPECT_EQ(bytes(w[0]), abort_frame(0x1010, sub, 0x06060000)) << int(sub);
    const auto l = sdo_write(0x1011, sub, u32(ParameterStore::kLoadSignature));
    ASSERT_EQ(l.size(), 1u);
    EXPECT_EQ(bytes(l[0]), abort_frame(0x1011, sub, 0x06060000)) << int(sub);
  }
  EXPECT_TRUE(std::filesystem::is_directory(store_path()));
}

// A corrupt store likewise: a partial save would write a file of its own group only, erasing
// the others the host saved (and that a repair could still recover); 1010h:01 replaces it.
TEST_F(NodeTest, CorruptStoreRefusesAPartialSaveAndSaveAllReplacesIt) {
  std::string text = ParameterStore::serialize({{{0x1017, 0}, {0x2C, 0x01}}, {{0x6200, 1}, {0x09}}});
  text[text.find("6200 01 09") + 9] = '8';
  std::ofstream(store_path(), std::ios::binary) << text;
  make();
  start();
  const auto w = sdo_write(0x1010, 2, u32(ParameterStore::kSaveSignature));
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(bytes(w[0]), abort_frame(0x1010, 2, 0x06060000));
  EXPECT_EQ(read_text(store_path()), text);  // untouched
  sdo_ok(0x1017, 0, u16(300));
  sdo_ok(0x1010, 1, u32(ParameterStore::kSaveSignature));
  const auto stored = stored_entries();
  EXPECT_EQ(stored.at({0x1017, 0}), u16(300));
}

// A readable store: a save of one group merges with what is stored (CiA 301 §7.5.2.13: sub 2
// saves the communication parameters, leaving the application ones as they were stored).
TEST_F(NodeTest, PartialSaveMergesWithTheStoredGroups) {
  make();
  start();
  sdo_ok(0x1017, 0, u16(300));
  sdo_ok(0x6200, 1, {9});
  sdo_ok(0x1010, 1, u32(ParameterStore::kSaveSignature));
  sdo_ok(0x1017, 0, u16(400));
  sdo_ok(0x6200, 1, {5});  // not saved: sub 2 below is the communication group only
  sdo_ok(0x1010, 2, u32(ParameterStore::kSaveSignature));
  const auto stored = stored_entries();
  EXPECT_EQ(stored.at({0x1017, 0}), u16(400));
  EXPECT_EQ(stored.at({0x6200, 1}), Bytes{9});
}

// 1003h is the history of errors that occurred (CiA 301 §7.5.2.5), not a parameter: a save
// never stores it, and a reset never brings back a count without its entries.
TEST_F(NodeTest, SaveNeverStoresTheErrorHistory) {
  make();
  start();
  ASSERT_TRUE(node->emcy().raise(0x5000, 0x00, now));
  ASSERT_EQ(od.get<std::uint8_t>(0x1003, 0), 1u);
  sdo_ok(0x1010, 1, u32(ParameterStore::kSaveSignature));
  const auto stored = stored_entries();
  for (const auto& [key, value] : stored) EXPECT_NE(key.first, 0x1003) << "1003h:" << int(key.second);
  // A store written before this rule, holding 1003h:00 = 1: not loaded either.
  std::ofstream(store_path(), std::ios::binary) << ParameterStore::serialize({{{0x1003, 0}, {0x01}}});
  ASSERT_TRUE(node->emcy().clear(0x5000, now));
  sdo_ok(0x1003, 0, {0});  // history cleared by the host
  nmt(0x81, 0);            // reset node: defaults, then the store
  EXPECT_EQ(od.get<std::uint8_t>(0x1003, 0), 0u);
  const auto r = sdo_read(0x1003, 0);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x4F, 0x03, 0x10, 0x00, 0x00, 0, 0, 0}));
}

// The temporary file is created, never opened through whatever is there: a link planted at
// "<store>.tmp" is removed, not written through (its target stays as it was), and a stale
// temporary file of a crash is replaced.
TEST_F(NodeTest, SaveNeverWritesThroughALinkAtTheTemporaryFile) {
  const auto victim = dir_ / "victim";
  std::ofstream(victim) << "precious\n";
  const auto tmp = std::filesystem::path(store_path().string() + ".tmp");
  std::filesystem::create_symlink(victim, tmp);
  make();
  start();
  sdo_ok(0x1017, 0, u16(300));
  sdo_ok(0x1010, 1, u32(ParameterStore::kSaveSignature));
  EXPECT_EQ(read_text(victim), "precious\n");
  EXPECT_FALSE(std::filesystem::exists(std::filesystem::symlink_status(tmp)));
  EXPECT_TRUE(std::filesystem::is_regular_file(std::filesystem::symlink_status(store_path())));
  std::ofstream(tmp) << "half-written by a crash";
  sdo_ok(0x1017, 0, u16(400));
  sdo_ok(0x1010, 2, u32(ParameterStore::kSaveSignature));
  const auto stored = stored_entries();
  EXPECT_EQ(stored.at({0x1017, 0}), u16(400));
  EXPECT_FALSE(std::filesystem::exists(tmp));
}

// A symbolic link at the store's own path is never followed: not read at start (EMCY 6000h,
// defaults), not replaced by a save of any group (0606 0000h), its target untouched.
TEST_F(NodeTest, SymlinkedStoreIsRefusedByEveryOperation) {
  const auto target = dir_ / "elsewhere.store";
  const std::string text = ParameterStore::serialize({{{0x1017, 0}, {0x2C, 0x01}}});
  std::ofstream(target, std::ios::binary) << text;
  std::filesystem::create_symlink(target, store_path());
  make();
  const auto r = start();
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("symbolic link"), std::string::npos) << r.error;
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(bytes(out[1]), (Bytes{0x00, 0x60, 0x01, 0, 0, 0, 0, 0}));
  EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 100u);  // the default, not the link's 300
  for (const std::uint8_t sub : {1, 2, 3}) {
    const auto w = sdo_write(0x1010, sub, u32(ParameterStore::kSaveSignature));
    ASSERT_EQ(w.size(), 1u);
    EXPECT_EQ(bytes(w[0]), abort_frame(0x1010, sub, 0x06060000)) << int(sub);
  }
  const auto l = sdo_write(0x1011, 1, u32(ParameterStore::kLoadSignature));
  ASSERT_EQ(l.size(), 1u);
  EXPECT_EQ(bytes(l[0]), abort_frame(0x1011, 1, 0x06060000));
  EXPECT_TRUE(std::filesystem::is_symlink(store_path()));
  EXPECT_EQ(read_text(target), text);
}

// ------------------------------------------------------------------ COB-IDs of 11-bit frames

// CiA 301 §7.5.2.35 (and every COB-ID entry): with bit 29 = 0 bits 11..28 are 0. A write with any
// of them set is refused with 0609 0030h and changes nothing — never cut to its 11 bits: the PDO
// COB-IDs (RPDO 1400h:01, TPDO 1800h:01), SYNC 1005h, EMCY 1014h, the EMCY consumer 1028h, an
// additional SDO server's 1201h:01 (which refused it already); a 29-bit one (bit 29) is taken.
TEST_F(NodeTest, ACobIdOfAnElevenBitFrameWithBitsElevenToTwentyEightSetIsRefused) {
  NodeConfig c = config();
  c.sdo_servers = {SdoServerChannel{.request = 0x80000000u | 0x640, .response = 0x80000000u | 0x5C0}};
  make(c);
  EmcyConsumer consumer(
      od, [](const EmcyMessage&, TimePoint) {}, 4);
  start();
  struct Entry {
    std::uint16_t index;
    std::uint8_t sub;
    std::uint32_t value;  // the 11-bit CAN-ID with bit 11, 20 or 28 set besides
  };
  for (const Entry& e : {Entry{0x1400, 1, 0x800008A0u}, Entry{0x1800, 1, 0x800101A0u}, Entry{0x1005, 0, 0x00000880u},
                         Entry{0x1014, 0, 0x900000A0u}, Entry{0x1028, 1, 0x00100081u}, Entry{0x1201, 1, 0x80000E40u}}) {
    const std::uint32_t before = od.get<std::uint32_t>(e.index, e.sub);
    const auto r = sdo_write(e.index, e.sub, u32(e.value));
    ASSERT_EQ(r.size(), 1u) << std::hex << e.index;
    EXPECT_EQ(bytes(r[0]), (Bytes{0x80, static_cast<std::uint8_t>(e.index), static_cast<std::uint8_t>(e.index >> 8),
                                  e.sub, 0x30, 0x00, 0x09, 0x06}))
        << std::hex << e.index << ":" << int(e.sub) << " = " << e.value;
    EXPECT_EQ(od.get<std::uint32_t>(e.index, e.sub), before) << std::hex << e.index;
  }
  // Bit 29: a 29-bit CAN-ID, whose bits 11..28 belong to it.
  sdo_ok(0x1400, 1, u32(0x80000000u | 0x20000000u | 0x12345));
  EXPECT_EQ(CobId{od.get<std::uint32_t>(0x1400, 1)}.can_id(), 0x12345u);
  sdo_ok(0x1028, 1, u32(0x20000000u | 0x1ABCD));
}

// ------------------------------------------------------------------ SYNC length, resets

// CiA 301 §7.2.5 / Table 26: a SYNC of the wrong length (1019h = 0: no counter) raises 8240h
// (1001h bit 4); it is over with the next SYNC of the right length: EMCY 0000h, 1001h 0.
TEST_F(NodeTest, Emcy8240hEndsWithTheNextSyncOfTheRightLength) {
  make();
  start();
  auto r = rx(0x080, {0x05});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x40, 0x82, 0x11, 0, 0, 0, 0, 0}));
  EXPECT_TRUE(rx(0x080, {0x06}).empty()) << "still the same error";
  EXPECT_EQ(od.get<std::uint8_t>(0x1001, 0), 0x11u);
  r = rx(CanFrame(0x080, std::span<const std::uint8_t>{}));
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0xA0u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x00, 0x00, 0x00, 0, 0, 0, 0, 0}));
  EXPECT_EQ(od.get<std::uint8_t>(0x1001, 0), 0x00u);
  EXPECT_FALSE(node->emcy().active(0x8240));
  // With 1019h = 5 the SYNC carries a counter: one without is wrong, one with it right.
  sdo_ok(0x1019, 0, {5});
  r = rx(CanFrame(0x080, std::span<const std::uint8_t>{}));
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x40, 0x82, 0x11, 0, 0, 0, 0, 0}));
  r = rx(0x080, {0x01});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x00, 0x00, 0x00, 0, 0, 0, 0, 0}));
}

// CiA 301 §7.3.2.2.1: reset node restarts the application with its power-on values, and the
// errors with it: nothing active, 1001h 0, no EMCY but what still holds — the controller still
// error passive raises 8120h anew. Reset communication keeps the active errors.
TEST_F(NodeTest, ResetNodeEndsTheActiveErrorsResetCommunicationKeepsThem) {
  make();
  start();
  (void)rx(0x080, {0x05});  // 8240h
  ASSERT_TRUE(node->emcy().active(0x8240));
  auto r = nmt(0x82, 0);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x720u);
  EXPECT_TRUE(node->emcy().active(0x8240));
  EXPECT_EQ(od.get<std::uint8_t>(0x1001, 0), 0x11u);
  r = nmt(0x81, 0);
  ASSERT_EQ(r.size(), 1u) << "the boot-up only: no EMCY";
  EXPECT_EQ(bytes(r[0]), Bytes{0x00});
  EXPECT_EQ(node->emcy().active_count(), 0u);
  r = sdo_read(0x1001, 0);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x4F, 0x01, 0x10, 0x00, 0x00, 0, 0, 0}));
  EXPECT_TRUE(rx(CanFrame(0x080, std::span<const std::uint8_t>{})).empty()) << "no error to end: no 0000h";
  // The controller error passive (8120h): still so after a reset node, so raised again.
  out.clear();
  node->on_bus_event(BusEvent::ErrorPassive, now);
  node->advance(now);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(bytes(out[0]), (Bytes{0x20, 0x81, 0x11, 0, 0, 0, 0, 0}));
  r = nmt(0x81, 0);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_EQ(bytes(r[0]), Bytes{0x00});
  EXPECT_EQ(bytes(r[1]), (Bytes{0x20, 0x81, 0x11, 0, 0, 0, 0, 0}));
  out.clear();
  node->on_bus_event(BusEvent::ErrorActive, now);
  node->advance(now);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(bytes(out[0]), (Bytes{0x00, 0x00, 0x00, 0, 0, 0, 0, 0}));
}

// ------------------------------------------------------------------ SYNC producer

// CiA 301 §7.2.5 / §7.5.2.5-6: 1005h bit 30 makes the node the SYNC producer, one SYNC every
// 1006h µs; TPDO type 1 goes out after every SYNC (§7.5.2.35).
TEST_F(NodeTest, SyncProducerDrivesSynchronousTpdo) {
  NodeConfig c = config();
  c.sync = SyncConfig{.cob_id = cob::kSync | 0x40000000u, .period_us = 10'000};
  make(c);
  start();
  const TimePoint t0 = now;
  EXPECT_TRUE(node->sync().producer());
  EXPECT_EQ(od.get<std::uint32_t>(0x1005, 0), 0x40000080u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1006, 0), 10'000u);
  at(t0);  // production starts: first SYNC one period later
  EXPECT_EQ(od.set<std::uint8_t>(0x6000, 1, 0x5A), SdoAbortCode::None);
  auto r = nmt(0x01, 0);
  ASSERT_EQ(r.size(), 1u);  // event-driven TPDO1 once on entering operational
  EXPECT_EQ(r[0].id, 0x1A0u);
  for (int i = 1; i <= 3; ++i) {
    out.clear();
    at(t0 + i * 10ms - 1us);
    EXPECT_TRUE(out.empty()) << i;
    at(t0 + i * 10ms);
    ASSERT_EQ(out.size(), 2u) << i;
    EXPECT_EQ(out[0].id, 0x080u);
    EXPECT_EQ(out[0].dlc, 0u);
    EXPECT_EQ(out[1].id, 0x2A0u);
    EXPECT_EQ(bytes(out[1]), Bytes{0x5A});
  }
  // In pre-operational the SYNC goes on, the TPDO does not.
  nmt(0x80, 0);
  out.clear();
  at(t0 + 40ms);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0x080u);
}

// ------------------------------------------------------------------ EMCY

// CiA 301 §7.2.7: EMCY 80h+id: error code, 1001h, manufacturer field; 1003h history; the last
// cleared error sends the error-reset EMCY 0000h.
TEST_F(NodeTest, EmcyRaiseAndClearInPreOperational) {
  make();
  start();
  out.clear();
  EXPECT_TRUE(node->emcy().raise(0x8130, 0x10, now));  // life guard / heartbeat error, comm bit
  node->advance(now);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0xA0u);
  EXPECT_EQ(bytes(out[0]), (Bytes{0x30, 0x81, 0x11, 0, 0, 0, 0, 0}));
  EXPECT_EQ(od.get<std::uint8_t>(0x1001, 0), 0x11u);
  EXPECT_EQ(od.get<std::uint8_t>(0x1003, 0), 1u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1003, 1) & 0xFFFFu, 0x8130u);
  auto r = sdo_read(0x1001, 0);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x4F, 0x01, 0x10, 0x00, 0x11, 0, 0, 0}));
  r = sdo_read(0x1003, 1);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(bytes(r[0]), (Bytes{0x43, 0x03, 0x10, 0x01, 0x30, 0x81, 0x00, 0x00}));

  out.clear();
  EXPECT_TRUE(node->emcy().clear(0x8130, now));
  node->advance(now);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0xA0u);
  EXPECT_EQ(bytes(out[0]), (Bytes{0x00, 0x00, 0x00, 0, 0, 0, 0, 0}));
  EXPECT_EQ(od.get<std::uint8_t>(0x1001, 0), 0u);
  EXPECT_EQ(od.get<std::uint8_t>(0x1003, 0), 1u);  // the history keeps the entry
}

}  // namespace
}  // namespace oegw::canopen
