// Novotechnik406Driver against Novotechnik406Sim over the virtual bus, simulated clock.
// Document: the Novotechnik "CANopen" sensor protocol document (V02), §n.
#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "canopen/master.hpp"
#include "subdevices/families.hpp"
#include "subdevices/novotechnik_406.hpp"
#include "subdevices/sim/novotechnik_406_sim.hpp"
#include "virtual_network.hpp"

using namespace oegw::canopen;
using namespace oegw::subdevices;
using namespace std::chrono_literals;
using oegw::subdevices::sim::Novotechnik406Sim;
using oegw::subdevices::sim::Novotechnik406SimConfig;
using Bytes = std::vector<std::uint8_t>;

namespace {

constexpr NodeId kNode{0x7F};  // §3.1 default node-ID 127

class NovotechnikSim : public ::testing::Test {
 protected:
  NovotechnikSim() {
    dir_ = std::filesystem::temp_directory_path() / ("oegw-novo-" + std::to_string(::getpid()) + "-" +
                                                     ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    Novotechnik406SimConfig cfg;
    cfg.store_path = dir_ / "params.txt";
    sim_ = std::make_unique<Novotechnik406Sim>(net_.sink("sim"), cfg);
    net_.attach("sim", *sim_);
    probe_ = net_.sink("probe");
    host_ = std::make_unique<Master>(host_od_, net_.sink("host"),
                                     MasterConfig{.heartbeat_entries = 2, .sdo_timeout = 500ms});
    net_.attach("host", *host_);
    driver_ = std::make_unique<Novotechnik406Driver>(kNode, net_.sink("driver"), Novotechnik406Options{});
    host_->on_other_frame = [this](const CanFrame& f, TimePoint now) {
      for (const std::uint32_t id : driver_->consumed_cob_ids())
        if (f.id == id) (void)driver_->on_frame(f, now);
    };
    host_->on_emcy = [this](const EmcyMessage& m, TimePoint now) {
      if (m.node == kNode) decoded_.push_back(driver_->on_emcy(m, now));
    };
    net_.bus().set_logging(true);
  }
  ~NovotechnikSim() override { std::filesystem::remove_all(dir_); }

  void boot() {
    sim_->start(net_.now());
    net_.settle();
  }
  // Sends one raw frame from the probe and returns the frames on `reply_id` that followed.
  std::vector<CanFrame> exchange(std::uint32_t id, Bytes bytes, std::uint32_t reply_id) {
    return net_.exchange("probe", CanFrame(id, std::span<const std::uint8_t>(bytes)), reply_id);
  }
  std::vector<CanFrame> frames(std::uint32_t id) { return net_.logged(id); }
  CanFrame sdo(Bytes req) {
    const auto r = exchange(0x600 + kNode.value(), std::move(req), 0x580 + kNode.value());
    EXPECT_EQ(r.size(), 1u);
    return r.empty() ? CanFrame{} : r[0];
  }
  SdoAbortCode download(std::uint16_t index, std::uint8_t sub, Bytes data) {
    SdoAbortCode code = SdoAbortCode::GeneralError;
    bool done = false;
    host_->sdo(kNode).download(index, sub, std::move(data), [&](SdoAbortCode c, Bytes) {
      code = c;
      done = true;
    });
    net_.run_for(50ms);
    EXPECT_TRUE(done);
    return code;
  }
  // The driver's configuration() as the network manager would apply it, then NMT start.
  void configure_and_start() {
    for (const SdoWrite& w : driver_->configuration())
      ASSERT_EQ(download(w.index, w.sub, w.data), SdoAbortCode::None) << w.what;
    driver_->on_online(net_.now());
    host_->nmt().start(kNode);
    net_.run_for(1ms);
    ASSERT_EQ(sim_->node().state(), NmtState::Operational);
  }
  const SignalValue& pos() const { return driver_->value(Novotechnik406Driver::kPosition); }
  const SignalValue& spd() const { return driver_->value(Novotechnik406Driver::kSpeed); }

  std::filesystem::path dir_;
  oegw::testing::VirtualNetwork net_;
  std::unique_ptr<Novotechnik406Sim> sim_;
  FrameSink probe_;
  ObjectDictionary host_od_;
  std::unique_ptr<Master> host_;
  std::unique_ptr<Novotechnik406Driver> driver_;
  std::vector<DecodedEmcy> decoded_;
};

// §3.1 default node-ID 7Fh: boot-up on 77Fh; §4.1 1000h = 00020196h, 1018h:01 = 0182h.
TEST_F(NovotechnikSim, BootUpAndIdentityObjects) {
  boot();
  ASSERT_FALSE(frames(0x77F).empty());
  EXPECT_EQ(frames(0x77F)[0], CanFrame(0x77F, {0x00}));
  EXPECT_EQ(sdo({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}),
            CanFrame(0x5FF, {0x43, 0x00, 0x10, 0x00, 0x96, 0x01, 0x02, 0x00}));
  EXPECT_EQ(sdo({0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0}),
            CanFrame(0x5FF, {0x43, 0x18, 0x10, 0x01, 0x82, 0x01, 0x00, 0x00}));
  EXPECT_EQ(sdo({0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0}),
            CanFrame(0x5FF, {0x43, 0x18, 0x10, 0x02, 0xE0, 0x0B, 0x00, 0x00}));
  // §4.1 1800h:01 default 40000180h + node-ID, 1800h:02 FEh, 1A00h:01 60200120h.
  EXPECT_EQ(sdo({0x40, 0x00, 0x18, 0x01, 0, 0, 0, 0}),
            CanFrame(0x5FF, {0x43, 0x00, 0x18, 0x01, 0xFF, 0x01, 0x00, 0x40}));
  EXPECT_EQ(sdo({0x40, 0x00, 0x18, 0x02, 0, 0, 0, 0}), CanFrame(0x5FF, {0x4F, 0x00, 0x18, 0x02, 0xFE, 0, 0, 0}));
  EXPECT_EQ(sdo({0x40, 0x00, 0x1A, 0x01, 0, 0, 0, 0}),
            CanFrame(0x5FF, {0x43, 0x00, 0x1A, 0x01, 0x20, 0x01, 0x20, 0x60}));
  // §4.2 6002h default 002C0000h, 650Ah:03 002BFFFFh, 6504h C002h.
  EXPECT_EQ(sdo({0x40, 0x02, 0x60, 0x00, 0, 0, 0, 0}),
            CanFrame(0x5FF, {0x43, 0x02, 0x60, 0x00, 0x00, 0x00, 0x2C, 0x00}));
  EXPECT_EQ(sdo({0x40, 0x0A, 0x65, 0x03, 0, 0, 0, 0}),
            CanFrame(0x5FF, {0x43, 0x0A, 0x65, 0x03, 0xFF, 0xFF, 0x2B, 0x00}));
  EXPECT_EQ(sdo({0x40, 0x04, 0x65, 0x00, 0, 0, 0, 0}), CanFrame(0x5FF, {0x4B, 0x04, 0x65, 0x00, 0x02, 0xC0, 0, 0}));
}

// §7.1 examples, byte for byte.
TEST_F(NovotechnikSim, DocumentSdoExamplesStoreRestoreAndNodeId) {
  boot();
  // "object index 0x1010 subindex 01 'store all parameters'"
  EXPECT_EQ(sdo({0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65}),
            CanFrame(0x5FF, {0x60, 0x10, 0x10, 0x01, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_TRUE(std::filesystem::exists(dir_ / "params.txt"));
  // "object index 0x1011 subindex 01 'restore all parameters'"
  EXPECT_EQ(sdo({0x23, 0x11, 0x10, 0x01, 0x6C, 0x6F, 0x61, 0x64}),
            CanFrame(0x5FF, {0x60, 0x11, 0x10, 0x01, 0x00, 0x00, 0x00, 0x00}));
  // A wrong signature is refused (§7.3 08000020h data transport error).
  EXPECT_EQ(sdo({0x23, 0x10, 0x10, 0x01, 0x00, 0x00, 0x00, 0x00}),
            CanFrame(0x5FF, {0x80, 0x10, 0x10, 0x01, 0x20, 0x00, 0x00, 0x08}));
  // "object index 0x2000 'set new node-ID' with 0x40" ...
  EXPECT_EQ(sdo({0x2F, 0x00, 0x20, 0x00, 0x40, 0x00, 0x00, 0x00}),
            CanFrame(0x5FF, {0x60, 0x00, 0x20, 0x00, 0x00, 0x00, 0x00, 0x00}));
  // ... "effective after a communication restart": boot-up and SDO on the new node-ID 40h.
  (void)exchange(0x000, {0x82, 0x7F}, 0x740);
  EXPECT_EQ(frames(0x740), std::vector<CanFrame>{CanFrame(0x740, {0x00})});
  const auto r = exchange(0x640, {0x40, 0x00, 0x18, 0x01, 0, 0, 0, 0}, 0x5C0);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0], CanFrame(0x5C0, {0x43, 0x00, 0x18, 0x01, 0xC0, 0x01, 0x00, 0x40}));  // TPDO1 = 40000180h + 40h
}

// §8.2 steps 1..5 with the document's mapping frames; §7.3 abort codes.
TEST_F(NovotechnikSim, DocumentMappingFramesAndAborts) {
  boot();
  EXPECT_EQ(sdo({0x23, 0x00, 0x18, 0x01, 0xFF, 0x01, 0x00, 0xC0}).data[0], 0x60);  // step 1: C00001FFh
  EXPECT_EQ(sdo({0x2F, 0x00, 0x1A, 0x00, 0x00, 0, 0, 0}).data[0], 0x60);           // step 2
  EXPECT_EQ(sdo({0x23, 0x00, 0x1A, 0x01, 0x20, 0x01, 0x20, 0x60}),                 // step 3, mapping #1
            CanFrame(0x5FF, {0x60, 0x00, 0x1A, 0x01, 0, 0, 0, 0}));
  EXPECT_EQ(sdo({0x23, 0x00, 0x1A, 0x02, 0x10, 0x01, 0x30, 0x60}),  // mapping #2
            CanFrame(0x5FF, {0x60, 0x00, 0x1A, 0x02, 0, 0, 0, 0}));
  EXPECT_EQ(sdo({0x2F, 0x00, 0x1A, 0x00, 0x02, 0, 0, 0}).data[0], 0x60);           // step 4
  EXPECT_EQ(sdo({0x23, 0x00, 0x18, 0x01, 0xFF, 0x01, 0x00, 0x40}).data[0], 0x60);  // step 5
  // §7.3: 06010002h "object is read only" (6004h), 06020000h "object does not exist".
  EXPECT_EQ(sdo({0x23, 0x04, 0x60, 0x00, 1, 0, 0, 0}),
            CanFrame(0x5FF, {0x80, 0x04, 0x60, 0x00, 0x02, 0x00, 0x01, 0x06}));
  EXPECT_EQ(sdo({0x40, 0x99, 0x60, 0x00, 0, 0, 0, 0}),
            CanFrame(0x5FF, {0x80, 0x99, 0x60, 0x00, 0x00, 0x00, 0x02, 0x06}));
  // §4.2 6031h:02 allows 1, 2, 3, 6, 12, 25 ms: 4 -> 06090030h "value exceeded"; 6 sets 2010h:02 = 6 (§5.2).
  EXPECT_EQ(sdo({0x2B, 0x31, 0x60, 0x02, 0x04, 0x00, 0, 0}).data[0], 0x80);
  EXPECT_EQ(sdo({0x2B, 0x31, 0x60, 0x02, 0x06, 0x00, 0, 0}).data[0], 0x60);
  EXPECT_EQ(sdo({0x40, 0x10, 0x20, 0x02, 0, 0, 0, 0}), CanFrame(0x5FF, {0x4F, 0x10, 0x20, 0x02, 0x06, 0, 0, 0}));
  // §5.4: 6001h writable only with scaling on; with 6000h bit 2 set -> 08000022h "wrong state".
  EXPECT_EQ(sdo({0x2F, 0x00, 0x60, 0x00, 0x04, 0, 0, 0}).data[0], 0x60);
  EXPECT_EQ(sdo({0x23, 0x01, 0x60, 0x00, 0x00, 0x10, 0x00, 0x00}),
            CanFrame(0x5FF, {0x80, 0x01, 0x60, 0x00, 0x22, 0x00, 0x00, 0x08}));
  EXPECT_EQ(sdo({0x2F, 0x00, 0x60, 0x00, 0x00, 0, 0, 0}).data[0], 0x60);
  // Scaling on: 6001h = 1000h steps; "Changes of this object also changes object 0x6002" (x 44 turns).
  EXPECT_EQ(sdo({0x23, 0x01, 0x60, 0x00, 0x00, 0x10, 0x00, 0x00}).data[0], 0x60);
  EXPECT_EQ(sdo({0x40, 0x02, 0x60, 0x00, 0, 0, 0, 0}),
            CanFrame(0x5FF, {0x43, 0x02, 0x60, 0x00, 0x00, 0xC0, 0x02, 0x00}));
  // §5.4 "The resolution can only be reduced": 10001h is too high.
  EXPECT_EQ(sdo({0x23, 0x01, 0x60, 0x00, 0x01, 0x00, 0x01, 0x00}).data[0], 0x80);
}

// §6 LSS, the document's frames.
TEST_F(NovotechnikSim, DocumentLssFrames) {
  boot();
  // "0x7E5 8 0x04 0x00 ..." (switch state global: waiting) — no answer.
  EXPECT_TRUE(exchange(0x7E5, {0x04, 0x00, 0, 0, 0, 0, 0, 0}, 0x7E4).empty());
  // Switch mode selective: vendor 0182h, product 0BE0h, revision 00010003h, serial 12345678h -> 44h.
  EXPECT_TRUE(exchange(0x7E5, {0x40, 0x82, 0x01, 0x00, 0x00, 0, 0, 0}, 0x7E4).empty());
  EXPECT_TRUE(exchange(0x7E5, {0x41, 0xE0, 0x0B, 0x00, 0x00, 0, 0, 0}, 0x7E4).empty());
  EXPECT_TRUE(exchange(0x7E5, {0x42, 0x03, 0x00, 0x01, 0x00, 0, 0, 0}, 0x7E4).empty());
  EXPECT_EQ(exchange(0x7E5, {0x43, 0x78, 0x56, 0x34, 0x12, 0, 0, 0}, 0x7E4),
            std::vector<CanFrame>{CanFrame(0x7E4, {0x44, 0, 0, 0, 0, 0, 0, 0})});
  // §6.1 configure node-ID: 1..127 -> err 0; 128 -> err 1 "Node-ID out of range".
  EXPECT_EQ(exchange(0x7E5, {0x11, 0x20, 0, 0, 0, 0, 0, 0}, 0x7E4),
            std::vector<CanFrame>{CanFrame(0x7E4, {0x11, 0x00, 0, 0, 0, 0, 0, 0})});
  EXPECT_EQ(exchange(0x7E5, {0x11, 0x80, 0, 0, 0, 0, 0, 0}, 0x7E4),
            std::vector<CanFrame>{CanFrame(0x7E4, {0x11, 0x01, 0, 0, 0, 0, 0, 0})});
  // §6.2 configure bit rate, table index 04h = 125 kBaud -> err 0.
  EXPECT_EQ(exchange(0x7E5, {0x13, 0x00, 0x04, 0, 0, 0, 0, 0}, 0x7E4),
            std::vector<CanFrame>{CanFrame(0x7E4, {0x13, 0x00, 0, 0, 0, 0, 0, 0})});
  // §6.3 store configuration -> err 0.
  EXPECT_EQ(exchange(0x7E5, {0x17, 0, 0, 0, 0, 0, 0, 0}, 0x7E4),
            std::vector<CanFrame>{CanFrame(0x7E4, {0x17, 0x00, 0, 0, 0, 0, 0, 0})});
  // Back to waiting, then the new node-ID is active after reset communication.
  (void)exchange(0x7E5, {0x04, 0x00, 0, 0, 0, 0, 0, 0}, 0x7E4);
  (void)exchange(0x000, {0x82, 0x7F}, 0x720);
  EXPECT_EQ(frames(0x720), std::vector<CanFrame>{CanFrame(0x720, {0x00})});
  // Switch mode global "0x04 0x01": configuration state again (a node-ID write is answered).
  (void)exchange(0x7E5, {0x04, 0x01, 0, 0, 0, 0, 0, 0}, 0x7E4);
  EXPECT_EQ(exchange(0x7E5, {0x11, 0x7F, 0, 0, 0, 0, 0, 0}, 0x7E4).size(), 1u);
}

TEST_F(NovotechnikSim, DriverConfiguresAndReadsPositionAndSpeedOnTheEventTimer) {
  boot();
  configure_and_start();
  net_.bus().clear_log();
  sim_->set_position(0x12345, net_.now());
  sim_->set_speed(-150, net_.now());
  net_.run_for(25ms);
  const auto tpdos = frames(0x1FF);
  // Event timer 10 ms (driver default, type 254): entering operational sends once, then every 10 ms.
  ASSERT_GE(tpdos.size(), 2u);
  // Position, speed, then (as the driver maps them, §8.2) CAM state and work area state.
  EXPECT_EQ(tpdos.back(), CanFrame(0x1FF, {0x45, 0x23, 0x01, 0x00, 0x6A, 0xFF, 0x00, 0x00}));
  EXPECT_EQ(pos().value, 0x12345);
  EXPECT_EQ(pos().status, SignalStatus::Valid);
  EXPECT_EQ(spd().value, -150);
  // Type 254: a change alone sends nothing before the timer.
  net_.bus().clear_log();
  net_.run_for(1ms);
  const std::size_t before = frames(0x1FF).size();
  sim_->set_position(0x20000, net_.now());
  net_.run_for(1ms);
  EXPECT_EQ(frames(0x1FF).size(), before);
  net_.run_for(10ms);
  EXPECT_EQ(pos().value, 0x20000);
  EXPECT_EQ(driver_->counters().wrong_length, 0u);
}

TEST_F(NovotechnikSim, MeasurementErrorGoesToErrorAndRecovers) {
  boot();
  configure_and_start();
  sim_->set_position(5000, net_.now());
  net_.run_for(20ms);
  ASSERT_EQ(pos().status, SignalStatus::Valid);
  sim_->inject_fault(Novotechnik406Sim::Fault::Measurement, net_.now());
  net_.run_for(1ms);
  // The EMCY arrives first (5051h/1/0), then the TPDO with 7FFFFFFCh.
  ASSERT_FALSE(decoded_.empty());
  EXPECT_EQ(decoded_.back().code, 0x5051);
  EXPECT_TRUE(decoded_.back().error);
  EXPECT_NE(decoded_.back().text.find("measurement error"), std::string::npos);
  EXPECT_EQ(pos().status, SignalStatus::Error);
  EXPECT_EQ(pos().value, 0);
  net_.run_for(20ms);
  EXPECT_EQ(driver_->last_error_position(), 0x7FFFFFFCu);
  EXPECT_EQ(pos().status, SignalStatus::Error);
  EXPECT_EQ(spd().status, SignalStatus::Error);
  EXPECT_EQ(sdo({0x40, 0x03, 0x65, 0x00, 0, 0, 0, 0}).data[4], 0x01);  // 6503h alarm bit 0 (§10.2)
  ASSERT_TRUE(sim_->clear_fault(net_.now()));
  net_.run_for(1ms);
  EXPECT_EQ(decoded_.back().code, 0x5051) << "§9.1 5051h/0/0 \"Valid position\"";
  EXPECT_FALSE(decoded_.back().error);
  EXPECT_NE(pos().status, SignalStatus::Error);
  net_.run_for(20ms);
  EXPECT_EQ(pos().status, SignalStatus::Valid);
  EXPECT_EQ(pos().value, 5000);
}

// §9.1 5051h/1/1: "Reset via Position Error Reset (see 4.3 Index 0x2100)".
TEST_F(NovotechnikSim, OverflowNeedsPositionErrorReset2100) {
  boot();
  configure_and_start();
  sim_->set_position(100, net_.now());
  sim_->inject_fault(Novotechnik406Sim::Fault::Overflow, net_.now());
  net_.run_for(20ms);
  EXPECT_EQ(driver_->last_error_position(), 0x7FFFFFF8u);
  EXPECT_EQ(pos().status, SignalStatus::Error);
  EXPECT_FALSE(sim_->clear_fault(net_.now()));
  net_.run_for(20ms);
  EXPECT_EQ(pos().status, SignalStatus::Error);
  decoded_.clear();
  EXPECT_EQ(download(0x2100, 0, {0x01}), SdoAbortCode::None);
  ASSERT_FALSE(decoded_.empty());
  EXPECT_EQ(decoded_.back().code, 0x5051) << "§9.1: \"an EMCY with 0x0000 (valid position)\", 5051h/0/0";
  EXPECT_FALSE(decoded_.back().error);
  net_.run_for(20ms);
  EXPECT_EQ(pos().status, SignalStatus::Valid);
  EXPECT_EQ(pos().value, 100);
}

TEST_F(NovotechnikSim, UnderflowMarkerWithoutEmcyIsStillError) {
  boot();
  configure_and_start();
  sim_->inject_error_position(0x80000008, net_.now());
  net_.run_for(20ms);
  EXPECT_TRUE(decoded_.empty());
  EXPECT_EQ(pos().status, SignalStatus::Error);
  EXPECT_EQ(driver_->last_error_position(), 0x80000008u);
}

// §9.1 EMCY table via the simulator's frames, and §4.3 2104h EMCY behaviour.
TEST_F(NovotechnikSim, EmcyDecodeAndSuppression) {
  boot();
  configure_and_start();
  sim_->send_emcy(0x4210, 1, 1, {0, 0, 0, 0}, net_.now(), "Warn");
  net_.run_for(1ms);
  ASSERT_EQ(decoded_.size(), 1u);
  EXPECT_NE(decoded_[0].text.find("temperature overrun"), std::string::npos) << decoded_[0].text;
  EXPECT_FALSE(decoded_[0].error);
  EXPECT_EQ(download(0x2104, 0, {0x02}), SdoAbortCode::None);  // info and warnings suppressed
  sim_->send_emcy(0x4210, 1, 1, {0, 0, 0, 0}, net_.now(), "Warn");
  sim_->send_emcy(0x6000, 1, 0, {0, 0, 0, 0}, net_.now(), "Hard");  // "Hard errors rises always"
  net_.run_for(1ms);
  ASSERT_EQ(decoded_.size(), 2u);
  EXPECT_EQ(decoded_[1].code, 0x6000);
  EXPECT_TRUE(decoded_[1].error);
  EXPECT_EQ(pos().status, SignalStatus::Error);
}

// §5.6 CAMs -> 6300h and EMCY 9080h; §5.7 work area -> 6400h and EMCY 9090h. The driver maps
// 6300h:01 and 6400h:01 into TPDO1: the signals come from there, the EMCYs are reported.
TEST_F(NovotechnikSim, CamAndWorkAreaStatesComeInTpdo1AndAsEmcys) {
  boot();
  ASSERT_EQ(download(0x6310, 1, encode<std::int32_t>(1000)), SdoAbortCode::None);
  ASSERT_EQ(download(0x6320, 1, encode<std::int32_t>(2000)), SdoAbortCode::None);
  ASSERT_EQ(download(0x6301, 1, {0x01}), SdoAbortCode::None);
  ASSERT_EQ(download(0x6402, 1, encode<std::int32_t>(50000)), SdoAbortCode::None);
  configure_and_start();
  sim_->set_position(500, net_.now());
  net_.run_for(20ms);
  EXPECT_EQ(driver_->value(Novotechnik406Driver::kCams).status, SignalStatus::Valid);
  EXPECT_EQ(driver_->value(Novotechnik406Driver::kCams).value, 0);
  sim_->set_position(1500, net_.now());
  net_.run_for(11ms);  // the next TPDO1 (event timer 10 ms)
  EXPECT_EQ(driver_->value(Novotechnik406Driver::kCams).value, 1);
  EXPECT_EQ(driver_->value(Novotechnik406Driver::kCams).status, SignalStatus::Valid);
  ASSERT_FALSE(frames(0xFF).empty());
  EXPECT_EQ(frames(0xFF).back(), CanFrame(0xFF, {0x80, 0x90, 0x01, 0x00, 0x01, 0x00, 0x00, 0x01}));
  sim_->set_position(60000, net_.now());  // above the work area high limit: bit 1
  net_.run_for(11ms);
  EXPECT_EQ(driver_->value(Novotechnik406Driver::kWorkArea).value, 0x02);
  EXPECT_EQ(driver_->value(Novotechnik406Driver::kCams).value, 0);
  EXPECT_EQ(pos().status, SignalStatus::Valid);
}

TEST_F(NovotechnikSim, NmtStartupBit3StartsOperationalAfterStore) {
  boot();
  ASSERT_EQ(download(0x1F80, 0, encode<std::uint32_t>(0x08)), SdoAbortCode::None);
  EXPECT_EQ(sdo({0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65}).data[0], 0x60);
  sim_->reboot(net_.now());
  net_.run_for(1ms);
  EXPECT_EQ(sim_->node().state(), NmtState::Operational);
}

// §3.3 / §4.1: TPDO2 (280h + node = 2FFh) synchronous (1801h:02 = 1): one PDO per SYNC (080h),
// same default mapping. The driver's configuration turns the unused TPDO2 off: then a SYNC brings nothing on 2FFh.
TEST_F(NovotechnikSim, Tpdo2SynchronousOnEverySyncUntilTheDriverTurnsItOff) {
  boot();
  host_->nmt().start(kNode);
  net_.run_for(1ms);
  sim_->set_position(-42, net_.now());
  sim_->set_speed(7, net_.now());
  net_.run_for(1ms);
  EXPECT_EQ(exchange(0x080, {}, 0x2FF), std::vector<CanFrame>{CanFrame(0x2FF, {0xD6, 0xFF, 0xFF, 0xFF, 0x07, 0x00})});
  EXPECT_EQ(exchange(0x080, {}, 0x2FF).size(), 1u);
  host_->nmt().enter_pre_operational(kNode);
  net_.run_for(1ms);
  configure_and_start();
  sim_->set_position(-43, net_.now());
  net_.run_for(1ms);
  EXPECT_TRUE(exchange(0x080, {}, 0x2FF).empty()) << "TPDO2 disabled by the driver (1801h:01 bit 31)";
}

// §4.1 1800h:02 = 255 "synchronous to measurement cycle": every new measurement is sent at once.
TEST_F(NovotechnikSim, Type255SendsEachMeasurement) {
  std::string error;
  auto d =
      make_novotechnik_406_driver(kNode, net_.sink("driver"),
                                  DriverOptions{{{"transmission_type", "255"}, {"event_timer_ms", "1000"}}}, error);
  ASSERT_NE(d, nullptr) << error;
  driver_.reset(static_cast<Novotechnik406Driver*>(d.release()));
  boot();
  configure_and_start();
  net_.bus().clear_log();
  sim_->set_position(11, net_.now());
  net_.run_for(1ms);
  sim_->set_position(12, net_.now());
  net_.run_for(1ms);
  EXPECT_EQ(frames(0x1FF).size(), 2u);
  EXPECT_EQ(pos().value, 12);
}

// §4.3 2001h CAN bit rate in kbit/s: only the §3.1 rates are accepted.
TEST_F(NovotechnikSim, BitRateObjectAcceptsDocumentedRatesOnly) {
  boot();
  EXPECT_EQ(download(0x2001, 0, encode<std::uint16_t>(500)), SdoAbortCode::None);
  EXPECT_EQ(download(0x2001, 0, encode<std::uint16_t>(300)), SdoAbortCode::InvalidValue);
  EXPECT_EQ(download(0x2000, 0, {0x00}), SdoAbortCode::ValueTooLow);  // node-ID range 1..127
}

}  // namespace

namespace {

// §11 "Deletion and Restoration to Default via SDO Object 0x1010": the signature "kill"
// (0x6C6C696B) on 1010h sub 1..4 deletes that group's stored data and restores its defaults.
// §7.1's frame layout: 23 10 10 01 6B 69 6C 6C -> 60 10 10 01.
TEST_F(NovotechnikSim, KillSignatureDeletesTheStoredGroupAndRestoresDefaults) {
  boot();
  ASSERT_EQ(download(0x1017, 0, encode<std::uint16_t>(250)), SdoAbortCode::None);   // §11: communication group
  ASSERT_EQ(download(0x6003, 0, encode<std::uint32_t>(1234)), SdoAbortCode::None);  // application group
  EXPECT_EQ(sdo({0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65}),
            CanFrame(0x5FF, {0x60, 0x10, 0x10, 0x01, 0, 0, 0, 0}));
  sim_->reboot(net_.now());
  net_.settle();
  EXPECT_EQ(sim_->od().get<std::uint16_t>(0x1017, 0), 250) << "saved and loaded at power-on";
  EXPECT_EQ(sim_->od().get<std::uint32_t>(0x6003, 0), 1234u);
  // "kill" on sub 2: the communication group only.
  EXPECT_EQ(sdo({0x23, 0x10, 0x10, 0x02, 0x6B, 0x69, 0x6C, 0x6C}),
            CanFrame(0x5FF, {0x60, 0x10, 0x10, 0x02, 0, 0, 0, 0}));
  EXPECT_EQ(sim_->od().get<std::uint16_t>(0x1017, 0), 0) << "its default, at once";
  sim_->reboot(net_.now());
  net_.settle();
  EXPECT_EQ(sim_->od().get<std::uint16_t>(0x1017, 0), 0) << "deleted from the store";
  EXPECT_EQ(sim_->od().get<std::uint32_t>(0x6003, 0), 1234u) << "the application group kept";
  // A wrong signature: §7.3 0800 0020h.
  EXPECT_EQ(sdo({0x23, 0x10, 0x10, 0x01, 0x6B, 0x69, 0x6C, 0x6D}),
            CanFrame(0x5FF, {0x80, 0x10, 0x10, 0x01, 0x20, 0x00, 0x00, 0x08}));
}

// §7.1 "NODE-ID: Using writing to object 0x2000, non-volatile storage has to be done by writing
// the "save" signature (0x65766173) on object 0x1010/4. These changes will become effective after
// a communication restart or a power up." The document's frames: 2F 00 20 00 40 -> 60 00 20 00.
TEST_F(NovotechnikSim, NodeIdBySdoStoredBy1010h4IsActiveAfterAPowerUp) {
  boot();
  EXPECT_EQ(sdo({0x2F, 0x00, 0x20, 0x00, 0x40, 0x00, 0x00, 0x00}),
            CanFrame(0x5FF, {0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(sdo({0x23, 0x10, 0x10, 0x04, 0x73, 0x61, 0x76, 0x65}),
            CanFrame(0x5FF, {0x60, 0x10, 0x10, 0x04, 0, 0, 0, 0}));
  net_.bus().clear_log();
  sim_->reboot(net_.now());
  net_.settle();
  EXPECT_EQ(frames(0x740), std::vector<CanFrame>{CanFrame(0x740, {0x00})}) << "boot-up at the stored node-ID 40h";
  EXPECT_TRUE(frames(0x77F).empty());
  // 1011h:04 "load": the user data back to the factory's (§4.1 "Restore user data parameters").
  const auto r = exchange(0x640, {0x23, 0x11, 0x10, 0x04, 0x6C, 0x6F, 0x61, 0x64}, 0x5C0);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(r[0], CanFrame(0x5C0, {0x60, 0x11, 0x10, 0x04, 0, 0, 0, 0}));
  net_.bus().clear_log();
  sim_->reboot(net_.now());
  net_.settle();
  EXPECT_EQ(frames(0x77F), std::vector<CanFrame>{CanFrame(0x77F, {0x00})}) << "the factory node-ID 7Fh again";
}

// §4.1 1011h:02 "Restore communication default parameters", :03 "application": each restores its
// §11 column only (CiA 301: the defaults come at the next reset).
TEST_F(NovotechnikSim, RestoreSubIndices2And3RestoreTheirGroupOnly) {
  boot();
  ASSERT_EQ(download(0x1017, 0, encode<std::uint16_t>(300)), SdoAbortCode::None);
  ASSERT_EQ(download(0x2104, 0, {0x02}), SdoAbortCode::None);  // §11 "EMCY Behaviour": communication
  ASSERT_EQ(download(0x6003, 0, encode<std::uint32_t>(77)), SdoAbortCode::None);
  ASSERT_EQ(download(0x6401, 1, encode<std::int32_t>(-5)), SdoAbortCode::None);  // "Work Area Low Limit": application
  EXPECT_EQ(sdo({0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65}).data[0], 0x60);
  EXPECT_EQ(sdo({0x23, 0x11, 0x10, 0x02, 0x6C, 0x6F, 0x61, 0x64}),
            CanFrame(0x5FF, {0x60, 0x11, 0x10, 0x02, 0, 0, 0, 0}));
  EXPECT_EQ(sim_->od().get<std::uint16_t>(0x1017, 0), 300) << "restored at the next reset, not at once";
  sim_->reboot(net_.now());
  net_.settle();
  EXPECT_EQ(sim_->od().get<std::uint16_t>(0x1017, 0), 0);
  EXPECT_EQ(sim_->od().get<std::uint8_t>(0x2104, 0), 0);
  EXPECT_EQ(sim_->od().get<std::uint32_t>(0x6003, 0), 77u);
  EXPECT_EQ(sim_->od().get<std::int32_t>(0x6401, 1), -5);
  EXPECT_EQ(sdo({0x23, 0x11, 0x10, 0x03, 0x6C, 0x6F, 0x61, 0x64}).data[0], 0x60);
  sim_->reboot(net_.now());
  net_.settle();
  EXPECT_EQ(sim_->od().get<std::uint32_t>(0x6003, 0), 0u);
  EXPECT_EQ(sim_->od().get<std::int32_t>(0x6401, 1), 0);
  // A wrong signature, and a sub-index beyond 1011h's four: §7.3 0800 0020h, 0609 0011h.
  EXPECT_EQ(sdo({0x23, 0x11, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65}),
            CanFrame(0x5FF, {0x80, 0x11, 0x10, 0x01, 0x20, 0x00, 0x00, 0x08}));
  EXPECT_EQ(sdo({0x23, 0x11, 0x10, 0x05, 0x6C, 0x6F, 0x61, 0x64}),
            CanFrame(0x5FF, {0x80, 0x11, 0x10, 0x05, 0x11, 0x00, 0x09, 0x06}));
}

// §11 "Load via SDO Object 0x1011 ... will upload data from the non-volatile memory" (the other
// reading of 1011h "load", corner load=stored): the stored values come back at once.
TEST(NovotechnikSimCorners, LoadReadingStoredBringsTheStoredValuesAtOnce) {
  oegw::testing::VirtualNetwork net;
  const auto dir = std::filesystem::temp_directory_path() / ("oegw-novo-load-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  Novotechnik406SimConfig cfg;
  cfg.store_path = dir / "params.txt";
  cfg.load_restores_defaults = false;
  Novotechnik406Sim sim(net.sink("sim"), cfg);
  net.attach("sim", sim);
  sim.start(net.now());
  net.settle();
  (void)sim.od().set<std::uint32_t>(0x6003, 0, 55);
  sim.node().nmt().enter(NmtState::PreOperational, net.now());
  auto send = net.sink("probe");
  send(CanFrame(0x67F, {0x23, 0x10, 0x10, 0x03, 0x73, 0x61, 0x76, 0x65}));
  net.run_for(5ms);
  (void)sim.od().set<std::uint32_t>(0x6003, 0, 99);
  send(CanFrame(0x67F, {0x23, 0x11, 0x10, 0x03, 0x6C, 0x6F, 0x61, 0x64}));
  net.run_for(5ms);
  EXPECT_EQ(sim.od().get<std::uint32_t>(0x6003, 0), 55u);
  std::filesystem::remove_all(dir);
}

// §7.3 "SDO Abort": the frame "0x580+Node-ID 8 Tx 0x80 Index Sub-index Abort code" for the codes
// the sensor gives, as it sends them (those the simulator produces by the document's rules) and
// as the gateway's SDO client reads them (every code of the list).
TEST_F(NovotechnikSim, AbortCodesOfSection73) {
  boot();
  // 0x06090011 "subindex does not exist": 1018h:05.
  EXPECT_EQ(sdo({0x40, 0x18, 0x10, 0x05, 0, 0, 0, 0}),
            CanFrame(0x5FF, {0x80, 0x18, 0x10, 0x05, 0x11, 0x00, 0x09, 0x06}));
  // 0x06010001 "object is write only": 2100h "Position Error Reset", Bool W.
  EXPECT_EQ(sdo({0x40, 0x00, 0x21, 0x00, 0, 0, 0, 0}),
            CanFrame(0x5FF, {0x80, 0x00, 0x21, 0x00, 0x01, 0x00, 0x01, 0x06}));
  // 0x06060000 "access error": a store that cannot be written (a sensor without its memory).
  {
    oegw::testing::VirtualNetwork net;
    Novotechnik406Sim bare(net.sink("sim"), Novotechnik406SimConfig{});  // no store file
    net.attach("sim", bare);
    net.bus().set_logging(true);
    bare.start(net.now());
    net.settle();
    EXPECT_EQ(net.exchange("probe", CanFrame(0x67F, {0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65}), 0x5FF),
              std::vector<CanFrame>{CanFrame(0x5FF, {0x80, 0x10, 0x10, 0x01, 0x00, 0x00, 0x06, 0x06})});
  }
  // Every code of the list, read from its frame by the gateway's SDO client.
  struct Code {
    std::uint32_t raw;
    SdoAbortCode code;
  };
  for (const Code& c :
       {Code{0x06090011, SdoAbortCode::SubIndexDoesNotExist}, Code{0x06090030, SdoAbortCode::InvalidValue},
        Code{0x06020000, SdoAbortCode::ObjectDoesNotExist}, Code{0x06010001, SdoAbortCode::ReadOfWriteOnly},
        Code{0x06010002, SdoAbortCode::WriteOfReadOnly}, Code{0x06060000, SdoAbortCode::HardwareError},
        Code{0x08000020, SdoAbortCode::CannotTransfer}, Code{0x08000000, SdoAbortCode::GeneralError},
        Code{0x08000022, SdoAbortCode::CannotTransferDeviceState}}) {
    // The sensor's answer is the abort frame of §7.3 (sent by the probe; the simulator is silent).
    sim_->set_silent(true);
    SdoAbortCode got = SdoAbortCode::None;
    bool done = false;
    host_->sdo(kNode).upload(0x2002, 0, [&](SdoAbortCode code, Bytes) {
      got = code;
      done = true;
    });
    net_.run_for(1ms);
    probe_(CanFrame(0x5FF,
                    {0x80, 0x02, 0x20, 0x00, static_cast<std::uint8_t>(c.raw), static_cast<std::uint8_t>(c.raw >> 8),
                     static_cast<std::uint8_t>(c.raw >> 16), static_cast<std::uint8_t>(c.raw >> 24)}));
    net_.run_for(5ms);
    sim_->set_silent(false);
    EXPECT_TRUE(done) << std::hex << c.raw;
    EXPECT_EQ(got, c.code) << std::hex << c.raw;
    EXPECT_EQ(static_cast<std::uint32_t>(got), c.raw);
  }
}

}  // namespace
