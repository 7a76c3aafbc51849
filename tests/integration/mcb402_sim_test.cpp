// Tier 2: Mcb402Driver against Mcb402Sim on the in-process virtual bus, with a host Master that
// boots the node as the network manager does: identity check, driver.configuration() by SDO, NMT
// start; the host routes the node's TPDOs and EMCYs to the driver. Simulated clock, no sleeping.
// Document: reference/003_44a28fc862638d35.txt (MCB-402 v1.0): [MCB §n] the board's chapters,
// [CO4013 ...] the controller's chapter 5.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include "canopen/master.hpp"
#include "subdevices/families.hpp"
#include "subdevices/mcb402.hpp"
#include "subdevices/sim/mcb402_sim.hpp"
#include "virtual_network.hpp"

using namespace oegw::canopen;
using namespace std::chrono_literals;
using oegw::subdevices::DecodedEmcy;
using oegw::subdevices::Driver;
using oegw::subdevices::DriverOptions;
using oegw::subdevices::SignalStatus;
using oegw::subdevices::sim::Mcb402Sim;
using oegw::subdevices::sim::Mcb402SimConfig;
using Bytes = std::vector<std::uint8_t>;
namespace mcb402 = oegw::subdevices::mcb402;

namespace {

constexpr NodeId kNode{0x03};  // [MCB §4] "configured at address 0x03"
constexpr std::size_t kX = 0, kY = 1, kZ = 2, kT = 3;
constexpr std::size_t button(std::size_t n) { return mcb402::kFirstButton + n - 1; }
constexpr std::size_t led(std::size_t n) { return mcb402::kFirstLed + n - 1; }

class Mcb402OnBus : public ::testing::Test {
 protected:
  Mcb402OnBus() {
    sim_ = std::make_unique<Mcb402Sim>(net_.sink("mcb402"), Mcb402SimConfig{});
    net_.attach("mcb402", *sim_);
    host_ = std::make_unique<Master>(host_od_, net_.sink("host"),
                                     MasterConfig{.heartbeat_entries = 4, .sdo_timeout = 500ms});
    net_.attach("host", *host_);
    std::string error;
    // The bit order commissioned for this board: the simulator's default wiring (the table's
    // right-end reading, docs/design/device-documents.md#corners-every-reading-a-document-permits),
    // given explicitly as a mapping file must.
    driver_ = oegw::subdevices::make_mcb402_driver(kNode, net_.sink("host"),
                                                   DriverOptions{{{"button_bits", "0,1,2,3,4,6,5"}}}, error);
    EXPECT_NE(driver_, nullptr) << error;
    const auto cobs = driver_->consumed_cob_ids();
    host_->on_other_frame = [this, cobs](const CanFrame& f, TimePoint now) {
      if (std::find(cobs.begin(), cobs.end(), f.id) != cobs.end()) (void)driver_->on_frame(f, now);
    };
    host_->on_emcy = [this](const EmcyMessage& m, TimePoint now) {
      if (m.node == kNode) emcys_.push_back(driver_->on_emcy(m, now));
    };
    host_->on_boot = [this](NodeId n) { boots_.push_back(n); };
    net_.bus().set_logging(true);
  }

  SdoAbortCode download(std::uint16_t index, std::uint8_t sub, Bytes data) {
    std::optional<SdoAbortCode> r;
    host_->sdo(kNode).download(index, sub, std::move(data), [&r](SdoAbortCode c, Bytes) { r = c; });
    net_.run_for(50ms);
    EXPECT_TRUE(r.has_value());
    return r.value_or(SdoAbortCode::GeneralError);
  }
  std::pair<SdoAbortCode, Bytes> upload(std::uint16_t index, std::uint8_t sub) {
    std::optional<std::pair<SdoAbortCode, Bytes>> r;
    host_->sdo(kNode).upload(index, sub, [&r](SdoAbortCode c, Bytes d) { r = {c, std::move(d)}; });
    net_.run_for(50ms);
    EXPECT_TRUE(r.has_value());
    return r.value_or(std::pair<SdoAbortCode, Bytes>{SdoAbortCode::GeneralError, {}});
  }
  std::optional<std::uint32_t> upload_u32(std::uint16_t index, std::uint8_t sub) {
    auto [c, d] = upload(index, sub);
    if (c != SdoAbortCode::None || d.size() != 4) return std::nullopt;
    return get_u32(d.data());
  }

