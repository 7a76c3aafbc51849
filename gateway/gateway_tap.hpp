// What crosses the Gateway's boundary, call by call: the black box (gateway/record/,
// docs/guides/black-box.md) listens here. The gateway is sans I/O, so every decision it makes is
// a function of these inputs in this order; the outputs and decisions follow each input, inside
// the call that caused them. A tap only watches: it cannot change what the gateway does.
//
// Inputs are told at the start of each entry point, before the gateway acts on them; outputs
// (frames it sends) and decisions as they happen. Every method has an empty default, so an
// observer overrides what it needs. A gateway is tapped from its construction on
// (GatewayOptions::tap) or by set_tap().
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>

#include "canopen/301/emcy.hpp"
#include "canopen/bus_event.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"
#include "mapping/config.hpp"
#include "subdevices/network_manager.hpp"

namespace oegw::gateway {

class Gateway;

// The gateway's two buses: the host's (upstream) and the sub-devices' (downstream).
enum class Bus : std::uint8_t { Up, Down };

class GatewayTap {
 public:
  virtual ~GatewayTap() = default;

  // ---- Inputs (Gateway's entry points) ----
  virtual void started(canopen::TimePoint /*now*/) {}
  virtual void received(Bus, const canopen::CanFrame&, canopen::TimePoint /*t*/) {}
  virtual void bus_event(Bus, canopen::BusEvent, canopen::TimePoint /*now*/) {}
  virtual void advanced(canopen::TimePoint /*now*/) {}
  virtual void indicators(std::uint8_t /*instance*/, std::uint64_t /*bits*/, mapping::CommandSource,
                          canopen::TimePoint /*now*/) {}
  virtual void display(std::uint8_t /*instance*/, const std::array<std::int16_t, 12>& /*parameters*/,
                       mapping::CommandSource, canopen::TimePoint /*now*/) {}
  virtual void subdevice_command(const std::string& /*name*/, std::string_view /*command*/, canopen::TimePoint) {}
  virtual void downstream_nmt(canopen::NodeId, canopen::NmtCommand, canopen::TimePoint /*now*/) {}
  // A control-socket request (docs/reference/control-protocol.md, the JSON line as received) and
  // the parts of the gateway a commissioning session reaches directly (`what`: "remote_sdo",
  // "send_downstream"): recorded, not replayed (docs/guides/black-box.md).
  virtual void control(std::string_view /*what*/, canopen::TimePoint /*now*/) {}

  // ---- Outputs and decisions ----
  // `gw`: the gateway that sent it (during a reload the old one hands over, the new one starts).
  virtual void sent(const Gateway& /*gw*/, Bus, const canopen::CanFrame&) {}
  // The outcome of the command just told (indicators, display, subdevice_command; nmt: `why`
  // empty when sent).
  virtual void command_outcome(bool /*taken*/, std::string_view /*why*/) {}
  virtual void node_state(const std::string& /*name*/, subdevices::NodeState, const std::string& /*why*/) {}
  // The fault policy raised (`raised`) or cleared a sub-device's fault: the reason, or the
  // evidence that cleared it (docs/design/fault-policy.md).
  virtual void fault(const std::string& /*name*/, bool /*raised*/, std::string_view /*text*/) {}
  virtual void subdevice_emcy(const std::string& /*name*/, const canopen::EmcyMessage&) {}
  // An FE's value or status changed (once per FE at the end of the call, as on_fe_change).
  virtual void fe_changed(const Gateway& /*gw*/, mapping::FeId) {}
  virtual void logged(const std::string& /*line*/) {}
};

}  // namespace oegw::gateway
