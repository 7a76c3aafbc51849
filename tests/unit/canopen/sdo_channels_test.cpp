// The additional SDO server channels 1201h..127Fh of a Node (CiA 301 §7.2.4, §7.5.2.33) frame by
// frame: a manual TimePoint, a vector sink, no bus. The host side is the default channel 1200h
// (sdo_write/sdo_read) or a plain SdoClient on the extra channel's COB-IDs.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "canopen/301/sdo_client.hpp"
#include "canopen/node.hpp"

namespace oegw::canopen {
namespace {

using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

constexpr NodeId kId{0x20};
constexpr std::uint32_t kInvalid = CobId::kInvalidBit;
constexpr auto kInvalidValue = static_cast<std::uint32_t>(SdoAbortCode::InvalidValue);

Bytes u32(std::uint32_t v) { return encode<std::uint32_t>(v); }

class SdoChannelsTest : public ::testing::Test {
 protected:
  SdoChannelsTest() {
    dir_ = std::filesystem::temp_directory_path() / ("oegw-sdo-channels-test-" + std::to_string(::getpid()) + "-" +
                                                     ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    od.add_var(0x2000, "Setting", DataType::Unsigned16, Access::ReadWrite, encode<std::uint16_t>(7));
    // TPDO1 valid on 1A0h: a COB-ID the device uses.
    install_tpdo(od, 1, PdoParameters{.cob_id = cob::kTpdo1 + kId.value(), .transmission_type = 0xFF, .mapping = {}});
  }
  ~SdoChannelsTest() override { std::filesystem::remove_all(dir_); }

  // 1201h on 690h/6B0h from power-on, 1202h disabled (both COB-IDs 8000 0000h).
  NodeConfig config() const {
    NodeConfig c;
    c.node_id = kId;
    c.device_name = "oegw node";
    c.identity = {.vendor = 0x1234, .product = 0x852, .revision = 0x10002, .serial = 42};
    c.store_path = dir_ / "params.txt";
    c.sdo_servers = {SdoServerChannel{0x690, 0x6B0}, SdoServerChannel{}};
    return c;
  }
  void make(NodeConfig c) {
    node.reset();
    node = std::make_unique<Node>(od, std::move(c), [this](const CanFrame& f) {
      out.push_back(f);
      if (client) client->on_frame(f, now);
    });
  }
  void make() { make(config()); }
  void start() {
    node->start(now);
    out.clear();
  }

  std::vector<CanFrame> rx(const CanFrame& f) {
    out.clear();
    node->on_frame(f, now);
    node->advance(now);
    return out;
  }
  std::vector<CanFrame> rx(std::uint32_t id, std::initializer_list<std::uint8_t> b) { return rx(CanFrame(id, b)); }
  std::vector<CanFrame> nmt(std::uint8_t cs) { return rx(0x000, {cs, kId.value()}); }

  // Expedited upload/download on channel `rx_id` (default: 1200h's 620h).
  std::vector<CanFrame> sdo_read(std::uint16_t index, std::uint8_t sub, std::uint32_t rx_id = 0x620) {
    return rx(rx_id, {0x40, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0});
  }
  std::vector<CanFrame> sdo_write32(std::uint16_t index, std::uint8_t sub, std::uint32_t v,
                                    std::uint32_t rx_id = 0x620) {
    Bytes f{0x23, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0};
    put_u32(f.data() + 4, v);
    return rx(CanFrame(rx_id, std::span<const std::uint8_t>(f)));
  }
  // A write through 1200h that must be confirmed (60h on 5A0h).
  void write_ok(std::uint16_t index, std::uint8_t sub, std::uint32_t v) {
    const auto r = sdo_write32(index, sub, v);
    ASSERT_EQ(r.size(), 1u) << std::hex << index << ":" << int(sub);
    EXPECT_EQ(r[0].id, 0x5A0u);
    EXPECT_EQ(r[0].data[0], 0x60) << std::hex << index << ":" << int(sub) << " = " << v;
  }
  // A write through 1200h that must be aborted with `code`.
  void write_refused(std::uint16_t index, std::uint8_t sub, std::uint32_t v, std::uint32_t code) {
    const auto r = sdo_write32(index, sub, v);
    ASSERT_EQ(r.size(), 1u) << std::hex << index << ":" << int(sub);
    EXPECT_EQ(r[0].data[0], 0x80) << std::hex << index << ":" << int(sub) << " = " << v;
    EXPECT_EQ(get_u32(r[0].data.data() + 4), code) << std::hex << index << ":" << int(sub) << " = " << v;
  }
  // True if an upload of 1000h on `rx_id` is answered on `tx_id`.
  bool answers(std::uint32_t rx_id, std::uint32_t tx_id) {
    const auto r = sdo_read(0x1000, 0, rx_id);
    return r.size() == 1 && r[0].id == tx_id && r[0].data[0] == 0x43;
  }

  std::filesystem::path dir_;
  ObjectDictionary od;
  std::vector<CanFrame> out;
  TimePoint now{std::chrono::seconds(100)};
  std::unique_ptr<SdoClient> client;
  std::unique_ptr<Node> node;
};

// CiA 301 §7.5.2.33: 1201h/1202h exist as RECORDs with sub 0 = 3, the COB-IDs rw with the
// configured defaults, sub 3 node-ID of the SDO client rw default 0; the accessors give the servers.
TEST_F(SdoChannelsTest, ObjectsExistWithTheirDefaults) {
  make();
  start();
  ASSERT_EQ(node->sdo_server_count(), 3u);
  for (const std::uint16_t index : {0x1201, 0x1202}) {
    const Object* o = od.find(index);
    ASSERT_NE(o, nullptr) << std::hex << index;
    EXPECT_EQ(o->code(), ObjectCode::Record);
    EXPECT_EQ(o->name(), "SDO server parameter");
    EXPECT_EQ(od.get<std::uint8_t>(index, 0), 3u);
    for (std::uint8_t sub = 1; sub <= 3; ++sub) EXPECT_EQ(od.find(index, sub)->access, Access::ReadWrite);
    EXPECT_EQ(od.find(index, 1)->type, DataType::Unsigned32);
    EXPECT_EQ(od.find(index, 2)->type, DataType::Unsigned32);
    EXPECT_EQ(od.find(index, 3)->type, DataType::Unsigned8);
    EXPECT_EQ(od.get<std::uint8_t>(index, 3), 0u);
  }
  EXPECT_EQ(od.get<std::uint32_t>(0x1201, 1), 0x690u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1201, 2), 0x6B0u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1202, 1), kInvalid);
  EXPECT_EQ(od.get<std::uint32_t>(0x1202, 2), kInvalid);
  EXPECT_EQ(od.find(0x1203), nullptr);
  // The default channel stays read-only.
  EXPECT_EQ(od.find(0x1200, 1)->access, Access::ReadOnly);
  EXPECT_EQ(node->sdo_server(0).rx_cob_id(), CobId{0x620});
  EXPECT_EQ(node->sdo_server(1).rx_cob_id(), CobId{0x690});
  EXPECT_EQ(node->sdo_server(1).tx_cob_id(), CobId{0x6B0});
  EXPECT_FALSE(node->sdo_server(2).rx_cob_id().valid());
  EXPECT_THROW((void)node->sdo_server(3), std::out_of_range);
  // Sub 3 takes a node-ID 0..127.
  const auto r = rx(0x620, {0x2F, 0x01, 0x12, 0x03, 0x7F, 0, 0, 0});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].data[0], 0x60);
  EXPECT_EQ(od.get<std::uint8_t>(0x1201, 3), 0x7Fu);
  const auto high = rx(0x620, {0x2F, 0x01, 0x12, 0x03, 0x80, 0, 0, 0});
  ASSERT_EQ(high.size(), 1u);
  EXPECT_EQ(high[0].data[0], 0x80);
}