  // Power-on, identity check, configuration, NMT start, on_online: the network manager's boot.
  void boot() {
    sim_->start(net_.now());
    net_.settle();
    ASSERT_EQ(boots_, std::vector<NodeId>{kNode});
    const auto id = driver_->expected_identity();
    EXPECT_EQ(upload_u32(0x1000, 0), id.device_type);
    EXPECT_EQ(upload_u32(0x1018, 1), id.vendor_id);
    EXPECT_EQ(upload_u32(0x1018, 2), id.product_code);
    for (const auto& w : driver_->configuration())
      ASSERT_EQ(download(w.index, w.sub, w.data), SdoAbortCode::None) << w.what;
    start();
  }
  void start() {
    host_->nmt().start(kNode);
    net_.run_for(1ms);
    ASSERT_EQ(sim_->node().state(), NmtState::Operational);
    driver_->on_online(net_.now());
    net_.settle();
  }
  std::vector<CanFrame> frames(std::uint32_t id) { return net_.logged(id); }
  const oegw::subdevices::SignalValue& v(std::size_t i) const { return driver_->value(i); }

  oegw::testing::VirtualNetwork net_;
  std::unique_ptr<Mcb402Sim> sim_;
  ObjectDictionary host_od_;
  std::unique_ptr<Master> host_;
  std::unique_ptr<Driver> driver_;
  std::vector<DecodedEmcy> emcys_;
  std::vector<NodeId> boots_;
};

TEST_F(Mcb402OnBus, PowerOnSequenceAndConfigurationAsTheDocumentSays) {
  boot();
  // [MCB §4] "At the power on, MCB402 writes on the bus: 703 00"; after "000 01 03" it sends
  // "183 00 00 cc 0" and "283 aa bb ...".
  ASSERT_FALSE(net_.bus().log().empty());
  EXPECT_EQ(net_.bus().log()[0].frame, CanFrame(0x703, {0x00}));
  ASSERT_FALSE(frames(0x183).empty());
  EXPECT_EQ(frames(0x183)[0], CanFrame(0x183, {0x00, 0x00, 0x00, 0x00}));
  ASSERT_FALSE(frames(0x283).empty());
  EXPECT_EQ(frames(0x283)[0], CanFrame(0x283, {0, 0, 0, 0, 0, 0, 0, 0}));
  for (std::size_t i = 0; i < led(1); ++i) {
    EXPECT_EQ(v(i).status, SignalStatus::Valid) << i;
    EXPECT_EQ(v(i).value, 0) << i;
  }
  // The configuration landed in the simulated dictionary.
  EXPECT_EQ(sim_->od().get<std::uint16_t>(0x1801, 5), 20);
  EXPECT_EQ(sim_->od().get<std::uint16_t>(0x1800, 5), 100);
  EXPECT_EQ(sim_->od().get<std::uint8_t>(0x1801, 2), 0xFF);
  EXPECT_EQ(driver_->counters().wrong_length + driver_->counters().unknown_cob, 0u);
}

TEST_F(Mcb402OnBus, AxesArriveByTheEventTimerOnly) {
  boot();
  net_.bus().clear_log();
  // 6423h is FALSE by default [CO4013 Index 6423]: moving the stick sends nothing by itself...
  sim_->move_axis(1, 12345, net_.now());
  sim_->move_axis(2, -32768, net_.now());
  sim_->move_axis(3, 32767, net_.now());
  sim_->move_axis(4, -1, net_.now());
  net_.settle();
  EXPECT_TRUE(frames(0x283).empty());
  EXPECT_EQ(v(kX).value, 0);
  // ...the 20 ms event timer does ([MCB §4] "returns now the values of axis each 0xbbaa ms").
  net_.run_for(20ms);
  ASSERT_EQ(frames(0x283).size(), 1u);
  // "283 aa bb cc dd ee ff gg hh", X = 0xbbaa = 12345 = 0x3039.
  EXPECT_EQ(frames(0x283)[0], CanFrame(0x283, {0x39, 0x30, 0x00, 0x80, 0xFF, 0x7F, 0xFF, 0xFF}));
  EXPECT_EQ(v(kX).value, 12345);
  EXPECT_EQ(v(kY).value, -32768);
  EXPECT_EQ(v(kZ).value, 32767);
  EXPECT_EQ(v(kT).value, -1);
  net_.run_for(200ms);
  EXPECT_EQ(frames(0x283).size(), 11u) << "one every 20 ms";
}

TEST_F(Mcb402OnBus, ZeroPointEnlargementAsTheFormula) {
  boot();
  // [CO4013 Index 5401] "If 6401 > 5401 then 6401 = 6401 - 5401, else if 6401 < -5401 then
  // 6401 = 6401 + 5401, else 6401 = 0"; default 1000h.
  sim_->convert_axis(1, 0x2000, net_.now());
  sim_->convert_axis(2, 0x0800, net_.now());
  sim_->convert_axis(3, -0x1800, net_.now());
  sim_->convert_axis(4, -0x1000, net_.now());
  net_.run_for(20ms);
  EXPECT_EQ(v(kX).value, 0x1000);
  EXPECT_EQ(v(kY).value, 0);
  EXPECT_EQ(v(kZ).value, -0x0800);
  EXPECT_EQ(v(kT).value, 0) << "-5401 itself is inside the zone";
  ASSERT_EQ(download(0x5401, 1, {0x00, 0x00}), SdoAbortCode::None);
  sim_->convert_axis(1, 0x2000, net_.now());
  net_.run_for(20ms);
  EXPECT_EQ(v(kX).value, 0x2000);
}

TEST_F(Mcb402OnBus, TheDocumentsEventTimerFrameIsAcceptedLiterally) {
  boot();
  net_.bus().clear_log();
  // [MCB §4] "Write : 603 22 01 18 05 aa bb 00 00" with 0xbbaa = 500 ms.
  (void)net_.bus().inject(CanFrame(0x603, {0x22, 0x01, 0x18, 0x05, 0xF4, 0x01, 0x00, 0x00}), "doc");
  net_.settle();
  ASSERT_FALSE(frames(0x583).empty());
  EXPECT_EQ(frames(0x583)[0], CanFrame(0x583, {0x60, 0x01, 0x18, 0x05, 0, 0, 0, 0}));
  EXPECT_EQ(sim_->od().get<std::uint16_t>(0x1801, 5), 500);
  net_.bus().clear_log();
  net_.run_for(1600ms);
  EXPECT_EQ(frames(0x283).size(), 3u);
}

TEST_F(Mcb402OnBus, ChangeDrivenAxesWhenTheAnalogueInterruptIsEnabled) {
  boot();
  ASSERT_EQ(download(0x6423, 0, {1}), SdoAbortCode::None);
  net_.bus().clear_log();
  sim_->move_axis(3, 1000, net_.now());
  net_.settle();
  ASSERT_EQ(frames(0x283).size(), 1u);
  EXPECT_EQ(v(kZ).value, 1000);
}

TEST_F(Mcb402OnBus, EachButtonPressAndReleaseIsSentAtOnce) {
  boot();
  for (std::size_t b = 1; b <= 7; ++b) {
    net_.bus().clear_log();
    sim_->press(b, net_.now());
    net_.settle();
    // CN6: a pressed button shorts its pin to GND (active low)...
    EXPECT_EQ(sim_->input_pins() & (1u << sim_->config().button_bits[b - 1]), 0u);
    // ...and the controller sends 1 for it ([MCB §4] "If a switch is pressed ... MCB402 returns 183 ...").
    ASSERT_EQ(frames(0x183).size(), 1u) << "BP" << b;
    EXPECT_EQ(frames(0x183)[0].data[2], 1u << sim_->config().button_bits[b - 1]);
    for (std::size_t o = 1; o <= 7; ++o) EXPECT_EQ(v(button(o)).value, o == b ? 1 : 0) << "BP" << b << "/" << o;
    sim_->release(b, net_.now());
    net_.settle();
    EXPECT_EQ(frames(0x183).size(), 2u);
    EXPECT_EQ(v(button(b)).value, 0);
    EXPECT_EQ(v(button(b)).status, SignalStatus::Valid);
  }
}

TEST_F(Mcb402OnBus, InputPolarityIsPinnedByTheConfiguration) {
  // Someone stored an inversion of IN7..IN0 (6002h:03): the wire would read 1 = released.
  sim_->start(net_.now());
  net_.settle();
  ASSERT_EQ(download(0x6002, 3, {0xFF}), SdoAbortCode::None);
  EXPECT_EQ(sim_->od().get<std::uint8_t>(0x6000, 3), 0xFF);
  // The driver's configuration puts it back: nothing pressed reads as nothing pressed.
  for (const auto& w : driver_->configuration()) ASSERT_EQ(download(w.index, w.sub, w.data), SdoAbortCode::None);
  start();
  for (std::size_t b = 1; b <= 7; ++b) EXPECT_EQ(v(button(b)).value, 0);
  sim_->press(5, net_.now());
  net_.settle();
  EXPECT_EQ(v(button(5)).value, 1);
}

TEST_F(Mcb402OnBus, LedsFollowSetOutputThroughRpdo1) {
  boot();
  EXPECT_TRUE(driver_->set_output(led(1), 1, net_.now()));
  EXPECT_TRUE(driver_->set_output(led(4), 1, net_.now()));
  net_.settle();
  // [CO4013 "Operation mode 4"] RPDO1 -> 6200h:01, OUT3..OUT0.
  EXPECT_EQ(sim_->leds(), 0x09);
  EXPECT_TRUE(sim_->led(1));
  EXPECT_FALSE(sim_->led(2));
  EXPECT_TRUE(sim_->led(4));
  EXPECT_EQ(frames(0x203).back(), CanFrame(0x203, {0x09}));
  EXPECT_TRUE(driver_->set_output(led(1), 0, net_.now()));
  net_.settle();
  EXPECT_EQ(sim_->leds(), 0x08);
  // [CO4013 Index 6200] 6200h is write only.
  EXPECT_EQ(upload(0x6200, 1).first, SdoAbortCode::ReadOfWriteOnly);
  // [CO4013 Index 6206/6207]: in a device error the outputs go to 6207h (0 = inactive).
  sim_->device_error(true);
  EXPECT_EQ(sim_->leds(), 0x00);
  sim_->device_error(false);
  EXPECT_EQ(sim_->leds(), 0x08);
}

// [MCB §4] "At the power on, MCB402 writes on the bus: 703 00 ... 083 00 81 11 0": the boot-up,
// then the EMCY "CAN Bus in Error Warning state" 00 81 11 00 00 00 00 00 ([CO4013 "Emergency
// Messages"]). A warning: decoded, faulting nothing; the joystick is live once started.
TEST_F(Mcb402OnBus, PowerOnSendsTheTracesWarning8100hWhichFaultsNothing) {
  sim_->start(net_.now());
  net_.settle();
  const auto& log = net_.bus().log();
  ASSERT_GE(log.size(), 2u);
  EXPECT_EQ(log[0].frame, CanFrame(0x703, {0x00}));
  EXPECT_EQ(log[1].frame, CanFrame(0x83, {0x00, 0x81, 0x11, 0x00, 0x00, 0x00, 0x00, 0x00}));
  ASSERT_EQ(emcys_.size(), 1u);
  EXPECT_EQ(emcys_[0].code, 0x8100);
  EXPECT_FALSE(emcys_[0].error);
  EXPECT_TRUE(emcys_[0].affected.empty());
  EXPECT_FALSE(driver_->any_fault());
  // An event: the board's error register is not left set by it.
  EXPECT_EQ(upload(0x1001, 0).second, Bytes{0x00});
  for (const auto& w : driver_->configuration())
    ASSERT_EQ(download(w.index, w.sub, w.data), SdoAbortCode::None) << w.what;
  start();
  sim_->move_axis(1, 1234, net_.now());
  net_.run_for(50ms);
  EXPECT_EQ(v(kX).status, SignalStatus::Valid);
  EXPECT_EQ(v(kX).value, 1234);
  // After a power cycle, again.
  emcys_.clear();
  sim_->reboot(net_.now());
  net_.settle();
  ASSERT_EQ(emcys_.size(), 1u);
  EXPECT_EQ(emcys_[0].code, 0x8100);
}

// A cable broken while powered, mended while the board is off: the board sends no error reset
// (it is off), and after the power cycle its 1001h has no device error bit ([CO4013 Index 1001]
// bit 7): the driver's read-back at the restart clears the latch; one still broken keeps it.
TEST_F(Mcb402OnBus, CableBreakLatchIsDecidedByThe1001hReadBackAfterAReboot) {
  boot();
  sim_->cable_break(1, true, net_.now());
  net_.run_for(50ms);
  ASSERT_EQ(v(kX).status, SignalStatus::Error);
  // Still broken across a power cycle: 1001h = 81h, the latch stays.
  driver_->on_offline(net_.now());
  sim_->reboot(net_.now());
  net_.settle();
  driver_->on_application_reset(net_.now());
  driver_->begin_boot();
  auto reads = driver_->boot_reads();
  ASSERT_EQ(reads.size(), 1u);
  EXPECT_EQ(reads[0], (std::pair<std::uint16_t, std::uint8_t>{0x1001, 0}));
  std::string error;
  const Bytes reg = upload(0x1001, 0).second;
  EXPECT_EQ(reg, Bytes{0x81});
  ASSERT_TRUE(driver_->on_boot_read(0x1001, 0, reg, error));
  EXPECT_TRUE(driver_->boot_reads().empty());
  for (const auto& w : driver_->configuration()) ASSERT_EQ(download(w.index, w.sub, w.data), SdoAbortCode::None);
  start();
  net_.run_for(50ms);
  EXPECT_EQ(v(kX).status, SignalStatus::Error);
  EXPECT_EQ(v(kY).status, SignalStatus::Valid);
  // Switched off, repaired, switched on: no 0000h ever reaches the gateway.
  driver_->on_offline(net_.now());
  sim_->set_silent(true);
  sim_->cable_break(1, false, net_.now());
  sim_->set_silent(false);
  sim_->reboot(net_.now());
  net_.settle();
  driver_->on_application_reset(net_.now());
  driver_->begin_boot();
  ASSERT_EQ(driver_->boot_reads().size(), 1u);
  const Bytes reg2 = upload(0x1001, 0).second;
  EXPECT_EQ(reg2, Bytes{0x00});
  ASSERT_TRUE(driver_->on_boot_read(0x1001, 0, reg2, error));
  EXPECT_FALSE(driver_->any_fault());
  for (const auto& w : driver_->configuration()) ASSERT_EQ(download(w.index, w.sub, w.data), SdoAbortCode::None);
  start();
  sim_->move_axis(1, 777, net_.now());
  net_.run_for(50ms);
  EXPECT_EQ(v(kX).status, SignalStatus::Valid);
  EXPECT_EQ(v(kX).value, 777);
}

TEST_F(Mcb402OnBus, CableBreakPutsTheAxisInErrorAndRecoveryNeedsTheDevice) {
  boot();
  sim_->move_axis(2, 5000, net_.now());
  net_.run_for(20ms);
  ASSERT_EQ(v(kY).value, 5000);
  net_.bus().clear_log();
  emcys_.clear();  // the power-on 8100h
  sim_->cable_break(2, true, net_.now());
  net_.settle();
  // [CO4013 "Emergency Messages"] cable break detection "20 31 81 00 8x 00 00 00", bit1 = y-axis.
  ASSERT_EQ(frames(0x83).size(), 1u);
  EXPECT_EQ(frames(0x83)[0], CanFrame(0x83, {0x20, 0x31, 0x81, 0x00, 0x82, 0x00, 0x00, 0x00}));
  ASSERT_EQ(emcys_.size(), 1u);
  EXPECT_EQ(emcys_[0].affected, std::vector<std::size_t>{kY});
  EXPECT_EQ(v(kY).status, SignalStatus::Error);
  EXPECT_EQ(v(kY).value, 0);
  // The broken wiper reads full scale on the wire; the driver never passes it through.
  net_.run_for(100ms);
  ASSERT_FALSE(frames(0x283).empty());
  EXPECT_EQ(frames(0x283).back().data[2], 0x00);
  EXPECT_EQ(frames(0x283).back().data[3], 0x80);
  EXPECT_EQ(v(kY).status, SignalStatus::Error);
  EXPECT_EQ(v(kY).value, 0);
  EXPECT_EQ(v(kX).status, SignalStatus::Valid);
  // A second axis: the bits are ORed, sent as error reset + the new set (see the simulator).
  sim_->cable_break(4, true, net_.now());
  net_.settle();
  EXPECT_EQ(frames(0x83).back(), CanFrame(0x83, {0x20, 0x31, 0x81, 0x00, 0x8A, 0x00, 0x00, 0x00}));
  EXPECT_EQ(v(kY).status, SignalStatus::Error);
  EXPECT_EQ(v(kT).status, SignalStatus::Error);
  // Both mended: error reset 0000h; the next TPDO2 brings the real values back.
  sim_->cable_break(2, false, net_.now());
  sim_->cable_break(4, false, net_.now());
  net_.settle();
  EXPECT_EQ(frames(0x83).back(), CanFrame(0x83, {0, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_FALSE(emcys_.back().error);
  net_.run_for(20ms);
  EXPECT_EQ(v(kY).status, SignalStatus::Valid);
  EXPECT_EQ(v(kY).value, 5000);
  EXPECT_EQ(v(kT).status, SignalStatus::Valid);
  EXPECT_EQ(driver_->counters().unknown_emcy, 0u);
}

TEST_F(Mcb402OnBus, RebootedBoardGetsItsLedsBackAndReadsItsPins) {
  boot();
  ASSERT_TRUE(driver_->set_output(led(3), 1, net_.now()));
  sim_->press(2, net_.now());
  net_.settle();
  ASSERT_TRUE(sim_->led(3));
  sim_->reboot(net_.now());
  net_.settle();
  EXPECT_EQ(sim_->leds(), 0x00) << "6200h back to its default";
  driver_->on_offline(net_.now());
  EXPECT_EQ(v(button(2)).status, SignalStatus::Offline);
  for (const auto& w : driver_->configuration()) ASSERT_EQ(download(w.index, w.sub, w.data), SdoAbortCode::None);
  start();
  EXPECT_TRUE(sim_->led(3)) << "on_online re-sends the remembered output byte";
  EXPECT_EQ(v(button(2)).value, 1) << "the pin is still pressed after the reset";
  EXPECT_EQ(v(button(2)).status, SignalStatus::Valid);
}

TEST_F(Mcb402OnBus, DictionaryHoldsTheDocumentedObjects) {
  sim_->start(net_.now());
  net_.settle();
  EXPECT_EQ(upload_u32(0x1000, 0), 0x01070191u);  // [CO4013 Index 1000] CO4013A4
  EXPECT_EQ(upload(0x1018, 0).second, Bytes{3});  // [CO4013 Index 1018] sub 0 = 3
  EXPECT_EQ(upload(0x1018, 4).first, SdoAbortCode::SubIndexDoesNotExist);
  auto name = upload(0x1008, 0).second;
  EXPECT_EQ(std::string(name.begin(), name.end()), "CO4013A");
  auto maker = upload(0x2000, 0).second;
  EXPECT_EQ(std::string(maker.begin(), maker.end()), "Frenzel + Berg");
  EXPECT_EQ(upload_u32(0x2101, 0), 4u);  // operation mode 4
  EXPECT_EQ(upload_u32(0x100E, 0), 0x703u);
  EXPECT_EQ(upload_u32(0x1014, 0), 0x83u);  // [CO4013 Index 1014] 80h + node-ID
  EXPECT_EQ(upload_u32(0x1800, 1), 0x183u);
  EXPECT_EQ(upload_u32(0x1801, 1), 0x283u);
  EXPECT_EQ(upload_u32(0x1400, 1), 0x203u);            // [CO4013 Index 1400] 200h + node-ID
  EXPECT_EQ(upload(0x1801, 5).second, (Bytes{0, 0}));  // event time default 0
  EXPECT_EQ(upload(0x6423, 0).second, Bytes{0});       // analogue interrupt disabled
  EXPECT_EQ(upload(0x6005, 0).second, Bytes{1});       // digital interrupt enabled
  EXPECT_EQ(upload(0x6006, 3).second, Bytes{0xFF});
  EXPECT_EQ(upload(0x6421, 1).second, Bytes{7});
  EXPECT_EQ(upload(0x5401, 4).second, (Bytes{0x00, 0x10}));
  EXPECT_EQ(upload(0x6206, 1).second, Bytes{0xFF});
  EXPECT_EQ(upload_u32(0x1002, 0), 0u);
  EXPECT_EQ(upload(0x6401, 0).second, Bytes{4});
  host_->nmt().start(kNode);
  net_.run_for(1ms);
  EXPECT_EQ(upload_u32(0x1002, 0), 0x80000000u);  // [CO4013 Index 1002] bit 31 = operational
}

TEST(Mcb402Jumpers, AddressAndBitRateFromTheCn3Table) {
  // [MCB §3] CN3: pins 14..2 = address bits 6..0 (1 = open), pins 20,18,16 = bit rate.
  auto c = Mcb402SimConfig::from_jumpers(0b1111110, 0b101);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->node_id, NodeId{0x01});
  EXPECT_EQ(c->kbaud, 500);
  c = Mcb402SimConfig::from_jumpers(0b1111101, 0b100);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->node_id, NodeId{0x02});
  EXPECT_EQ(c->kbaud, 250);
  c = Mcb402SimConfig::from_jumpers(0b1111100, 0b011);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->node_id, NodeId{0x03});
  EXPECT_EQ(c->kbaud, 125);
  c = Mcb402SimConfig::from_jumpers(0b0000000, 0b001);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->node_id, NodeId{0x7F});
  EXPECT_EQ(c->kbaud, 20);
  c = Mcb402SimConfig::from_jumpers(0b1111100, 0b010);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->kbaud, 50);
  EXPECT_FALSE(Mcb402SimConfig::from_jumpers(0b1111111, 0b101)) << "address 0 is not selectable";
  EXPECT_FALSE(Mcb402SimConfig::from_jumpers(0b1111100, 0b000));
  EXPECT_FALSE(Mcb402SimConfig::from_jumpers(0b1111100, 0b110));
  // The simulated node runs on them (CiA 305 bit-timing index 2 = 500 kbit/s).
  oegw::testing::VirtualNetwork net;
  auto cfg = Mcb402SimConfig::from_jumpers(0b1111110, 0b101);
  Mcb402Sim sim(net.sink("sim"), *cfg);
  EXPECT_EQ(sim.node().node_id(), NodeId{1});
  EXPECT_EQ(sim.bit_timing_index(), 2);
  EXPECT_EQ(sim.node().bit_timing_index(), 2);
}

}  // namespace

