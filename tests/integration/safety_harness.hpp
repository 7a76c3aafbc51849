// The bench of the safety tests (tier 2): one sub-device family behind the Gateway, on two
// virtual buses with a simulated clock, a host canopen::Master upstream, the invariant monitor
// (safety_monitor.hpp) on every frame of both buses, on every on_fe_change and on a 1 ms tick.
//
// Faults are injected through the simulators' public controls and by filtering frames in the
// bench's own wiring (nothing in subdevices/sim or the gateway is touched):
//   * device side: `dev_drop_all` (bus-off: nothing from or to the device), `dev_drop_tpdos`
//     (its TPDOs lost, the heartbeat goes on);
//   * gateway side: `gw_link_down` (the downstream interface down: nothing in or out; the
//     monitor then sees only what the gateway's interface carries, like the gateway);
//   * another master on the downstream bus (port "other") for foreign NMT commands;
//   * a one-shot trigger on the downstream tap, run before any receiver gets the frame, to inject
//     a fault at an exact protocol moment (the 2nd SDO request of the configuration, the NMT start).
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "canopen/master.hpp"
#include "gateway/gateway.hpp"
#include "rig/cab_rig.hpp"
#include "safety_monitor.hpp"
#include "subdevices/sim/cia401_sim.hpp"
#include "subdevices/sim/elobau_mfg_sim.hpp"
#include "subdevices/sim/mcb402_sim.hpp"
#include "subdevices/sim/novotechnik_406_sim.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "tests/fixtures/fixtures.hpp"

