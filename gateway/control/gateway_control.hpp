// The control socket of `oegw run` (docs/reference/control-protocol.md): the server on the
// gateway's event loop and the commands it answers on the running Gateway: `status` (`oegw status`)
// and `oegw ctl`'s (sdo_read, sdo_write, nmt, info, events: gateway/control/ctl_service.hpp) and
// `oegw scan`'s (scan: gateway/control/scan_service.hpp).
#pragma once

#include <functional>
#include <memory>
#include <string>
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

 private:
  std::vector<std::pair<std::string, std::function<nlohmann::json()>>> status_fields_;
  Gateway* gw_;
  const mapping::Config* config_;
  ControlProtocol protocol_;
  std::unique_ptr<CtlService> ctl_;  // destroyed after the server: its answers then go nowhere
  std::unique_ptr<ScanService> scan_;
  std::unique_ptr<ControlServer> server_;
};

}  // namespace oegw::gateway::control
