// Tier 2, end to end: the whole gateway between two virtual buses on a simulated clock.
// Downstream, the simulated cab devices (SimBench, as `oegw-sim` runs them); in the middle the
// Gateway built from a mapping file (the demo's, plus the elobau LEDs); upstream a host
// canopen::Master that configures the CiA 852 PDOs by SDO (disabled by default, clause 12),
// sets 6423h TRUE and NMT-starts node 20h, then checks the exact TPDO bytes the mapping
// promises (oe_device.hpp: PDO numbers and byte layouts) and every fault of the fault policy
// (gateway.hpp) as FE values, FE status and upstream EMCY. Nothing sleeps: time only moves
// when a test advances the loop.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "canopen/master.hpp"
#include "gateway/gateway.hpp"
#include "profiles/cia852/device_type.hpp"
#include "rig/cab_rig.hpp"
#include "subdevices/sim/elobau_mfg_sim.hpp"
#include "subdevices/sim/mcb402_sim.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "tests/fixtures/fixtures.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
using oegw::gateway::FeStatus;
using oegw::gateway::Gateway;
using oegw::mapping::FeId;
using oegw::mapping::FeKind;
namespace sd = oegw::subdevices;
namespace gw = oegw::gateway;
using Bytes = std::vector<std::uint8_t>;

namespace {

constexpr NodeId kGw{0x20};
constexpr std::uint8_t kHostNode = 0x01;
const FeId kJoy1{FeKind::Joystick, 1};
const FeId kJoy2{FeKind::Joystick, 2};
const FeId kPedal1{FeKind::FootPedal, 1};
const FeId kEnc1{FeKind::Encoder, 1};
const FeId kWheel1{FeKind::Wheel, 1};
const FeId kButtons1{FeKind::ButtonCluster, 1};

// COB-IDs the host assigns (clause 12: every PDO but TPDO 1 has none by default).
constexpr std::uint32_t kTpdo1 = 0x1A0;   // joystick 1 (the default 180h + node-ID)
constexpr std::uint32_t kTpdo5 = 0x2A0;   // joystick 2
constexpr std::uint32_t kTpdo20 = 0x2B0;  // pedals 1, 2
constexpr std::uint32_t kTpdo28 = 0x2C0;  // encoders 1, 2
constexpr std::uint32_t kTpdo32 = 0x2D0;  // wheels 1..4
constexpr std::uint32_t kTpdo34 = 0x2E0;  // push-button cluster 1
constexpr std::uint32_t kRpdo1 = 0x220;   // indicators 1 (the cluster's lamps)
constexpr std::uint32_t kRpdo5 = 0x225;   // indicators 2 (MCB-402 OUT0..3)
constexpr std::uint32_t kRpdo6 = 0x226;   // indicators 3 (elobau LEDs)

// tests/fixtures/demo_cab.yaml: config/demo.yaml's devices and FEs, plus the elobau LEDs as
// indicators.3. `right_grip_extra` goes into right_grip's flow map, after "mandatory: true" (e.g.
// ", identity: { vendor_id: 0x99 }").
std::string mapping_yaml(const std::string& right_grip_extra = "") {
  std::string yaml = oegw::fixtures::mapping_file("demo_cab.yaml");
  const std::string end = "mandatory: true";
  yaml.insert(yaml.find(end) + end.size(), right_grip_extra);
  return yaml;
}

std::int16_t i16(const CanFrame& f, std::size_t at) { return static_cast<std::int16_t>(get_u16(&f.data[at])); }

class GatewayE2E : public ::testing::Test {
 protected:
  // Builds everything; `right_grip_extra` changes the mapping file (identity tests).
  void build(const std::string& right_grip_extra = "", const std::function<std::string(std::string)>& edit = {}) {
    std::string yaml = mapping_yaml(right_grip_extra);
    if (edit) yaml = edit(yaml);
    yaml_ = yaml;
    auto loaded = oegw::mapping::load_config_text(yaml, "e2e.yaml", gw::driver_catalogue());
    ASSERT_TRUE(loaded.ok()) << loaded.error_text();
    config_ = std::move(*loaded.config);
    store_ = std::filesystem::path(::testing::TempDir()) /
             fmt::format("gateway_e2e_{}_{}.store", ::getpid(), ::testing::UnitTest::GetInstance()->random_seed());
    std::filesystem::remove(store_);
    rig_ = std::make_unique<oegw::rig::CabRig>(config_, loop_,
                                               oegw::rig::CabRigOptions{.store = store_,
                                                                        .simulator_options = sim_options_});
    rig_->up().set_tap([this](const BusRecord& r) { upstream_.push_back(r); });
    rig_->down().set_tap([this](const BusRecord& r) {
      downstream_.push_back(r);
      // A sub-device's EMCY: the gateway forwards it upstream (remote EMCY, oe_device.hpp).
      if (r.frame.id > 0x80 && r.frame.id < 0x100 && r.frame.dlc == 8) {
        EmcyMessage m;
        m.node = NodeId{static_cast<std::uint8_t>(r.frame.id - 0x80)};
        m.code = get_u16(r.frame.data.data());
        m.error_register = r.frame.data[2];
        std::copy_n(r.frame.data.begin() + 3, 5, m.msef.begin());
        to_forward_.push_back(m);
      }
    });
    // The devices' frames pass drop_from_devices_ (a test cuts some of them: PDOs that stop).
    rig_->from_devices = [this](const CanFrame& f) { return drop_from_devices_ && drop_from_devices_(f); };
    rig_->on_gateway = [this](Gateway& g) {
      gw_ = &g;
      g.on_log = [this](const std::string& l) { log_ += fmt::format("[{:>6}] {}\n", ms(), l); };
    };
    rig_->build_devices();
    bench_ = &rig_->devices();
    host_ = &rig_->host();
    host_port_ = &rig_->host_port();
    host_->on_emcy = [this](const EmcyMessage& m, TimePoint) {
      // emcys_: the gateway's own EMCYs (what these tests assert); a sub-device's EMCY passed
      // on (code, then node-ID, its register and its bytes 0..2) goes to forwarded_.
      const auto fwd = std::find_if(to_forward_.begin(), to_forward_.end(), [&](const EmcyMessage& d) {
        return d.code == m.code && gw::OeDevice::forwarded_msef(d) == m.msef;
      });
      if (fwd != to_forward_.end()) {
        forwarded_.push_back(m);
        to_forward_.erase(fwd);
        return;
      }
      emcys_.push_back(m);
      // What the host could read at the very moment the EMCY arrives.
      joy1_at_emcy_.push_back(gw_->fields(kJoy1));
    };
    host_->on_other_frame = [this](const CanFrame& f, TimePoint) { pdos_.push_back(f); };
    connect_gateway();
  }
  // A gateway process on the mapping file and store_, attached to both buses (a restart calls
  // this again: the old gateway is detached and destroyed first).
  void connect_gateway() { rig_->connect_gateway(); }
  // A reload (gateway/reload.hpp) of the built file as `edit` changes it: the settings refused
  // (nothing changed then), or none, the gateway replaced (gw_ follows it through on_gateway).
  std::vector<std::string> reload(const std::function<std::string(std::string)>& edit) {
    auto loaded = oegw::mapping::load_config_text(edit(yaml_), "e2e.yaml", gw::driver_catalogue());
    if (!loaded.ok()) return {"not loaded: " + loaded.error_text()};
    std::vector<std::string> refused;
    for (const auto& d : rig_->reload(*loaded.config)) refused.push_back(d.str());
    return refused;
  }
  void TearDown() override {
    rig_.reset();
    if (!store_.empty()) std::filesystem::remove(store_);
  }

  long ms() const {
    return static_cast<long>(std::chrono::duration_cast<std::chrono::milliseconds>(loop_.now() - t0_).count());
  }
  void run_for(Duration d) { rig_->run_for(d); }
  std::string cmd(const std::string& line) {
    const std::string r = bench_->command(line, loop_.now());
    EXPECT_EQ(r.rfind("ok", 0), 0u) << line << ": " << r;
    return r;
  }

  // Power on: the gateway boots (boot-up 720#00) and its sub-devices.
  void power_on() {
    t0_ = loop_.now();
    rig_->power_on();
    run_for(3s);
  }
  bool all_operational() {
    for (const auto& n : gw_->downstream().names())
      if (gw_->downstream().state(n) != sd::NodeState::Operational) return false;
    return true;
  }

  SdoAbortCode sdo_write(std::uint16_t index, std::uint8_t sub, Bytes data) {
    SdoAbortCode code = SdoAbortCode::GeneralError;
    bool done = false;
    host_->sdo(kGw).download(index, sub, std::move(data), [&](SdoAbortCode c, Bytes) {
      code = c;
      done = true;
    });
    for (int i = 0; i < 100 && !done; ++i) run_for(10ms);
    EXPECT_TRUE(done) << fmt::format("SDO download {:04X}h:{:02X} never finished", index, sub);
    return code;
  }
  std::optional<Bytes> sdo_read(std::uint16_t index, std::uint8_t sub) {
    std::optional<Bytes> out;
    bool done = false;
    host_->sdo(kGw).upload(index, sub, [&](SdoAbortCode c, Bytes d) {
      if (c == SdoAbortCode::None) out = std::move(d);
      done = true;
    });
    for (int i = 0; i < 100 && !done; ++i) run_for(10ms);
    return out;
  }
  void enable_pdo(std::uint16_t comm_index, std::uint32_t cob) {
    ASSERT_EQ(sdo_write(comm_index, 1, encode<std::uint32_t>(cob)), SdoAbortCode::None)
        << fmt::format("{:04X}h:01 = {:X}h", comm_index, cob);
  }
  // The host's whole set-up (demo order): PDOs, 6423h, NMT start.
  void host_configures_and_starts(bool analog_interrupts = true) {
    enable_pdo(0x1800, kTpdo1);   // TPDO 1
    enable_pdo(0x1804, kTpdo5);   // TPDO 5
    enable_pdo(0x1813, kTpdo20);  // TPDO 20
    enable_pdo(0x181B, kTpdo28);  // TPDO 28
    enable_pdo(0x181F, kTpdo32);  // TPDO 32
    enable_pdo(0x1821, kTpdo34);  // TPDO 34
    enable_pdo(0x1400, kRpdo1);   // RPDO 1
    enable_pdo(0x1404, kRpdo5);   // RPDO 5
    enable_pdo(0x1405, kRpdo6);   // RPDO 6
    if (analog_interrupts) {
      ASSERT_EQ(sdo_write(0x6423, 0, {1}), SdoAbortCode::None);
    }
    host_->nmt().start(kGw);
    run_for(200ms);
    ASSERT_EQ(gw_->upstream().node().state(), NmtState::Operational);
  }
  // The host produces its heartbeat (701h, 100 ms) while `alive`, and the gateway consumes it
  // (1016h:01, 250 ms).
  void host_heartbeat_watched(const bool& alive) {
    loop_.call_every(loop_.now(), 100ms, [this, &alive] {
      if (alive) (void)host_port_->send(CanFrame(0x700 + kHostNode, {0x05}));
    });
    ASSERT_EQ(sdo_write(0x1016, 1, encode<std::uint32_t>(std::uint32_t{kHostNode} << 16 | 250)), SdoAbortCode::None);
  }
  // CiA 401 error mode (6206h) and error value (6207h) of one 6200h sub-index, by the host.
  void error_values(std::uint8_t sub, std::uint8_t mode, std::uint8_t value) {
    ASSERT_EQ(sdo_write(0x6206, sub, {mode}), SdoAbortCode::None);
    ASSERT_EQ(sdo_write(0x6207, sub, {value}), SdoAbortCode::None);
  }
  void boot_and_start() {
    power_on();
    ASSERT_TRUE(all_operational()) << log_;
    host_configures_and_starts();
    pdos_.clear();
    emcys_.clear();
    joy1_at_emcy_.clear();
  }

