#include "gateway/control/gateway_control.hpp"

#include <spdlog/spdlog.h>

#include <time.h>

#include <algorithm>

#include "canopen/io/clock.hpp"
#include "gateway/control/status_report.hpp"

namespace oegw::gateway::control {

GatewayControl::GatewayControl(canopen::io::EventLoop& loop, Gateway& gw, const mapping::Config& config,
                               const std::string& file, std::function<void()> rearm,
                               const canopen::io::CanTransport* up, const canopen::io::CanTransport* down)
    : gw_(&gw), config_(&config) {
  if (loop.simulated()) {
    cost_clock_ = [&loop] { return loop.now(); };
  } else {
    cost_clock_ = [] {
      timespec t{};
      ::clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
      return canopen::io::time_point_from_monotonic(t.tv_sec, t.tv_nsec);
    };
  }
  const canopen::TimePoint started = loop.now();
  protocol_.add("status", [this, &loop, started, up, down](const nlohmann::json&) {
    StatusContext at{loop.now(), started};
    if (up != nullptr) at.upstream_bus = &up->counters();
    if (down != nullptr) at.downstream_bus = &down->counters();
    nlohmann::json report = status_report(*gw_, *config_, at);
    for (const auto& [name, field] : status_fields_) report[name] = field();
    ++status_renders_;
    report["control"] = control_status();
    status_rendering_ = true;  // the answer line is kept for reuse (answer())
    return nlohmann::json{{"status", report}};
  });
  ctl_ = std::make_unique<CtlService>(loop, gw, config, protocol_, rearm);
  scan_ = std::make_unique<ScanService>(loop, gw, config, protocol_, std::move(rearm));
  ControlSocketSettings settings = control_settings(config.control, file);
  settings.log = [](const std::string& line) { spdlog::info("{}", line); };
  settings.warn = [](const std::string& line) { spdlog::warn("{}", line); };
  server_ = std::make_unique<ControlServer>(loop, std::move(settings),
                                            ControlServer::AsyncHandler(
                                                [this, &loop](std::string_view line, ControlServer::Reply reply) {
                                                  answer(line, loop.now(), std::move(reply));
                                                }));
  spdlog::info("control: {} (oegw status, oegw ctl)", config.control.socket);
}

void GatewayControl::answer(std::string_view line, canopen::TimePoint now, ControlServer::Reply reply) {
  gw_->control_request(line, now);  // the black box notes it (gateway/gateway_tap.hpp)
  if (last_status_ && last_status_->request == line && now - last_status_->at < last_status_->reuse)
    return reply(last_status_->line);
  status_rendering_ = false;
  const canopen::TimePoint began = cost_clock_();
  protocol_.answer(line, [this, reply = std::move(reply), request = std::string(line), now, began](std::string answer) {
    // Only a status answer given while its command runs is kept, with its render's cost (the
    // answer line included): an async command's later answer finds the flag down, and ends the
    // reuse as it is given: what the command did shows in the next status.
    if (status_rendering_)
      last_status_ =
          StatusAnswer{request, now, answer,
                       std::clamp(kStatusReuseCost * (cost_clock_() - began), kStatusReuse, kStatusReuseMost)};
    else last_status_.reset();
    reply(std::move(answer));
  });
  if (!status_rendering_) last_status_.reset();  // any other request may change what status shows
  status_rendering_ = false;
}

// The socket's own counters (docs/reference/control-protocol.md#status): what its clients cost
// and what its bounds did to them, seen by the operator who asks.
nlohmann::json GatewayControl::control_status() const {
  if (!server_) return nullptr;
  return nlohmann::json{{"clients", server_->clients()},     {"max_clients", server_->limits().max_clients},
                        {"handled", server_->handled()},     {"answered", server_->answered()},
                        {"status_renders", status_renders_}, {"refused", server_->refused()},
                        {"dropped", server_->dropped()},     {"evicted", server_->evicted()}};
}

void GatewayControl::detach() {
  ctl_->detach();
  scan_->detach();
}

void GatewayControl::attach(Gateway& gw, const mapping::Config& config) {
  gw_ = &gw;
  config_ = &config;
  last_status_.reset();  // it described the gateway before the reload
  ctl_->attach(gw, config);
  scan_->attach(gw, config);
}

}  // namespace oegw::gateway::control
