// `oegw demo`: `oegw sim` on config/demo.yaml (its cab: an elobau grip, an MCB-402, a pedal, an
// encoder, a button cluster with lamps), told with the demo's story: the host starts the gateway
// and watches joystick 1 move, lights the MCB-402's lamps by RPDO and is refused the machine
// application's lamps, then a grip cable is pulled and plugged back with the stick deflected. Each
// step checks what it caused; a fault the story did not cause fails the demo.
#include "programs/gateway_demo.hpp"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <string_view>

#include <fmt/format.h>

#include "canopen/io/event_loop.hpp"
#include "gateway/gateway.hpp"
#include "gateway/programs.hpp"
#include "programs/demo_files.hpp"
#include "programs/gateway_sim.hpp"
#include "programs/private_folder.hpp"
#include "programs/sim_story.hpp"
#include "subdevices/sim/sim_bench.hpp"

namespace oegw::programs {

using namespace gateway;  // the programs compose the daemon's library

using namespace canopen;
using namespace canopen::io;
using namespace std::chrono_literals;
namespace sd = oegw::subdevices;

namespace {

// The sub-devices' boot steps (waiting for boot-up, configuring, starting, their identity) are
// the table's `sub-devices:` row; in the log they pushed the introduction off an 80x24 screen
// within a second. `oegw sim` and `oegw run` log them all.
bool boot_step(const std::string& line) {
  for (const char* step : {": waiting for boot-up", ": configuring (", ": starting (", ": boot diagnostics:"})
    if (line.find(step) != std::string::npos) return true;
  return false;
}

// The demo's files (its embedded demo.yaml and EDS files) go into a private folder: nothing
// outside is read. The source tree's layout: demo.yaml names its EDS files from its own folder
// config/ (docs/reference/mapping-file.md#paths), so they go to subdevices/eds/ beside it.
void write_demo_files(const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir / "subdevices/eds");
  std::filesystem::create_directories(dir / "config");
  std::ofstream(dir / "config/demo.yaml") << demo_files::kDemoYaml;
  std::ofstream(dir / "subdevices/eds/generic_pedal.eds") << demo_files::kPedalEds;
  std::ofstream(dir / "subdevices/eds/button_cluster.eds") << demo_files::kClusterEds;
}

// The demo's story on the sim: the state its steps share, one method per step in the order
// begin() schedules them.
class DemoStory : public SimStory {
 public:
  explicit DemoStory(const GatewayDemoOptions& o) : options(o) {}

  void banner(const std::string& control_socket) const override {
    std::printf(
        // Every line within 79 columns: an 80x24 terminal shows it unwrapped.
        "oegw demo: the CiA 852 gateway between a simulated cab and a built-in host\n"
        "  downstream: elobau grip 11h, MCB-402 03h, pedal 30h, Novotechnik encoder 7Fh,\n"
        "              button cluster 31h\n"
        "  upstream:   the gateway is node 20h; a host configures its PDOs, reads them\n"
        "  mapping:    config/demo.yaml on the in-process bus: this is `oegw sim\n"
        "              config/demo.yaml` plus a story; `oegw run FILE` on a cab\n");
    if (!control_socket.empty()) std::printf("  status:     oegw status --socket %s\n", control_socket.c_str());
    std::printf("\n");
    std::fflush(stdout);
  }

  [[nodiscard]] bool host_waits() const override { return true; }
  [[nodiscard]] bool shows(const std::string& line) const override { return !boot_step(line); }

  void begin(SimStage& s) override {
    stage = &s;
    loop = &s.loop;
    gw = &s.rig.gw();
    bench = &s.rig.devices();
    tpdo1 = s.cob_ids.at({true, 1});
    t0 = loop->now();
    power_on();
    at(2500ms, [this] { the_host_starts_the_gateway(); });
    const Duration live = std::chrono::duration_cast<Duration>(std::chrono::duration<double>(options.seconds));
    at(3000ms + live, [this] { the_host_writes_the_lamps(); });
    at(3500ms + live, [this] { the_grip_cable_is_pulled(); });
    at(4500ms + live, [this] { the_grip_is_plugged_back(); });
    at(7500ms + live, [this] { the_stick_goes_back_to_zero(); });
    at(9000ms + live, [this] { the_fault_clears(); });
  }

  // The host reads joystick 1 from TPDO 1 (the sim's host keeps it on 180h + node-ID) and counts
  // the gateway's EMCYs.
  void host_frame(const CanFrame& f) override {
    if (stage == nullptr || f.id != tpdo1 || f.dlc < 4) return;
    ++tpdos;
    host_x = static_cast<std::int16_t>(get_u16(&f.data[0]));
    x_min = std::min(x_min, host_x);
    x_max = std::max(x_max, host_x);
  }

