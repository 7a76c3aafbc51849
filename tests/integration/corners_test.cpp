// The drivers at every corner of their documents
// (docs/design/device-documents.md#corners-every-reading-a-document-permits): where a device
// document is ambiguous, silent or self-contradictory, each reading it permits is a simulator
// option, and the gateway must work against each (or refuse it at boot, saying how to commission
// the device). One sub-device behind the gateway on the virtual buses with a simulated clock
// (rig/cab_rig.hpp), the simulator at the corner under test.
#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "gateway/gateway.hpp"
#include "rig/cab_rig.hpp"
#include "subdevices/sim/elobau_mfg_sim.hpp"
#include "subdevices/sim/mcb402_sim.hpp"
#include "subdevices/sim/novotechnik_406_sim.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
namespace gw = oegw::gateway;
namespace sd = oegw::subdevices;
namespace sim = oegw::subdevices::sim;
using oegw::mapping::FeId;
using oegw::mapping::FeKind;

namespace {

constexpr std::uint32_t kGatewayEmcy = 0x80 + 0x20;
const std::string kHead =
    "upstream: { interface: virtual, node_id: 0x20, identity: { vendor_id: 0, product_code: 0x852, revision: 0x10000, "
    "serial: 1 } }\n"
    "downstream: { interface: virtual }\n";

// One sub-device `dev` (the mapping file's lines) at the simulator options `corner`.
class Corners : public ::testing::Test {
 protected:
  ~Corners() override {
    rig_.reset();
    for (const auto& p : stores_) {
      std::filesystem::remove(p);
      std::filesystem::remove(p + ".lss");
    }
  }
  // A store file for the simulator (1010h "save" works with one).
  std::string store(const std::string& name) {
    stores_.push_back(
        (std::filesystem::path(::testing::TempDir()) / fmt::format("corners_{}_{}", ::getpid(), name)).string());
    std::filesystem::remove(stores_.back());
    return stores_.back();
  }
  void build(const std::string& subdevices_and_fes, const std::string& dev, sd::DriverOptions corner) {
    rig_.reset();
    down_.clear();
    up_emcys_.clear();
    auto loaded = oegw::mapping::load_config_text(kHead + subdevices_and_fes, "corners.yaml", gw::driver_catalogue());
    ASSERT_TRUE(loaded.ok()) << loaded.error_text();
    config_ = std::move(*loaded.config);
    dev_ = dev;
    oegw::rig::CabRigOptions o;
    o.simulator_options[dev] = std::move(corner);
    rig_ = std::make_unique<oegw::rig::CabRig>(config_, loop_, o);
    rig_->up().set_tap([this](const BusRecord& r) {
      if (r.frame.id == kGatewayEmcy) up_emcys_.push_back(r.frame);
    });
    rig_->down().set_tap([this](const BusRecord& r) { down_.push_back(r); });
    rig_->on_gateway = [this](gw::Gateway& g) {
      g.on_log = [this](const std::string& l) { log_ += fmt::format("[{}] {}\n", ms(), l); };
    };
    rig_->build();
    rig_->power_on();
    rig_->run_for(3s);
  }
  long ms() const {
    return static_cast<long>(
        std::chrono::duration_cast<std::chrono::milliseconds>(loop_.now().time_since_epoch()).count());
  }
  sd::NodeState state() const { return rig_->gw().downstream().state(dev_); }
  sd::Driver& driver() { return *rig_->gw().downstream().driver(dev_); }
  sim::SimulatedDevice& device() { return *rig_->devices().device(dev_); }
  template <class T>
  T& as() {
    return dynamic_cast<T&>(device());
  }
  std::size_t faults_named(std::uint8_t node) const {
    std::size_t n = 0;
    for (const auto& f : up_emcys_)
      if (f.data[0] == 0x00 && f.data[1] == 0x70 && f.data[3] == node) ++n;
    return n;
  }
  std::size_t resets() const {
    std::size_t n = 0;
    for (const auto& f : up_emcys_)
      if (f.data[0] == 0x00 && f.data[1] == 0x00) ++n;
    return n;
  }
  std::int64_t field(FeId fe, const std::string& name) const {
    for (const auto& f : rig_->gw().fields(fe))
      if (f.name == name) return f.value;
    return -999999;
  }
  const sd::SignalValue& signal(const std::string& name) { return driver().value(*driver().find_signal(name)); }
  // Downstream frames the device sent with identifier `id` since `from`.
  std::vector<CanFrame> sent(std::uint32_t id, TimePoint from) const {
    std::vector<CanFrame> out;
    for (const auto& r : down_)
      if (r.frame.id == id && r.time >= from) out.push_back(r.frame);
    return out;
  }
  std::string cmd(const std::string& line) { return rig_->command(line); }

