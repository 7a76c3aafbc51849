// The event loop of a command-line tool that runs one sans-I/O service directly on a CAN
// interface until the service is done (`oegw scan --direct`, `oegw signals mcb402
// --find-button-bits`): the interface opened (a failure logged), the service's timers and frames.
#pragma once

#include <csignal>
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "canopen/io/event_loop.hpp"
#include "canopen/io/socketcan_transport.hpp"

namespace oegw::gateway {

// The interface, or nullptr with the reason logged.
inline std::unique_ptr<canopen::io::SocketCanTransport> open_tool_interface(const std::string& interface) {
  try {
    return canopen::io::SocketCanTransport::open(interface, canopen::io::SocketCanOptions{});
  } catch (const canopen::io::CanOpenError& e) {
    spdlog::error("interface: {}", e.what());
    return nullptr;
  }
}

// Runs `service` on `port` until its done() (after a timer or a frame) or SIGINT/SIGTERM: its
// start(now), every frame to on_frame(frame, now), its next_deadline() / advance(now).
template <class Service>
void run_on_bus(canopen::io::SocketCanTransport& port, Service& service) {
  using namespace canopen;
  using namespace canopen::io;
  EventLoop loop;
  ServiceDriver driver(
      loop, [&service] { return service.next_deadline(); },
      [&](TimePoint now) {
        service.advance(now);
        if (service.done()) loop.stop();
      });
  port.set_receiver([&](const CanFrame& f, TimePoint t) {
    (void)service.on_frame(f, t);
    if (service.done()) loop.stop();
    driver.rearm();
  });
  watch_transport(loop, port);
  loop.handle_signals({SIGINT, SIGTERM});
  service.start(loop.now());
  driver.rearm();
  loop.run();
  port.set_receiver({});
}

}  // namespace oegw::gateway
