#include "canopen/io/event_loop.hpp"

#include "canopen/io/uring_receiver.hpp"

#include <sys/epoll.h>
#include <sys/signalfd.h>
#include <sys/timerfd.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <stdexcept>
#include <system_error>

namespace oegw::canopen::io {

static_assert(events::kReadable == EPOLLIN && events::kWritable == EPOLLOUT && events::kError == EPOLLERR &&
              events::kHangup == EPOLLHUP);

namespace {

constexpr std::uint64_t kTimerFdWatch = 1;

[[noreturn]] void throw_errno(const char* what) { throw std::system_error(errno, std::generic_category(), what); }

}  // namespace

EventLoop::EventLoop(Wait wait) {
  init();
  if (wait == Wait::Best) {
    ring_ = UringReceiver::open(epoll_fd_, &why_not_io_uring_);
  } else {
    why_not_io_uring_ = "epoll chosen";
  }
}

EventLoop::EventLoop(SimulatedClock& clock) : clock_(&clock), simulated_(&clock) { init(); }

void EventLoop::init() {
  sigemptyset(&old_mask_);
  sigemptyset(&handled_set_);
  epoll_fd_ = ::epoll_create1(EPOLL_CLOEXEC);
  if (epoll_fd_ < 0) throw_errno("epoll_create1");
  if (simulated_ != nullptr) return;  // simulated time needs no timerfd
  timer_fd_ = ::timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC);
  if (timer_fd_ < 0) {
    const int e = errno;
    ::close(epoll_fd_);
    throw std::system_error(e, std::generic_category(), "timerfd_create(CLOCK_MONOTONIC)");
  }
  epoll_event ev{};
  ev.events = EPOLLIN;
  ev.data.u64 = kTimerFdWatch;
  if (::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, timer_fd_, &ev) != 0) {
    const int e = errno;
    ::close(timer_fd_);
    ::close(epoll_fd_);
    throw std::system_error(e, std::generic_category(), "epoll_ctl(timerfd)");
  }
}

EventLoop::~EventLoop() {
  ring_.reset();  // ends its requests before the descriptors they poll go
  if (signal_fd_ >= 0) {
    // Discard what is still pending, so that unblocking cannot kill the process.
    signalfd_siginfo info{};
    while (::read(signal_fd_, &info, sizeof info) == static_cast<ssize_t>(sizeof info)) {
    }
    ::close(signal_fd_);
  }
  if (signals_blocked_) ::pthread_sigmask(SIG_SETMASK, &old_mask_, nullptr);
  if (timer_fd_ >= 0) ::close(timer_fd_);
  if (epoll_fd_ >= 0) ::close(epoll_fd_);
}

// ---- timers -------------------------------------------------------------------------------

void EventLoop::arm_timer(TimerId id, TimePoint at, Timer timer) {
  const TimerKey key{at, arm_seq_++};
  timers_.emplace(key, std::make_pair(id, std::move(timer)));
  timer_keys_[id] = key;
}

EventLoop::TimerId EventLoop::call_at(TimePoint at, Callback fn) {
  const TimerId id = next_timer_id_++;
  arm_timer(id, at, Timer{std::make_shared<Callback>(std::move(fn)), Duration{0}});
  return id;
}

EventLoop::TimerId EventLoop::call_every(TimePoint first, Duration period, Callback fn) {
  if (period <= Duration::zero()) throw std::invalid_argument("EventLoop::call_every: period must be positive");
  const TimerId id = next_timer_id_++;
  arm_timer(id, first, Timer{std::make_shared<Callback>(std::move(fn)), period});
  return id;
}

bool EventLoop::cancel(TimerId id) {
  auto it = timer_keys_.find(id);
  if (it == timer_keys_.end()) return false;
  timers_.erase(it->second);
  timer_keys_.erase(it);
  return true;
}

std::optional<TimePoint> EventLoop::next_timer() const {
  if (timers_.empty()) return std::nullopt;
  return timers_.begin()->first.first;
}

bool EventLoop::fire_first_timer_due(TimePoint limit) {
  if (timers_.empty()) return false;
  auto it = timers_.begin();
  const TimePoint due = it->first.first;
  if (due > limit) return false;
  const TimerId id = it->second.first;
  Timer timer = std::move(it->second.second);
  timers_.erase(it);
  timer_keys_.erase(id);
  if (timer.period > Duration::zero()) {
    // Fixed rate; skip whole periods missed (only possible in real time).
    TimePoint next = due + timer.period;
    const TimePoint current = now();
    if (next <= current) next += ((current - next) / timer.period + 1) * timer.period;
    arm_timer(id, next, timer);  // before the call, so the callback may cancel it
  }
  std::shared_ptr<Callback> fn = timer.fn;  // keeps it alive if the callback cancels its timer
  (*fn)();
  return true;
}

