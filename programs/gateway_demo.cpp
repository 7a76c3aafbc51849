// `oegw demo`: the whole gateway on the in-process virtual bus, in real time. Downstream, the
// simulated cab devices of config/demo.yaml (an elobau grip, an MCB-402, a pedal, an encoder,
// a button cluster with lamps) with an operator moving them; the gateway in the middle; upstream,
// a built-in host controller (a CANopen master) that configures the gateway's PDOs, starts it
// and reads the joystick from its TPDOs. Then a grip cable is pulled and plugged back.
#include "programs/gateway_demo.hpp"

#include <sys/ioctl.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <string_view>

#include <fmt/format.h>

#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "gateway/gateway.hpp"
#include "gateway/programs.hpp"
#include "gateway/publishing.hpp"
#include "programs/demo_files.hpp"
#include "programs/live_view.hpp"
#include "publish/dds_publisher.hpp"
#include "rig/cab_rig.hpp"
#include "subdevices/sim/sim_bench.hpp"

namespace oegw::programs {

using namespace gateway;  // the programs compose the daemon's library

using namespace canopen;
using namespace canopen::io;
using namespace std::chrono_literals;
namespace sd = oegw::subdevices;

namespace {
constexpr NodeId kGateway{0x20};

// The sub-devices' boot steps (waiting for boot-up, configuring, starting, their identity) are
// the table's `sub-devices:` row; in the log they pushed the introduction off an 80x24 screen
// within a second. `oegw sim` and `oegw run` log them all.
bool boot_step(const std::string& line) {
  for (const char* step : {": waiting for boot-up", ": configuring (", ": starting (", ": boot diagnostics:"})
    if (line.find(step) != std::string::npos) return true;
  return false;
}

// The demo's files go into a private folder: nothing is left behind, nothing outside is read.
// std::nullopt when it cannot be made (printed).
std::optional<std::filesystem::path> make_demo_folder() {
  char tmpl[] = "/tmp/oegw-demo-XXXXXX";
  const char* dir_c = ::mkdtemp(tmpl);
  if (dir_c == nullptr) {
    std::perror("oegw demo: mkdtemp");
    return std::nullopt;
  }
  const std::filesystem::path dir = dir_c;
  // The source tree's layout: demo.yaml names its EDS files from its own folder config/
  // (docs/reference/mapping-file.md#paths), so they go to subdevices/eds/ beside it.
  std::filesystem::create_directories(dir / "subdevices/eds");
  std::ofstream(dir / "subdevices/eds/generic_pedal.eds") << demo_files::kPedalEds;
  std::ofstream(dir / "subdevices/eds/button_cluster.eds") << demo_files::kClusterEds;
  return dir;
}

// The simulated cab: the devices of demo.yaml downstream (its MCB-402 wired as the file's
// button_bits say), the gateway, a host upstream.
rig::CabRigOptions cab_options(const mapping::Config& cfg, const std::filesystem::path& dir) {
  rig::CabRigOptions rig_options{.store = dir / "upstream.store"};
  rig_options.simulator_options = rig::simulators_as_wired(cfg);
  return rig_options;
}

// The demo on a built cab: the state its steps share, one method per step of the story in the
// order run() takes them. Members in the order they are made, so they go in reverse.
class GatewayDemo {
 public:
  GatewayDemo(const GatewayDemoOptions& o, const mapping::Config& c, const std::filesystem::path& d, EventLoop& l)
      : options(o), cfg(c), dir(d), loop(l) {
    if (options.frames) print_frames_of(rig, t0);
    screen = LiveScreen(tty);
  }

