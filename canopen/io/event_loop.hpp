// A single-threaded event loop: epoll for descriptors, a timerfd (CLOCK_MONOTONIC) for timers,
// signalfd for signals, and a queue of posted callbacks. In real time, where the kernel allows
// it, the loop waits through io_uring instead (canopen/io/uring_receiver.hpp): the buses'
// datagrams arrive already read (receive_datagrams), the epoll descriptor is polled through the
// ring, and timers are the wait's timeout, so a frame costs one system call to wait for and read.
//
// Two modes:
//  * real time, `EventLoop loop;` - time is CLOCK_MONOTONIC, run()/run_once() block in epoll_wait;
//    the clock is read once per wake-up and every callback of that wake-up sees that instant
//    (WakeClock), outside run_once() now() reads the clock.
//  * deterministic, `EventLoop loop(simulated_clock);` - time only moves through advance_to(),
//    which fires the timers due in (time, creation) order, setting the clock to each timer's
//    time first, without sleeping. Descriptors are still served by run_once(), and timers due at
//    the clock's current time fire there too, but run_once() never moves the clock.
//
// Callbacks may add/cancel timers, add/remove watchers and post from inside callbacks. Timers
// due at the same time fire in the order they were armed.
//
// Work that is not a bus's is cut into slices (defer()): run_once() runs at most one deferred
// slice per wake-up, after that wake-up's descriptors, timers and posted callbacks, and while a
// slice waits the next epoll_wait does not block. So a descriptor that becomes ready while
// slices queue up (a CAN socket) is served after at most one slice, whatever the backlog of
// slices (docs/reference/limits.md#can-first-what-the-event-loop-does-beside-the-buses).
//
// Driving a "sans I/O" CANopen service:
//
//   EventLoop loop;
//   auto port = SocketCanTransport::open("can0");
//   Node node(od, port->sink());                 // has on_frame/advance/next_deadline
//   ServiceDriver driver(loop, node);            // runs node.advance() at node.next_deadline()
//   driver.bind_receiver(*port, node);           // frames -> node.on_frame(), then re-arm
//   watch_transport(loop, *port);                // port fd readable -> port->poll_readable()
//   loop.handle_signals({SIGTERM, SIGINT});      // -> loop.stop()
//   loop.run();
//
// After calling into the service from outside (an API call that may change its deadline), call
// driver.rearm().
#pragma once

#include <signal.h>

#include <concepts>
#include <cstdint>
#include <deque>
#include <functional>
#include <initializer_list>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "canopen/io/can_transport.hpp"
#include "canopen/io/clock.hpp"
#include "canopen/io/datagram.hpp"
#include "canopen/types.hpp"

struct epoll_event;  // <sys/epoll.h>

namespace oegw::canopen::io {

// Event bits for fd watchers (the same values as EPOLLIN, EPOLLOUT, EPOLLERR, EPOLLHUP).
namespace events {
inline constexpr std::uint32_t kReadable = 0x001;
inline constexpr std::uint32_t kWritable = 0x004;
inline constexpr std::uint32_t kError = 0x008;
inline constexpr std::uint32_t kHangup = 0x010;
}  // namespace events

class UringReceiver;

class EventLoop {
 public:
  using Callback = std::function<void()>;
  using FdCallback = std::function<void(std::uint32_t events)>;
  using SignalCallback = std::function<void(int signo)>;
  using TimerId = std::uint64_t;  // never 0
  using WatchId = std::uint64_t;  // never 0
  using DatagramCallback = std::function<void(const ReceivedDatagram& datagram)>;

  // How a real-time loop waits.
  enum class Wait : std::uint8_t {
    Best,   // io_uring where the kernel and process allow it (uring_receiver.hpp), else epoll
    Epoll,  // epoll_wait, the timerfd; each socket read by its owner
  };

  // Real time (SteadyClock, timerfd). Throws std::system_error if epoll/timerfd fail.
  EventLoop() : EventLoop(Wait::Best) {}
  explicit EventLoop(Wait wait);
  // Deterministic: time is `clock`, which must outlive the loop; use advance_to() to move it.
  explicit EventLoop(SimulatedClock& clock);
  EventLoop(const EventLoop&) = delete;
  EventLoop& operator=(const EventLoop&) = delete;
  ~EventLoop();

  [[nodiscard]] bool simulated() const { return simulated_ != nullptr; }
  // True if the loop waits through io_uring; otherwise why not (empty for a simulated loop or
  // Wait::Epoll).
  [[nodiscard]] bool uses_io_uring() const { return ring_ != nullptr; }
  [[nodiscard]] const std::string& why_not_io_uring() const { return why_not_io_uring_; }
  [[nodiscard]] TimePoint now() const { return clock_->now(); }
  [[nodiscard]] const Clock& clock() const { return *clock_; }

