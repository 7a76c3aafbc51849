#include "gateway/control/gateway_control.hpp"

#include <spdlog/spdlog.h>

#include "gateway/control/status_report.hpp"

namespace oegw::gateway {

GatewayControl::GatewayControl(canopen::EventLoop& loop, Gateway& gw, const mapping::Config& config,
                               const std::string& file, std::function<void()> rearm, const canopen::CanTransport* up,
                               const canopen::CanTransport* down) {
  const canopen::TimePoint started = loop.now();
  protocol_.add("status", [&loop, &gw, &config, started, up, down](const nlohmann::json&) {
    StatusContext at{loop.now(), started};
    if (up != nullptr) at.upstream_bus = &up->counters();
    if (down != nullptr) at.downstream_bus = &down->counters();
    return nlohmann::json{{"status", status_report(gw, config, at)}};
  });
  ctl_ = std::make_unique<CtlService>(loop, gw, config, protocol_, rearm);
  scan_ = std::make_unique<ScanService>(loop, gw, config, protocol_, std::move(rearm));
  ControlSocketSettings settings = control_settings(config.control, file);
  settings.log = [](const std::string& line) { spdlog::info("{}", line); };
  settings.warn = [](const std::string& line) { spdlog::warn("{}", line); };
  server_ = std::make_unique<ControlServer>(
      loop, std::move(settings),
      ControlServer::AsyncHandler([this](std::string_view line, ControlServer::Reply reply) { protocol_.answer(line, std::move(reply)); }));
  spdlog::info("control: {} (oegw status, oegw ctl)", config.control.socket);
}

}  // namespace oegw::gateway
