// The event loop's two ways of waiting (EventLoop::Wait): through io_uring, where the loop reads
// the buses' datagrams itself (canopen/io/uring_receiver.hpp), and epoll, where each transport
// reads its own. Each behaviour a bus relies on is checked both ways on a SeqpacketCanTransport
// (the I/O SocketCanTransport shares): frames in order with their kernel stamps, more than the
// ring's buffers in one go, a closed peer, an unwatched socket, the other descriptors and the
// timers beside them.
#include <fcntl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <liburing.h>
#include <sys/socket.h>
#include <sys/utsname.h>
#include <unistd.h>

#include <cstdio>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "canopen/io/event_loop.hpp"
#include "canopen/io/seqpacket_transport.hpp"
#include "canopen/io/uring_receiver.hpp"
#include "tests/fixtures/kernel_frame.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
using ::testing::ElementsAre;

namespace {

using oegw::fixtures::kernel_frame;

// Whether this kernel and process can make a ring at all, and the kernel's version, asked
// without the code under test.
bool ring_can_be_made() {
  io_uring ring{};
  if (io_uring_queue_init(4, &ring, 0) != 0) return false;
  io_uring_queue_exit(&ring);
  return true;
}

bool kernel_at_least(int major, int minor) {
  utsname u{};
  if (::uname(&u) != 0) return false;
  int ma = 0;
  int mi = 0;
  if (std::sscanf(u.release, "%d.%d", &ma, &mi) != 2) return false;
  return ma > major || (ma == major && mi >= minor);
}

// One end a transport watched by `loop`, the other a raw descriptor (a prober's).
struct Bus {
  int peer = -1;
  std::unique_ptr<SeqpacketCanTransport> transport;
  EventLoop::WatchId watch = 0;
  std::vector<std::string> got;
  std::vector<TimePoint> stamps;
  std::vector<BusEvent> events;
  explicit Bus(EventLoop& loop) {
    int fds[2];
    SeqpacketCanTransport::make_socketpair(fds);
    transport = SeqpacketCanTransport::adopt(fds[0]);
    peer = fds[1];
    transport->set_receiver([this](const CanFrame& f, TimePoint t) {
      got.push_back(f.to_string());
      stamps.push_back(t);
    });
    transport->set_event_handler([this](BusEvent e) { events.push_back(e); });
    watch = watch_transport(loop, *transport);
  }
  ~Bus() {
    if (peer >= 0) ::close(peer);
  }
  Bus(const Bus&) = delete;
  Bus& operator=(const Bus&) = delete;
  void inject(const ::can_frame& k) const { ASSERT_EQ(::send(peer, &k, sizeof k, 0), static_cast<ssize_t>(sizeof k)); }
};

class LoopWait : public ::testing::TestWithParam<EventLoop::Wait> {};

std::string wait_name(const ::testing::TestParamInfo<EventLoop::Wait>& info) {
  return info.param == EventLoop::Wait::Best ? "IoUring" : "Epoll";
}

// Where the kernel allows io_uring (the ring can be made; Linux 6.0 for multishot recvmsg), the
// loop uses it; where not (qemu-user in the cross tier, a seccomp filter) it says why and waits
// with epoll. Epoll chosen is epoll.
TEST(LoopWaitChoice, TheLoopWaitsThroughIoUringWhereTheKernelAllowsIt) {
  EventLoop best;
  if (ring_can_be_made() && kernel_at_least(6, 0) && std::getenv("OEGW_IO_URING") == nullptr) {
    EXPECT_TRUE(best.uses_io_uring()) << best.why_not_io_uring();
  } else {
    EXPECT_FALSE(best.uses_io_uring());
    EXPECT_FALSE(best.why_not_io_uring().empty());
  }
  EventLoop epoll(EventLoop::Wait::Epoll);
  EXPECT_FALSE(epoll.uses_io_uring());
  SimulatedClock clock;
  EventLoop simulated(clock);
  EXPECT_FALSE(simulated.uses_io_uring());
}

TEST_P(LoopWait, FramesArriveInOrderWithTheirKernelStamps) {
  EventLoop loop(GetParam());
  Bus bus(loop);
  const TimePoint before = SteadyClock().now();
  bus.inject(kernel_frame(0x191, {0x0A, 0x00}));
  bus.inject(kernel_frame(0x18FF0001 | CAN_EFF_FLAG, {0xFF}));
  for (int i = 0; i < 20 && bus.got.size() < 2; ++i) loop.run_once(1s);
  const TimePoint after = SteadyClock().now();
  EXPECT_THAT(bus.got, ElementsAre("191#0A00", "18FF0001#FF"));
  ASSERT_EQ(bus.stamps.size(), 2u);
  for (const TimePoint t : bus.stamps) {
    EXPECT_GE(t, before - 1ms);
    EXPECT_LE(t, after);
  }
  EXPECT_EQ(bus.transport->counters().rx_frames, 2u);
}

// More frames than the ring has buffers (256) queued before the loop looks: every one arrives,
// in order (the ring's request ends for want of buffers and is armed again).
TEST_P(LoopWait, MoreFramesThanTheRingHasBuffersAllArriveInOrder) {
  EventLoop loop(GetParam());
  Bus bus(loop);
  int rcv = 1 << 20;
  ::setsockopt(bus.transport->fd(), SOL_SOCKET, SO_RCVBUF, &rcv, sizeof rcv);
  ::setsockopt(bus.peer, SOL_SOCKET, SO_SNDBUF, &rcv, sizeof rcv);
  constexpr int kFrames = 700;
  int sent = 0;
  for (; sent < kFrames; ++sent) {
    const ::can_frame k = kernel_frame(0x100 + static_cast<canid_t>(sent % 0x600), {static_cast<std::uint8_t>(sent)});
    if (::send(bus.peer, &k, sizeof k, MSG_DONTWAIT) != static_cast<ssize_t>(sizeof k)) break;
  }
  ASSERT_GT(sent, 300) << "the socket buffers took too few to test";
  for (int i = 0; i < 200 && bus.got.size() < static_cast<std::size_t>(sent); ++i) loop.run_once(100ms);
  ASSERT_EQ(bus.got.size(), static_cast<std::size_t>(sent));
  for (int i = 0; i < sent; ++i) {
    char want[32];
    std::snprintf(want, sizeof want, "%03X#%02X", 0x100 + (i % 0x600), i & 0xFF);
    ASSERT_EQ(bus.got[static_cast<std::size_t>(i)], want) << "frame " << i;
  }
}

// The peer closes: reported once (InterfaceDown), and the loop does not spin on the ended socket.
TEST_P(LoopWait, APeerThatClosesIsReportedOnce) {
  EventLoop loop(GetParam());
  Bus bus(loop);
  bus.inject(kernel_frame(0x181, {1}));
  ::close(bus.peer);
  bus.peer = -1;
  for (int i = 0; i < 20 && bus.events.empty(); ++i) loop.run_once(1s);
  EXPECT_THAT(bus.got, ElementsAre("181#01"));
  EXPECT_THAT(bus.events, ElementsAre(BusEvent::InterfaceDown));
  if (loop.uses_io_uring()) {
    // epoll keeps reporting the ended socket (its owner must unwatch it); the ring does not.
    // (Wait::Best is epoll where io_uring is refused: qemu-user in the cross tier.)
    EXPECT_EQ(loop.run_once(0us), 0u);
  }
  loop.unwatch(bus.watch);
  EXPECT_EQ(loop.run_once(0us), 0u);
  EXPECT_THAT(bus.events, ElementsAre(BusEvent::InterfaceDown));
}

// Unwatched, a socket's frames are no longer taken, and the socket may be closed at once and its
// number reused: the new socket's frames go to its own watch only.
TEST_P(LoopWait, AnUnwatchedSocketIsReadNoMoreAndItsNumberMayBeReused) {
  EventLoop loop(GetParam());
  auto first = std::make_unique<Bus>(loop);
  first->inject(kernel_frame(0x101, {1}));
  for (int i = 0; i < 20 && first->got.empty(); ++i) loop.run_once(1s);
  ASSERT_THAT(first->got, ElementsAre("101#01"));
  const int number = first->transport->fd();
  loop.unwatch(first->watch);
  first.reset();
  Bus second(loop);
  EXPECT_EQ(second.transport->fd(), number) << "the lowest free number: the first one's";
  second.inject(kernel_frame(0x102, {2}));
  for (int i = 0; i < 20 && second.got.empty(); ++i) loop.run_once(1s);
  EXPECT_THAT(second.got, ElementsAre("102#02"));
}

// Beside the buses: a descriptor the loop watches the epoll way, reported again while it stays
// readable (level-triggered, as epoll_wait does), and timers on time.
TEST_P(LoopWait, OtherDescriptorsAndTimersAreServedBesideTheBuses) {
  EventLoop loop(GetParam());
  Bus bus(loop);
  int fds[2];
  ASSERT_EQ(::pipe2(fds, O_NONBLOCK | O_CLOEXEC), 0);
  int readable = 0;
  const EventLoop::WatchId pipe_watch = loop.watch(fds[0], events::kReadable, [&](std::uint32_t) { ++readable; });
  ASSERT_EQ(::write(fds[1], "x", 1), 1);
  loop.run_once(1s);
  loop.run_once(1s);
  EXPECT_EQ(readable, 2) << "left readable, reported at the next wake-up too";
  char c;
  ASSERT_EQ(::read(fds[0], &c, 1), 1);
  bool fired = false;
  const TimePoint due = loop.now() + 20ms;
  loop.call_at(due, [&] { fired = true; });
  const TimePoint start = SteadyClock().now();
  while (!fired && SteadyClock().now() - start < 2s) loop.run_once(std::nullopt);
  EXPECT_TRUE(fired);
  EXPECT_GE(SteadyClock().now(), due);
  EXPECT_EQ(readable, 2) << "drained: not reported again";
  bus.inject(kernel_frame(0x181, {3}));
  for (int i = 0; i < 20 && bus.got.empty(); ++i) loop.run_once(1s);
  EXPECT_THAT(bus.got, ElementsAre("181#03"));
  loop.unwatch(pipe_watch);
  ::close(fds[0]);
  ::close(fds[1]);
}

// A receiver that unwatches its own transport while the loop hands it a wake-up's frames: the
// frame being handed over is delivered, nothing after the unwatch is, and nothing is freed under
// the callback (the ring keeps the socket's buffers until no dispatch is under way).
TEST_P(LoopWait, AReceiverThatUnwatchesItsOwnTransportMidWakeUp) {
  EventLoop loop(GetParam());
  Bus bus(loop);
  bus.transport->set_receiver([&](const CanFrame& f, TimePoint) {
    bus.got.push_back(f.to_string());
    if (bus.watch != 0) loop.unwatch(std::exchange(bus.watch, 0));
  });
  bus.inject(kernel_frame(0x101, {1}));
  bus.inject(kernel_frame(0x102, {2}));
  bus.inject(kernel_frame(0x103, {3}));
  for (int i = 0; i < 20 && bus.got.empty(); ++i) loop.run_once(1s);
  ASSERT_FALSE(bus.got.empty());
  EXPECT_EQ(bus.got.front(), "101#01");
  const std::size_t after_unwatch = bus.got.size();  // epoll: the rest of its recvmmsg batch
  bus.inject(kernel_frame(0x104, {4}));
  EXPECT_EQ(loop.run_once(20ms), 0u);
  EXPECT_EQ(bus.got.size(), after_unwatch) << "unwatched: nothing more";
}

// The kernel ends a thread's io_uring requests when the thread exits (-ECANCELED): a loop whose
// first wake-ups ran in a thread that is gone, run on from another, still reads its buses and
// fires its timers.
TEST_P(LoopWait, ALoopRunOnAfterTheThreadThatStartedItExitedStillReadsItsBuses) {
  EventLoop loop(GetParam());
  Bus bus(loop);
  bool fired = false;
  loop.call_after(50ms, [&] { fired = true; });
  std::thread([&] { loop.run_once(0us); }).join();  // the requests submitted there, then it exits
  bus.inject(kernel_frame(0x181, {5}));
  for (int i = 0; i < 20 && bus.got.empty(); ++i) loop.run_once(1s);
  EXPECT_THAT(bus.got, ElementsAre("181#05"));
  for (int i = 0; i < 20 && !fired; ++i) loop.run_once(1s);
  EXPECT_TRUE(fired);
}

TEST(LoopWaitChoice, ATimeNamespaceOffsettingTheMonotonicClockIsSeen) {
  EXPECT_FALSE(monotonic_offset_in("monotonic           0         0\nboottime            0         0\n"));
  EXPECT_TRUE(monotonic_offset_in("monotonic        1000         0\nboottime            0         0\n"));
  EXPECT_TRUE(monotonic_offset_in("monotonic          -1         0\nboottime            0         0\n"));
  EXPECT_TRUE(monotonic_offset_in("monotonic 0 5\n"));
  EXPECT_FALSE(monotonic_offset_in("boottime 1000 0\n")) << "only the monotonic clock matters";
  EXPECT_FALSE(monotonic_offset_in(""));
}

// The loop's next timer moved earlier, then later, then gone: each wait ends at the timer that is
// next now (io_uring: its timeout request updated or removed, not left where it was).
TEST_P(LoopWait, TheWaitFollowsTheNextTimerAsItMoves) {
  EventLoop loop(GetParam());
  bool far_fired = false;
  bool near_fired = false;
  const EventLoop::TimerId far = loop.call_after(10s, [&] { far_fired = true; });
  loop.run_once(0us);  // the far timer is the wait's limit now
  loop.call_after(20ms, [&] { near_fired = true; });
  const TimePoint start = SteadyClock().now();
  for (int i = 0; i < 5 && !near_fired; ++i) loop.run_once(5s);
  EXPECT_TRUE(near_fired) << "the wait did not end at the nearer timer";
  EXPECT_LT(SteadyClock().now() - start, 5s);
  EXPECT_FALSE(far_fired);
  // Earlier, then cancelled before it is due: the wait goes back to the far one (not due yet).
  bool cancelled_fired = false;
  const EventLoop::TimerId cancelled = loop.call_after(30ms, [&] { cancelled_fired = true; });
  loop.run_once(0us);
  EXPECT_TRUE(loop.cancel(cancelled));
  EXPECT_EQ(loop.run_once(60ms), 0u);
  EXPECT_FALSE(cancelled_fired);
  EXPECT_TRUE(loop.cancel(far));
  EXPECT_EQ(loop.run_once(20ms), 0u) << "no timer left: nothing runs";
  // A timer again after none: armed anew.
  bool again = false;
  loop.call_after(10ms, [&] { again = true; });
  for (int i = 0; i < 5 && !again; ++i) loop.run_once(5s);
  EXPECT_TRUE(again);
}

// What one wake-up sends goes out together at its end (the transport's batch), both ways.
TEST_P(LoopWait, AnswersSentInAWakeUpGoOutAtItsEnd) {
  EventLoop loop(GetParam());
  Bus bus(loop);
  bus.transport->set_receiver([&](const CanFrame& f, TimePoint) {
    (void)bus.transport->send(CanFrame{f.id + 1, {f.data[0]}});
  });
  bus.inject(kernel_frame(0x180, {7}));
  bus.inject(kernel_frame(0x190, {8}));
  std::vector<std::string> answers;
  for (int i = 0; i < 20 && answers.size() < 2; ++i) {
    loop.run_once(1s);
    ::can_frame k{};
    while (::recv(bus.peer, &k, sizeof k, MSG_DONTWAIT) == static_cast<ssize_t>(sizeof k)) {
      char text[32];
      std::snprintf(text, sizeof text, "%03X#%02X", k.can_id, k.data[0]);
      answers.emplace_back(text);
    }
  }
  EXPECT_THAT(answers, ElementsAre("181#07", "191#08"));
}

// run(): the answers of the wake-up that stopped the loop are on the wire when run() returns
// (through io_uring they would otherwise wait for a next wait that never comes).
TEST_P(LoopWait, TheLastWakeUpsAnswersAreSentBeforeRunReturns) {
  EventLoop loop(GetParam());
  Bus bus(loop);
  bus.transport->set_receiver([&](const CanFrame& f, TimePoint) {
    (void)bus.transport->send(CanFrame{f.id + 1, {f.data[0]}});
    loop.stop();
  });
  bus.inject(kernel_frame(0x180, {9}));
  loop.run();
  ::can_frame k{};
  ASSERT_EQ(::recv(bus.peer, &k, sizeof k, MSG_DONTWAIT), static_cast<ssize_t>(sizeof k));
  EXPECT_EQ(k.can_id, 0x181u);
  EXPECT_EQ(k.data[0], 9);
}

// One wake-up answering with more frames than a batch holds (64) and than the ring's submission
// queue has entries (64): all on the wire, in order.
TEST_P(LoopWait, ManyAnswersOfOneWakeUpGoOutInOrder) {
  EventLoop loop(GetParam());
  Bus bus(loop);
  constexpr int kAnswers = 150;
  bus.transport->set_receiver([&](const CanFrame&, TimePoint) {
    for (int i = 0; i < kAnswers; ++i)
      (void)bus.transport->send(CanFrame{0x200u + static_cast<std::uint32_t>(i), {static_cast<std::uint8_t>(i)}});
  });
  bus.inject(kernel_frame(0x180, {1}));
  std::vector<canid_t> ids;
  for (int i = 0; i < 20 && ids.size() < kAnswers; ++i) {
    loop.run_once(1s);
    ::can_frame k{};
    while (::recv(bus.peer, &k, sizeof k, MSG_DONTWAIT) == static_cast<ssize_t>(sizeof k)) ids.push_back(k.can_id);
  }
  ASSERT_EQ(ids.size(), static_cast<std::size_t>(kAnswers));
  for (int i = 0; i < kAnswers; ++i) EXPECT_EQ(ids[static_cast<std::size_t>(i)], 0x200u + i) << "answer " << i;
  EXPECT_EQ(bus.transport->counters().tx_frames, static_cast<std::uint64_t>(kAnswers));
}

// More answers than the peer's socket takes: what it did not take is counted as dropped (a full TX
// queue), what it took as sent, both ways — through the ring the refusals come back afterwards.
TEST_P(LoopWait, AnswersTheQueueRefusesAreCountedAsDropped) {
  EventLoop loop(GetParam());
  Bus bus(loop);
  const int small = 4096;
  ::setsockopt(bus.peer, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
  ::setsockopt(bus.transport->fd(), SOL_SOCKET, SO_SNDBUF, &small, sizeof small);
  constexpr int kAnswers = 2000;
  bus.transport->set_receiver([&](const CanFrame&, TimePoint) {
    for (int i = 0; i < kAnswers; ++i) (void)bus.transport->send(CanFrame{0x300, {static_cast<std::uint8_t>(i)}});
  });
  bus.inject(kernel_frame(0x180, {1}));
  for (int i = 0; i < 20 && bus.transport->counters().tx_frames + bus.transport->counters().tx_dropped == 0; ++i)
    loop.run_once(1s);
  loop.run_once(0us);  // the refusals' completions
  int on_the_wire = 0;
  ::can_frame k{};
  while (::recv(bus.peer, &k, sizeof k, MSG_DONTWAIT) == static_cast<ssize_t>(sizeof k)) ++on_the_wire;
  const TransportCounters& c = bus.transport->counters();
  EXPECT_GT(on_the_wire, 0);
  EXPECT_LT(on_the_wire, kAnswers) << "the peer's buffer should have filled";
  EXPECT_EQ(c.tx_frames, static_cast<std::uint64_t>(on_the_wire));
  EXPECT_EQ(c.tx_frames + c.tx_dropped + c.errors, static_cast<std::uint64_t>(kAnswers));
}

// A callback that throws after sending: what the wake-up sent is on the wire all the same (the
// epoll loop's sendmmsg ran as the wake-up unwound; the ring's queue is submitted on the way out).
TEST_P(LoopWait, AnswersOfAWakeUpWhoseCallbackThrowsAreSentAllTheSame) {
  EventLoop loop(GetParam());
  Bus bus(loop);
  bus.transport->set_receiver([&](const CanFrame& f, TimePoint) {
    (void)bus.transport->send(CanFrame{f.id + 1, {f.data[0]}});
    throw std::runtime_error("a callback's bug");
  });
  bus.inject(kernel_frame(0x180, {4}));
  EXPECT_THROW(loop.run_once(1s), std::runtime_error);
  ::can_frame k{};
  ASSERT_EQ(::recv(bus.peer, &k, sizeof k, MSG_DONTWAIT), static_cast<ssize_t>(sizeof k));
  EXPECT_EQ(k.can_id, 0x181u);
}

// A transport whose peer closed, unwatched and closed inside the wake-up in which it answered a
// frame, its descriptor's number taken by a new socket at once: the answer never reaches the new
// socket (what the ring had queued for the old one went before the close).
TEST_P(LoopWait, AnswersQueuedForAClosedSocketNeverReachTheSocketThatTakesItsNumber) {
  EventLoop loop(GetParam());
  auto old_bus = std::make_unique<Bus>(loop);
  std::unique_ptr<Bus> new_bus;
  int number = old_bus->transport->fd();
  // 64 answers: a full batch, handed to the ring within the wake-up (not only at its end).
  old_bus->transport->set_receiver([&](const CanFrame& f, TimePoint) {
    for (int i = 0; i < 64; ++i) (void)old_bus->transport->send(CanFrame{f.id + 1, {f.data[0]}});
  });
  old_bus->transport->set_event_handler([&](BusEvent) {
    loop.unwatch(old_bus->watch);
    loop.post([&] {                // still in this wake-up, once the transport's own call returned
      old_bus->transport.reset();  // closes the descriptor
      new_bus = std::make_unique<Bus>(loop);
    });
  });
  old_bus->inject(kernel_frame(0x180, {6}));
  ::close(old_bus->peer);  // the frame, then the end of the stream: one wake-up
  old_bus->peer = -1;
  for (int i = 0; i < 20 && !new_bus; ++i) loop.run_once(1s);
  ASSERT_TRUE(new_bus);
  EXPECT_EQ(new_bus->transport->fd(), number);
  loop.run_once(20ms);
  ::can_frame k{};
  EXPECT_EQ(::recv(new_bus->peer, &k, sizeof k, MSG_DONTWAIT), -1) << "a frame for the old socket reached the new one";
}

INSTANTIATE_TEST_SUITE_P(Both, LoopWait, ::testing::Values(EventLoop::Wait::Best, EventLoop::Wait::Epoll), wait_name);

}  // namespace
