// Run-time state export/import of the drivers (Driver::export_state, canopen/state.hpp). As the
// services' twin tests (tests/unit/canopen/301/service_state_test.cpp): driver A is driven into a
// mid-life state, B is built with the same options (but not booted: the state carries the boot
// writes) and given A's state, a third is booted fresh; all three get the same frames, poll
// answers and times, and B must report exactly what A does while the fresh one does not.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "canopen/state.hpp"
#include "subdevices/elobau_mfg.hpp"
#include "subdevices/families.hpp"
#include "subdevices/mcb402.hpp"
#include "subdevices/novotechnik_406.hpp"
#include "tests/unit/canopen/state_twin.hpp"

using namespace oegw::subdevices;
using oegw::canopen::CanFrame;
using oegw::canopen::EmcyMessage;
using oegw::canopen::StateError;
using oegw::canopen::StateReader;
using oegw::canopen::StateWriter;
using oegw::canopen::TimePoint;
using namespace std::chrono_literals;
using oegw::canopen::test_support::copy_state;
using ::testing::Contains;

namespace {

constexpr NodeId kNode{0x03};

TimePoint at(int ms) { return TimePoint{} + std::chrono::milliseconds(ms); }

// One driver and what it reported, with times.
struct Watched {
  std::unique_ptr<Driver> driver;
  std::vector<CanFrame> sent;
  std::vector<std::string> log;
  explicit Watched(std::unique_ptr<Driver> d) : driver(std::move(d)) {
    driver->bind_sink([this](const CanFrame& f) { sent.push_back(f); });
    driver->on_change = [this](std::size_t i, const SignalValue& v) {
      log.push_back(std::to_string(i) + "=" + std::to_string(v.value) + " " + std::string(to_string(v.status)) +
                    " at " + std::to_string(v.timestamp.time_since_epoch().count() / 1000));
    };
  }
  void frame(const CanFrame& f, int ms) {
    driver->pdo_received(f.id, at(ms));
    driver->on_frame(f, at(ms));
  }
  // An EMCY as the Master hands it over: code, error register, and the manufacturer field whose
  // second byte is the MCB-402's axis byte ("20 31 81 00 8x").
  void emcy(std::uint16_t code, std::uint8_t reg, std::uint8_t axes, int ms) {
    emcy(EmcyMessage{.node = kNode, .code = code, .error_register = reg, .msef = {0, axes, 0, 0, 0}}, ms);
  }
  void emcy(const EmcyMessage& m, int ms) {
    const DecodedEmcy d = driver->on_emcy(m, at(ms));
    log.push_back("emcy " + std::to_string(m.code) + (d.error ? " error" : " no error"));
  }
};

// booted: given its boot writes, as the network manager does after a boot. A copy is not: the
// state carries them.
std::unique_ptr<Driver> mcb402(bool booted = true) {
  std::string error;
  DriverOptions options;
  options.values.emplace_back("button_bits", "1,2,3,4,5,7,6");
  auto d = make_mcb402_driver(kNode, {}, options, error);
  EXPECT_NE(d, nullptr) << error;
  if (booted) d->apply_boot_writes(d->configuration());
  return d;
}

// [CO4013 "Emergency Messages"] cable break "20 31 81 00 8x": bit 0 X, bit 1 Y; the latch ends
// only on a 1001h read that shows no device error, and only one asked after the last latch.
TEST(DriverState, AnMcb402CableBreakLatchAndItsPollEpochCarryOver) {
  Watched a(mcb402());
  a.driver->on_online(at(0));
  a.driver->set_alive_since(at(0));
  a.frame(CanFrame(0x283, {1, 0, 2, 0, 3, 0, 4, 0}), 1);
  a.driver->on_frame(CanFrame(0x283, {1, 0}), at(1));  // wrong length: counted
  a.emcy(0x3120, 0x81, 0x81, 2);                       // X broken
  a.driver->on_fault_poll_sent();
  a.emcy(0x3120, 0x81, 0x83, 3);  // Y too, after that request went out: its answer is no evidence
  a.log.push_back(a.driver->on_fault_poll(std::vector<std::uint8_t>{0x00}, at(4)));
  a.frame(CanFrame(0x283, {5, 0, 6, 0, 7, 0, 8, 0}), 4);
  ASSERT_TRUE(a.driver->set_output(mcb402::kFirstLed, 1, at(4)));
  a.driver->on_fault_poll_sent();  // a request after the last latch: its answer is evidence
  a.log.clear();
  a.sent.clear();

  Watched b(mcb402(false));
  Watched fresh(mcb402());
  fresh.driver->on_online(at(0));
  fresh.driver->set_alive_since(at(0));
  fresh.log.clear();
  copy_state(*a.driver, *b.driver);
  EXPECT_EQ(dynamic_cast<Mcb402Driver&>(*b.driver).broken_axes(), 0x03);
  EXPECT_EQ(b.driver->counters(), a.driver->counters());
  // The watches' times and the proof of life: the same deadlines. (The freshness equals the
  // constructor's here; the elobau test shows a written event timer carried.)
  EXPECT_EQ(b.driver->next_deadline(), a.driver->next_deadline());
  EXPECT_EQ(b.driver->freshness(0), a.driver->freshness(0));
  for (Watched* w : {&a, &b, &fresh}) {
    // The power-on warning's 11h: no device error.
    w->log.push_back("answer: " + w->driver->on_fault_poll(std::vector<std::uint8_t>{0x11}, at(5)));
    w->frame(CanFrame(0x283, {9, 0, 10, 0, 11, 0, 12, 0}), 7);
    w->driver->advance(at(250));  // no TPDO2 for the 200 ms floor: stale
    w->driver->on_offline(at(300));
    w->driver->on_online(at(400));  // the outputs as last commanded go out again
  }
  EXPECT_EQ(b.log, a.log);
  EXPECT_NE(fresh.log, a.log);
  EXPECT_EQ(b.sent, a.sent);
  for (std::size_t i = 0; i < a.driver->signals().size(); ++i) {
    EXPECT_EQ(b.driver->value(i), a.driver->value(i)) << a.driver->signals()[i].name;
  }
}

constexpr NodeId kGrip{0x11};  // elobau §7: the default node-ID

std::unique_ptr<Driver> elobau(bool booted = true) {
  std::string error;
  auto d = make_elobau_mfg_driver(kGrip, {}, DriverOptions{}, error);
  EXPECT_NE(d, nullptr) << error;
  if (booted) d->apply_boot_writes(d->configuration());
  return d;
}

// elobau Table 6: 0012h (X signal difference, which the PDOs need not show) holds until a pair of
// agreeing channels comes after it; 0063h (button 3 timeout) until the error reset (§12.4). The
// LEDs as commanded go out again when the grip comes back.
TEST(DriverState, AnElobauGripsLatchesChannelsAndLedsCarryOver) {
  const auto axis_emcy = [](std::uint8_t code) {
    return EmcyMessage{.node = kGrip, .code = 0x1000, .error_register = 0x81, .msef = {code, 0x00, 0xFF, 0xFF, 0xFF}};
  };
  Watched a(elobau());
  a.driver->on_online(at(0));
  a.driver->set_alive_since(at(0));
  a.frame(CanFrame(0x191, {0x0A, 0x00, 0x00, 0x00, 0x00, 0x04, 0x00, 0xFF}), 1);
  a.frame(CanFrame(0x291, {0x0A, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF}), 2);
  a.emcy(axis_emcy(0x12), 3);
  a.emcy(axis_emcy(0x63), 4);
  ASSERT_TRUE(a.driver->set_output(*a.driver->find_signal("leds[1]"), 1, at(5)));
  a.log.clear();
  a.sent.clear();

  Watched b(elobau(false));
  Watched fresh(elobau());
  fresh.driver->on_online(at(0));
  fresh.driver->set_alive_since(at(0));
  fresh.log.clear();
  copy_state(*a.driver, *b.driver);
  for (Watched* w : {&a, &b, &fresh}) {
    w->frame(CanFrame(0x191, {0x0A, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF}), 10);
    w->frame(CanFrame(0x291, {0x0A, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF}), 11);
    w->emcy(EmcyMessage{.node = kGrip, .code = 0x0000, .error_register = 0, .msef = {0, 0, 0xFF, 0xFF, 0xFF}}, 12);
    w->driver->set_output(*w->driver->find_signal("leds[1]"), 1, at(13));  // sent already: not again
    w->driver->on_offline(at(20));
    w->driver->on_online(at(30));
  }
  EXPECT_EQ(b.log, a.log);
  EXPECT_NE(fresh.log, a.log);
  EXPECT_EQ(b.sent, a.sent);
  ASSERT_FALSE(a.sent.empty()) << "the LED state goes out again when the grip is back";
  EXPECT_NE(fresh.sent, a.sent);
}

// What this grip's boot read and was written (2100h:01h = 07h: buttons 1..3 fitted, §15.2.1; a
// mapping file's 1800h:05 and 1801h:05 of 300 ms), a channel 2 that disagreed and awaits the next channel 1
// (channel_tolerance), and when channel 2 last came (channel2_timeout_ms) carry over.
TEST(DriverState, AnElobauGripsFittedButtonsChannelCheckAndBootWritesCarryOver) {
  const auto grip = [] {
    std::string error;
    DriverOptions options;
    options.values.emplace_back("channel2_timeout_ms", "300");
    auto d = make_elobau_mfg_driver(kGrip, {}, options, error);
    EXPECT_NE(d, nullptr) << error;
    return d;
  };
  Watched a(grip());
  std::vector<SdoWrite> writes = a.driver->configuration();
  // Both TPDOs carry the axes (channel 1 and 2): the shorter event timer sets their freshness.
  writes.push_back(SdoWrite{0x1800, 0x05, {0x2C, 0x01}, "mapping file: TPDO #0 every 300 ms"});
  writes.push_back(SdoWrite{0x1801, 0x05, {0x2C, 0x01}, "mapping file: TPDO #1 every 300 ms"});
  a.driver->apply_boot_writes(writes);
  a.driver->begin_boot();
  std::string error;
  ASSERT_TRUE(a.driver->on_boot_read(0x2100, 0x01, std::vector<std::uint8_t>{0x07}, error)) << error;
  ASSERT_TRUE(a.driver->on_boot_read(0x2100, 0x02, std::vector<std::uint8_t>{0x00}, error)) << error;
  a.driver->on_online(at(0));
  a.driver->set_alive_since(at(0));
  a.frame(CanFrame(0x291, {0x0A, 0x0A, 0x00, 0x00, 0x70, 0xFF, 0xFF, 0xFF}), 1);  // 112: out of range
  a.frame(CanFrame(0x191, {0x0A, 0x0A, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF}), 2);
  a.frame(CanFrame(0x291, {0x3C, 0x0A, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF}), 3);  // X: 60 against 10
  a.log.clear();

  Watched b(grip());
  Watched fresh(grip());
  fresh.driver->apply_boot_writes(fresh.driver->configuration());
  fresh.driver->on_online(at(0));
  fresh.driver->set_alive_since(at(0));
  fresh.log.clear();
  copy_state(*a.driver, *b.driver);
  EXPECT_EQ(b.driver->freshness(ElobauMfgDriver::kX), a.driver->freshness(ElobauMfgDriver::kX));
  EXPECT_NE(fresh.driver->freshness(ElobauMfgDriver::kX), a.driver->freshness(ElobauMfgDriver::kX));
  EXPECT_EQ(b.driver->boot_reads(), a.driver->boot_reads());
  for (Watched* w : {&a, &b, &fresh}) {
    // Channel 1 agrees with its old channel 2, not the newer one: a mismatch where it was suspect.
    // Button 5 pressed: not fitted on this grip.
    w->frame(CanFrame(0x191, {0x0A, 0x0A, 0x00, 0x00, 0x00, 0x10, 0x00, 0xFF}), 5);
    w->frame(CanFrame(0x191, {0x0A, 0x0A, 0x00, 0x00, 0x00, 0x10, 0x00, 0xFF}), 304);  // channel 2 301 ms old
  }
  EXPECT_EQ(b.log, a.log);
  EXPECT_NE(fresh.log, a.log);
  EXPECT_EQ(b.driver->counters(), a.driver->counters());
  EXPECT_EQ(a.driver->counters().mismatches, 1u);
  const auto& ea = dynamic_cast<const ElobauMfgDriver&>(*a.driver);
  const auto& eb = dynamic_cast<const ElobauMfgDriver&>(*b.driver);
  EXPECT_EQ(eb.stats().channel2_missing, ea.stats().channel2_missing);
  EXPECT_EQ(ea.stats().channel2_missing, 1u);
  EXPECT_EQ(eb.stats().out_of_range, ea.stats().out_of_range);
  EXPECT_EQ(ea.stats().out_of_range, 1u);
  EXPECT_EQ(b.driver->value(ElobauMfgDriver::kFirstButton + 4).status, SignalStatus::NotAvailable);
  EXPECT_EQ(fresh.driver->value(ElobauMfgDriver::kFirstButton + 4).status, SignalStatus::Valid);
  EXPECT_EQ(b.driver->value(ElobauMfgDriver::kX + 1).status, SignalStatus::Error) << "channel 2 late";
  EXPECT_EQ(fresh.driver->value(ElobauMfgDriver::kX + 1).status, SignalStatus::Valid);
}

constexpr NodeId kSensor{0x7F};  // Novotechnik §3.1: standard models 127

// A Novotechnik that refused 6020h in its TPDO (§4.1 against §4.2): the copy keeps mapping 6004h
// in its configuration for the next boot. Its position latch (§9.1 5051h/1/1) holds through a
// good position until the "valid position" EMCY; the boot's 6503h read is not asked again.
TEST(DriverState, ANovotechniksLatchMarkerReadsAndMappingCarryOver) {
  const auto sensor = [] {
    std::string error;
    auto d = make_novotechnik_406_driver(kSensor, {}, DriverOptions{}, error);
    EXPECT_NE(d, nullptr) << error;
    return d;
  };
  const auto emcy = [](std::uint16_t code, std::uint8_t reg, std::uint8_t b3) {
    return EmcyMessage{.node = kSensor, .code = code, .error_register = reg, .msef = {b3, 0, 0, 0, 0}};
  };
  const std::uint32_t tpdo1 = 0x180 + kSensor.value();
  Watched a(sensor());
  std::vector<SdoWrite> writes = a.driver->configuration();
  const auto instead = a.driver->instead_of_refused(writes[5], oegw::canopen::SdoAbortCode::ObjectDoesNotExist);
  ASSERT_TRUE(instead);
  writes[5] = *instead;
  a.driver->apply_boot_writes(writes);
  a.driver->begin_boot();
  std::string error;
  ASSERT_TRUE(a.driver->on_boot_read(0x6503, 0, std::vector<std::uint8_t>{0x00, 0x00}, error));  // §10.2: no alarm
  a.driver->on_online(at(0));
  a.driver->set_alive_since(at(0));
  a.frame(CanFrame(tpdo1, {0x10, 0, 0, 0, 0, 0, 0, 0}), 1);
  a.emcy(emcy(0x5051, 1, 1), 2);                                      // Out of range (+): latched
  a.frame(CanFrame(tpdo1, {0xF8, 0xFF, 0xFF, 0x7F, 0, 0, 0, 0}), 3);  // its marker 7FFFFFF8h
  a.log.clear();

  Watched b(sensor());
  Watched fresh(sensor());
  fresh.driver->apply_boot_writes(fresh.driver->configuration());
  fresh.driver->begin_boot();
  fresh.driver->on_online(at(0));
  fresh.driver->set_alive_since(at(0));
  fresh.log.clear();
  copy_state(*a.driver, *b.driver);
  const auto& nb = dynamic_cast<const Novotechnik406Driver&>(*b.driver);
  EXPECT_EQ(nb.position_object(), 0x6004);
  EXPECT_EQ(nb.last_error_position(), 0x7FFFFFF8u);
  EXPECT_EQ(b.driver->configuration()[5].data, instead->data) << "the next boot maps 6004h again";
  const std::vector<std::pair<std::uint16_t, std::uint8_t>> only_warnings{{0x6505, 0}};
  EXPECT_EQ(b.driver->boot_reads(), only_warnings);
  EXPECT_NE(fresh.driver->boot_reads(), only_warnings);
  for (Watched* w : {&a, &b, &fresh}) {
    w->frame(CanFrame(tpdo1, {0x20, 0, 0, 0, 0, 0, 0, 0}), 10);  // back in range: the latch holds
    w->log.push_back("position " + std::string(to_string(w->driver->value(0).status)));
    w->emcy(emcy(0x5051, 0, 0), 11);  // valid position
    w->frame(CanFrame(tpdo1, {0x21, 0, 0, 0, 0, 0, 0, 0}), 12);
  }
  EXPECT_EQ(b.log, a.log);
  EXPECT_NE(fresh.log, a.log);
  EXPECT_THAT(a.log, Contains("position error")) << "the latch held in A";
  EXPECT_THAT(fresh.log, Contains("position valid"));
  EXPECT_EQ(b.driver->value(0), a.driver->value(0));
}

TEST(DriverState, AStateOfAnotherBootsPdosIsRefused) {
  Watched a(mcb402());
  StateWriter w;
  a.driver->export_state(w);
  Watched b(mcb402());
  EXPECT_EQ(oegw::canopen::test_support::refusal(*b.driver,
                                                 oegw::canopen::test_support::with_value(w.text(), "watches.0.cob",
                                                                                         "1")),
            "state: 'watches.0.cob' differs: the state is of another boot's PDOs");
}

// A state no boot or run of that driver could have left is refused, naming the key.
TEST(DriverState, AStateNoRunCouldLeaveIsRefusedNamingTheKey) {
  struct Case {
    std::function<std::unique_ptr<Driver>()> make;
    std::string key, value, message;
  };
  const auto sensor = [] {
    std::string error;
    return make_novotechnik_406_driver(kSensor, {}, DriverOptions{}, error);
  };
  const auto grip_with_led = [] {
    auto d = elobau();
    d->set_output(*d->find_signal("leds[1]"), 1, at(0));
    return d;
  };
  const Case cases[] = {
      {[] { return mcb402(); }, "family.broken", "16", "state: 'family.broken' names an axis the board does not have"},
      {[] { return mcb402(); }, "family.outputs", "16", "state: 'family.outputs' sets a bit no LED of the board has"},
      {[] { return mcb402(); }, "signals.count", "3", "state: 'signals.count' differs from this driver's 15 signals"},
      {[] { return mcb402(); }, "signals.0.status", "9", "state: 'signals.0.status' is no signal status"},
      {grip_with_led, "family.led.0", "3", "state: 'family.led.0' is no LED code the gateway commands"},
      {sensor, "family.latches", "8", "state: 'family.latches' names no latch"},
      // A latch without the faults it sets (or the reverse) is no run's: the faults decide
      // what the inputs show. The refusal names the latch that decides.
      {[] { return mcb402(); }, "family.broken", "1", "state: 'family.broken' differs from signal 0's fault"},
      {[] { return mcb402(); }, "family.broken", "4", "state: 'family.broken' differs from signal 2's fault"},
      {[] { return mcb402(); }, "family.unknown_fault", "1",
       "state: 'family.unknown_fault' differs from signal 0's fault"},
      {sensor, "family.latches", "1", "state: 'family.latches' differs from signal 0's fault"},
      {sensor, "family.latches", "4", "state: 'family.latches' differs from signal 0's fault"},
      {[] { return elobau(); }, "family.global_emcy", "1", "state: 'family.global_emcy' differs from signal 0's fault"},
      {[] { return elobau(); }, "family.axis.2.emcy", "1", "state: 'family.axis.2.emcy' differs from signal 2's fault"},
      {[] { return elobau(); }, "family.button_emcy", "4", "state: 'family.button_emcy' differs from signal 7's fault"},
      {[] { return elobau(); }, "family.led_emcy", "1", "state: 'family.led_emcy' differs from signal 22's fault"},
  };
  for (const Case& c : cases) {
    const std::unique_ptr<Driver> a = c.make();
    StateWriter w;
    a->export_state(w);
    const std::unique_ptr<Driver> b = c.make();
    EXPECT_EQ(oegw::canopen::test_support::refusal(*b,
                                                   oegw::canopen::test_support::with_value(w.text(), c.key, c.value)),
              c.message);
  }
}

}  // namespace
