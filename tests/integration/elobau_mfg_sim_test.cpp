// ElobauMfgDriver against ElobauMfgSim over the virtual bus, simulated clock. A Master NMT-starts
// the grip and routes its TPDOs and EMCYs to the driver; the driver's RPDOs reach the grip.
// Source: "CANopen Protocol for MFG 34xG and 36xG" v01.21
// (elobau "CANopen Protocol for MFG 34xG and 36xG"); each test names its section/table.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "canopen/master.hpp"
#include "subdevices/elobau_mfg.hpp"
#include "subdevices/families.hpp"
#include "subdevices/sim/elobau_mfg_sim.hpp"
#include "virtual_network.hpp"

using namespace oegw::canopen;
using namespace oegw::subdevices;
using oegw::subdevices::sim::ElobauMfgSim;
using oegw::subdevices::sim::ElobauMfgSimConfig;
using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

namespace {

constexpr NodeId kGrip{0x11};  // §7 default node-ID

class ElobauOnBus : public ::testing::Test {
 protected:
  explicit ElobauOnBus(ElobauMfgSimConfig cfg = {}, DriverOptions opts = {}) {
    sim_ = std::make_unique<ElobauMfgSim>(net_.sink("grip"), cfg);
    net_.attach("grip", *sim_);
    host_ = std::make_unique<Master>(host_od_, net_.sink("host"), MasterConfig{.heartbeat_entries = 4});
    net_.attach("host", *host_);
    std::string err;
    auto d = make_elobau_mfg_driver(kGrip, net_.sink("host"), opts, err);
    EXPECT_TRUE(d) << err;
    drv_.reset(static_cast<ElobauMfgDriver*>(d.release()));
    host_->on_other_frame = [this](const CanFrame& f, TimePoint t) {
      for (auto id : drv_->consumed_cob_ids())
        if (f.id == id) drv_->on_frame(f, t);
    };
    host_->on_emcy = [this](const EmcyMessage& m, TimePoint t) {
      if (m.node == kGrip) emcys_.push_back(drv_->on_emcy(m, t));
    };
    net_.bus().set_logging(true);
  }

  void boot() {
    sim_->start(net_.now());
    net_.settle();
    boot_reads();
    host_->nmt().start(kGrip);  // the network manager reports the node online as it starts it
    drv_->on_online(net_.now());
    net_.run_for(5ms);
    ASSERT_EQ(sim_->node().state(), NmtState::Operational);
  }
  // The driver's read-backs at boot (4001h, the buttons fitted 2100h:01h/02h), as the network
  // manager runs them; false (and `error`) when the driver refuses the node.
  bool boot_reads(std::string* error = nullptr) {
    drv_->begin_boot();
    std::string why;
    for (auto reads = drv_->boot_reads(); !reads.empty(); reads = drv_->boot_reads())
      for (const auto& [index, sub] : reads)
        if (!drv_->on_boot_read(index, sub, upload(index, sub), why)) {
          if (error) *error = why;
          return false;
        }
    return true;
  }
  const SignalValue& val(std::string_view name) const { return drv_->value(*drv_->find_signal(name)); }
  std::size_t idx(std::string_view name) const { return *drv_->find_signal(name); }
  std::vector<CanFrame> frames(std::uint32_t id) { return net_.logged(id); }
  SdoAbortCode download(std::uint16_t index, std::uint8_t sub, Bytes data) {
    SdoAbortCode code = SdoAbortCode::GeneralError;
    bool done = false;
    host_->sdo(kGrip).download(index, sub, std::move(data), [&](SdoAbortCode c, Bytes) {
      code = c;
      done = true;
    });
    net_.run_for(100ms);
    EXPECT_TRUE(done);
    return code;
  }
  Bytes upload(std::uint16_t index, std::uint8_t sub) {
    Bytes out;
    host_->sdo(kGrip).upload(index, sub, [&](SdoAbortCode c, Bytes d) {
      EXPECT_EQ(c, SdoAbortCode::None) << std::hex << index << " " << int(sub);
      out = std::move(d);
    });
    net_.run_for(100ms);
    return out;
  }