  int run() {
    if (!build_the_cab()) return 1;
    watch_the_host();
    std::printf(
        // Every line within 79 columns: an 80x24 terminal shows it unwrapped.
        "oegw demo: the CiA 852 gateway between a simulated cab and a built-in host\n"
        "  downstream: elobau grip 11h, MCB-402 03h, pedal 30h, Novotechnik encoder 7Fh,\n"
        "              button cluster 31h\n"
        "  upstream:   the gateway is node 20h; a host configures its PDOs, reads them\n"
        "  mapping:    config/demo.yaml on the in-process bus; `oegw sim FILE` runs your\n"
        "              own file so, `oegw run FILE` on a cab controller\n\n");
    if (auto refused = start_publishing()) return *refused;
    if (publishing) publishing->run_on(loop, [this] { rig.rearm(); });
    loop.call_every(loop.now(), 20ms, [this] {
      if (!moving) return;
      bench->move(loop.now());
      rig.rearm();
    });

    // The script, step by step.
    at(0ms, [this] { power_on(); });
    at(2500ms, [this] { the_host_starts_the_gateway(); });
    live = std::chrono::duration_cast<Duration>(std::chrono::duration<double>(options.seconds));
    view_timer = loop.call_every(loop.now() + 3s, tty ? 100ms : 1s, [this] { view(false); });
    at(3000ms + live, [this] { the_host_writes_the_lamps(); });
    at(3500ms + live, [this] { the_grip_cable_is_pulled(); });
    at(4500ms + live, [this] { the_grip_is_plugged_back(); });
    at(7500ms + live, [this] { the_stick_goes_back_to_zero(); });
    at(9000ms + live, [this] { the_fault_clears(); });
    return play();
  }

 private:
  void say(const std::string& s) { screen.log(stamped(loop.now() - t0, s)); }
  void check(bool ok, const std::string& what) {
    if (!ok) ++failures;
    say(std::string(ok ? "ok: " : "FAILED: ") + what);
  }
  void at(Duration d, std::function<void()> fn) { steps.emplace_back(d, std::move(fn)); }

  bool build_the_cab() {
    rig.on_gateway = [this](Gateway& g) {
      g.on_log = [this](const std::string& line) {
        if (!boot_step(line)) say("gateway: " + line);
      };
    };
    try {
      rig.build();
    } catch (const std::runtime_error& e) {
      std::fprintf(stderr, "oegw demo: %s\n", e.what());
      std::filesystem::remove_all(dir);
      return false;
    }
    gw = &rig.gw();
    host = &rig.host();
    bench = &rig.devices();
    host_port = &rig.host_port();
    return true;
  }

  // What the screen shows must be what the story caused: a fault of another FE, or of the
  // pulled grip's FEs outside the window from the pull until it is back, fails the demo (a
  // loaded machine that misses heartbeats shows `stale` and EMCY 7000h; the demo must say so).
  void spurious_fault(const std::string& what) {
    if (spurious.size() < 5) say("FAILED: a fault the story did not cause: " + what);
    spurious.push_back(what);
  }

  // The host reads joystick 1 from TPDO1 and counts the gateway's EMCYs.
  void watch_the_host() {
    host->on_other_frame = [this](const CanFrame& f, TimePoint) {
      if (f.id == 0x1A0 && f.dlc >= 4) {
        ++tpdos;
        host_x = static_cast<std::int16_t>(get_u16(&f.data[0]));
        x_min = std::min(x_min, host_x);
        x_max = std::max(x_max, host_x);
      }
    };
    host->on_emcy = [this](const EmcyMessage& m, TimePoint) {
      if (m.code == 0x7000 && !grip_pulled)
        spurious_fault(fmt::format("EMCY 7000h naming sub-device {:02X}h", m.msef[0]));
      emcys.push_back(m.code);
      say(fmt::format("host: EMCY from the gateway: {:04X}h {}", m.code,
                      m.code == 0x7000 ? fmt::format("(additional modules: sub-device {:02X}h failed)", m.msef[0])
                      : m.code == 0    ? "(error reset)"
                                       : ""));
    };
  }