  void host_emcy(const EmcyMessage& m) override {
    if (m.code == 0x7000 && !grip_pulled)
      spurious_fault(fmt::format("EMCY 7000h naming sub-device {:02X}h", m.msef[0]));
    emcys.push_back(m.code);
  }

  [[nodiscard]] std::string host_row() const override {
    return fmt::format("  host: {} TPDO1 frames, joystick.1 x as the host reads it = {:+6d}", tpdos, host_x);
  }

  int end(SimStage& s) override {
    // Below the last table, which the log does not pass any more.
    if (!done) {
      ++failures;
      std::printf("FAILED: the story was stopped before its end\n");
    }
    if (const auto n = s.published()) std::printf("published: %llu FE samples\n", static_cast<unsigned long long>(*n));
    std::printf("\n%s\n", failures == 0 ? "demo complete: every step as expected" : "demo: SOME STEPS FAILED");
    return failures == 0 ? 0 : 1;
  }

 private:
  void say(const std::string& s) const { stage->say(s); }
  void check(bool ok, const std::string& what) {
    if (!ok) ++failures;
    say(std::string(ok ? "ok: " : "FAILED: ") + what);
  }
  void at(Duration d, std::function<void()> fn) const { (void)loop->call_at(t0 + d, std::move(fn)); }
  void rearm() const { stage->rig.rearm(); }

  // What the screen shows must be what the story caused: a fault of another FE, or of the
  // pulled grip's FEs outside the window from the pull until it is back, fails the demo (a
  // loaded machine that misses heartbeats shows `stale` and EMCY 7000h; the demo must say so).
  void spurious_fault(const std::string& what) {
    if (spurious.size() < 5) say("FAILED: a fault the story did not cause: " + what);
    spurious.push_back(what);
  }

  // "every sub-device operational" the moment it is so (polled every 10 ms), not at the next step.
  void power_on() {
    say("power on: the gateway boots (upstream boot-up 720#00) and boots its sub-devices");
    up_watch = loop->call_every(loop->now() + 10ms, 10ms, [this] {
      bool all = true;
      for (const auto& n : gw->downstream().names())
        all = all && gw->downstream().state(n) == sd::NodeState::Operational;
      if (!all) return;
      all_up = true;
      watch_for_spurious_faults();
      loop->cancel(up_watch);
      check(true, "every sub-device configured and operational");
    });
  }

