#include "rig/cab_rig.hpp"

#include <stdexcept>

#include "gateway/reload.hpp"

namespace oegw::rig {

using canopen::CanFrame;
using canopen::TimePoint;

void add_cab_simulators(subdevices::sim::SimBench& bench, const mapping::Config& config,
                        const std::map<std::string, subdevices::DriverOptions>& simulator_options) {
  for (const auto& s : config.subdevices) {
    subdevices::DeviceSpec spec{s.driver, s.node(), {}};
    for (const auto& [key, value] : s.options.values)
      if (key == "eds") spec.options.values.emplace_back(key, value);
    if (const auto it = simulator_options.find(s.name); it != simulator_options.end())
      for (const auto& kv : it->second.values) spec.options.values.push_back(kv);
    spec.options.values.emplace_back("name", s.name);
    std::string error;
    if (!bench.add(spec, error)) throw std::runtime_error("simulator " + s.name + ": " + error);
  }
}

std::map<std::string, subdevices::DriverOptions> simulators_as_wired(const mapping::Config& config) {
  std::map<std::string, subdevices::DriverOptions> out;
  for (const auto& sc : config.subdevices)
    if (const auto bits = sc.options.get("button_bits"); sc.driver == "mcb402" && bits)
      out[sc.name].values.emplace_back("wiring", *bits);
  return out;
}

CabRig::CabRig(const mapping::Config& config, canopen::io::EventLoop& loop, CabRigOptions options)
    : config_(config), loop_(loop), options_(std::move(options)) {
  if (options_.timed_buses) {
    up_.run_timed_on(loop_, config_.upstream.bitrate);
    down_.run_timed_on(loop_, config_.downstream.bitrate);
  } else {
    up_.run_on(loop_);
    down_.run_on(loop_);
  }
  gw_up_ = up_.attach("gateway");
  host_port_ = up_.attach("host");
  gw_down_ = down_.attach("gateway");
  sims_port_ = down_.attach("devices");
}

CabRig::~CabRig() {
  // The receivers point at the service drivers and the participants: cut them first.
  for (auto* p : {gw_up_.get(), host_port_.get(), gw_down_.get(), sims_port_.get()})
    if (p) p->set_receiver({});
  up_.set_tap({});
  down_.set_tap({});
}

canopen::FrameSink CabRig::through(const Interceptor& consumed, canopen::FrameSink sink) {
  return [&consumed, sink = std::move(sink)](const CanFrame& f) {
    if (consumed && consumed(f)) return;
    sink(f);
  };
}

void CabRig::build_devices() {
  bench_ = std::make_unique<subdevices::sim::SimBench>(through(from_devices, sims_port_->sink()));
  bench_->set_sdo_latency(options_.device_sdo_latency.value_or(
      options_.timed_buses ? subdevices::sim::kTypicalSdoLatency : canopen::Duration{0}));
  add_cab_simulators(*bench_, config_, options_.simulator_options);
  host_ = std::make_unique<canopen::Master>(host_od_, host_port_->sink(),
                                            canopen::MasterConfig{.heartbeat_entries = options_.host_heartbeat_entries,
                                                                  .sdo_timeout = options_.host_sdo_timeout});
  bench_drv_ = std::make_unique<canopen::io::ServiceDriver>(loop_, *bench_);
  host_drv_ = std::make_unique<canopen::io::ServiceDriver>(loop_, *host_);
  sims_port_->set_receiver([this](const CanFrame& f, TimePoint t) {
    if (to_devices && to_devices(f)) return;
    bench_->on_frame(f, t);
    bench_drv_->rearm();
  });
  host_port_->set_receiver([this](const CanFrame& f, TimePoint t) {
    host_->on_frame(f, t);
    host_drv_->rearm();
  });
}

gateway::GatewayOptions CabRig::gateway_options() const {
  gateway::GatewayOptions opt = options_.gateway;
  opt.store_path = options_.store;
  // The instant buses have no time on the wire to share: the gateway's SDO is not paced there
  // (GatewayOptions::sdo_bus_share), so the phases the safety matrix aims at stay where they are.
  if (!options_.timed_buses) opt.sdo_bus_share = 0;
  return opt;
}

void CabRig::connect_gateway() {
  gw_up_->set_receiver({});
  gw_down_->set_receiver({});
  gw_drv_.reset();
  gw_.reset();
  gw_ = std::make_unique<gateway::Gateway>(config_, through(from_gateway_up, gw_up_->sink()),
                                           through(from_gateway_down, gw_down_->sink()), gateway_options());
  if (on_gateway) on_gateway(*gw_);
  gw_drv_ = std::make_unique<canopen::io::ServiceDriver>(loop_, *gw_);
  gw_down_->set_receiver([this](const CanFrame& f, TimePoint t) {
    if (to_gateway_down && to_gateway_down(f)) return;
    gw_->on_downstream_frame(f, t);
    gw_drv_->rearm();
  });
  gw_up_->set_receiver([this](const CanFrame& f, TimePoint t) {
    gw_->on_upstream_frame(f, t);
    gw_drv_->rearm();
  });
}

std::vector<mapping::Diagnostic> CabRig::reload(const mapping::Config& next) {
  auto refused = gateway::reload_refusals(config_, next);
  if (!refused.empty()) return refused;
  // As `oegw run` does: the drivers built beforehand (beside the buses there), then handed over.
  gateway::ReloadDrivers drivers = gateway::build_reload_drivers(next);
  if (!drivers.refusals.empty()) return drivers.refusals;
  config_ = next;
  gw_drv_.reset();  // it holds the old gateway
  gw_ = gateway::reload_gateway(std::move(gw_), config_, through(from_gateway_down, gw_down_->sink()),
                                gateway_options(), loop_.now(), std::move(drivers.drivers));
  if (on_gateway) on_gateway(*gw_);
  gw_drv_ = std::make_unique<canopen::io::ServiceDriver>(loop_, *gw_);
  return {};
}

void CabRig::build() {
  build_devices();
  connect_gateway();
}

void CabRig::drop_devices() {
  sims_port_->set_receiver({});
  host_port_->set_receiver({});
  bench_drv_.reset();
  host_drv_.reset();
  bench_.reset();
  host_.reset();
}

void CabRig::power_on() {
  (void)gw_->start(loop_.now());
  if (bench_) bench_->start(loop_.now());
  rearm();
}

void CabRig::rearm() {
  for (auto* d : {bench_drv_.get(), gw_drv_.get(), host_drv_.get()})
    if (d) d->rearm();
}

void CabRig::run_for(canopen::Duration d) {
  rearm();
  loop_.advance_by(canopen::Duration{0});
  rearm();
  loop_.advance_by(d);
}

std::string CabRig::command(const std::string& line) {
  auto r = bench_->command(line, loop_.now());
  rearm();
  return r;
}

}  // namespace oegw::rig
