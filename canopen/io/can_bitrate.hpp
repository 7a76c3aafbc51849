// The bit rate of a SocketCAN interface: what it is (rtnetlink RTM_GETLINK) and setting it
// (Debian's libsocketcan: can_do_stop, can_set_bitrate, can_do_start).
//
//   auto link = netlink_can_link();
//   const BitRateOutcome r = apply_bit_rate(*link, "can0", 250000);
//   if (!r.ok()) fail(r.message);  // "cannot set can0 to 250000 bit/s: Operation not permitted"
//
// What apply_bit_rate() decides (plan_bit_rate() says the same without changing anything):
//  * a CAN controller (link kind "can": it has bit timing) already at the rate: nothing (Keep);
//  * a CAN controller at another rate, or none set yet: interface down (if it is up), set the
//    rate, interface up (Set). The kernel refuses a new rate while the interface is up ("Device or
//    resource busy"), hence the stop. When setting fails, an interface that was up is brought up
//    again at its old rate and the outcome carries the error;
//  * an interface without bit timing (vcan, vxcan: no IFLA_CAN_* data): nothing (NoBitTiming),
//    the owner reports it;
//  * an interface that does not exist: nothing (Missing); opening it reports that.
// The calls need CAP_NET_ADMIN for a change; reading works for anyone.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

namespace oegw::canopen::io {

// What the kernel says about one interface's CAN link.
struct CanLinkState {
  bool exists = false;
  bool up = false;              // IFF_UP
  bool has_bit_timing = false;  // link kind "can" (a controller driven by can-dev)
  std::uint32_t bitrate = 0;    // IFLA_CAN_BITTIMING; 0: none set yet (or no bit timing)
};

// The netlink calls, behind an interface so that the decisions above are tested with a fake.
// Each returns 0 or the errno of the failure.
class CanLink {
 public:
  virtual ~CanLink() = default;
  virtual int query(const std::string& interface, CanLinkState& state) = 0;
  virtual int stop(const std::string& interface) = 0;
  virtual int set_bitrate(const std::string& interface, std::uint32_t bitrate) = 0;
  virtual int start(const std::string& interface) = 0;
};

// The real one: RTM_GETLINK for query(), libsocketcan for the changes (its own messages on
// stderr are suppressed: the outcome's message says what failed).
[[nodiscard]] std::unique_ptr<CanLink> netlink_can_link();

enum class BitRateAction : std::uint8_t {
  Keep,         // already at the rate
  Set,          // set (or, from plan_bit_rate, to be set)
  NoBitTiming,  // virtual CAN: there is no bit rate to set
  Missing,      // no such interface
};

struct BitRateOutcome {
  BitRateAction action = BitRateAction::Keep;
  std::uint32_t before = 0;  // the rate the interface had (0: none)
  bool was_up = false;
  int error = 0;  // errno of the step that failed; 0 = done
  // Set when error != 0: "cannot set can0 to 250000 bit/s: Operation not permitted"
  // ("cannot query can0: ..." when the kernel could not be asked).
  std::string message;
  [[nodiscard]] bool ok() const { return error == 0; }
};

[[nodiscard]] BitRateOutcome plan_bit_rate(CanLink& link, const std::string& interface, std::uint32_t bitrate);
[[nodiscard]] BitRateOutcome apply_bit_rate(CanLink& link, const std::string& interface, std::uint32_t bitrate);

}  // namespace oegw::canopen::io