  oegw::testing::VirtualNetwork net_;
  ObjectDictionary host_od_;
  std::unique_ptr<ElobauMfgSim> sim_;
  std::unique_ptr<Master> host_;
  std::unique_ptr<ElobauMfgDriver> drv_;
  std::vector<DecodedEmcy> emcys_;
};

TEST_F(ElobauOnBus, AxesTravelInTpdo0WithTheTable7Layout) {
  boot();
  net_.bus().clear_log();
  sim_->move_axis("x", -50);
  sim_->move_axis("wheel_b", 110);  // §15.1.2 detent
  sim_->press(3);
  net_.run_for(10ms);
  EXPECT_EQ(val("x").value, -50);
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(val("wheel_b").value, 110);
  EXPECT_EQ(val("buttons[3]").value, 1);
  EXPECT_EQ(val("buttons[3]").status, SignalStatus::Valid);
  auto f0 = frames(0x191);
  ASSERT_FALSE(f0.empty());
  EXPECT_EQ(f0.back(), CanFrame(0x191, {0xCE, 0x00, 0x00, 0x6E, 0x00, 0x04, 0x00, 0xFF}));  // Table 7
  auto f1 = frames(0x291);
  ASSERT_FALSE(f1.empty());
  EXPECT_EQ(f1.back(), CanFrame(0x291, {0xCE, 0x00, 0x00, 0x6E, 0x00, 0xFF, 0xFF, 0xFF}));  // Table 8
}

TEST_F(ElobauOnBus, BothTpdosAreCyclicAt100ms) {
  boot();
  net_.bus().clear_log();
  net_.run_for(1000ms);
  // Table 14: 1800h:05 / 1801h:05 event timer default 100 ms.
  EXPECT_EQ(frames(0x191).size(), 10u);
  EXPECT_EQ(frames(0x291).size(), 10u);
  EXPECT_EQ(val("y").status, SignalStatus::Valid);
  EXPECT_EQ(drv_->counters().mismatches, 0u);
}

TEST_F(ElobauOnBus, NothingBeforeOperational) {
  sim_->start(net_.now());
  net_.run_for(500ms);
  EXPECT_TRUE(frames(0x191).empty());  // §14.1: transmitted after entering "Operational"
  EXPECT_EQ(val("x").status, SignalStatus::Offline);
}

TEST_F(ElobauOnBus, DriverConfigurationIsAcceptedByTheGrip) {
  boot();
  for (const auto& w : drv_->configuration()) EXPECT_EQ(download(w.index, w.sub, w.data), SdoAbortCode::None) << w.what;
  EXPECT_EQ(upload(0x1018, 1), encode<std::uint32_t>(*drv_->expected_identity().vendor_id));
  EXPECT_EQ(upload(0x1000, 0), encode<std::uint32_t>(*drv_->expected_identity().device_type));
  EXPECT_EQ(download(0x1800, 2, {255}), SdoAbortCode::WriteOfReadOnly);  // Table 14: ro
}

TEST_F(ElobauOnBus, ButtonsNotFittedCarryTheNotAvailableValue) {
  boot();
  sim_->press(9);  // 2100h:02h default 0: buttons 9..16 not available -> 2100h:0Ah = 0
  sim_->press(6);  // 2100h:01h default 63: buttons 1..6
  net_.run_for(10ms);
  EXPECT_EQ(frames(0x191).back().data[6], 0x00) << "the not-available value 2100h:0Ah";
  EXPECT_EQ(val("buttons[9]").status, SignalStatus::NotAvailable) << "read back from 2100h:02h at boot";
  EXPECT_EQ(val("buttons[6]").value, 1);
  sim_->release(6);
  net_.run_for(10ms);
  EXPECT_EQ(val("buttons[6]").value, 0);
}

class ElobauWithPresence : public ElobauOnBus {
 protected:
  ElobauWithPresence() : ElobauOnBus(presence_config()) {}
  static ElobauMfgSimConfig presence_config() {
    ElobauMfgSimConfig c;
    c.buttons_9_16 = 0x08;  // 2100h:02h: button 12 fitted
    return c;
  }
};

TEST_F(ElobauWithPresence, PresenceSensorIsButton12) {
  boot();
  sim_->press(12);  // §15.2.1
  net_.run_for(10ms);
  EXPECT_EQ(val("presence").value, 1);
  EXPECT_EQ(val("buttons[12]").value, 1);
  EXPECT_EQ(frames(0x191).back().data[6], 0x08);
}

TEST_F(ElobauOnBus, LedsSetThroughTheDriverLightInTheGrip) {
  boot();
  ASSERT_TRUE(drv_->set_output(idx("leds[1]"), 1, net_.now()));
  net_.run_for(10ms);
  EXPECT_EQ(sim_->led(1), 1);
  ASSERT_TRUE(drv_->set_output(idx("leds[4]"), 2, net_.now()));
  ASSERT_TRUE(drv_->set_output(idx("leds[15]"), 1, net_.now()));  // wheel A LED 1+3
  net_.run_for(10ms);
  EXPECT_EQ(sim_->led(1), 1);
  EXPECT_EQ(sim_->led(4), 2);
  EXPECT_EQ(sim_->led(15), 1);
  EXPECT_EQ(sim_->led(11), 0);
  ASSERT_TRUE(drv_->set_output(idx("leds[1]"), 0, net_.now()));
  net_.run_for(10ms);
  EXPECT_EQ(sim_->led(1), 0);
  EXPECT_EQ(sim_->led(4), 2);
}

TEST_F(ElobauOnBus, NoChangeCodeLeavesLedsTheGatewayNeverCommanded) {
  boot();
  // Another master lit button 5 LED 1 (leds[9], byte 2 bits 0,1) with a raw RPDO (Table 9).
  net_.sink("other")(CanFrame(0x211, {0xFF, 0xFF, 0xFD, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF}));
  net_.run_for(10ms);
  EXPECT_EQ(sim_->led(9), 1);
  drv_->set_output(idx("leds[2]"), 1, net_.now());
  net_.run_for(10ms);
  EXPECT_EQ(sim_->led(2), 1);
  EXPECT_EQ(sim_->led(9), 1) << "Table 13: 11 = no change";
}

TEST_F(ElobauOnBus, LedMaskHidesDisabledLeds) {
  boot();
  EXPECT_EQ(download(0x2200, 0x0A, encode<std::uint16_t>(0xFFFE)), SdoAbortCode::None);  // LED 1 not used
  drv_->set_output(idx("leds[1]"), 1, net_.now());
  drv_->set_output(idx("leds[2]"), 1, net_.now());
  net_.run_for(10ms);
  EXPECT_EQ(sim_->led(1), 1);
  EXPECT_EQ(sim_->led_displayed(1), 0);  // §15.3: only LEDs allowed by 2200h:0Ah are displayed
  EXPECT_EQ(sim_->led_displayed(2), 1);
}

TEST_F(ElobauOnBus, ErrorAndNotAvailableValues) {
  boot();
  sim_->move_axis("y", 30);
  sim_->inject("y", ElobauMfgSim::Fault::Error);               // 20xxh:1Bh = 126
  sim_->inject("wheel_c", ElobauMfgSim::Fault::NotAvailable);  // 1Ch = 127
  net_.run_for(10ms);
  EXPECT_EQ(sim_->transmitted("y", 1), 126);
  EXPECT_EQ(val("y").status, SignalStatus::Error);
  EXPECT_EQ(val("y").value, 0);
  EXPECT_EQ(val("wheel_c").status, SignalStatus::NotAvailable);
  sim_->inject("y", ElobauMfgSim::Fault::None);
  net_.run_for(10ms);
  EXPECT_EQ(val("y").status, SignalStatus::Valid);
  EXPECT_EQ(val("y").value, 30);
}

TEST_F(ElobauOnBus, OnlyChannel2InErrorStillMakesTheAxisAnError) {
  boot();
  sim_->move_axis("x", 20);
  sim_->inject("x", ElobauMfgSim::Fault::Error, 2);
  net_.run_for(250ms);  // several cycles: no flicker back to Valid on TPDO #0
  EXPECT_EQ(sim_->transmitted("x", 1), 20);
  EXPECT_EQ(val("x").status, SignalStatus::Error);
}

TEST_F(ElobauOnBus, ChannelMismatchIsAnError) {
  boot();
  sim_->move_axis("x", 40, 10);  // channel 2 reads 50
  // The disagreeing TPDO #1 is a suspicion; the next TPDO #0 (one 100 ms cycle) confirms it.
  net_.run_for(110ms);
  EXPECT_EQ(val("x").status, SignalStatus::Error);
  EXPECT_GE(drv_->counters().mismatches, 1u);
  net_.run_for(300ms);
  EXPECT_EQ(val("x").status, SignalStatus::Error);
  sim_->move_axis("x", 40, 3);  // within the 5 % default
  net_.run_for(10ms);
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(val("x").value, 40);
}

TEST_F(ElobauOnBus, FastMovementIsNoMismatch) {
  boot();
  for (int p = -100; p <= 100; p += 20) {
    sim_->move_axis("x", p);
    net_.run_for(5ms);
    EXPECT_EQ(val("x").status, SignalStatus::Valid) << p;
  }
  EXPECT_EQ(drv_->counters().mismatches, 0u);
}

TEST_F(ElobauOnBus, SingleChannelAxisSendsNotAvailableOnChannel2AndIsFine) {
  boot();
  EXPECT_EQ(download(0x2002, 0x01, {1}), SdoAbortCode::None);  // Table 14: 1 = only signal 1
  sim_->move_axis("wheel_a", 30);
  net_.run_for(10ms);
  EXPECT_EQ(sim_->transmitted("wheel_a", 2), 127);
  EXPECT_EQ(val("wheel_a").status, SignalStatus::Valid);
  EXPECT_EQ(val("wheel_a").value, 30);
}

TEST_F(ElobauOnBus, EmcyAxisErrorIsDecodedAndClears) {
  boot();
  sim_->move_axis("y", 20);
  net_.run_for(10ms);
  sim_->raise_error(0x0021, net_.now());  // Table 6: Y axis, signal 2, out of range
  net_.run_for(10ms);
  ASSERT_EQ(emcys_.size(), 1u);
  EXPECT_EQ(emcys_[0].code, 0x1000);
  EXPECT_EQ(emcys_[0].text, "elobau 4001h 0021h: Y Axis, Signal 2, Out Of Range");
  EXPECT_EQ(emcys_[0].affected, (std::vector<std::size_t>{idx("y")}));
  EXPECT_EQ(upload(0x4001, 0), encode<std::uint16_t>(0x0021));
  EXPECT_EQ(sim_->transmitted("y", 2), 126);  // §12.2: 4000h = 1 -> error value sent
  net_.run_for(300ms);
  EXPECT_EQ(val("y").status, SignalStatus::Error);
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  sim_->clear_error(0x0021, net_.now());
  net_.run_for(10ms);
  ASSERT_EQ(emcys_.size(), 2u);
  EXPECT_FALSE(emcys_[1].error);  // 0000h error reset
  EXPECT_EQ(val("y").status, SignalStatus::Valid);
  EXPECT_EQ(val("y").value, 20);
}

TEST_F(ElobauOnBus, EmcyFrameLayoutIsTable5) {
  boot();
  net_.bus().clear_log();
  sim_->raise_error(0x0063, net_.now());
  net_.run_for(10ms);
  auto e = frames(0x91);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0], CanFrame(0x91, {0x00, 0x10, 0x00, 0x63, 0x00, 0xFF, 0xFF, 0xFF}));
  EXPECT_EQ(emcys_.back().affected, (std::vector<std::size_t>{idx("buttons[3]")}));
  EXPECT_EQ(val("buttons[3]").status, SignalStatus::Error);
  sim_->clear_error(0x0063, net_.now());
  net_.run_for(10ms);
  EXPECT_EQ(frames(0x91).back(), CanFrame(0x91, {0x00, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF}));
  EXPECT_EQ(val("buttons[3]").status, SignalStatus::Valid);
}