  // One-shot timer at `at` (a time in the past fires at the next opportunity).
  TimerId call_at(TimePoint at, Callback fn);
  TimerId call_after(Duration delay, Callback fn) { return call_at(now() + delay, std::move(fn)); }
  // Periodic timer: first at `first`, then every `period` at fixed rate (first + k*period, no
  // drift). If the loop fell behind by whole periods, the missed ones are skipped, not bunched.
  // Throws std::invalid_argument if period <= 0.
  TimerId call_every(TimePoint first, Duration period, Callback fn);
  // True if the timer existed (a one-shot timer that already fired no longer exists).
  bool cancel(TimerId id);
  [[nodiscard]] bool pending(TimerId id) const { return timer_keys_.contains(id); }
  [[nodiscard]] std::optional<TimePoint> next_timer() const;

  // Watches `fd` for `events` (io_events bits). Throws std::system_error (e.g. fd already
  // watched, or not pollable). The loop does not own the fd; unwatch() before closing it.
  WatchId watch(int fd, std::uint32_t events, FdCallback fn);
  bool unwatch(WatchId id);
  // Changes what watch `id` waits for (io_events bits; 0: only errors and hang-ups, which epoll
  // always reports). One epoll_ctl(EPOLL_CTL_MOD); false if there is no such watch (or it is a
  // receive_datagrams one taken by io_uring).
  bool modify(WatchId id, std::uint32_t events);

  // A datagram socket the loop reads itself where it waits through io_uring: each datagram (or a
  // failed receive) goes to `on_datagram`, in the order received, at most `spec` of it. Otherwise
  // as watch(fd, kReadable, on_readable): the owner reads. Either way unwatch(id) ends it, before
  // the socket is closed. Throws std::system_error.
  // `on_send_failed` hears of each datagram send_datagram() queued that the kernel refused.
  WatchId receive_datagrams(int fd, DatagramSpec spec, DatagramCallback on_datagram, FdCallback on_readable,
                            std::function<void(int error)> on_send_failed = {});
  // Where such a watch is read through io_uring, its owner may send through the ring too: the
  // datagram is copied and sent (send(MSG_DONTWAIT), in the order queued) when the loop next
  // enters the kernel — with its next wait in run(), at the end of run_once() — so a wake-up's
  // answers cost no system call of their own. NotQueued where the loop does not (epoll, another
  // watch): the owner sends itself.
  DatagramSend send_datagram(WatchId id, const void* data, std::size_t size);

  // Brackets every real-time wake-up while watch `id` exists: `begin` after epoll_wait returns,
  // before any callback; `end` after the wake-up's dispatch, also when a callback throws.
  // watch_transport uses it to batch a transport's sends. Removed by unwatch(id).
  void bracket_wakeups(WatchId id, Callback begin, Callback end);

  // Runs `fn` on the loop soon: in the current/next run_once(), or in advance_to().
  void post(Callback fn);
  // Queues `fn` as one slice of work that is not a bus's (see the top of this file): slices run
  // in the order they were deferred, at most one per run_once(), after everything else that
  // wake-up dispatches; run_once() does not block while one waits. A slice with more to do
  // defers its continuation (it then queues behind the others: round robin). advance_to() runs
  // none (it polls no descriptors either).
  void defer(Callback fn);
  [[nodiscard]] std::size_t deferred() const { return deferred_.size(); }

  // Blocks `signals` for the calling thread (call before starting other threads so they inherit
  // the mask) and receives them through a signalfd: `on_signal(signo)`, or stop() if none is
  // given. May be called again to add signals (the latest callback then serves all of them).
  // The destructor restores the previous mask, after discarding any of these signals still
  // pending.
  void handle_signals(std::initializer_list<int> signals, SignalCallback on_signal = {});

  // Runs until stop(). If stop() was called before run(), returns at once. Resets the stop flag
  // on return, so run() can be called again. What the last wake-up sent through the ring
  // (send_datagram) is submitted before it returns.
  void run();
  void stop() { stop_ = true; }
  [[nodiscard]] bool stop_requested() const { return stop_; }

  // One iteration: waits up to `timeout` (nullopt = until something happens; 0 = poll) for
  // descriptors and, in real time, for the next timer; then dispatches ready descriptors, due
  // timers, posted callbacks and one deferred slice. Returns the number of callbacks run. What
  // the wake-up sent through the ring (send_datagram) is submitted before it returns.
  std::size_t run_once(std::optional<Duration> timeout);

  // Deterministic mode only (throws std::logic_error in real time, or if `t` is in the past):
  // runs posted callbacks and fires every timer due up to `t`, in order, moving the clock to each
  // timer's time; then sets the clock to `t` and runs posted callbacks again. Returns the number
  // of callbacks run. Does not poll descriptors.
  std::size_t advance_to(TimePoint t);
  std::size_t advance_by(Duration d) { return advance_to(now() + d); }

 private:
  struct Timer {
    std::shared_ptr<Callback> fn;
    Duration period{0};  // 0 = one-shot
  };
  using TimerKey = std::pair<TimePoint, std::uint64_t>;  // (due, arm sequence)
  struct Watcher {
    int fd;
    std::shared_ptr<FdCallback> fn;
  };

