#include "gateway/control/gateway_control.hpp"

#include <spdlog/spdlog.h>

#include "gateway/control/status_report.hpp"

namespace oegw::gateway::control {

GatewayControl::GatewayControl(canopen::io::EventLoop& loop, Gateway& gw, const mapping::Config& config,
                               const std::string& file, std::function<void()> rearm,
                               const canopen::io::CanTransport* up, const canopen::io::CanTransport* down)
    : gw_(&gw), config_(&config) {
  const canopen::TimePoint started = loop.now();
  protocol_.add("status", [this, &loop, started, up, down](const nlohmann::json&) {
    StatusContext at{loop.now(), started};
    if (up != nullptr) at.upstream_bus = &up->counters();
    if (down != nullptr) at.downstream_bus = &down->counters();
    nlohmann::json report = status_report(*gw_, *config_, at);
    for (const auto& [name, field] : status_fields_) report[name] = field();
    return nlohmann::json{{"status", report}};
  });
  ctl_ = std::make_unique<CtlService>(loop, gw, config, protocol_, rearm);
  scan_ = std::make_unique<ScanService>(loop, gw, config, protocol_, std::move(rearm));
  ControlSocketSettings settings = control_settings(config.control, file);
  settings.log = [](const std::string& line) { spdlog::info("{}", line); };
  settings.warn = [](const std::string& line) { spdlog::warn("{}", line); };
  server_ = std::make_unique<ControlServer>(
      loop, std::move(settings),
      ControlServer::AsyncHandler([this, &loop](std::string_view line, ControlServer::Reply reply) {
        gw_->control_request(line, loop.now());  // the black box notes it (gateway/gateway_tap.hpp)
        protocol_.answer(line, std::move(reply));
      }));
  spdlog::info("control: {} (oegw status, oegw ctl)", config.control.socket);
}

void GatewayControl::detach() {
  ctl_->detach();
  scan_->detach();
}

void GatewayControl::attach(Gateway& gw, const mapping::Config& config) {
  gw_ = &gw;
  config_ = &config;
  ctl_->attach(gw, config);
  scan_->attach(gw, config);
}

}  // namespace oegw::gateway::control
