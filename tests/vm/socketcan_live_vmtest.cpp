// Tier 3: the SocketCAN transport on a real vcan interface. Runs only inside the test VM
// (tests/vm, `vm_socketcan_transport`); this machine's own kernel has no AF_CAN. It fails — never
// skips — when there is no CAN interface, so a broken VM set-up cannot pass silently.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>
#include <vector>

#include "canopen/io/event_loop.hpp"
#include "canopen/io/socketcan_transport.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
using ::testing::IsEmpty;

namespace {

TEST(SocketCanLive, RoundTripFiltersTimestampsAndNoOwnEcho) {
  const char* env = std::getenv("OEGW_VCAN");
  const std::string ifname = env ? env : "vcan0";
  const InterfaceInfo info = probe_interface(ifname);
  ASSERT_TRUE(info.exists && info.is_can && info.up) << "no CAN interface '" << ifname << "' up";

  auto a = SocketCanTransport::open(ifname);
  SocketCanOptions only_sdo;
  only_sdo.filters = std::vector<CanFilter>{{0x580, 0x780}};
  auto b = SocketCanTransport::open(ifname, only_sdo);
  ASSERT_GE(a->fd(), 0);

  EventLoop loop;
  watch_transport(loop, *a);
  watch_transport(loop, *b);
  std::vector<std::string> a_seen;
  std::vector<std::pair<std::string, TimePoint>> b_seen;
  a->set_receiver([&](const CanFrame& f, TimePoint) { a_seen.push_back(f.to_string()); });
  b->set_receiver([&](const CanFrame& f, TimePoint t) { b_seen.emplace_back(f.to_string(), t); });

  const TimePoint before = loop.now();
  ASSERT_TRUE(a->send(CanFrame{0x701, {0x05}}).ok());
  ASSERT_TRUE(a->send(CanFrame{0x581, {0x60, 0x00, 0x10, 0x00}}).ok());
  ASSERT_TRUE(a->send(CanFrame::remote(0x5FF, 0)).ok());
  for (int i = 0; i < 50 && b_seen.size() < 2; ++i) loop.run_once(20ms);
  const TimePoint after = loop.now();
  ASSERT_EQ(b_seen.size(), 2u);
  EXPECT_EQ(b_seen[0].first, "581#60001000");
  EXPECT_EQ(b_seen[1].first, "5FF#R");
  EXPECT_GE(b_seen[0].second, before - 1ms);
  EXPECT_LE(b_seen[0].second, after);
  EXPECT_THAT(a_seen, IsEmpty()) << "CAN_RAW_RECV_OWN_MSGS must be off";
  EXPECT_EQ(a->counters().tx_frames, 3u);
  EXPECT_EQ(b->counters().rx_frames, 2u);
}

// oegw-sim's acceptance filter on a real socket: set while open, the kernel drops the data frames
// on the excluded COB-IDs and still delivers their remote frames and everything else; set back
// to nullopt, every frame comes again.
TEST(SocketCanLive, FiltersReplacedWhileOpenWithJoinedExclusions) {
  const char* env = std::getenv("OEGW_VCAN");
  const std::string ifname = env ? env : "vcan0";
  auto reader = SocketCanTransport::open(ifname);
  auto sender = SocketCanTransport::open(ifname);
  EventLoop loop;
  watch_transport(loop, *reader);
  std::vector<std::string> seen;
  reader->set_receiver([&](const CanFrame& f, TimePoint) { seen.push_back(f.to_string()); });
  const auto send_all_and_read = [&] {
    seen.clear();
    ASSERT_TRUE(sender->send(CanFrame{0x191, {0x01}}).ok());
    ASSERT_TRUE(sender->send(CanFrame::remote(0x191, 0)).ok());
    ASSERT_TRUE(sender->send(CanFrame{0x291, {0x02}}).ok());
    ASSERT_TRUE(sender->send(CanFrame{0x192, {0x03}}).ok());
    ASSERT_TRUE(sender->send(CanFrame{0x701, {0x05}}).ok());  // the last: all before it are in
    for (int i = 0; i < 50 && (seen.empty() || seen.back() != "701#05"); ++i) loop.run_once(20ms);
  };
  reader->set_filters(all_but_data_frames_on({CobId{0x191}, CobId{0x291}}), true);
  send_all_and_read();
  EXPECT_THAT(seen, ::testing::ElementsAre("191#R", "192#03", "701#05"));
  reader->set_filters(std::nullopt, false);
  send_all_and_read();
  EXPECT_THAT(seen, ::testing::ElementsAre("191#01", "191#R", "291#02", "192#03", "701#05"));
}

// A reader held off while a 1 Mbit/s bus runs full loses nothing for half a second.
// 3,000 frames (~0.4 s of such a bus) arrive while the reader does not read; with the kernel's
// default receive buffer (~200 frames) the kernel drops most of them (SO_RXQ_OVFL), with the
// transport's default (SocketCanOptions::rx_buffer_bytes) all arrive, in order. The test runs
// as root in the VM, so SO_RCVBUFFORCE applies; rx_buffer_bytes 0 keeps the kernel's default
// and shows the loss the larger buffer prevents (so the test would fail without it).
std::pair<std::uint64_t, std::uint64_t> burst_while_not_reading(const std::string& ifname, std::size_t rx_buffer) {
  SocketCanOptions opts;
  opts.filters = std::vector<CanFilter>{{0x191, 0x7FF}};
  opts.rx_buffer_bytes = rx_buffer;
  auto reader = SocketCanTransport::open(ifname, opts);
  auto sender = SocketCanTransport::open(ifname);
  constexpr int kFrames = 3000;
  std::uint64_t next = 0;
  bool in_order = true;
  reader->set_receiver([&](const CanFrame& f, TimePoint) {
    const std::uint64_t v = f.data[0] | (std::uint64_t{f.data[1]} << 8);
    in_order = in_order && v >= next;
    next = v + 1;
  });
  for (int i = 0; i < kFrames; ++i)
    EXPECT_TRUE(sender->send(CanFrame{0x191, {static_cast<std::uint8_t>(i), static_cast<std::uint8_t>(i >> 8)}}).ok());
  EventLoop loop;
  watch_transport(loop, *reader);
  // Then read until all have come or nothing more comes for 200 ms (vcan delivers at once).
  std::uint64_t seen = 0;
  for (int quiet = 0; quiet < 10 && reader->counters().rx_frames < kFrames;) {
    loop.run_once(20ms);
    quiet = reader->counters().rx_frames == seen ? quiet + 1 : 0;
    seen = reader->counters().rx_frames;
  }
  EXPECT_TRUE(in_order);
  // SO_RXQ_OVFL: a frame carries the drop count as it was when the frame was queued, so the
  // drops after the last frame read show with the next one: one more frame to carry them.
  EXPECT_TRUE(sender->send(CanFrame{0x191, {0xFF, 0xFF}}).ok());
  for (int i = 0; i < 10 && reader->counters().rx_frames == seen; ++i) loop.run_once(20ms);
  EXPECT_EQ(reader->counters().rx_frames, seen + 1) << "the frame after the burst did not come";
  return {seen, reader->counters().rx_dropped};
}

TEST(SocketCanLive, ReceiveBufferHoldsHalfASecondOfAFullBus) {
  const char* env = std::getenv("OEGW_VCAN");
  const std::string ifname = env ? env : "vcan0";
  {
    auto probe = SocketCanTransport::open(ifname);
    EXPECT_GE(probe->rx_buffer_bytes(), SocketCanOptions::kDefaultRxBufferBytes);
    EXPECT_FALSE(probe->rx_buffer_capped());
  }
  const auto [got, dropped] = burst_while_not_reading(ifname, SocketCanOptions::kDefaultRxBufferBytes);
  EXPECT_EQ(got, 3000u);
  EXPECT_EQ(dropped, 0u);
  const auto [got_small, dropped_small] = burst_while_not_reading(ifname, 0);
  EXPECT_LT(got_small, 3000u) << "the kernel's default buffer held the whole burst: the test shows nothing";
  EXPECT_GT(dropped_small, 0u);
  EXPECT_EQ(got_small + dropped_small, 3000u);
}

}  // namespace