namespace {

// A board with its store, and a probe that sends raw frames and collects the board's answers.
class Mcb402Frames : public ::testing::Test {
 protected:
  Mcb402Frames() {
    dir_ = std::filesystem::temp_directory_path() / ("oegw-mcb-" + std::to_string(::getpid()) + "-" +
                                                     ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
    cfg_.store_path = dir_ / "params.txt";
  }
  ~Mcb402Frames() override { std::filesystem::remove_all(dir_); }
  void power_on() {
    sim_ = std::make_unique<Mcb402Sim>(net_.sink("sim"), cfg_);
    net_.attach("sim", *sim_);
    net_.bus().set_logging(true);
    sim_->start(net_.now());
    net_.settle();
  }
  std::vector<CanFrame> exchange(std::uint32_t id, Bytes bytes, std::uint32_t reply) {
    return net_.exchange("probe", CanFrame(id, std::span<const std::uint8_t>(bytes)), reply);
  }
  std::vector<CanFrame> frames(std::uint32_t id) { return net_.logged(id); }
  std::filesystem::path dir_;
  Mcb402SimConfig cfg_;
  oegw::testing::VirtualNetwork net_;
  std::unique_ptr<Mcb402Sim> sim_;
};

using Frames = std::vector<CanFrame>;

// [CO4013 Index 1010/1011]: the signature in bytes 4..7 ("save" = 65h 76h 61h 73h MSB first:
// 73 61 76 65; "load" = 6C 6F 61 64); "By read access to object 1010h Subindex 1, the device
// responds with SDO data 00000001h"; a wrong signature: "Abort code: 0800 002x h" (0800 0020h);
// "Writing to this object is only allowed in preoperational mode".
TEST_F(Mcb402Frames, StoreAndRestoreSignaturesAndTheWrongSignatureAbort) {
  power_on();
  EXPECT_EQ(exchange(0x603, {0x40, 0x10, 0x10, 0x01, 0, 0, 0, 0}, 0x583),
            Frames{CanFrame(0x583, {0x43, 0x10, 0x10, 0x01, 0x01, 0x00, 0x00, 0x00})});
  EXPECT_EQ(exchange(0x603, {0x40, 0x11, 0x10, 0x01, 0, 0, 0, 0}, 0x583),
            Frames{CanFrame(0x583, {0x43, 0x11, 0x10, 0x01, 0x01, 0x00, 0x00, 0x00})});
  EXPECT_EQ(exchange(0x603, {0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65}, 0x583),
            Frames{CanFrame(0x583, {0x60, 0x10, 0x10, 0x01, 0, 0, 0, 0})});
  EXPECT_TRUE(std::filesystem::exists(cfg_.store_path));
  EXPECT_EQ(exchange(0x603, {0x23, 0x10, 0x10, 0x01, 0x65, 0x76, 0x61, 0x73}, 0x583),  // the letters reversed
            Frames{CanFrame(0x583, {0x80, 0x10, 0x10, 0x01, 0x20, 0x00, 0x00, 0x08})});
  EXPECT_EQ(exchange(0x603, {0x23, 0x11, 0x10, 0x01, 0x6C, 0x6F, 0x61, 0x64}, 0x583),
            Frames{CanFrame(0x583, {0x60, 0x11, 0x10, 0x01, 0, 0, 0, 0})});
  EXPECT_EQ(exchange(0x603, {0x23, 0x11, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65}, 0x583),
            Frames{CanFrame(0x583, {0x80, 0x11, 0x10, 0x01, 0x20, 0x00, 0x00, 0x08})});
  (void)exchange(0x000, {0x01, 0x03}, 0x583);  // operational: "otherwise ... SDO abort telegrams"
  EXPECT_EQ(exchange(0x603, {0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65}, 0x583),
            Frames{CanFrame(0x583, {0x80, 0x10, 0x10, 0x01, 0x22, 0x00, 0x00, 0x08})});
}

// [CO4013 "Emergency Messages"]: "Life-Guarding Error 30 81 11 00 00 00 00 00", "CAN Bus in Error
// Warning state 00 81 11 00 ...", "Return from Bus OFF 40 81 11 00 ...", and the cable break
// "20 31 81 00 8x 00 00 00" — as the simulated board sends them, 1001h in byte 2.
TEST_F(Mcb402Frames, TheDocumentsEmergencyFrames) {
  power_on();
  EXPECT_EQ(frames(0x083), Frames{CanFrame(0x083, {0x00, 0x81, 0x11, 0x00, 0x00, 0x00, 0x00, 0x00})}) << "power-on";
  (void)exchange(0x000, {0x01, 0x03}, 0x083);
  net_.bus().clear_log();
  sim_->life_guarding(net_.now());
  sim_->bus_off_recovered(net_.now());
  sim_->cable_break(2, true, net_.now());
  net_.settle();
  EXPECT_EQ(frames(0x083), (Frames{CanFrame(0x083, {0x30, 0x81, 0x11, 0x00, 0x00, 0x00, 0x00, 0x00}),
                                   CanFrame(0x083, {0x40, 0x81, 0x11, 0x00, 0x00, 0x00, 0x00, 0x00}),
                                   CanFrame(0x083, {0x20, 0x31, 0x81, 0x00, 0x82, 0x00, 0x00, 0x00})}));
  EXPECT_EQ(sim_->error_register(), 0x81) << "the CAN warnings' bits not kept (power_on_1001h=00h)";
}

// The corners of what the document leaves open: the mend sends 0000h or nothing
// (clear_after_break), 1001h keeps the CAN warnings' 11h or not (power_on_1001h).
TEST_F(Mcb402Frames, MendWithoutErrorResetAndAKept11h) {
  cfg_.clear_with_error_reset = false;
  cfg_.keep_communication_bits = true;
  power_on();
  EXPECT_EQ(sim_->error_register(), 0x11);
  (void)exchange(0x000, {0x01, 0x03}, 0x083);
  net_.bus().clear_log();
  sim_->cable_break(1, true, net_.now());
  net_.settle();
  EXPECT_EQ(frames(0x083), Frames{CanFrame(0x083, {0x20, 0x31, 0x91, 0x00, 0x81, 0x00, 0x00, 0x00})});
  EXPECT_EQ(sim_->error_register(), 0x91);
  net_.bus().clear_log();
  sim_->cable_break(1, false, net_.now());
  net_.settle();
  EXPECT_TRUE(frames(0x083).empty()) << "no error reset";
  EXPECT_EQ(sim_->error_register(), 0x11) << "1001h shows the mend";
  EXPECT_EQ(exchange(0x603, {0x40, 0x01, 0x10, 0x00, 0, 0, 0, 0}, 0x583),
            Frames{CanFrame(0x583, {0x4F, 0x01, 0x10, 0x00, 0x11, 0x00, 0x00, 0x00})});
}

}  // namespace