  std::vector<CanFrame> pdos(std::uint32_t id) const {
    std::vector<CanFrame> r;
    for (const auto& f : pdos_)
      if (f.id == id) r.push_back(f);
    return r;
  }
  std::optional<CanFrame> last(std::uint32_t id) const {
    auto v = pdos(id);
    if (v.empty()) return std::nullopt;
    return v.back();
  }
  std::vector<EmcyMessage> emcys(std::uint16_t code) const {
    std::vector<EmcyMessage> r;
    for (const auto& e : emcys_)
      if (e.code == code) r.push_back(e);
    return r;
  }
  std::int64_t field(FeId fe, const std::string& name) const {
    for (const auto& f : gw_->fields(fe))
      if (f.name == name) return f.value;
    ADD_FAILURE() << "no field " << name;
    return -1;
  }
  bool neutral(const std::vector<Gateway::FieldState>& fields) const {
    return std::all_of(fields.begin(), fields.end(), [](const auto& f) { return f.value == 0; });
  }
  sd::sim::ElobauMfgSim& grip() { return dynamic_cast<sd::sim::ElobauMfgSim&>(*bench_->device("right_grip")); }
  // The MCB-402's OUT0..3 as "1010".
  std::string mcb_leds() const {
    std::string out;
    for (int i = 1; i <= 4; ++i)
      out += std::to_string(*bench_->device("left_grip")->output("leds[" + std::to_string(i) + "]"));
    return out;
  }
  sd::sim::Mcb402Sim& mcb() { return dynamic_cast<sd::sim::Mcb402Sim&>(*bench_->device("left_grip")); }
  std::string dump() const {
    std::string s = log_ + "upstream frames:\n";
    for (const auto& r : upstream_) s += "  " + r.to_string() + "\n";
    return s;
  }

