#include "canopen/301/nmt_slave.hpp"

#include "canopen/state.hpp"

namespace oegw::canopen {

NmtSlave::NmtSlave(NodeId node_id, FrameSink sink)
    : node_id_(node_id), pending_node_id_(node_id), sink_(std::move(sink)) {}

void NmtSlave::set_state(NmtState s, TimePoint now) {
  if (s == state_) return;
  state_ = s;
  last_transition_ = now;
  if (on_state_change_) on_state_change_(s);
}

void NmtSlave::initialise(TimePoint now) {
  // CiA 301 §7.3.2.2.2: Initialisation ends with the boot-up message and the autonomous
  // transition to Pre-operational. Without a valid node-ID (LSS unconfigured) it does not end.
  node_id_ = pending_node_id_;
  if (!node_id_.valid()) return;
  if (sink_) sink_(CanFrame(cob::kHeartbeat + node_id_.value(), {0x00}));
  set_state(NmtState::PreOperational, now);
}

void NmtSlave::start(TimePoint now) {
  state_ = NmtState::Initialisation;
  last_transition_ = now;
  if (on_state_change_) on_state_change_(state_);
  initialise(now);
}

void NmtSlave::reset(bool communication_only, TimePoint now) {
  // Through Initialisation: the owner restores its parameters before the boot-up.
  set_state(NmtState::Initialisation, now);
  if (on_reset_) on_reset_(communication_only);
  initialise(now);
}

void NmtSlave::enter(NmtState target, TimePoint now) {
  if (state_ == NmtState::Initialisation) return;  // not booted (yet): nothing to leave
  if (target == NmtState::Initialisation) {
    reset(true, now);
    return;
  }
  set_state(target, now);
}

bool NmtSlave::on_frame(const CanFrame& frame, TimePoint now) {
  if (frame.id != cob::kNmt || frame.extended) return false;
  if (frame.rtr || frame.dlc != 2) {
    ++stats_.malformed;
    return true;
  }
  const std::uint8_t target = frame.data[1];
  if (target != 0 && target != node_id_.value()) {
    ++stats_.other_node;
    return true;
  }
  const auto cs = static_cast<NmtCommand>(frame.data[0]);
  switch (cs) {
    case NmtCommand::Start:
    case NmtCommand::Stop:
    case NmtCommand::EnterPreOperational:
    case NmtCommand::ResetNode:
    case NmtCommand::ResetCommunication: break;
    default: ++stats_.unknown_command; return true;
  }
  ++stats_.commands;
  if (state_ == NmtState::Initialisation) return true;  // unconfigured: NMT not yet running
  switch (cs) {
    case NmtCommand::Start: set_state(NmtState::Operational, now); break;
    case NmtCommand::Stop: set_state(NmtState::Stopped, now); break;
    case NmtCommand::EnterPreOperational: set_state(NmtState::PreOperational, now); break;
    case NmtCommand::ResetNode: reset(false, now); break;
    case NmtCommand::ResetCommunication: reset(true, now); break;
  }
  return true;
}

void NmtSlave::export_state(StateWriter& w) const {
  w.put("node_id", node_id_.value());
  w.put("pending_node_id", pending_node_id_.value());
  w.put("state", state_);
  w.put("last_transition", last_transition_);
  w.put("stats.commands", stats_.commands);
  w.put("stats.malformed", stats_.malformed);
  w.put("stats.unknown_command", stats_.unknown_command);
  w.put("stats.other_node", stats_.other_node);
}

void NmtSlave::import_state(const StateReader& r) {
  const NodeId node_id = r.node_id("node_id");
  const NodeId pending = r.node_id("pending_node_id");
  const NmtState state = r.nmt_state("state");
  const TimePoint last_transition = r.time("last_transition");
  const StateReader sr = r.in("stats");
  const Stats stats{sr.get<std::uint64_t>("commands"), sr.get<std::uint64_t>("malformed"),
                    sr.get<std::uint64_t>("unknown_command"), sr.get<std::uint64_t>("other_node")};
  node_id_ = node_id;
  pending_node_id_ = pending;
  state_ = state;
  last_transition_ = last_transition;
  stats_ = stats;
}

}  // namespace oegw::canopen
