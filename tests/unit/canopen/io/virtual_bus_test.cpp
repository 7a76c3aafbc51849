#include "canopen/io/virtual_bus.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "canopen/frame_bits.hpp"
#include "canopen/io/event_loop.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
using ::testing::ElementsAre;
using ::testing::IsEmpty;

namespace {

// Records "name<-frame" per receiving port, in global receive order.
struct Recorder {
  std::vector<std::string> seen;
  void listen(VirtualPort& port) {
    port.set_receiver(
        [this, name = port.name()](const CanFrame& f, TimePoint) { seen.push_back(name + "<-" + f.to_string()); });
  }
};

TEST(VirtualBus, DeliversToEveryOtherNodeButNotToTheSender) {
  VirtualBus bus;
  auto a = bus.attach("a");
  auto b = bus.attach("b");
  auto c = bus.attach("c");
  Recorder rec;
  rec.listen(*a);
  rec.listen(*b);
  rec.listen(*c);

  EXPECT_TRUE(b->send(CanFrame{0x181, {1, 2}}).ok());
  EXPECT_THAT(rec.seen, IsEmpty()) << "delivery is queued, not synchronous";
  EXPECT_EQ(bus.pending(), 1u);
  EXPECT_EQ(bus.deliver_all(TimePoint{1s}), 1u);
  EXPECT_THAT(rec.seen, ElementsAre("a<-181#0102", "c<-181#0102"));
  EXPECT_EQ(bus.pending(), 0u);
  EXPECT_EQ(b->counters().tx_frames, 1u);
  EXPECT_EQ(b->counters().rx_frames, 0u);
  EXPECT_EQ(a->counters().rx_frames, 1u);
  EXPECT_EQ(c->counters().rx_frames, 1u);
}

TEST(VirtualBus, KeepsGlobalSendOrderAcrossManyNodes) {
  VirtualBus bus;
  std::vector<std::unique_ptr<VirtualPort>> ports;
  std::vector<std::vector<std::uint32_t>> received(10);
  for (int i = 0; i < 10; ++i) {
    ports.push_back(bus.attach("n" + std::to_string(i)));
    ports.back()->set_receiver(
        [&received, i](const CanFrame& f, TimePoint) { received[static_cast<std::size_t>(i)].push_back(f.id); });
  }
  // Interleaved senders: 0x700+i from node i, twice round.
  for (int round = 0; round < 2; ++round) {
    for (int i = 0; i < 10; ++i)
      ports[static_cast<std::size_t>(i)]->send(CanFrame{0x700u + static_cast<std::uint32_t>(i), {0x05}});
  }
  EXPECT_EQ(bus.deliver_all(TimePoint{}), 20u);
  for (std::size_t i = 0; i < 10; ++i) {
    std::vector<std::uint32_t> expected;
    for (int round = 0; round < 2; ++round) {
      for (std::uint32_t j = 0; j < 10; ++j) {
        if (j != i) expected.push_back(0x700 + j);
      }
    }
    EXPECT_EQ(received[i], expected) << "node " << i;
  }
}

TEST(VirtualBus, FramesSentFromAReceiverGoAfterThoseAlreadyQueuedWithoutReentry) {
  VirtualBus bus;
  auto client = bus.attach("client");
  auto server = bus.attach("server");
  auto other = bus.attach("other");
  int depth = 0;
  int max_depth = 0;
  server->set_receiver([&](const CanFrame& f, TimePoint) {
    ++depth;
    max_depth = std::max(max_depth, depth);
    if (f.id == 0x601) server->send(CanFrame{0x581, {0x60}});  // answer from inside on_frame
    EXPECT_EQ(bus.deliver_all(TimePoint{}), 0u) << "nested deliver_all must not deliver";
    --depth;
  });
  std::vector<std::string> order;
  bus.set_tap([&](const BusRecord& r) { order.push_back(r.to_string()); });
  std::vector<std::string> client_seen;
  client->set_receiver([&](const CanFrame& f, TimePoint) { client_seen.push_back(f.to_string()); });

  client->send(CanFrame{0x601, {0x40}});
  other->send(CanFrame{0x080, {}});
  EXPECT_EQ(bus.deliver_all(TimePoint{2s}), 3u);
  EXPECT_THAT(order, ElementsAre("client: 601#40", "other: 080#", "server: 581#60"));
  EXPECT_THAT(client_seen, ElementsAre("080#", "581#60"));
  EXPECT_EQ(max_depth, 1);
}

TEST(VirtualBus, StampsFramesWithTheDeliveryTime) {
  VirtualBus bus;
  auto a = bus.attach("a");
  auto b = bus.attach("b");
  TimePoint stamp{};
  b->set_receiver([&](const CanFrame&, TimePoint t) { stamp = t; });
  a->send(CanFrame{0x100, {}});
  bus.deliver_all(TimePoint{42ms});
  EXPECT_EQ(stamp, TimePoint{42ms});
}

TEST(VirtualBus, OwnEchoOnlyWhenAskedFor) {
  VirtualBus bus;
  auto echo = bus.attach("echo", PortOptions{.receive_own = true});
  auto plain = bus.attach("plain");
  int echo_rx = 0;
  int plain_rx = 0;
  echo->set_receiver([&](const CanFrame&, TimePoint) { ++echo_rx; });
  plain->set_receiver([&](const CanFrame&, TimePoint) { ++plain_rx; });
  echo->send(CanFrame{0x1, {}});
  plain->send(CanFrame{0x2, {}});
  bus.deliver_all(TimePoint{});
  EXPECT_EQ(echo_rx, 2);   // its own and plain's
  EXPECT_EQ(plain_rx, 1);  // only echo's
}

TEST(VirtualBus, LogRecordsSenderFrameAndTimeOnlyWhenEnabled) {
  VirtualBus bus;
  auto a = bus.attach("a");
  auto b = bus.attach("b");
  a->send(CanFrame{0x10, {}});
  bus.deliver_all(TimePoint{1ms});
  EXPECT_THAT(bus.log(), IsEmpty());
  bus.set_logging(true);
  a->send(CanFrame{0x11, {0xAA}});
  b->send(CanFrame::remote(0x12345, 4));
  bus.inject(CanFrame{0x000, {0x01, 0x00}}, "tester");
  bus.deliver_all(TimePoint{2ms});
  ASSERT_EQ(bus.log().size(), 3u);
  EXPECT_EQ(bus.log()[0].to_string(), "a: 011#AA");
  EXPECT_EQ(bus.log()[1].to_string(), "b: 00012345#R4");
  EXPECT_EQ(bus.log()[2].to_string(), "tester: 000#0100");
  EXPECT_EQ(bus.log()[2].time, TimePoint{2ms});
  bus.clear_log();
  EXPECT_THAT(bus.log(), IsEmpty());
}

TEST(VirtualBus, InjectedFramesReachEveryPort) {
  VirtualBus bus;
  auto a = bus.attach("a");
  auto b = bus.attach("b");
  Recorder rec;
  rec.listen(*a);
  rec.listen(*b);
  bus.inject(CanFrame{0x80, {}});
  bus.deliver_all(TimePoint{});
  EXPECT_THAT(rec.seen, ElementsAre("a<-080#", "b<-080#"));
}

TEST(VirtualBus, DropNextLosesExactlyThatManyFrames) {
  VirtualBus bus;
  auto a = bus.attach("a");
  auto b = bus.attach("b");
  Recorder rec;
  rec.listen(*b);
  bus.set_logging(true);
  bus.drop_next(2);
  for (std::uint8_t i = 1; i <= 4; ++i) EXPECT_TRUE(a->send(CanFrame{0x200, {i}}).ok());
  bus.deliver_all(TimePoint{});
  EXPECT_THAT(rec.seen, ElementsAre("b<-200#03", "b<-200#04"));
  EXPECT_EQ(bus.dropped_frames(), 2u);
  EXPECT_EQ(bus.log().size(), 2u);
}

TEST(VirtualBus, DropNextMatchingOnlyDropsMatchingFrames) {
  VirtualBus bus;
  auto a = bus.attach("a");
  auto b = bus.attach("b");
  Recorder rec;
  rec.listen(*b);
  bus.drop_next(1, [](const CanFrame& f) { return f.id == 0x581; });
  a->send(CanFrame{0x701, {0x05}});
  a->send(CanFrame{0x581, {0x60}});
  a->send(CanFrame{0x581, {0x61}});
  bus.deliver_all(TimePoint{});
  EXPECT_THAT(rec.seen, ElementsAre("b<-701#05", "b<-581#61"));
  EXPECT_EQ(bus.dropped_frames(), 1u);
}

TEST(VirtualBus, DisconnectedNodeIsSilentBothWaysUntilReconnected) {
  VirtualBus bus;
  auto a = bus.attach("a");
  auto b = bus.attach("b");
  Recorder rec;
  rec.listen(*a);
  rec.listen(*b);
  b->set_connected(false);
  EXPECT_TRUE(b->send(CanFrame{0x702, {0x05}}).ok()) << "the controller accepts, the bus never sees it";
  a->send(CanFrame{0x701, {0x05}});
  bus.deliver_all(TimePoint{});
  EXPECT_THAT(rec.seen, IsEmpty());
  EXPECT_EQ(b->counters().tx_dropped, 1u);
  EXPECT_EQ(b->counters().tx_frames, 0u);

  b->set_connected(true);
  b->send(CanFrame{0x702, {0x05}});
  a->send(CanFrame{0x701, {0x05}});
  bus.deliver_all(TimePoint{});
  EXPECT_THAT(rec.seen, ElementsAre("a<-702#05", "b<-701#05"));
}

TEST(VirtualBus, DestroyedPortStopsReceivingAndPortSurvivesBus) {
  auto bus = std::make_unique<VirtualBus>();
  auto a = bus->attach("a");
  auto b = bus->attach("b");
  int b_rx = 0;
  b->set_receiver([&](const CanFrame&, TimePoint) { ++b_rx; });
  a->send(CanFrame{0x1, {}});
  b.reset();  // detached before delivery
  EXPECT_EQ(bus->deliver_all(TimePoint{}), 1u);
  EXPECT_EQ(b_rx, 0);
  bus.reset();
  EXPECT_TRUE(a->send(CanFrame{0x1, {}}).ok());  // no crash, frame vanishes
  EXPECT_EQ(a->counters().tx_dropped, 1u);
}

TEST(VirtualBus, PortDestroyedByAReceiverMidDeliveryIsSkipped) {
  VirtualBus bus;
  auto a = bus.attach("a");
  auto b = bus.attach("b");
  auto c = bus.attach("c");
  int c_rx = 0;
  b->set_receiver([&](const CanFrame&, TimePoint) { c.reset(); });
  c->set_receiver([&](const CanFrame&, TimePoint) { ++c_rx; });
  a->send(CanFrame{0x1, {}});
  bus.deliver_all(TimePoint{});
  EXPECT_EQ(c_rx, 0);
}

TEST(VirtualBus, RejectsMalformedFrames) {
  VirtualBus bus;
  auto a = bus.attach("a");
  CanFrame bad_id;
  bad_id.id = 0x800;  // 11-bit frame with a 12-bit id
  CanFrame bad_dlc{0x100, {}};
  bad_dlc.dlc = 9;
  EXPECT_EQ(a->send(bad_id).status, SendStatus::InvalidFrame);
  EXPECT_EQ(a->send(bad_dlc).status, SendStatus::InvalidFrame);
  EXPECT_EQ(bus.inject(bad_dlc).status, SendStatus::InvalidFrame);
  EXPECT_EQ(bus.pending(), 0u);
  EXPECT_EQ(a->counters().errors, 2u);
}

TEST(VirtualBus, InjectedBusEventsReachTheHandler) {
  VirtualBus bus;
  auto a = bus.attach("a");
  std::vector<BusEvent> events;
  a->set_event_handler([&](BusEvent e) { events.push_back(e); });
  a->inject_event(BusEvent::BusOff);
  a->inject_event(BusEvent::Restarted);
  EXPECT_THAT(events, ElementsAre(BusEvent::BusOff, BusEvent::Restarted));
  EXPECT_EQ(a->counters().error_frames, 2u);
}

TEST(VirtualBus, MaxFramesBoundsOneDeliveryCall) {
  VirtualBus bus;
  auto a = bus.attach("a");
  auto b = bus.attach("b");
  for (int i = 0; i < 5; ++i) a->send(CanFrame{0x1, {}});
  EXPECT_EQ(bus.deliver_all(TimePoint{}, 3), 3u);
  EXPECT_EQ(bus.pending(), 2u);
  EXPECT_EQ(bus.deliver_all(TimePoint{}), 2u);
  EXPECT_EQ(b->counters().rx_frames, 5u);
}

TEST(VirtualBus, KeepsFifoOrderWhenTheQueueIsNeverDrained) {
  // Deliveries in small batches while a receiver keeps sending: the queue never empties (the
  // delivered part is compacted away), and every frame still arrives once, in send order.
  VirtualBus bus;
  auto a = bus.attach("a");
  auto b = bus.attach("b");
  std::vector<std::uint32_t> got;
  std::uint32_t next = 0;
  b->set_receiver([&](const CanFrame& f, TimePoint) {
    got.push_back(get_u32(f.data.data()));
    if (next < 6000) {
      CanFrame g{0x181, {0, 0, 0, 0}};
      put_u32(g.data.data(), next++);
      (void)a->send(g);
    }
  });
  for (int i = 0; i < 3000; ++i) {
    CanFrame g{0x181, {0, 0, 0, 0}};
    put_u32(g.data.data(), next++);
    (void)a->send(g);
  }
  std::size_t rounds = 0;
  while (bus.pending() != 0) {
    EXPECT_LE(bus.deliver_all(TimePoint{}, 7), 7u);
    ++rounds;
  }
  ASSERT_EQ(got.size(), 6000u);
  for (std::uint32_t i = 0; i < got.size(); ++i) ASSERT_EQ(got[i], i);
  EXPECT_GT(rounds, 800u);
}

TEST(VirtualBus, SinkSendsThroughThePort) {
  VirtualBus bus;
  auto a = bus.attach("a");
  auto b = bus.attach("b");
  Recorder rec;
  rec.listen(*b);
  FrameSink sink = a->sink();
  sink(CanFrame{0x181, {0x01}});
  bus.deliver_all(TimePoint{});
  EXPECT_THAT(rec.seen, ElementsAre("b<-181#01"));
}

TEST(VirtualBus, RunOnLoopDeliversWithTheLoopTimeAndSeesRepliesToo) {
  SimulatedClock clock(TimePoint{1s});
  EventLoop loop(clock);
  VirtualBus bus;
  bus.run_on(loop);
  auto a = bus.attach("a");
  auto b = bus.attach("b");
  std::vector<std::pair<std::string, TimePoint>> a_seen;
  a->set_receiver([&](const CanFrame& f, TimePoint t) { a_seen.emplace_back(f.to_string(), t); });
  b->set_receiver([&](const CanFrame& f, TimePoint) {
    if (f.id == 0x601) b->send(CanFrame{0x581, {0x60}});
  });
  // A timer sends at t = 1.5 s; the reply comes back within the same advance.
  loop.call_at(TimePoint{1500ms}, [&] { a->send(CanFrame{0x601, {0x40}}); });
  loop.advance_to(TimePoint{2s});
  ASSERT_EQ(a_seen.size(), 1u);
  EXPECT_EQ(a_seen[0].first, "581#60");
  EXPECT_EQ(a_seen[0].second, TimePoint{1500ms});
  EXPECT_EQ(bus.pending(), 0u);
  // And with run_once (what run() does): a frame sent outside any callback.
  a->send(CanFrame{0x601, {0x40}});
  loop.run_once(0us);
  EXPECT_EQ(a_seen.size(), 2u);
}

TEST(VirtualBus, RunOnLoopDrainsAFloodInBatchesLettingTimersInterleave) {
  SimulatedClock clock;
  EventLoop loop(clock);
  VirtualBus bus;
  bus.run_on(loop);
  auto a = bus.attach("a");
  auto b = bus.attach("b");
  for (int i = 0; i < 3000; ++i) a->send(CanFrame{0x181, {}});
  EXPECT_EQ(bus.pending(), 3000u);
  // One run_once delivers one batch (1024), then the rest follow on later iterations.
  loop.run_once(0us);
  EXPECT_EQ(b->counters().rx_frames, 1024u);
  for (int i = 0; i < 5 && bus.pending() > 0; ++i) loop.run_once(0us);
  EXPECT_EQ(b->counters().rx_frames, 3000u);
  EXPECT_EQ(bus.pending(), 0u);
}

TEST(VirtualBus, RunOnLoopIgnoresPostsAfterTheBusIsGone) {
  SimulatedClock clock;
  EventLoop loop(clock);
  auto bus = std::make_unique<VirtualBus>();
  bus->run_on(loop);
  auto a = bus->attach("a");
  a->send(CanFrame{0x1, {}});  // posts a delivery
  bus.reset();
  EXPECT_NO_FATAL_FAILURE(loop.advance_to(TimePoint{1ms}));
}

}  // namespace

