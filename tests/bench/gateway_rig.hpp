// Shared by gateway_bench.cpp and gateway_rss.cpp: a Gateway built from YAML text, booted for
// real against the simulators (SimBench) on a downstream VirtualBus, with a host controller (a
// CANopen master) on an upstream VirtualBus that enables TPDO 1 (joystick.1 on 1A0h), sets 6423h
// TRUE and starts the gateway, as gateway_demo.cpp does; all on a SimulatedClock, so the boot
// is deterministic and takes no wall time beyond the computing.
//
// After bring_up(), detach() cuts both buses: the benchmark then calls on_downstream_frame()
// directly and the upstream sink only records (steady_clock) what the gateway queues.
#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <unistd.h>

#include <fmt/format.h>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "canopen/master.hpp"
#include "gateway/gateway.hpp"
#include "mapping/config.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "tests/fixtures/fixtures.hpp"

namespace oegw::bench {

using namespace std::chrono_literals;

// The rig's mapping files (tests/fixtures/): one_grip.yaml, one elobau grip (node 11h) feeding
// joystick.1 (x, y, buttons[1..8]); full_fe_set.yaml, the full FE set of DESIGN.md "Numbers to
// reach", 48 sub-devices:
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

  explicit GatewayRig(const mapping::Config& cfg) : cfg_(cfg) {}
  GatewayRig(const GatewayRig&) = delete;
  GatewayRig& operator=(const GatewayRig&) = delete;
  ~GatewayRig() {
    // Receivers point at the service drivers and the participants: cut them first.
    for (auto* p : {gw_up_.get(), host_port_.get(), gw_down_.get(), sims_port_.get()})
      if (p) p->set_receiver({});
  }

  // Phase 1: the gateway alone (no simulators yet), so its own memory can be measured.
  void build_gateway() {
    up_.run_on(loop_);
    down_.run_on(loop_);
    gw_up_ = up_.attach("gateway");
    host_port_ = up_.attach("host");
    gw_down_ = down_.attach("gateway");
    sims_port_ = down_.attach("devices");
    gateway::GatewayOptions opt;
    opt.store_path = std::filesystem::path("/nonexistent-oegw-bench") / "upstream.store";  // never saved
    canopen::VirtualPort* up = gw_up_.get();
    canopen::VirtualPort* down = gw_down_.get();
    gw_ = std::make_unique<gateway::Gateway>(
        cfg_,
        [this, up](const canopen::CanFrame& f) {
          if (detached_) {
            rec_.at = std::chrono::steady_clock::now();
            ++rec_.frames;
            rec_.last = f;
            return;
          }
          (void)up->send(f);
        },
        [this, down](const canopen::CanFrame& f) {
          if (detached_) {
            ++downstream_while_detached_;
            if (on_downstream_detached) on_downstream_detached(f);
            return;
          }
          (void)down->send(f);
        },
        opt);
  }

  // Phase 2: the simulators (one per sub-device of the mapping file) and the host.
  void build_rest() {
    bench_ = std::make_unique<subdevices::sim::SimBench>(sims_port_->sink());
    for (const auto& s : cfg_.subdevices) {
      subdevices::DeviceSpec spec{s.driver, s.node(), s.options};
      spec.options.values.emplace_back("name", s.name);
      std::string error;
      if (!bench_->add(spec, error)) throw std::runtime_error("simulator " + s.name + ": " + error);
    }
    host_ = std::make_unique<canopen::Master>(host_od_, host_port_->sink(),
                                               canopen::MasterConfig{.heartbeat_entries = 2, .sdo_timeout = 500ms});
    host_->on_other_frame = [this](const canopen::CanFrame& f, canopen::TimePoint) {
      if (f.id == 0x1A0) ++host_tpdo1_;
    };
    bench_drv_ = std::make_unique<canopen::ServiceDriver>(loop_, *bench_);
    gw_drv_ = std::make_unique<canopen::ServiceDriver>(loop_, *gw_);
    host_drv_ = std::make_unique<canopen::ServiceDriver>(loop_, *host_);
    sims_port_->set_receiver([this](const canopen::CanFrame& f, canopen::TimePoint t) {
      bench_->on_frame(f, t);
      bench_drv_->rearm();
    });
    gw_down_->set_receiver([this](const canopen::CanFrame& f, canopen::TimePoint t) {
      gw_->on_downstream_frame(f, t);
      gw_drv_->rearm();
    });
    gw_up_->set_receiver([this](const canopen::CanFrame& f, canopen::TimePoint t) {
      gw_->on_upstream_frame(f, t);
      gw_drv_->rearm();
    });
    host_port_->set_receiver([this](const canopen::CanFrame& f, canopen::TimePoint t) {
      host_->on_frame(f, t);
      host_drv_->rearm();
    });
  }

