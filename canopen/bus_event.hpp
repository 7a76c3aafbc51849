// What a CAN controller reports besides frames. The transports in io/ deliver these events;
// canopen::Node reacts to them (CiA 301 Table 26).
#pragma once

#include <cstdint>
#include <string_view>

namespace oegw::canopen {

// Controller / bus conditions reported by a transport. SocketCAN reports them as error frames
// (linux/can/error.h); the virtual bus only reports what a test injects.
enum class BusEvent : std::uint8_t {
  ErrorActive,         // controller (back) in error-active state (CAN_ERR_CRTL_ACTIVE)
  Restarted,           // controller restarted after bus-off (CAN_ERR_RESTARTED)
  ErrorWarning,        // RX or TX error counter reached the warning level (96)
  ErrorPassive,        // RX or TX error counter reached error-passive (128)
  BusOff,              // TX error counter > 255: the controller left the bus
  TxTimeout,           // the driver gave up transmitting a frame
  ControllerOverflow,  // RX or TX buffer overflow in the controller: frames were lost
  LostArbitration,
  ProtocolError,  // form/stuff/bit/CRC error
  TransceiverError,
  NoAck,  // transmitted frame was not acknowledged: nobody else on the bus?
  BusError,
  InterfaceDown,  // the network interface went down (ENETDOWN)
};

[[nodiscard]] std::string_view to_string(BusEvent event);

}  // namespace oegw::canopen
