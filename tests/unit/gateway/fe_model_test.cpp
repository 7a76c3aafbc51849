// The typed FE model (gateway/fe_model.hpp): field names resolve once to slots, writes report
// changes once per FE in FE order, the source time follows the value, and the device sink sees
// every changed slot with its whole value.
#include <gtest/gtest.h>

#include <algorithm>

#include "gateway/fe_model.hpp"
#include "gateway/gateway.hpp"
#include "tests/unit/canopen/state_twin.hpp"

namespace {

using namespace oegw;
using gateway::FeModel;
using gateway::FeSlot;
using gateway::FieldRef;
using mapping::FeId;
using mapping::FeKind;

const FeId kJoy1{FeKind::Joystick, 1};
const FeId kJoy2{FeKind::Joystick, 2};
const FeId kCluster3{FeKind::ButtonCluster, 3};
const FeId kDisplay1{FeKind::Display, 1};

canopen::TimePoint at(int ms) { return canopen::TimePoint{} + std::chrono::milliseconds(ms); }

TEST(FeModel, EveryFieldOfEveryFeResolvesToASlotAndBack) {
  for (int k = 0; k <= static_cast<int>(FeKind::Display); ++k) {
    const FeId fe{static_cast<FeKind>(k), 1};
    for (const auto& f : mapping::fe_fields(fe)) {
      const auto ref = gateway::field_ref(fe, f.name);
      ASSERT_TRUE(ref) << mapping::fe_name(fe) << " " << f.name;
      EXPECT_EQ(gateway::field_name(fe, *ref), f.name);
    }
  }
  EXPECT_FALSE(gateway::field_ref(kJoy1, "w"));
  EXPECT_FALSE(gateway::field_ref(kJoy1, "buttons[9]"));
  EXPECT_FALSE(gateway::field_ref(kJoy1, "buttons[0]"));
  EXPECT_FALSE(gateway::field_ref(kCluster3, "switch[65]"));
  EXPECT_FALSE(gateway::field_ref(kDisplay1, "parameter[13]"));
  EXPECT_FALSE(gateway::field_ref({FeKind::Wheel, 1}, "x"));
}

TEST(FeModel, AWriteChangesTheTypedStateAndStampsTheSourceTime) {
  FeModel m({kJoy1, kCluster3});
  EXPECT_TRUE(m.write(kJoy1, *gateway::field_ref(kJoy1, "x"), -1200, at(5)));
  EXPECT_TRUE(m.write(kJoy1, *gateway::field_ref(kJoy1, "buttons[3]"), 1, at(7)));
  EXPECT_TRUE(m.write(kJoy1, *gateway::field_ref(kJoy1, "memory_z"), 1, at(7)));
  const auto* j = m.get<gateway::JoystickState>(kJoy1);
  ASSERT_NE(j, nullptr);
  EXPECT_EQ(j->x, -1200);
  EXPECT_EQ(j->buttons, 0x04);
  EXPECT_EQ(j->memory, 0x04);
  EXPECT_EQ(j->h.source_time, at(7));
  // The same value again is no change and keeps the source time of the frame that carried it.
  EXPECT_FALSE(m.write(kJoy1, *gateway::field_ref(kJoy1, "x"), -1200, at(9)));
  EXPECT_EQ(m.source_time(kJoy1), at(7));
  EXPECT_TRUE(m.write(kCluster3, *gateway::field_ref(kCluster3, "switch[64]"), 1, at(8)));
  EXPECT_EQ(m.get<gateway::ButtonClusterState>(kCluster3)->switches, std::uint64_t{1} << 63);
  EXPECT_EQ(m.get<gateway::PedalState>(kJoy1), nullptr) << "wrong kind";
  EXPECT_FALSE(m.write(kJoy2, FieldRef{FeSlot::X}, 1, at(1))) << "not configured";
}

// Run-time state (canopen/state.hpp): a copy given the model's state holds every FE's values,
// status and source time, and owes the publishers the same FEs; its slot observer is not called
// (the dictionary it mirrors carries its own state).
TEST(FeModel, ACopyGivenTheStateHoldsEveryFeAndOwesThePublishersTheSame) {
  const std::vector<FeId> fes{kJoy1,
                              {FeKind::FootPedal, 2},
                              {FeKind::Encoder, 1},
                              {FeKind::Wheel, 3},
                              kCluster3,
                              {FeKind::IndicatorCluster, 1},
                              kDisplay1};
  FeModel a(fes);
  const auto write = [&](FeId fe, const char* field, std::int64_t v, int ms) {
    ASSERT_TRUE(a.write(fe, *gateway::field_ref(fe, field), v, at(ms))) << mapping::fe_name(fe) << " " << field;
  };
  write(kJoy1, "x", -1200, 5);
  write(kJoy1, "y", 7, 5);
  write(kJoy1, "z", -32768, 5);
  write(kJoy1, "buttons[8]", 1, 6);
  write(kJoy1, "memory_y", 1, 6);
  write(fes[1], "position", 300, 7);
  write(fes[1], "memory_x", 1, 7);
  write(fes[2], "position", 0xFFFFFFF0, 8);
  write(fes[3], "position", -5, 9);
  write(kCluster3, "switch[64]", 1, 10);
  write(fes[5], "indicator[6]", 1, 11);
  write(kDisplay1, "parameter[12]", -7, 12);
  for (const FeId& fe : fes) a.set_status(fe, gateway::FeStatus::Valid, at(13));
  a.set_status(kJoy1, gateway::FeStatus::Stale, at(14));
  a.for_each_changed([](FeId) {});  // published
  a.set_status(fes[1], gateway::FeStatus::Error, at(15));
  write(kDisplay1, "parameter[1]", 9, 16);

  FeModel b(fes);
  int observed = 0;
  b.on_slot_change([&](FeId, FeSlot, std::int64_t) { ++observed; });
  canopen::test_support::copy_state(a, b);
  EXPECT_EQ(observed, 0);
  const FeModel fresh(fes);
  for (const FeId& fe : fes) {
    EXPECT_EQ(b.status(fe), a.status(fe)) << mapping::fe_name(fe);
    EXPECT_EQ(b.source_time(fe), a.source_time(fe)) << mapping::fe_name(fe);
    for (const auto& f : mapping::fe_fields(fe)) {
      const FieldRef ref = *gateway::field_ref(fe, f.name);
      EXPECT_EQ(b.read(fe, ref), a.read(fe, ref)) << mapping::fe_name(fe) << " " << f.name;
    }
  }
  EXPECT_NE(fresh.status(kJoy1), a.status(kJoy1));
  EXPECT_EQ(b.get<gateway::EncoderState>(fes[2])->position, 0xFFFFFFF0u);
  EXPECT_EQ(b.get<gateway::ButtonClusterState>(kCluster3)->switches, std::uint64_t{1} << 63);
  // Owed to the publishers: the pedal and the display, in FE order, and then nothing.
  const auto owed = [](FeModel& m) {
    std::vector<FeId> out;
    m.for_each_changed([&](FeId fe) { out.push_back(fe); });
    return out;
  };
  const std::vector<FeId> expected{fes[1], kDisplay1};
  EXPECT_EQ(owed(a), expected);
  EXPECT_EQ(owed(b), expected);
  EXPECT_TRUE(owed(b).empty());
}

TEST(FeModel, AStateOfOtherFesOrValuesNoFieldHoldsIsRefused) {
  const std::string text = canopen::test_support::state_text(FeModel({kJoy1}));
  using canopen::test_support::refusal;
  using canopen::test_support::with_value;
  FeModel other({kJoy2});
  EXPECT_EQ(refusal(other, text),
            "state: 'fe.0.kind' differs: the state is of another mapping file's FEs (here joystick.2)");
  FeModel fewer({});
  EXPECT_EQ(refusal(fewer, text), "state: 'fe.count' = 1 is above 0");
  FeModel b({kJoy1});
  EXPECT_EQ(refusal(b, with_value(text, "fe.0.memory", "8")),
            "state: 'fe.0.memory' sets a bit the FE has no field for");
  EXPECT_EQ(refusal(b, with_value(text, "fe.0.status", "5")), "state: 'fe.0.status' is no FE status");
  EXPECT_EQ(refusal(b, with_value(text, "fe.0.x", "32768")), "state: 'fe.0.x' = 32768 is outside -32768..32767");
}

TEST(FeModel, ChangedFesAreReportedOnceEachInFeOrder) {
  FeModel m({kCluster3, kJoy2, kJoy1});
  (void)m.write(kCluster3, FieldRef{FeSlot::Switches, 0}, 1, at(1));
  (void)m.write(kJoy2, FieldRef{FeSlot::X}, 5, at(1));
  (void)m.write(kJoy2, FieldRef{FeSlot::Y}, 5, at(1));
  (void)m.set_status(kJoy1, gateway::FeStatus::Valid, at(1));
  std::vector<FeId> seen;
  m.for_each_changed([&](FeId fe) { seen.push_back(fe); });
  EXPECT_EQ(seen, (std::vector<FeId>{kJoy1, kJoy2, kCluster3}));
  seen.clear();
  m.for_each_changed([&](FeId fe) { seen.push_back(fe); });
  EXPECT_TRUE(seen.empty());
}

TEST(FeModel, TheSlotObserverSeesTheWholeSlotValue) {
  FeModel m({kCluster3, kJoy1});
  std::vector<std::tuple<FeId, FeSlot, std::int64_t>> calls;
  m.on_slot_change([&](FeId fe, FeSlot s, std::int64_t v) { calls.emplace_back(fe, s, v); });
  (void)m.write(kCluster3, FieldRef{FeSlot::Switches, 9}, 1, at(1));
  (void)m.write(kCluster3, FieldRef{FeSlot::Switches, 9}, 1, at(2));  // no change: no call
  (void)m.write(kJoy1, FieldRef{FeSlot::Buttons, 0}, 1, at(3));
  (void)m.write(kJoy1, FieldRef{FeSlot::Z}, -32768, at(3));
  ASSERT_EQ(calls.size(), 3u);
  EXPECT_EQ(calls[0], std::make_tuple(kCluster3, FeSlot::Switches, std::int64_t{1} << 9));
  EXPECT_EQ(calls[1], std::make_tuple(kJoy1, FeSlot::Buttons, std::int64_t{1}));
  EXPECT_EQ(calls[2], std::make_tuple(kJoy1, FeSlot::Z, std::int64_t{-32768}));
}

TEST(FeModel, AStatusChangeIsStampedWithTheTimeItWasDecided) {
  FeModel m({kJoy1});
  EXPECT_EQ(m.status(kJoy1), gateway::FeStatus::Offline);
  EXPECT_TRUE(m.set_status(kJoy1, gateway::FeStatus::Stale, at(40)));
  EXPECT_FALSE(m.set_status(kJoy1, gateway::FeStatus::Stale, at(50)));
  EXPECT_EQ(m.source_time(kJoy1), at(40));
}

TEST(FeModel, DisplayParametersAreReadOneByOne) {
  FeModel m({kDisplay1});
  EXPECT_TRUE(m.write(kDisplay1, FieldRef{FeSlot::Parameters, 11}, -7, at(1)));
  EXPECT_EQ(m.read(kDisplay1, FieldRef{FeSlot::Parameters, 11}), -7);
  EXPECT_EQ(m.get<gateway::DisplayState>(kDisplay1)->parameters[11], -7);
}

// The gateway's model at start: every input at its fault value, offline, stamped with the
// start time (a consumer never sees a source time of 0); an output FE commanded from inside an
// on_fe_change callback is reported too, in the same call.
TEST(GatewayModel, StartStampsEveryFeAndAChangeMadeByAConsumerIsReportedToo) {
  auto r = mapping::load_config_text(
      "upstream: { interface: virtual, node_id: 0x20 }\n"
      "downstream: { interface: virtual }\n"
      "publish: { dds: { domain: 0, network: loopback } }\n"
      "subdevices:\n"
      "  grip: { driver: elobau-mfg, node_id: 0x11 }\n"
      "functional_elements:\n"
      "  joystick.1: { x: { signal: grip.x } }\n"
      "  indicators.1:\n"
      "    sources: [dds]\n"
      "    indicator[1]: grip.leds[1]\n",
      "t.yaml", gateway::driver_catalogue());
  ASSERT_TRUE(r.ok()) << r.error_text();
  gateway::Gateway gw(
      *r.config, [](const canopen::CanFrame&) {}, [](const canopen::CanFrame&) {});
  std::vector<FeId> seen;
  bool commanded = false;
  gw.on_fe_change = [&](FeId fe) {
    seen.push_back(fe);
    if (!commanded) {
      commanded = true;
      (void)gw.command_indicators(1, 0x01, at(10), mapping::CommandSource::Dds);
    }
  };
  (void)gw.start(at(10));
  EXPECT_EQ(gw.model().source_time(kJoy1), at(10));
  EXPECT_EQ(gw.model().status(kJoy1), gateway::FeStatus::Offline);
  const FeId leds{FeKind::IndicatorCluster, 1};
  EXPECT_EQ(gw.model().get<gateway::IndicatorState>(leds)->indicators, 1u);
  EXPECT_EQ(std::count(seen.begin(), seen.end(), kJoy1), 1);
  EXPECT_EQ(std::count(seen.begin(), seen.end(), leds), 2) << "the start, then the command made from the callback";
}

}  // namespace