TEST_F(ElobauOnBus, ErrorBehaviourStoppedSilencesTheGrip) {
  boot();
  EXPECT_EQ(download(0x4000, 0, {2}), SdoAbortCode::None);  // §12.2: 2 = stopped
  sim_->raise_error(0x0010, net_.now());
  net_.run_for(10ms);
  EXPECT_EQ(sim_->node().state(), NmtState::Stopped);
  ASSERT_EQ(emcys_.size(), 1u);
  net_.bus().clear_log();
  sim_->clear_error(0x0010, net_.now());
  net_.run_for(300ms);
  EXPECT_TRUE(frames(0x91).empty()) << "§12.1: no EMCY in STOPPED";
  EXPECT_TRUE(frames(0x191).empty());
}

TEST_F(ElobauOnBus, ZeroPositionAfterRebootUntilSeenAtZero) {
  boot();
  sim_->move_axis("x", 60);
  net_.run_for(10ms);
  EXPECT_EQ(val("x").value, 60);
  drv_->on_offline(net_.now());
  sim_->reboot(net_.now());
  net_.settle();
  host_->nmt().start(kGrip);
  drv_->on_online(net_.now());
  net_.run_for(200ms);
  // §4: "the zero position is sent permanently on the non-zero position until this axis ...
  // reaches the zero position".
  EXPECT_TRUE(sim_->zero_locked("x"));
  EXPECT_EQ(sim_->transmitted("x", 1), 0);
  EXPECT_EQ(sim_->transmitted("x", 2), 0);
  EXPECT_EQ(val("x").value, 0);
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  sim_->move_axis("x", 80);
  net_.run_for(10ms);
  EXPECT_EQ(val("x").value, 0) << "still not seen at zero";
  sim_->move_axis("x", 0);
  net_.run_for(10ms);
  sim_->move_axis("x", 30);
  net_.run_for(10ms);
  EXPECT_FALSE(sim_->zero_locked("x"));
  EXPECT_EQ(val("x").value, 30);
}

