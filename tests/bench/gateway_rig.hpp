// Shared by gateway_bench.cpp and gateway_rss.cpp: the simulated cab of rig/cab_rig.hpp (the
// harness of the demo and the e2e tests) on a mapping file built from YAML text, booted for real,
// with the host enabling TPDO 1 (joystick.1 on 1A0h), setting 6423h TRUE and starting the
// gateway, as gateway_demo.cpp does; all on a SimulatedClock, so the boot is deterministic and
// takes no wall time beyond the computing.
//
// After bring_up(), detach() cuts both buses: the benchmark then calls on_downstream_frame()
// directly and the upstream sink only records (steady_clock) what the gateway queues.
#pragma once

#include <unistd.h>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "canopen/master.hpp"
#include "gateway/gateway.hpp"
#include "mapping/config.hpp"
#include "rig/cab_rig.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "tests/fixtures/fixtures.hpp"

namespace oegw::bench {

using namespace std::chrono_literals;

// The rig's mapping files (tests/fixtures/): one_grip.yaml, one elobau grip (node 11h) feeding
// joystick.1 (x, y, buttons[1..8]); full_fe_set.yaml, the full FE set (16 of each input FE kind
// that has 16 instances, 8 of the others), 48 sub-devices:
//   16 joysticks  <- 16 elobau grips, nodes 11h..20h (x, y, buttons[1..8])
//    8 wheels     <- wheel_a of grips 1..8
//   16 pedals     <- 16 generic CiA 401 pedal nodes (generic_pedal.eds, analog[1]), 30h..3Fh
//    8 encoders   <- 8 Novotechnik CiA 406 encoders (position), 40h..47h
//    8 clusters   <- 8 generic CiA 401 button-cluster nodes (button_cluster.eds), 50h..57h:
//                    buttons.n switch[1..16] <- in[1..2], indicators.n indicator[1..8] <- out[1]
// Both run the bus at 1 Mbit/s; the rig overrides their store path.
struct FullSetCounts {
  static constexpr int grips = 16, pedals = 16, encoders = 8, clusters = 8, wheels = 8;
  static constexpr int nodes = grips + pedals + encoders + clusters;
};
inline std::string yaml_one_grip() { return fixtures::mapping_file("one_grip.yaml"); }
inline std::string yaml_full_set() { return fixtures::mapping_file("full_fe_set.yaml"); }

inline mapping::Config load_or_throw(const std::string& yaml, const char* name) {
  auto r = mapping::load_config_text(yaml, name, gateway::driver_catalogue());
  if (!r.ok()) throw std::runtime_error(std::string(name) + ":\n" + r.error_text());
  return std::move(*r.config);
}

// What the gateway sends upstream while detached: counted, the last one kept with its time.
struct UpstreamRecord {
  std::uint64_t frames = 0;
  std::chrono::steady_clock::time_point at{};
  canopen::CanFrame last{};
};

class GatewayRig {
 public:
  static constexpr canopen::NodeId kGateway{0x20};

  explicit GatewayRig(const mapping::Config& cfg)
      : rig_(cfg, loop_,
             oegw::rig::CabRigOptions{.store = std::filesystem::path("/nonexistent-oegw-bench") / "upstream.store"}) {
    // Detached, the gateway's frames are recorded here instead of reaching the buses.
    rig_.from_gateway_up = [this](const canopen::CanFrame& f) {
      if (!detached_) return false;
      rec_.at = std::chrono::steady_clock::now();
      ++rec_.frames;
      rec_.last = f;
      return true;
    };
    rig_.from_gateway_down = [this](const canopen::CanFrame& f) {
      if (!detached_) return false;
      ++downstream_while_detached_;
      if (on_downstream_detached) on_downstream_detached(f);
      return true;
    };
  }
  GatewayRig(const GatewayRig&) = delete;
  GatewayRig& operator=(const GatewayRig&) = delete;

  // Phase 1: the gateway alone (no simulators yet), so its own memory can be measured.
  void build_gateway() { rig_.connect_gateway(); }