TEST_F(SdoChannelsTest, NoChannelsConfiguredMeansOnlyTheDefaultServer) {
  NodeConfig c = config();
  c.sdo_servers.clear();
  make(c);
  start();
  EXPECT_EQ(node->sdo_server_count(), 1u);
  EXPECT_EQ(od.find(0x1201), nullptr);
  EXPECT_THROW((void)node->sdo_server(1), std::out_of_range);
  c.sdo_servers.assign(128, SdoServerChannel{});
  EXPECT_THROW(make(c), std::invalid_argument);
}

// A plain SDO client on 690h/6B0h reads 1018h (expedited) and 1008h (segmented, and block)
// through the extra channel.
TEST_F(SdoChannelsTest, PlainSdoClientReadsThroughTheExtraChannel) {
  make();
  start();
  SdoClientConfig cc;
  cc.request_cob = CobId{0x690};
  cc.response_cob = CobId{0x6B0};
  client = std::make_unique<SdoClient>([this](const CanFrame& f) { node->on_frame(f, now); }, cc);
  std::vector<std::pair<SdoAbortCode, Bytes>> results;
  auto keep = [&results](SdoAbortCode c, Bytes d) { results.emplace_back(c, std::move(d)); };
  client->upload(0x1018, 1, keep);
  client->upload(0x1018, 4, keep);
  client->upload(0x1008, 0, keep, SdoTransfer::Segmented);
  client->upload(0x1008, 0, keep, SdoTransfer::Block);
  for (int i = 0; i < 100 && results.size() < 4; ++i) {
    node->advance(now);
    client->advance(now);
  }
  ASSERT_EQ(results.size(), 4u);
  EXPECT_EQ(results[0].first, SdoAbortCode::None);
  EXPECT_EQ(results[0].second, u32(0x1234));
  EXPECT_EQ(results[1].first, SdoAbortCode::None);
  EXPECT_EQ(results[1].second, u32(42));
  const Bytes name{'o', 'e', 'g', 'w', ' ', 'n', 'o', 'd', 'e'};
  EXPECT_EQ(results[2].first, SdoAbortCode::None);
  EXPECT_EQ(results[2].second, name);
  EXPECT_EQ(results[3].first, SdoAbortCode::None);
  EXPECT_EQ(results[3].second, name);
  // Every answer went out on 6B0h, none on the default 5A0h.
  for (const auto& f : out) EXPECT_NE(f.id, 0x5A0u) << f.to_string();
}

