// The control socket of `oegw run` (PROTOCOL.md): the server on the gateway's event loop and the
// commands it answers on the running Gateway: `status` (`oegw status`) and `oegw ctl`'s
// (sdo_read, sdo_write, nmt, info, events: gateway/control/ctl_service.hpp) and `oegw scan`'s
// (scan: gateway/control/scan_service.hpp).
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "canopen/io/event_loop.hpp"
#include "gateway/control/control_protocol.hpp"
#include "gateway/control/control_server.hpp"
#include "gateway/control/ctl_service.hpp"
#include "gateway/control/scan_service.hpp"
#include "gateway/gateway.hpp"
#include "mapping/config.hpp"

namespace oegw::gateway {

class GatewayControl {
 public:
  // Serves config.control (file: the mapping file, for the errors); throws ControlError (a
  // group this machine lacks, a live daemon's socket, ...). `gw` and `config` outlive it.
  // `rearm`: called after a command acted on the gateway (its next deadline may have changed).
  // `up`, `down`: the interfaces' transports, for the counters of `status` (may be null).
  GatewayControl(canopen::EventLoop& loop, Gateway& gw, const mapping::Config& config, const std::string& file,
                 std::function<void()> rearm = {}, const canopen::CanTransport* up = nullptr,
                 const canopen::CanTransport* down = nullptr);

 private:
  ControlProtocol protocol_;
  std::unique_ptr<CtlService> ctl_;  // destroyed after the server: its answers then go nowhere
  std::unique_ptr<ScanService> scan_;
  std::unique_ptr<ControlServer> server_;
};

}  // namespace oegw::gateway
