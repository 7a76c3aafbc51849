// An in-process CAN bus for tests and simulations: any number of nodes, deterministic delivery.
//
//   VirtualBus bus;
//   auto master = bus.attach("master");
//   auto slave = bus.attach("slave");
//   slave->set_receiver([&](const CanFrame& f, TimePoint t) { sdo_server.on_frame(f, t); });
//   master->send(CanFrame{0x601, {0x40, 0x00, 0x10, 0x00}});
//   bus.deliver_all(clock.now());   // slave receives 601#40001000, master does not
//
// Delivery is queued, not synchronous: send() only appends to the bus queue and returns, and
// deliver_all() hands the queued frames to the receivers. So a service that sends from inside
// its on_frame() (an SDO server answering a request) is never re-entered from its own send(),
// and every node sees frames in one global order, the order of the send() calls - just like a
// real bus serialises frames. Frames sent by receivers during deliver_all() are delivered by the
// same deliver_all() call, after the frames already queued.
//
// Within one frame, ports receive it in attach order. A port does not receive its own frames
// (like a real CAN controller and like CAN_RAW_RECV_OWN_MSGS off) unless attached with
// PortOptions::receive_own.
//
// With an event loop, run_on(loop) posts a deliver_all() to the loop whenever frames are queued.
//
// Time on the wire (optional; the default bus is instant): run_timed_on(loop, bit_rate) makes
// each frame occupy the bus for its real length at that bit rate, stuff bits included
// (canopen/frame_bits.hpp, ISO 11898-1 §10.4/§10.5). Sent frames wait for the bus; when it goes
// idle (after the intermission), the waiting frame with the highest priority - the lowest
// arbitration field, ISO 11898-1 §10.8.3, so the lowest CAN-ID - goes next, frames sent at the
// same instant all competing. A frame reaches the receivers at the end of its end-of-frame
// field, stamped with that time (ISO 11898-1 §10.7: a receiver takes a frame as valid at the
// last-but-one EOF bit; the 1-bit difference is not modelled), and the bus is idle 3 bits
// later. Times are microseconds: a frame's duration is rounded up to the next microsecond (exact
// at 1 Mbit/s, 500, 250, 125 kbit/s). stats() counts the frames and bits sent and the time the
// bus was busy. In this mode deliver_all() is not used (it throws std::logic_error): the loop
// moves the frames.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "canopen/io/can_transport.hpp"
#include "canopen/io/event_loop.hpp"

namespace oegw::canopen::io {

class EventLoop;
class VirtualBus;

// One frame as it went over the virtual bus.
struct BusRecord {
  TimePoint time;      // the `now` given to deliver_all()
  std::string sender;  // the port name (or the name given to inject())
  CanFrame frame;
  // "master: 601#40001000"
  [[nodiscard]] std::string to_string() const;
};

struct PortOptions {
  bool receive_own = false;  // also receive this port's own frames (an echo)
};

class VirtualPort final : public CanTransport {
 public:
  ~VirtualPort() override;

  // Queues the frame on the bus. Returns InvalidFrame for a malformed frame. On a disconnected
  // port (or a destroyed bus) the frame silently vanishes: the result is Ok, as a controller
  // would accept it, but tx_dropped counts it.
  SendResult send(const CanFrame& frame) override;

  [[nodiscard]] const std::string& name() const { return name_; }

  // Fault injection: a disconnected port neither sends onto nor receives from the bus.
  void set_connected(bool connected) { connected_ = connected; }
  [[nodiscard]] bool connected() const { return connected_; }

  // Fault injection: report a bus event to this port's event handler right away.
  void inject_event(BusEvent event) { deliver_event(event); }

 private:
  friend class VirtualBus;
  VirtualPort(VirtualBus* bus, std::uint64_t id, std::string name, PortOptions options)
      : bus_(bus), id_(id), name_(std::move(name)), options_(options) {}

  VirtualBus* bus_;
  std::uint64_t id_;
  std::string name_;
  PortOptions options_;
  bool connected_ = true;
};

class VirtualBus {
 public:
  using Tap = std::function<void(const BusRecord&)>;
  using FramePredicate = std::function<bool(const CanFrame&)>;

  VirtualBus() = default;
  VirtualBus(const VirtualBus&) = delete;
  VirtualBus& operator=(const VirtualBus&) = delete;
  ~VirtualBus();  // ports outliving the bus become disconnected

  [[nodiscard]] std::unique_ptr<VirtualPort> attach(std::string name, PortOptions options = {});

  // Puts a frame on the bus as if from a node without a port; every connected port receives it.
  SendResult inject(const CanFrame& frame, std::string sender = "inject");