TEST_F(ElobauOnBus, ZeroPositionAtPowerOnToo) {
  sim_->move_axis("wheel_a", -40);
  sim_->move_axis("y", 0);
  boot();
  net_.run_for(50ms);
  EXPECT_EQ(val("wheel_a").value, 0);
  EXPECT_TRUE(sim_->zero_locked("wheel_a"));
  EXPECT_FALSE(sim_->zero_locked("y"));
}

TEST_F(ElobauOnBus, BusOffRecoverySendsCountAndArmsZeroRule) {
  boot();
  sim_->move_axis("x", 50);
  net_.run_for(10ms);
  sim_->bus_off(net_.now());
  net_.run_for(10ms);
  ASSERT_EQ(emcys_.size(), 1u);
  EXPECT_EQ(emcys_[0].code, 0x8140);
  EXPECT_EQ(emcys_[0].text, "elobau EMCY 8140h: recovered from bus off (count 1)");
  EXPECT_EQ(val("x").value, 0);  // §4: "after power on and bus off"
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
}

TEST_F(ElobauOnBus, LssObjectRefusesUnlistedBaudRates) {
  boot();
  EXPECT_EQ(download(0x5999, 1, encode<std::uint16_t>(300)), SdoAbortCode::InvalidValue);
  EXPECT_EQ(download(0x5999, 1, encode<std::uint16_t>(500)), SdoAbortCode::None);  // §16 list
  EXPECT_EQ(sim_->baud_rate(), 500);
  EXPECT_EQ(download(0x5999, 2, {0}), SdoAbortCode::ValueTooLow);
  EXPECT_EQ(upload(0x1008, 0), (Bytes{'J', 'S', 'T'}));
}

