// A story told on `oegw sim` (gateway_sim.hpp). The sim builds everything a user's file gets —
// the simulated cab, the built-in host and its PDO set-up, publishing, the control socket, the
// live table, --frames, --vcan, the loop on either clock; a story adds a banner, its steps on the
// loop with the checks of what they caused, and the summary. `oegw demo` is the sim of
// config/demo.yaml told with the demo's story (gateway_demo.cpp), so that what the demo shows is
// what `oegw sim` shows for a user's own file.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>

#include "canopen/301/emcy.hpp"
#include "canopen/io/event_loop.hpp"
#include "rig/cab_rig.hpp"

namespace oegw::programs {

// What a story sees of the running sim.
struct SimStage {
  canopen::io::EventLoop& loop;
  rig::CabRig& rig;  // the gateway, the host, the simulators, the host's port; rearm() after a change
  // The COB-IDs the host gave the gateway's PDOs, by {transmit, number} (CiA 852 §12.1: the host
  // assigns them; TPDO 1 keeps 180h + node-ID).
  const std::map<std::pair<bool, std::uint16_t>, std::uint32_t>& cob_ids;
  std::function<void(const std::string&)> say;  // a log line, stamped with the time since start
  std::function<void(bool)> motion;             // the operator moves every input (true) or lets go
  std::function<void()> configure_host;         // the host's PDO set-up, then NMT start (SimStory::host_waits)
  std::function<void(bool)> view;               // the table drawn now (true: the last one, kept on screen)
  std::function<void()> steps_only;             // no table every second from now on when not on a terminal
  std::function<int()> host_refusals;           // the host's set-up writes the gateway refused so far
  std::function<std::optional<std::uint64_t>()> published;  // FE samples published so far; nullopt: not publishing
};

class SimStory {
 public:
  SimStory() = default;
  SimStory(const SimStory&) = delete;
  SimStory& operator=(const SimStory&) = delete;
  virtual ~SimStory() = default;

  // Printed instead of the sim's banner; `control_socket` is where `oegw status --socket` reaches
  // this run ("" without a control socket: --fast).
  virtual void banner(const std::string& control_socket) const = 0;
  // Whether the host waits for the story's configure_host() (the sim's host configures at power-on).
  [[nodiscard]] virtual bool host_waits() const { return false; }
  // At power-on, before the gateway boots: the story's steps and watches on the loop. The story
  // ends the run (loop.stop()); --seconds and ^C end it too.
  virtual void begin(SimStage& stage) = 0;
  // Whether a line of the gateway's log is shown.
  [[nodiscard]] virtual bool shows(const std::string& log_line) const {
    (void)log_line;
    return true;
  }
  // Each frame the host takes beside its own protocol (TPDOs), each EMCY of the gateway it gets.
  virtual void host_frame(const canopen::CanFrame& f) { (void)f; }
  virtual void host_emcy(const canopen::EmcyMessage& m) { (void)m; }
  // The row below the table in place of the sim's host counts; "" keeps the sim's.
  [[nodiscard]] virtual std::string host_row() const { return {}; }
  // After the loop, the last table drawn: the summary printed, the exit status returned.
  virtual int end(SimStage& stage) = 0;
};

}  // namespace oegw::programs
