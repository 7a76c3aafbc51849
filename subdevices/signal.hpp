// Named, typed signals with a status and a timestamp: what a sub-device driver makes of a node's
// PDOs and EMCYs, and what the mapping layer feeds into functional elements. Knows nothing of
// CiA 852: a signal is "right_grip.x", not "joystick 1 x".
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "canopen/state.hpp"
#include "canopen/types.hpp"

namespace oegw::subdevices {

using canopen::Duration;
using canopen::TimePoint;

// Every input carries one of these (docs/design/fault-policy.md).
enum class SignalStatus : std::uint8_t {
  Valid,         // a fresh value the device vouches for
  Error,         // the device reported an error for this signal (error code, EMCY, mismatch)
  NotAvailable,  // the device says the signal does not exist / is not fitted (e.g. elobau 127)
  Stale,         // no update within the expected period, node still alive
  Offline,       // the node is gone (heartbeat lost, not booted, not configured)
};
[[nodiscard]] std::string_view to_string(SignalStatus s);
// A status read back from a run-time state (canopen/state.hpp); fails on a number no status has.
[[nodiscard]] SignalStatus get_signal_status(const canopen::StateReader& r, std::string_view key);

// What a signal is, so that the mapping layer can check that it fits the field it feeds.
enum class SignalKind : std::uint8_t {
  Axis,      // a deflection with a neutral (joystick axis, thumb wheel, pedal): signed
  Button,    // 0/1
  Position,  // an absolute position (encoder): signed or unsigned 32-bit
  Speed,     // a rate (encoder speed)
  Digital,   // a group of bits (generic 6000h input byte)
  Analog,    // a generic analogue value (generic 6401h)
  Output,    // written by the gateway: an LED, an output bit/byte, an analogue output
};
[[nodiscard]] std::string_view to_string(SignalKind k);

struct SignalInfo {
  std::string name;  // "x", "wheel_a", "buttons[3]", "leds[1]" — unique per driver
  SignalKind kind = SignalKind::Analog;
  std::int64_t min = 0;  // the value range the driver reports (or accepts, for outputs)
  std::int64_t max = 0;
  std::int64_t neutral = 0;  // the value meaning "not operated" (fault value by default)
  std::string unit;          // "percent" (elobau S8), "raw16" (INTEGER16 full scale), "counts", "bits"
  [[nodiscard]] bool output() const { return kind == SignalKind::Output; }
};

struct SignalValue {
  std::int64_t value = 0;
  SignalStatus status = SignalStatus::Offline;
  TimePoint timestamp{};  // when the frame carrying it was received (or the status changed)
  friend bool operator==(const SignalValue&, const SignalValue&) = default;
};

// Counters for bad input: each malformed or unexpected frame is counted, logged once per kind
// and ignored.
struct InputCounters {
  std::uint64_t wrong_length = 0;  // a PDO/EMCY whose DLC does not fit its layout
  std::uint64_t unknown_cob = 0;   // a frame from this node on a COB-ID the driver does not use
  std::uint64_t unknown_emcy = 0;  // an EMCY code the driver cannot decode
  std::uint64_t mismatches = 0;    // redundant channels disagreeing (elobau channel 1/2)

  bool operator==(const InputCounters&) const = default;
};

}  // namespace oegw::subdevices