TEST_F(ElobauOnBus, NodeIdBySdoBecomesActiveAfterResetCommunication) {
  boot();
  EXPECT_EQ(download(0x5999, 2, {0x12}), SdoAbortCode::None);  // §7: node-ID via 5999h:02
  net_.bus().clear_log();
  host_->nmt().send(NmtCommand::ResetCommunication, kGrip);
  net_.run_for(10ms);
  EXPECT_EQ(sim_->node().node_id(), NodeId{0x12});
  EXPECT_EQ(frames(0x712).size(), 1u);  // boot-up on the new node-ID
}

TEST_F(ElobauOnBus, DictionaryMatchesTable14) {
  boot();
  EXPECT_EQ(upload(0x1014, 0), encode<std::uint32_t>(0x91));        // 80h + node-ID
  EXPECT_EQ(upload(0x1018, 2), encode<std::uint32_t>(0x00010003));  // product code
  EXPECT_EQ(upload(0x1400, 1), encode<std::uint32_t>(0x211));
  EXPECT_EQ(upload(0x1400, 2), (Bytes{254}));
  EXPECT_EQ(upload(0x1600, 1), encode<std::uint32_t>(0x22000108));
  EXPECT_EQ(upload(0x1600, 8), encode<std::uint32_t>(0x22000808));
  EXPECT_EQ(upload(0x1800, 0), (Bytes{5}));
  EXPECT_EQ(upload(0x1800, 3), encode<std::uint16_t>(20));
  EXPECT_EQ(upload(0x1801, 1), encode<std::uint32_t>(0x291));
  EXPECT_EQ(upload(0x1801, 5), encode<std::uint16_t>(100));
  EXPECT_EQ(upload(0x1A00, 1), encode<std::uint32_t>(0x20002008));
  EXPECT_EQ(upload(0x1A00, 7), encode<std::uint32_t>(0x21001108));
  EXPECT_EQ(upload(0x1A00, 8), encode<std::uint32_t>(0x40020008));
  EXPECT_EQ(upload(0x1A01, 5), encode<std::uint32_t>(0x20042108));
  EXPECT_EQ(upload(0x2000, 0x01), (Bytes{3}));
  EXPECT_EQ(upload(0x2003, 0x06), encode<std::uint16_t>(200));  // X1
  EXPECT_EQ(upload(0x2003, 0x07), (Bytes{0x9C}));               // Y1 = -100
  EXPECT_EQ(upload(0x2004, 0x1B), (Bytes{126}));
  EXPECT_EQ(upload(0x2004, 0x1C), (Bytes{127}));
  EXPECT_EQ(upload(0x2100, 0x01), (Bytes{63}));
  EXPECT_EQ(upload(0x2200, 0x00), (Bytes{9}));
  EXPECT_EQ(upload(0x2200, 0x0A), encode<std::uint16_t>(0xFFFF));
  EXPECT_EQ(upload(0x4000, 0), (Bytes{1}));
  EXPECT_EQ(upload(0x4002, 0), (Bytes{0xFF}));
  EXPECT_EQ(upload(0x5001, 0), encode<std::uint16_t>(20));
  EXPECT_EQ(upload(0x5999, 1), encode<std::uint16_t>(250));
  EXPECT_EQ(upload(0x5999, 2), (Bytes{0x11}));
}

