// SeqpacketCanTransport: CAN_RAW's frames over an AF_UNIX SOCK_SEQPACKET socketpair, with the
// I/O SocketCanTransport shares (CanFrameSocket): one struct can_frame per datagram, kernel
// receive stamps, the loop's batching, a closed peer reported once.
#include "canopen/io/seqpacket_transport.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <linux/can/error.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>
#include <vector>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "tests/fixtures/kernel_frame.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
using ::testing::ElementsAre;

namespace {

using oegw::fixtures::kernel_frame;

// One end a transport, the other a raw descriptor (a prober's).
struct RawPeer {
  int peer = -1;
  std::unique_ptr<SeqpacketCanTransport> transport;
  RawPeer() {
    int fds[2];
    SeqpacketCanTransport::make_socketpair(fds);
    transport = SeqpacketCanTransport::adopt(fds[0]);
    peer = fds[1];
  }
  ~RawPeer() {
    if (peer >= 0) ::close(peer);
  }
  void inject(const ::can_frame& k) const { ASSERT_EQ(::send(peer, &k, sizeof k, 0), static_cast<ssize_t>(sizeof k)); }
};

TEST(SeqpacketCanTransport, APairCarriesFramesBothWaysWithTheirArrivalTimes) {
  auto [a, b] = SeqpacketCanTransport::pair();
  std::vector<std::string> at_a, at_b;
  std::vector<TimePoint> stamps;
  a->set_receiver([&](const CanFrame& f, TimePoint) { at_a.push_back(f.to_string()); });
  b->set_receiver([&](const CanFrame& f, TimePoint t) {
    at_b.push_back(f.to_string());
    stamps.push_back(t);
  });
  SteadyClock clock;
  const TimePoint before = clock.now();
  ASSERT_TRUE(a->send(CanFrame{0x191, {0x0A, 0x00}}).ok());
  ASSERT_TRUE(a->send(CanFrame{0x18FF0001, {0xFF}}).ok());
  ASSERT_TRUE(b->send(CanFrame{0x1A0, {0x01, 0x02, 0x03}}).ok());
  b->poll_readable();
  a->poll_readable();
  const TimePoint after = clock.now();
  EXPECT_THAT(at_b, ElementsAre("191#0A00", "18FF0001#FF"));
  EXPECT_THAT(at_a, ElementsAre("1A0#010203"));
  for (const TimePoint t : stamps) {
    EXPECT_GE(t, before - 1ms);
    EXPECT_LE(t, after);
  }
  EXPECT_EQ(a->counters().tx_frames, 2u);
  EXPECT_EQ(b->counters().rx_frames, 2u);
}

// A datagram is a frame only if it is exactly one struct can_frame: a shorter one, or a longer one
// the kernel cuts to the buffer (MSG_TRUNC, which would otherwise pass as 16 bytes), is counted
// and dropped; the frames around it arrive.
TEST(SeqpacketCanTransport, ADatagramThatIsNotOneFrameIsCountedNotDelivered) {
  RawPeer s;
  std::vector<std::string> got;
  s.transport->set_receiver([&](const CanFrame& f, TimePoint) { got.push_back(f.to_string()); });
  const char shorter[5] = {1, 2, 3, 4, 5};
  ASSERT_EQ(::send(s.peer, shorter, sizeof shorter, 0), 5);
  s.inject(kernel_frame(0x100, {1}));
  char longer[sizeof(::can_frame) + 4] = {};
  const ::can_frame k = kernel_frame(0x181, {7});
  std::memcpy(longer, &k, sizeof k);
  ASSERT_EQ(::send(s.peer, longer, sizeof longer, 0), static_cast<ssize_t>(sizeof longer));
  s.inject(kernel_frame(0x101, {2}));
  s.transport->poll_readable();
  EXPECT_THAT(got, ElementsAre("100#01", "101#02"));
  EXPECT_EQ(s.transport->counters().errors, 2u);
}

TEST(SeqpacketCanTransport, ErrorFramesFromThePeerAreBusEvents) {
  RawPeer s;
  std::vector<BusEvent> events;
  int frames = 0;
  s.transport->set_receiver([&](const CanFrame&, TimePoint) { ++frames; });
  s.transport->set_event_handler([&](BusEvent e) { events.push_back(e); });
  s.inject(kernel_frame(CAN_ERR_FLAG | CAN_ERR_BUSOFF, {0, 0, 0, 0, 0, 0, 0, 0}));
  s.transport->poll_readable();
  EXPECT_THAT(events, ElementsAre(BusEvent::BusOff));
  EXPECT_EQ(frames, 0);
}

// The peer closes its end: the transport says so once (InterfaceDown) and reads nothing more,
// where the end of the stream would otherwise read as 64 empty datagrams at every wake-up.
TEST(SeqpacketCanTransport, APeerThatClosesIsReportedOnceAsInterfaceDown) {
  RawPeer s;
  std::vector<std::string> got;
  std::vector<BusEvent> events;
  s.transport->set_receiver([&](const CanFrame& f, TimePoint) { got.push_back(f.to_string()); });
  s.transport->set_event_handler([&](BusEvent e) { events.push_back(e); });
  s.inject(kernel_frame(0x181, {1}));
  ::close(s.peer);
  s.peer = -1;
  s.transport->poll_readable();
  s.transport->poll_readable();
  EXPECT_THAT(got, ElementsAre("181#01")) << "what came before the close is read";
  EXPECT_THAT(events, ElementsAre(BusEvent::InterfaceDown));
  EXPECT_EQ(s.transport->counters().errors, 1u);
  EXPECT_EQ(s.transport->counters().rx_frames, 1u);
}

// Sending to a closed peer is an error the caller sees (EPIPE), not SIGPIPE ending the process.
TEST(SeqpacketCanTransport, SendingToAClosedPeerIsAnErrorNotASignal) {
  RawPeer s;
  ::close(s.peer);
  s.peer = -1;
  const SendResult r = s.transport->send(CanFrame{0x181, {1}});
  EXPECT_EQ(r.status, SendStatus::Error);
  EXPECT_EQ(r.error, EPIPE);
  EXPECT_EQ(s.transport->counters().errors, 1u);
}

TEST(SeqpacketCanTransport, AFullQueueDropsAndCountsInsteadOfBlocking) {
  RawPeer s;
  SendResult r;
  int sent = 0;
  while ((r = s.transport->send(CanFrame{0x181, {1}})).ok() && sent < 1'000'000) ++sent;
  EXPECT_EQ(r.status, SendStatus::QueueFull) << "after " << sent << " frames";
  EXPECT_GT(sent, 0);
  EXPECT_EQ(s.transport->counters().tx_dropped, 1u);
}

// Through the event loop as `oegw run` drives its buses: a frame in, two frames out of the
// receiver, both leaving together when the wake-up's dispatch ends.
TEST(SeqpacketCanTransport, TheLoopBatchesWhatAWakeUpSends) {
  RawPeer s;
  EventLoop loop;
  int pending_during_dispatch = -1;
  s.transport->set_receiver([&](const CanFrame& f, TimePoint) {
    (void)s.transport->send(CanFrame{f.id + 1, {}});
    (void)s.transport->send(CanFrame{f.id + 2, {}});
    ::ioctl(s.peer, FIONREAD, &pending_during_dispatch);
  });
  ASSERT_NE(watch_transport(loop, *s.transport), 0u);
  s.inject(kernel_frame(0x100, {}));
  loop.run_once(1s);
  EXPECT_EQ(pending_during_dispatch, 0) << "held until the wake-up ends";
  ::can_frame k;
  for (std::uint32_t want : {0x101u, 0x102u}) {
    ASSERT_EQ(::recv(s.peer, &k, sizeof k, MSG_DONTWAIT), static_cast<ssize_t>(sizeof k));
    EXPECT_EQ(k.can_id, want);
  }
  EXPECT_EQ(s.transport->counters().tx_frames, 2u);
}

TEST(SeqpacketCanTransport, AdoptRejectsABadDescriptor) {
  EXPECT_THROW((void)SeqpacketCanTransport::adopt(-1), std::invalid_argument);
}

}  // namespace
