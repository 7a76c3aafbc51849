// The steady-state bus load `oegw check` predicts from a mapping file (gateway/bus_load.hpp).
// PDOs at their worst-case lengths (canopen/frame_bits.hpp): 8 bytes 98 stuffable bits +
// floor(97 / 4) = 24 stuff bits + 13 = 135 bits. Heartbeats and SYNC at their exact lengths,
// worked out apart from frame_bits.cpp (a script's own CRC-15 and stuffing, ISO 11898-1 §10.5):
// 711h: 05h and 04h 57 bits, 7Fh 58 (3 stuff bits), so 58; 720h: 05h 58, 7Fh and 04h 59, so 59;
// SYNC 080h with no data 51 (4 stuff bits).
#include "gateway/bus_load.hpp"

#include <gtest/gtest.h>

#include "gateway/gateway.hpp"
#include "tests/fixtures/fixtures.hpp"

using namespace oegw;

namespace {

mapping::Config load(const std::string& yaml) {
  auto r = mapping::load_config_text(yaml, "load.yaml", gateway::driver_catalogue());
  EXPECT_TRUE(r.ok()) << r.error_text();
  return *r.config;
}

TEST(BusLoad, OneElobauGripIsItsHeartbeatAndTwoTpdosEvery100Ms) {
  // tests/fixtures/one_grip.yaml: grip 11h, heartbeat 100 ms, TPDO #0 (191h) and #1 (291h),
  // 8 bytes each, event timers 100 ms (the driver's cycle_ms); the gateway's heartbeat 100 ms;
  // both buses at 1 Mbit/s.
  const auto p = gateway::predict_bus_load(load(fixtures::mapping_file("one_grip.yaml")));
  // Downstream: 10/s x 58 + 2 x 10/s x 135 = 3,280 bit/s = 0.328 %.
  EXPECT_DOUBLE_EQ(p.downstream.bits_per_second(), 3280.0);
  EXPECT_DOUBLE_EQ(p.downstream.percent(), 0.328);
  EXPECT_DOUBLE_EQ(p.downstream.frames_per_second(), 30.0);
  ASSERT_EQ(p.downstream.periodic.size(), 3u);
  EXPECT_EQ(p.downstream.periodic[0].cob_id, 0x711u);
  EXPECT_EQ(p.downstream.periodic[0].bits, 58u);
  EXPECT_TRUE(p.downstream.periodic[0].exact);
  EXPECT_FALSE(p.downstream.periodic[1].exact);
  EXPECT_EQ(p.downstream.periodic[1].cob_id, 0x191u);
  EXPECT_EQ(p.downstream.periodic[2].cob_id, 0x291u);
  // Upstream: the gateway's heartbeat 720h, 590 bit/s.
  EXPECT_DOUBLE_EQ(p.upstream.bits_per_second(), 590.0);
  // TPDO #0's 2 ms inhibit time bounds its change-driven frames: listed, not counted.
  bool listed = false;
  for (const auto& c : p.downstream.on_change)
    listed = listed || (c.find("191h") != std::string::npos && c.find("at most 500/s") != std::string::npos);
  EXPECT_TRUE(listed);
  const std::string text = gateway::describe_bus_load(p.downstream, "downstream");
  EXPECT_NE(text.find("downstream 1000000 bit/s: 0.3 % steady state (30.0 frames/s, 3280 bit/s"), std::string::npos)
      << text;
  EXPECT_EQ(text.find("warning"), std::string::npos) << text;
}

TEST(BusLoad, TheMappingFilesSdoWritesAndSyncCountAndAnOverloadedBusWarns) {
  std::string yaml = fixtures::mapping_file("one_grip.yaml");
  // 20 kbit/s, SYNC every 10 ms, the grip's cycle 20 ms, and TPDO #1 made synchronous (type 2:
  // every second SYNC) by the `sdo` list, which the boot writes after the driver's own.
  yaml =
      fixtures::replace_all(yaml,
                            "  bitrate: 1000000\nsubdevices:", "  bitrate: 20000\n  sync_period_ms: 10\nsubdevices:");
  yaml = fixtures::replace_all(yaml, "mandatory: true }",
                               "mandatory: true, options: { cycle_ms: 20 },\n"
                               "          sdo: [ { index: 0x1801, sub_index: 2, value: 2, type: u8 } ] }");
  const auto p = gateway::predict_bus_load(load(yaml));
  // SYNC 100/s x 51 + heartbeat 10/s x 58 + TPDO #0 50/s x 135 + TPDO #1 50/s x 135 (every
  // 2 x 10 ms) = 5,100 + 580 + 6,750 + 6,750 = 19,180 bit/s: 95.9 % of 20 kbit/s.
  EXPECT_DOUBLE_EQ(p.downstream.bits_per_second(), 19180.0);
  const std::string text = gateway::describe_bus_load(p.downstream, "downstream");
  EXPECT_NE(text.find("warning: the downstream bus is 95.9 %"), std::string::npos) << text;
  EXPECT_NE(text.find("grip1 TPDO 291h, 8 bytes, every 2 SYNC"), std::string::npos) << text;
}

}  // namespace