  // Every FE on DDS (loopback only) and LCM (ttl=0, 224.0.0.1), as a machine application sees
  // it: the embedded demo.yaml's publish section (--no-publish turns it off). An exit code when
  // the demo cannot run so.
  std::optional<int> start_publishing() {
    publish_config = cfg.publish;
    if (!options.dds_security.empty()) {
      // The secure mode: the set's file names (scripts/make-dds-security.sh), the gateway's identity.
      auto& sec = publish_config.dds.security.emplace();
      const std::filesystem::path set = std::filesystem::absolute(options.dds_security);
      sec.path = {(set / "ca.pem").string(), (set / "gateway.pem").string(),    (set / "gateway.key").string(),
                  (set / "ca.pem").string(), (set / "governance.p7s").string(), (set / "permissions.p7s").string()};
    }
    const mapping::PublishConfig& publish = publish_config;
    if (!options.publish || !(publish.dds.enabled || publish.lcm.enabled)) return std::nullopt;
    try {
      publishing = std::make_unique<gateway::GatewayPublishing>(*gw, publish, [this] { return loop.now(); });
      say(
          fmt::format("publishing every FE on DDS (topics oegw/*, domain {}, partition {}, network {}{}) and LCM "
                      "(channels {}*, {}); indicators.1 takes its commands from there",
                      publish.dds.domain, publish.dds.partition, publish.dds.network,
                      publish.dds.security ? ", DDS Security with " + options.dds_security : std::string(),
                      publish.lcm.channel_prefix, publish.lcm.url));
      // The machine cannot carry one now (an offline computer has no multicast route for LCM):
      // the demo runs without it and it is opened again as `oegw run` does.
      for (const auto& t : publishing->transports())
        if (!t.up) say(t.name + " not publishing yet: " + t.reason + "; opened again until it works");
    } catch (const publish::PublishConfigError& e) {
      // A set asked for and refused: no demo without it (it would publish in the clear).
      if (publish.dds.security) {
        std::fprintf(stderr, "oegw demo: --dds-security %s: %s\n", options.dds_security.c_str(), e.what());
        std::filesystem::remove_all(dir);
        return exit_code::kCannotStart;
      }
      // A setting that cannot work: the demo goes on without publishing; `oegw run` refuses to
      // start instead.
      say(std::string("not publishing: ") + e.what());
    }
    return std::nullopt;
  }

  void sdo_write(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data, std::function<void()> next) {
    host->sdo(kGateway).download(index, sub, data, [this, index, sub, next](SdoAbortCode c, std::vector<std::uint8_t>) {
      if (c != SdoAbortCode::None) check(false, fmt::format("host: SDO {:04X}h:{:02X}: {}", index, sub, to_string(c)));
      next();
    });
    rig.rearm();
  }

  void view(bool final_frame) {
    std::vector<std::string> lines = gateway_rows(*gw, screen.size().first - 1);
    lines.push_back(fmt::format("  host: {} TPDO1 frames, joystick.1 x as the host reads it = {:+6d}", tpdos, host_x));
    screen.draw(std::move(lines), final_frame);
  }

  // "every sub-device operational" the moment it is so (polled every 10 ms), not at the next step.
  void power_on() {
    say("power on: the gateway boots (upstream boot-up 720#00) and boots its sub-devices");
    rig.power_on();
    (void)host->monitor_heartbeat(kGateway, 300);
    rig.rearm();
    up_watch = loop.call_every(loop.now() + 10ms, 10ms, [this] {
      bool all = true;
      for (const auto& n : gw->downstream().names())
        all = all && gw->downstream().state(n) == sd::NodeState::Operational;
      if (!all) return;
      all_up = true;
      watch_for_spurious_faults();
      loop.cancel(up_watch);
      check(true, "every sub-device configured and operational");
    });
  }

  // From here every FE is valid or not available, but the grip's while it is pulled.
  void watch_for_spurious_faults() {
    std::map<std::string, gateway::FeStatus> last;
    loop.call_every(loop.now() + 10ms, 10ms, [this, last]() mutable {
      for (const auto& fe : gw->fes()) {
        const std::string name = mapping::fe_name(fe);
        const FeStatus st = gw->status(fe);
        const bool fault = st == FeStatus::Stale || st == FeStatus::Error || st == FeStatus::Offline;
        const bool grips = name == "joystick.1" || name == "wheel.1";  // demo.yaml: right_grip's
        if (fault && !(grip_pulled && grips) && last[name] != st)
          spurious_fault(fmt::format("{} {} at {:.2f} s", name,
                                     st == FeStatus::Stale   ? "stale"
                                     : st == FeStatus::Error ? "error"
                                                             : "offline",
                                     std::chrono::duration<double>(loop.now() - t0).count()));
        last[name] = st;
      }
    });
  }

