// The whole gateway's run-time state (Gateway::export_state, canopen/state.hpp) on the simulated
// cab of the demo (tests/fixtures/demo_cab.yaml) through an incident: the host's configuration
// and heartbeat, sweeps of every input, commands from every source (one refused, the LEDs'
// watchdog expiring), the host reaching a grip through the gateway (remote SDO, one write
// refused), the downstream interface down, the right grip's cable pulled and plugged back, an
// MCB-402 cable break, the host's heartbeat lost, its NMT commands and resets while a
// sub-device is faulty, the grip rebooted. At quiet moments a fork is
// taken: a new gateway of the same mapping file, not started, is given the running one's state
// and from then on the same inputs (every frame, bus event, time step and command, as the black
// box records them). Everything it then sends, logs and decides must be what the running gateway
// does, to the frame; a gateway given no state, or an older one, must differ.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/state.hpp"
#include "gateway/control/status_report.hpp"
#include "gateway/gateway.hpp"
#include "gateway/gateway_tap.hpp"
#include "rig/cab_rig.hpp"
#include "tests/fixtures/fixtures.hpp"
#include "tests/integration/cab_steps.hpp"
#include "tests/unit/canopen/state_twin.hpp"

namespace oegw::gateway {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using canopen::CanFrame;
using canopen::TimePoint;
using oegw::testing::cab_command;
using oegw::testing::host_sdo_write;
using oegw::testing::sweep;

constexpr canopen::NodeId kGw{0x20};

std::string frame_text(const CanFrame& f) {
  std::string s = fmt::format("{:03X}{}", f.id, f.rtr ? " R" : "");
  for (std::uint8_t b : f.payload()) s += fmt::format(" {:02X}", b);
  return s;
}

// What one gateway sends, logs and decides, one line each, in order.
class Capture : public GatewayTap {
 public:
  std::vector<std::string> lines;
  void sent(const Gateway&, Bus bus, const CanFrame& f) override {
    lines.push_back(std::string(bus == Bus::Up ? "up " : "down ") + frame_text(f));
  }
  void command_outcome(bool taken, std::string_view why) override {
    lines.push_back(fmt::format("outcome {} {}", taken, why));
  }
  void node_state(const std::string& name, subdevices::NodeState st, const std::string& why) override {
    lines.push_back(fmt::format("node {} {} {}", name, subdevices::to_string(st), why));
  }
  void fault(const std::string& name, bool raised, std::string_view text) override {
    lines.push_back(fmt::format("fault {} {} {}", name, raised, text));
  }
  void subdevice_emcy(const std::string& name, const canopen::EmcyMessage& e) override {
    lines.push_back(fmt::format("emcy {} {:04X}", name, e.code));
  }
  void fe_changed(const Gateway& gw, mapping::FeId fe) override {
    std::string s = fmt::format("fe {} {} {}", mapping::fe_name(fe), static_cast<int>(gw.status(fe)),
                                gw.model().source_time(fe).time_since_epoch().count());
    for (const auto& f : gw.fields(fe)) {
      s += fmt::format(" {}={}/{}{}", f.name, f.value, subdevices::to_string(f.status), f.interlocked ? "/i" : "");
    }
    lines.push_back(s);
  }
  void logged(const std::string& line) override { lines.push_back("log " + line); }
};

// A forked gateway: its own capture, fed every input the running one gets from the fork on.
struct Shadow {
  Capture capture;
  std::unique_ptr<Gateway> gw;
  std::size_t from = 0;  // the running gateway's capture at the fork
  std::string at;        // where the fork was taken, for the report
  bool control = false;  // given no state or an older one: must differ
};

// The running gateway's tap: its capture, and every input handed to the shadows too.
class Fork : public Capture {
 public:
  std::vector<std::unique_ptr<Shadow>> shadows;
  const Gateway* running = nullptr;
  void received(Bus bus, const CanFrame& f, TimePoint t) override {
    each([&](Gateway& g) { (void)(bus == Bus::Up ? g.on_upstream_frame(f, t) : g.on_downstream_frame(f, t)); });
  }
  void bus_event(Bus bus, canopen::BusEvent e, TimePoint now) override {
    each([&](Gateway& g) {
      if (bus == Bus::Up) {
        g.on_upstream_bus_event(e, now);
      } else {
        g.on_downstream_bus_event(e, now);
      }
    });
  }
  void advanced(TimePoint now) override {
    each([&](Gateway& g) { g.advance(now); });
  }
  void indicators(std::uint8_t instance, std::uint64_t bits, mapping::CommandSource source, TimePoint now) override {
    each([&](Gateway& g) { (void)g.command_indicators(instance, bits, now, source); });
  }
  void display(std::uint8_t instance, const std::array<std::int16_t, 12>& p, mapping::CommandSource source,
               TimePoint now) override {
    each([&](Gateway& g) { (void)g.command_display(instance, p, now, source); });
  }
  void subdevice_command(const std::string& name, std::string_view command, TimePoint now) override {
    each([&](Gateway& g) { (void)g.subdevice_command(name, command, now); });
  }
  void downstream_nmt(canopen::NodeId node, canopen::NmtCommand cs, TimePoint now) override {
    each([&](Gateway& g) { (void)g.downstream_nmt(node, cs, now); });
  }