// A channel without valid COB-IDs answers nothing; one valid COB-ID is not enough; both make it
// serve; a write of the host through 1200h changes it at once.
TEST_F(SdoChannelsTest, DisabledByDefaultEnabledByTheHost) {
  make();
  start();
  EXPECT_TRUE(sdo_read(0x1000, 0, 0x6A0).empty());
  write_ok(0x1202, 1, 0x6A0);
  EXPECT_TRUE(sdo_read(0x1000, 0, 0x6A0).empty());  // 1202h:02 still not valid
  EXPECT_FALSE(node->sdo_server(2).rx_cob_id().valid());
  write_ok(0x1202, 2, 0x6C0);
  EXPECT_TRUE(answers(0x6A0, 0x6C0));
  EXPECT_EQ(node->sdo_server(2).rx_cob_id(), CobId{0x6A0});
  // 29-bit COB-IDs are served too.
  write_ok(0x1202, 1, kInvalid | 0x6A0);
  write_ok(0x1202, 1, CobId::kExtendedBit | 0x12345);
  const auto r = rx([] {
    CanFrame f(0x12345, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0});
    f.extended = true;
    return f;
  }());
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x6C0u);
}

// CiA 301 §7.5.2.33: the identifier changes only while bit 31 is set; setting bit 31 disables the
// channel at once, clearing it enables it again.
TEST_F(SdoChannelsTest, IdentifierChangesOnlyWhileNotValid) {
  make();
  start();
  ASSERT_TRUE(answers(0x690, 0x6B0));
  write_refused(0x1201, 1, 0x691, kInvalidValue);
  write_refused(0x1201, 2, 0x6B1, kInvalidValue);
  write_refused(0x1201, 1, CobId::kExtendedBit | 0x690, kInvalidValue);  // bit 29 too
  write_ok(0x1201, 1, 0x690);                                            // the same value: no change
  EXPECT_TRUE(answers(0x690, 0x6B0));
  write_ok(0x1201, 1, kInvalid | 0x690);
  EXPECT_TRUE(sdo_read(0x1000, 0, 0x690).empty());
  EXPECT_FALSE(node->sdo_server(1).rx_cob_id().valid());
  write_ok(0x1201, 1, kInvalid | 0x691);  // changed while not valid
  write_ok(0x1201, 1, 0x691);
  EXPECT_TRUE(sdo_read(0x1000, 0, 0x690).empty());
  EXPECT_TRUE(answers(0x691, 0x6B0));
  EXPECT_EQ(od.get<std::uint32_t>(0x1201, 1), 0x691u);
}

