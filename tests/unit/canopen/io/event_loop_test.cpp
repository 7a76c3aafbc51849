#include "canopen/io/event_loop.hpp"

#include <fcntl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <cstdlib>
#include <functional>
#include <new>
#include <string>
#include <vector>

#include "canopen/io/seqpacket_transport.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "tests/fixtures/kernel_frame.hpp"

// Counts heap allocations (AWakeUpOfABusAllocatesNothing): the replaceable operator new
// ([replacement.functions]) counts, then allocates as the library's own does. Not inlined, so
// GCC does not see free() meet operator new's result.
namespace {
std::size_t g_allocations = 0;
}  // namespace
[[gnu::noinline]] void* operator new(std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
[[gnu::noinline]] void operator delete(void* p) noexcept { std::free(p); }
[[gnu::noinline]] void operator delete(void* p, std::size_t) noexcept { std::free(p); }

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
using ::testing::ElementsAre;
using ::testing::IsEmpty;

namespace {

struct Pipe {
  int r = -1;
  int w = -1;
  Pipe() {
    int fds[2];
    if (::pipe2(fds, O_NONBLOCK | O_CLOEXEC) != 0) throw std::runtime_error("pipe2");
    r = fds[0];
    w = fds[1];
  }
  ~Pipe() {
    ::close(r);
    ::close(w);
  }
};

TEST(EventLoopSimulated, FiresTimersInTimeOrderMovingTheClockToEach) {
  SimulatedClock clock(TimePoint{100ms});
  EventLoop loop(clock);
  std::vector<std::pair<std::string, TimePoint>> fired;
  auto note = [&](std::string name) { return [&, name] { fired.emplace_back(name, loop.now()); }; };
  loop.call_at(TimePoint{300ms}, note("c"));
  loop.call_at(TimePoint{150ms}, note("a"));
  loop.call_after(100ms, note("b"));  // 200 ms
  loop.call_at(TimePoint{400ms}, note("late"));

  EXPECT_EQ(loop.advance_to(TimePoint{350ms}), 3u);
  EXPECT_THAT(fired, ElementsAre(std::pair<std::string, TimePoint>{"a", TimePoint{150ms}},
                                 std::pair<std::string, TimePoint>{"b", TimePoint{200ms}},
                                 std::pair<std::string, TimePoint>{"c", TimePoint{300ms}}));
  EXPECT_EQ(clock.now(), TimePoint{350ms});
  EXPECT_EQ(loop.next_timer(), TimePoint{400ms});
}

TEST(EventLoopSimulated, SameTimeTimersFireInArmingOrder) {
  SimulatedClock clock;
  EventLoop loop(clock);
  std::vector<int> order;
  for (int i = 0; i < 5; ++i) loop.call_at(TimePoint{10ms}, [&, i] { order.push_back(i); });
  loop.advance_to(TimePoint{10ms});  // due exactly at the target: fires
  EXPECT_THAT(order, ElementsAre(0, 1, 2, 3, 4));
}

TEST(EventLoopSimulated, TimerArmedByACallbackWithinTheWindowFiresInTheSameAdvance) {
  SimulatedClock clock;
  EventLoop loop(clock);
  std::vector<TimePoint> fired;
  loop.call_at(TimePoint{10ms}, [&] {
    fired.push_back(loop.now());
    loop.call_after(5ms, [&] { fired.push_back(loop.now()); });
    loop.call_after(50ms, [&] { fired.push_back(loop.now()); });
  });
  loop.advance_to(TimePoint{20ms});
  EXPECT_THAT(fired, ElementsAre(TimePoint{10ms}, TimePoint{15ms}));
  loop.advance_to(TimePoint{60ms});
  EXPECT_THAT(fired, ElementsAre(TimePoint{10ms}, TimePoint{15ms}, TimePoint{60ms}));
}

TEST(EventLoopSimulated, CancelledTimersDoNotFire) {
  SimulatedClock clock;
  EventLoop loop(clock);
  int a = 0;
  int b = 0;
  auto ta = loop.call_at(TimePoint{1ms}, [&] { ++a; });
  auto tb = loop.call_at(TimePoint{2ms}, [&] { ++b; });
  EXPECT_TRUE(loop.pending(ta));
  EXPECT_TRUE(loop.cancel(ta));
  EXPECT_FALSE(loop.cancel(ta));
  EXPECT_FALSE(loop.pending(ta));
  loop.advance_to(TimePoint{5ms});
  EXPECT_EQ(a, 0);
  EXPECT_EQ(b, 1);
  EXPECT_FALSE(loop.cancel(tb)) << "a fired one-shot timer no longer exists";
}

TEST(EventLoopSimulated, ACallbackCanCancelALaterTimerDueInTheSameAdvance) {
  SimulatedClock clock;
  EventLoop loop(clock);
  int later = 0;
  EventLoop::TimerId second = 0;
  loop.call_at(TimePoint{1ms}, [&] { loop.cancel(second); });
  second = loop.call_at(TimePoint{2ms}, [&] { ++later; });
  loop.advance_to(TimePoint{3ms});
  EXPECT_EQ(later, 0);
}

TEST(EventLoopSimulated, PeriodicTimerFiresAtFixedRateUntilItCancelsItself) {
  SimulatedClock clock;
  EventLoop loop(clock);
  std::vector<TimePoint> ticks;
  EventLoop::TimerId id = 0;
  id = loop.call_every(TimePoint{100ms}, 100ms, [&] {
    ticks.push_back(loop.now());
    if (ticks.size() == 4) loop.cancel(id);
  });
  loop.advance_to(TimePoint{250ms});
  EXPECT_THAT(ticks, ElementsAre(TimePoint{100ms}, TimePoint{200ms}));
  loop.advance_to(TimePoint{1s});
  EXPECT_THAT(ticks, ElementsAre(TimePoint{100ms}, TimePoint{200ms}, TimePoint{300ms}, TimePoint{400ms}));
  EXPECT_FALSE(loop.pending(id));
  EXPECT_THROW(loop.call_every(TimePoint{}, 0us, [] {}), std::invalid_argument);
}

TEST(EventLoopSimulated, PostedCallbacksRunBeforeTimersAndInOrder) {
  SimulatedClock clock;
  EventLoop loop(clock);
  std::vector<std::string> order;
  loop.call_at(TimePoint{1ms}, [&] {
    order.push_back("timer");
    loop.post([&] { order.push_back("posted-by-timer"); });
  });
  loop.post([&] { order.push_back("p1"); });
  loop.post([&] {
    order.push_back("p2");
    loop.post([&] { order.push_back("p3"); });
  });
  loop.call_at(TimePoint{2ms}, [&] { order.push_back("timer2"); });
  loop.advance_to(TimePoint{5ms});
  EXPECT_THAT(order, ElementsAre("p1", "p2", "p3", "timer", "posted-by-timer", "timer2"));
}

TEST(EventLoopSimulated, AdvanceRefusesToGoBackAndRealLoopRefusesAdvance) {
  SimulatedClock clock(TimePoint{1s});
  EventLoop loop(clock);
  EXPECT_THROW(loop.advance_to(TimePoint{999ms}), std::logic_error);
  EventLoop real;
  EXPECT_FALSE(real.simulated());
  EXPECT_THROW(real.advance_to(real.now() + 1ms), std::logic_error);
}

TEST(EventLoopSimulated, RunOnceFiresTimersDueNowButNeverMovesTheClock) {
  SimulatedClock clock(TimePoint{1s});
  EventLoop loop(clock);
  int now_timer = 0;
  int future_timer = 0;
  loop.call_at(TimePoint{1s}, [&] { ++now_timer; });
  loop.call_at(TimePoint{2s}, [&] { ++future_timer; });
  EXPECT_EQ(loop.run_once(0us), 1u);
  EXPECT_EQ(now_timer, 1);
  EXPECT_EQ(future_timer, 0);
  EXPECT_EQ(clock.now(), TimePoint{1s});
}

TEST(EventLoopSimulated, AfterAStallAFramePostedByAnOverdueTimerArrivesBeforeALaterDeadlineIsJudged) {
  // A producer's heartbeat due at 100 ms and its consumer's deadline at 250 ms, both in one
  // process (`oegw sim`, a virtual bus delivering by post()). The process stalls until 1 s: one
  // wake-up finds both timers overdue. The heartbeat the producer sends must be delivered before
  // the consumer judges, as advance_to() would have done.
  SimulatedClock clock;
  EventLoop loop(clock);
  VirtualBus bus;
  bus.run_on(loop);
  auto producer = bus.attach("producer");
  auto consumer = bus.attach("consumer");
  std::vector<std::string> order;
  consumer->set_receiver([&](const CanFrame& f, TimePoint) { order.push_back("heartbeat " + f.to_string()); });
  loop.call_at(TimePoint{100ms}, [&] { producer->send(CanFrame{0x721, {0x05}}); });
  loop.call_at(TimePoint{250ms}, [&] { order.push_back("deadline judged"); });
  clock.set(TimePoint{1s});  // the stall
  loop.run_once(0us);
  EXPECT_THAT(order, ElementsAre("heartbeat 721#05", "deadline judged"));
}

TEST(EventLoop, FdWatcherRunsWhenAPipeBecomesReadable) {
  EventLoop loop;
  Pipe p;
  std::string got;
  auto id = loop.watch(p.r, events::kReadable, [&](std::uint32_t ev) {
    EXPECT_TRUE(ev & events::kReadable);
    char buf[16];
    const auto n = ::read(p.r, buf, sizeof buf);
    if (n > 0) got.append(buf, static_cast<std::size_t>(n));
  });
  EXPECT_EQ(loop.run_once(0us), 0u) << "nothing written yet";
  ASSERT_EQ(::write(p.w, "hi", 2), 2);
  EXPECT_EQ(loop.run_once(1s), 1u);  // returns as soon as readable, long before 1 s
  EXPECT_EQ(got, "hi");
  EXPECT_TRUE(loop.unwatch(id));
  EXPECT_FALSE(loop.unwatch(id));
  ASSERT_EQ(::write(p.w, "x", 1), 1);
  EXPECT_EQ(loop.run_once(0us), 0u) << "unwatched: callback must not run";
  EXPECT_EQ(got, "hi");
}

// The wake-up of a bus, nothing posted: no allocation. At 8,000 frames/s every allocation per
// wake-up is thousands of malloc/free pairs a second (oegw_bench_path counted 2 per wake-up of
// `oegw run`: the empty batch of posted callbacks, a std::deque, built every time).
TEST(EventLoop, AWakeUpOfABusAllocatesNothing) {
  EventLoop loop;
  Pipe p;
  int woken = 0;
  loop.watch(p.r, events::kReadable, [&](std::uint32_t) {
    char c;
    while (::read(p.r, &c, 1) == 1) {
    }
    ++woken;
  });
  for (int i = 0; i < 3; ++i) {
    ASSERT_EQ(::write(p.w, "x", 1), 1);
    const std::size_t before = g_allocations;
    EXPECT_EQ(loop.run_once(1s), 1u);
    EXPECT_EQ(g_allocations - before, 0u) << "wake-up " << i;
  }
  EXPECT_EQ(woken, 3);
}

// The same through io_uring: a bus's frame read by the loop into its ring's buffer, handed to the
// transport and the receiver, the ring's buffer given back: no allocation either.
TEST(EventLoop, AWakeUpOfABusThroughIoUringAllocatesNothing) {
  EventLoop loop;
  int fds[2];
  SeqpacketCanTransport::make_socketpair(fds);
  auto transport = SeqpacketCanTransport::adopt(fds[0]);
  int frames = 0;
  transport->set_receiver([&](const CanFrame&, TimePoint) { ++frames; });
  watch_transport(loop, *transport);
  const ::can_frame k = oegw::fixtures::kernel_frame(0x181, {1, 2});
  loop.run_once(0us);  // the ring's request submitted
  for (int i = 0; i < 3; ++i) {
    ASSERT_EQ(::send(fds[1], &k, sizeof k, 0), static_cast<ssize_t>(sizeof k));
    const std::size_t before = g_allocations;
    EXPECT_EQ(loop.run_once(1s), 1u);
    EXPECT_EQ(g_allocations - before, 0u) << "wake-up " << i << (loop.uses_io_uring() ? " (io_uring)" : " (epoll)");
  }
  EXPECT_EQ(frames, 3);
  ::close(fds[1]);
}

TEST(EventLoop, WatchingTheSameFdTwiceThrows) {
  EventLoop loop;
  Pipe p;
  loop.watch(p.r, events::kReadable, [](std::uint32_t) {});
  EXPECT_THROW(loop.watch(p.r, events::kReadable, [](std::uint32_t) {}), std::system_error);
}

TEST(EventLoop, AWatcherRemovedByAnEarlierCallbackInTheSameBatchDoesNotRun) {
  EventLoop loop;
  Pipe p1;
  Pipe p2;
  int runs = 0;
  EventLoop::WatchId w1 = 0;
  EventLoop::WatchId w2 = 0;
  // Whichever runs first removes the other.
  w1 = loop.watch(p1.r, events::kReadable, [&](std::uint32_t) {
    ++runs;
    loop.unwatch(w2);
    loop.unwatch(w1);
  });
  w2 = loop.watch(p2.r, events::kReadable, [&](std::uint32_t) {
    ++runs;
    loop.unwatch(w1);
    loop.unwatch(w2);
  });
  ASSERT_EQ(::write(p1.w, "a", 1), 1);
  ASSERT_EQ(::write(p2.w, "b", 1), 1);
  loop.run_once(0us);
  EXPECT_EQ(runs, 1);
}

// Work that is not a bus's runs in deferred slices, one per wake-up: a descriptor that is
// ready the whole time (a CAN socket with a backlog) is served between every two slices, and the
// slices of several sources take turns.
TEST(EventLoop, DeferredSlicesRunOnePerWakeUpAfterTheDescriptors) {
  SimulatedClock clock;
  EventLoop loop(clock);
  Pipe bus;
  ASSERT_EQ(::write(bus.w, "f", 1), 1);  // never read: readable at every wake-up
  std::string order;
  loop.watch(bus.r, events::kReadable, [&](std::uint32_t) { order += 'B'; });
  int a_left = 3, b_left = 2;
  std::function<void()> a = [&] {
    order += 'a';
    if (--a_left > 0) loop.defer(a);
  };
  std::function<void()> b = [&] {
    order += 'b';
    if (--b_left > 0) loop.defer(b);
  };
  loop.defer(a);
  loop.defer(b);
  EXPECT_EQ(loop.deferred(), 2u);
  for (int i = 0; i < 7; ++i) loop.run_once(0us);
  EXPECT_EQ(order, "BaBbBaBbBaBB") << "one slice per wake-up, after the descriptor; a and b in turn";
  EXPECT_EQ(loop.deferred(), 0u);
}

TEST(EventLoop, RunOnceDoesNotBlockWhileASliceWaits) {
  EventLoop loop;
  int slices = 0;
  loop.defer([&] { ++slices; });
  EXPECT_EQ(loop.run_once(std::nullopt), 1u) << "would block for ever if it waited";
  EXPECT_EQ(slices, 1);
}

TEST(EventLoop, ModifyChangesWhatAWatchWaitsFor) {
  EventLoop loop;
  Pipe p;
  int runs = 0;
  const auto id = loop.watch(p.r, events::kReadable, [&](std::uint32_t) { ++runs; });
  ASSERT_EQ(::write(p.w, "x", 1), 1);
  EXPECT_TRUE(loop.modify(id, 0));
  loop.run_once(0us);
  EXPECT_EQ(runs, 0) << "readable, but not waited for";
  EXPECT_TRUE(loop.modify(id, events::kReadable));
  loop.run_once(0us);
  EXPECT_EQ(runs, 1);
  EXPECT_FALSE(loop.modify(id + 100, events::kReadable));
}

TEST(EventLoop, RealTimerFiresViaTimerfdAndRunStopsFromACallback) {
  EventLoop loop;
  const TimePoint start = loop.now();
  TimePoint fired{};
  int periodic = 0;
  loop.call_every(start + 1ms, 1ms, [&] { ++periodic; });
  loop.call_after(5ms, [&] {
    fired = loop.now();
    loop.stop();
  });
  loop.run();  // blocks in epoll_wait; only the timerfd can wake it
  EXPECT_GE(fired - start, 5ms);
  EXPECT_LT(fired - start, 2s);
  EXPECT_GE(periodic, 1);
  EXPECT_FALSE(loop.stop_requested()) << "run() resets the stop flag";
}

TEST(EventLoop, RunOnceWithTimeoutReturnsWhenNothingHappens) {
  EventLoop loop;
  const TimePoint start = loop.now();
  EXPECT_EQ(loop.run_once(2ms), 0u);
  EXPECT_GE(loop.now() - start, 2ms);
}

// One clock reading per wake-up (WakeClock): everything one wake-up dispatches sees the same
// instant, however long the callbacks take; outside run_once() now() reads the clock.
TEST(EventLoop, EveryCallbackOfAWakeUpSeesTheSameNow) {
  EventLoop loop;
  SteadyClock steady;
  std::vector<TimePoint> seen;
  loop.post([&] {
    seen.push_back(loop.now());
    const TimePoint t = steady.now();
    while (steady.now() < t + 2ms) {
    }  // the clock moves on while this callback runs
  });
  loop.post([&] { seen.push_back(loop.now()); });
  loop.run_once(0us);
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_EQ(seen[0], seen[1]);
  EXPECT_GE(loop.now(), seen[0] + 2ms) << "read again outside the wake-up";
}

TEST(EventLoop, StopBeforeRunReturnsAtOnce) {
  EventLoop loop;
  loop.call_after(10s, [] { FAIL() << "must not wait for this"; });
  loop.stop();
  loop.run();
  SUCCEED();
}

TEST(EventLoop, BlockedSigtermIsDeliveredThroughSignalfdAndStopsTheLoop) {
  EventLoop loop;
  loop.handle_signals({SIGTERM, SIGINT});
  // Blocked now: raise() leaves it pending instead of killing the process.
  sigset_t mask;
  ::pthread_sigmask(SIG_SETMASK, nullptr, &mask);
  EXPECT_EQ(sigismember(&mask, SIGTERM), 1);
  ASSERT_EQ(::raise(SIGTERM), 0);
  bool timer_ran = false;
  loop.call_after(10s, [&] { timer_ran = true; });
  loop.run();  // would hang for 10 s (and then fail) if the signal were not seen
  EXPECT_FALSE(timer_ran);
}

TEST(EventLoop, SignalCallbackGetsTheSignalNumberAndMaskIsRestoredAfterwards) {
  sigset_t before;
  ::pthread_sigmask(SIG_SETMASK, nullptr, &before);
  ASSERT_EQ(sigismember(&before, SIGUSR1), 0);
  {
    EventLoop loop;
    std::vector<int> got;
    loop.handle_signals({SIGUSR1}, [&](int signo) { got.push_back(signo); });
    ASSERT_EQ(::raise(SIGUSR1), 0);
    loop.run_once(1s);
    EXPECT_THAT(got, ElementsAre(SIGUSR1));
    EXPECT_FALSE(loop.stop_requested()) << "a callback replaces the default stop";
    ASSERT_EQ(::raise(SIGUSR1), 0);  // left pending: the destructor must discard it
  }
  sigset_t after;
  ::pthread_sigmask(SIG_SETMASK, nullptr, &after);
  EXPECT_EQ(sigismember(&after, SIGUSR1), 0);
}

// A stand-in for a "sans I/O" service: a heartbeat producer every 100 ms, plus a one-off
// deadline requested by a frame.
struct FakeService {
  TimePoint next_beat;
  std::optional<TimePoint> oneoff;
  std::vector<std::string> log;
  std::optional<TimePoint> next_deadline() const {
    if (oneoff && *oneoff < next_beat) return oneoff;
    return next_beat;
  }
  void advance(TimePoint now) {
    if (oneoff && *oneoff <= now) {
      log.push_back("oneoff@" + std::to_string(now.time_since_epoch().count()));
      oneoff.reset();
    }
    while (next_beat <= now) {
      log.push_back("beat@" + std::to_string(now.time_since_epoch().count()));
      next_beat += 100ms;
    }
  }
  bool on_frame(const CanFrame& f, TimePoint t) {
    log.push_back("frame " + f.to_string());
    oneoff = t + 30ms;
    return true;
  }
};

TEST(ServiceDriver, AdvancesTheServiceAtEachDeadline) {
  SimulatedClock clock;
  EventLoop loop(clock);
  FakeService svc;
  svc.next_beat = TimePoint{100ms};
  ServiceDriver driver(loop, svc);
  EXPECT_EQ(driver.armed_deadline(), TimePoint{100ms});
  loop.advance_to(TimePoint{350ms});
  EXPECT_THAT(svc.log, ElementsAre("beat@100000", "beat@200000", "beat@300000"));
  EXPECT_EQ(driver.armed_deadline(), TimePoint{400ms});
}

TEST(ServiceDriver, FramesFromATransportReachTheServiceAndRearmTheTimer) {
  SimulatedClock clock;
  EventLoop loop(clock);
  VirtualBus bus;
  bus.run_on(loop);
  auto node_port = bus.attach("node");
  auto tester = bus.attach("tester");
  FakeService svc;
  svc.next_beat = TimePoint{100ms};
  ServiceDriver driver(loop, svc);
  driver.bind_receiver(*node_port, svc);

  loop.call_at(TimePoint{120ms}, [&] { tester->send(CanFrame{0x601, {0x40}}); });
  loop.advance_to(TimePoint{260ms});
  // The frame at 120 ms asks for a one-off at 150 ms, before the 200 ms beat.
  EXPECT_THAT(svc.log, ElementsAre("beat@100000", "frame 601#40", "oneoff@150000", "beat@200000"));
}

TEST(ServiceDriver, ExplicitRearmPicksUpAnEarlierDeadlineAndDestructorCancels) {
  SimulatedClock clock;
  EventLoop loop(clock);
  FakeService svc;
  svc.next_beat = TimePoint{1s};
  {
    ServiceDriver driver(loop, svc);
    svc.oneoff = TimePoint{10ms};  // changed behind the driver's back
    driver.rearm();
    EXPECT_EQ(driver.armed_deadline(), TimePoint{10ms});
    loop.advance_to(TimePoint{20ms});
    EXPECT_THAT(svc.log, ElementsAre("oneoff@10000"));
  }
  EXPECT_EQ(loop.next_timer(), std::nullopt) << "destroyed driver must cancel its timer";
  loop.advance_to(TimePoint{2s});
  EXPECT_THAT(svc.log, ElementsAre("oneoff@10000"));
}

TEST(ServiceDriver, IdleServiceArmsNothing) {
  SimulatedClock clock;
  EventLoop loop(clock);
  int advances = 0;
  ServiceDriver driver(
      loop, [] { return std::optional<TimePoint>{}; }, [&](TimePoint) { ++advances; });
  EXPECT_EQ(driver.armed_deadline(), std::nullopt);
  EXPECT_EQ(loop.next_timer(), std::nullopt);
  loop.advance_to(TimePoint{10s});
  EXPECT_EQ(advances, 0);
}

TEST(WatchTransport, TransportWithoutFdIsNotWatched) {
  EventLoop loop;
  VirtualBus bus;
  auto port = bus.attach("p");
  EXPECT_EQ(watch_transport(loop, *port), 0u);
}

}  // namespace