  // Delivers queued frames, including frames queued by receivers meanwhile, stamped `now`, until
  // the queue is empty or `max_frames` were delivered. Returns the number delivered. A call made
  // from inside a receiver returns 0 at once (the outer call keeps draining).
  std::size_t deliver_all(TimePoint now, std::size_t max_frames = 1'000'000);

  [[nodiscard]] std::size_t pending() const { return queue_.size() - head_ + waiting_.size(); }

  // Observes every frame as it is delivered (dropped frames are not seen).
  void set_tap(Tap tap) { tap_ = std::move(tap); }
  // Keeps every delivered frame in log() (off by default, it grows without bound).
  void set_logging(bool on) { logging_ = on; }
  [[nodiscard]] const std::vector<BusRecord>& log() const { return log_; }
  void clear_log() { log_.clear(); }

  // Fault injection: the next `count` frames sent (that match `match`, if given) are lost: not
  // delivered to anyone, not logged, not tapped; dropped_frames() counts them.
  void drop_next(std::size_t count, FramePredicate match = {});
  [[nodiscard]] std::uint64_t dropped_frames() const { return dropped_; }

  // Called whenever the queue goes from empty to non-empty outside deliver_all().
  void set_wakeup(std::function<void()> wakeup) { wakeup_ = std::move(wakeup); }
  // Drives the bus from an event loop: whenever frames are queued, a deliver_all(loop.now()) is
  // posted to the loop. The loop must outlive the bus or stop running it first.
  void run_on(EventLoop& loop);
  // The bus with time on the wire at `bit_rate` bit/s (see the header comment), driven by
  // `loop` (a simulated clock in tests). Call before any frame is sent; the loop must outlive
  // the bus. Throws std::invalid_argument for a bit rate of 0.
  void run_timed_on(EventLoop& loop, std::uint32_t bit_rate);
  [[nodiscard]] bool timed() const { return bit_rate_ != 0; }
  [[nodiscard]] std::uint32_t bit_rate() const { return bit_rate_; }

  // What went over the timed bus (all zero on the instant bus).
  struct Stats {
    std::uint64_t frames = 0;  // frames transmitted (dropped frames never reach the wire)
    std::uint64_t bits = 0;    // their length, stuff bits and intermission included
    Duration busy{0};          // the time they occupied the bus (bits at the bit rate)
  };
  [[nodiscard]] const Stats& stats() const { return stats_; }
  // The duration of `bits` at this bus's bit rate, rounded up to the microsecond.
  [[nodiscard]] Duration bit_time(std::uint64_t bits) const;

 private:
  friend class VirtualPort;
  struct Pending {
    std::uint64_t sender_id;  // 0 = injected
    std::string sender;
    CanFrame frame;
  };

  void enqueue(std::uint64_t sender_id, const std::string& sender, const CanFrame& frame);
  // Hands one frame to every connected port (but its sender's), logged and tapped.
  void deliver_one(Pending p, TimePoint now);
  // Timed bus: the bus went idle or a frame arrived on an idle bus; the winner goes on the wire.
  void arbitrate();
  void detach(std::uint64_t id) { ports_.erase(id); }

  std::map<std::uint64_t, VirtualPort*> ports_;  // id order = attach order
  std::uint64_t next_id_ = 1;
  // FIFO: frames queue_[head_..] are pending. A vector cleared (capacity kept) when drained, so
  // that a frame on the bus costs no allocation (a drained std::deque frees its chunk).
  std::vector<Pending> queue_;
  std::size_t head_ = 0;
  bool delivering_ = false;
  std::vector<std::uint64_t> targets_;  // deliver_all()'s per-frame snapshot of the port ids
  Tap tap_;
  bool logging_ = false;
  std::vector<BusRecord> log_;
  std::size_t drop_count_ = 0;
  FramePredicate drop_match_;
  std::uint64_t dropped_ = 0;
  std::function<void()> wakeup_;
  std::shared_ptr<int> alive_ = std::make_shared<int>(0);  // for callbacks posted to a loop
  // Timed bus: the frames waiting for the bus, by (arbitration field, send order).
  std::uint32_t bit_rate_ = 0;
  EventLoop* timed_loop_ = nullptr;
  std::map<std::pair<std::uint64_t, std::uint64_t>, Pending> waiting_;
  std::uint64_t send_seq_ = 0;
  bool on_wire_ = false;  // a frame (or its intermission) occupies the bus
  bool arbitration_posted_ = false;
  EventLoop::TimerId deliver_timer_ = 0, idle_timer_ = 0;
  Stats stats_;
};

}  // namespace oegw::canopen::io