namespace oegw::testing::safety {

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using gateway::FeStatus;
using mapping::FeKind;
namespace sd = oegw::subdevices;
namespace sim = oegw::subdevices::sim;
using Bytes = std::vector<std::uint8_t>;

enum class FamilyId { Elobau, Mcb402, Novotechnik, Cia401Pedal, Cia401Cluster };
inline const char* name(FamilyId f) {
  switch (f) {
    case FamilyId::Elobau: return "Elobau";
    case FamilyId::Mcb402: return "Mcb402";
    case FamilyId::Novotechnik: return "Novotechnik406";
    case FamilyId::Cia401Pedal: return "Cia401Pedal";
    case FamilyId::Cia401Cluster: return "Cia401Cluster";
  }
  return "?";
}
inline constexpr FamilyId kFamilies[] = {FamilyId::Elobau, FamilyId::Mcb402, FamilyId::Novotechnik,
                                         FamilyId::Cia401Pedal, FamilyId::Cia401Cluster};

// A corner of a family's document
// (docs/design/device-documents.md#corners-every-reading-a-document-permits): a reading the
// document permits, as its simulator's options, and what the mapping file then says (the driver
// options commissioning finds: the MCB-402's button bits, the elobau's save). The matrix and the
// random scenarios run every family at each of its corners; together they hold every value of every
// simulator option of the family at least once.
struct Corner {
  std::string name;  // "Doc": the document's first reading (the simulator's defaults)
  std::vector<std::pair<std::string, std::string>> sim;
  std::vector<std::pair<std::string, std::string>> driver;
  bool sim_store = false;  // the simulator keeps a parameter store (1010h "save" works)
  // Periods of the device's TPDO until a channel mismatch is reported: an elobau grip sending on
  // its timer only shows the disagreeing TPDO #1 and the TPDO #0 that confirms it a cycle apart.
  int mismatch_periods = 1;
};
inline std::vector<Corner> corners(FamilyId id) {
  switch (id) {
    case FamilyId::Elobau:
      return {{"Doc", {{"tpdo", "change"}, {"saved", "yes"}, {"buttons", "63"}}, {}, false},
              {"Opposite",
               {{"tpdo", "timer"}, {"saved", "no"}, {"buttons", "255"}},
               {{"parameter_checksum", "save"}},
               true,
               2}};
    case FamilyId::Mcb402:
      return {{"Doc",
               {{"wiring", "1/2/3/4/5/7/6"}, {"clear_after_break", "0000h"}, {"power_on_1001h", "00h"}},
               {{"button_bits", "1,2,3,4,5,7,6"}},
               false},
              {"Opposite",
               {{"wiring", "0/1/2/3/4/6/5"}, {"clear_after_break", "none"}, {"power_on_1001h", "11h"}},
               {{"button_bits", "0,1,2,3,4,6,5"}},
               false}};
    case FamilyId::Novotechnik:
      return {{"Doc",
               {{"error_register_size", "1"},
                {"emcy_behaviour", "0"},
                {"has_6020h", "yes"},
                {"work_area_emcy", "bits"}},
               {},
               false},
              {"Opposite",
               {{"error_register_size", "2"}, {"emcy_behaviour", "3"}, {"has_6020h", "no"}, {"work_area_emcy", "enum"}},
               {},
               false},
              {"Emcy1", {{"emcy_behaviour", "1"}, {"has_6020h", "no"}}, {}, false},
              {"Emcy2", {{"emcy_behaviour", "2"}, {"error_register_size", "2"}}, {}, false}};
    case FamilyId::Cia401Pedal:
    case FamilyId::Cia401Cluster: return {{"Doc", {}, {}, false}};  // CiA 401 / CiA 306: no device document
  }
  return {};
}

// What a family looks like to the test: the mapping file, the tables the monitor gets, and how to
// move its input.
struct Family {
  FamilyId id;
  std::string yaml;  // the mapping file (tests/fixtures/safety_<family>.yaml)
  std::string dut;   // the sub-device's name
  std::uint8_t node = 0;
  FeId fe;                         // its input FE
  std::string primary;             // the FE field the cells follow ("x", "position", "switch[1]")
  std::int64_t live = 0;           // that field's FE value when deflect(true)
  bool interlock = false;          // the primary field passes the neutral interlock
  bool analog_fe = false;          // 6423h exists (joystick, pedal, wheel)
  std::uint16_t up_comm = 0x1800;  // the FE's TPDO communication index upstream
  std::uint32_t up_cob = 0;
  std::optional<FeId> out;  // indicator FE on the device (RPDO 1 upstream = 220h)
  std::uint64_t out_mask = 0;
  Duration pdo_period{0};        // the device's TPDO event timer (0: on change only)
  Duration pdo_deadline{0};      // 3 x that: contract point 2
  Duration pdo_deadline_max{0};  // the longest deadline of the device's TPDOs (MCB-402: buttons 300 ms)
  Knowledge knowledge;
};

inline constexpr std::uint8_t kGwNode = 0x20;
inline constexpr std::uint32_t kUpRpdo1 = 0x220;

inline Family make_family(FamilyId id) {
  Family f;
  f.id = id;
  auto bits = [](UpFe& fe, const std::string& base, std::size_t n, std::size_t byte, std::uint8_t node,
                 std::uint32_t source, std::size_t first = 1) {
    for (std::size_t k = 0; k < n; ++k)
      fe.fields.push_back({fmt::format("{}[{}]", base, first + k), byte, 1, static_cast<int>(k), 0, node, source});
  };
  switch (id) {
    case FamilyId::Elobau: {
      // elobau MFG: TPDO #0 180h+id (x, y, wheels, buttons), #1 280h+id (channel 2); cycle_ms 100
      // (the driver's default event timer) -> 300 ms. RPDO #0 200h+id, 2 bits per LED (Table 9/13).
      f.yaml = fixtures::mapping_file("safety_elobau.yaml");
      f.dut = "grip";
      f.node = 0x11;
      f.fe = {FeKind::Joystick, 1};
      f.primary = "x";
      f.live = 16384;  // 50 % of 32767
      f.interlock = true;
      f.analog_fe = true;
      f.up_comm = 0x1800;
      f.up_cob = 0x1A0;
      f.out = FeId{FeKind::IndicatorCluster, 1};
      f.out_mask = 0x03;
      f.pdo_period = 100ms;
      f.pdo_deadline = 300ms;
      f.pdo_deadline_max = 300ms;
      NodeKnowledge n{"grip", 0x11, 150ms, {{0x191, 300ms}, {0x291, 300ms}}};
      UpFe fe{f.fe, f.up_cob, {{"x", 0, 2, -1, 0, 0x11, 0x191}, {"y", 2, 2, -1, 0, 0x11, 0x191}}};
      bits(fe, "buttons", 6, 7, 0x11, 0x191);  // 2100h:01h default 63: the grip has buttons 1..6
      f.knowledge = {kGwNode, {n}, {fe}, {{*f.out, 0x11, 0x211, {{0, 0, 2}, {0, 2, 2}}}}};
      break;
    }
    case FamilyId::Mcb402: {
      // MCB-402: TPDO1 183h buttons (button_timer_ms 100 -> 300 ms), TPDO2 283h axes
      // (event_timer_ms 20 -> 60 ms, raised to the family's 200 ms freshness floor); RPDO1 203h
      // byte 0 bits 0..3 = OUT0..3.
      f.yaml = fixtures::mapping_file("safety_mcb402.yaml");
      f.dut = "grip";
      f.node = 0x03;
      f.fe = {FeKind::Joystick, 1};
      f.primary = "x";
      f.live = 10000;
      f.interlock = true;
      f.analog_fe = true;
      f.up_comm = 0x1800;
      f.up_cob = 0x1A0;
      f.out = FeId{FeKind::IndicatorCluster, 1};
      f.out_mask = 0x0F;
      f.pdo_period = 20ms;
      f.pdo_deadline = 200ms;
      f.pdo_deadline_max = 300ms;
      NodeKnowledge n{"grip", 0x03, 150ms, {{0x183, 300ms}, {0x283, 200ms}}};
      UpFe fe{f.fe,
              f.up_cob,
              {{"x", 0, 2, -1, 0, 0x03, 0x283}, {"y", 2, 2, -1, 0, 0x03, 0x283}, {"z", 4, 2, -1, 0, 0x03, 0x283}}};
      bits(fe, "buttons", 7, 7, 0x03, 0x183);
      f.knowledge = {kGwNode, {n}, {fe}, {{*f.out, 0x03, 0x203, {{0, 0, 1}, {0, 1, 1}, {0, 2, 1}, {0, 3, 1}}}}};
      break;
    }
    case FamilyId::Novotechnik: {
      // Novotechnik CiA 406: TPDO1 1FFh position (event_timer_ms 10 -> 30 ms, raised to the family's
      // 200 ms freshness floor). Encoder 1 = TPDO 28.
      f.yaml = fixtures::mapping_file("safety_novotechnik_406.yaml");
      f.dut = "knob";
      f.node = 0x7F;
      f.fe = {FeKind::Encoder, 1};
      f.primary = "position";
      f.live = 123456;
      f.interlock = false;  // a position, not an axis: no neutral interlock
      f.up_comm = 0x181B;
      f.up_cob = 0x2C0;
      f.pdo_period = 10ms;
      f.pdo_deadline = 200ms;
      f.pdo_deadline_max = 200ms;
      NodeKnowledge n{"knob", 0x7F, 150ms, {{0x1FF, 200ms}}};
      UpFe fe{f.fe, f.up_cob, {{"position", 0, 4, -1, 0, 0x7F, 0x1FF}}};
      f.knowledge = {kGwNode, {n}, {fe}, {}};
      break;
    }
    case FamilyId::Cia401Pedal: {
      // generic_pedal.eds: TPDO1 1B0h = 6401h:01, 6401h:02, 6000h:01, event timer 50 -> 150 ms,
      // raised to the family's 200 ms freshness floor. Pedal 1 = TPDO 20 (1813h): memory byte,
      // then position INTEGER16.
      f.yaml = fixtures::mapping_file("safety_cia401_pedal.yaml");
      f.dut = "pedal";
      f.node = 0x30;
      f.fe = {FeKind::FootPedal, 1};
      f.primary = "position";
      f.live = 20000;
      f.interlock = true;
      f.analog_fe = true;
      f.up_comm = 0x1813;
      f.up_cob = 0x2B0;
      f.pdo_period = 50ms;
      f.pdo_deadline = 200ms;
      f.pdo_deadline_max = 200ms;
      NodeKnowledge n{"pedal", 0x30, 150ms, {{0x1B0, 200ms}}};
      UpFe fe{f.fe, f.up_cob, {{"position", 1, 2, -1, 0, 0x30, 0x1B0}}};
      f.knowledge = {kGwNode, {n}, {fe}, {}};
      break;
    }
    case FamilyId::Cia401Cluster: {
      // button_cluster.eds: TPDO1 1B1h = 6000h:01, 6000h:02, event timer 0 (on change only: no
      // deadline); RPDO1 231h = 6200h:01, 6200h:02, 6411h:01. Cluster 1 = TPDO 34 (1821h).
      f.yaml = fixtures::mapping_file("safety_cia401_cluster.yaml");
      f.dut = "cluster";
      f.node = 0x31;
      f.fe = {FeKind::ButtonCluster, 1};
      f.primary = "switch[1]";
      f.live = 1;
      f.interlock = false;
      f.up_comm = 0x1821;
      f.up_cob = 0x2E0;
      f.out = FeId{FeKind::IndicatorCluster, 1};
      f.out_mask = 0xFF;
      NodeKnowledge n{"cluster", 0x31, 150ms, {{0x1B1, 0ms}, {0x2B1, 0ms}}};
      UpFe fe{f.fe, f.up_cob, {}};
      bits(fe, "switch", 8, 0, 0x31, 0x1B1);
      std::vector<OutBit> ob;
      for (unsigned k = 0; k < 8; ++k) ob.push_back({0, k, 1});
      f.knowledge = {kGwNode, {n}, {fe}, {{*f.out, 0x31, 0x231, ob}}};
      break;
    }
  }
  return f;
}

class Bench {
 public:
  // `corner`: the family's document reading to run at (corners(); default its first, "Doc").
  explicit Bench(FamilyId id, Monitor::Options mo = {}, std::optional<Corner> corner = std::nullopt)
      : fam_(make_family(id)), corner_(corner ? std::move(*corner) : corners(id).front()), mon_(fam_.knowledge, mo) {}
  Bench(const Bench&) = delete;
  Bench& operator=(const Bench&) = delete;
  ~Bench() {
    other_.reset();
    rig_.reset();
    for (const auto& p : {store_, sim_store_})
      if (!p.empty()) {
        std::filesystem::remove(p);
        std::filesystem::remove(std::filesystem::path(p.string() + ".lss"));
      }
  }