std::size_t EventLoop::run_due_timers() {
  std::size_t n = 0;
  // Work posted before a due timer runs before it, as in advance_to(). After a stall every
  // overdue timer fires in one wake-up: a frame a timer sends on a virtual bus (delivered by
  // post()) must reach its receiver before a later timer judges that receiver's deadline, or a
  // sender and a receiver that were late together look like a lost sender. With no timer due,
  // nothing runs here: iterate() runs one batch, so a flood of posts cannot starve the
  // descriptors. Bounded by the timers due now: a periodic timer is re-armed in the future, so
  // this ends unless callbacks keep arming timers in the past; each pass runs only what was
  // posted before it.
  for (;;) {
    const std::optional<TimePoint> next = next_timer();
    if (!next || *next > now()) break;
    n += run_posted();
    if (fire_first_timer_due(now())) ++n;
  }
  return n;
}

void EventLoop::arm_timerfd() {
  if (timer_fd_ < 0) return;
  const std::optional<TimePoint> next = next_timer();
  if (next == timerfd_armed_) return;
  itimerspec spec{};
  if (next) {
    auto us = next->time_since_epoch().count();
    if (us <= 0) us = 1;  // an all-zero it_value would disarm
    spec.it_value.tv_sec = static_cast<time_t>(us / 1'000'000);
    spec.it_value.tv_nsec = static_cast<long>((us % 1'000'000) * 1'000);
  }
  if (::timerfd_settime(timer_fd_, TFD_TIMER_ABSTIME, &spec, nullptr) != 0) throw_errno("timerfd_settime");
  timerfd_armed_ = next;
}

// ---- fds, posts, signals -----------------------------------------------------------------

EventLoop::WatchId EventLoop::watch(int fd, std::uint32_t events, FdCallback fn) {
  const WatchId id = next_watch_id_++;
  epoll_event ev{};
  ev.events = events;
  ev.data.u64 = id;
  if (::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, fd, &ev) != 0) throw_errno("epoll_ctl(EPOLL_CTL_ADD)");
  watchers_.emplace(id, Watcher{fd, std::make_shared<FdCallback>(std::move(fn))});
  return id;
}

EventLoop::WatchId EventLoop::receive_datagrams(int fd, DatagramSpec spec, DatagramCallback on_datagram,
                                                FdCallback on_readable, std::function<void(int)> on_send_failed) {
  if (!ring_) return watch(fd, events::kReadable, std::move(on_readable));
  const WatchId id = next_watch_id_++;
  try {
    ring_->add(id, fd, spec, std::move(on_datagram), std::move(on_send_failed));
  } catch (const std::system_error& e) {
    if (e.code().value() == EEXIST) throw;
    // The kernel refused the socket's buffers (memory): this socket is read the epoll way.
    return watch(fd, events::kReadable, std::move(on_readable));
  }
  return id;
}

DatagramSend EventLoop::send_datagram(WatchId id, const void* data, std::size_t size) {
  return ring_ ? ring_->send(id, data, size) : DatagramSend::NotQueued;
}

bool EventLoop::unwatch(WatchId id) {
  if (ring_ && ring_->remove(id)) {
    end_brackets_of(id);
    return true;
  }
  auto it = watchers_.find(id);
  if (it == watchers_.end()) return false;
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, it->second.fd, nullptr);  // fails only if already closed
  watchers_.erase(it);
  end_brackets_of(id);
  return true;
}

void EventLoop::end_brackets_of(WatchId id) {
  // Unwatched during a wake-up: its end comes now (a transport's held frames go out), not never.
  for (std::size_t i = 0; i < brackets_.size();) {
    if (brackets_[i].id != id) {
      ++i;
      continue;
    }
    const Bracket b = std::move(brackets_[i]);
    brackets_.erase(brackets_.begin() + static_cast<std::ptrdiff_t>(i));
    if (wake_.held()) b.end();
  }
}

bool EventLoop::modify(WatchId id, std::uint32_t events) {
  const auto it = watchers_.find(id);
  if (it == watchers_.end()) return false;
  epoll_event ev{};
  ev.events = events;
  ev.data.u64 = id;
  if (::epoll_ctl(epoll_fd_, EPOLL_CTL_MOD, it->second.fd, &ev) != 0) throw_errno("epoll_ctl(EPOLL_CTL_MOD)");
  return true;
}

void EventLoop::bracket_wakeups(WatchId id, Callback begin, Callback end) {
  brackets_.push_back(Bracket{id, std::move(begin), std::move(end)});
}

void EventLoop::post(Callback fn) { posted_.push_back(std::move(fn)); }

void EventLoop::defer(Callback fn) { deferred_.push_back(std::move(fn)); }