  // Phase 2: the simulators (one per sub-device of the mapping file) and the host.
  void build_rest() {
    rig_.build_devices();
    rig_.host().on_other_frame = [this](const canopen::CanFrame& f, canopen::TimePoint) {
      if (f.id == 0x1A0) ++host_tpdo1_;
    };
  }

  // Phase 3: the real boot (3 s simulated), then the host's configuration (TPDO 1 on 1A0h,
  // 6423h TRUE, NMT start), then `extra` simulated time. Throws when a sub-device is not
  // operational or the host sees no TPDO 1 for a moved grip.
  void boot(canopen::Duration extra = 500ms) {
    rig_.power_on();
    loop_.advance_by(3s);
    auto& gw = rig_.gw();
    for (const auto& n : gw.downstream().names())
      if (gw.downstream().state(n) != subdevices::NodeState::Operational)
        throw std::runtime_error("sub-device " + n +
                                 " not operational: " + std::string(subdevices::to_string(gw.downstream().state(n))));
    int pending = 2;
    std::string failed;
    auto write = [&](std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data) {
      rig_.host().sdo(kGateway).download(index, sub, std::move(data),
                                         [&, index, sub](canopen::SdoAbortCode c, std::vector<std::uint8_t>) {
                                           if (c != canopen::SdoAbortCode::None)
                                             failed += fmt::format(" {:04X}h:{:02X} aborted", index, sub);
                                           --pending;
                                         });
    };
    write(0x1800, 1, canopen::encode<std::uint32_t>(0x1A0));
    write(0x6423, 0, {1});
    rig_.rearm();
    loop_.advance_by(200ms);
    if (pending != 0 || !failed.empty()) throw std::runtime_error("host configuration SDOs failed:" + failed);
    rig_.host().nmt().start(kGateway);
    rig_.rearm();
    loop_.advance_by(100ms);
    // The grip on joystick.1 moves: the host must see TPDO 1.
    const auto before = host_tpdo1_;
    const std::string grip = rig_.config().functional_elements.front().fields.front().subdevice;
    (void)rig_.command(grip + " x 30");
    loop_.advance_by(300ms);
    if (host_tpdo1_ == before) throw std::runtime_error("the host saw no TPDO 1 after moving " + grip);
    (void)rig_.command(grip + " x 0");
    loop_.advance_by(extra);
  }

  // While detached, every frame the gateway sends downstream (RPDOs to the devices) also goes here.
  std::function<void(const canopen::CanFrame&)> on_downstream_detached;

  // Cuts the gateway from both buses: from now on the caller feeds it and the sinks record.
  void detach() { detached_ = true; }

  // Runs the whole network for `d` more simulated time (before detach()).
  void run_for(canopen::Duration d) {
    rig_.rearm();
    loop_.advance_by(d);
  }

  // A text command to the simulators (SimBench::command), e.g. "cluster8 silent on".
  std::string command(const std::string& line) { return rig_.command(line); }

  // Destroys the simulators and the host (after detach()): what remains is the gateway.
  void drop_simulators() { rig_.drop_devices(); }

  [[nodiscard]] gateway::Gateway& gw() { return rig_.gw(); }
  [[nodiscard]] canopen::TimePoint now() const { return loop_.now(); }
  [[nodiscard]] UpstreamRecord& upstream() { return rec_; }
  [[nodiscard]] std::uint64_t downstream_while_detached() const { return downstream_while_detached_; }
  [[nodiscard]] std::uint64_t host_tpdo1() const { return host_tpdo1_; }

 private:
  canopen::io::SimulatedClock clock_;
  canopen::io::EventLoop loop_{clock_};
  oegw::rig::CabRig rig_;
  bool detached_ = false;
  UpstreamRecord rec_;
  std::uint64_t downstream_while_detached_ = 0;
  std::uint64_t host_tpdo1_ = 0;
};

}  // namespace oegw::bench