  // Builds everything; the device stays unpowered (silent) until power_device().
  void build() {
    auto loaded = mapping::load_config_text(fam_.yaml, "safety.yaml", gateway::driver_catalogue());
    ASSERT_TRUE(loaded.ok()) << loaded.error_text();
    config_ = std::move(*loaded.config);
    store_ = std::filesystem::path(::testing::TempDir()) /
             fmt::format("safety_{}_{}_{}.store", ::getpid(), name(fam_.id), reinterpret_cast<std::uintptr_t>(this));
    std::filesystem::remove(store_);
    // The corner: the driver options the mapping file says at it (replacing the file's), the
    // simulator's options (and its store, for a grip the gateway saves).
    auto& opts = config_.subdevices.front().options.values;
    for (const auto& [key, value] : corner_.driver) {
      std::erase_if(opts, [&key](const auto& kv) { return kv.first == key; });
      opts.emplace_back(key, value);
    }
    subdevices::DriverOptions sim_options{corner_.sim};
    if (corner_.sim_store) {
      sim_store_ = std::filesystem::path(store_.string() + ".device");
      std::filesystem::remove(sim_store_);
      sim_options.values.emplace_back("store", sim_store_.string());
    }
    // The cab of rig/cab_rig.hpp (the demo's and the e2e tests' harness), with this bench's
    // fault switches in its wiring and another master's port on the downstream bus.
    rig_ =
        std::make_unique<oegw::rig::CabRig>(config_, loop_,
                                            oegw::rig::CabRigOptions{.store = store_,
                                                                     .simulator_options = {{fam_.dut, sim_options}}});
    other_ = rig_->down().attach("other");
    rig_->from_devices = [this](const CanFrame& f) { return device_dropped(f); };
    rig_->to_devices = [this](const CanFrame&) { return dev_drop_all; };
    rig_->from_gateway_down = [this](const CanFrame& f) {
      if (!gw_link_down) return false;
      mon_.sent_into_dead_interface(f, loop_.now());
      lost_tx_.push_back({loop_.now(), "gateway", f});
      return true;
    };
    rig_->to_gateway_down = [this](const CanFrame&) { return gw_link_down; };
    rig_->on_gateway = [this](gateway::Gateway& g) {
      gw_ = &g;
      g.on_log = [this](const std::string& l) { log_ += fmt::format("[{:>7}] {}\n", ms(), l); };
      g.on_fe_change = [this](FeId fe) { mon_.on_sample(fe, *gw_, loop_.now()); };
    };
    try {
      rig_->build_devices();
    } catch (const std::runtime_error& e) {
      FAIL() << e.what();
    }
    bench_ = &rig_->devices();
    host_ = &rig_->host();
    host_port_ = &rig_->host_port();
    dev()->set_silent(true);
    rig_->connect_gateway();
    rig_->down().set_tap([this](const BusRecord& r) {
      if (trace_) trace_line("down", r);
      if (trigger_ && trigger_(r)) {
        trigger_ = {};
        if (on_trigger_) {
          auto action = std::move(on_trigger_);
          on_trigger_ = {};
          action(r.time);
          rig_->rearm();
        }
      }
      // What the gateway's interface carried: everything it sent (a frame of its own on the bus
      // left while the interface was up) and what it receives now (the flag as its receiver,
      // right after this tap, sees it).
      const bool from_gateway = r.sender == "gateway";
      if (from_gateway || !gw_link_down) mon_.on_downstream(r, from_gateway);
      if (r.sender == "gateway" && r.frame.id >= 0x200 && r.frame.id < 0x580) rpdos_.push_back(r);
    });
    rig_->up().set_tap([this](const BusRecord& r) {
      if (trace_) trace_line("up", r);
      mon_.on_upstream(r, *gw_);
      if (r.frame.id == 0x80u + kGwNode) up_emcys_.push_back(r);
    });
    mon_.context = [this] {
      return (context_ ? context_() : std::string()) +
             (trace_ ? "\nframes:\n" + trace_tail(trace_lines_) : std::string());
    };
    if (const char* tr = std::getenv("OEGW_SAFETY_TRACE")) {
      trace_ = true;
      trace_lines_ = std::max<std::size_t>(60, std::strtoul(tr, nullptr, 10));
    }
  }