  // From here every FE is valid or not available, but the grip's while it is pulled.
  void watch_for_spurious_faults() {
    std::map<std::string, gateway::FeStatus> last;
    loop->call_every(loop->now() + 10ms, 10ms, [this, last]() mutable {
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
                                     std::chrono::duration<double>(loop->now() - t0).count()));
        last[name] = st;
      }
    });
  }

  void the_host_starts_the_gateway() {
    if (!all_up) {
      loop->cancel(up_watch);
      check(false, "every sub-device configured and operational within 2.5 s");
    }
    // CiA 852 clause 12: the PDOs are disabled by default; the host assigns their COB-IDs.
    say(
        fmt::format("host: enables TPDO1 (joystick 1) on {:03X}h and the other PDOs, sets 6423h TRUE, starts "
                    "node 20h",
                    stage->cob_ids.at({true, 1})));
    stage->configure_host();
    stage->motion(true);
    say("the operator moves the joysticks:");
  }

  void the_host_writes_the_lamps() {
    // On a terminal the table stays live to the end; in a pipe it was printed every second while
    // the operator moved, and from here at each step.
    stage->steps_only();
    stage->view(false);
    check(tpdos > 0 && x_max - x_min > 20000,
          fmt::format("the host saw joystick 1 move in {} TPDOs (x from {} to {})", tpdos, x_min, x_max));
    // RPDO 5 maps 6200h:09..10h (indicators.2, CiA 852 §12.1); the sim's host gave it its COB-ID.
    const auto rpdo5 = stage->cob_ids.find({false, 5});
    if (rpdo5 == stage->cob_ids.end()) {
      check(false, "the host has an RPDO 5 (indicators.2) to write");
    } else {
      const CanFrame lamps(rpdo5->second, {0x05, 0, 0, 0, 0, 0, 0, 0});
      say(fmt::format("host: RPDO5 {} -> indicators.2 lamps 1 and 3 -> the MCB-402's LEDs", lamps.to_string()));
      (void)stage->rig.host_port().send(lamps);
    }
    // indicators.1 lists `sources: [dds, lcm]` in demo.yaml: the host may not drive its lamps.
    say("host: SDO write 6200h:01 = FFh (indicators.1, the cluster's lamps, driven by the machine application)");
    // The lamps as they are before the write: the machine application may drive them meanwhile
    // (the DDS/LCM command examples), so the check is "unchanged by the write", not "off".
    auto* lamps = bench->device("cluster");
    const std::optional<std::int64_t> lamps_before = lamps ? lamps->output("out[1]") : std::nullopt;
    stage->rig.host()
        .sdo(NodeId{0x20})
        .download(0x6200, 0x01, {0xFF}, [this, lamps, lamps_before](SdoAbortCode c, std::vector<std::uint8_t>) {
          check(lamps && lamps_before && lamps->output("out[1]") == lamps_before,
                fmt::format("the button cluster's lamps unchanged by the refused write ({:02X}h)",
                            lamps_before.value_or(0)));
          check(c == SdoAbortCode::CannotTransferLocalControl,
                fmt::format("the gateway refused it: abort {:08X}h ({}); only the machine application's DDS/LCM "
                            "commands drive those lamps",
                            static_cast<std::uint32_t>(c), to_string(c)));
        });
    rearm();
  }
  void the_grip_cable_is_pulled() {
    auto* mcb = bench->device("left_grip");
    check(mcb && mcb->output("leds[1]") == 1 && mcb->output("leds[2]") == 0 && mcb->output("leds[3]") == 1,
          "MCB-402 LEDs 1 and 3 lit, 2 off");
    say("the right grip's cable is pulled");
    grip_pulled = true;
    (void)bench->command("right_grip silent on", loop->now());
  }

  void the_grip_is_plugged_back() {
    stage->view(false);
    const auto f = gw->fields({mapping::FeKind::Joystick, 1});
    const bool neutral = std::all_of(f.begin(), f.end(), [](const auto& s) { return s.value == 0; });
    check(gw->status({mapping::FeKind::Joystick, 1}) == FeStatus::Offline && neutral,
          "joystick.1 went offline and every field to its fault value (neutral)");
    check(std::count(emcys.begin(), emcys.end(), 0x7000) > 0, "the host got EMCY 7000h naming the grip");
    say("the cable is plugged back and the grip powers up with its stick deflected");
    stage->motion(false);
    (void)bench->command("right_grip x 60", loop->now());
    (void)bench->command("right_grip silent off", loop->now());
    (void)bench->command("right_grip reboot", loop->now());
    rearm();
  }

  void the_stick_goes_back_to_zero() {
    stage->view(false);
    const auto x = gw->fields({mapping::FeKind::Joystick, 1});
    check(gw->downstream().state("right_grip") == sd::NodeState::Operational,
          "the grip is back: reconfigured and started");
    check(!x.empty() && std::all_of(x.begin(), x.end(), [](const auto& s) { return s.name != "x" || s.value == 0; }),
          "joystick.1 x held at neutral although the stick reads 60 %: it has not been seen at zero yet");
    say("the operator lets the stick and the wheels go back to zero, then moves again");
    for (const char* axis : {"x", "y", "wheel_a", "wheel_b", "wheel_c"})
      (void)bench->command(std::string("right_grip ") + axis + " 0", loop->now());
    stage->motion(true);
    rearm();
  }

  void the_fault_clears() {
    check(std::count(emcys.begin(), emcys.end(), 0x0000) > 0, "the host got the error-reset EMCY");
    check(stage->host_refusals() == 0,
          fmt::format("the host's PDO set-up taken by the gateway ({} write(s) refused)", stage->host_refusals()));
    check(gw->status({mapping::FeKind::Joystick, 1}) == FeStatus::Valid, "joystick.1 valid and following again");
    grip_pulled = false;
    check(spurious.empty(), spurious.empty() ? std::string("no fault the story did not cause")
                                             : fmt::format("{} fault(s) the story did not cause, the first: {}",
                                                           spurious.size(), spurious.front()));
    done = true;
    loop->stop();
  }

  const GatewayDemoOptions& options;
  SimStage* stage = nullptr;
  EventLoop* loop = nullptr;
  Gateway* gw = nullptr;
  sd::sim::SimBench* bench = nullptr;
  std::uint32_t tpdo1 = 0;  // the COB-ID the host gave TPDO 1
  TimePoint t0{};
  int failures = 0;
  bool done = false;
  std::size_t tpdos = 0;
  std::int16_t host_x = 0, x_min = 0, x_max = 0;
  std::vector<std::uint16_t> emcys;
  bool grip_pulled = false;
  std::vector<std::string> spurious;
  bool all_up = false;
  EventLoop::TimerId up_watch = 0;
};

}  // namespace

int run_gateway_demo(const GatewayDemoOptions& options) {
  const auto folder = PrivateFolder::make("demo");
  if (!folder) return 1;
  write_demo_files(folder->path());
  // The story's clock: --fast runs it on the simulated clock, as fast as the machine goes (tests).
  GatewaySimOptions sim{.file = (folder->path() / "config/demo.yaml").string(),
                        .fast = options.fast,
                        .motion = false,  // the story moves the operator's hands
                        .publish = options.publish,
                        .frames = options.frames,
                        .vcan = options.vcan,
                        .dds_security = options.dds_security};
  DemoStory story(options);
  return run_gateway_sim(sim, &story);
}

}  // namespace oegw::programs