  void the_host_starts_the_gateway() {
    if (!all_up) {
      loop.cancel(up_watch);
      check(false, "every sub-device configured and operational within 2.5 s");
    }
    say("host: enables TPDO1 (joystick 1) on 1A0h and RPDO5 (indicators 2) on 225h, sets 6423h TRUE, starts node 20h");
    // CiA 852 clause 12: the PDOs are disabled by default; the host assigns their COB-IDs.
    sdo_write(0x1800, 1, encode<std::uint32_t>(0x1A0), [this] {
      sdo_write(0x1404, 1, encode<std::uint32_t>(0x225), [this] {
        sdo_write(0x6423, 0, {1}, [this] {
          host->nmt().start(kGateway);
          rig.rearm();
          moving = true;
          say("the operator moves the joysticks:");
        });
      });
    });
  }

  void the_host_writes_the_lamps() {
    // On a terminal the table stays live to the end; in a pipe it was printed every second while
    // the operator moved, and from here at each step.
    if (!tty) loop.cancel(view_timer);
    view(false);
    check(tpdos > 0 && x_max - x_min > 20000,
          fmt::format("the host saw joystick 1 move in {} TPDOs (x from {} to {})", tpdos, x_min, x_max));
    say("host: RPDO 225h#0500000000000000 -> indicators.2 lamps 1 and 3 -> the MCB-402's LEDs");
    (void)host_port->send(CanFrame(0x225, {0x05, 0, 0, 0, 0, 0, 0, 0}));  // RPDO 5 maps 6200h:09..10h
    // indicators.1 lists `sources: [dds, lcm]` in demo.yaml: the host may not drive its lamps.
    say("host: SDO write 6200h:01 = FFh (indicators.1, the cluster's lamps, driven by the machine application)");
    // The lamps as they are before the write: the machine application may drive them meanwhile
    // (the DDS/LCM command examples), so the check is "unchanged by the write", not "off".
    auto* lamps = bench->device("cluster");
    const std::optional<std::int64_t> lamps_before = lamps ? lamps->output("out[1]") : std::nullopt;
    host->sdo(kGateway)
        .download(0x6200, 0x01, {0xFF}, [this, lamps, lamps_before](SdoAbortCode c, std::vector<std::uint8_t>) {
          check(lamps && lamps_before && lamps->output("out[1]") == lamps_before,
                fmt::format("the button cluster's lamps unchanged by the refused write ({:02X}h)",
                            lamps_before.value_or(0)));
          check(c == SdoAbortCode::CannotTransferLocalControl,
                fmt::format("the gateway refused it: abort {:08X}h ({}); only the machine application's DDS/LCM "
                            "commands drive those lamps",
                            static_cast<std::uint32_t>(c), to_string(c)));
        });
    rig.rearm();
  }

  void the_grip_cable_is_pulled() {
    auto* mcb = bench->device("left_grip");
    check(mcb && mcb->output("leds[1]") == 1 && mcb->output("leds[2]") == 0 && mcb->output("leds[3]") == 1,
          "MCB-402 LEDs 1 and 3 lit, 2 off");
    say("the right grip's cable is pulled");
    grip_pulled = true;
    (void)bench->command("right_grip silent on", loop.now());
  }

  void the_grip_is_plugged_back() {
    view(false);
    const auto f = gw->fields({mapping::FeKind::Joystick, 1});
    const bool neutral = std::all_of(f.begin(), f.end(), [](const auto& s) { return s.value == 0; });
    check(gw->status({mapping::FeKind::Joystick, 1}) == FeStatus::Offline && neutral,
          "joystick.1 went offline and every field to its fault value (neutral)");
    check(std::count(emcys.begin(), emcys.end(), 0x7000) > 0, "the host got EMCY 7000h naming the grip");
    say("the cable is plugged back and the grip powers up with its stick deflected");
    moving = false;
    (void)bench->command("right_grip x 60", loop.now());
    (void)bench->command("right_grip silent off", loop.now());
    (void)bench->command("right_grip reboot", loop.now());
    rig.rearm();
  }

  void the_stick_goes_back_to_zero() {
    view(false);
    const auto x = gw->fields({mapping::FeKind::Joystick, 1});
    check(gw->downstream().state("right_grip") == sd::NodeState::Operational,
          "the grip is back: reconfigured and started");
    check(!x.empty() && std::all_of(x.begin(), x.end(), [](const auto& s) { return s.name != "x" || s.value == 0; }),
          "joystick.1 x held at neutral although the stick reads 60 %: it has not been seen at zero yet");
    say("the operator lets the stick and the wheels go back to zero, then moves again");
    for (const char* axis : {"x", "y", "wheel_a", "wheel_b", "wheel_c"})
      (void)bench->command(std::string("right_grip ") + axis + " 0", loop.now());
    moving = true;
    rig.rearm();
  }

