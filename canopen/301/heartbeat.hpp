// Heartbeat producer and consumer (CiA 301 §7.2.8.3.2.2, objects 1016h/1017h §7.5.2.18/19).
//
// Producer: every 1017h ms (0 = off) it sends 700h+node-ID, DLC 1, the NMT state byte. The first
// heartbeat comes one period after the boot-up. A write to 1017h takes effect at once: 0 stops
// the heartbeat; a new period is counted from the last heartbeat sent (or from the boot-up), so
// if that moment has already passed the next advance() sends straight away.
//
// Consumer: 1016h sub 1..n, UNSIGNED32 = node-ID (bits 23..16) << 16 | time in ms (bits 15..0);
// an entry with node-ID 0 or > 127 or time 0 is unused. Monitoring of a node starts at the first
// heartbeat received from it; a timeout is reported exactly when `now` reaches last + time, once;
// monitoring resumes with the next heartbeat. A heartbeat received at or after last + time
// (advance() was not called in time) reports that timeout first, then resumes monitoring. A boot-up (state 00h) is
// reported with on_boot() and, not being a heartbeat, suspends monitoring until the next heartbeat (the producer's
// first heartbeat comes one of its periods after its boot-up). Two entries with the same node-ID and a non-zero time
// are refused with 06040043h (parameter incompatibility).
//
// ObjectDictionary::reset_to_defaults() does not notify observers: after a reset, the owner calls
// reload() on both.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "canopen/301/object_dictionary.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

class StateWriter;  // canopen/state.hpp
class StateReader;

// Adds 1017h "Producer heartbeat time" (UNSIGNED16 rw, ms) if absent.
Object& install_heartbeat_producer_objects(ObjectDictionary& od, std::uint16_t default_ms = 0);
// Adds 1016h "Consumer heartbeat time" (ARRAY of `entries` UNSIGNED32 rw, default 0) if absent.
Object& install_heartbeat_consumer_objects(ObjectDictionary& od, std::uint8_t entries);
[[nodiscard]] constexpr std::uint32_t heartbeat_consumer_entry(NodeId node, std::uint16_t ms) {
  return (static_cast<std::uint32_t>(node.value()) << 16) | ms;
}

class HeartbeatProducer {
 public:
  // 1017h must exist in `od` (install_heartbeat_producer_objects). The producer stays silent
  // until start().
  HeartbeatProducer(ObjectDictionary& od, NodeId node_id, FrameSink sink);
  HeartbeatProducer(const HeartbeatProducer&) = delete;  // the OD observer holds `this`
  HeartbeatProducer& operator=(const HeartbeatProducer&) = delete;

  // After the boot-up: heartbeats from now + period with `state`.
  void start(NmtState state, NodeId node_id, TimePoint now);
  // Silent until the next start() (e.g. while in Initialisation during a reset).
  void stop();
  void set_state(NmtState state) { state_ = state; }
  // Re-reads 1017h (after reset_to_defaults or a stored-parameter load).
  void reload();

  bool on_frame(const CanFrame& /*frame*/, TimePoint /*now*/) { return false; }
  void advance(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const;

  [[nodiscard]] Duration period() const { return period_; }
  [[nodiscard]] bool running() const { return running_; }

  // Run-time state (canopen/state.hpp), for an object of the same configuration whose
  // dictionary values have been imported and reloaded first. Throws StateError.
  void export_state(StateWriter& w) const;
  void import_state(const StateReader& r);

 private:
  void set_period_ms(std::uint16_t ms);

  ObjectDictionary& od_;
  NodeId node_id_;
  FrameSink sink_;
  NmtState state_ = NmtState::PreOperational;
  bool running_ = false;
  Duration period_{0};
  TimePoint reference_{};  // last heartbeat sent, or the start
  Subscriptions subs_;     // declared last: unregisters the OD callbacks first on destruction
};

class HeartbeatConsumer {
 public:
  using NodeCallback = std::function<void(NodeId)>;
  using StateCallback = std::function<void(NodeId, NmtState)>;

  // 1016h must exist in `od` (install_heartbeat_consumer_objects). Installs a write hook (the
  // duplicate check) and an observer (reconfigure the changed entry).
  explicit HeartbeatConsumer(ObjectDictionary& od);
  HeartbeatConsumer(const HeartbeatConsumer&) = delete;
  HeartbeatConsumer& operator=(const HeartbeatConsumer&) = delete;

  void on_timeout(NodeCallback cb) { on_timeout_ = std::move(cb); }
  void on_boot(NodeCallback cb) { on_boot_ = std::move(cb); }
  void on_state(StateCallback cb) { on_state_ = std::move(cb); }
  // Every heartbeat (not the boot-up) of a monitored node, with the state it reports, changed
  // or not: a master that needs proof of life after a command of its own (NMT start) cannot
  // rely on on_state(), which reports changes only.
  void on_heartbeat(StateCallback cb) { on_heartbeat_ = std::move(cb); }

  // True for a heartbeat/boot-up frame (700h+id, DLC 1, not RTR) from a monitored node.
  bool on_frame(const CanFrame& frame, TimePoint now);
  void advance(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const;
  // Re-reads every 1016h entry; all monitoring restarts (waits for a first heartbeat).
  void reload();

  enum class Status : std::uint8_t { Unused, Waiting, Active, TimedOut };
  [[nodiscard]] Status status(NodeId node) const;
  [[nodiscard]] std::optional<NmtState> last_state(NodeId node) const;
  [[nodiscard]] std::uint64_t invalid_frames() const { return invalid_frames_; }

  // Run-time state (canopen/state.hpp), for an object of the same configuration whose
  // dictionary values have been imported and reloaded first (1016h read again). Throws StateError.
  void export_state(StateWriter& w) const;
  void import_state(const StateReader& r);

 private:
  struct Entry {
    NodeId node{0};
    Duration time{0};
    Status status = Status::Unused;
    TimePoint last{};
    std::optional<NmtState> state;
  };
  void load_entry(std::uint8_t sub);
  [[nodiscard]] const Entry* find(NodeId node) const;
  void forget_deadline() { deadline_known_ = false; }

  ObjectDictionary& od_;
  std::vector<Entry> entries_;  // [sub - 1]
  // next_deadline() is asked after every frame of the bus, the entries change with a heartbeat
  // (one per node and period): it is kept until an entry changes. Every function that writes
  // entries_ calls forget_deadline() after each write, before any callback (which may ask).
  mutable std::optional<TimePoint> deadline_;
  mutable bool deadline_known_ = false;
  std::uint64_t invalid_frames_ = 0;
  NodeCallback on_timeout_;
  NodeCallback on_boot_;
  StateCallback on_state_;
  StateCallback on_heartbeat_;
  Subscriptions subs_;  // declared last: unregisters the OD callbacks first on destruction
};

}  // namespace oegw::canopen