  oegw::mapping::Config config_;
  SimulatedClock clock_;
  EventLoop loop_{clock_};
  std::unique_ptr<oegw::rig::CabRig> rig_;
  std::string dev_;
  std::vector<CanFrame> up_emcys_;
  std::vector<BusRecord> down_;
  std::vector<std::string> stores_;
  std::string log_;
};

// ---- Novotechnik (document 004) ----------------------------------------------------------------

const std::string kKnob =
    "subdevices:\n  knob: { driver: novotechnik-406, node_id: 0x7F, heartbeat_ms: 100 }\n"
    "functional_elements:\n  encoder.1: { position: knob.position }\n";
const FeId kEncoder{FeKind::Encoder, 1};

// §4.1 "1001 Error register Unsigned16 RO": a sensor that answers 1001h as its document says (two
// bytes) boots like one that answers CiA 301's one byte; the CiA 301 bits are the low byte.
TEST_F(Corners, NovotechnikErrorRegisterOfEitherSizeBoots) {
  for (const char* size : {"1", "2"}) {
    SCOPED_TRACE(std::string("error_register_size=") + size);
    log_.clear();
    build(kKnob, "knob", {{{"error_register_size", size}}});
    ASSERT_EQ(state(), sd::NodeState::Operational) << log_;
    const auto* diag = rig_->gw().downstream().diagnostics("knob");
    ASSERT_TRUE(diag && diag->error_register) << log_;
    EXPECT_EQ(*diag->error_register, 0x00);
    as<sim::Novotechnik406Sim>().set_position(4242, loop_.now());
    rig_->run_for(50ms);
    EXPECT_EQ(field(kEncoder, "position"), 4242);
  }
}

// §4.3 2104h "EMCY behaviour" (1 info, 2 also warnings, 3 also errors suppressed), stored by
// 1010h (§11): whatever the sensor stored, the gateway writes 0 at configuration, so the error
// EMCY and the "valid position" that ends it still come.
TEST_F(Corners, NovotechnikStoredEmcyBehaviourIsPinnedToAllEvents) {
  for (const char* stored : {"0", "1", "2", "3"}) {
    SCOPED_TRACE(std::string("emcy_behaviour=") + stored);
    up_emcys_.clear();
    build(kKnob, "knob", {{{"emcy_behaviour", stored}}});
    ASSERT_EQ(state(), sd::NodeState::Operational) << log_;
    EXPECT_EQ(device().od().get<std::uint8_t>(0x2104, 0), 0) << "2104h not written at configuration";
    auto& knob = as<sim::Novotechnik406Sim>();
    knob.set_position(1000, loop_.now());
    rig_->run_for(50ms);
    knob.inject_fault(sim::Novotechnik406Sim::Fault::HardwareFault, loop_.now());  // "Hard": always sent
    rig_->run_for(50ms);
    knob.clear_fault(loop_.now());  // 0000h
    rig_->run_for(50ms);
    knob.inject_fault(sim::Novotechnik406Sim::Fault::Measurement, loop_.now());  // "Error": suppressed by 3
    rig_->run_for(50ms);
    EXPECT_TRUE(driver().any_fault()) << "a stored 2104h silenced the measurement error\n" << log_;
    EXPECT_EQ(rig_->gw().status(kEncoder), gw::FeStatus::Error);
    EXPECT_GE(faults_named(0x7F), 1u);
    knob.clear_fault(loop_.now());  // 5051h/0/0 "valid position"
    rig_->run_for(50ms);
    EXPECT_FALSE(driver().any_fault()) << log_;
    EXPECT_EQ(rig_->gw().status(kEncoder), gw::FeStatus::Valid) << log_;
  }
}

// §4.1's default mapping names 6020h:01, which §4.2's object list lacks (it lists 6004h, and §8.2's
// mappable objects 6004h): a sensor without 6020h has TPDO1 mapped on 6004h, and the position
// still comes.
TEST_F(Corners, NovotechnikWithout6020hMapsThePositionFrom6004h) {
  for (const char* has : {"yes", "no"}) {
    SCOPED_TRACE(std::string("has_6020h=") + has);
    build(kKnob, "knob", {{{"has_6020h", has}}});
    ASSERT_EQ(state(), sd::NodeState::Operational) << log_;
    EXPECT_EQ(device().od().get<std::uint32_t>(0x1A00, 1), std::string(has) == "yes" ? 0x60200120u : 0x60040020u);
    as<sim::Novotechnik406Sim>().set_position(-777, loop_.now());
    rig_->run_for(50ms);
    EXPECT_EQ(field(kEncoder, "position"), std::int64_t{static_cast<std::uint32_t>(-777)})
        << log_;  // 6120h: UNSIGNED32
    EXPECT_EQ(rig_->gw().status(kEncoder), gw::FeStatus::Valid);
  }
}

// §9.1 9090h byte 7: "coded according to 0x6400", or "0: Valid, 1: WorkArea underflow, 2:
// WorkArea overflow". The driver maps 6400h:01 (and 6300h:01) into TPDO1: work_area is the 6400h
// bits whichever coding the sensor's EMCY uses.
TEST_F(Corners, NovotechnikWorkAreaIsThe6400hBitsInEitherEmcyCoding) {
  for (const char* coding : {"bits", "enum"}) {
    SCOPED_TRACE(std::string("work_area_emcy=") + coding);
    build(kKnob, "knob", {{{"work_area_emcy", coding}}});
    ASSERT_EQ(state(), sd::NodeState::Operational) << log_;
    auto& knob = as<sim::Novotechnik406Sim>();
    (void)device().od().set<std::int32_t>(0x6401, 1, 1000);  // work area 1000..2000
    (void)device().od().set<std::int32_t>(0x6402, 1, 2000);
    knob.set_position(500, loop_.now());
    rig_->run_for(50ms);
    EXPECT_EQ(signal("work_area").value, 0x04) << "below the low limit: bit 2 (§5.7.1)";
    EXPECT_EQ(signal("work_area").status, sd::SignalStatus::Valid);
    knob.set_position(2500, loop_.now());
    rig_->run_for(50ms);
    EXPECT_EQ(signal("work_area").value, 0x02) << "above the high limit: bit 1";
    knob.set_position(1500, loop_.now());
    rig_->run_for(50ms);
    EXPECT_EQ(signal("work_area").value, 0x00);
  }
}

// ---- MCB-402 (document 003) ---------------------------------------------------------------------

std::string mcb_yaml(const std::string& bits) {
  return "subdevices:\n  grip: { driver: mcb402, node_id: 0x03, heartbeat_ms: 100, options: { button_bits: [" + bits +
         "] } }\nfunctional_elements:\n  joystick.1:\n    x: { signal: grip.x, deadband: 300 }\n"
         "    buttons: grip.buttons[1..7]\n";
}
const FeId kJoy1{FeKind::Joystick, 1};

// [CO4013 "Emergency Messages"] lists the cable break and no error reset: a board that never sends
// 0000h after a mend is cleared by its 1001h (bit 7 "device error" clear), read while the fault
// lasts; a board that sends it is cleared by it.
TEST_F(Corners, Mcb402CableBreakClearsWithOrWithoutAnErrorReset) {
  for (const char* clear : {"0000h", "none"}) {
    SCOPED_TRACE(std::string("clear_after_break=") + clear);
    up_emcys_.clear();
    log_.clear();
    build(mcb_yaml("0, 1, 2, 3, 4, 6, 5"), "grip", {{{"clear_after_break", clear}}});
    ASSERT_EQ(state(), sd::NodeState::Operational) << log_;
    auto& mcb = as<sim::Mcb402Sim>();
    mcb.move_axis(1, 0, loop_.now());
    rig_->run_for(100ms);
    mcb.cable_break(1, true, loop_.now());
    rig_->run_for(100ms);
    ASSERT_TRUE(driver().any_fault());
    EXPECT_EQ(faults_named(0x03), 1u);
    const TimePoint mended = loop_.now();
    mcb.cable_break(1, false, loop_.now());
    rig_->run_for(400ms);  // a poll period (250 ms) and an SDO round trip, then a TPDO2
    const bool reset_sent = !sent(0x83, mended).empty();
    EXPECT_EQ(reset_sent, std::string(clear) == "0000h") << "the simulator's corner";
    EXPECT_FALSE(driver().any_fault()) << log_;
    EXPECT_EQ(rig_->gw().status(kJoy1), gw::FeStatus::Valid) << log_;
    EXPECT_GE(resets(), 1u) << "no EMCY 0000h upstream\n" << log_;
  }
}

// The power-on EMCY "083 00 81 11" carries 1001h = 11h (generic + communication); whether the
// board keeps those bits the document does not say. Neither is a fault: at boot, and read back
// after a reboot.
TEST_F(Corners, Mcb402PowerOnRegister11hKeptOrNotIsNoFault) {
  for (const char* reg : {"00h", "11h"}) {
    SCOPED_TRACE(std::string("power_on_1001h=") + reg);
    up_emcys_.clear();
    build(mcb_yaml("0, 1, 2, 3, 4, 6, 5"), "grip", {{{"power_on_1001h", reg}}});
    ASSERT_EQ(state(), sd::NodeState::Operational) << log_;
    EXPECT_EQ(as<sim::Mcb402Sim>().error_register(), std::string(reg) == "11h" ? 0x11 : 0x00);
    EXPECT_FALSE(driver().any_fault());
    (void)cmd("grip reboot");
    rig_->run_for(3s);
    ASSERT_EQ(state(), sd::NodeState::Operational) << log_;
    EXPECT_FALSE(driver().any_fault()) << log_;
    EXPECT_EQ(rig_->gw().status(kJoy1), gw::FeStatus::Valid) << log_;
  }
}

// CiA 301 Table 26 81xxh is "communication": every 81xxh a CO4013 sends (the document's 8100h,
// 8130h "30 81 11", 8140h "40 81 11", and CiA 301's 8110h overrun / 8120h error passive) is a
// warning, as in the elobau and CiA 401 drivers.
TEST_F(Corners, Mcb402Every81xxhIsAWarning) {
  build(mcb_yaml("0, 1, 2, 3, 4, 6, 5"), "grip", {});
  ASSERT_EQ(state(), sd::NodeState::Operational) << log_;
  auto& mcb = as<sim::Mcb402Sim>();
  mcb.life_guarding(loop_.now());
  mcb.bus_off_recovered(loop_.now());
  for (const std::uint8_t code : {0x10, 0x20})
    (void)rig_->devices_port().send(CanFrame(0x83, {code, 0x81, 0x11, 0, 0, 0, 0, 0}));
  rig_->run_for(100ms);
  EXPECT_FALSE(driver().any_fault()) << log_;
  EXPECT_EQ(faults_named(0x03), 0u) << log_;
  EXPECT_EQ(rig_->gw().status(kJoy1), gw::FeStatus::Valid);
}

// The table's two readings (left end: bit 7 = BP6, bit 6 = BP7; right end: bit 6 = BP6, bit 5 =
// BP7): with button_bits as the board is wired, each button is the right one.
TEST_F(Corners, Mcb402EitherWiringWithItsButtonBitsReportsTheRightButton) {
  for (const auto& [wiring, bits] : {std::pair<std::string, std::string>{"1/2/3/4/5/7/6", "1, 2, 3, 4, 5, 7, 6"},
                                     std::pair<std::string, std::string>{"0/1/2/3/4/6/5", "0, 1, 2, 3, 4, 6, 5"}}) {
    SCOPED_TRACE("wiring=" + wiring);
    build(mcb_yaml(bits), "grip", {{{"wiring", wiring}}});
    ASSERT_EQ(state(), sd::NodeState::Operational) << log_;
    auto& mcb = as<sim::Mcb402Sim>();
    for (std::size_t bp = 1; bp <= 7; ++bp) {
      mcb.press(bp, loop_.now());
      rig_->run_for(20ms);
      for (std::size_t k = 1; k <= 7; ++k)
        EXPECT_EQ(field(kJoy1, fmt::format("buttons[{}]", k)), k == bp ? 1 : 0) << "BP" << bp << " pressed";
      mcb.release(bp, loop_.now());
      rig_->run_for(20ms);
    }
  }
}

// ---- elobau (document 000) ----------------------------------------------------------------------

std::string grip_yaml(const std::string& options, const std::string& buttons = "1..6") {
  return "subdevices:\n  grip: { driver: elobau-mfg, node_id: 0x11, heartbeat_ms: 100" +
         (options.empty() ? std::string() : ", options: { " + options + " }") +
         " }\nfunctional_elements:\n  joystick.1:\n    x: { signal: grip.x, deadband: 2 }\n    buttons: grip.buttons[" +
         buttons + "]\n";
}

// Table 14 18xxh:02 = 254 "transmission event is manufacturer specific, i.e. event timer": a grip
// that sends only on its timer works; a change arrives within one cycle, and with cycle_ms 20
// (the recommendation for such a grip,
// docs/design/device-documents.md#elobau-mfg-elobau-mfg-document-000-12) within 20 ms.
TEST_F(Corners, ElobauGripSendingOnItsTimerOnlyWorks) {
  for (const auto& [cycle, bound] :
       {std::pair<std::string, Duration>{"100", 100ms}, std::pair<std::string, Duration>{"20", 20ms}}) {
    SCOPED_TRACE("cycle_ms " + cycle);
    log_.clear();
    build(grip_yaml("cycle_ms: " + cycle), "grip", {{{"tpdo", "timer"}}});
    ASSERT_EQ(state(), sd::NodeState::Operational) << log_;
    auto& grip = as<sim::ElobauMfgSim>();
    rig_->run_for(500ms);
    const TimePoint moved = loop_.now();
    (void)grip.move_axis("x", 0);
    (void)grip.press(1);
    rig_->rearm();
    rig_->run_for(bound + 2ms);
    EXPECT_EQ(field(kJoy1, "buttons[1]"), 1) << "not seen within one cycle";
    (void)grip.move_axis("x", 40);
    rig_->rearm();
    rig_->run_for(2 * bound + 2ms);
    // The corner itself: TPDO #0 only every cycle, none on the changes.
    TimePoint last{};
    for (const auto& r : down_) {
      if (r.frame.id != 0x191 || r.time < moved - bound) continue;
      if (last != TimePoint{}) {
        EXPECT_GE(r.time - last, bound - 1ms) << "a timer-only grip sent on change";
      }
      last = r.time;
    }
    EXPECT_GT(field(kJoy1, "x"), 0);
    EXPECT_EQ(rig_->gw().status(kJoy1), gw::FeStatus::Valid) << log_;
    EXPECT_EQ(faults_named(0x11), 0u) << log_;
  }
}

// Table 6 0002h "also set until first parameter saving process": a never-saved grip is refused at
// boot, the reason saying how to commission it (the default, parameter_checksum: refuse) ...
TEST_F(Corners, ElobauNeverSavedGripIsRefusedWithTheCommissioningStep) {
  build(grip_yaml(""), "grip", {{{"saved", "no"}}});
  EXPECT_EQ(state(), sd::NodeState::Refused) << log_;
  EXPECT_NE(log_.find("4001h reads 0002h"), std::string::npos) << log_;
  EXPECT_NE(log_.find("write 1010h:01 = 65766173h"), std::string::npos) << log_;
  EXPECT_NE(log_.find("parameter_checksum: save"), std::string::npos) << log_;
  EXPECT_EQ(rig_->gw().status(kJoy1), gw::FeStatus::Offline);
}

// ... or, with parameter_checksum: save, saved by the gateway ("save" on 1010h:01, §8) and
// restarted (NMT reset node, "Restart the joystick after saving procedure"), then run.
TEST_F(Corners, ElobauNeverSavedGripIsSavedAndRestartedWhenAllowed) {
  build(grip_yaml("parameter_checksum: save"), "grip", {{{"saved", "no"}, {"store", store("grip")}}});
  ASSERT_EQ(state(), sd::NodeState::Operational) << log_;
  bool saved = false, reset_node = false;
  for (const auto& r : down_) {
    const auto& d = r.frame.data;
    if (r.frame.id == 0x611 && d[0] == 0x23 && d[1] == 0x10 && d[2] == 0x10 && d[3] == 0x01 && d[4] == 0x73 &&
        d[5] == 0x61 && d[6] == 0x76 && d[7] == 0x65)
      saved = true;
    if (saved && r.frame.id == 0x000 && d[0] == 0x81 && d[1] == 0x11) reset_node = true;
  }
  EXPECT_TRUE(saved) << "no 611#2310100173617665 (\"save\")";
  EXPECT_TRUE(reset_node) << "no NMT reset node after the save";
  EXPECT_EQ(device().od().get<std::uint16_t>(0x4001, 0), 0) << "0002h still set after the restart";
  EXPECT_FALSE(driver().any_fault()) << log_;
  (void)as<sim::ElobauMfgSim>().move_axis("x", 0);
  rig_->rearm();
  rig_->run_for(300ms);
  EXPECT_EQ(rig_->gw().status(kJoy1), gw::FeStatus::Valid) << log_;
}

// 2100h:01h default 63: a grip has buttons 1..6; a mapped button it lacks is not available, never
// "valid, released" (its TPDO bit is only 2100h:0Ah). A grip configured with them reports them.
TEST_F(Corners, ElobauButtonsTheGripLacksAreNotAvailable) {
  build(grip_yaml("", "1..8"), "grip", {});
  ASSERT_EQ(state(), sd::NodeState::Operational) << log_;
  (void)as<sim::ElobauMfgSim>().move_axis("x", 0);
  rig_->rearm();
  rig_->run_for(300ms);
  EXPECT_EQ(signal("buttons[6]").status, sd::SignalStatus::Valid);
  EXPECT_EQ(signal("buttons[7]").status, sd::SignalStatus::NotAvailable);
  EXPECT_EQ(signal("buttons[16]").status, sd::SignalStatus::NotAvailable);
  EXPECT_NE(rig_->gw().status(kJoy1), gw::FeStatus::Valid) << "a mapped button the grip lacks went unnoticed";
  EXPECT_NE(log_.find("fault (buttons[7] not available)"), std::string::npos) << log_;
  // All eight fitted (the grip's own 2100h:01h, or the mapping file's sdo list writing it).
  build(grip_yaml("", "1..8"), "grip", {{{"buttons", "255"}}});
  (void)as<sim::ElobauMfgSim>().press(8);
  rig_->rearm();
  rig_->run_for(300ms);
  EXPECT_EQ(signal("buttons[8]").status, sd::SignalStatus::Valid);
  EXPECT_EQ(field(kJoy1, "buttons[8]"), 1);
  build(
      "subdevices:\n  grip:\n    driver: elobau-mfg\n    node_id: 0x11\n    heartbeat_ms: 100\n    sdo:\n"
      "      - { index: 0x2100, sub_index: 1, value: 0xFF, type: u8 }\n"
      "functional_elements:\n  joystick.1:\n    buttons: grip.buttons[1..8]\n",
      "grip", {});
  (void)as<sim::ElobauMfgSim>().press(8);
  rig_->rearm();
  rig_->run_for(300ms);
  EXPECT_EQ(signal("buttons[8]").status, sd::SignalStatus::Valid) << log_;
  EXPECT_EQ(rig_->gw().status(kJoy1), gw::FeStatus::Valid) << log_;
}

// ---- Freshness floors ---------------------------------------------------------------------------

// Each family's derived deadline (3 x the event timer) is raised to its floor, 200 ms: a stall of
// the controller of 130 ms (as a loaded VM showed, the PDOs then arriving that late) is no stale
// fault, a device whose PDOs stop still is one within the floor.
TEST_F(Corners, FreshnessFloorRidesOutAStallButCatchesALostDevice) {
  struct Case {
    std::string yaml, dev;
    std::uint32_t cob;
    FeId fe;
  };
  for (const Case& c :
       {Case{kKnob, "knob", 0x1FF, kEncoder}, Case{mcb_yaml("0, 1, 2, 3, 4, 6, 5"), "grip", 0x283, kJoy1}}) {
    SCOPED_TRACE(c.dev);
    up_emcys_.clear();
    build(c.yaml, c.dev, {});
    ASSERT_EQ(state(), sd::NodeState::Operational) << log_;
    EXPECT_EQ(driver().freshness(0), 200ms);
    rig_->run_for(500ms);
    ASSERT_EQ(rig_->gw().status(c.fe), gw::FeStatus::Valid) << log_;
    // Stalled: the PDOs are held back 130 ms (one period plus 130 ms between two PDOs).
    TimePoint until = loop_.now() + 130ms;
    rig_->from_devices = [&](const CanFrame& f) { return f.id == c.cob && loop_.now() < until; };
    rig_->run_for(400ms);
    EXPECT_EQ(faults_named(c.dev == "knob" ? 0x7F : 0x03), 0u) << "a 130 ms gap was a stale fault\n" << log_;
    // Lost: no PDO for good; stale within 200 ms (plus the period the last one was into).
    until = loop_.now() + 10s;
    rig_->run_for(250ms);
    EXPECT_EQ(rig_->gw().status(c.fe), gw::FeStatus::Stale) << log_;
    EXPECT_EQ(faults_named(c.dev == "knob" ? 0x7F : 0x03), 1u) << log_;
    rig_->from_devices = {};
  }
}

}  // namespace
