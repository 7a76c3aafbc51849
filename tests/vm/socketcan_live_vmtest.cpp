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

}  // namespace
