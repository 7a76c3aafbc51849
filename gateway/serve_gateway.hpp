// `oegw run` once its buses are open (gateway/programs.cpp: run_gateway opens the SocketCAN
// interfaces, then calls serve_gateway), so that the same serving runs on any CanTransport: the
// benchmark of the whole path (tests/bench/bench_path.cpp) runs it on socketpairs where the
// kernel has no AF_CAN.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "canopen/io/can_bitrate.hpp"
#include "canopen/io/can_transport.hpp"
#include "canopen/io/event_loop.hpp"
#include "mapping/config.hpp"

namespace oegw::gateway {

// The buses serve_gateway() runs on, and what only a CAN controller has.
struct GatewayBuses {
  canopen::io::CanTransport& up;
  canopen::io::CanTransport& down;
  // LSS activate bit timing (CiA 305): sets the upstream interface to `rate` (run_gateway:
  // apply_bit_rate). Unset: the transport has no bit timing, as a virtual CAN interface.
  std::function<canopen::io::BitRateOutcome(std::uint32_t rate)> set_upstream_bit_rate;
  // Called once both buses are watched, before publishing starts (run_gateway: warns of a
  // receive buffer smaller than asked).
  std::function<void()> watching;
};

// What a test may do within serve_gateway (tests/integration/serve_gateway_test.cpp).
struct ServeHooks {
  // Called in the thread that reads the file for a SIGHUP reload, before it reads.
  std::function<void()> reload_reading;
  // Called on the loop once a reload's outcome is known: true if the file was applied.
  std::function<void(bool applied)> reload_done;
  // Called on the loop at each SIGHUP: true if a reading is under way (this one waits for it).
  std::function<void(bool while_reading)> reload_signal;
};

// The gateway of `config` (read from `file`, which names it in the log and which SIGHUP reloads)
// on `buses`, with the black box, publishing, the control socket and systemd's notifications as
// `config` sets them, on `loop` (a real-time loop of the calling thread) until SIGINT or SIGTERM;
// SIGUSR1 keeps the recording. Returns the exit status (exit_code in gateway/programs.hpp). The
// buses' receivers and event handlers are cleared on return.
int serve_gateway(const std::string& file, mapping::Config& config, canopen::io::EventLoop& loop,
                  const GatewayBuses& buses, const ServeHooks& hooks = {});

}  // namespace oegw::gateway