  // Power on of the gateway; the host configures the upstream PDOs (and 6423h) and NMT-starts it.
  // The device stays off.
  void start_gateway() {
    t0_ = loop_.now();
    mon_.set_epoch(t0_);
    (void)gw_->start(loop_.now());
    loop_.call_every(loop_.now(), 1ms, [this] { mon_.tick(*gw_, loop_.now()); });
    run_for(10ms);
    enable_pdo(fam_.up_comm, fam_.up_cob);
    if (fam_.out) enable_pdo(0x1400, kUpRpdo1);
    if (fam_.analog_fe) {
      ASSERT_EQ(sdo_write(0x6423, 0, {1}), SdoAbortCode::None);
    }
    host_->nmt().start(NodeId{kGwNode});
    run_for(10ms);
    ASSERT_EQ(gw_->upstream().node().state(), NmtState::Operational);
  }
  void power_device() {
    dev()->set_silent(false);
    dev()->start(loop_.now());
    rig_->rearm();
  }

  void run_for(Duration d) { rig_->run_for(d); }
  // Runs in 1 ms steps until `done` (true) or `limit` passed (false).
  bool run_until(const std::function<bool()>& done, Duration limit) {
    const TimePoint end = loop_.now() + limit;
    while (loop_.now() < end) {
      if (done()) return true;
      run_for(1ms);
    }
    return done();
  }
  // The next downstream frame matching `match` runs `action` before anyone receives it.
  void on_next(std::function<bool(const BusRecord&)> match, std::function<void(TimePoint)> action) {
    trigger_ = std::move(match);
    on_trigger_ = std::move(action);
  }
  [[nodiscard]] bool trigger_pending() const { return static_cast<bool>(trigger_); }
  // Drops an armed trigger that has not fired (a scenario's end removes every fault).
  void cancel_trigger() {
    trigger_ = {};
    on_trigger_ = {};
  }