 private:
  template <class F>
  void each(F&& f) {
    for (auto& s : shadows) {
      // Each input comes when the two have handled the last one alike: the same deadline and
      // the same faults reported (`oegw status`).
      if (running != nullptr && s->gw->next_deadline() != running->next_deadline()) {
        s->capture.lines.push_back("deadline differs");
      }
      if (running != nullptr && s->gw->faults() != running->faults()) s->capture.lines.push_back("faults differ");
      f(*s->gw);
    }
  }
};

std::string state_of(const Gateway& gw) {
  canopen::StateWriter w;
  gw.export_state(w);
  return w.text();
}

class GatewayState : public ::testing::Test {
 protected:
  void SetUp() override {
    char tmpl[] = "/tmp/oegw-gateway-state-test-XXXXXX";
    dir_ = ::mkdtemp(tmpl);
    config_ = oegw::testing::fixture_config("demo_cab.yaml");
    // The left grip's LEDs on a watchdog (CommandArbiter): it expires in the incident.
    for (auto& fe : config_.functional_elements) {
      if (mapping::fe_name(fe.id) == "indicators.2") fe.command_timeout_ms = 1500;
    }
    build_rig({});
  }
  // The cab; `sdo_latency`: each simulator's SDO answer that much later (else at once).
  void build_rig(std::optional<canopen::Duration> sdo_latency) {
    if (gw_ != nullptr) gw_->set_tap(nullptr);
    rig_ = std::make_unique<rig::CabRig>(config_, loop_,
                                         rig::CabRigOptions{.store = dir_ / "upstream.store",
                                                            .device_sdo_latency = sdo_latency});
    rig_->on_gateway = [this](Gateway& g) {
      gw_ = &g;
      fork_.running = &g;
      g.set_tap(&fork_);
    };
    rig_->from_devices = [this](const CanFrame& f) { return silent_ || (pulled_ && (f.id & 0x7F) == 0x11); };
    rig_->build();
  }
  void TearDown() override {
    if (gw_ != nullptr) gw_->set_tap(nullptr);
    rig_.reset();
    fork_.shadows.clear();
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  // A gateway of the same file and options, on its own copy of the parameter store, sending
  // nowhere; given the running one's state, or as a control `given` (empty: no state at all).
  void fork(const std::string& at, const std::optional<std::string>& given = std::nullopt) {
    for (int i = 0; i < 1000 && !gw_->busy().empty(); ++i) rig_->run_for(1ms);
    ASSERT_EQ(gw_->busy(), "") << at;
    auto s = std::make_unique<Shadow>();
    s->at = at;
    s->control = given.has_value();
    s->from = fork_.lines.size();
    GatewayOptions options = rig_->gateway_options();
    options.store_path = dir_ / fmt::format("shadow{}.store", fork_.shadows.size());
    std::error_code ec;
    fs::copy_file(dir_ / "upstream.store", *options.store_path, ec);  // none before a save
    s->gw = std::make_unique<Gateway>(
        config_, [](const CanFrame&) {}, [](const CanFrame&) {}, options);
    if (!given || !given->empty()) {
      const std::string state = given ? *given : state_of(*gw_);
      const canopen::StateReader r = canopen::StateReader::parse(state);
      s->gw->import_state(r);
      EXPECT_THAT(r.unread(), ::testing::IsEmpty()) << at;
      EXPECT_EQ(state_of(*s->gw), state) << at << ": a round trip changes the state";
    }
    s->gw->set_tap(&s->capture);
    fork_.shadows.push_back(std::move(s));
  }

  // The running gateway's lines since a fork, against the shadow's.
  static std::vector<std::string> since(const std::vector<std::string>& lines, std::size_t from) {
    return {lines.begin() + static_cast<std::ptrdiff_t>(from), lines.end()};
  }

  fs::path dir_;
  mapping::Config config_;
  canopen::io::SimulatedClock clock_;
  canopen::io::EventLoop loop_{clock_};
  std::unique_ptr<rig::CabRig> rig_;
  Fork fork_;
  Gateway* gw_ = nullptr;
  bool pulled_ = false;  // the right grip's cable
  bool silent_ = false;  // the downstream bus
  bool host_alive_ = true;
};

TEST_F(GatewayState, AForkGivenTheStateDoesWhatTheRunningGatewayDoesThroughAnIncident) {
  rig_->power_on();
  rig_->run_for(3s);
  fork("after the boot");
  fork("after the boot, given no state", "");
  const std::string after_boot = state_of(*gw_);
  loop_.call_every(loop_.now(), 100ms, [this] {
    if (host_alive_) (void)rig_->host_port().send(CanFrame(0x701, {0x05}));
  });
  const auto configure = [&] {  // the host's configuration of the gateway, and its start
    host_sdo_write(*rig_, kGw, 0x1800, 1, {0xA0, 0x01, 0x00, 0x00});  // TPDO 1 on 1A0h
    host_sdo_write(*rig_, kGw, 0x6423, 0, {1});
    host_sdo_write(*rig_, kGw, 0x1016, 1, {0xFA, 0x00, 0x01, 0x00});
    rig_->host().nmt().start(kGw);
  };
  configure();
  sweep(*rig_, 1s);
  fork("operational, the inputs moving");
  // A state, but not this moment's: the host's configuration and NMT start are missing.
  fork("operational, given the state after the boot", after_boot);
  // The host reaches the right grip through the gateway (remote SDO): a network indication
  // redirects the gateway's SDO server (CiA 302-7), a read passes, a write of an object
  // the gateway configured is refused and counted; a sub-device command the driver does not
  // know is refused and counted.
  (void)rig_->host_port().send(CanFrame(0x620, {0xE0, 0, 0, 0, 2, 0x11, 0, 0}));
  rig_->run_for(5ms);
  int answers = 0;
  rig_->host().sdo(kGw).upload(0x1018, 1, [&](canopen::SdoAbortCode, std::vector<std::uint8_t>) { ++answers; });
  sweep(*rig_, 200ms);
  rig_->host().sdo(kGw).download(0x1800, 1, {0x91, 0x01, 0x00, 0x00},
                                 [&](canopen::SdoAbortCode, std::vector<std::uint8_t>) { ++answers; });
  sweep(*rig_, 200ms);
  ASSERT_EQ(answers, 2);
  (void)gw_->subdevice_command("seat_knob", "no_such_command", loop_.now());
  // Another node of the host's bus reports an error (1028h: logged, kept for `oegw status`).
  (void)rig_->host_port().send(CanFrame(0x085, {0x00, 0x10, 0x01, 1, 2, 3, 4, 5}));
  rig_->run_for(5ms);
  fork("a remote SDO redirect in force");
  (void)rig_->host_port().send(CanFrame(0x620, {0xE0, 0, 0, 0, 0, 0, 0, 0}));  // back to the gateway
  sweep(*rig_, 200ms);
  // The downstream interface down (its link lost): EMCY until a frame is received again, and
  // again after the host resets the gateway meanwhile.
  silent_ = true;
  gw_->on_downstream_bus_event(canopen::BusEvent::InterfaceDown, loop_.now());
  rig_->rearm();
  rig_->run_for(50ms);
  fork("the downstream interface down");
  rig_->host().nmt().reset_node(kGw);
  rig_->run_for(20ms);
  silent_ = false;
  configure();  // the reset took the host's configuration
  sweep(*rig_, 2s);
  (void)gw_->command_indicators(2, 0x05, loop_.now(), mapping::CommandSource::Dds);
  (void)gw_->command_indicators(2, 0x0A, loop_.now(), mapping::CommandSource::Lcm);
  (void)gw_->subdevice_command("seat_knob", "position_error_reset", loop_.now());
  rig_->rearm();
  sweep(*rig_, 1s);
  pulled_ = true;  // the right grip's cable
  sweep(*rig_, 1500ms);
  fork("the right grip missing");
  pulled_ = false;
  sweep(*rig_, 3s);
  cab_command(*rig_, "left_grip cable_break 2 on");
  sweep(*rig_, 500ms);
  fork("a cable break latched");
  // Refused again: logged once, before the fork.
  (void)gw_->command_indicators(2, 0x0A, loop_.now(), mapping::CommandSource::Lcm);
  cab_command(*rig_, "left_grip cable_break 2 off");
  sweep(*rig_, 1s);
  host_alive_ = false;
  sweep(*rig_, 600ms);
  fork("the host's heartbeat lost");
  host_alive_ = true;
  sweep(*rig_, 1s);
  rig_->host().nmt().start(kGw);  // its heartbeat's loss left the gateway pre-operational (1029h)
  // Indicators lit again (the heartbeat's loss gave them their error values).
  (void)gw_->command_indicators(2, 0x05, loop_.now(), mapping::CommandSource::Dds);
  rig_->rearm();
  sweep(*rig_, 500ms);
  // The host's NMT commands while a sub-device is faulty: the inputs come back after each reset,
  // the fault is reported again (OeDevice::after_reset) and a reset node's defaults reach the
  // outputs.
  cab_command(*rig_, "left_grip cable_break 2 on");
  sweep(*rig_, 300ms);
  fork("a fault held, before the host's resets");
  rig_->host().nmt().enter_pre_operational(kGw);
  sweep(*rig_, 200ms);
  rig_->host().nmt().reset_communication(kGw);
  sweep(*rig_, 500ms);
  rig_->host().nmt().reset_node(kGw);
  sweep(*rig_, 500ms);
  rig_->host().nmt().start(kGw);
  cab_command(*rig_, "left_grip cable_break 2 off");
  sweep(*rig_, 1s);
  cab_command(*rig_, "right_grip reboot");
  sweep(*rig_, 4s);
  for (int i = 0; i < 1000 && !gw_->busy().empty(); ++i) rig_->run_for(1ms);
  ASSERT_EQ(gw_->busy(), "");
  const std::string end = state_of(*gw_);

  for (const auto& s : fork_.shadows) {
    const std::vector<std::string> running = since(fork_.lines, s->from);
    ASSERT_GT(running.size(), 100u) << s->at;
    if (s->control) {
      EXPECT_NE(s->capture.lines, running) << s->at;
      // (It may be busy where the running one is not: a boot of its own under way.)
      if (s->gw->busy().empty()) {
        EXPECT_NE(state_of(*s->gw), end) << s->at;
      }
      continue;
    }
    // The first difference, with its neighbourhood, is the report.
    const auto [mine, theirs] =
        std::mismatch(s->capture.lines.begin(), s->capture.lines.end(), running.begin(), running.end());
    const auto index = static_cast<std::size_t>(mine - s->capture.lines.begin());
    EXPECT_TRUE(mine == s->capture.lines.end() && theirs == running.end())
        << s->at << ": differs at line " << index << " of " << running.size()
        << ":\n  fork:    " << (mine != s->capture.lines.end() ? *mine : "(end)")
        << "\n  running: " << (theirs != running.end() ? *theirs : "(end)");
    // And the state they end in (also what no output shows yet: counters, reasons), and what
    // `oegw status` reports of each.
    EXPECT_EQ(state_of(*s->gw), end) << s->at;
    const control::StatusContext at{loop_.now(), TimePoint{}};
    const nlohmann::json patch =
        nlohmann::json::diff(control::status_report(*gw_, config_, at), control::status_report(*s->gw, config_, at));
    EXPECT_TRUE(patch.empty()) << s->at << ": oegw status differs: " << patch.dump();
  }
}

// A state holds no request on the wire: while the sub-devices are booted none is taken, and
// busy() says why.
TEST_F(GatewayState, ABootUnderWayIsNoState) {
  build_rig(5ms);
  rig_->power_on();
  std::string why;
  for (int i = 0; i < 1000 && why.empty(); ++i) {
    rig_->run_for(1ms);
    why = gw_->busy();
  }
  EXPECT_NE(why.find(": configuring (an SDO request on the wire or held)"), std::string::npos) << why;
  canopen::StateWriter w;
  try {
    gw_->export_state(w);
    ADD_FAILURE() << "exported";
  } catch (const std::logic_error& e) {
    EXPECT_EQ(std::string(e.what()), "Gateway::export_state: " + why);
  }
  rig_->run_for(3s);
  EXPECT_EQ(gw_->busy(), "");
}

// A sub-device's fault text without its cause, or the reverse, is no run's. The texts may be long
// (a refused boot names every write), but not without bound.
TEST_F(GatewayState, AStateNoRunLeavesIsRefusedNamingTheKey) {
  rig_->power_on();
  rig_->run_for(3s);
  ASSERT_EQ(gw_->busy(), "");
  const std::string state = state_of(*gw_);
  const auto refusal = [&](const std::string& key, const std::string& value) {
    Gateway g(
        config_, [](const CanFrame&) {}, [](const CanFrame&) {}, rig_->gateway_options());
    return canopen::test_support::refusal(g, canopen::test_support::with_value(state, key, value));
  };
  const auto hex_text = [](std::size_t n) { return "#" + std::string(2 * n, '7'); };  // "www..."
  EXPECT_EQ(refusal("subdevices.0.cause.kind", "1"), "state: 'subdevices.0.fault' differs from the fault's cause");
  EXPECT_EQ(refusal("subdevices.0.cause.status", "5"), "state: 'subdevices.0.cause.status' is no signal status");
  EXPECT_EQ(refusal("bindings.0.status", "7"), "state: 'bindings.0.status' is no signal status");
  EXPECT_EQ(refusal("subdevices.0.why", hex_text(600)), "accepted");
  EXPECT_EQ(refusal("subdevices.0.why", hex_text(64 * 1024 + 1)),
            "state: 'subdevices.0.why' is longer than 65536 bytes");
}

// A gateway of another mapping file refuses the state, naming where it differs.
TEST_F(GatewayState, AStateOfAnotherMappingFileIsRefused) {
  rig_->power_on();
  rig_->run_for(3s);
  ASSERT_EQ(gw_->busy(), "");
  const std::string state = state_of(*gw_);
  mapping::Config other = config_;
  other.functional_elements.pop_back();
  Gateway g(
      other, [](const CanFrame&) {}, [](const CanFrame&) {}, rig_->gateway_options());
  const std::string refusal = canopen::test_support::refusal(g, state);
  EXPECT_EQ(refusal, "state: 'device.outputs.count' = 24 is above 16");  // without indicators.3's entries
}

}  // namespace
}  // namespace oegw::gateway