  // Phase 3: the real boot (3 s simulated), then the host's configuration (TPDO 1 on 1A0h,
  // 6423h TRUE, NMT start), then `extra` simulated time. Throws when a sub-device is not
  // operational or the host sees no TPDO 1 for a moved grip.
  void boot(canopen::Duration extra = 500ms) {
    (void)gw_->start(loop_.now());
    bench_->start(loop_.now());
    rearm_all();
    loop_.advance_by(3s);
    for (const auto& n : gw_->downstream().names())
      if (gw_->downstream().state(n) != subdevices::NodeState::Operational)
        throw std::runtime_error("sub-device " + n + " not operational: " +
                                 std::string(subdevices::to_string(gw_->downstream().state(n))));
    int pending = 2;
    std::string failed;
    auto write = [&](std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data) {
      host_->sdo(kGateway).download(index, sub, std::move(data), [&, index, sub](canopen::SdoAbortCode c, std::vector<std::uint8_t>) {
        if (c != canopen::SdoAbortCode::None) failed += fmt::format(" {:04X}h:{:02X} aborted", index, sub);
        --pending;
      });
    };
    write(0x1800, 1, canopen::encode<std::uint32_t>(0x1A0));
    write(0x6423, 0, {1});
    rearm_all();
    loop_.advance_by(200ms);
    if (pending != 0 || !failed.empty()) throw std::runtime_error("host configuration SDOs failed:" + failed);
    host_->nmt().start(kGateway);
    rearm_all();
    loop_.advance_by(100ms);
    // The grip on joystick.1 moves: the host must see TPDO 1.
    const auto before = host_tpdo1_;
    const std::string grip = cfg_.functional_elements.front().fields.front().subdevice;
    (void)bench_->command(grip + " x 30", loop_.now());
    rearm_all();
    loop_.advance_by(300ms);
    if (host_tpdo1_ == before) throw std::runtime_error("the host saw no TPDO 1 after moving " + grip);
    (void)bench_->command(grip + " x 0", loop_.now());
    rearm_all();
    loop_.advance_by(extra);
  }

  // While detached, every frame the gateway sends downstream (RPDOs to the devices) also goes here.
  std::function<void(const canopen::CanFrame&)> on_downstream_detached;

  // Cuts the gateway from both buses: from now on the caller feeds it and the sinks record.
  void detach() { detached_ = true; }

  // Runs the whole network for `d` more simulated time (before detach()).
  void run_for(canopen::Duration d) {
    rearm_all();
    loop_.advance_by(d);
  }

  // A text command to the simulators (SimBench::command), e.g. "cluster8 silent on".
  std::string command(const std::string& line) {
    auto r = bench_->command(line, loop_.now());
    rearm_all();
    return r;
  }

  // Destroys the simulators and the host (after detach()): what remains is the gateway.
  void drop_simulators() {
    sims_port_->set_receiver({});
    host_port_->set_receiver({});
    bench_drv_.reset();
    host_drv_.reset();
    bench_.reset();
    host_.reset();
  }

  [[nodiscard]] gateway::Gateway& gw() { return *gw_; }
  [[nodiscard]] canopen::TimePoint now() const { return loop_.now(); }
  [[nodiscard]] UpstreamRecord& upstream() { return rec_; }
  [[nodiscard]] std::uint64_t downstream_while_detached() const { return downstream_while_detached_; }
  [[nodiscard]] std::uint64_t host_tpdo1() const { return host_tpdo1_; }

 private:
  void rearm_all() {
    if (bench_drv_) bench_drv_->rearm();
    if (gw_drv_) gw_drv_->rearm();
    if (host_drv_) host_drv_->rearm();
  }

  mapping::Config cfg_;
  canopen::SimulatedClock clock_;
  canopen::EventLoop loop_{clock_};
  canopen::VirtualBus up_, down_;
  std::unique_ptr<canopen::VirtualPort> gw_up_, host_port_, gw_down_, sims_port_;
  std::unique_ptr<gateway::Gateway> gw_;
  std::unique_ptr<subdevices::sim::SimBench> bench_;
  canopen::ObjectDictionary host_od_;
  std::unique_ptr<canopen::Master> host_;
  std::unique_ptr<canopen::ServiceDriver> bench_drv_, gw_drv_, host_drv_;
  bool detached_ = false;
  UpstreamRecord rec_;
  std::uint64_t downstream_while_detached_ = 0;
  std::uint64_t host_tpdo1_ = 0;
};

}  // namespace oegw::bench
