#include "canopen/io/can_transport.hpp"

namespace oegw::canopen::io {

std::string_view to_string(SendStatus status) {
  switch (status) {
    case SendStatus::Ok: return "ok";
    case SendStatus::QueueFull: return "TX queue full, frame dropped";
    case SendStatus::InterfaceDown: return "interface down";
    case SendStatus::InvalidFrame: return "invalid frame";
    case SendStatus::Error: return "send error";
  }
  return "unknown send status";
}

bool is_valid_frame(const CanFrame& frame) {
  if (frame.dlc > 8) return false;
  return frame.extended ? frame.id <= 0x1FFFFFFFu : frame.id <= 0x7FFu;
}

void CanTransport::deliver_frame(const CanFrame& frame, TimePoint timestamp) {
  ++counters_.rx_frames;
  if (receiver_) receiver_(frame, timestamp);
}

void CanTransport::deliver_event(BusEvent event) {
  ++counters_.error_frames;
  if (event_handler_) event_handler_(event);
}

}  // namespace oegw::canopen::io
