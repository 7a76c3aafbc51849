// A simulated cab around one Gateway, on two virtual buses in one event loop: downstream the
// sub-devices of a mapping file as simulators (subdevices/sim, written from the manufacturers'
// documents), upstream a host controller (a canopen::Master). `oegw demo`, the e2e tests
// (tests/integration/gateway_e2e_test.cpp) and the benchmark rig (tests/bench/gateway_rig.hpp)
// are built on it; each adds what it watches (bus taps, the interceptors below, its own host
// script).
//
// Ports on each bus, in this order (the order frames are delivered in): upstream "gateway",
// "host"; downstream "gateway", "devices". More can be attached (VirtualBus::attach).
#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "canopen/master.hpp"
#include "gateway/gateway.hpp"
#include "mapping/config.hpp"
#include "subdevices/sim/sim_bench.hpp"

namespace oegw::rig {

struct CabRigOptions {
  std::filesystem::path store;  // the gateway's 1010h store (replaces upstream.store)
  canopen::Duration host_sdo_timeout = std::chrono::milliseconds(500);
  std::uint8_t host_heartbeat_entries = 2;
  gateway::GatewayOptions gateway{};  // its store_path is set from `store`; sdo_bus_share 0 unless timed_buses
  // Options of the simulated devices by sub-device name (subdevices/sim/sim_registry.hpp, e.g.
  // {"left_grip", {{{"wiring", "0/1/2/3/4/5/6"}}}}: an MCB-402 wired otherwise than the
  // document's table). The mapping file's driver options never reach a simulator, only a
  // cia401 node's `eds` (the device and its description are one file).
  std::map<std::string, subdevices::DriverOptions> simulator_options{};
  // Time on the wire (canopen/io/virtual_bus.hpp run_timed_on): both buses at the mapping
  // file's bit rates (upstream.bitrate, downstream.bitrate), frames taking their real length and
  // waiting for arbitration. false (the default): the instant buses, where timing does not matter.
  bool timed_buses = false;
  // The simulators' SDO latency (SimulatedDevice::set_sdo_latency); unset: none on the instant
  // buses, subdevices::sim::kTypicalSdoLatency (1 ms) on the timed ones.
  std::optional<canopen::Duration> device_sdo_latency{};
};

// The simulators of `config`'s sub-devices added to `bench`, each named as in the file, with
// its `eds` option (a cia401 node's device and description are one file) and the options
// `simulator_options` gives it (CabRigOptions::simulator_options). Throws std::runtime_error
// naming a sub-device whose simulator cannot be built. CabRig::build_devices, and the benchmark
// of the whole path (tests/bench/bench_path.cpp), whose simulators run on a socketpair.
void add_cab_simulators(subdevices::sim::SimBench& bench, const mapping::Config& config,
                        const std::map<std::string, subdevices::DriverOptions>& simulator_options = {});

// The simulators' options the file itself implies: an MCB-402 board wired as its `button_bits`
// says (a simulator is otherwise wired by the document table's other reading,
// docs/design/device-documents.md#corners-every-reading-a-document-permits: a board is wired as
// it is, the file must say so). `oegw demo` and `oegw sim` run the file's cab so.
[[nodiscard]] std::map<std::string, subdevices::DriverOptions> simulators_as_wired(const mapping::Config& config);

class CabRig {
 public:
  // `loop` runs everything (a simulated clock in tests and `oegw demo --fast`).
  CabRig(const mapping::Config& config, canopen::io::EventLoop& loop, CabRigOptions options = {});
  ~CabRig();
  CabRig(const CabRig&) = delete;
  CabRig& operator=(const CabRig&) = delete;

  // Interceptors, set before the frames flow; each returns true when it consumed the frame (it
  // does not reach the bus, or the receiver).
  using Interceptor = std::function<bool(const canopen::CanFrame&)>;
  Interceptor from_devices;       // a simulator's frame
  Interceptor from_gateway_up;    // the gateway's upstream frame
  Interceptor from_gateway_down;  // the gateway's downstream frame
  Interceptor to_devices;         // a frame the simulators would receive
  Interceptor to_gateway_down;    // a frame the gateway would receive downstream
  // Called with each gateway connect_gateway() makes, before it is attached (on_log, ...).
  std::function<void(gateway::Gateway&)> on_gateway;

  // The simulators (one per sub-device of the mapping file, named as there) and the host.
  // Throws std::runtime_error naming a sub-device whose simulator cannot be built.
  void build_devices();
  // A gateway on the mapping file and the store, attached to both buses. Called again: a
  // restart (the old gateway is detached and destroyed first, the store kept).
  void connect_gateway();
  // A reload of the mapping file (gateway/reload.hpp): `next`'s settings a reload cannot apply,
  // nothing changed then; else (empty) the gateway replaced by one of `next` around the same
  // upstream device (on_gateway is called with it). The simulators stay: the cab is the same.
  std::vector<mapping::Diagnostic> reload(const mapping::Config& next);
  // build_devices() and connect_gateway().
  void build();
  // Destroys the simulators and the host: what remains is the gateway (memory figures).
  void drop_devices();

  // Power on: the gateway (boot-up) and every simulator.
  void power_on();
  // After anything done from outside the loop (a command, a frame sent by hand): the service
  // drivers look at their deadlines again.
  void rearm();
  // Runs the loop for `d` (simulated clock).
  void run_for(canopen::Duration d);
  // A text command to the simulators (SimBench::command), e.g. "grip x 50".
  std::string command(const std::string& line);

  [[nodiscard]] gateway::Gateway& gw() { return *gw_; }
  [[nodiscard]] const gateway::Gateway& gw() const { return *gw_; }
  [[nodiscard]] canopen::Master& host() { return *host_; }
  [[nodiscard]] subdevices::sim::SimBench& devices() { return *bench_; }
  [[nodiscard]] canopen::io::VirtualBus& up() { return up_; }
  [[nodiscard]] canopen::io::VirtualBus& down() { return down_; }
  [[nodiscard]] canopen::io::VirtualPort& host_port() { return *host_port_; }
  [[nodiscard]] canopen::io::VirtualPort& devices_port() { return *sims_port_; }
  [[nodiscard]] canopen::io::EventLoop& loop() { return loop_; }
  [[nodiscard]] canopen::TimePoint now() const { return loop_.now(); }
  [[nodiscard]] const mapping::Config& config() const { return config_; }
  [[nodiscard]] canopen::io::ServiceDriver& gateway_driver() { return *gw_drv_; }
  // The options the rig builds its gateway with: CabRigOptions::gateway with the rig's store and
  // SDO pacing (a twin of the gateway is built with them).
  [[nodiscard]] gateway::GatewayOptions gateway_options() const;

 private:
  // `sink` behind the interceptor member `consumed` (read at each frame, so it may be set later).
  canopen::FrameSink through(const Interceptor& consumed, canopen::FrameSink sink);

  mapping::Config config_;
  canopen::io::EventLoop& loop_;
  CabRigOptions options_;
  canopen::io::VirtualBus up_, down_;
  std::unique_ptr<canopen::io::VirtualPort> gw_up_, host_port_, gw_down_, sims_port_;
  std::unique_ptr<subdevices::sim::SimBench> bench_;
  std::unique_ptr<gateway::Gateway> gw_;
  canopen::ObjectDictionary host_od_;
  std::unique_ptr<canopen::Master> host_;
  std::unique_ptr<canopen::io::ServiceDriver> bench_drv_, gw_drv_, host_drv_;
};

}  // namespace oegw::rig