  // ---- Host side ----
  SdoAbortCode sdo_write(std::uint16_t index, std::uint8_t sub, Bytes data) {
    SdoAbortCode code = SdoAbortCode::GeneralError;
    bool done = false;
    host_->sdo(NodeId{kGwNode}).download(index, sub, std::move(data), [&](SdoAbortCode c, Bytes) {
      code = c;
      done = true;
    });
    for (int i = 0; i < 1000 && !done; ++i) run_for(1ms);
    EXPECT_TRUE(done) << fmt::format("SDO download {:04X}h:{:02X} never finished", index, sub);
    return code;
  }
  void enable_pdo(std::uint16_t comm, std::uint32_t cob) {
    ASSERT_EQ(sdo_write(comm, 1, encode<std::uint32_t>(cob)), SdoAbortCode::None) << fmt::format("{:04X}h", comm);
  }
  // The host commands indicators.1 (6200h:01) by SDO download or by RPDO 1; the monitor is told.
  void command_outputs(std::uint8_t bits, bool by_rpdo) {
    if (!fam_.out) return;
    mon_.commanded(*fam_.out, bits, loop_.now(), by_rpdo);
    if (by_rpdo) {
      (void)host_port_->send(CanFrame(kUpRpdo1, {bits, 0, 0, 0, 0, 0, 0, 0}));
    } else {
      EXPECT_EQ(sdo_write(0x6200, 0x01, {bits}), SdoAbortCode::None);
    }
  }
  void error_values(std::uint8_t mode, std::uint8_t value) {
    if (!fam_.out) return;
    mon_.error_config(*fam_.out, mode, value);
    EXPECT_EQ(sdo_write(0x6206, 0x01, {mode}), SdoAbortCode::None);
    EXPECT_EQ(sdo_write(0x6207, 0x01, {value}), SdoAbortCode::None);
  }
  // The host produces its heartbeat (701h, 100 ms) while host_alive, watched by the gateway (1016h:01, 250 ms).
  void host_heartbeat() {
    if (!fam_.out) return;  // CiA 852 Annex A: 1016h (the host's heartbeat watched) exists with outputs only
    host_hb_first = loop_.now();
    loop_.call_every(loop_.now(), 100ms, [this] {
      if (host_alive) (void)host_port_->send(CanFrame(0x701, {0x05}));
    });
    ASSERT_EQ(sdo_write(0x1016, 1, encode<std::uint32_t>(std::uint32_t{0x01} << 16 | 250)), SdoAbortCode::None);
  }
  // Another master on the downstream bus sends NMT `cs` to the device.
  void foreign_nmt(std::uint8_t cs) { (void)other_->send(CanFrame(0x000, {cs, fam_.node})); }
  // A frame as if the device had sent it (through the device-side filters).
  void device_frame(const CanFrame& f) { device_out(f); }