std::size_t EventLoop::run_posted() {
  // Most wake-ups (a bus's frames) post nothing: then no batch is built (an empty std::deque
  // allocates its map and a first block).
  if (posted_.empty()) return 0;
  // Only what was posted before this call: callbacks posting again do not starve descriptors.
  std::deque<Callback> batch;
  batch.swap(posted_);
  for (auto& fn : batch) fn();
  return batch.size();
}

void EventLoop::handle_signals(std::initializer_list<int> signals, SignalCallback on_signal) {
  sigset_t add;
  sigemptyset(&add);
  for (int s : signals) {
    if (sigaddset(&add, s) != 0) throw std::invalid_argument("EventLoop::handle_signals: bad signal number");
    sigaddset(&handled_set_, s);
  }
  sigset_t previous;
  if (const int e = ::pthread_sigmask(SIG_BLOCK, &add, &previous); e != 0) {
    throw std::system_error(e, std::generic_category(), "pthread_sigmask");
  }
  if (!signals_blocked_) {
    old_mask_ = previous;
    signals_blocked_ = true;
  }
  const int fd = ::signalfd(signal_fd_, &handled_set_, SFD_NONBLOCK | SFD_CLOEXEC);
  if (fd < 0) throw_errno("signalfd");
  on_signal_ = std::move(on_signal);
  if (signal_fd_ < 0) {
    signal_fd_ = fd;
    signal_watch_ = watch(signal_fd_, events::kReadable, [this](std::uint32_t) { on_signalfd(); });
  }
}

void EventLoop::on_signalfd() {
  signalfd_siginfo info{};
  while (::read(signal_fd_, &info, sizeof info) == static_cast<ssize_t>(sizeof info)) {
    if (on_signal_) {
      on_signal_(static_cast<int>(info.ssi_signo));
    } else {
      stop();
    }
  }
}

// ---- running ------------------------------------------------------------------------------

// Waits for this wake-up's events: the epoll descriptors ready (into `events`, how many
// returned), and through io_uring the datagrams received (taken by dispatch below).
int EventLoop::wait_for_events(std::optional<Duration> timeout, epoll_event* events, int max) {
  const bool busy = !posted_.empty() || !deferred_.empty();
  if (ring_) {
    // The timers are the ring's timeout request (no timerfd, no clock reading here).
    ring_->set_timer(next_timer());
    ring_->wait(busy || epoll_ready_ ? std::optional<Duration>(Duration::zero()) : timeout);
    return 0;
  }
  arm_timerfd();
  int timeout_ms = -1;
  if (busy) {
    timeout_ms = 0;
  } else if (timeout) {
    const auto ms = (*timeout + std::chrono::microseconds(999)) / std::chrono::milliseconds(1);  // round up
    timeout_ms = ms <= 0 ? 0 : static_cast<int>(std::min<long long>(ms, INT_MAX));
  }
  if (simulated() && !timers_.empty() && timers_.begin()->first.first <= now()) timeout_ms = 0;
  const int n = ::epoll_wait(epoll_fd_, events, max, timeout_ms);
  if (n < 0) {
    if (errno != EINTR) throw_errno("epoll_wait");
    return 0;
  }
  return n;
}

namespace {

// The ring's queued sends submitted on the way out, also when a callback throws (as the epoll
// loop's sendmmsg at the wake-up's end sent them); a failure then is not the one to report.
struct FlushOnExit {
  explicit FlushOnExit(UringReceiver* r) : ring(r) {}
  UringReceiver* ring;
  FlushOnExit(const FlushOnExit&) = delete;
  FlushOnExit& operator=(const FlushOnExit&) = delete;
  ~FlushOnExit() {
    if (ring == nullptr) return;
    try {
      ring->flush();
    } catch (const std::system_error&) {
    }
  }
};

}  // namespace

std::size_t EventLoop::run_once(std::optional<Duration> timeout) {
  const FlushOnExit flush{ring_.get()};
  return iterate(timeout);
}

