#include "canopen/bus_event.hpp"

namespace oegw::canopen {

std::string_view to_string(BusEvent event) {
  switch (event) {
    case BusEvent::ErrorActive: return "error active";
    case BusEvent::Restarted: return "controller restarted";
    case BusEvent::ErrorWarning: return "error warning";
    case BusEvent::ErrorPassive: return "error passive";
    case BusEvent::BusOff: return "bus off";
    case BusEvent::TxTimeout: return "TX timeout";
    case BusEvent::ControllerOverflow: return "controller buffer overflow";
    case BusEvent::LostArbitration: return "lost arbitration";
    case BusEvent::ProtocolError: return "protocol error";
    case BusEvent::TransceiverError: return "transceiver error";
    case BusEvent::NoAck: return "no ACK";
    case BusEvent::BusError: return "bus error";
    case BusEvent::InterfaceDown: return "interface down";
  }
  return "unknown bus event";
}

}  // namespace oegw::canopen
