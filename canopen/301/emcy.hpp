// Emergency object (CiA 301 §7.2.7), producer and consumer, "sans I/O".
//
// EMCY frame: error code (UNSIGNED16, little endian), error register (1001h), 5 bytes of
// manufacturer-specific error field.
//
// EmcyProducer objects (installed by the constructor when absent):
//   1001h error register         UNSIGNED8 ro   bit 0 (generic) while any error is active, ORed
//                                               with the register bits of every active error
//   1003h pre-defined error field ARRAY of UNSIGNED32: sub 0 = number of errors (rw, only 0 may be
//                                 written: clears the history; others 0609 0030h), sub 1 = newest;
//                                 entry = error code | additional information << 16 (CiA 301
//                                 §7.5.2.13: bits 16..31 are manufacturer-specific; the caller's
//                                 `info`, 0 unless given)
//   1014h COB-ID EMCY            UNSIGNED32 rw  default 80h + node-ID; bit 31 = 1: no EMCY sent
//   1015h inhibit time EMCY      UNSIGNED16 rw  100 µs units; EMCYs raised sooner are queued
//
// Two kinds of EMCY go out, both through one queue (1015h: in the order they were made, each at
// least the inhibit time after the one before; a full queue drops the new one, counted in
// dropped()), both with byte 2 = 1001h as it is when the EMCY is made, both recorded in 1003h
// except the error reset 0000h, neither sent while 1014h bit 31 is set:
//  * an error held active (raise/clear): sets its 1001h bits until cleared; the error reset
//    0000h follows when the last active error goes;
//  * an event (report): sent once, 1001h and the active errors unchanged — for what the device
//    reports but does not hold, e.g. a gateway passing on another node's EMCY (CiA 302-7
//    remote EMCY) or a second fault of a class already active.
//
// EmcyConsumer: 1028h (ARRAY of UNSIGNED32, sub n = COB-ID of node n's EMCY, bit 31 = 1: not
// consumed) maps received EMCY frames to a callback.
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <unordered_map>
#include <vector>

#include "canopen/301/object_dictionary.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

class StateWriter;  // canopen/state.hpp
class StateReader;

using EmcyManufacturerField = std::array<std::uint8_t, 5>;

struct EmcyConfig {
  std::uint8_t history_size = 8;                       // 1003h sub-indices 1..n (1..254)
  std::optional<std::uint32_t> cob_id = std::nullopt;  // default 80h + node-ID
  std::uint16_t inhibit_time = 0;                      // 100 µs units
  std::size_t queue_limit = 16;                        // EMCYs held back by the inhibit time; more are dropped
};

class EmcyProducer {
 public:
  // CiA 301 §7.2.7.1, Table 26: error code 0000h "error reset or no error".
  static constexpr std::uint16_t kErrorReset = 0x0000;

  EmcyProducer(ObjectDictionary& od, FrameSink sink, NodeId node, EmcyConfig config = {});
  EmcyProducer(const EmcyProducer&) = delete;
  EmcyProducer& operator=(const EmcyProducer&) = delete;