  // ---- Device side: operator motion and family faults ----
  sim::SimulatedDevice* dev() { return bench_->device(fam_.dut); }
  template <class T>
  T& as() {
    return dynamic_cast<T&>(*dev());
  }
  // The operator: the primary input deflected (and a button held) or released.
  void deflect(bool on) { move(on ? 1.0 : 0.0, on); }
  // level -1..1 of full deflection; `button` = the first button held (joysticks).
  void move(double level, bool button) {
    const TimePoint now = loop_.now();
    switch (fam_.id) {
      case FamilyId::Elobau: {
        (void)as<sim::ElobauMfgSim>().move_axis("x", static_cast<int>(level * 50), 0);
        if (button) {
          (void)as<sim::ElobauMfgSim>().press(1);
        } else {
          (void)as<sim::ElobauMfgSim>().release(1);
        }
        break;
      }
      case FamilyId::Mcb402:
        as<sim::Mcb402Sim>().move_axis(1, static_cast<std::int16_t>(level * 10000), now);
        as<sim::Mcb402Sim>().set_button(1, button, now);
        break;
      case FamilyId::Novotechnik:
        as<sim::Novotechnik406Sim>().set_position(static_cast<std::int32_t>(level * 123456), now);
        break;
      case FamilyId::Cia401Pedal:
        (void)dev()->set_input("analog[1]", static_cast<std::int64_t>(level * 20000), now);
        break;
      case FamilyId::Cia401Cluster:
        (void)dev()->set_input("in[1]", level > 0.5 ? 5 : (level < -0.5 ? 2 : 0), now);
        break;
    }
    rig_->rearm();
  }
  // The family's error EMCY (elobau 4001h 0001h, MCB-402 cable break X, Novotechnik measurement
  // error, CiA 401 1000h generic error) and its clearing.
  void error_emcy(bool on) {
    const TimePoint now = loop_.now();
    switch (fam_.id) {
      case FamilyId::Elobau:
        if (on) {
          as<sim::ElobauMfgSim>().raise_error(0x0001, now);
        } else {
          as<sim::ElobauMfgSim>().clear_error(0x0001, now);
        }
        break;
      case FamilyId::Mcb402: as<sim::Mcb402Sim>().cable_break(1, on, now); break;
      case FamilyId::Novotechnik:
        if (on) {
          as<sim::Novotechnik406Sim>().inject_fault(sim::Novotechnik406Sim::Fault::Measurement, now);
        } else {
          (void)as<sim::Novotechnik406Sim>().clear_fault(now);
        }
        break;
      case FamilyId::Cia401Pedal:
      case FamilyId::Cia401Cluster:
        if (on) {
          (void)dev()->node().emcy().raise(0x1000, 0x01, now);
        } else {
          (void)dev()->node().emcy().clear(0x1000, now);
        }
        break;
    }
    rig_->rearm();
  }
  // Error / not-available codes in the PDO (elobau 126 / 127 on x channel 1, Novotechnik
  // 7FFFFFFCh); `restore` puts the real value back.
  bool has_error_value() const { return fam_.id == FamilyId::Elobau || fam_.id == FamilyId::Novotechnik; }
  bool has_not_available() const { return fam_.id == FamilyId::Elobau; }
  bool has_mismatch() const { return fam_.id == FamilyId::Elobau; }
  void error_value(bool on, bool not_available = false, std::uint32_t marker = 0x7FFFFFFC) {
    const TimePoint now = loop_.now();
    if (fam_.id == FamilyId::Elobau) {
      using F = sim::ElobauMfgSim::Fault;
      (void)as<sim::ElobauMfgSim>().inject("x", on ? (not_available ? F::NotAvailable : F::Error) : F::None, 1);
    } else if (fam_.id == FamilyId::Novotechnik) {
      auto& n = as<sim::Novotechnik406Sim>();
      if (on) {
        n.inject_error_position(marker, now);
      } else {
        // The simulator keeps an injected raw value until a power cycle (no other public
        // control undoes it): the sensor is power-cycled.
        n.reboot(now);
      }
    }
    rig_->rearm();
  }
  void mismatch(bool on, int percent = 50) {
    (void)as<sim::ElobauMfgSim>().move_axis("x", percent, on ? 20 : 0);
    rig_->rearm();
  }
  // After a bus-off: the device's own EMCY where its document has one (elobau 8140h with the
  // count and the zero-position rule; MCB-402 8140h; Novotechnik 8140h; CiA 301 8140h for the
  // generic node, followed by its error reset).
  void bus_off_recovered() {
    const TimePoint now = loop_.now();
    switch (fam_.id) {
      case FamilyId::Elobau:
        as<sim::ElobauMfgSim>().bus_off(now);
        if (dev()->silent()) {  // past 5001h: off-line until power-cycled
          dev()->reboot(now);
          dev()->set_silent(false);
        }
        break;
      case FamilyId::Mcb402: as<sim::Mcb402Sim>().bus_off_recovered(now); break;  // "40 81 11 ..."
      case FamilyId::Cia401Pedal:
      case FamilyId::Cia401Cluster:
        (void)dev()->node().emcy().raise(0x8140, 0x11, now);
        (void)dev()->node().emcy().clear(0x8140, now);
        break;
      case FamilyId::Novotechnik: as<sim::Novotechnik406Sim>().send_emcy(0x8140, 0, 0, {0, 0, 0, 0}, now); break;
    }
    rig_->rearm();
  }