// Restricted CAN-IDs (CiA 301 §7.3.5) and COB-IDs the device already uses are refused with
// 0609 0030h; the entry keeps its value.
TEST_F(SdoChannelsTest, RestrictedAndUsedCobIdsAreRefused) {
  make();
  start();
  for (const std::uint32_t id : {0x000u, 0x001u, 0x07Fu, 0x101u, 0x180u, 0x581u, 0x5FFu, 0x601u, 0x620u, 0x67Fu, 0x6E0u,
                                 0x6FFu, 0x701u, 0x720u, 0x77Fu, 0x780u, 0x7E5u, 0x7FFu}) {
    write_refused(0x1202, 1, id, kInvalidValue);
    write_refused(0x1202, 2, id, kInvalidValue);
  }
  write_refused(0x1202, 1, 0x890, kInvalidValue);  // 11-bit frame with bit 11 set
  write_refused(0x1202, 1, 0x690, kInvalidValue);  // 1201h:01
  write_refused(0x1202, 2, 0x6B0, kInvalidValue);  // 1201h:02
  write_refused(0x1202, 1, 0x1A0, kInvalidValue);  // TPDO1 (valid)
  write_refused(0x1202, 1, 0x080, kInvalidValue);  // SYNC 1005h
  write_refused(0x1202, 1, 0x0A0, kInvalidValue);  // EMCY 1014h
  EXPECT_EQ(od.get<std::uint32_t>(0x1202, 1), kInvalid);
  EXPECT_EQ(od.get<std::uint32_t>(0x1202, 2), kInvalid);
  // One channel's request and response may not share a COB-ID either.
  write_ok(0x1202, 1, 0x6A0);
  write_refused(0x1202, 2, 0x6A0, kInvalidValue);
  // A COB-ID freed (TPDO1 made not valid) may be taken.
  write_ok(0x1800, 1, kInvalid | 0x1A0);
  write_ok(0x1202, 2, 0x1A0);
  EXPECT_TRUE(answers(0x6A0, 0x1A0));
  // Not valid values are always accepted (nothing is occupied).
  write_ok(0x1202, 1, kInvalid | 0x620);
}

// Disabling a channel through itself is confirmed on it, then the channel is silent.
TEST_F(SdoChannelsTest, DisablingThroughTheChannelItselfIsConfirmed) {
  make();
  start();
  const auto r = sdo_write32(0x1201, 1, kInvalid | 0x690, 0x690);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].id, 0x6B0u);
  EXPECT_EQ(r[0].data[0], 0x60);
  EXPECT_TRUE(sdo_read(0x1000, 0, 0x690).empty());
  // Through 1202h once it is enabled, 1201h is re-enabled.
  write_ok(0x1202, 1, 0x6A0);
  write_ok(0x1202, 2, 0x6C0);
  const auto e = sdo_write32(0x1201, 1, 0x690, 0x6A0);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].id, 0x6C0u);
  EXPECT_EQ(e[0].data[0], 0x60);
  EXPECT_TRUE(answers(0x690, 0x6B0));
}

