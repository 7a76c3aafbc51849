// The Gateway end to end on the virtual buses (tests/bench/gateway_rig.hpp): the real boot of its
// sub-devices against the simulators, a host enabling TPDO 1, then frames fed to the hot path.
#include <gtest/gtest.h>

#include <vector>

#include "tests/bench/gateway_rig.hpp"

using namespace oegw;
using namespace std::chrono_literals;

namespace {

canopen::CanFrame grip1_frame(std::int8_t x, std::uint8_t buttons = 0) {
  return canopen::CanFrame(0x191, {static_cast<std::uint8_t>(x), 0, 0, 0, 0, buttons, 0, 0xFF});
}

std::unique_ptr<bench::GatewayRig> booted(const std::string& yaml) {
  auto rig = std::make_unique<bench::GatewayRig>(bench::load_or_throw(yaml, "test.yaml"));
  rig->build_gateway();
  rig->build_rest();
  rig->boot();
  return rig;
}

TEST(Gateway, FullFeSetBootsAndWatchesTheHeartbeatOfEverySubDevice) {
  auto rig = booted(bench::yaml_full_set());
  ASSERT_EQ(rig->gw().downstream().names().size(), 48u);
  // The 48th sub-device too: the master's 1016h has a consumer entry for every sub-device with a
  // heartbeat (48 here, more than 32), so a silent one goes missing.
  EXPECT_EQ(rig->command("cluster8 silent on"), "ok cluster8 silent on");
  EXPECT_EQ(rig->command("grip16 silent on"), "ok grip16 silent on");
  rig->run_for(1s);
  EXPECT_EQ(rig->gw().downstream().state("cluster8"), subdevices::NodeState::Missing);
  EXPECT_EQ(rig->gw().downstream().state("grip16"), subdevices::NodeState::Missing);
  EXPECT_EQ(rig->gw().status({mapping::FeKind::Joystick, 16}), gateway::FeStatus::Offline);
  EXPECT_EQ(rig->gw().downstream().state("grip1"), subdevices::NodeState::Operational);
  EXPECT_EQ(rig->gw().status({mapping::FeKind::Joystick, 1}), gateway::FeStatus::Valid);
  EXPECT_TRUE(rig->gw().faults().count("grip16"));
}

TEST(Gateway, AChangedGripFrameQueuesTpdo1AtOnceAndAnUnchangedOneNothing) {
  auto rig = booted(bench::yaml_one_grip());
  rig->detach();
  auto& up = rig->upstream();
  std::vector<mapping::FeId> changes;
  rig->gw().on_fe_change = [&](mapping::FeId fe) { changes.push_back(fe); };
  const auto before = up.frames;
  EXPECT_TRUE(rig->gw().on_downstream_frame(grip1_frame(40), rig->now()));
  ASSERT_EQ(up.frames, before + 1);
  EXPECT_EQ(up.last.id, 0x1A0u);
  EXPECT_EQ(static_cast<std::int16_t>(canopen::get_u16(&up.last.data[0])), 13107);  // 40 % of 32767
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0], (mapping::FeId{mapping::FeKind::Joystick, 1}));
  // x and a button in one frame: ONE TPDO 1 carrying both (no intermediate snapshot with the
  // new x and the old button), queued before the call returns.
  EXPECT_TRUE(rig->gw().on_downstream_frame(grip1_frame(-40, 0x01), rig->now()));
  EXPECT_EQ(up.frames, before + 2);
  EXPECT_EQ(up.last.id, 0x1A0u);
  EXPECT_EQ(static_cast<std::int16_t>(canopen::get_u16(&up.last.data[0])), -13107);
  EXPECT_EQ(up.last.data[7], 0x01);  // buttons[1]
  EXPECT_GE(changes.size(), 2u);
  const auto after_frames = up.frames;
  const auto after_changes = changes.size();
  EXPECT_TRUE(rig->gw().on_downstream_frame(grip1_frame(-40, 0x01), rig->now()));
  EXPECT_EQ(up.frames, after_frames) << "nothing changed, nothing sent";
  EXPECT_EQ(changes.size(), after_changes);
  EXPECT_EQ(rig->downstream_while_detached(), 0u);
}

