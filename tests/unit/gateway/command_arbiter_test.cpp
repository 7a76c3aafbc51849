// The command arbiter (gateway/command_arbiter.hpp) on a CiA 852 device alone: who may command
// an output FE, last writer wins, the refusal count, and the command watchdog with its CiA 401
// error values, as the outputs (drive) see them.
#include <gtest/gtest.h>

#include <string>
#include <tuple>
#include <vector>

#include "gateway/command_arbiter.hpp"
#include "gateway/runtime_config.hpp"
#include "tests/unit/canopen/state_twin.hpp"

namespace {

using namespace oegw;
using namespace std::chrono_literals;
using gateway::FieldRef;
using mapping::CommandSource;
using mapping::FeId;
using mapping::FeKind;

const FeId kLeds1{FeKind::IndicatorCluster, 1};  // sources: dds only, watchdog 100 ms
const FeId kLeds2{FeKind::IndicatorCluster, 2};  // all sources, no watchdog
const FeId kDisplay1{FeKind::Display, 1};        // canopen and lcm

mapping::Config config() {
  mapping::Config c;
  c.upstream.node_id = 0x20;
  c.upstream.store = "";
  mapping::FunctionalElementConfig a;
  a.id = kLeds1;
  a.sources = static_cast<mapping::CommandSources>(CommandSource::Dds);
  a.command_timeout_ms = 100;
  mapping::FunctionalElementConfig b;
  b.id = kLeds2;
  b.sources = mapping::kAllCommandSources;  // written out: LCM is opt-in (mapping/config.hpp)
  mapping::FunctionalElementConfig d;
  d.id = kDisplay1;
  d.sources = static_cast<mapping::CommandSources>(CommandSource::Canopen) |
              static_cast<mapping::CommandSources>(CommandSource::Lcm);
  c.functional_elements = {a, b, d};
  return c;
}

struct Rig {
  mapping::Config cfg = config();
  canopen::TimePoint now{};
  gateway::OeDevice device{gateway::device_config(cfg), [](const canopen::CanFrame&) {}};
  gateway::FeModel model{device.config().fes};
  gateway::CommandArbiter arbiter{cfg, device, model};
  std::vector<std::tuple<FeId, FieldRef, std::int64_t>> driven;
  std::vector<std::string> log;
  Rig() {
    arbiter.drive = [this](FeId fe, FieldRef r, std::int64_t v) { driven.emplace_back(fe, r, v); };
    arbiter.log = [this](const std::string& l) { log.push_back(l); };
    (void)device.start(now);
    arbiter.start(now);
    driven.clear();
  }
  std::uint64_t leds(FeId fe) const { return model.get<gateway::IndicatorState>(fe)->indicators; }
};

TEST(CommandArbiter, ASourceTheFeTakesDrivesTheOutputsAndAnotherIsRefusedAndCounted) {
  Rig r;
  EXPECT_TRUE(r.arbiter.command_indicators(1, 0x05, CommandSource::Dds, r.now));
  EXPECT_EQ(r.leds(kLeds1), 0x05u);
  ASSERT_EQ(r.driven.size(), 2u);  // indicator[1] and indicator[3], each once
  EXPECT_EQ(r.driven[0], std::make_tuple(kLeds1, FieldRef{gateway::FeSlot::Indicators, 0}, std::int64_t{1}));
  EXPECT_EQ(r.driven[1], std::make_tuple(kLeds1, FieldRef{gateway::FeSlot::Indicators, 2}, std::int64_t{1}));
  EXPECT_EQ(r.device.od().get<std::uint8_t>(0x6200, 0x01), 0x05) << "the host reads the command back";
  r.driven.clear();
  EXPECT_FALSE(r.arbiter.command_indicators(1, 0xFF, CommandSource::Lcm, r.now));
  EXPECT_FALSE(r.arbiter.command_indicators(1, 0x00, CommandSource::Lcm, r.now));
  EXPECT_TRUE(r.driven.empty());
  EXPECT_EQ(r.leds(kLeds1), 0x05u);
  EXPECT_EQ(r.arbiter.refused(), 2u);
  ASSERT_EQ(r.log.size(), 1u) << "logged once per FE and way";
  EXPECT_EQ(r.log[0], "indicators.1: a command from lcm ignored: its sources are dds");
  EXPECT_FALSE(r.arbiter.command_indicators(3, 0x01, CommandSource::Dds, r.now)) << "not configured";
  EXPECT_EQ(r.arbiter.refused(), 3u);
}

TEST(CommandArbiter, EachOutputFeCountsItsOwnRefusalsFromEveryWay) {
  Rig r;
  // indicators.1 takes dds only: LCM, the host's SDO and its RPDO bytes are refused.
  EXPECT_FALSE(r.arbiter.command_indicators(1, 0x01, CommandSource::Lcm, r.now));
  const std::uint8_t byte = 0xFF;
  EXPECT_EQ(r.device.od().write(0x6200, 0x01, std::span<const std::uint8_t>(&byte, 1), canopen::Origin::Sdo),
            canopen::SdoAbortCode::CannotTransferLocalControl);
  (void)r.device.od().write(0x6200, 0x01, std::span<const std::uint8_t>(&byte, 1), canopen::Origin::Pdo);
  // display.1 takes canopen and lcm: DDS is refused.
  EXPECT_FALSE(r.arbiter.command_display(1, {}, CommandSource::Dds, r.now));
  EXPECT_TRUE(r.arbiter.command_display(1, {}, CommandSource::Lcm, r.now));
  EXPECT_EQ(r.arbiter.refused(kLeds1), 3u);
  EXPECT_EQ(r.arbiter.refused(kDisplay1), 1u);
  EXPECT_EQ(r.arbiter.refused(kLeds2), 0u) << "all sources: nothing refused";
  // An FE the mapping file does not configure: only the total counts it.
  EXPECT_FALSE(r.arbiter.command_indicators(3, 0x01, CommandSource::Dds, r.now));
  EXPECT_EQ(r.arbiter.refused(FeId{FeKind::IndicatorCluster, 3}), 0u);
  EXPECT_EQ(r.arbiter.refused(), 5u);
}

TEST(CommandArbiter, AmongTheSourcesTheLastWriterWins) {
  Rig r;
  EXPECT_TRUE(r.arbiter.command_indicators(2, 0x0F, CommandSource::Dds, r.now));
  EXPECT_TRUE(r.arbiter.command_indicators(2, 0x30, CommandSource::Lcm, r.now));
  EXPECT_EQ(r.leds(kLeds2), 0x30u);
  // The host's SDO download of 6200h:09 (indicators.2) goes through the device to the arbiter.
  const std::uint8_t byte = 0x81;
  EXPECT_EQ(r.device.od().write(0x6200, 0x09, std::span<const std::uint8_t>(&byte, 1), canopen::Origin::Sdo),
            canopen::SdoAbortCode::None);
  EXPECT_EQ(r.leds(kLeds2), 0x81u);
}

TEST(CommandArbiter, AHostWriteOfAnFeWithoutCanopenIsAbortedWithLocalControl) {
  Rig r;
  const std::uint8_t byte = 0xFF;
  EXPECT_EQ(r.device.od().write(0x6200, 0x01, std::span<const std::uint8_t>(&byte, 1), canopen::Origin::Sdo),
            canopen::SdoAbortCode::CannotTransferLocalControl);
  EXPECT_EQ(r.leds(kLeds1), 0u);
  EXPECT_TRUE(r.driven.empty());
  EXPECT_EQ(r.arbiter.refused(), 1u);
  ASSERT_EQ(r.log.size(), 1u);
  EXPECT_EQ(r.log[0], "indicators.1: the host's SDO write refused (abort 0800 0021h): its sources are dds");
  // Display 1 takes the host: 6411h:01 applies.
  EXPECT_EQ(r.device.od().set<std::int16_t>(0x6411, 0x01, -300, canopen::Origin::Sdo), canopen::SdoAbortCode::None);
  EXPECT_EQ(r.model.get<gateway::DisplayState>(kDisplay1)->parameters[0], -300);
}

TEST(CommandArbiter, AHostWriteTakesTheTimeOfItsFrame) {
  Rig r;
  // The device's frames carry their own time; the arbiter keeps no clock of its own.
  const canopen::TimePoint t = r.now + 7ms;
  const std::uint32_t rx = 0x600 + r.device.node().node_id().value();
  // SDO expedited download of 6411h:01 = -300 (FED4h, 2 bytes: 2Bh), CiA 301 §7.2.4.3.3.
  ASSERT_TRUE(r.device.on_frame(canopen::CanFrame(rx, {0x2B, 0x11, 0x64, 0x01, 0xD4, 0xFE, 0, 0}), t));
  EXPECT_EQ(r.model.get<gateway::DisplayState>(kDisplay1)->parameters[0], -300);
  EXPECT_EQ(r.model.source_time(kDisplay1), t);
}

TEST(CommandArbiter, ASilentCommanderGivesTheErrorValuesUntilTheNextCommand) {
  Rig r;
  // CiA 401 6206h:01 = 0Fh (error mode on for indicators 1..4), 6207h:01 = 03h.
  (void)r.device.od().set<std::uint8_t>(0x6206, 0x01, 0x0F, canopen::Origin::Sdo);
  (void)r.device.od().set<std::uint8_t>(0x6207, 0x01, 0x03, canopen::Origin::Sdo);
  ASSERT_TRUE(r.arbiter.command_indicators(1, 0xF0, CommandSource::Dds, r.now));
  EXPECT_EQ(r.arbiter.next_deadline(), r.now + 100ms);
  r.now += 99ms;
  r.arbiter.advance(r.now);
  EXPECT_EQ(r.leds(kLeds1), 0xF0u);
  r.now += 1ms;
  r.arbiter.advance(r.now);
  EXPECT_EQ(r.leds(kLeds1), 0xF3u) << "indicators 1..4 take 6207h, 5..8 keep their value";
  EXPECT_EQ(r.log.back(),
            "indicators.1: no command for 100 ms: outputs set to their error values until the next command");
  EXPECT_FALSE(r.arbiter.next_deadline()) << "indicators.2 and display.1 have no watchdog";
  // The host rewrites the error value meanwhile: the silent FE follows it.
  (void)r.device.od().set<std::uint8_t>(0x6207, 0x01, 0x00, canopen::Origin::Sdo);
  r.arbiter.hold_error_values(r.now);
  EXPECT_EQ(r.leds(kLeds1), 0xF0u);
  // The next command ends it and restarts the watchdog.
  r.now += 5ms;
  ASSERT_TRUE(r.arbiter.command_indicators(1, 0x01, CommandSource::Dds, r.now));
  EXPECT_EQ(r.leds(kLeds1), 0x01u);
  EXPECT_EQ(r.log.back(), "indicators.1: commands again");
  EXPECT_EQ(r.arbiter.next_deadline(), r.now + 100ms);
}

// Run-time state (canopen/state.hpp): a copy given the arbiter's state times its watchdogs from
// the last command, counts on and logs no refusal twice; a fresh one does not. An expired
// watchdog carries over: the next command is "commands again".
TEST(CommandArbiter, ACopyGivenTheStateKeepsTheWatchdogsCountsAndLoggedRefusals) {
  Rig a;
  ASSERT_TRUE(a.arbiter.command_indicators(1, 0x01, CommandSource::Dds, a.now + 30ms));
  EXPECT_FALSE(a.arbiter.command_indicators(1, 0x02, CommandSource::Lcm, a.now + 40ms));
  EXPECT_FALSE(a.arbiter.command_display(1, {}, CommandSource::Dds, a.now + 45ms));
  Rig b;
  canopen::test_support::copy_state(a.arbiter, b.arbiter);
  Rig fresh;
  for (Rig* r : {&a, &b, &fresh}) {
    r->log.clear();
    EXPECT_FALSE(r->arbiter.command_indicators(1, 0x04, CommandSource::Lcm, r->now + 50ms));
    r->arbiter.advance(r->now + 100ms);
  }
  EXPECT_EQ(b.log, a.log);
  EXPECT_NE(fresh.log, a.log);
  EXPECT_TRUE(a.log.empty()) << "logged once, and the watchdog runs from the command at 30 ms";
  EXPECT_EQ(b.arbiter.next_deadline(), a.now + 130ms);
  EXPECT_EQ(b.arbiter.refused(), 3u);
  EXPECT_EQ(b.arbiter.refused(kLeds1), 2u);
  EXPECT_EQ(b.arbiter.refused(kDisplay1), 1u);

  a.arbiter.advance(a.now + 130ms);
  ASSERT_FALSE(a.arbiter.next_deadline()) << "expired";
  Rig c;
  canopen::test_support::copy_state(a.arbiter, c.arbiter);
  EXPECT_FALSE(c.arbiter.next_deadline());
  Rig fresh2;
  for (Rig* r : {&a, &c, &fresh2}) {
    r->log.clear();
    ASSERT_TRUE(r->arbiter.command_indicators(1, 0x08, CommandSource::Dds, r->now + 150ms));
  }
  EXPECT_EQ(c.log, std::vector<std::string>{"indicators.1: commands again"});
  EXPECT_EQ(c.log, a.log);
  EXPECT_TRUE(fresh2.log.empty());
}

TEST(CommandArbiter, AStateOfOtherOutputsOrNoRunIsRefused) {
  using canopen::test_support::refusal;
  using canopen::test_support::with_value;
  const std::string text = canopen::test_support::state_text(Rig().arbiter);
  Rig b;
  EXPECT_EQ(refusal(b.arbiter, with_value(text, "outputs.1.instance", "3")),
            "state: 'outputs.1.kind' differs: the state is of another mapping file's outputs (here indicators.2)");
  EXPECT_EQ(refusal(b.arbiter, with_value(text, "outputs.1.expired", "1")),
            "state: 'outputs.1.expired' is set for an output without a watchdog");
  EXPECT_EQ(refusal(b.arbiter, with_value(with_value(text, "outputs.0.expired", "1"), "started", "0")),
            "state: 'started' is not set, yet a watchdog expired");
  const std::string logged = text + "logged.0.kind 0\nlogged.0.instance 1\nlogged.0.way 3\n";
  EXPECT_EQ(refusal(b.arbiter, with_value(logged, "logged.count", "1")), "state: 'logged.0.kind' is no output FE");
}

}  // namespace