// ---- Time on the wire (run_timed_on) -------------------------------------------------------

namespace {

struct TimedFixture {
  SimulatedClock clock{TimePoint{std::chrono::seconds(100)}};
  EventLoop loop{clock};
  VirtualBus bus;
  std::vector<std::pair<std::string, TimePoint>> seen;  // "frame" and its receive time
  std::unique_ptr<VirtualPort> listener;
  explicit TimedFixture(std::uint32_t bit_rate) {
    bus.run_timed_on(loop, bit_rate);
    listener = bus.attach("listener");
    listener->set_receiver([this](const CanFrame& f, TimePoint t) { seen.emplace_back(f.to_string(), t); });
  }
  [[nodiscard]] Duration since_start(std::size_t i) const {
    return seen.at(i).second - TimePoint{std::chrono::seconds(100)};
  }
};

TEST(TimedVirtualBus, AFrameArrivesAfterItsLengthAtTheBitRate) {
  TimedFixture t(250'000);
  auto a = t.bus.attach("a");
  ASSERT_TRUE(a->send(CanFrame{0x080, {}}).ok());  // SYNC: 51 bits (frame_bits_test)
  t.loop.advance_by(0us);
  EXPECT_TRUE(t.seen.empty()) << "nothing is on the wire at no time";
  // Received at the end of EOF: 51 - 3 intermission bits = 48 bits of 4 us.
  t.loop.advance_by(191us);
  EXPECT_TRUE(t.seen.empty());
  t.loop.advance_by(1us);
  ASSERT_EQ(t.seen.size(), 1u);
  EXPECT_EQ(t.since_start(0), 192us);
  EXPECT_EQ(t.bus.stats().frames, 1u);
  EXPECT_EQ(t.bus.stats().bits, 51u);
  EXPECT_EQ(t.bus.stats().busy, 204us);
}

TEST(TimedVirtualBus, FramesSentTogetherGoByPriorityLowestIdFirst) {
  TimedFixture t(250'000);
  auto a = t.bus.attach("a");
  auto b = t.bus.attach("b");
  // Sent in the reverse order of their priority, at one instant, from two nodes.
  ASSERT_TRUE(a->send(CanFrame{0x701, {0x05}}).ok());        // 58 bits
  ASSERT_TRUE(b->send(CanFrame{0x181, {0x12, 0x34}}).ok());  // 66 bits
  ASSERT_TRUE(a->send(CanFrame{0x000, {0x01, 0x00}}).ok());  // 68 bits
  t.loop.advance_by(10ms);
  ASSERT_EQ(t.seen.size(), 3u);
  EXPECT_EQ(t.seen[0].first, "000#0100");
  EXPECT_EQ(t.seen[1].first, "181#1234");
  EXPECT_EQ(t.seen[2].first, "701#05");
  // Back to back: each starts when the previous one's intermission ends.
  EXPECT_EQ(t.since_start(0), 4us * (68 - 3));
  EXPECT_EQ(t.since_start(1), 4us * (68 + 66 - 3));
  EXPECT_EQ(t.since_start(2), 4us * (68 + 66 + 58 - 3));
  EXPECT_EQ(t.bus.stats().bits, 68u + 66u + 58u);
}

TEST(TimedVirtualBus, AFrameOnTheWireIsNotOvertakenButTheWaitingOnesAreReordered) {
  TimedFixture t(500'000);
  auto a = t.bus.attach("a");
  ASSERT_TRUE(a->send(CanFrame{0x701, {0x05}}).ok());  // alone: it takes the bus (58 bits, 116 us)
  t.loop.advance_by(10us);
  ASSERT_TRUE(a->send(CanFrame{0x581, {0x43, 0, 0x10, 0, 0x91, 0x01, 0x0F, 0x00}}).ok());
  t.loop.advance_by(10us);
  ASSERT_TRUE(a->send(CanFrame{0x080, {}}).ok());  // later, but of higher priority than 581h
  t.loop.advance_by(10ms);
  ASSERT_EQ(t.seen.size(), 3u);
  EXPECT_EQ(t.seen[0].first, "701#05");
  EXPECT_EQ(t.seen[1].first, "080#");
  EXPECT_EQ(t.seen[2].first,
            "581#430010009101"
            "0F00");
  EXPECT_EQ(t.since_start(0), 2us * 55);
  EXPECT_EQ(t.since_start(1), 2us * (58 + 48));
}

TEST(TimedVirtualBus, AnAnswerSentOnReceptionWaitsForTheIntermission) {
  TimedFixture t(1'000'000);
  auto server = t.bus.attach("server");
  auto client = t.bus.attach("client");
  server->set_receiver([&](const CanFrame& f, TimePoint) {
    if (f.id == 0x601) (void)server->send(CanFrame{0x581, {0x60, 0, 0x10, 0, 0, 0, 0, 0}});
  });
  ASSERT_TRUE(client->send(CanFrame{0x601, {0x40, 0x00, 0x10, 0, 0, 0, 0, 0}}).ok());  // 124 bits
  t.loop.advance_by(1ms);
  ASSERT_EQ(t.seen.size(), 2u);
  EXPECT_EQ(t.since_start(0), 121us);
  // The answer starts after the request's 3 intermission bits: 124 us, plus its own length.
  const CanFrame answer{0x581, {0x60, 0, 0x10, 0, 0, 0, 0, 0}};
  EXPECT_EQ(t.since_start(1), 124us + std::chrono::microseconds(frame_bits(answer) - 3));
}

TEST(TimedVirtualBus, DeliverAllIsRefusedAndDroppedFramesNeverTakeTheBus) {
  TimedFixture t(250'000);
  auto a = t.bus.attach("a");
  EXPECT_THROW(t.bus.deliver_all(t.loop.now()), std::logic_error);
  t.bus.drop_next(1);
  ASSERT_TRUE(a->send(CanFrame{0x701, {0x05}}).ok());
  ASSERT_TRUE(a->send(CanFrame{0x702, {0x05}}).ok());
  EXPECT_EQ(t.bus.pending(), 1u);
  t.loop.advance_by(1ms);
  ASSERT_EQ(t.seen.size(), 1u);
  EXPECT_EQ(t.seen[0].first, "702#05");
  EXPECT_EQ(t.bus.stats().frames, 1u);
  EXPECT_EQ(t.bus.dropped_frames(), 1u);
}

TEST(TimedVirtualBus, ABusDestroyedWithAFrameOnTheWireLeavesNoTimerBehind) {
  SimulatedClock clock{TimePoint{std::chrono::seconds(1)}};
  EventLoop loop{clock};
  {
    VirtualBus bus;
    bus.run_timed_on(loop, 125'000);
    auto a = bus.attach("a");
    ASSERT_TRUE(a->send(CanFrame{0x701, {0x05}}).ok());
    loop.advance_by(10us);  // on the wire now
    EXPECT_TRUE(loop.next_timer().has_value());
  }
  EXPECT_FALSE(loop.next_timer().has_value());
  loop.advance_by(10ms);  // nothing fires on the destroyed bus
}

TEST(TimedVirtualBus, ABitRateOfZeroIsRefused) {
  SimulatedClock clock;
  EventLoop loop{clock};
  VirtualBus bus;
  EXPECT_THROW(bus.run_timed_on(loop, 0), std::invalid_argument);
  EXPECT_FALSE(bus.timed());
}

}  // namespace