// CiA 852 Table 37 5000h: the downstream interface going down is the gateway's own hardware; held
// until a downstream frame shows it works again.
TEST(Gateway, DownstreamInterfaceDownRaisesEmcy5000hUntilAFrameArrives) {
  auto rig = booted(bench::yaml_one_grip());
  rig->detach();
  auto& up = rig->upstream();
  const auto before = up.frames;
  rig->gw().on_downstream_bus_event(canopen::BusEvent::InterfaceDown, rig->now());
  ASSERT_EQ(up.frames, before + 1);
  EXPECT_EQ(up.last.id, 0xA0u);
  EXPECT_EQ(canopen::get_u16(&up.last.data[0]), 0x5000u);
  EXPECT_EQ(up.last.data[2] & 0x01, 0x01);
  EXPECT_TRUE(rig->gw().upstream().node().emcy().active(0x5000));
  rig->gw().on_downstream_bus_event(canopen::BusEvent::InterfaceDown, rig->now());  // still down: once
  rig->gw().on_downstream_bus_event(canopen::BusEvent::ErrorWarning, rig->now());   // not a loss
  EXPECT_EQ(up.frames, before + 1);
  (void)rig->gw().on_downstream_frame(grip1_frame(0), rig->now());
  EXPECT_FALSE(rig->gw().upstream().node().emcy().active(0x5000));
  EXPECT_EQ(up.last.id, 0xA0u);
  EXPECT_EQ(canopen::get_u16(&up.last.data[0]), 0x0000u);
}

// An NMT reset node of the gateway restarts its EMCY producer (canopen/node.hpp): the downstream
// interface still down is raised again after the boot-up — not left out of 1001h as though it
// worked.
TEST(Gateway, ADownstreamInterfaceStillDownIsRaisedAgainAfterAResetNode) {
  auto rig = booted(bench::yaml_one_grip());
  rig->detach();
  auto& up = rig->upstream();
  rig->gw().on_downstream_bus_event(canopen::BusEvent::InterfaceDown, rig->now());
  ASSERT_TRUE(rig->gw().upstream().node().emcy().active(0x5000));
  const auto before = up.frames;
  (void)rig->gw().on_upstream_frame(canopen::CanFrame(0x000, {0x81, 0x20}), rig->now());
  EXPECT_EQ(up.frames, before + 2) << "the boot-up, then 5000h";
  EXPECT_EQ(up.last.id, 0xA0u);
  EXPECT_EQ(canopen::get_u16(&up.last.data[0]), 0x5000u);
  EXPECT_EQ(up.last.data[2], 0x01);
  EXPECT_TRUE(rig->gw().upstream().node().emcy().active(0x5000));
}

TEST(Gateway, OneSignalFeedingSeveralFesReportsEachOnceInFeOrder) {
  auto rig = booted(fixtures::mapping_file("one_signal_several_fes.yaml"));
  rig->detach();
  std::vector<mapping::FeId> changes;
  rig->gw().on_fe_change = [&](mapping::FeId fe) { changes.push_back(fe); };
  EXPECT_TRUE(rig->gw().on_downstream_frame(grip1_frame(-25), rig->now()));
  const std::vector<mapping::FeId> expected{{mapping::FeKind::Joystick, 1},
                                            {mapping::FeKind::Joystick, 3},
                                            {mapping::FeKind::FootPedal, 1},
                                            {mapping::FeKind::Wheel, 2}};
  ASSERT_EQ(changes.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) EXPECT_EQ(changes[i], expected[i]) << i;
  for (const auto& fe : expected)
    for (const auto& f : rig->gw().fields(fe)) EXPECT_EQ(f.value, -8192) << f.name;  // -25 % of 32767
}

}  // namespace