  // An error occurred: records it (1001h, 1003h entry code | info << 16) and sends its EMCY.
  // `register_bits` are the 1001h bits this error sets besides bit 0 (e.g. 0x10 communication
  // error). Returns false, and sends nothing, if the code is already active.
  bool raise(std::uint16_t code, std::uint8_t register_bits, const EmcyManufacturerField& msef, TimePoint now,
             std::uint16_t info = 0);
  bool raise(std::uint16_t code, std::uint8_t register_bits, TimePoint now) {
    return raise(code, register_bits, {}, now);
  }
  // An event EMCY: sent once (queued behind the inhibit time like any other), byte 2 = the
  // current 1001h, which it does not change; recorded in 1003h as code | info << 16 unless it is
  // the error reset 0000h. Returns false when it cannot go out: 1014h bit 31 set, or the inhibit
  // queue full (counted in dropped()).
  // `relayed`: an EMCY the device passes on for another node (a gateway's remote EMCY). While
  // the inhibit queue is full a relayed EMCY is dropped, and one of the device's own EMCYs (every
  // raise()/clear(), a report() not relayed) takes the place of the oldest relayed one queued
  // (that one counted in dropped()): another node's flood never drops the device's own errors.
  bool report(std::uint16_t code, const EmcyManufacturerField& msef, std::uint16_t info, TimePoint now,
              bool relayed = false);
  // The error is gone: updates 1001h; when no error remains, sends the error-reset EMCY (0000h)
  // with `reset_msef` as its manufacturer-specific error code field (CiA 301 §7.2.7.1: its
  // content is the manufacturer's; e.g. which part of the device recovered). Returns false if the
  // code was not active.
  bool clear(std::uint16_t code, TimePoint now, const EmcyManufacturerField& reset_msef = {});
  // Rewrites 1001h from the active errors (after a reset communication restored the
  // dictionary's defaults: it does not make an active error go away).
  void reapply_register() { update_register(); }
  // NMT reset node (CiA 301 §7.3.2.2.1: the application restarts with its power-on values): no
  // error is active any more, 1001h is 0 and the EMCYs waiting for the inhibit time are dropped;
  // nothing is sent. An error whose cause persists is raised again by whoever sees it.
  void restart();

  [[nodiscard]] bool active(std::uint16_t code) const;
  [[nodiscard]] std::size_t active_count() const { return active_.size(); }
  [[nodiscard]] std::uint8_t error_register() const;
  // EMCYs dropped because the inhibit queue was full.
  [[nodiscard]] std::size_t dropped() const { return dropped_; }

  // Run-time state (canopen/state.hpp), for an object of the same configuration whose
  // dictionary values have been imported and reloaded first. Throws StateError.
  void export_state(StateWriter& w) const;
  void import_state(const StateReader& r);

  bool on_frame(const CanFrame&, TimePoint) { return false; }  // a producer consumes nothing
  void advance(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const;

 private:
  struct ActiveError {
    std::uint16_t code;
    std::uint8_t bits;
  };
  void update_register();
  void push_history(std::uint32_t entry);
  // Sends or queues the frame; false if 1014h bit 31 is set or the queue is full.
  bool emit(std::uint16_t code, const EmcyManufacturerField& msef, TimePoint now, bool relayed = false);
  [[nodiscard]] Duration inhibit() const;

  ObjectDictionary& od_;
  FrameSink sink_;
  std::vector<ActiveError> active_;
  struct Queued {
    CanFrame frame;
    bool relayed = false;
  };
  std::deque<Queued> queue_;
  std::optional<TimePoint> last_sent_;
  std::size_t queue_limit_;
  std::size_t dropped_ = 0;
  Subscriptions subs_;  // declared last: unregisters the OD callbacks first on destruction
};

struct EmcyMessage {
  NodeId node;
  std::uint16_t code = 0;
  std::uint8_t error_register = 0;
  EmcyManufacturerField msef{};
};

using EmcyHandler = std::function<void(const EmcyMessage&, TimePoint)>;

class EmcyConsumer {
 public:
  // Installs 1028h with `nodes` entries (sub n = 80h + n, consumed) when absent.
  EmcyConsumer(ObjectDictionary& od, EmcyHandler handler, std::uint8_t nodes = 127);
  EmcyConsumer(const EmcyConsumer&) = delete;
  EmcyConsumer& operator=(const EmcyConsumer&) = delete;

  bool on_frame(const CanFrame& frame, TimePoint now);
  void advance(TimePoint) {}
  [[nodiscard]] std::optional<TimePoint> next_deadline() const { return std::nullopt; }
  // Reads 1028h again: after values were set without their hooks (a state's import).
  void reload() { rebuild(); }

 private:
  void rebuild();
  ObjectDictionary& od_;
  EmcyHandler handler_;
  std::unordered_map<std::uint32_t, std::uint8_t> by_id_;  // CAN-ID (| bit 31 if 29-bit) -> node
  Subscriptions subs_;  // declared last: unregisters the OD callbacks first on destruction
};

}  // namespace oegw::canopen
