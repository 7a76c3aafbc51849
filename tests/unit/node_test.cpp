// The Node (CiA 301 slave + CiA 305 LSS slave) frame by frame: a manual TimePoint, a vector sink,
// no bus. Each test feeds frames with rx() and checks exactly what the node sent.
#include "canopen/node.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace oegw::canopen {
namespace {

using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

constexpr NodeId kId{0x20};

Bytes bytes(const CanFrame& f) { return Bytes(f.data.begin(), f.data.begin() + f.dlc); }

class NodeTest : public ::testing::Test {
 protected:
  NodeTest() {
    dir_ = std::filesystem::temp_directory_path() /
           ("oegw-node-test-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    build_od(od);
  }
  ~NodeTest() override { std::filesystem::remove_all(dir_); }

  // The application's part of the dictionary: inputs, an output, two TPDOs and an RPDO whose
  // COB-ID defaults follow the node-ID.
  static void build_od(ObjectDictionary& d) {
    d.add_array(0x6000, "Read input 8-bit", DataType::Unsigned8, Access::ReadOnly, 2, {0}, true);
    d.add_array(0x6200, "Write output 8-bit", DataType::Unsigned8, Access::ReadWrite, 1, {0}, true);
    d.add_var(0x2000, "Setting", DataType::Unsigned16, Access::ReadWrite, encode<std::uint16_t>(7));
    install_tpdo(d, 1,
                 PdoParameters{.cob_id = cob::kTpdo1 + kId.value(),
                               .transmission_type = 0xFF,
                               .mapping = {pdo_map(0x6000, 1, 8), pdo_map(0x6000, 2, 8)}});
    install_tpdo(d, 2,
                 PdoParameters{.cob_id = cob::kTpdo2 + kId.value(),
                               .transmission_type = 1,
                               .mapping = {pdo_map(0x6000, 1, 8)}});
    install_rpdo(d, 1,
                 PdoParameters{.cob_id = cob::kRpdo1 + kId.value(),
                               .transmission_type = 0xFF,
                               .mapping = {pdo_map(0x6200, 1, 8)}});
  }

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
    EXPECT_EQ(bytes(r[0]), (Bytes{0x60, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8),
                                  sub, 0, 0, 0, 0}))
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

}  // namespace
}  // namespace oegw::canopen
