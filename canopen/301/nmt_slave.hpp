// NMT slave (CiA 301 §7.2.8.2.1 protocols, §7.3.2 state machine).
//
//   power-on / reset ──► Initialisation ──(boot-up 700h+id `00`)──► Pre-operational
//                                                                    ▲   │
//            Start (01h) ──► Operational    Stop (02h) ──► Stopped    │   │
//            Enter pre-operational (80h) ──► Pre-operational ─────────┘   │
//            Reset node (81h) / reset communication (82h) ──► Initialisation
//
// An NMT command is the frame 000h, DLC 2: [command specifier, node-ID]; node-ID 0 addresses
// every node. Frames on 000h with another DLC are malformed: they are ignored and counted.
//
// Resets: the owner is told through on_reset(communication_only) *before* the new boot-up, so
// it can restore 1000h–1FFFh (reset communication) or the whole dictionary (reset node) to
// their defaults / stored values. A node-ID configured through LSS (CiA 305 §4.2: "pending")
// becomes active at the next reset communication or reset node.
//
// A node whose node-ID is unconfigured (FFh, CiA 305) stays in Initialisation: no boot-up, and
// NMT commands are ignored, until an owner gives it a valid node-ID and calls reset().
#pragma once

#include <cstdint>
#include <functional>
#include <optional>

#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

class StateWriter;  // canopen/state.hpp
class StateReader;

class NmtSlave {
 public:
  using StateCallback = std::function<void(NmtState)>;
  using ResetCallback = std::function<void(bool communication_only)>;

  struct Stats {
    std::uint64_t commands = 0;         // well-formed commands addressed to this node (or to all)
    std::uint64_t malformed = 0;        // frames on 000h with DLC != 2 (or RTR)
    std::uint64_t unknown_command = 0;  // DLC 2 but an unknown command specifier
    std::uint64_t other_node = 0;       // well-formed, addressed to another node
  };

  NmtSlave(NodeId node_id, FrameSink sink);

  void on_state_change(StateCallback cb) { on_state_change_ = std::move(cb); }
  void on_reset(ResetCallback cb) { on_reset_ = std::move(cb); }

  // Power-on: Initialisation, then (with a valid node-ID) the boot-up frame and Pre-operational.
  void start(TimePoint now);

  // True for every frame on COB-ID 000h (NMT), malformed ones included.
  bool on_frame(const CanFrame& frame, TimePoint now);
  void advance(TimePoint /*now*/) {}
  [[nodiscard]] std::optional<TimePoint> next_deadline() const { return std::nullopt; }

  // Local (application-initiated) transitions, e.g. the error behaviour of 1029h or an
  // auto-start. Resets go through reset().
  void enter(NmtState target, TimePoint now);
  void reset(bool communication_only, TimePoint now);

  // The node-ID that the next reset communication / reset node makes active (LSS).
  void set_pending_node_id(NodeId id) { pending_node_id_ = id; }
  [[nodiscard]] NodeId pending_node_id() const { return pending_node_id_; }

  [[nodiscard]] NmtState state() const { return state_; }
  [[nodiscard]] NodeId node_id() const { return node_id_; }
  [[nodiscard]] const Stats& stats() const { return stats_; }
  // The time of the last state change (so a callback can schedule e.g. the heartbeat).
  [[nodiscard]] TimePoint last_transition() const { return last_transition_; }

  // Run-time state (canopen/state.hpp): the active and pending node-IDs, the state, its time and
  // the counts. Throws StateError.
  void export_state(StateWriter& w) const;
  void import_state(const StateReader& r);

 private:
  void set_state(NmtState s, TimePoint now);
  void initialise(TimePoint now);

  NodeId node_id_;
  NodeId pending_node_id_;
  FrameSink sink_;
  NmtState state_ = NmtState::Initialisation;
  TimePoint last_transition_{};
  Stats stats_;
  StateCallback on_state_change_;
  ResetCallback on_reset_;
};

}  // namespace oegw::canopen