TEST_F(ElobauOnBus, ErrorBehaviourPreOperational) {
  boot();
  EXPECT_EQ(download(0x4000, 0, {0}), SdoAbortCode::None);  // §12.2: 0 = pre-operational
  sim_->raise_error(0x0020, net_.now());
  net_.run_for(10ms);
  EXPECT_EQ(sim_->node().state(), NmtState::PreOperational);
  EXPECT_EQ(emcys_.size(), 1u) << "EMCY still sent in pre-operational";
  EXPECT_EQ(val("y").status, SignalStatus::Error);
}

TEST_F(ElobauOnBus, Signal1OutOfRangeSendsTheErrorValueOnChannel1) {
  boot();
  sim_->move_axis("wheel_c", -30);
  sim_->raise_error(0x0050, net_.now());  // Table 6: thumb wheel C, signal 1, out of range
  net_.run_for(10ms);
  EXPECT_EQ(sim_->transmitted("wheel_c", 1), 126);
  EXPECT_EQ(sim_->transmitted("wheel_c", 2), -30);
  EXPECT_EQ(emcys_.back().affected, (std::vector<std::size_t>{idx("wheel_c")}));
  net_.run_for(500ms);
  EXPECT_EQ(val("wheel_c").status, SignalStatus::Error);
}

TEST_F(ElobauOnBus, AutoNmtStartAfterPowerOn) {
  EXPECT_EQ(sim_->od().write(0x5000, 0, Bytes{1}), SdoAbortCode::None);  // 5000h: 1 = activated
  sim_->start(net_.now());
  drv_->on_online(net_.now());
  net_.run_for(150ms);
  EXPECT_EQ(sim_->node().state(), NmtState::Operational);
  EXPECT_FALSE(frames(0x191).empty());
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
}

