// The control socket of `oegw run` (PROTOCOL.md): the server on the gateway's event loop and the
// commands it answers on the running Gateway (`status` now; `oegw ctl`'s later, issue 16).
#pragma once

#include <memory>
#include <string>

#include "canopen/io/event_loop.hpp"
#include "gateway/control/control_protocol.hpp"
#include "gateway/control/control_server.hpp"
#include "gateway/gateway.hpp"
#include "mapping/config.hpp"

namespace oegw::gateway {

class GatewayControl {
 public:
  // Serves config.control (file: the mapping file, for the errors); throws ControlError (a
  // group this machine lacks, a live daemon's socket, ...). `gw` and `config` outlive it.
  GatewayControl(canopen::EventLoop& loop, const Gateway& gw, const mapping::Config& config, const std::string& file);

 private:
  ControlProtocol protocol_;
  std::unique_ptr<ControlServer> server_;
};

}  // namespace oegw::gateway
