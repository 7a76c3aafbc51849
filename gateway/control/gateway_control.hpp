// The control socket of `oegw run` (docs/reference/control-protocol.md): the server on the
// gateway's event loop and the commands it answers on the running Gateway: `status` (`oegw status`)
// and `oegw ctl`'s (sdo_read, sdo_write, nmt, info, events: gateway/control/ctl_service.hpp) and
// `oegw scan`'s (scan: gateway/control/scan_service.hpp).
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "canopen/io/event_loop.hpp"
#include "gateway/control/control_protocol.hpp"
#include "gateway/control/control_server.hpp"
#include "gateway/control/ctl_service.hpp"
#include "gateway/control/scan_service.hpp"
#include "gateway/gateway.hpp"
#include "mapping/config.hpp"

namespace oegw::gateway::control {

class GatewayControl {
 public:
  // Serves config.control (file: the mapping file, for the errors); throws ControlError (a
  // group this machine lacks, a live daemon's socket, ...). `gw` and `config` outlive it.
  // `rearm`: called after a command acted on the gateway (its next deadline may have changed).
  // `up`, `down`: the interfaces' transports, for the counters of `status` (may be null).
  GatewayControl(canopen::io::EventLoop& loop, Gateway& gw, const mapping::Config& config, const std::string& file,
                 std::function<void()> rearm = {}, const canopen::io::CanTransport* up = nullptr,
                 const canopen::io::CanTransport* down = nullptr);

  // A reload (gateway/reload.hpp): detach() while the old gateway still runs (what its clients
  // had running on it ends: CtlService::detach, ScanService::detach), attach() with the new one
  // and its configuration (which then outlive this, or the next attach). The socket and its
  // connections stay: `oegw status` is answered through a reload.
  void detach();
  void attach(Gateway& gw, const mapping::Config& config);

  // A command of another part of the daemon (the black box's `record_keep`), and a field it
  // adds to the `status` answer (`record`), built when asked.
  void add_command(std::string name, ControlProtocol::AsyncCommand command) {
    protocol_.add_async(std::move(name), std::move(command));
  }
  void add_status_field(std::string name, std::function<nlohmann::json()> field) {
    status_fields_.emplace_back(std::move(name), std::move(field));
  }

  // How long a `status` answer is given again, unchanged, to the same request line: many
  // clients asking at once (a monitoring script per process, 200 `oegw status` in a loop) share
  // one render, which is milliseconds on a slow controller for a full cab
  // (docs/reference/limits.md#the-control-socket). For kStatusReuse, or for kStatusReuseCost
  // times the CPU time the render itself took if that is longer (at most kStatusReuseMost): however
  // many ask with the same line, their renders take at most a twentieth of the loop's time, on a
  // fast machine or a slow one. Any other request, or an `oegw ctl` command's later answer, ends
  // the reuse at once: a status after it shows what it did.
  static constexpr canopen::Duration kStatusReuse = std::chrono::milliseconds(20);
  static constexpr int kStatusReuseCost = 20;
  static constexpr canopen::Duration kStatusReuseMost = std::chrono::seconds(1);
  // What a render's cost is measured on: the loop thread's CPU time (the loop's now() is its
  // wake-up's instant, which does not move during a render; time preempted is no cost of the
  // render); on a simulated loop its clock, so that a render takes no time. A test gives its own.
  using CostClock = std::function<canopen::TimePoint()>;
  void set_cost_clock(CostClock clock) { cost_clock_ = std::move(clock); }
  // The renders of `status` so far (the rest of its answers were reused).
  [[nodiscard]] std::uint64_t status_renders() const { return status_renders_; }

 private:
  // One request line from the socket: noted for the black box, then answered (a status asked
  // again while the last answer may be reused: above).
  void answer(std::string_view line, canopen::TimePoint now, ControlServer::Reply reply);
  // The last `status` answer: its request line, when it was rendered, the answer line, and for
  // how long it is given again.
  struct StatusAnswer {
    std::string request;
    canopen::TimePoint at{};
    std::string line;
    canopen::Duration reuse = kStatusReuse;
  };
  [[nodiscard]] nlohmann::json control_status() const;  // the `control` object of `status`
  std::optional<StatusAnswer> last_status_;
  bool status_rendering_ = false;  // true only while the status command runs (synchronously)
  std::uint64_t status_renders_ = 0;
  CostClock cost_clock_;
  std::vector<std::pair<std::string, std::function<nlohmann::json()>>> status_fields_;
  Gateway* gw_;
  const mapping::Config* config_;
  ControlProtocol protocol_;
  std::unique_ptr<CtlService> ctl_;  // destroyed after the server: its answers then go nowhere
  std::unique_ptr<ScanService> scan_;
  std::unique_ptr<ControlServer> server_;
};

}  // namespace oegw::gateway::control