  oegw::mapping::Config config_;
  std::string yaml_;  // the built file's text
  SimulatedClock clock_;
  EventLoop loop_{clock_};
  TimePoint t0_{};
  // Options of the simulated devices by name, set before build(): the MCB-402 wired as
  // demo_cab.yaml's button_bits say (the document's table as printed; a simulator is otherwise
  // wired by the table's other reading,
  // docs/design/device-documents.md#corners-every-reading-a-document-permits).
  std::map<std::string, sd::DriverOptions> sim_options_{
      {"left_grip", sd::DriverOptions{{{"wiring", "1/2/3/4/5/7/6"}}}}};
  std::filesystem::path store_;
  std::unique_ptr<oegw::rig::CabRig> rig_;  // the demo's harness (rig/cab_rig.hpp)
  // Into rig_: the simulators, the host, its port, the current gateway (connect_gateway).
  sd::sim::SimBench* bench_ = nullptr;
  Master* host_ = nullptr;
  VirtualPort* host_port_ = nullptr;
  Gateway* gw_ = nullptr;
  std::vector<BusRecord> upstream_;
  std::vector<BusRecord> downstream_;
  std::function<bool(const CanFrame&)> drop_from_devices_;
  std::vector<CanFrame> pdos_;
  std::vector<EmcyMessage> emcys_;
  std::vector<EmcyMessage> to_forward_;  // sub-device EMCYs seen downstream, not yet upstream
  std::vector<EmcyMessage> forwarded_;   // those the host received from the gateway
  std::vector<std::vector<Gateway::FieldState>> joy1_at_emcy_;
  std::string log_;
};

// ---- Configuration, start, and the TPDO bytes of every FE kind ---------------------------------

TEST_F(GatewayE2E, HostConfiguresAndStartsTheGateway) {
  build();
  power_on();
  EXPECT_TRUE(all_operational()) << log_;
  // Boot-up first, in pre-operational; the upstream heartbeat follows (1017h = 100 ms).
  ASSERT_FALSE(upstream_.empty());
  EXPECT_EQ(upstream_.front().frame.id, 0x720u);
  EXPECT_EQ(upstream_.front().frame.dlc, 1);
  EXPECT_EQ(upstream_.front().frame.data[0], 0x00);
  // 1000h per Table 8 for this FE set: the value `oegw check config/demo.yaml` prints (the extra
  // indicators.3 adds no bit) and the one device_type_for computes.
  const auto dt = sdo_read(0x1000, 0);
  ASSERT_TRUE(dt.has_value());
  EXPECT_EQ(decode_unsigned(*dt), 0xBF870191u);
  EXPECT_EQ(decode_unsigned(*dt), oegw::cia852::device_type_for(gw_->fes()));
  EXPECT_EQ(decode_unsigned(*dt) & 0xFFFF, 0x0191u);
  // 1018h as the mapping file says.
  EXPECT_EQ(decode_unsigned(*sdo_read(0x1018, 2)), 0x852u);
  EXPECT_EQ(decode_unsigned(*sdo_read(0x1018, 3)), 0x10000u);
  // PDOs disabled by default: nothing on 1A0h before the host enables it.
  EXPECT_EQ(decode_unsigned(*sdo_read(0x1800, 1)), 0x800001A0u);
  EXPECT_EQ(decode_unsigned(*sdo_read(0x1804, 1)) >> 31, 1u);
  host_configures_and_starts();
  run_for(150ms);
  EXPECT_TRUE(std::any_of(upstream_.begin(), upstream_.end(),
                          [](const BusRecord& r) { return r.frame.id == 0x720 && r.frame.data[0] == 0x05; }));
  // 6423h TRUE before the start: no EMCY 0080h.
  EXPECT_TRUE(emcys(0x0080).empty());
}

TEST_F(GatewayE2E, Joystick1Tpdo1CarriesXYZMemoryAndButtons) {
  build();
  boot_and_start();
  cmd("right_grip x 50");   // 50 % of 32767 = 16383.5 -> 16384 (halves away from zero)
  cmd("right_grip y -25");  // -8191.75 -> -8192
  cmd("right_grip buttons[3] 1");
  run_for(300ms);
  const auto f = last(kTpdo1);
  ASSERT_TRUE(f) << dump();
  // oe_device.hpp: 6401h x, y, z (INTEGER16 LE), 6000h memory byte, 6000h buttons byte.
  EXPECT_EQ(f->dlc, 8);
  EXPECT_EQ(i16(*f, 0), 16384);
  EXPECT_EQ(i16(*f, 2), -8192);
  EXPECT_EQ(i16(*f, 4), 0) << "z is not fed: 0";
  EXPECT_EQ(f->data[6], 0x00) << "memory bits";
  EXPECT_EQ(f->data[7], 0x04) << "buttons[3] = bit 2";
  EXPECT_EQ(f->to_string(), "1A0#004000E000000004");
  // The detent (110 %) is clamped to full scale, never -32768.
  cmd("right_grip x -110");
  run_for(300ms);
  EXPECT_EQ(i16(*last(kTpdo1), 0), -32767);
  // Inside the deadband (2 %): neutral.
  cmd("right_grip x 2");
  run_for(300ms);
  EXPECT_EQ(i16(*last(kTpdo1), 0), 0);
  cmd("right_grip x 3");
  run_for(300ms);
  EXPECT_EQ(i16(*last(kTpdo1), 0), 983);  // 3 * 327.67 = 983.01
  // Event-driven on change (type FFh): a frame per change, none while nothing changes.
  const auto n = pdos(kTpdo1).size();
  run_for(1s);
  EXPECT_EQ(pdos(kTpdo1).size(), n) << "nothing changed: no TPDO (event timer 0)";
  EXPECT_TRUE(emcys_.empty());
}

TEST_F(GatewayE2E, Joystick2FromMcb402WithInvertedY) {
  build();
  boot_and_start();
  cmd("left_grip x 10000");
  cmd("left_grip y -12000");  // invert: true -> +12000
  cmd("left_grip z 200");     // inside the deadband of 300 -> 0
  cmd("left_grip buttons[2] 1");
  run_for(300ms);
  const auto f = last(kTpdo5);
  ASSERT_TRUE(f) << dump();
  EXPECT_EQ(f->dlc, 8);
  EXPECT_EQ(i16(*f, 0), 10000);
  EXPECT_EQ(i16(*f, 2), 12000);
  EXPECT_EQ(i16(*f, 4), 0);
  EXPECT_EQ(f->data[6], 0x00);
  EXPECT_EQ(f->data[7], 0x02);
  cmd("left_grip z -32768");  // clamp [-32767, 32767]
  cmd("left_grip y 32767");   // inverted: -32767
  run_for(300ms);
  EXPECT_EQ(i16(*last(kTpdo5), 4), -32767);
  EXPECT_EQ(i16(*last(kTpdo5), 2), -32767);
  EXPECT_EQ(field(kJoy2, "y"), -32767);
}

// The MCB-402 button bit order is the mapping file's (demo_cab.yaml: the document's table as
// printed, BP6 = bit 7, BP7 = bit 6), and the simulated board's wiring its own: wired the same,
// BP6 arrives as buttons[6]; wired by the simulator's default (the table's other reading), it
// would not.
TEST_F(GatewayE2E, Mcb402ButtonsAsTheMappingFilesBitOrderWhenTheBoardIsWiredSo) {
  build();
  boot_and_start();
  cmd("left_grip buttons[6] 1");
  run_for(300ms);
  EXPECT_EQ(field(kJoy2, "buttons[6]"), 1) << dump();
  EXPECT_EQ(field(kJoy2, "buttons[7]"), 0);
  const auto f = last(kTpdo5);
  ASSERT_TRUE(f) << dump();
  EXPECT_EQ(f->data[7], 0x20) << "buttons[6] = bit 5 of the joystick's button byte";
}

// A board wired otherwise (BP6 on bit 6, BP7 on bit 7) than the mapping file's choice: the
// gateway reports the wrong button. Nothing on the bus can tell, which is why the bit order is a
// commissioning step
// (docs/design/device-documents.md#mcb-402-button-bits-a-required-commissioning-choice) and not a
// default.
TEST_F(GatewayE2E, Mcb402ButtonBitOrderOtherThanTheBoardsReportsTheWrongButton) {
  sim_options_["left_grip"] = sd::DriverOptions{{{"wiring", "1/2/3/4/5/6/7"}}};
  build();
  boot_and_start();
  cmd("left_grip buttons[6] 1");
  run_for(300ms);
  EXPECT_EQ(field(kJoy2, "buttons[6]"), 0) << dump();
  EXPECT_EQ(field(kJoy2, "buttons[7]"), 1) << "BP6 pressed, buttons[7] reported";
  cmd("left_grip buttons[6] 0");
  cmd("left_grip buttons[1] 1");  // the bits both orders agree on
  run_for(300ms);
  EXPECT_EQ(field(kJoy2, "buttons[1]"), 1);
  EXPECT_EQ(field(kJoy2, "buttons[7]"), 0);
}

// Without button_bits the mapping file is refused where the sub-device names its driver, with
// the setting and the commissioning step (what `oegw check` prints).
TEST(GatewayE2EConfig, Mcb402WithoutButtonBitsIsRefusedWithFileLineColumn) {
  std::string yaml = mapping_yaml();
  const std::string bits = ", options: { button_bits: [1, 2, 3, 4, 5, 7, 6] }";
  ASSERT_NE(yaml.find(bits), std::string::npos);
  yaml.erase(yaml.find(bits), bits.size());
  const auto loaded = oegw::mapping::load_config_text(yaml, "e2e.yaml", gw::driver_catalogue());
  ASSERT_FALSE(loaded.ok());
  const std::string text = loaded.error_text();
  EXPECT_NE(text.find("e2e.yaml:10:25: driver mcb402 refused sub-device 'left_grip': mcb402: option button_bits is "
                      "required"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("press BP1..BP7 one at a time"), std::string::npos) << text;
}

TEST_F(GatewayE2E, PedalEncoderWheelAndButtonClusterTpdos) {
  build();
  boot_and_start();
  cmd("pedal analog[1] 20000");
  cmd("seat_knob position 123456");
  cmd("right_grip wheel_a 20");  // 20 % -> 6553.4 -> 6553
  cmd("cluster in[1] 5");        // switch[1], switch[3]
  run_for(500ms);
  // TPDO 20 (Table 16): pedal 1 memory (6000h:21h), position (6401h:31h), then pedal 2's
  // (not configured: 0).
  const auto p = last(kTpdo20);
  ASSERT_TRUE(p) << dump();
  EXPECT_EQ(p->dlc, 6);
  EXPECT_EQ(p->data[3], 0x00);
  EXPECT_EQ(i16(*p, 4), 0);
  EXPECT_EQ(p->data[0], 0x00);
  EXPECT_EQ(i16(*p, 1), 20000);
  // TPDO 28 (Table 20): encoder 1 (6120h:81h) UNSIGNED32, then encoder 2 (not configured: 0).
  const auto e = last(kTpdo28);
  ASSERT_TRUE(e) << dump();
  EXPECT_EQ(e->dlc, 8);
  EXPECT_EQ(get_u32(&e->data[4]), 0u);
  EXPECT_EQ(static_cast<std::int32_t>(get_u32(&e->data[0])), 123456);
  // TPDO 32 (Table 24): wheel 1 (6401h:41h), then wheels 2..4 (not configured: 0).
  const auto w = last(kTpdo32);
  ASSERT_TRUE(w) << dump();
  EXPECT_EQ(w->dlc, 8);
  EXPECT_EQ(i16(*w, 2), 0);
  EXPECT_EQ(i16(*w, 6), 0);
  EXPECT_EQ(i16(*w, 0), 6553);
  // TPDO 34: push-button cluster 1, its 6000h bytes; switch k = bit k-1 of the first.
  const auto b = last(kTpdo34);
  ASSERT_TRUE(b) << dump();
  EXPECT_GE(b->dlc, 1);
  EXPECT_EQ(b->data[0], 0x05);
  // A negative encoder value keeps its 32-bit pattern (6120h is UNSIGNED32), the pedal's deadband
  // (100) gives neutral.
  cmd("seat_knob position -5");
  cmd("pedal analog[1] 99");
  run_for(500ms);
  EXPECT_EQ(static_cast<std::int32_t>(get_u32(&last(kTpdo28)->data[0])), -5);
  EXPECT_EQ(i16(*last(kTpdo20), 1), 0);
  EXPECT_EQ(field(kPedal1, "position"), 0);
  EXPECT_EQ(field(kEnc1, "position"), 0xFFFFFFFBLL);  // -5 as UNSIGNED32
  EXPECT_EQ(field(kWheel1, "position"), 6553);
  EXPECT_EQ(field(kButtons1, "switch[3]"), 1);
}

// ---- Faults -----------------------------------------------------------------------------------

TEST_F(GatewayE2E, HeartbeatLossFaultValueAtOnceEmcy7000hThenRecovery) {
  build();
  boot_and_start();
  cmd("right_grip x 40");
  cmd("right_grip buttons[1] 1");
  run_for(300ms);
  ASSERT_NE(field(kJoy1, "x"), 0);
  cmd("right_grip heartbeat off");
  run_for(400ms);  // consumer time 150 ms
  EXPECT_EQ(gw_->downstream().state("right_grip"), sd::NodeState::Missing) << log_;
  const auto e = emcys(0x7000);
  ASSERT_EQ(e.size(), 1u) << dump();
  EXPECT_EQ(e[0].node, kGw);
  EXPECT_EQ(e[0].msef[0], 0x11) << "the sub-device's node-ID in manufacturer byte 0";
  EXPECT_EQ(e[0].msef[1], 'r');
  EXPECT_EQ(e[0].error_register & 0x01, 0x01);
  // At the moment the EMCY reached the host, every field of joystick 1 already was neutral.
  ASSERT_FALSE(joy1_at_emcy_.empty());
  EXPECT_TRUE(neutral(joy1_at_emcy_.front()));
  EXPECT_EQ(gw_->status(kJoy1), FeStatus::Offline);
  EXPECT_EQ(gw_->status(kWheel1), FeStatus::Offline);
  EXPECT_EQ(gw_->status(kJoy2), FeStatus::Valid) << "the other grip is not affected";
  const auto f = last(kTpdo1);
  ASSERT_TRUE(f);
  EXPECT_EQ(f->to_string(), "1A0#0000000000000000") << "the host read neutral";
  // The fault TPDO went out before (or with) the EMCY: no TPDO after the EMCY carries x != 0.
  cmd("right_grip heartbeat on");
  cmd("right_grip x 0");
  cmd("right_grip buttons[1] 0");
  run_for(5s);
  EXPECT_EQ(gw_->downstream().state("right_grip"), sd::NodeState::Operational) << log_;
  EXPECT_EQ(emcys(0x0000).size(), 1u) << dump();
  EXPECT_EQ(gw_->status(kJoy1), FeStatus::Valid);
  cmd("right_grip x 40");
  run_for(300ms);
  EXPECT_EQ(i16(*last(kTpdo1), 0), 13107);
}

TEST_F(GatewayE2E, ElobauErrorCode126OnXThenNeutralInterlockAfterRecovery) {
  build();
  boot_and_start();
  cmd("right_grip x 50");
  run_for(300ms);
  ASSERT_EQ(i16(*last(kTpdo1), 0), 16384);
  ASSERT_TRUE(grip().inject("x", sd::sim::ElobauMfgSim::Fault::Error, 1));
  run_for(300ms);
  EXPECT_EQ(gw_->status(kJoy1), FeStatus::Error);
  EXPECT_EQ(field(kJoy1, "x"), 0);
  EXPECT_EQ(i16(*last(kTpdo1), 0), 0) << dump();
  const auto e = emcys(0x7000);
  ASSERT_EQ(e.size(), 1u) << dump();
  EXPECT_EQ(e[0].msef[0], 0x11);
  ASSERT_FALSE(joy1_at_emcy_.empty());
  EXPECT_TRUE(neutral(joy1_at_emcy_.front())) << "x at its fault value when the EMCY left";
  EXPECT_EQ(gw_->downstream().state("right_grip"), sd::NodeState::Operational) << "an input error, not a lost node";
  // Recovery with the stick still deflected: the error reset goes up, x stays at neutral.
  ASSERT_TRUE(grip().inject("x", sd::sim::ElobauMfgSim::Fault::None, 1));
  run_for(300ms);
  EXPECT_EQ(emcys(0x0000).size(), 1u) << dump();
  EXPECT_EQ(gw_->status(kJoy1), FeStatus::Valid);
  EXPECT_EQ(field(kJoy1, "x"), 0) << "interlocked: not seen in its deadband yet";
  const auto joy = gw_->fields(kJoy1);
  const auto x_state = std::find_if(joy.begin(), joy.end(), [](const auto& f) { return f.name == "x"; });
  ASSERT_NE(x_state, joy.end());
  EXPECT_TRUE(x_state->interlocked);
  cmd("right_grip x 60");
  run_for(300ms);
  EXPECT_EQ(field(kJoy1, "x"), 0) << "still held";
  EXPECT_EQ(i16(*last(kTpdo1), 0), 0);
  cmd("right_grip x 1");  // inside the 2 % deadband: released
  run_for(300ms);
  EXPECT_EQ(field(kJoy1, "x"), 0);
  cmd("right_grip x 60");
  run_for(300ms);
  EXPECT_EQ(field(kJoy1, "x"), 19660);  // 60 * 327.67 = 19660.2
  EXPECT_EQ(i16(*last(kTpdo1), 0), 19660);
  // y was never faulty: it followed throughout.
  cmd("right_grip y 10");
  run_for(300ms);
  EXPECT_EQ(i16(*last(kTpdo1), 2), 3277);
}

TEST_F(GatewayE2E, ElobauNotAvailable127OnX) {
  build();
  boot_and_start();
  cmd("right_grip x 30");
  run_for(300ms);
  ASSERT_TRUE(grip().inject("x", sd::sim::ElobauMfgSim::Fault::NotAvailable, 1));
  run_for(300ms);
  EXPECT_EQ(gw_->status(kJoy1), FeStatus::NotAvailable);
  EXPECT_EQ(field(kJoy1, "x"), 0);
  EXPECT_EQ(i16(*last(kTpdo1), 0), 0);
  ASSERT_EQ(emcys(0x7000).size(), 1u) << dump();
  EXPECT_EQ(emcys(0x7000)[0].msef[0], 0x11);
  ASSERT_TRUE(grip().inject("x", sd::sim::ElobauMfgSim::Fault::None, 1));
  cmd("right_grip x 0");
  run_for(300ms);
  EXPECT_EQ(emcys(0x0000).size(), 1u) << dump();
  EXPECT_EQ(gw_->status(kJoy1), FeStatus::Valid);
  EXPECT_TRUE(gw_->faults().empty());
}

TEST_F(GatewayE2E, ElobauChannelMismatch) {
  build();
  boot_and_start();
  ASSERT_TRUE(grip().move_axis("x", 30, 20));  // channel 2 reads 50 %: 20 > tolerance 5
  run_for(300ms);
  EXPECT_EQ(gw_->status(kJoy1), FeStatus::Error) << log_;
  EXPECT_EQ(field(kJoy1, "x"), 0);
  EXPECT_EQ(i16(*last(kTpdo1), 0), 0);
  ASSERT_EQ(emcys(0x7000).size(), 1u) << dump();
  EXPECT_EQ(emcys(0x7000)[0].msef[0], 0x11);
  ASSERT_TRUE(grip().move_axis("x", 0, 0));
  run_for(300ms);
  EXPECT_EQ(emcys(0x0000).size(), 1u);
  EXPECT_EQ(gw_->status(kJoy1), FeStatus::Valid);
  ASSERT_TRUE(grip().move_axis("x", 30, 3));  // within tolerance
  run_for(300ms);
  EXPECT_EQ(field(kJoy1, "x"), 9830);  // 30 * 327.67 = 9830.1
  EXPECT_EQ(emcys(0x7000).size(), 1u);
}

TEST_F(GatewayE2E, SubdeviceErrorEmcy) {
  build();
  boot_and_start();
  cmd("right_grip x 20");
  run_for(300ms);
  grip().raise_error(0x0001, loop_.now());  // Table 6 0001h: every input Error
  run_for(300ms);
  ASSERT_EQ(emcys(0x7000).size(), 1u) << dump();
  EXPECT_EQ(emcys(0x7000)[0].msef[0], 0x11);
  ASSERT_FALSE(joy1_at_emcy_.empty());
  EXPECT_TRUE(neutral(joy1_at_emcy_.front())) << "fault values before the EMCY leaves";
  EXPECT_NE(gw_->faults().count("right_grip"), 0u);
  EXPECT_EQ(gw_->faults().at("right_grip"), "error EMCY");
  EXPECT_TRUE(neutral(gw_->fields(kJoy1)));
  EXPECT_EQ(field(kWheel1, "position"), 0);
  EXPECT_EQ(last(kTpdo1)->to_string(), "1A0#0000000000000000");
  grip().clear_error(0x0001, loop_.now());  // the grip's error reset 0000h
  cmd("right_grip x 0");
  run_for(500ms);
  EXPECT_EQ(emcys(0x0000).size(), 1u) << dump();
  EXPECT_TRUE(gw_->faults().empty()) << log_;
  EXPECT_EQ(gw_->status(kJoy1), FeStatus::Valid);
}

// An error EMCY the driver does not map to any signal (MCB-402: an undocumented code, "signals
// untouched") still faults the sub-device: its fields go to their fault values at once.
TEST_F(GatewayE2E, UnknownErrorEmcyStillPutsTheFieldsAtTheirFaultValues) {
  build();
  boot_and_start();
  cmd("left_grip x 10000");
  cmd("left_grip buttons[1] 1");
  run_for(300ms);
  ASSERT_EQ(field(kJoy2, "x"), 10000);
  mcb().node().emcy().raise(0x5000, 0x80, loop_.now());  // "device hardware", not in the document
  run_for(300ms);
  ASSERT_EQ(emcys(0x7000).size(), 1u) << dump();
  EXPECT_EQ(emcys(0x7000)[0].msef[0], 0x03);
  EXPECT_TRUE(neutral(gw_->fields(kJoy2))) << log_;
  EXPECT_NE(gw_->status(kJoy2), FeStatus::Valid);
  EXPECT_EQ(i16(*last(kTpdo5), 0), 0) << dump();
  EXPECT_EQ(last(kTpdo5)->data[7], 0x00);
  // The device's error reset: the fault clears, the axis is held until seen at neutral.
  mcb().node().emcy().clear(0x5000, loop_.now());
  run_for(300ms);
  EXPECT_EQ(emcys(0x0000).size(), 1u) << dump();
  EXPECT_TRUE(gw_->faults().empty());
  EXPECT_EQ(field(kJoy2, "x"), 0);
  EXPECT_EQ(field(kJoy2, "buttons[1]"), 1) << "a button has no interlock";
  cmd("left_grip x 0");
  run_for(300ms);
  cmd("left_grip x 10000");
  run_for(300ms);
  EXPECT_EQ(field(kJoy2, "x"), 10000);
  EXPECT_EQ(gw_->status(kJoy2), FeStatus::Valid);
}

// A warning EMCY (elobau 8140h "recovered from bus-off", decoded as no error) while an error
// EMCY is active does not end the error: the fault stays until the device's error reset. With
// 0001h the driver itself holds every input in Error; 0070h (LED message timeout) marks only
// the LEDs, so only the gateway's EMCY state keeps the fault.
class GatewayE2EWarning : public GatewayE2E, public ::testing::WithParamInterface<std::uint16_t> {};

TEST_P(GatewayE2EWarning, AWarningEmcyDoesNotEndAnActiveSubdeviceError) {
  build();
  boot_and_start();
  grip().raise_error(GetParam(), loop_.now());
  run_for(300ms);
  ASSERT_EQ(emcys(0x7000).size(), 1u) << dump();
  EXPECT_NE(gw_->status(kJoy1), FeStatus::Valid);
  grip().bus_off(loop_.now());  // EMCY 8140h with the bus-off count
  run_for(300ms);
  ASSERT_NE(log_.find("right_grip: EMCY 8140h"), std::string::npos) << log_;
  EXPECT_NE(gw_->faults().count("right_grip"), 0u) << log_;
  EXPECT_TRUE(emcys(0x0000).empty()) << dump();
  EXPECT_NE(gw_->status(kJoy1), FeStatus::Valid);
  cmd("right_grip x 50");
  run_for(300ms);
  EXPECT_EQ(field(kJoy1, "x"), 0) << "still held while the error is active";
  grip().clear_error(GetParam(), loop_.now());
  cmd("right_grip x 0");
  run_for(500ms);
  EXPECT_EQ(emcys(0x0000).size(), 1u) << dump();
  EXPECT_TRUE(gw_->faults().empty()) << log_;
  cmd("right_grip x 50");
  run_for(300ms);
  EXPECT_EQ(field(kJoy1, "x"), 16384);
}
INSTANTIATE_TEST_SUITE_P(Elobau, GatewayE2EWarning, ::testing::Values(std::uint16_t{0x0001}, std::uint16_t{0x0070}));

TEST_F(GatewayE2E, Mcb402CableBreak) {
  build();
  boot_and_start();
  cmd("left_grip y -12000");
  run_for(300ms);
  ASSERT_EQ(i16(*last(kTpdo5), 2), 12000);
  mcb().cable_break(2, true, loop_.now());  // axis 2 = Y
  run_for(300ms);
  EXPECT_EQ(gw_->status(kJoy2), FeStatus::Error) << log_;
  EXPECT_EQ(field(kJoy2, "y"), 0);
  EXPECT_EQ(i16(*last(kTpdo5), 2), 0) << dump();
  ASSERT_EQ(emcys(0x7000).size(), 1u) << dump();
  EXPECT_EQ(emcys(0x7000)[0].msef[0], 0x03);
  EXPECT_EQ(emcys(0x7000)[0].msef[1], 'l');
  EXPECT_EQ(gw_->status(kJoy1), FeStatus::Valid) << "the right grip is not affected";
  // Mended while y is still at -12000: error reset, then y held until seen at neutral.
  mcb().cable_break(2, false, loop_.now());
  run_for(300ms);
  EXPECT_EQ(emcys(0x0000).size(), 1u) << dump();
  EXPECT_EQ(field(kJoy2, "y"), 0);
  cmd("left_grip y 100");
  run_for(300ms);
  cmd("left_grip y -12000");
  run_for(300ms);
  EXPECT_EQ(field(kJoy2, "y"), 12000);
  EXPECT_EQ(i16(*last(kTpdo5), 2), 12000);
}

TEST_F(GatewayE2E, TwoFaultySubdevicesEachNamedAndClearedInTurn) {
  build();
  boot_and_start();
  cmd("right_grip heartbeat off");
  run_for(400ms);
  mcb().cable_break(2, true, loop_.now());
  run_for(300ms);
  // oe_device.hpp: the second fault while 7000h is active is an extra 7000h frame naming it.
  const auto e = emcys(0x7000);
  ASSERT_EQ(e.size(), 2u) << dump();
  EXPECT_EQ(e[0].msef[0], 0x11);
  EXPECT_EQ(e[1].msef[0], 0x03);
  EXPECT_EQ(gw_->faults().size(), 2u);
  // The MCB-402 recovers first: EMCY 0000h naming it, the error register still set (the grip).
  mcb().cable_break(2, false, loop_.now());
  run_for(300ms);
  auto r = emcys(0x0000);
  ASSERT_EQ(r.size(), 1u) << dump();
  EXPECT_EQ(r[0].msef[0], 0x03);
  EXPECT_EQ(r[0].error_register & 0x01, 0x01);
  EXPECT_EQ(gw_->status(kJoy1), FeStatus::Offline);
  // Then the grip: the last one clears 7000h, register 0.
  cmd("right_grip heartbeat on");
  run_for(5s);
  r = emcys(0x0000);
  ASSERT_EQ(r.size(), 2u) << dump();
  EXPECT_EQ(r[1].error_register, 0x00);
  EXPECT_TRUE(gw_->faults().empty()) << log_;
}

// The host resets the gateway (NMT reset node): the application objects go back to their
// defaults, the EMCY producer forgets its errors. What the host reads afterwards must still be
// the truth: the inputs' current values, and the sub-device that is still lost.
TEST_F(GatewayE2E, HostResetNodeKeepsInputsAndFaultsTrue) {
  build();
  boot_and_start();
  cmd("right_grip x 50");
  cmd("right_grip buttons[2] 1");
  cmd("seat_knob position 777");
  run_for(300ms);
  cmd("left_grip heartbeat off");
  run_for(400ms);
  ASSERT_EQ(emcys(0x7000).size(), 1u);
  emcys_.clear();
  upstream_.clear();
  host_->nmt().reset_node(kGw);
  run_for(500ms);
  EXPECT_TRUE(std::any_of(upstream_.begin(), upstream_.end(), [](const BusRecord& r) {
    return r.frame.to_string() == "720#00";
  })) << dump();
  EXPECT_EQ(gw_->upstream().node().state(), NmtState::PreOperational);
  const auto x = sdo_read(0x6401, 1);
  ASSERT_TRUE(x.has_value());
  EXPECT_EQ(static_cast<std::int16_t>(decode_unsigned(*x)), 16384) << "the stick is still at 50 %";
  EXPECT_EQ(decode_unsigned(*sdo_read(0x6000, 2)), 0x02u) << "joystick 1 buttons";
  EXPECT_EQ(static_cast<std::int32_t>(decode_unsigned(*sdo_read(0x6120, 0x81))), 777);
  // The MCB-402 is still lost: EMCY 7000h naming it again after the boot-up, and 1001h says so.
  const auto e = emcys(0x7000);
  ASSERT_EQ(e.size(), 1u) << dump();
  EXPECT_EQ(e[0].msef[0], 0x03);
  EXPECT_EQ(decode_unsigned(*sdo_read(0x1001, 0)) & 0x01, 0x01u);
  EXPECT_EQ(gw_->status(kJoy2), FeStatus::Offline);
}

// NMT reset node restarts the application and its errors with it (CiA 301 §7.3.2.2.1): an
// error whose cause is gone does not survive it — 8240h for a SYNC of the wrong length, 1001h
// bit 4 — and one whose cause persists is raised anew once pre-operational: the MCB-402 still
// lost, EMCY 7000h with 1001h = 01h (generic) as its own error, not an event with the old
// register. A reset communication keeps the active errors (only the communication restarts).
TEST_F(GatewayE2E, HostResetNodeEndsTheErrorsAndRaisesWhatPersistsAnew) {
  build();
  boot_and_start();
  cmd("left_grip heartbeat off");
  run_for(400ms);
  ASSERT_EQ(emcys(0x7000).size(), 1u);
  (void)host_port_->send(CanFrame(0x080, {0x07}));  // SYNC with a counter, 1019h = 0: wrong length
  run_for(10ms);
  ASSERT_EQ(emcys(0x8240).size(), 1u) << dump();
  EXPECT_EQ(emcys(0x8240)[0].error_register, 0x11) << "generic and communication";
  host_->nmt().reset_communication(kGw);
  run_for(500ms);
  EXPECT_EQ(decode_unsigned(*sdo_read(0x1001, 0)), 0x11u) << "reset communication keeps 8240h and 7000h";
  emcys_.clear();
  upstream_.clear();
  host_->nmt().reset_node(kGw);
  run_for(500ms);
  // The boot-up, then 7000h naming the MCB-402 as a new error: register 01h.
  std::vector<std::string> seen;
  for (const auto& r : upstream_)
    if (r.frame.id == 0x720 || r.frame.id == 0x0A0) seen.push_back(r.frame.to_string());
  ASSERT_GE(seen.size(), 2u) << dump();
  EXPECT_EQ(seen[0], "720#00");
  EXPECT_EQ(seen[1].substr(0, 12), "0A0#00700103") << "7000h, 1001h = 01h, node 03h\n" << dump();
  EXPECT_EQ(decode_unsigned(*sdo_read(0x1001, 0)), 0x01u) << "8240h did not survive the reset node";
  EXPECT_EQ(gw_->status(kJoy2), FeStatus::Offline);
  // The MCB-402 back: the last error goes, 0000h, 1001h 0.
  cmd("left_grip heartbeat on");
  run_for(5s);
  EXPECT_EQ(emcys(0x0000).size(), 1u) << dump();
  EXPECT_EQ(decode_unsigned(*sdo_read(0x1001, 0)), 0x00u);
}

// A store the gateway cannot read when the host resets it (a reset node reads it again, CiA 301
// 1010h/1011h) is refused as at power-on: defaults, EMCY 6000h once pre-operational, and the log
// says so and why (the power-on's refusal is logged by oegw run; a reset's was silent).
TEST_F(GatewayE2E, AStoreRefusedAtAResetNodeIsLoggedAndSentAsEmcy6000h) {
  build();
  boot_and_start();
  std::ofstream(store_) << "not a parameter store\n";
  emcys_.clear();
  log_.clear();
  host_->nmt().reset_node(kGw);
  run_for(500ms);
  EXPECT_EQ(emcys(0x6000).size(), 1u) << dump();
  EXPECT_NE(log_.find("upstream store refused at NMT reset node: "), std::string::npos) << log_;
  EXPECT_NE(log_.find("running on defaults, EMCY 6000h sent upstream"), std::string::npos) << log_;
  // A reset communication reads its part again: refused again, said again.
  log_.clear();
  host_->nmt().reset_communication(kGw);
  run_for(500ms);
  EXPECT_NE(log_.find("upstream store refused at NMT reset communication: "), std::string::npos) << log_;
}

// Upstream bus-off and recovery (the controller restarted): EMCY 8140h, 1029h:01 = 0 takes the
// gateway to pre-operational; a sub-device fault still active is not cleared by it.
TEST_F(GatewayE2E, UpstreamBusOffRecoveryReportsEmcy8140hAndKeepsTheSubdeviceFault) {
  build();
  boot_and_start();
  cmd("left_grip heartbeat off");
  run_for(400ms);
  ASSERT_EQ(emcys(0x7000).size(), 1u);
  gw_->on_upstream_bus_event(BusEvent::BusOff, loop_.now());
  run_for(10ms);
  EXPECT_EQ(gw_->upstream().node().state(), NmtState::PreOperational);
  gw_->on_upstream_bus_event(BusEvent::Restarted, loop_.now());
  run_for(100ms);
  EXPECT_EQ(emcys(0x8140).size(), 1u) << dump();
  EXPECT_TRUE(emcys(0x0000).empty()) << "7000h is still active: no error reset";
  EXPECT_EQ(decode_unsigned(*sdo_read(0x1001, 0)) & 0x01, 0x01u);
  EXPECT_EQ(gw_->status(kJoy2), FeStatus::Offline);
  // The MCB-402 comes back: now the last error goes, 0000h.
  cmd("left_grip heartbeat on");
  run_for(5s);
  EXPECT_EQ(emcys(0x0000).size(), 1u) << dump();
  EXPECT_EQ(decode_unsigned(*sdo_read(0x1001, 0)), 0x00u);
}

TEST_F(GatewayE2E, WrongIdentityAtBootRefusesTheMandatoryNode) {
  build(", identity: { vendor_id: 0x99 }");  // the elobau grip answers B4h
  power_on();
  EXPECT_EQ(gw_->downstream().state("right_grip"), sd::NodeState::Refused) << log_;
  EXPECT_EQ(gw_->downstream().state("left_grip"), sd::NodeState::Operational);
  EXPECT_TRUE(gw_->downstream().fault()) << "mandatory";
  EXPECT_NE(gw_->faults().count("right_grip"), 0u);
  EXPECT_EQ(gw_->status(kJoy1), FeStatus::Offline);
  EXPECT_TRUE(neutral(gw_->fields(kJoy1)));
  // The EMCY went up in pre-operational, naming the grip.
  const auto e = emcys(0x7000);
  ASSERT_GE(e.size(), 1u) << dump();
  EXPECT_EQ(e[0].msef[0], 0x11);
  // The host starts the gateway anyway: joystick 1 stays neutral while the grip moves.
  host_configures_and_starts();
  cmd("right_grip x 50");
  run_for(500ms);
  EXPECT_EQ(field(kJoy1, "x"), 0);
  EXPECT_NE(gw_->downstream().state("right_grip"), sd::NodeState::Operational);
}

TEST_F(GatewayE2E, AnalogInterruptsDisabledAtStartSendsEmcy0080hAndStaysOperational) {
  build();
  power_on();
  host_configures_and_starts(/*analog_interrupts=*/false);
  run_for(300ms);
  const auto e = emcys(0x0080);
  ASSERT_EQ(e.size(), 1u) << dump();
  EXPECT_EQ(e[0].error_register, 0x01);
  EXPECT_EQ(gw_->upstream().node().state(), NmtState::Operational);
  const auto hb = std::count_if(upstream_.begin(), upstream_.end(),
                                [](const BusRecord& r) { return r.frame.id == 0x720 && r.frame.data[0] == 0x05; });
  EXPECT_GT(hb, 0) << "the heartbeat says operational";
  // Axis changes alone send nothing while 6423h is FALSE, a button does (carrying the axis).
  pdos_.clear();
  cmd("right_grip x 50");
  run_for(300ms);
  EXPECT_TRUE(pdos(kTpdo1).empty()) << dump();
  cmd("right_grip buttons[1] 1");
  run_for(300ms);
  ASSERT_FALSE(pdos(kTpdo1).empty());
  EXPECT_EQ(last(kTpdo1)->to_string(), "1A0#0040000000000001");
  // Setting 6423h TRUE clears it (error reset).
  ASSERT_EQ(sdo_write(0x6423, 0, {1}), SdoAbortCode::None);
  run_for(100ms);
  EXPECT_EQ(emcys(0x0000).size(), 1u);
  EXPECT_EQ(gw_->upstream().node().state(), NmtState::Operational);
}

TEST_F(GatewayE2E, IndicatorsFromHostReachElobauAndMcb402LedsByRpdoAndSdo) {
  build();
  boot_and_start();
  // RPDO 5 -> indicators.2 (6200h:09h) -> MCB-402 OUT0..3.
  (void)host_port_->send(CanFrame(kRpdo5, {0x05, 0, 0, 0, 0, 0, 0, 0}));
  // RPDO 6 -> indicators.3 (6200h:11h) -> elobau LEDs 1, 2.
  (void)host_port_->send(CanFrame(kRpdo6, {0x02, 0, 0, 0, 0, 0, 0, 0}));
  // RPDO 1 -> indicators.1 -> the cluster's output byte.
  (void)host_port_->send(CanFrame(kRpdo1, {0xA5, 0, 0, 0, 0, 0, 0, 0}));
  run_for(300ms);
  auto* left = bench_->device("left_grip");
  auto* right = bench_->device("right_grip");
  auto* cluster = bench_->device("cluster");
  EXPECT_EQ(left->output("leds[1]"), 1);
  EXPECT_EQ(left->output("leds[2]"), 0);
  EXPECT_EQ(left->output("leds[3]"), 1);
  EXPECT_EQ(left->output("leds[4]"), 0);
  EXPECT_EQ(right->output("leds[1]"), 0);
  EXPECT_EQ(right->output("leds[2]"), 1);
  EXPECT_EQ(cluster->output("out[1]"), 0xA5);
  // SDO download of 6200h:11h (indicators.3) and 6200h:09h (indicators.2).
  ASSERT_EQ(sdo_write(0x6200, 0x11, {0x01}), SdoAbortCode::None);
  ASSERT_EQ(sdo_write(0x6200, 0x09, {0x0A}), SdoAbortCode::None);
  run_for(300ms);
  EXPECT_EQ(right->output("leds[1]"), 1);
  EXPECT_EQ(right->output("leds[2]"), 0);
  EXPECT_EQ(left->output("leds[1]"), 0);
  EXPECT_EQ(left->output("leds[2]"), 1);
  EXPECT_EQ(left->output("leds[4]"), 1);
  EXPECT_EQ(decode_unsigned(*sdo_read(0x6200, 0x09)), 0x0Au);
}

TEST_F(GatewayE2E, IndicatorsSetWhileTheMcb402IsLostReachItWhenItReturns) {
  build();
  boot_and_start();
  cmd("left_grip silent on");
  run_for(400ms);
  ASSERT_EQ(gw_->downstream().state("left_grip"), sd::NodeState::Missing);
  (void)host_port_->send(CanFrame(kRpdo5, {0x06, 0, 0, 0, 0, 0, 0, 0}));  // lamps 2, 3
  run_for(100ms);
  EXPECT_EQ(decode_unsigned(*sdo_read(0x6200, 0x09)), 0x06u);
  auto* left = bench_->device("left_grip");
  EXPECT_EQ(left->output("leds[2]"), 0) << "the board is unplugged";
  cmd("left_grip silent off");
  cmd("left_grip reboot");  // powers up with its outputs off
  run_for(5s);
  ASSERT_EQ(gw_->downstream().state("left_grip"), sd::NodeState::Operational) << log_;
  EXPECT_EQ(left->output("leds[1]"), 0);
  EXPECT_EQ(left->output("leds[2]"), 1);
  EXPECT_EQ(left->output("leds[3]"), 1);
  EXPECT_EQ(left->output("leds[4]"), 0);
}

TEST_F(GatewayE2E, HostHeartbeatLossAppliesErrorValuesToTheLeds) {
  build();
  boot_and_start();
  bool host_alive = true;
  host_heartbeat_watched(host_alive);
  // Error mode for every bit of indicators.2 and .3, error values: MCB OUT1/OUT3, elobau LED 2.
  error_values(0x09, 0xFF, 0x0A);
  error_values(0x11, 0xFF, 0x02);
  (void)host_port_->send(CanFrame(kRpdo5, {0x05, 0, 0, 0, 0, 0, 0, 0}));
  (void)host_port_->send(CanFrame(kRpdo6, {0x01, 0, 0, 0, 0, 0, 0, 0}));
  run_for(1s);
  auto* left = bench_->device("left_grip");
  auto* right = bench_->device("right_grip");
  ASSERT_EQ(left->output("leds[1]"), 1);
  ASSERT_EQ(left->output("leds[3]"), 1);
  ASSERT_EQ(right->output("leds[1]"), 1);
  EXPECT_TRUE(emcys(0x8130).empty());
  host_alive = false;
  run_for(500ms);
  EXPECT_EQ(emcys(0x8130).size(), 1u) << dump();
  EXPECT_EQ(decode_unsigned(*sdo_read(0x6200, 0x09)), 0x0Au);
  EXPECT_EQ(left->output("leds[1]"), 0);
  EXPECT_EQ(left->output("leds[2]"), 1);
  EXPECT_EQ(left->output("leds[3]"), 0);
  EXPECT_EQ(left->output("leds[4]"), 1);
  EXPECT_EQ(right->output("leds[1]"), 0);
  EXPECT_EQ(right->output("leds[2]"), 1);
}

// ---- Who commands the outputs: the mapping file's `sources` per FE ---------------------------

// indicators.1 (the cluster's lamps) from DDS only, indicators.2 (MCB-402) from the host and LCM,
// indicators.3 (elobau LEDs) from the host and DDS (no `sources`: LCM is opt-in).
// Inserts `line` into a mapping file right after the first `after`.
void insert_after(std::string& yaml, const std::string& after, const std::string& line) {
  const auto at = yaml.find(after);
  ASSERT_NE(at, std::string::npos) << after;
  yaml.insert(at + after.size(), line);
}

std::string with_sources(std::string yaml) {
  auto put = [&yaml](const std::string& after, const std::string& line) { insert_after(yaml, after, line); };
  put("  indicators.1:\n", "    sources: [dds]\n");
  put("  indicators.2:\n", "    sources: [canopen, lcm]\n");
  // Both transports on: a source listed whose transport is off is refused
  // (docs/reference/mapping-file.md#functional_elements-kindinstance-field-signal-required-may-be-empty). CabRig runs
  // no publisher; the tests hand the commands to the gateway.
  put("downstream: { interface: virtual, bitrate: 250000 }\n",
      "publish: { dds: { enabled: true }, lcm: { enabled: true } }\n");
  return yaml;
}

TEST_F(GatewayE2E, HostMayNotCommandAnFeWhoseSourcesLeaveOutCanopen) {
  build("", with_sources);
  boot_and_start();
  auto* cluster = bench_->device("cluster");
  // SDO download: refused with "local control", nothing changes.
  EXPECT_EQ(sdo_write(0x6200, 0x01, {0xFF}), SdoAbortCode::CannotTransferLocalControl);
  // RPDO 1 maps indicators.1 only: its bytes are ignored.
  (void)host_port_->send(CanFrame(kRpdo1, {0xA5, 0, 0, 0, 0, 0, 0, 0}));
  run_for(300ms);
  EXPECT_EQ(cluster->output("out[1]"), 0);
  EXPECT_EQ(decode_unsigned(*sdo_read(0x6200, 0x01)), 0u);
  EXPECT_EQ(gw_->refused_commands(), 9u) << "the SDO download and RPDO 1's eight entries";
  EXPECT_NE(log_.find("indicators.1: the host's SDO write refused (abort 0800 0021h): its sources are dds"),
            std::string::npos)
      << log_;
  EXPECT_NE(log_.find("indicators.1: the host's RPDO bytes for it ignored: its sources are dds"), std::string::npos)
      << log_;
  // The FE's error mode/value stay the host's to configure, and the host may read the lamps.
  EXPECT_EQ(sdo_write(0x6206, 0x01, {0xFF}), SdoAbortCode::None);
  // The machine application over DDS drives them.
  EXPECT_TRUE(gw_->command_indicators(1, 0x3C, loop_.now(), oegw::mapping::CommandSource::Dds));
  run_for(300ms);
  EXPECT_EQ(cluster->output("out[1]"), 0x3C);
  EXPECT_EQ(decode_unsigned(*sdo_read(0x6200, 0x01)), 0x3Cu);
  // LCM is not among its sources: refused, counted, logged once.
  EXPECT_FALSE(gw_->command_indicators(1, 0xFF, loop_.now(), oegw::mapping::CommandSource::Lcm));
  EXPECT_FALSE(gw_->command_indicators(1, 0x01, loop_.now(), oegw::mapping::CommandSource::Lcm));
  run_for(300ms);
  EXPECT_EQ(cluster->output("out[1]"), 0x3C);
  EXPECT_EQ(gw_->refused_commands(), 11u);
  const std::string line = "indicators.1: a command from lcm ignored: its sources are dds";
  const auto first = log_.find(line);
  EXPECT_NE(first, std::string::npos) << log_;
  EXPECT_EQ(log_.find(line, first + 1), std::string::npos) << "logged once per FE and source\n" << log_;
  // An FE the mapping file does not configure takes nothing.
  EXPECT_FALSE(gw_->command_indicators(4, 0xFF, loop_.now(), oegw::mapping::CommandSource::Dds));
  EXPECT_FALSE(gw_->command_display(1, {}, loop_.now(), oegw::mapping::CommandSource::Dds));
  EXPECT_FALSE(gw_->command_indicators(0, 0xFF, loop_.now(), oegw::mapping::CommandSource::Dds));
  EXPECT_FALSE(gw_->command_indicators(200, 0xFF, loop_.now(), oegw::mapping::CommandSource::Dds));
  EXPECT_EQ(gw_->refused_commands(), 15u);
  EXPECT_NE(log_.find("indicators.200: a command from dds ignored: the mapping file does not configure "
                      "indicators.200"),
            std::string::npos)
      << log_;
}

// An RPDO the host maps with a refused entry (indicators.1, DDS only) and an accepted one
// (indicators.2): the refused bytes are dropped, the rest of the RPDO applies (CiA 301 has no
// error for one entry; the gateway logs it once).
TEST_F(GatewayE2E, AnRpdoMixingARefusedAndAnAcceptedEntryAppliesTheAcceptedOne) {
  build("", with_sources);
  boot_and_start();
  // CiA 301 §7.5.2.35 mapping procedure: disable, clear, map, count, enable.
  ASSERT_EQ(sdo_write(0x1400, 1, encode<std::uint32_t>(0x80000000u | kRpdo1)), SdoAbortCode::None);
  ASSERT_EQ(sdo_write(0x1600, 0, {0}), SdoAbortCode::None);
  ASSERT_EQ(sdo_write(0x1600, 1, encode<std::uint32_t>(0x62000108)), SdoAbortCode::None);  // indicators.1
  ASSERT_EQ(sdo_write(0x1600, 2, encode<std::uint32_t>(0x62000908)), SdoAbortCode::None);  // indicators.2
  ASSERT_EQ(sdo_write(0x1600, 0, {2}), SdoAbortCode::None);
  ASSERT_EQ(sdo_write(0x1400, 1, encode<std::uint32_t>(kRpdo1)), SdoAbortCode::None);
  (void)host_port_->send(CanFrame(kRpdo1, {0xFF, 0x05}));
  run_for(300ms);
  EXPECT_EQ(bench_->device("cluster")->output("out[1]"), 0) << "indicators.1 is the machine application's";
  auto* left = bench_->device("left_grip");
  EXPECT_EQ(left->output("leds[1]"), 1);
  EXPECT_EQ(left->output("leds[2]"), 0);
  EXPECT_EQ(left->output("leds[3]"), 1);
  EXPECT_EQ(decode_unsigned(*sdo_read(0x6200, 0x09)), 0x05u);
  EXPECT_EQ(gw_->refused_commands(), 1u);
}

// command_timeout_ms: an output FE whose commander falls silent takes its error values
// (6206h/6207h) until the next command; any accepted command restarts the watchdog — a DDS
// command for indicators.1 (DDS only), the host's SDO downloads for indicators.2.
TEST_F(GatewayE2E, ASilentCommanderPutsItsFeToTheErrorValuesUntilTheNextCommand) {
  build("", [](std::string yaml) {
    yaml = with_sources(yaml);
    insert_after(yaml, "    sources: [dds]\n", "    command_timeout_ms: 500\n");
    insert_after(yaml, "    sources: [canopen, lcm]\n", "    command_timeout_ms: 1000\n");
    return yaml;
  });
  using oegw::mapping::CommandSource;
  auto* cluster = bench_->device("cluster");
  // The loop may run before power-on: the watchdogs start with the gateway, not before.
  run_for(600ms);
  EXPECT_EQ(log_.find("no command for"), std::string::npos) << log_;
  boot_and_start();
  // Nobody commanded since power-on: both timed out (error values = defaults: off).
  EXPECT_NE(log_.find("indicators.1: no command for 500 ms: outputs set to their error values"), std::string::npos)
      << log_;
  EXPECT_NE(log_.find("indicators.2: no command for 1000 ms"), std::string::npos) << log_;
  // Error values configured while timed out apply at once (the FE holds its error values).
  ASSERT_EQ(sdo_write(0x6206, 0x01, {0xFF}), SdoAbortCode::None);
  ASSERT_EQ(sdo_write(0x6207, 0x01, {0x81}), SdoAbortCode::None);
  ASSERT_EQ(sdo_write(0x6206, 0x09, {0x0F}), SdoAbortCode::None);
  ASSERT_EQ(sdo_write(0x6207, 0x09, {0x0A}), SdoAbortCode::None);
  run_for(100ms);
  EXPECT_EQ(cluster->output("out[1]"), 0x81);
  EXPECT_EQ(mcb_leds(), "0101");

  // The host commands indicators.2 (1000 ms watchdog), DDS commands indicators.1 (500 ms).
  ASSERT_EQ(sdo_write(0x6200, 0x09, {0x05}), SdoAbortCode::None);
  EXPECT_NE(log_.find("indicators.2: commands again"), std::string::npos) << log_;
  ASSERT_TRUE(gw_->command_indicators(1, 0x3C, loop_.now(), CommandSource::Dds));
  EXPECT_NE(log_.find("indicators.1: commands again"), std::string::npos) << log_;
  run_for(300ms);
  ASSERT_TRUE(gw_->command_indicators(1, 0x3C, loop_.now(), CommandSource::Dds));
  run_for(300ms);
  EXPECT_EQ(cluster->output("out[1]"), 0x3C) << "600 ms after the first command, 300 ms after the last";
  run_for(250ms);
  EXPECT_EQ(cluster->output("out[1]"), 0x81) << "silent for 550 ms > 500 ms\n" << log_;
  EXPECT_EQ(decode_unsigned(*sdo_read(0x6200, 0x01)), 0x81u);
  EXPECT_EQ(mcb_leds(), "1010") << "indicators.2 is commanded (850 ms < 1000 ms): only indicators.1 took error values";
  ASSERT_TRUE(gw_->command_indicators(1, 0x0F, loop_.now(), CommandSource::Dds));
  run_for(100ms);
  EXPECT_EQ(cluster->output("out[1]"), 0x0F) << "the next command takes over again";

  // indicators.2: the host's SDO download restarts its watchdog; a refused DDS command does not.
  ASSERT_EQ(sdo_write(0x6200, 0x09, {0x05}), SdoAbortCode::None);
  run_for(700ms);
  EXPECT_FALSE(gw_->command_indicators(2, 0x05, loop_.now(), CommandSource::Dds));
  EXPECT_EQ(mcb_leds(), "1010") << "700 ms after the last host write";
  run_for(400ms);
  EXPECT_EQ(mcb_leds(), "0101") << "silent for 1100 ms: 6207h:09 = 0Ah\n" << log_;
}

// The same rules for a display (6411h, error value 6444h): display.1 parameter 1 drives the
// cluster's analogue output, from DDS only, with a 400 ms watchdog.
TEST_F(GatewayE2E, ADisplayTakesItsSourcesAndItsWatchdogLikeAnIndicatorCluster) {
  build("", [](std::string yaml) {
    return with_sources(yaml) +
           "  display.1:\n    sources: [dds]\n    command_timeout_ms: 400\n    parameter[1]: cluster.aout[1]\n";
  });
  boot_and_start();
  using oegw::mapping::CommandSource;
  auto* cluster = bench_->device("cluster");
  ASSERT_EQ(sdo_write(0x6444, 0x01, encode<std::int32_t>(777)), SdoAbortCode::None);  // 6443h:01 = 1 by default
  std::array<std::int16_t, 12> p{};
  p[0] = 500;
  ASSERT_TRUE(gw_->command_display(1, p, loop_.now(), CommandSource::Dds));
  run_for(100ms);
  EXPECT_EQ(cluster->output("aout[1]"), 500);
  EXPECT_EQ(sdo_write(0x6411, 0x01, encode<std::int16_t>(100)), SdoAbortCode::CannotTransferLocalControl);
  EXPECT_FALSE(gw_->command_display(1, p, loop_.now(), CommandSource::Lcm));
  run_for(100ms);
  EXPECT_EQ(cluster->output("aout[1]"), 500) << "200 ms after the command";
  run_for(250ms);
  EXPECT_EQ(cluster->output("aout[1]"), 777) << "silent for 450 ms > 400 ms: 6444h:01\n" << log_;
  EXPECT_EQ(static_cast<std::int16_t>(decode_unsigned(*sdo_read(0x6411, 0x01))), 777);
  p[0] = 300;
  ASSERT_TRUE(gw_->command_display(1, p, loop_.now(), CommandSource::Dds));
  run_for(100ms);
  EXPECT_EQ(cluster->output("aout[1]"), 300);
}

TEST_F(GatewayE2E, AmongTheListedSourcesTheLastWriteWins) {
  build("", with_sources);
  boot_and_start();
  using oegw::mapping::CommandSource;
  // indicators.2 takes canopen and lcm.
  ASSERT_EQ(sdo_write(0x6200, 0x09, {0x05}), SdoAbortCode::None);
  run_for(200ms);
  EXPECT_EQ(mcb_leds(), "1010");
  EXPECT_TRUE(gw_->command_indicators(2, 0x0A, loop_.now(), CommandSource::Lcm));
  run_for(200ms);
  EXPECT_EQ(mcb_leds(), "0101") << "LCM wrote last";
  EXPECT_EQ(decode_unsigned(*sdo_read(0x6200, 0x09)), 0x0Au) << "the host reads what LCM set";
  (void)host_port_->send(CanFrame(kRpdo5, {0x01, 0, 0, 0, 0, 0, 0, 0}));
  run_for(200ms);
  EXPECT_EQ(mcb_leds(), "1000") << "the host's RPDO wrote last";
  EXPECT_FALSE(gw_->command_indicators(2, 0x0F, loop_.now(), CommandSource::Dds)) << "DDS is not listed";
  run_for(200ms);
  EXPECT_EQ(mcb_leds(), "1000");
  // indicators.3 lists no sources: the host and DDS, not LCM (it must be listed to command).
  auto* right = bench_->device("right_grip");
  EXPECT_TRUE(gw_->command_indicators(3, 0x02, loop_.now(), CommandSource::Dds));
  run_for(200ms);
  EXPECT_EQ(right->output("leds[2]"), 1);
  EXPECT_FALSE(gw_->command_indicators(3, 0x01, loop_.now(), CommandSource::Lcm)) << "LCM is opt-in";
  run_for(200ms);
  EXPECT_EQ(right->output("leds[1]"), 0);
  EXPECT_EQ(right->output("leds[2]"), 1);
  EXPECT_NE(log_.find("indicators.3: a command from lcm ignored: its sources are canopen, dds"), std::string::npos)
      << log_;
  ASSERT_EQ(sdo_write(0x6200, 0x11, {0x01}), SdoAbortCode::None);
  run_for(200ms);
  EXPECT_EQ(right->output("leds[1]"), 1);
  EXPECT_EQ(right->output("leds[2]"), 0);
}

// A DDS-only FE still takes its error values when the host's heartbeat is lost (CiA 401
// 6206h/6207h apply to every output, whoever commands it: the safe side).
TEST_F(GatewayE2E, HostHeartbeatLossAppliesErrorValuesAlsoToAnFeTheHostDoesNotCommand) {
  build("", with_sources);
  boot_and_start();
  bool host_alive = true;
  host_heartbeat_watched(host_alive);
  ASSERT_EQ(sdo_write(0x6206, 0x01, {0xFF}), SdoAbortCode::None);
  ASSERT_EQ(sdo_write(0x6207, 0x01, {0x81}), SdoAbortCode::None);
  ASSERT_TRUE(gw_->command_indicators(1, 0x3C, loop_.now(), oegw::mapping::CommandSource::Dds));
  run_for(500ms);
  auto* cluster = bench_->device("cluster");
  ASSERT_EQ(cluster->output("out[1]"), 0x3C);
  host_alive = false;
  run_for(500ms);
  EXPECT_EQ(emcys(0x8130).size(), 1u) << dump();
  EXPECT_EQ(cluster->output("out[1]"), 0x81);
}

// 1010h "save" keeps the host's upstream configuration (PDO COB-IDs, 6423h) across a restart of
// the gateway process (a new Gateway on the same store file); the sub-devices are booted again.
TEST_F(GatewayE2E, SavedUpstreamConfigurationSurvivesAGatewayRestart) {
  build();
  boot_and_start();
  ASSERT_EQ(sdo_write(0x1010, 1, {'s', 'a', 'v', 'e'}), SdoAbortCode::None);
  // Power cycle of the gateway: a new process on the same mapping file and store.
  connect_gateway();
  const auto loaded = gw_->start(loop_.now());
  EXPECT_TRUE(loaded.ok) << loaded.error;
  run_for(3s);
  EXPECT_TRUE(all_operational()) << log_;
  EXPECT_EQ(decode_unsigned(*sdo_read(0x1800, 1)), kTpdo1);
  EXPECT_EQ(decode_unsigned(*sdo_read(0x1804, 1)), kTpdo5);
  EXPECT_EQ(decode_unsigned(*sdo_read(0x1404, 1)), kRpdo5);
  EXPECT_EQ(decode_unsigned(*sdo_read(0x6423, 0)), 1u);
  // Only the NMT start is needed now.
  emcys_.clear();
  pdos_.clear();
  host_->nmt().start(kGw);
  run_for(100ms);
  cmd("right_grip x 50");
  run_for(300ms);
  ASSERT_TRUE(last(kTpdo1)) << dump();
  EXPECT_EQ(i16(*last(kTpdo1), 0), 16384);
  EXPECT_TRUE(emcys(0x0080).empty()) << "6423h TRUE was stored";
}

// ---- A bad mapping file: refused with file:line:column, nothing built --------------------------

TEST(GatewayE2EBadMapping, ErrorsCarryFileLineColumnAndNoGatewayIsBuilt) {
  std::string text = mapping_yaml();
  // An unknown key with a suggestion (line 6), a signal the elobau driver does not provide
  // (line 28, at the signal's value), an FE instance out of range (line 38).
  auto replace = [&](const std::string& from, const std::string& to) {
    const auto p = text.find(from);
    ASSERT_NE(p, std::string::npos) << from;
    text.replace(p, from.size(), to);
  };
  replace("  heartbeat_ms: 100\ndownstream", "  heartbeat_msec: 100\ndownstream");
  replace("    y: { signal: right_grip.y, deadband: 2 }", "    y: { signal: right_grip.why, deadband: 2 }");
  replace("  encoder.1:", "  encoder.9:");
  const auto r = oegw::mapping::load_config_text(text, "bad.yaml", gw::driver_catalogue());
  ASSERT_FALSE(r.ok());
  EXPECT_FALSE(r.config.has_value()) << "no Config, so no Gateway can be constructed";
  std::vector<std::string> lines;
  for (const auto& d : r.errors) lines.push_back(d.str());
  ASSERT_EQ(lines.size(), 3u) << r.error_text();
  EXPECT_EQ(lines[0],
            "bad.yaml:6:3: unknown key 'heartbeat_msec' in upstream; expected one of interface, node_id, bitrate, "
            "identity, heartbeat_ms, store, network_id, sdo_servers (did you mean 'heartbeat_ms'?)");
  EXPECT_EQ(lines[1].rfind(
                "bad.yaml:28:18: sub-device 'right_grip' (elobau-mfg) has no signal 'why'; expected one of x, y,", 0),
            0u)
      << lines[1];
  EXPECT_EQ(lines[2].rfind("bad.yaml:38:3: instance 9 of 'encoder.9' is out of range; expected encoder.1..8", 0), 0u)
      << lines[2];
  // A YAML syntax error (unquoted brackets inside braces) is one error with the parser's mark.
  const auto s = oegw::mapping::load_config_text(
      "upstream: { node_id: 0x20 }\ndownstream: {}\nsubdevices: {}\nfunctional_elements:\n"
      "  joystick.1: { buttons: right_grip.buttons[1..8] }\n",
      "syntax.yaml", gw::driver_catalogue());
  ASSERT_FALSE(s.ok());
  ASSERT_EQ(s.errors.size(), 1u) << s.error_text();
  EXPECT_EQ(s.errors[0].where.file, "syntax.yaml");
  EXPECT_EQ(s.errors[0].where.line, 5);
  EXPECT_GT(s.errors[0].where.column, 0);
  EXPECT_EQ(s.errors[0].str().rfind("syntax.yaml:5:", 0), 0u) << s.errors[0].str();
}

}  // namespace

namespace {

// ---- Proof of life and atomic outputs -----------------------------------------------------------

// Frames the gateway sent downstream on `id` since `from` (an index into downstream_), as text.
std::vector<std::string> frames_to(const std::vector<BusRecord>& records, std::size_t from, std::uint32_t id) {
  std::vector<std::string> out;
  for (std::size_t i = from; i < records.size(); ++i)
    if (records[i].sender == "gateway" && records[i].frame.id == id) out.push_back(records[i].frame.to_string());
  return out;
}

// Finding 1: the grip's heartbeat stops and never comes back, also after the gateway reset it.
// The reboot, configuration and NMT start are no proof of life: the fault stays (no EMCY 0000h),
// and the stick deflected afterwards never reaches the host.
TEST_F(GatewayE2E, AHeartbeatThatNeverReturnsAfterTheResetKeepsTheFaultAndTheStickNeutral) {
  build();
  boot_and_start();
  cmd("right_grip heartbeat off");
  run_for(400ms);  // consumer time 150 ms
  ASSERT_EQ(emcys(0x7000).size(), 1u) << dump();
  run_for(4s);  // retries: reset communication, boot-up, configuration, NMT start, no heartbeat
  EXPECT_GE(gw_->downstream().counters().gateway_resets, 2u) << "the first boot and a retry, answered\n" << log_;
  EXPECT_EQ(gw_->downstream().counters().reboots_seen, 0u) << "the gateway caused every boot-up\n" << log_;
  EXPECT_TRUE(emcys(0x0000).empty()) << "cleared without evidence\n" << dump();
  EXPECT_EQ(gw_->faults().count("right_grip"), 1u);
  EXPECT_NE(log_.find("right_grip: missing (no heartbeat in operational within 150 ms of NMT start)"),
            std::string::npos)
      << log_;
  const std::size_t seen = pdos(kTpdo1).size();
  cmd("right_grip x 50");
  run_for(5s);
  const auto after = pdos(kTpdo1);
  for (std::size_t i = seen; i < after.size(); ++i) EXPECT_EQ(i16(after[i], 0), 0) << after[i].to_string();
  EXPECT_EQ(field(kJoy1, "x"), 0);
  EXPECT_NE(gw_->status(kJoy1), FeStatus::Valid);
  EXPECT_TRUE(emcys(0x0000).empty()) << dump();
  // The heartbeat returns: that is the evidence; the stick must then be seen at zero first.
  cmd("right_grip heartbeat on");
  run_for(40s);  // the back-off has grown meanwhile (at most 30 s)
  ASSERT_EQ(gw_->downstream().state("right_grip"), sd::NodeState::Operational) << log_;
  EXPECT_EQ(emcys(0x0000).size(), 1u) << dump();
  EXPECT_NE(log_.find("right_grip: fault cleared (first heartbeat in operational after NMT start)"), std::string::npos)
      << log_;
  EXPECT_EQ(field(kJoy1, "x"), 0) << "held at neutral until the stick has been seen at zero";
  cmd("right_grip x 0");
  run_for(300ms);
  cmd("right_grip x 40");
  run_for(300ms);
  EXPECT_EQ(i16(*last(kTpdo1), 0), 13107);
}

// Finding 2: the MCB-402's pre-operational heartbeat crosses the gateway's NMT start on the bus
// (sent before the node saw the start, received after it was sent). That is not the node leaving
// operational: no fault, no EMCY, and joystick 2 goes live with the node's operational heartbeat.
TEST_F(GatewayE2E, APreOperationalHeartbeatThatCrossedTheNmtStartIsNoFault) {
  build();
  rig_->to_devices = [this](const CanFrame& f) {
    if (f.id == 0 && f.dlc == 2 && f.data[0] == 0x01 && f.data[1] == 0x03)
      (void)rig_->devices_port().send(CanFrame(0x703, {0x7F}));  // queued before the node acts on the start
    return false;
  };
  power_on();
  ASSERT_TRUE(all_operational()) << log_;
  host_configures_and_starts();
  run_for(500ms);
  EXPECT_TRUE(emcys(0x7000).empty()) << dump();
  EXPECT_TRUE(gw_->faults().empty()) << log_;
  EXPECT_EQ(log_.find("left operational"), std::string::npos) << log_;
  EXPECT_EQ(gw_->status(kJoy2), FeStatus::Valid);
}

// Finding 4: one host command changing several LEDs of the MCB-402 reaches it as one frame with
// the new state, never through states nobody commanded (00h -> 05h is not 01h then 05h).
TEST_F(GatewayE2E, OneHostCommandChangingSeveralLedsReachesTheMcb402AsOneFrame) {
  build();
  boot_and_start();
  bool host_alive = true;
  host_heartbeat_watched(host_alive);
  run_for(200ms);
  std::size_t from = downstream_.size();
  (void)host_port_->send(CanFrame(kRpdo5, {0x05, 0, 0, 0, 0, 0, 0, 0}));  // RPDO: 00h -> 05h
  run_for(100ms);
  EXPECT_EQ(frames_to(downstream_, from, 0x203), (std::vector<std::string>{"203#05"}));
  EXPECT_EQ(mcb_leds(), "1010");
  from = downstream_.size();
  ASSERT_EQ(sdo_write(0x6200, 0x09, {0x0A}), SdoAbortCode::None);  // SDO: 05h -> 0Ah
  run_for(100ms);
  EXPECT_EQ(frames_to(downstream_, from, 0x203), (std::vector<std::string>{"203#0A"}));
  EXPECT_EQ(mcb_leds(), "0101");
  // Several elobau LEDs from one RPDO: one RPDO #0 (211h) frame.
  from = downstream_.size();
  (void)host_port_->send(CanFrame(kRpdo6, {0x03, 0, 0, 0, 0, 0, 0, 0}));
  run_for(100ms);
  EXPECT_EQ(frames_to(downstream_, from, 0x211).size(), 1u);
  // The error values of a host heartbeat loss: 0Ah -> 05h in one frame.
  error_values(0x09, 0xFF, 0x05);
  from = downstream_.size();
  host_alive = false;
  run_for(500ms);
  ASSERT_EQ(emcys(0x8130).size(), 1u) << dump();
  EXPECT_EQ(frames_to(downstream_, from, 0x203), (std::vector<std::string>{"203#05"}));
}

// Finding 3, end to end: the host heartbeat stops while the sub-devices keep sending PDOs; the
// error values reach the MCB-402 at the consumer time, whichever frame or timer notices it.
TEST_F(GatewayE2E, HostHeartbeatLossUnderDownstreamLoadSetsTheErrorValuesAtTheDeadline) {
  build();
  boot_and_start();
  bool host_alive = true;
  host_heartbeat_watched(host_alive);
  error_values(0x09, 0xFF, 0x0A);
  (void)host_port_->send(CanFrame(kRpdo5, {0x05, 0, 0, 0, 0, 0, 0, 0}));
  run_for(300ms);
  ASSERT_EQ(mcb_leds(), "1010");
  host_alive = false;
  const TimePoint stopped = loop_.now();
  std::optional<TimePoint> applied;
  for (int i = 0; i < 600 && !applied; ++i) {
    cmd(fmt::format("right_grip x {}", i % 2 == 0 ? 10 : 20));  // a PDO load downstream
    run_for(1ms);
    if (mcb_leds() == "0101") applied = loop_.now();
  }
  ASSERT_TRUE(applied) << dump();
  ASSERT_EQ(emcys(0x8130).size(), 1u);
  // The last heartbeat came at most 100 ms before `stopped`; the consumer time is 250 ms.
  EXPECT_LE(*applied - stopped, 250ms + 2ms) << "error values late";
}

// PDOs stop while the heartbeat goes on (a firmware fault, a TPDO disabled by another tool): past
// the freshness deadline (3 x the 100 ms event timer) the stick is stale, at neutral, and the host
// is told; a fresh PDO is the evidence that clears it, and the stick passes the interlock.
TEST_F(GatewayE2E, PdosThatStopWhileTheHeartbeatGoesOnMakeTheJoystickStale) {
  build();
  boot_and_start();
  cmd("right_grip x 50");
  run_for(300ms);
  ASSERT_EQ(i16(*last(kTpdo1), 0), 16384);
  bool cut = true;
  drop_from_devices_ = [&cut](const CanFrame& f) { return cut && (f.id == 0x191 || f.id == 0x291); };
  run_for(200ms);
  EXPECT_EQ(field(kJoy1, "x"), 16384) << "within the deadline";
  run_for(200ms);
  EXPECT_EQ(gw_->downstream().state("right_grip"), sd::NodeState::Operational) << "its heartbeat goes on";
  EXPECT_EQ(field(kJoy1, "x"), 0);
  EXPECT_EQ(gw_->status(kJoy1), FeStatus::Stale);
  EXPECT_EQ(i16(*last(kTpdo1), 0), 0) << "the host read neutral";
  const auto e = emcys(0x7000);
  ASSERT_EQ(e.size(), 1u) << dump();
  EXPECT_EQ(e[0].msef[0], 0x11);
  EXPECT_NE(log_.find("right_grip: fault (x stale (no PDO for 300 ms))"), std::string::npos) << log_;
  cut = false;  // PDOs again, the stick still deflected
  run_for(300ms);
  EXPECT_EQ(gw_->status(kJoy1), FeStatus::Valid);
  EXPECT_EQ(emcys(0x0000).size(), 1u) << dump();
  EXPECT_NE(log_.find("right_grip: fault cleared (fresh PDO)"), std::string::npos) << log_;
  EXPECT_EQ(field(kJoy1, "x"), 0) << "neutral interlock";
  cmd("right_grip x 0");
  run_for(300ms);
  cmd("right_grip x 40");
  run_for(300ms);
  EXPECT_EQ(i16(*last(kTpdo1), 0), 13107);
}

// ---- Reloading the mapping file (gateway/reload.hpp) --------------------------------------------

std::string replaced(std::string yaml, const std::string& from, const std::string& to) {
  const auto at = yaml.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) yaml.replace(at, from.size(), to);
  return yaml;
}

// The largest gap between two of the gateway's heartbeats (700h + node-ID) on the host's bus.
Duration largest_heartbeat_gap(const std::vector<BusRecord>& up) {
  Duration most{0};
  std::optional<TimePoint> last;
  for (const auto& r : up) {
    if (r.frame.id != 0x700u + kGw.value()) continue;
    if (last) most = std::max(most, r.time - *last);
    last = r.time;
  }
  return most;
}

// A valid file under traffic: the upstream device goes on (no boot-up, still operational, its
// heartbeat every 1017h), every input at its fault value and every output at its error value
// in between, EMCY 6300h until the sub-devices, all booted again, are operational; then the new
// file's translation applies, after the stick has been seen at neutral as at a start.
TEST_F(GatewayE2E, AValidReloadKeepsTheUpstreamDeviceAndAppliesTheFileAsAStartDoes) {
  build();
  boot_and_start();
  ASSERT_EQ(sdo_write(0x6207, 0x09, {0x0A}), SdoAbortCode::None);  // indicators.2's error value: OUT1, OUT3
  ASSERT_EQ(sdo_write(0x6200, 0x09, {0x05}), SdoAbortCode::None);
  cmd("right_grip x 50");
  run_for(300ms);
  ASSERT_EQ(i16(*last(kTpdo1), 0), 16384);
  ASSERT_EQ(mcb_leds(), "1010");
  const std::size_t up_at = upstream_.size();
  const std::size_t down_at = downstream_.size();
  pdos_.clear();
  emcys_.clear();
  const TimePoint reloaded = loop_.now();
  ASSERT_THAT(reload([](std::string y) {
                return replaced(y, "x: { signal: right_grip.x, deadband: 2 }",
                                "x: { signal: right_grip.x, deadband: 2, invert: true }");
              }),
              ::testing::IsEmpty());
  run_for(1ms);
  // In between: the fault value in TPDO 1, the error value at the MCB-402 — sent before its NMT
  // reset communication —, EMCY 6300h (register bit 0), and no boot-up: the device goes on.
  ASSERT_TRUE(last(kTpdo1)) << dump();
  EXPECT_EQ(i16(*last(kTpdo1), 0), 0);
  EXPECT_EQ(mcb_leds(), "0101");
  std::optional<std::size_t> leds_at, reset_at;
  for (std::size_t i = down_at; i < downstream_.size(); ++i) {
    const CanFrame& f = downstream_[i].frame;
    if (!leds_at && f.id == 0x203 && f.data[0] == 0x0A) leds_at = i;
    if (!reset_at && f.id == 0x000 && f.data[0] == 0x82 && f.data[1] == 0x03) reset_at = i;
  }
  ASSERT_TRUE(leds_at && reset_at) << dump();
  EXPECT_LT(*leds_at, *reset_at);
  ASSERT_EQ(emcys(0x6300).size(), 1u) << dump();
  EXPECT_EQ(emcys(0x6300)[0].error_register, 0x01);
  EXPECT_EQ(gw_->upstream().node().state(), NmtState::Operational);
  EXPECT_TRUE(gw_->reloading());
  run_for(3s);
  ASSERT_TRUE(all_operational()) << log_;
  EXPECT_FALSE(gw_->reloading());
  ASSERT_FALSE(emcys(0x0000).empty()) << "6300h ends with the error reset\n" << dump();
  EXPECT_EQ(gw_->upstream().od().get<std::uint8_t>(0x1001, 0), 0u);
  EXPECT_EQ(mcb_leds(), "0101") << "the error value until the next command";
  for (std::size_t i = up_at; i < upstream_.size(); ++i)
    EXPECT_FALSE(upstream_[i].frame.id == 0x720 && upstream_[i].frame.data[0] == 0x00) << "a boot-up";
  EXPECT_LE(largest_heartbeat_gap(upstream_), 100ms);
  EXPECT_GT(upstream_.back().time - reloaded, 2s);
  // The new file: x inverted, once the stick has been seen at neutral.
  EXPECT_EQ(i16(*last(kTpdo1), 0), 0) << "held at neutral";
  cmd("right_grip x 0");
  run_for(300ms);
  cmd("right_grip x 50");
  run_for(300ms);
  EXPECT_EQ(i16(*last(kTpdo1), 0), -16384);
  ASSERT_EQ(sdo_write(0x6200, 0x09, {0x05}), SdoAbortCode::None);
  run_for(50ms);
  EXPECT_EQ(mcb_leds(), "1010");
}

// A file that would change the upstream device (here its node-ID and its FE set) is refused as
// a whole, each setting at its place: nothing changes on either bus.
TEST_F(GatewayE2E, AReloadThatWouldChangeTheUpstreamDeviceIsRefusedAndChangesNothing) {
  build();
  boot_and_start();
  cmd("right_grip x 50");
  run_for(300ms);
  ASSERT_EQ(i16(*last(kTpdo1), 0), 16384);
  const Gateway* before = gw_;
  const std::size_t down_at = downstream_.size();
  pdos_.clear();
  const auto refused = reload([](std::string y) {
    y = replaced(y, "node_id: 0x20", "node_id: 0x21");
    y = replaced(y, "downstream: { interface: virtual, bitrate: 250000 }",
                 "downstream: { interface: virtual, bitrate: 500000 }");
    return y + "  display.1: { \"parameter[1]\": \"cluster.aout[1]\" }\n";
  });
  ASSERT_EQ(refused.size(), 3u) << ::testing::PrintToString(refused);
  EXPECT_THAT(refused[0], ::testing::StartsWith("e2e.yaml:1:"));
  EXPECT_THAT(refused[0], ::testing::HasSubstr("upstream.node_id changed from 20h to 21h"));
  EXPECT_THAT(refused[0], ::testing::EndsWith("a reload cannot apply it, a restart can (systemctl restart oegw)"));
  EXPECT_THAT(refused[1], ::testing::StartsWith("e2e.yaml:7:"));
  EXPECT_THAT(refused[1], ::testing::HasSubstr("downstream.bitrate changed from 250000 to 500000"));
  EXPECT_THAT(refused[2], ::testing::HasSubstr("display.1 is new: it adds to the upstream device's dictionary"));
  EXPECT_EQ(gw_, before);
  cmd("right_grip x 40");  // live, neither held at neutral nor inverted: the same gateway
  run_for(300ms);
  ASSERT_TRUE(last(kTpdo1)) << dump();
  EXPECT_EQ(i16(*last(kTpdo1), 0), 13107);
  EXPECT_TRUE(emcys_.empty()) << dump();
  for (std::size_t i = down_at; i < downstream_.size(); ++i)
    EXPECT_NE(downstream_[i].frame.id, 0x000u) << "an NMT command: " << downstream_[i].to_string();
}

// A sub-device faulty before the reload stays faulty after it until its own evidence (its 7000h
// is not cleared by the reload, nor does it hold 6300h up); one the file no longer has is put in
// pre-operational and no longer watched.
TEST_F(GatewayE2E, AReloadKeepsAFaultUntilItsEvidenceAndReleasesADroppedSubDevice) {
  const std::string spare =
      "  spare:\n    driver: cia401\n    node_id: 0x32\n    options: { eds: " + std::string(OEGW_SOURCE_DIR) +
      "/subdevices/eds/button_cluster.eds }\n";
  build("",
        [&spare](std::string y) { return replaced(y, "functional_elements:\n", spare + "functional_elements:\n"); });
  boot_and_start();
  ASSERT_EQ(gw_->downstream().state("spare"), sd::NodeState::Operational) << log_;
  cmd("right_grip heartbeat off");
  run_for(400ms);
  ASSERT_EQ(emcys(0x7000).size(), 1u) << dump();
  emcys_.clear();
  const std::size_t down_at = downstream_.size();
  ASSERT_THAT(reload([&spare](std::string y) { return replaced(y, spare, ""); }), ::testing::IsEmpty());
  run_for(3s);
  bool preop = false;
  for (std::size_t i = down_at; i < downstream_.size(); ++i) {
    const CanFrame& f = downstream_[i].frame;
    preop = preop || (f.id == 0x000 && f.data[0] == 0x80 && f.data[1] == 0x32);
    EXPECT_FALSE(f.id == 0x000 && f.data[0] != 0x80 && f.data[1] == 0x32) << downstream_[i].to_string();
  }
  EXPECT_TRUE(preop) << dump();
  EXPECT_EQ(bench_->device("spare")->node().state(), NmtState::PreOperational);
  EXPECT_EQ(gw_->downstream().state("spare"), sd::NodeState::Idle);
  EXPECT_FALSE(gw_->reloading()) << "right_grip is faulty: it does not hold the reload's end up\n" << log_;
  EXPECT_EQ(gw_->faults().count("right_grip"), 1u) << log_;
  EXPECT_TRUE(gw_->upstream().node().emcy().active(0x7000));
  // The reload's end, 7000h still active: EMCY 0000h with the remaining register, naming nobody.
  ASSERT_EQ(emcys(0x0000).size(), 1u) << dump();
  EXPECT_EQ(emcys(0x0000)[0].error_register, 0x01);
  EXPECT_EQ(emcys(0x0000)[0].msef[0], 0x00) << "right_grip cleared without evidence";
  cmd("right_grip heartbeat on");
  run_for(40s);
  ASSERT_EQ(gw_->downstream().state("right_grip"), sd::NodeState::Operational) << log_;
  EXPECT_EQ(emcys(0x0000).size(), 2u) << dump();
  EXPECT_NE(log_.find("right_grip: fault cleared ("), std::string::npos) << log_;
  EXPECT_FALSE(gw_->upstream().node().emcy().active(0x7000));
}

}  // namespace