  // ---- Accessors ----
  [[nodiscard]] const Family& fam() const { return fam_; }
  [[nodiscard]] const Corner& corner() const { return corner_; }
  Monitor& mon() { return mon_; }
  gateway::Gateway& gw() { return *gw_; }
  EventLoop& loop() { return loop_; }
  [[nodiscard]] TimePoint now() const { return loop_.now(); }
  [[nodiscard]] long ms() const { return ms_at(loop_.now()); }
  [[nodiscard]] long ms_at(TimePoint t) const {
    return static_cast<long>(std::chrono::duration_cast<std::chrono::milliseconds>(t - t0_).count());
  }
  [[nodiscard]] std::int64_t field(const std::string& n) const {
    for (const auto& f : gw_->fields(fam_.fe))
      if (f.name == n) return f.value;
    return -999999;
  }
  [[nodiscard]] bool all_neutral() const {
    for (const auto& f : gw_->fields(fam_.fe))
      if (f.value != 0) return false;
    return true;
  }
  [[nodiscard]] FeStatus status() const { return gw_->status(fam_.fe); }
  [[nodiscard]] sd::NodeState node_state() const { return gw_->downstream().state(fam_.dut); }
  [[nodiscard]] const std::string& log() const { return log_; }
  [[nodiscard]] std::string trace() const { return trace_text_; }
  void set_trace(bool on) { trace_ = on; }
  [[nodiscard]] std::string trace_tail(std::size_t lines) const {
    std::size_t pos = trace_text_.size();
    for (std::size_t n = 0; n < lines && pos > 1; ++n) {
      const auto p = trace_text_.rfind('\n', pos - 2);
      pos = p == std::string::npos ? 0 : p + 1;
    }
    return trace_text_.substr(pos);
  }
  void set_context(std::function<std::string()> c) { context_ = std::move(c); }
  [[nodiscard]] std::string tail(std::size_t lines = 40) const {
    std::size_t pos = log_.size();
    for (std::size_t n = 0; n < lines && pos > 1; ++n) {
      const auto p = log_.rfind('\n', pos - 2);
      pos = p == std::string::npos ? 0 : p + 1;
    }
    return log_.substr(pos);
  }