TEST_F(ElobauOnBus, BusOffBeyondTheLimitTakesTheGripOffLine) {
  boot();
  EXPECT_EQ(download(0x5001, 0, encode<std::uint16_t>(2)), SdoAbortCode::None);
  sim_->bus_off(net_.now());
  sim_->bus_off(net_.now());
  net_.run_for(10ms);
  EXPECT_EQ(emcys_.size(), 2u);
  EXPECT_EQ(emcys_.back().text, "elobau EMCY 8140h: recovered from bus off (count 2)");
  sim_->bus_off(net_.now());  // third: beyond the limit of 2
  net_.bus().clear_log();
  net_.run_for(500ms);
  EXPECT_TRUE(sim_->silent());
  EXPECT_TRUE(net_.bus().log().empty());
}

class ElobauNeverSaved : public ElobauOnBus {
 protected:
  ElobauNeverSaved() : ElobauOnBus(config()) {}
  ~ElobauNeverSaved() override { std::filesystem::remove_all(dir()); }
  static std::filesystem::path dir() {
    return std::filesystem::temp_directory_path() / ("oegw-elobau-" + std::to_string(::getpid()));
  }
  static ElobauMfgSimConfig config() {
    std::filesystem::remove_all(dir());
    std::filesystem::create_directories(dir());
    ElobauMfgSimConfig c;
    c.store_path = dir() / "params.txt";
    c.parameters_saved = false;
    return c;
  }
};

// Table 6 0002h: "This error is also set until first parameter saving process." — sent at every
// power-on of a grip whose parameters were never saved: every input in doubt, and read back at
// boot the driver refuses the grip (parameter_checksum: refuse), saying how to save it. Saved
// (§7: 5999h:03, or 1010h:01) and restarted, it runs.
TEST_F(ElobauNeverSaved, ParameterChecksumErrorUntilFirstSave) {
  sim_->start(net_.now());
  net_.run_for(5ms);
  ASSERT_EQ(emcys_.size(), 1u);
  EXPECT_EQ(emcys_[0].text.rfind("elobau 4001h 0002h: Parameter Checksum Error", 0), 0u) << emcys_[0].text;
  EXPECT_TRUE(emcys_[0].error);
  EXPECT_EQ(emcys_[0].affected.size(), ElobauMfgDriver::kFirstLed);
  std::string error;
  EXPECT_FALSE(boot_reads(&error));
  EXPECT_NE(error.find("4001h reads 0002h"), std::string::npos) << error;
  EXPECT_EQ(upload(0x4001, 0), encode<std::uint16_t>(0x0002));
  // §7: 5999h:03 "save" saves all parameters (incl. LSS); §8: restart the joystick afterwards.
  // Saved in pre-operational: the simulator refuses a store while operational (0800 0022h, the
  // CiA 301 answer taken where the document is silent;
  // docs/design/device-documents.md#boot-pre-operational-sync-identity-diagnostics-network_managerhpp).
  EXPECT_EQ(download(0x5999, 3, encode<std::uint32_t>(0x65766173)), SdoAbortCode::None);
  EXPECT_TRUE(std::filesystem::exists(dir() / "params.txt"));
  drv_->on_offline(net_.now());
  emcys_.clear();
  sim_->reboot(net_.now());
  net_.settle();
  ASSERT_TRUE(boot_reads(&error)) << error;
  EXPECT_FALSE(drv_->any_fault()) << "4001h = 0 after the restart";
  host_->nmt().start(kGrip);
  drv_->on_online(net_.now());
  net_.run_for(300ms);
  EXPECT_TRUE(emcys_.empty());
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(val("buttons[1]").status, SignalStatus::Valid);
}

}  // namespace