// A transfer in progress on the channel is dropped when it is disabled; the timeout runs per
// channel and counts in next_deadline().
TEST_F(SdoChannelsTest, DisablingDropsATransferAndTimersRunPerChannel) {
  make();
  start();
  // Segmented upload of 1008h started on 1201h.
  auto r = rx(0x690, {0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].data[0], 0x41);
  EXPECT_TRUE(node->sdo_server(1).busy());
  EXPECT_EQ(node->next_deadline(), now + 1s);
  write_ok(0x1201, 1, kInvalid | 0x690);
  EXPECT_FALSE(node->sdo_server(1).busy());
  EXPECT_EQ(node->next_deadline(), std::nullopt);
  write_ok(0x1201, 1, 0x690);
  r = rx(0x690, {0x60, 0, 0, 0, 0, 0, 0, 0});  // upload segment: no transfer any more
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0].data[0], 0x80);
  EXPECT_EQ(get_u32(r[0].data.data() + 4), static_cast<std::uint32_t>(SdoAbortCode::UnknownCommandSpecifier));

  // Timeout on the extra channel: 0504 0000h on 6B0h after 1 s.
  r = rx(0x690, {0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(node->next_deadline(), now + 1s);
  out.clear();
  now += 1s;
  node->advance(now);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0x6B0u);
  EXPECT_EQ(get_u32(out[0].data.data() + 4), static_cast<std::uint32_t>(SdoAbortCode::Timeout));
}

// Reset communication brings back the defaults, then what 1010h saved (as for every 1xxxh
// object), and the servers follow.
TEST_F(SdoChannelsTest, ResetCommunicationRestoresDefaultsThenStoredValues) {
  make();
  start();
  write_ok(0x1201, 1, kInvalid | 0x690);
  write_ok(0x1202, 1, 0x6A0);
  write_ok(0x1202, 2, 0x6C0);
  nmt(0x82);
  EXPECT_EQ(od.get<std::uint32_t>(0x1201, 1), 0x690u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1202, 1), kInvalid);
  EXPECT_TRUE(answers(0x690, 0x6B0));
  EXPECT_TRUE(sdo_read(0x1000, 0, 0x6A0).empty());

  // Saved (communication parameters), then changed again: reset communication gives the saved.
  write_ok(0x1201, 1, kInvalid | 0x690);
  write_ok(0x1202, 1, 0x6A0);
  write_ok(0x1202, 2, 0x6C0);
  ASSERT_EQ(rx(0x620, {0x2F, 0x02, 0x12, 0x03, 0x7F, 0, 0, 0}).at(0).data[0], 0x60);  // 1202h:03 = 7Fh
  write_ok(0x1010, 2, ParameterStore::kSaveSignature);
  write_ok(0x1202, 1, kInvalid | 0x6A0);
  write_ok(0x1201, 1, 0x690);
  nmt(0x82);
  EXPECT_EQ(od.get<std::uint32_t>(0x1201, 1), kInvalid | 0x690);
  EXPECT_EQ(od.get<std::uint32_t>(0x1202, 1), 0x6A0u);
  EXPECT_EQ(od.get<std::uint8_t>(0x1202, 3), 0x7Fu);
  EXPECT_TRUE(sdo_read(0x1000, 0, 0x690).empty());
  EXPECT_TRUE(answers(0x6A0, 0x6C0));

  // A new Node on the saved file applies it at power-on.
  od.find(0x1202, 1)->value = u32(kInvalid);
  make();
  start();
  EXPECT_EQ(od.get<std::uint32_t>(0x1202, 1), 0x6A0u);
  EXPECT_TRUE(answers(0x6A0, 0x6C0));
  EXPECT_TRUE(sdo_read(0x1000, 0, 0x690).empty());
}

// CiA 301 §7.3.2.2.1: no SDO in stopped, on every channel; entering stopped drops transfers.
TEST_F(SdoChannelsTest, StoppedSilencesTheExtraChannels) {
  make();
  start();
  auto r = rx(0x690, {0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});
  ASSERT_EQ(r.size(), 1u);
  nmt(0x02);
  EXPECT_EQ(node->state(), NmtState::Stopped);
  EXPECT_FALSE(node->sdo_server(1).busy());
  EXPECT_TRUE(sdo_read(0x1000, 0, 0x690).empty());
  nmt(0x01);
  EXPECT_TRUE(answers(0x690, 0x6B0));
  nmt(0x80);
  EXPECT_TRUE(answers(0x690, 0x6B0));
}

}  // namespace
}  // namespace oegw::canopen