  void init();
  [[nodiscard]] int wait_for_events(std::optional<Duration> timeout, ::epoll_event* events, int max);
  void arm_timer(TimerId id, TimePoint at, Timer timer);
  bool fire_first_timer_due(TimePoint limit);  // fires at most one timer due at or before limit
  std::size_t run_due_timers();
  std::size_t run_posted();
  void arm_timerfd();
  void end_brackets_of(WatchId id);
  std::size_t iterate(std::optional<Duration> timeout);  // run_once() but the ring's sends left queued  // an unwatched
                                                         // id's brackets go; its end runs if in a wake-up
  void on_signalfd();

  std::unique_ptr<UringReceiver> ring_;  // null: epoll_wait
  std::string why_not_io_uring_;
  bool epoll_ready_ = false;  // io_uring: the epoll descriptor is readable (or was left with more)
  WakeClock wake_;            // held from the wake-up to the end of its dispatch (run_once)
  const Clock* clock_ = &wake_;
  SimulatedClock* simulated_ = nullptr;
  int epoll_fd_ = -1;
  int timer_fd_ = -1;
  std::optional<TimePoint> timerfd_armed_;
  int signal_fd_ = -1;
  WatchId signal_watch_ = 0;
  SignalCallback on_signal_;
  bool signals_blocked_ = false;
  sigset_t old_mask_{};
  sigset_t handled_set_{};
  std::map<TimerKey, std::pair<TimerId, Timer>> timers_;
  std::unordered_map<TimerId, TimerKey> timer_keys_;
  std::uint64_t next_timer_id_ = 1;
  std::uint64_t arm_seq_ = 0;
  std::unordered_map<WatchId, Watcher> watchers_;
  struct Bracket {
    WatchId id;
    Callback begin, end;
  };
  std::vector<Bracket> brackets_;
  WatchId next_watch_id_ = 2;  // 1 is the timerfd
  std::deque<Callback> posted_;
  std::deque<Callback> deferred_;
  bool stop_ = false;
};

// Runs a "sans I/O" service's timers from the loop: whenever armed, a loop timer is set at
// service.next_deadline(); when it fires, service.advance(loop.now()) runs and the timer is re-set
// at the new next_deadline(). A service must move its deadline past `now` in advance(now).
class ServiceDriver {
 public:
  using DeadlineFn = std::function<std::optional<TimePoint>()>;
  using AdvanceFn = std::function<void(TimePoint)>;

  ServiceDriver(EventLoop& loop, DeadlineFn next_deadline, AdvanceFn advance);

  template <class Service>
  requires requires(Service& s, TimePoint t) {
    s.advance(t);
    { s.next_deadline() } -> std::convertible_to<std::optional<TimePoint>>;
  }
  ServiceDriver(EventLoop& loop, Service& service)
      : ServiceDriver(
            loop, [&service] { return std::optional<TimePoint>(service.next_deadline()); },
            [&service](TimePoint now) { service.advance(now); }) {}

  ServiceDriver(const ServiceDriver&) = delete;
  ServiceDriver& operator=(const ServiceDriver&) = delete;
  ~ServiceDriver();

  // Re-reads next_deadline() and (re)sets the loop timer. Call after anything that may have
  // changed it (a frame fed in, an API call). The constructor arms once.
  void rearm();
  [[nodiscard]] std::optional<TimePoint> armed_deadline() const { return armed_at_; }

  // Makes `transport` feed received frames to service.on_frame(frame, timestamp), then rearm().
  // The transport keeps a pointer to this driver: destroy the transport (or replace its
  // receiver) before the driver.
  template <class Service>
  requires requires(Service& s, const CanFrame& f, TimePoint t) { s.on_frame(f, t); }
  void bind_receiver(CanTransport& transport, Service& service) {
    transport.set_receiver([this, &service](const CanFrame& frame, TimePoint timestamp) {
      service.on_frame(frame, timestamp);
      rearm();
    });
  }

 private:
  void on_timer();

  EventLoop& loop_;
  DeadlineFn next_deadline_;
  AdvanceFn advance_;
  EventLoop::TimerId timer_ = 0;
  std::optional<TimePoint> armed_at_;
};

// Watches transport.fd() (if >= 0) and calls transport.poll_readable() when it is readable, or,
// where the loop reads datagrams itself (io_uring) and the transport takes them
// (CanTransport::datagram_spec), hands it each datagram (take_datagram); the transport reads "now" from the loop's
// clock (one reading per wake-up) and batches what each wake-up sends (CanTransport::begin_batch/end_batch). Returns
// the watch id, or 0 if the transport has no descriptor. unwatch() the id before the transport goes.
EventLoop::WatchId watch_transport(EventLoop& loop, CanTransport& transport);

}  // namespace oegw::canopen::io