namespace {

// §8 "To save all parameters (objects with marking PARA) except LSS parameters, write "save"
// (0x65766173) into the object 0x1010.1"; §9 "To restore all parameters to factory settings write
// "load" (0x64616F6C) into the object 0x1011.1". The SDO frames (CiA 301 expedited download,
// little endian: "save" = 73 61 76 65, "load" = 6C 6F 61 64) and the grip's answers.
TEST_F(ElobauNeverSaved, SaveAndLoadSignaturesOfSections8And9) {
  sim_->start(net_.now());
  net_.settle();
  auto send = net_.sink("probe");
  auto answer = [&](Bytes req) {
    net_.bus().clear_log();
    send(CanFrame(0x611, std::span<const std::uint8_t>(req)));
    net_.run_for(5ms);
    const auto f = frames(0x591);
    return f.empty() ? CanFrame{} : f.back();
  };
  EXPECT_EQ(answer({0x2B, 0x17, 0x10, 0x00, 0xF4, 0x01, 0, 0}).data[0], 0x60);  // 1017h = 500 ms, PARA
  EXPECT_EQ(answer({0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65}),
            CanFrame(0x591, {0x60, 0x10, 0x10, 0x01, 0, 0, 0, 0}));
  sim_->reboot(net_.now());
  net_.settle();
  EXPECT_EQ(upload(0x1017, 0), encode<std::uint16_t>(500)) << "saved";
  EXPECT_EQ(upload(0x4001, 0), encode<std::uint16_t>(0)) << "0002h ended by the first saving";
  EXPECT_EQ(answer({0x23, 0x11, 0x10, 0x01, 0x6C, 0x6F, 0x61, 0x64}),
            CanFrame(0x591, {0x60, 0x11, 0x10, 0x01, 0, 0, 0, 0}));
  sim_->reboot(net_.now());
  net_.settle();
  EXPECT_EQ(upload(0x1017, 0), encode<std::uint16_t>(0)) << "factory settings";
}

// §15.1.2 Table 11 "Transformation function example with detent": X1..X10 = 0,2 1,0 1,3 1,3 2,3
// 2,7 3,7 3,7 4,0 4,8 V, Y1..Y10 = -110 -110 -100 -100 0 0 100 100 110 110 %; "The detent function
// is a jump from 100% to 110%", "X2 and X9 are used for detent detection", "X1 and X10 are also
// used for error detection". Written into 2000h (X axis), the grip sends the table's values, and
// the driver reports the detent as ±110 (detent: pass) — or ±100 (clamp).
TEST_F(ElobauOnBus, Table11DetentCurve) {
  boot();
  const std::uint16_t x[10] = {200, 1000, 1300, 1300, 2300, 2700, 3700, 3700, 4000, 4800};
  const std::int8_t y[10] = {-110, -110, -100, -100, 0, 0, 100, 100, 110, 110};
  for (std::uint8_t p = 0; p < 10; ++p) {
    ASSERT_EQ(download(0x2000, static_cast<std::uint8_t>(0x06 + 2 * p), encode<std::uint16_t>(x[p])),
              SdoAbortCode::None);
    ASSERT_EQ(download(0x2000, static_cast<std::uint8_t>(0x07 + 2 * p), encode<std::int8_t>(y[p])), SdoAbortCode::None);
  }
  struct Point {
    int mv;
    int percent;  // sent; 126: the error value (out of range)
  };
  for (const Point& pt :
       {Point{200, -110}, Point{600, -110}, Point{1000, -110}, Point{1150, -100}, Point{1300, -100}, Point{1800, -50},
        Point{2300, 0}, Point{2500, 0}, Point{2700, 0}, Point{3200, 50}, Point{3700, 100}, Point{3850, 100},
        Point{4000, 110}, Point{4800, 110}, Point{100, 126}, Point{4900, 126}}) {
    (void)sim_->apply_voltage("x", pt.mv);
    net_.run_for(110ms);
    EXPECT_EQ(sim_->transmitted("x", 1), pt.percent) << pt.mv << " mV";
    EXPECT_EQ(frames(0x191).back().data[0], static_cast<std::uint8_t>(static_cast<std::int8_t>(pt.percent))) << pt.mv;
    if (pt.percent == 126) {
      EXPECT_EQ(val("x").status, SignalStatus::Error) << pt.mv << " mV: out of range";
    } else {
      EXPECT_EQ(val("x").value, pt.percent) << pt.mv << " mV";
    }
  }
}

}  // namespace
