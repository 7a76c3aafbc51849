// The life of a sub-device fault on the virtual buses (rig/cab_rig.hpp, the demo cab of
// tests/fixtures/demo_cab.yaml, a simulated clock), as each family's document says its device
// behaves (docs/design/device-documents.md#faults-what-sets-them-what-clears-them): what the device
// reports at power-on is no fault, a fault is the driver's until the device's own evidence clears
// it, and the gateway holds none of its own.
#include <gtest/gtest.h>

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "gateway/gateway.hpp"
#include "rig/cab_rig.hpp"
#include "subdevices/novotechnik_406.hpp"
#include "subdevices/sim/elobau_mfg_sim.hpp"
#include "subdevices/sim/mcb402_sim.hpp"
#include "subdevices/sim/novotechnik_406_sim.hpp"
#include "tests/fixtures/fixtures.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
namespace gw = oegw::gateway;
namespace sd = oegw::subdevices;
namespace sim = oegw::subdevices::sim;

namespace {

constexpr std::uint32_t kGatewayEmcy = 0x80 + 0x20;
constexpr std::uint8_t kGrip = 0x11, kLeft = 0x03, kKnob = 0x7F;

class Faults : public ::testing::Test {
 protected:
  void SetUp() override {
    auto loaded = oegw::mapping::load_config_text(oegw::fixtures::mapping_file("demo_cab.yaml"), "faults.yaml",
                                                  gw::driver_catalogue());
    ASSERT_TRUE(loaded.ok()) << loaded.error_text();
    config_ = std::move(*loaded.config);
    rig_ = std::make_unique<oegw::rig::CabRig>(config_, loop_);
    rig_->up().set_tap([this](const BusRecord& r) {
      if (r.frame.id == kGatewayEmcy) up_emcys_.push_back(r.frame);
    });
    rig_->on_gateway = [this](gw::Gateway& g) { g.on_log = [this](const std::string& l) { log_ += l + "\n"; }; };
    rig_->build();
  }
  void power_on() {
    rig_->power_on();
    rig_->run_for(3s);
    for (const auto& n : rig_->gw().downstream().names())
      ASSERT_EQ(rig_->gw().downstream().state(n), sd::NodeState::Operational) << n << "\n" << log_;
  }
  TimePoint now() const { return loop_.now(); }
  // EMCY 7000h frames naming `node` (oe_device.hpp: byte 3 = node-ID).
  std::size_t faults_named(std::uint8_t node) const {
    std::size_t n = 0;
    for (const auto& f : up_emcys_)
      if (f.data[0] == 0x00 && f.data[1] == 0x70 && f.data[3] == node) ++n;
    return n;
  }
  // The gateway's error resets 0000h naming `node`, or its plain one (the last error gone).
  std::size_t resets_named(std::uint8_t node) const {
    std::size_t n = 0;
    for (const auto& f : up_emcys_)
      if (f.data[0] == 0x00 && f.data[1] == 0x00 && (f.data[3] == node || f.data[3] == 0x00)) ++n;
    return n;
  }
  sd::Driver& driver(const char* name) { return *rig_->gw().downstream().driver(name); }
  sim::ElobauMfgSim& grip() { return dynamic_cast<sim::ElobauMfgSim&>(*rig_->devices().device("right_grip")); }
  sim::Mcb402Sim& mcb() { return dynamic_cast<sim::Mcb402Sim&>(*rig_->devices().device("left_grip")); }
  sim::Novotechnik406Sim& knob() { return dynamic_cast<sim::Novotechnik406Sim&>(*rig_->devices().device("seat_knob")); }
  std::string cmd(const std::string& line) { return rig_->command(line); }
  gw::FeStatus joy2() const { return rig_->gw().status(oegw::mapping::FeId{oegw::mapping::FeKind::Joystick, 2}); }