  // The gateway's RPDOs downstream and its EMCYs upstream, as delivered.
  [[nodiscard]] const std::vector<BusRecord>& rpdos() const { return rpdos_; }
  [[nodiscard]] const std::vector<BusRecord>& up_emcys() const { return up_emcys_; }
  // What the gateway sent while its downstream interface was down (lost).
  [[nodiscard]] const std::vector<BusRecord>& lost_tx() const { return lost_tx_; }
  // Feeds a frame to the gateway's downstream side directly (sans I/O), as its interface would.
  void gateway_receives(const CanFrame& f) {
    gw_->on_downstream_frame(f, loop_.now());
    rig_->rearm();
  }

  // Fault switches of the wiring.
  bool dev_drop_all = false;                  // bus-off: nothing from/to the device
  bool dev_drop_tpdos = false;                // its TPDOs are lost
  std::optional<std::uint32_t> dev_drop_cob;  // the device's frames on this COB-ID are lost
  bool gw_link_down = false;                  // the gateway's downstream interface is down
  bool host_alive = true;
  TimePoint host_hb_first{};  // the host's heartbeats go at host_hb_first + k x 100 ms

 private:
  // True when the device's frame is lost on its way to the bus.
  bool device_dropped(const CanFrame& f) const {
    if (dev_drop_all) return true;
    if (dev_drop_tpdos && ((f.id >= 0x181 && f.id <= 0x4FF) && (f.id & 0x7F) == fam_.node)) return true;
    return dev_drop_cob && f.id == *dev_drop_cob;
  }
  void device_out(const CanFrame& f) {
    if (!device_dropped(f)) (void)rig_->devices_port().send(f);
  }
  void trace_line(const char* bus, const BusRecord& r) {
    trace_text_ += fmt::format("[{:>7}] {:4} {}\n", ms_at(r.time), bus, r.to_string());
  }

  Family fam_;
  Corner corner_;
  Monitor mon_;
  mapping::Config config_;
  SimulatedClock clock_;
  EventLoop loop_{clock_};
  TimePoint t0_{};
  std::filesystem::path store_;
  std::filesystem::path sim_store_;  // the simulator's parameter store (Corner::sim_store)
  std::unique_ptr<oegw::rig::CabRig> rig_;
  std::unique_ptr<VirtualPort> other_;  // another master on the downstream bus
  // Into rig_:
  sim::SimBench* bench_ = nullptr;
  Master* host_ = nullptr;
  VirtualPort* host_port_ = nullptr;
  gateway::Gateway* gw_ = nullptr;
  std::function<bool(const BusRecord&)> trigger_;
  std::function<void(TimePoint)> on_trigger_;
  std::function<std::string()> context_;
  std::string log_;
  std::vector<BusRecord> rpdos_, up_emcys_, lost_tx_;
  bool trace_ = false;
  std::size_t trace_lines_ = 60;
  std::string trace_text_;
};

}  // namespace oegw::testing::safety
