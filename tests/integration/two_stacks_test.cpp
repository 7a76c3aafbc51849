// Tier 2: two CANopen stacks over the in-process virtual bus — a device (Node) and a host
// (Master) — with a simulated clock. Every exchange below goes frame by frame over the bus.
#include <gtest/gtest.h>

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "canopen/master.hpp"
#include "canopen/node.hpp"
#include "virtual_network.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

namespace {

constexpr NodeId kDevice{0x20};

struct SdoResult {
  SdoAbortCode code = SdoAbortCode::GeneralError;
  Bytes data;
  bool done = false;
};

class TwoStacks : public ::testing::Test {
 protected:
  TwoStacks() {
    store_dir_ =
        std::filesystem::temp_directory_path() / ("oegw-two-stacks-" + std::to_string(::getpid()) + "-" +
                                                  ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(store_dir_);
    std::filesystem::create_directories(store_dir_);
    build_device_od();
    make_device();
    host_ = std::make_unique<Master>(host_od_, net_.sink("host"),
                                     MasterConfig{.heartbeat_entries = 4, .sdo_timeout = 500ms});
    net_.attach("host", *host_);
    host_->on_boot = [this](NodeId n) { boots_.push_back(n); };
    host_->on_state = [this](NodeId n, NmtState s) {
      if (n == kDevice) states_.push_back(s);
    };
    host_->on_heartbeat_timeout = [this](NodeId n) { timeouts_.emplace_back(n, net_.now()); };
    host_->on_emcy = [this](const EmcyMessage& m, TimePoint) { emcys_.push_back(m); };
    host_->on_other_frame = [this](const CanFrame& f, TimePoint) { others_.push_back(f); };
    EXPECT_EQ(host_->monitor_heartbeat(kDevice, 150), SdoAbortCode::None);
    net_.bus().set_logging(true);
  }
  ~TwoStacks() override { std::filesystem::remove_all(store_dir_); }

  void build_device_od() {
    device_od_->add_array(0x6000, "Read input 8-bit", DataType::Unsigned8, Access::ReadOnly, 2, {0}, true);
    device_od_->add_array(0x6401, "Read analogue input 16-bit", DataType::Integer16, Access::ReadOnly, 2,
                          encode<std::int16_t>(0), true);
    device_od_->add_array(0x6200, "Write output 8-bit", DataType::Unsigned8, Access::ReadWrite, 1, {0}, true);
    device_od_->add_var(0x2000, "Blob", DataType::Domain, Access::ReadWrite, {});
    device_od_->find(0x2000, 0)->max_size = 4096;
    install_tpdo(*device_od_, 1,
                 PdoParameters{.cob_id = cob::kTpdo1 + kDevice.value(),
                               .transmission_type = 0xFF,
                               .mapping = {pdo_map(0x6401, 1, 16), pdo_map(0x6401, 2, 16)}});
    install_rpdo(*device_od_, 1,
                 PdoParameters{.cob_id = cob::kRpdo1 + kDevice.value(),
                               .transmission_type = 0xFF,
                               .mapping = {pdo_map(0x6200, 1, 8)}});
  }

  void make_device() {
    NodeConfig cfg;
    cfg.node_id = kDevice;
    cfg.device_type = 0x000F0191;
    cfg.device_name = "oegw two-stacks test device";
    cfg.identity = {.vendor = 0x1234, .product = 0x852, .revision = 1, .serial = 42};
    cfg.heartbeat_ms = 100;
    cfg.store_path = store_dir_ / "params.txt";
    device_ = std::make_unique<Node>(*device_od_, cfg, net_.sink("device"));
    net_.attach("device", *device_);
  }

  SdoResult upload(std::uint16_t index, std::uint8_t sub, SdoTransfer mode = SdoTransfer::Auto) {
    SdoResult r;
    host_->sdo(kDevice).upload(
        index, sub,
        [&r](SdoAbortCode c, Bytes d) {
          r.code = c;
          r.data = std::move(d);
          r.done = true;
        },
        mode);
    net_.run_for(2s);
    EXPECT_TRUE(r.done);
    return r;
  }
  SdoAbortCode download(std::uint16_t index, std::uint8_t sub, Bytes data, SdoTransfer mode = SdoTransfer::Auto) {
    SdoResult r;
    host_->sdo(kDevice).download(
        index, sub, std::move(data),
        [&r](SdoAbortCode c, Bytes) {
          r.code = c;
          r.done = true;
        },
        mode);
    net_.run_for(2s);
    EXPECT_TRUE(r.done);
    return r.code;
  }
  static Bytes u32(std::uint32_t v) { return encode<std::uint32_t>(v); }

  void boot() {
    (void)device_->start(net_.now());
    net_.settle();
  }

  std::filesystem::path store_dir_;
  oegw::testing::VirtualNetwork net_;
  std::unique_ptr<ObjectDictionary> device_od_ = std::make_unique<ObjectDictionary>();
  ObjectDictionary host_od_;
  std::unique_ptr<Node> device_;
  std::unique_ptr<Master> host_;
  std::vector<NodeId> boots_;
  std::vector<NmtState> states_;
  std::vector<std::pair<NodeId, TimePoint>> timeouts_;
  std::vector<EmcyMessage> emcys_;
  std::vector<CanFrame> others_;
};

TEST_F(TwoStacks, BootUpIsSeenAndHeartbeatCarriesPreOperational) {
  boot();
  ASSERT_EQ(boots_.size(), 1u);
  EXPECT_EQ(boots_[0], kDevice);
  ASSERT_FALSE(net_.bus().log().empty());
  EXPECT_EQ(net_.bus().log()[0].frame, CanFrame(0x720, {0x00}));
  net_.run_for(100ms);
  ASSERT_FALSE(states_.empty());
  EXPECT_EQ(states_.back(), NmtState::PreOperational);
  EXPECT_EQ(device_->state(), NmtState::PreOperational);
}

TEST_F(TwoStacks, ExpeditedSegmentedAndBlockTransfersBothWays) {
  boot();
  auto dt = upload(0x1000, 0);
  EXPECT_EQ(dt.code, SdoAbortCode::None);
  EXPECT_EQ(dt.data, u32(0x000F0191));
  auto name = upload(0x1008, 0);  // 27 bytes: segmented
  EXPECT_EQ(name.code, SdoAbortCode::None);
  EXPECT_EQ(std::string(name.data.begin(), name.data.end()), "oegw two-stacks test device");
  auto name_block = upload(0x1008, 0, SdoTransfer::Block);
  EXPECT_EQ(name_block.data, name.data);

  Bytes blob(889);
  for (std::size_t i = 0; i < blob.size(); ++i) blob[i] = static_cast<std::uint8_t>(i * 7 + 3);
  EXPECT_EQ(download(0x2000, 0, blob, SdoTransfer::Segmented), SdoAbortCode::None);
  EXPECT_EQ(upload(0x2000, 0, SdoTransfer::Block).data, blob);
  std::reverse(blob.begin(), blob.end());
  EXPECT_EQ(download(0x2000, 0, blob, SdoTransfer::Block), SdoAbortCode::None);
  EXPECT_EQ(upload(0x2000, 0, SdoTransfer::Segmented).data, blob);
  EXPECT_EQ(download(0x1017, 0, encode<std::uint16_t>(250)), SdoAbortCode::None);
  EXPECT_EQ(device_od_->get<std::uint16_t>(0x1017, 0), 250);
}

TEST_F(TwoStacks, RefusedWritesComeBackAsAbortCodesAndChangeNothing) {
  boot();
  EXPECT_EQ(download(0x1000, 0, u32(1)), SdoAbortCode::WriteOfReadOnly);
  EXPECT_EQ(download(0x1017, 0, u32(1)), SdoAbortCode::LengthTooHigh);
  EXPECT_EQ(download(0x3000, 0, u32(1)), SdoAbortCode::ObjectDoesNotExist);
  EXPECT_EQ(download(0x1018, 9, u32(1)), SdoAbortCode::SubIndexDoesNotExist);
  Bytes too_big(4097, 1);
  EXPECT_NE(download(0x2000, 0, too_big, SdoTransfer::Block), SdoAbortCode::None);
  EXPECT_TRUE(device_od_->find(0x2000, 0)->value.empty());
  EXPECT_EQ(device_od_->get<std::uint32_t>(0x1000, 0), 0x000F0191u);
}

TEST_F(TwoStacks, PdoMappingChangedBySdoThenInputsArriveAsTpdo) {
  boot();
  // CiA 301 §7.3.5 dynamic mapping procedure: invalidate, clear, write entries, set count, validate.
  EXPECT_EQ(download(0x1A00, 1, u32(pdo_map(0x6000, 1, 8))), SdoAbortCode::CannotTransferDeviceState)
      << "an entry is written only while sub-index 0 is 0";
  EXPECT_EQ(download(0x1800, 1, u32(CobId::kInvalidBit | 0x1A0)), SdoAbortCode::None);
  EXPECT_EQ(download(0x1A00, 0, {0}), SdoAbortCode::None);
  EXPECT_EQ(download(0x1A00, 1, u32(pdo_map(0x6000, 1, 8))), SdoAbortCode::None);
  EXPECT_EQ(download(0x1A00, 2, u32(pdo_map(0x6000, 2, 8))), SdoAbortCode::None);
  EXPECT_EQ(download(0x1A00, 3, u32(pdo_map(0x6200, 9, 8))), SdoAbortCode::ObjectDoesNotExist)
      << "an entry naming a missing sub-index is refused";
  EXPECT_EQ(download(0x1A00, 3, u32(pdo_map(0x1000, 0, 32))), SdoAbortCode::CannotBeMapped);
  EXPECT_EQ(download(0x1A00, 0, {9}), SdoAbortCode::MappingExceedsPdoLength) << "capacity is 8 entries";
  EXPECT_EQ(download(0x1A00, 0, {2}), SdoAbortCode::None);
  EXPECT_EQ(download(0x1800, 1, u32(0x1A0)), SdoAbortCode::None);

  host_->nmt().start(kDevice);
  net_.run_for(10ms);
  EXPECT_EQ(device_->state(), NmtState::Operational);
  others_.clear();
  device_od_->set<std::uint8_t>(0x6000, 1, 0x5A);
  device_od_->set<std::uint8_t>(0x6000, 2, 0xA5);
  net_.run_for(10ms);
  ASSERT_FALSE(others_.empty());
  EXPECT_EQ(others_.back(), CanFrame(0x1A0, {0x5A, 0xA5}));
}

TEST_F(TwoStacks, RpdoWritesOutputsAndAShortRpdoRaisesEmcy8210) {
  boot();
  host_->nmt().start(kDevice);
  net_.run_for(10ms);
  net_.bus().inject(CanFrame(0x220, {0x0F}), "host");
  net_.run_for(1ms);
  EXPECT_EQ(device_od_->get<std::uint8_t>(0x6200, 1), 0x0F);
  net_.bus().inject(CanFrame(0x220, {}), "host");
  net_.run_for(1ms);
  ASSERT_EQ(emcys_.size(), 1u);
  EXPECT_EQ(emcys_[0].node, kDevice);
  EXPECT_EQ(emcys_[0].code, 0x8210);
  EXPECT_EQ(device_od_->get<std::uint8_t>(0x6200, 1), 0x0F) << "a short RPDO changes nothing";
  net_.bus().inject(CanFrame(0x220, {0x0A}), "host");
  net_.run_for(1ms);
  ASSERT_EQ(emcys_.size(), 2u) << "a good RPDO ends the length error";
  EXPECT_EQ(emcys_[1].code, 0x0000);
  EXPECT_EQ(device_od_->get<std::uint8_t>(0x6200, 1), 0x0A);
}

TEST_F(TwoStacks, NmtCommandsDriveTheStateMachine) {
  boot();
  host_->nmt().start(kDevice);
  net_.run_for(200ms);
  EXPECT_EQ(states_.back(), NmtState::Operational);
  host_->nmt().stop(kDevice);
  net_.run_for(200ms);
  EXPECT_EQ(states_.back(), NmtState::Stopped);
  // CiA 301 Table 47: no SDO in Stopped; the client times out with 0504 0000h.
  EXPECT_EQ(upload(0x1000, 0).code, SdoAbortCode::Timeout);
  host_->nmt().enter_pre_operational(kDevice);
  net_.run_for(200ms);
  EXPECT_EQ(states_.back(), NmtState::PreOperational);
  EXPECT_EQ(upload(0x1000, 0).code, SdoAbortCode::None);
  boots_.clear();
  host_->nmt().reset_communication(kDevice);
  net_.run_for(10ms);
  EXPECT_EQ(boots_.size(), 1u);
  host_->nmt().send(NmtCommand::ResetNode, NodeId{0});  // all nodes
  net_.run_for(10ms);
  EXPECT_EQ(boots_.size(), 2u);
}

TEST_F(TwoStacks, HeartbeatLossIsDetectedAtTheConsumerTime) {
  boot();
  net_.run_for(1s);
  EXPECT_TRUE(timeouts_.empty());
  // The device goes silent right after a heartbeat: find when that heartbeat was.
  std::optional<TimePoint> last_hb;
  net_.bus().set_tap([&](const BusRecord& r) {
    if (r.frame.id == 0x720) last_hb = r.time;
  });
  net_.run_for(100ms);
  ASSERT_TRUE(last_hb.has_value());
  net_.bus().drop_next(1000, [](const CanFrame& f) { return f.id == 0x720; });
  net_.run_for(500ms);
  ASSERT_EQ(timeouts_.size(), 1u);
  EXPECT_EQ(timeouts_[0].first, kDevice);
  EXPECT_EQ(timeouts_[0].second - *last_hb, 150ms) << "1016h consumer time is 150 ms";
}

TEST_F(TwoStacks, StoredParametersSurviveResetAndRestoreBringsDefaultsBack) {
  boot();
  EXPECT_EQ(download(0x1017, 0, encode<std::uint16_t>(250)), SdoAbortCode::None);
  // Novotechnik §7.1: "save" = 73 61 76 65 to 1010h:01.
  EXPECT_EQ(download(0x1010, 1, {0x73, 0x61, 0x76, 0x65}), SdoAbortCode::None);
  EXPECT_EQ(download(0x1010, 1, {0x73, 0x61, 0x76, 0x00}), SdoAbortCode::CannotTransfer);
  host_->nmt().reset_node(kDevice);
  net_.run_for(10ms);
  EXPECT_EQ(device_od_->get<std::uint16_t>(0x1017, 0), 250);
  // A new process on the same store file (power cycle) comes up with the stored value too.
  net_.bus().set_logging(false);
  net_.detach("device");
  device_.reset();
  device_od_ = std::make_unique<ObjectDictionary>();  // services leave observers in their OD
  build_device_od();
  make_device();
  boot();
  EXPECT_EQ(device_od_->get<std::uint16_t>(0x1017, 0), 250);
  // "load" to 1011h:01 restores the defaults at the next reset.
  EXPECT_EQ(download(0x1011, 1, {0x6C, 0x6F, 0x61, 0x64}), SdoAbortCode::None);
  host_->nmt().reset_node(kDevice);
  net_.run_for(10ms);
  EXPECT_EQ(device_od_->get<std::uint16_t>(0x1017, 0), 100);
}

TEST_F(TwoStacks, BusOffAndErrorPassiveBecomeEmcysAndFollow1029h) {
  boot();
  host_->nmt().start(kDevice);
  net_.run_for(10ms);
  device_->on_bus_event(BusEvent::ErrorPassive, net_.now());
  net_.run_for(1ms);
  ASSERT_EQ(emcys_.size(), 1u);
  EXPECT_EQ(emcys_[0].code, 0x8120);
  EXPECT_EQ(emcys_[0].error_register & 0x11, 0x11) << "generic + communication bits of 1001h";
  // Bus-off in operational with 1029h:01 = 0: the device falls back to pre-operational.
  device_->on_bus_event(BusEvent::BusOff, net_.now());
  EXPECT_EQ(device_->state(), NmtState::PreOperational);
  device_->on_bus_event(BusEvent::Restarted, net_.now());
  net_.run_for(1ms);
  ASSERT_GE(emcys_.size(), 3u);
  EXPECT_EQ(emcys_[1].code, 0x0000) << "8120h cleared on restart: error reset";
  EXPECT_EQ(emcys_[2].code, 0x8140) << "recovered from bus off";
  // 1029h:01 = 1: no state change on a communication error.
  EXPECT_EQ(download(0x1029, 1, {1}), SdoAbortCode::None);
  EXPECT_EQ(download(0x1029, 1, {3}), SdoAbortCode::ValueTooHigh);
  host_->nmt().start(kDevice);
  net_.run_for(10ms);
  device_->on_bus_event(BusEvent::BusOff, net_.now());
  EXPECT_EQ(device_->state(), NmtState::Operational);
}

}  // namespace