  oegw::mapping::Config config_;
  SimulatedClock clock_;
  EventLoop loop_{clock_};
  std::unique_ptr<oegw::rig::CabRig> rig_;
  std::vector<CanFrame> up_emcys_;
  std::string log_;
};

// 1001h is read once per boot (network_manager.cpp): the manager's diagnostics read is what the
// MCB-402 and cia401 drivers decide their faults by, not a second upload of the same object.
TEST_F(Faults, ErrorRegisterIsReadOncePerBootAndStillDecides) {
  std::map<std::uint8_t, int> reads;  // node -> SDO upload requests of 1001h:00
  rig_->down().set_tap([&](const BusRecord& r) {
    const auto& f = r.frame;
    if (f.id > 0x600 && f.id < 0x680 && f.dlc == 8 && f.data[0] == 0x40 && f.data[1] == 0x01 && f.data[2] == 0x10 &&
        f.data[3] == 0x00)
      ++reads[static_cast<std::uint8_t>(f.id - 0x600)];
  });
  power_on();
  for (const std::uint8_t node : {kGrip, kLeft, kKnob, std::uint8_t{0x30}, std::uint8_t{0x31}})
    EXPECT_EQ(reads[node], 1) << "node " << int{node};
  // Still the evidence: a cable break latched, the board rebooted with its device error bit
  // (the break persists) -> the latch stays after the single read of this boot.
  (void)cmd("left_grip cable_break 1 on");
  rig_->run_for(200ms);
  ASSERT_TRUE(driver("left_grip").any_fault());
  reads.clear();
  (void)cmd("left_grip reboot");
  rig_->run_for(20ms);  // its boot-up seen: being configured again
  ASSERT_NE(rig_->gw().downstream().state("left_grip"), sd::NodeState::Operational) << log_;
  // Once in the boot; afterwards, while the break lasts, the driver's fault poll reads it too.
  for (int i = 0; i < 3000 && rig_->gw().downstream().state("left_grip") != sd::NodeState::Operational; ++i)
    rig_->run_for(1ms);
  EXPECT_EQ(reads[kLeft], 1);
  rig_->run_for(1s);
  EXPECT_GE(reads[kLeft], 4) << "read every 250 ms while the cable break is latched";
  EXPECT_TRUE(driver("left_grip").any_fault()) << log_;
  (void)cmd("left_grip cable_break 1 off");
  rig_->run_for(200ms);
  EXPECT_FALSE(driver("left_grip").any_fault()) << log_;
}

// [MCB §4] power-on trace "703 00" then "083 00 81 11 0": the EMCY 8100h "CAN bus in error warning
// state" right after the boot-up, during the gateway's configuration, and never an error reset.
// A warning: joystick 2 goes live, no 7000h names the board.
TEST_F(Faults, Mcb402PowerOnWarning8100hDoesNotFaultTheJoystick) {
  power_on();
  ASSERT_NE(log_.find("left_grip: EMCY 8100h"), std::string::npos) << log_;
  EXPECT_EQ(faults_named(kLeft), 0u) << log_;
  EXPECT_FALSE(driver("left_grip").any_fault());
  EXPECT_EQ(rig_->gw().faults().count("left_grip"), 0u) << log_;
  EXPECT_EQ(joy2(), gw::FeStatus::Valid) << log_;
  // A real fault still is one: cable break on X, 7000h naming the board, cleared by its reset.
  mcb().cable_break(1, true, now());
  rig_->run_for(300ms);
  EXPECT_EQ(faults_named(kLeft), 1u) << log_;
  EXPECT_EQ(joy2(), gw::FeStatus::Error);
  mcb().cable_break(1, false, now());
  rig_->run_for(300ms);
  EXPECT_GE(resets_named(kLeft), 1u) << log_;
  EXPECT_EQ(joy2(), gw::FeStatus::Valid) << log_;
}

// elobau Table 6 0002h "also set until first parameter saving process": a never-saved grip is
// neither a silent latch nor a silent pass: refused at boot with the commissioning step in the
// reason (its EMCY 0002h at power-on faults nothing of a node that is not yet operational).
TEST_F(Faults, ElobauUnsavedGripIsRefusedSayingHowToSaveIt) {
  grip().set_parameters_saved(false);
  rig_->power_on();
  rig_->run_for(3s);
  ASSERT_NE(log_.find("right_grip: EMCY 1000h elobau 4001h 0002h"), std::string::npos) << log_;
  EXPECT_EQ(rig_->gw().downstream().state("right_grip"), sd::NodeState::Refused) << log_;
  EXPECT_NE(log_.find("right_grip: refused (4001h:00: 4001h reads 0002h"), std::string::npos) << log_;
  for (const char* other : {"left_grip", "pedal", "seat_knob", "cluster"})
    EXPECT_EQ(rig_->gw().downstream().state(other), sd::NodeState::Operational) << other << "\n" << log_;
}

// A grip that reboots while in use (its boot-up while operational): the host is told at once
// by 7000h naming it, and again by its 0000h only when it is back; a grip that keeps rebooting
// (every 94 ms, faster than any boot completes) stays reported for as long as it does.
TEST_F(Faults, ARebootWhileInUseIsReportedAtOnceAndARebootLoopForItsWholeLength) {
  power_on();
  ASSERT_EQ(faults_named(kGrip), 0u) << log_;
  grip().reboot(now());
  rig_->run_for(50ms);
  EXPECT_EQ(faults_named(kGrip), 1u) << log_;
  EXPECT_EQ(rig_->gw().faults().count("right_grip"), 1u) << log_;
  rig_->run_for(3s);
  ASSERT_EQ(rig_->gw().downstream().state("right_grip"), sd::NodeState::Operational) << log_;
  EXPECT_EQ(rig_->gw().faults().count("right_grip"), 0u) << log_;
  EXPECT_GE(resets_named(kGrip), 1u) << log_;

  const auto before = faults_named(kGrip);
  for (int i = 0; i < 100; ++i) {
    grip().reboot(now());
    rig_->run_for(94ms);
    ASSERT_EQ(rig_->gw().faults().count("right_grip"), 1u) << "reboot " << i << "\n" << log_;
  }
  EXPECT_EQ(faults_named(kGrip), before + 1) << log_;  // reported once, held throughout
}

// A cable broken while powered, the board switched off, repaired, switched on: it sends no error
// reset, and its 1001h read back at the restart has no device error: the fault goes, with the
// gateway's error reset naming it.
TEST_F(Faults, Mcb402CableBreakClearedByTheReadBackAfterARebootWithTheRepair) {
  power_on();
  mcb().cable_break(2, true, now());
  rig_->run_for(300ms);
  ASSERT_EQ(faults_named(kLeft), 1u) << log_;
  // Switched off (silent), repaired, then on again.
  mcb().set_silent(true);
  rig_->run_for(500ms);
  mcb().cable_break(2, false, now());
  mcb().set_silent(false);
  mcb().reboot(now());
  rig_->run_for(5s);
  ASSERT_EQ(rig_->gw().downstream().state("left_grip"), sd::NodeState::Operational) << log_;
  EXPECT_FALSE(driver("left_grip").any_fault()) << log_;
  EXPECT_EQ(rig_->gw().faults().count("left_grip"), 0u) << log_;
  EXPECT_GE(resets_named(kLeft), 1u) << log_;
  // Still broken across a power cycle: the read-back keeps it.
  mcb().cable_break(3, true, now());
  rig_->run_for(300ms);
  mcb().reboot(now());
  rig_->run_for(5s);
  ASSERT_EQ(rig_->gw().downstream().state("left_grip"), sd::NodeState::Operational) << log_;
  EXPECT_TRUE(driver("left_grip").faulted(2)) << log_;
  EXPECT_NE(rig_->gw().faults().count("left_grip"), 0u) << log_;
}

// Novotechnik §9.1 5051h/1/1 "Out of range (+) ... Reset via Position Error Reset (2100h)": the
// fault holds (the sensor stays operational: 1029h:02 = 1) until the integrator's command
// "position_error_reset" and the sensor's answer, its "valid position" EMCY 5051h/0/0.
TEST_F(Faults, NovotechnikOverflowClearedOnlyAfterTheResetCommandAndTheSensorsValidPosition) {
  power_on();
  EXPECT_EQ(knob().od().get<std::uint8_t>(0x1029, 2), 1) << "written at configuration";
  knob().set_position(1000, now());
  rig_->run_for(100ms);
  knob().inject_fault(sim::Novotechnik406Sim::Fault::Overflow, now());
  rig_->run_for(300ms);
  ASSERT_EQ(faults_named(kKnob), 1u) << log_;
  EXPECT_EQ(rig_->gw().downstream().state("seat_knob"), sd::NodeState::Operational) << "not pre-operational";
  EXPECT_TRUE(driver("seat_knob").faulted(sd::Novotechnik406Driver::kPosition));
  // Unknown commands are refused and change nothing.
  EXPECT_FALSE(rig_->gw().subdevice_command("seat_knob", "reboot", now()));
  EXPECT_FALSE(rig_->gw().subdevice_command("left_grip", "position_error_reset", now()));
  // The command while the sensor is still out of range (below 650Ah:02): written, but the sensor
  // resets nothing ("Precondition: The sensor is turned back into the measurement range").
  knob().set_position(-100, now());
  ASSERT_TRUE(rig_->gw().subdevice_command("seat_knob", "position_error_reset", now()));
  rig_->run_for(300ms);
  EXPECT_NE(log_.find("seat_knob: position error reset (2100h = 1): done"), std::string::npos) << log_;
  EXPECT_TRUE(driver("seat_knob").faulted(sd::Novotechnik406Driver::kPosition)) << "the write is no evidence";
  EXPECT_EQ(resets_named(kKnob), 0u);
  // Back in range, the command again: the sensor answers 5051h/0/0, and only that clears it.
  knob().set_position(1000, now());
  ASSERT_TRUE(rig_->gw().subdevice_command("seat_knob", "position_error_reset", now()));
  rig_->run_for(300ms);
  EXPECT_NE(log_.find("seat_knob: EMCY 5051h"), std::string::npos);
  EXPECT_NE(log_.find("valid position"), std::string::npos) << log_;
  EXPECT_FALSE(driver("seat_knob").any_fault());
  EXPECT_GE(resets_named(kKnob), 1u) << log_;
  EXPECT_EQ(driver("seat_knob").value(sd::Novotechnik406Driver::kPosition).status, sd::SignalStatus::Valid);
}

// The same reset from the host, by SDO: 3000h "Sub-device command" = 01h << 8 | 7Fh (the sensor).
// Refused with a precise abort and no effect for an unknown node, an unknown code, a command the
// node's driver has not; accepted, 2100h reaches the sensor, and only its 5051h/0/0 clears.
TEST_F(Faults, TheHostResetsTheNovotechnikPositionErrorThrough3000h) {
  power_on();
  knob().set_position(1000, now());
  rig_->run_for(100ms);
  knob().inject_fault(sim::Novotechnik406Sim::Fault::Overflow, now());
  rig_->run_for(300ms);
  ASSERT_TRUE(driver("seat_knob").faulted(sd::Novotechnik406Driver::kPosition)) << log_;
  SdoClient& host = rig_->host().sdo(NodeId{0x20});
  const auto write = [&](std::uint32_t v) {
    std::optional<SdoAbortCode> got;
    host.download(0x3000, 0, encode<std::uint32_t>(v), [&](SdoAbortCode c, std::vector<std::uint8_t>) { got = c; });
    for (int i = 0; i < 2000 && !got; ++i) rig_->run_for(1ms);
    return got.value_or(SdoAbortCode::Timeout);
  };
  EXPECT_EQ(write(0x0155), SdoAbortCode::SubIndexDoesNotExist) << "no sub-device on node 55h";
  EXPECT_EQ(write(0x027F), SdoAbortCode::InvalidValue) << "no command 02h";
  EXPECT_EQ(write(0x0103), SdoAbortCode::InvalidValue) << "the MCB-402 has no position error reset";
  EXPECT_EQ(write(0x0001017F), SdoAbortCode::InvalidValue) << "bits 16..31 are 0";
  rig_->run_for(300ms);
  EXPECT_TRUE(driver("seat_knob").faulted(sd::Novotechnik406Driver::kPosition));
  EXPECT_EQ(write(0x017F), SdoAbortCode::None) << log_;
  rig_->run_for(300ms);
  EXPECT_NE(log_.find("host: 3000h sub-device command position_error_reset to seat_knob"), std::string::npos) << log_;
  EXPECT_NE(log_.find("valid position"), std::string::npos) << log_;
  EXPECT_FALSE(driver("seat_knob").any_fault()) << log_;
  EXPECT_GE(resets_named(kKnob), 1u) << log_;
}

// 1029h as the document says: a sensor left at its default 0 goes to pre-operational on a
// measurement error ([§4.1] 1029h:02) — what the gateway's configuration avoids.
TEST_F(Faults, NovotechnikMeasurementErrorKeepsTheSensorOperationalAsConfigured) {
  power_on();
  knob().inject_fault(sim::Novotechnik406Sim::Fault::Measurement, now());
  rig_->run_for(500ms);
  EXPECT_EQ(knob().node().state(), NmtState::Operational);
  EXPECT_EQ(rig_->gw().downstream().state("seat_knob"), sd::NodeState::Operational) << log_;
  EXPECT_NE(rig_->gw().faults().count("seat_knob"), 0u);
  EXPECT_NE(rig_->gw().faults().at("seat_knob").find("EMCY"), std::string::npos) << rig_->gw().faults().at("seat_knob");
  ASSERT_TRUE(knob().clear_fault(now()));
  rig_->run_for(300ms);
  EXPECT_EQ(rig_->gw().faults().count("seat_knob"), 0u) << log_;
  // The default: pre-operational.
  const std::vector<std::uint8_t> pre_operational{0x00};
  ASSERT_EQ(knob().od().write(0x1029, 2, pre_operational, Origin::Local), SdoAbortCode::None);
  knob().inject_fault(sim::Novotechnik406Sim::Fault::Measurement, now());
  EXPECT_EQ(knob().node().state(), NmtState::PreOperational);
}

// oegw-sim's text commands for the Novotechnik faults (sim_bench.hpp), as a bench operator types them.
TEST_F(Faults, NovotechnikFaultsByTheSimulatorsTextCommands) {
  power_on();
  EXPECT_EQ(cmd("seat_knob position 1000"), "ok seat_knob position = 1000");
  EXPECT_EQ(cmd("seat_knob fault overflow"), "ok seat_knob fault overflow");
  rig_->run_for(300ms);
  EXPECT_TRUE(driver("seat_knob").any_fault());
  EXPECT_EQ(cmd("seat_knob fault clear").rfind("error:", 0), 0u) << "out of range: 2100h only";
  EXPECT_EQ(cmd("left_grip fault overflow").rfind("error:", 0), 0u);
  EXPECT_EQ(cmd("seat_knob fault nonsense").rfind("error:", 0), 0u);
  ASSERT_TRUE(rig_->gw().subdevice_command("seat_knob", "position_error_reset", now()));
  rig_->run_for(300ms);
  EXPECT_FALSE(driver("seat_knob").any_fault()) << log_;
  EXPECT_EQ(cmd("seat_knob fault measurement"), "ok seat_knob fault measurement");
  rig_->run_for(300ms);
  EXPECT_TRUE(driver("seat_knob").any_fault());
  EXPECT_EQ(cmd("seat_knob fault clear"), "ok seat_knob fault cleared");
  rig_->run_for(300ms);
  EXPECT_FALSE(driver("seat_knob").any_fault()) << log_;
}

}  // namespace
