// NMT master (CiA 301 §7.2.8.2.1): sends node-control commands on COB-ID 000h, DLC 2.
#pragma once

#include <cstdint>
#include <optional>

#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

class NmtMaster {
 public:
  // NMT addressing: node-ID 0 means every node.
  static constexpr NodeId kAllNodes{0};

  explicit NmtMaster(FrameSink sink) : sink_(std::move(sink)) {}

  // Sends [cs, node]. Returns false (sending nothing) for a node-ID outside 0..127.
  bool send(NmtCommand cs, NodeId node);
  bool start(NodeId node) { return send(NmtCommand::Start, node); }
  bool stop(NodeId node) { return send(NmtCommand::Stop, node); }
  bool enter_pre_operational(NodeId node) { return send(NmtCommand::EnterPreOperational, node); }
  bool reset_node(NodeId node) { return send(NmtCommand::ResetNode, node); }
  bool reset_communication(NodeId node) { return send(NmtCommand::ResetCommunication, node); }

  bool on_frame(const CanFrame& /*frame*/, TimePoint /*now*/) { return false; }
  void advance(TimePoint /*now*/) {}
  [[nodiscard]] std::optional<TimePoint> next_deadline() const { return std::nullopt; }

 private:
  FrameSink sink_;
};

}  // namespace oegw::canopen
