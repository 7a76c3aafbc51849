#include "gateway/control/gateway_control.hpp"

#include <spdlog/spdlog.h>

#include "gateway/control/status_report.hpp"

namespace oegw::gateway {

GatewayControl::GatewayControl(canopen::EventLoop& loop, const Gateway& gw, const mapping::Config& config,
                               const std::string& file) {
  const canopen::TimePoint started = loop.now();
  protocol_.add("status", [&loop, &gw, &config, started](const nlohmann::json&) {
    return nlohmann::json{{"status", status_report(gw, config, {loop.now(), started})}};
  });
  ControlSocketSettings settings = control_settings(config.control, file);
  settings.log = [](const std::string& line) { spdlog::info("{}", line); };
  settings.warn = [](const std::string& line) { spdlog::warn("{}", line); };
  server_ = std::make_unique<ControlServer>(loop, std::move(settings),
                                            [this](std::string_view line) { return protocol_.answer(line); });
  spdlog::info("control: {} (oegw status)", config.control.socket);
}

}  // namespace oegw::gateway