  void the_fault_clears() {
    check(std::count(emcys.begin(), emcys.end(), 0x0000) > 0, "the host got the error-reset EMCY");
    check(gw->status({mapping::FeKind::Joystick, 1}) == FeStatus::Valid, "joystick.1 valid and following again");
    grip_pulled = false;
    check(spurious.empty(), spurious.empty() ? std::string("no fault the story did not cause")
                                             : fmt::format("{} fault(s) the story did not cause, the first: {}",
                                                           spurious.size(), spurious.front()));
    loop.cancel(view_timer);
    done = true;
    loop.stop();
  }

  // The steps on the loop, run to the last; the summary.
  int play() {
    // The script's times count from here, once the setup is done: publishing with DDS Security
    // takes its participant's authentication set-up first, 3 s on an emulated arm64
    // (scripts/cross-build.sh; a slow cab controller alike), which counted from t0 fired the first
    // steps at once ("operational within 2.5 s" failed at 3.01 s). The log's times stay since start.
    const TimePoint script_start = loop.now();
    for (auto& [d, fn] : steps) loop.call_at(script_start + d, fn);
    if (options.fast) {
      while (!done) loop.advance_by(5ms);
    } else {
      loop.handle_signals({SIGINT, SIGTERM});
      loop.run();
    }
    // The last table stays on the screen, below the log. Drawn here, once the loop has returned:
    // frames handled in the same wake-up as the last step still log, and would land below it.
    view(true);
    std::filesystem::remove_all(dir);
    if (publishing)
      std::printf("published: %llu FE samples\n", static_cast<unsigned long long>(publishing->published()));
    std::printf("\n%s\n", failures == 0 ? "demo complete: every step as expected" : "demo: SOME STEPS FAILED");
    return failures == 0 ? 0 : 1;
  }

  const GatewayDemoOptions& options;
  const mapping::Config& cfg;
  const std::filesystem::path& dir;
  EventLoop& loop;
  bool done = false;
  rig::CabRigOptions rig_options = cab_options(cfg, dir);
  rig::CabRig rig{cfg, loop, rig_options};
  const TimePoint t0 = loop.now();
  const bool tty = ::isatty(STDOUT_FILENO) != 0 && !options.frames && !options.fast;
  LiveScreen screen{false};
  int failures = 0;
  Gateway* gw = nullptr;
  Master* host = nullptr;
  sd::sim::SimBench* bench = nullptr;
  VirtualPort* host_port = nullptr;
  std::size_t tpdos = 0;
  std::int16_t host_x = 0, x_min = 0, x_max = 0;
  std::vector<std::uint16_t> emcys;
  bool grip_pulled = false;
  std::vector<std::string> spurious;
  std::unique_ptr<gateway::GatewayPublishing> publishing;
  mapping::PublishConfig publish_config;
  bool moving = false;
  std::vector<std::pair<Duration, std::function<void()>>> steps;
  bool all_up = false;
  EventLoop::TimerId up_watch = 0;
  Duration live{0};
  EventLoop::TimerId view_timer = 0;
};

}  // namespace

int run_gateway_demo(const GatewayDemoOptions& options) {
  const auto folder = make_demo_folder();
  if (!folder) return 1;
  const std::filesystem::path& dir = *folder;
  auto loaded =
      mapping::load_config_text(demo_files::kDemoYaml, "config/demo.yaml", gateway::driver_catalogue(), dir / "config");
  if (!loaded.ok()) {
    std::fprintf(stderr, "%s", loaded.error_text().c_str());
    std::filesystem::remove_all(dir);
    return 1;
  }
  // --fast: the same script on a simulated clock, as fast as the machine goes (tests use it).
  SimulatedClock sim_clock;
  auto loop_ptr = options.fast ? std::make_unique<EventLoop>(sim_clock) : std::make_unique<EventLoop>();
  GatewayDemo demo(options, *loaded.config, dir, *loop_ptr);
  return demo.run();
}

}  // namespace oegw::programs