std::size_t EventLoop::iterate(std::optional<Duration> timeout) {
  constexpr int kMaxEvents = 32;
  epoll_event events[kMaxEvents];
  int n = wait_for_events(timeout, events, kMaxEvents);
  // One clock reading for everything this wake-up dispatches (WakeClock); released on the way out,
  // also when a callback throws.
  struct Hold {
    WakeClock* clock;
    std::vector<Bracket>* brackets;
    ~Hold() {
      if (clock == nullptr) return;
      // Sends held in this wake-up go out here. By index: a callback may unwatch (rare).
      for (std::size_t i = 0; i < brackets->size(); ++i) (*brackets)[i].end();
      clock->release();
    }
  } hold{simulated() || wake_.held() ? nullptr : &wake_, &brackets_};
  if (hold.clock != nullptr) {
    hold.clock->hold();
    for (std::size_t i = 0; i < brackets_.size(); ++i) brackets_[i].begin();
  }
  std::size_t ran = 0;
  if (ring_) {
    ran += ring_->dispatch(epoll_ready_);
    if (epoll_ready_) {
      n = ::epoll_wait(epoll_fd_, events, kMaxEvents, 0);
      if (n < 0) {
        if (errno != EINTR) throw_errno("epoll_wait");
        n = 0;
      }
      // A full batch may have left more: the next wake-up does not wait for them.
      epoll_ready_ = n == kMaxEvents;
      ring_->poll_again();
    }
  }
  for (int i = 0; i < n; ++i) {
    const std::uint64_t id = events[i].data.u64;
    if (id == kTimerFdWatch) {
      std::uint64_t expirations = 0;
      (void)!::read(timer_fd_, &expirations, sizeof expirations);
      timerfd_armed_.reset();  // fired: must be re-armed even for the same time
      continue;
    }
    auto it = watchers_.find(id);
    if (it == watchers_.end()) continue;  // removed by an earlier callback in this batch
    std::shared_ptr<FdCallback> fn = it->second.fn;
    (*fn)(events[i].events);
    ++ran;
  }
  ran += run_due_timers();
  ran += run_posted();
  if (!deferred_.empty()) {
    // One slice; the buses' descriptors are polled again before the next.
    Callback slice = std::move(deferred_.front());
    deferred_.pop_front();
    slice();
    ++ran;
  }
  return ran;
}

void EventLoop::run() {
  // The ring's sends of one wake-up go with the next wait's system call.
  const FlushOnExit flush{ring_.get()};
  while (!stop_) iterate(std::nullopt);
  stop_ = false;
}

std::size_t EventLoop::advance_to(TimePoint t) {
  if (simulated_ == nullptr) throw std::logic_error("EventLoop::advance_to needs a SimulatedClock");
  if (t < now()) throw std::logic_error("EventLoop::advance_to: time would go backwards");
  std::size_t ran = 0;
  for (;;) {
    while (!posted_.empty()) ran += run_posted();
    if (timers_.empty() || timers_.begin()->first.first > t) break;
    const TimePoint due = timers_.begin()->first.first;
    if (due > now()) simulated_->set(due);
    if (fire_first_timer_due(t)) ++ran;
  }
  simulated_->set(t);
  while (!posted_.empty()) ran += run_posted();
  return ran;
}

// ---- ServiceDriver ------------------------------------------------------------------------

ServiceDriver::ServiceDriver(EventLoop& loop, DeadlineFn next_deadline, AdvanceFn advance)
    : loop_(loop), next_deadline_(std::move(next_deadline)), advance_(std::move(advance)) {
  rearm();
}

ServiceDriver::~ServiceDriver() {
  if (timer_ != 0) loop_.cancel(timer_);
}

void ServiceDriver::rearm() {
  const std::optional<TimePoint> deadline = next_deadline_();
  if (timer_ != 0 && deadline == armed_at_) return;
  if (timer_ != 0) loop_.cancel(timer_);
  timer_ = 0;
  armed_at_ = deadline;
  if (deadline) timer_ = loop_.call_at(*deadline, [this] { on_timer(); });
}

void ServiceDriver::on_timer() {
  timer_ = 0;
  armed_at_.reset();
  advance_(loop_.now());
  rearm();
}

EventLoop::WatchId watch_transport(EventLoop& loop, CanTransport& transport) {
  const int fd = transport.fd();
  if (fd < 0) return 0;
  transport.set_clock(&loop.clock());
  auto readable = [&transport](std::uint32_t) { transport.poll_readable(); };
  const std::optional<DatagramSpec> spec = transport.datagram_spec();
  const EventLoop::WatchId id =
      spec ? loop.receive_datagrams(
                 fd, *spec, [&transport](const ReceivedDatagram& d) { transport.take_datagram(d); }, readable,
                 [&transport](int error) { transport.datagram_send_failed(error); })
           : loop.watch(fd, events::kReadable, readable);
  // NotQueued once unwatched (or read the epoll way): the transport then sends itself. Without a
  // ring none: a sender of another loop the transport was watched by before would outlive it.
  transport.set_datagram_sender(spec && loop.uses_io_uring()
                                    ? DatagramSender([&loop, id](const void* data, std::size_t size) {
                                        return loop.send_datagram(id, data, size);
                                      })
                                    : DatagramSender());
  loop.bracket_wakeups(
      id, [&transport] { transport.begin_batch(); }, [&transport] { transport.end_batch(); });
  return id;
}

}  // namespace oegw::canopen::io
