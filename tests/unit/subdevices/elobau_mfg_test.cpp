// ElobauMfgDriver frame by frame. Source: "CANopen Protocol for MFG 34xG and 36xG" v01.21
// (elobau); each test names its section/table.
#include "subdevices/elobau_mfg.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "subdevices/families.hpp"

namespace oegw::subdevices {
namespace {

using namespace std::chrono_literals;
using canopen::Duration;
using canopen::EmcyManufacturerField;

constexpr NodeId kNode{0x11};  // §7: default node-ID 0x11

class ElobauDriverTest : public ::testing::Test {
 protected:
  explicit ElobauDriverTest(DriverOptions opts = {}) {
    std::string err;
    auto d = make_elobau_mfg_driver(
        kNode, [this](const CanFrame& f) { sent.push_back(f); }, opts, err);
    EXPECT_TRUE(d) << err;
    drv.reset(static_cast<ElobauMfgDriver*>(d.release()));
    drv->on_change = [this](std::size_t i, const SignalValue& v) { changes.emplace_back(i, v); };
    drv->on_online(t);
  }
  std::size_t idx(std::string_view name) const {
    auto i = drv->find_signal(name);
    EXPECT_TRUE(i) << name;
    return i.value_or(0);
  }
  const SignalValue& val(std::string_view name) const { return drv->value(idx(name)); }
  // §14.1 Table 7: X, Y, A, B, C (channel 1), buttons 1..8, buttons 9..16, FFh.
  bool tpdo0(std::initializer_list<std::uint8_t> b) { return drv->on_frame(CanFrame(0x191, b), t); }
  // §14.2 Table 8: X, Y, A, B, C (channel 2), FFh, FFh, FFh.
  bool tpdo1(std::initializer_list<std::uint8_t> b) { return drv->on_frame(CanFrame(0x291, b), t); }
  DecodedEmcy emcy(std::uint16_t code, EmcyManufacturerField msef) {
    return drv->on_emcy(EmcyMessage{kNode, code, 0, msef}, t);
  }

  std::unique_ptr<ElobauMfgDriver> drv;
  std::vector<CanFrame> sent;
  std::vector<std::pair<std::size_t, SignalValue>> changes;
  TimePoint t{Duration{1'000'000}};
};

TEST_F(ElobauDriverTest, SignalListNamesUnitsAndRanges) {
  const auto& s = drv->signals();
  ASSERT_EQ(s.size(), 38u);
  EXPECT_EQ(s[0].name, "x");
  EXPECT_EQ(s[4].name, "wheel_c");
  EXPECT_EQ(s[0].min, -110);  // §15.1.2: detent ±110 reported by default ("pass")
  EXPECT_EQ(s[0].max, 110);
  EXPECT_EQ(s[0].unit, "percent");
  EXPECT_EQ(s[5].name, "buttons[1]");
  EXPECT_EQ(s[20].name, "buttons[16]");
  EXPECT_EQ(s[21].name, "presence");
  EXPECT_EQ(s[22].name, "leds[1]");
  EXPECT_EQ(s[37].name, "leds[16]");
  EXPECT_TRUE(s[22].output());
  EXPECT_EQ(drv->consumed_cob_ids(), (std::vector<std::uint32_t>{0x191, 0x291}));
}

TEST_F(ElobauDriverTest, Tpdo0DecodesAxesAsSignedPercentAndButtonBits) {
  // A grip with all 16 buttons (2100h:01h/02h = FFh, read back at boot).
  std::string error;
  drv->begin_boot();
  ASSERT_TRUE(drv->on_boot_read(0x2100, 0x01, std::vector<std::uint8_t>{0xFF}, error));
  ASSERT_TRUE(drv->on_boot_read(0x2100, 0x02, std::vector<std::uint8_t>{0xFF}, error));
  // Table 7 + Table 12: X = -50 % (CEh), Y = +100 % (64h), A = 0, B = -110 (92h, detent),
  // C = +110 (6Eh), buttons 1 and 3 pressed (05h), button 12 (presence) pressed (08h), FFh.
  EXPECT_TRUE(tpdo0({0xCE, 0x64, 0x00, 0x92, 0x6E, 0x05, 0x08, 0xFF}));
  EXPECT_EQ(val("x").value, -50);
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(val("y").value, 100);
  EXPECT_EQ(val("wheel_a").value, 0);
  EXPECT_EQ(val("wheel_b").value, -110);
  EXPECT_EQ(val("wheel_c").value, 110);
  EXPECT_EQ(val("buttons[1]").value, 1);
  EXPECT_EQ(val("buttons[2]").value, 0);
  EXPECT_EQ(val("buttons[3]").value, 1);
  EXPECT_EQ(val("buttons[12]").value, 1);
  EXPECT_EQ(val("presence").value, 1);  // §15.2.1: presence sensor = button 12
  EXPECT_EQ(val("presence").status, SignalStatus::Valid);
  EXPECT_EQ(val("buttons[16]").value, 0);
  EXPECT_EQ(val("x").timestamp, t);
}

TEST(ElobauDriverOptions, ClampReportsDetentAsHundred) {
  std::string err;
  auto d = make_elobau_mfg_driver(kNode, {}, DriverOptions{{{"detent", "clamp"}}}, err);
  ASSERT_TRUE(d) << err;
  d->on_online(TimePoint{});  // PDOs count once the node is operational
  // §15.1.2: the detent is the jump 100 % -> 110 %; "clamp" reports it as 100 %.
  d->on_frame(CanFrame(0x191, {0x6E, 0x92, 0x64, 0x00, 0x00, 0x00, 0x00, 0xFF}), TimePoint{});
  EXPECT_EQ(d->value(0).value, 100);
  EXPECT_EQ(d->value(1).value, -100);
  EXPECT_EQ(d->value(2).value, 100);
  EXPECT_EQ(d->signals()[0].max, 100);
}

TEST(ElobauDriverOptions, UnknownOrBadOptionsAreRefused) {
  std::string err;
  EXPECT_FALSE(make_elobau_mfg_driver(kNode, {}, DriverOptions{{{"tolerance", "5"}}}, err));
  EXPECT_NE(err.find("unknown option"), std::string::npos);
  EXPECT_FALSE(make_elobau_mfg_driver(kNode, {}, DriverOptions{{{"detent", "round"}}}, err));
  EXPECT_FALSE(make_elobau_mfg_driver(kNode, {}, DriverOptions{{{"channel_tolerance", "5x"}}}, err));
  EXPECT_FALSE(make_elobau_mfg_driver(kNode, {}, DriverOptions{{{"cycle_ms", "2"}}}, err));  // §14.2 Notice
  EXPECT_FALSE(make_elobau_mfg_driver(kNode, {}, DriverOptions{{{"channel2_timeout_ms", "50"}}}, err))
      << "a timeout below the 100 ms cycle would always fire";
  EXPECT_TRUE(make_elobau_mfg_driver(kNode, {}, DriverOptions{{{"channel2_timeout_ms", "250"}}}, err)) << err;
}

TEST_F(ElobauDriverTest, ErrorValue126AndNotAvailable127) {
  // §15.1 / Table 14 20xxh:1Bh = 126 error value, 1Ch = 127 not-available value.
  tpdo0({0x7E, 0x7F, 0x14, 0x00, 0x00, 0x00, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Error);
  EXPECT_EQ(val("x").value, 0);  // neutral, never 126
  EXPECT_EQ(val("y").status, SignalStatus::NotAvailable);
  EXPECT_EQ(val("y").value, 0);
  EXPECT_EQ(val("wheel_a").value, 20);
  EXPECT_EQ(val("wheel_a").status, SignalStatus::Valid);
  // A good value afterwards clears it.
  tpdo0({0x0A, 0x00, 0x14, 0x00, 0x00, 0x00, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(val("x").value, 10);
  EXPECT_EQ(val("y").status, SignalStatus::Valid);
}

TEST_F(ElobauDriverTest, UndefinedValuesBeyondDetentAreErrors) {
  // Only -110..110 (Tables 10/11) plus the codes 126/127 are defined: 111 (6Fh) and -128 (80h) are not.
  tpdo0({0x6F, 0x80, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Error);
  EXPECT_EQ(val("x").value, 0);
  EXPECT_EQ(val("y").status, SignalStatus::Error);
  EXPECT_EQ(drv->stats().out_of_range, 2u);
}

TEST_F(ElobauDriverTest, ChannelMismatchBeyondToleranceIsAnError) {
  // Tables 7/8: channel 1 X = 50, channel 2 X = 56 (> 5 % apart), Y = 20 / 25 (5 %: within).
  tpdo0({0x32, 0x14, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  tpdo1({0x38, 0x19, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  // A TPDO #1 may run ahead of TPDO #0 (its own timer, no inhibit time): the next TPDO #0
  // decides. Channel 1 still 50 against 56: a mismatch.
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(drv->counters().mismatches, 0u);
  tpdo0({0x32, 0x14, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Error);
  EXPECT_EQ(val("x").value, 0);
  EXPECT_EQ(val("y").status, SignalStatus::Valid);
  EXPECT_EQ(val("y").value, 20);
  EXPECT_EQ(drv->counters().mismatches, 1u);
  // The verdict holds for the next channel-1 frame until a TPDO #1 agrees again.
  tpdo0({0x33, 0x14, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Error);
  tpdo1({0x34, 0x14, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(val("x").value, 51);
  EXPECT_EQ(drv->counters().mismatches, 1u);
}

// The grip's TPDO #1 carries a movement before TPDO #0 may (its 2 ms inhibit time, Table 14): the
// channels were only out of step, no mismatch.
TEST_F(ElobauDriverTest, ATpdo1AheadOfTpdo0IsNoMismatch) {
  tpdo0({0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  tpdo1({0x00, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  tpdo1({0x32, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});  // the stick moved to 50 %
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  tpdo0({0x32, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});  // channel 1 catches up
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(val("x").value, 50);
  EXPECT_EQ(drv->counters().mismatches, 0u);
}

TEST(ElobauDriverOptions, ToleranceOptionIsHonoured) {
  std::string err;
  auto d = make_elobau_mfg_driver(kNode, {}, DriverOptions{{{"channel_tolerance", "10"}}}, err);
  ASSERT_TRUE(d);
  d->on_online(TimePoint{});  // PDOs count once the node is operational
  d->on_frame(CanFrame(0x191, {0x32, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF}), TimePoint{});
  d->on_frame(CanFrame(0x291, {0x3C, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF}), TimePoint{});
  EXPECT_EQ(d->value(0).status, SignalStatus::Valid);  // 50 vs 60: exactly 10
  d->on_frame(CanFrame(0x291, {0x3D, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF}), TimePoint{});
  d->on_frame(CanFrame(0x191, {0x32, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF}), TimePoint{});
  EXPECT_EQ(d->value(0).status, SignalStatus::Error);  // 50 vs 61, confirmed by the next TPDO #0
}

TEST_F(ElobauDriverTest, DetentOnOneChannelAndHundredOnTheOtherAgree) {
  // §15.1.2: "The detent function is a jump from 100% to 110%" — the same mechanical end.
  tpdo0({0x6E, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  tpdo1({0x64, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(val("x").value, 110);
  EXPECT_EQ(drv->counters().mismatches, 0u);
}

TEST_F(ElobauDriverTest, Channel2ErrorIsAnErrorChannel2NotAvailableIsNot) {
  tpdo0({0x32, 0x32, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  // Table 14 20xxh:01h: 1 = only signal 1 available -> channel 2 carries 127.
  tpdo1({0x7E, 0x7F, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Error);
  EXPECT_EQ(val("y").status, SignalStatus::Valid);
  EXPECT_EQ(val("y").value, 50);
  // Sticky until channel 2 recovers: the next TPDO #0 does not flicker back to Valid.
  tpdo0({0x32, 0x32, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Error);
  tpdo1({0x32, 0x7F, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
}

TEST_F(ElobauDriverTest, MissingChannel2IsNotAnErrorByDefault) {
  for (int i = 0; i < 50; ++i) {
    t += 100ms;
    tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  }
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(drv->stats().channel2_missing, 0u);
}

class ElobauDriverChannel2Timeout : public ElobauDriverTest {
 protected:
  ElobauDriverChannel2Timeout() : ElobauDriverTest(DriverOptions{{{"channel2_timeout_ms", "250"}}}) {}
};

TEST_F(ElobauDriverChannel2Timeout, OverdueChannel2MakesAxesErrors) {
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  tpdo1({0x0A, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  t += 250ms;
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Valid) << "exactly the timeout is still in time";
  t += 1ms;
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Error);
  EXPECT_EQ(val("wheel_c").status, SignalStatus::Error);
  EXPECT_EQ(val("buttons[1]").status, SignalStatus::Valid) << "buttons have no second channel";
  EXPECT_EQ(drv->stats().channel2_missing, 1u);
  tpdo1({0x0A, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
}

TEST_F(ElobauDriverChannel2Timeout, NeverSeenChannel2CountsFromTheFirstChannel1Frame) {
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  t += 300ms;
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Error);
}

TEST_F(ElobauDriverTest, WrongLengthAndForeignFramesAreCountedAndIgnored) {
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  EXPECT_FALSE(tpdo0({0x50, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}));  // 7 bytes, Table 7 has 8
  EXPECT_FALSE(tpdo1({0x50}));
  EXPECT_FALSE(drv->on_frame(CanFrame(0x192, {0x50, 0, 0, 0, 0, 0, 0, 0xFF}), t));  // another node
  EXPECT_FALSE(drv->on_frame(CanFrame::remote(0x191, 8), t));
  EXPECT_EQ(drv->counters().wrong_length, 2u);
  EXPECT_EQ(drv->counters().unknown_cob, 2u);
  EXPECT_EQ(val("x").value, 10) << "nothing of a bad frame is passed through";
}

TEST_F(ElobauDriverTest, OnChangeFiresOnlyOnChange) {
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  const auto n = changes.size();
  EXPECT_EQ(n, 5u + 16u + 1u);  // every input left Offline
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  EXPECT_EQ(changes.size(), n);
  tpdo0({0x0B, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  ASSERT_EQ(changes.size(), n + 1);
  EXPECT_EQ(changes.back().first, idx("x"));
  EXPECT_EQ(changes.back().second.value, 11);
}

TEST_F(ElobauDriverTest, OfflineThenOnlineWaitsForAPdo) {
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  drv->on_offline(t);
  EXPECT_EQ(val("x").status, SignalStatus::Offline);
  EXPECT_EQ(val("x").value, 0);
  EXPECT_EQ(val("buttons[1]").value, 0);
  drv->on_online(t);
  EXPECT_EQ(val("x").status, SignalStatus::Offline);
  tpdo1({0x0A, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Offline) << "channel 2 alone reports nothing";
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
}

// §12.3 Table 5: code, error register (always 0), 4001h in bytes 3..4, then FFh.
TEST_F(ElobauDriverTest, EmcyAxisOutOfRangeIsDecodedAndPutsThatAxisInError) {
  tpdo0({0x0A, 0x14, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  tpdo1({0x0A, 0x14, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  auto d = emcy(0x1000, {0x21, 0x00, 0xFF, 0xFF, 0xFF});  // Table 6 0021h
  EXPECT_TRUE(d.error);
  EXPECT_EQ(d.text, "elobau 4001h 0021h: Y Axis, Signal 2, Out Of Range");
  EXPECT_EQ(d.affected, (std::vector<std::size_t>{idx("y")}));
  EXPECT_EQ(val("y").status, SignalStatus::Error);
  EXPECT_EQ(val("y").value, 0);
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  // §12.2 (4000h = 1): the device then sends the error value on channel 2 -> stays Error.
  tpdo0({0x0A, 0x14, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  EXPECT_EQ(val("y").status, SignalStatus::Error);
  tpdo1({0x0A, 0x7E, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(val("y").status, SignalStatus::Error);
  // Fault gone: a good pair clears it.
  tpdo0({0x0A, 0x14, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  tpdo1({0x0A, 0x14, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(val("y").status, SignalStatus::Valid);
}

TEST_F(ElobauDriverTest, EmcyEveryTable6AxisCodeHitsItsAxis) {
  tpdo0({0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  const std::pair<std::uint8_t, const char*> cases[] = {{0x10, "x"},       {0x12, "x"},       {0x20, "y"},
                                                        {0x31, "wheel_a"}, {0x42, "wheel_b"}, {0x50, "wheel_c"}};
  for (const auto& [code, name] : cases) {
    auto d = emcy(0x1000, {code, 0x00, 0xFF, 0xFF, 0xFF});
    ASSERT_EQ(d.affected.size(), 1u) << int(code);
    EXPECT_EQ(d.affected[0], idx(name)) << int(code);
    EXPECT_EQ(val(name).status, SignalStatus::Error);
  }
}

TEST_F(ElobauDriverTest, EmcyButtonTimeoutLatchesUntilErrorReset) {
  tpdo0({0x00, 0x00, 0x00, 0x00, 0x00, 0x04, 0x00, 0xFF});
  auto d = emcy(0x1000, {0x63, 0x00, 0xFF, 0xFF, 0xFF});  // Table 6 0063h button 3 timeout
  EXPECT_EQ(d.text, "elobau 4001h 0063h: Button 3 Timeout");
  EXPECT_EQ(d.affected, (std::vector<std::size_t>{idx("buttons[3]")}));
  EXPECT_EQ(val("buttons[3]").status, SignalStatus::Error);
  // The device sends the button error value 0 (2100h:09h): indistinguishable from released.
  tpdo0({0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  EXPECT_EQ(val("buttons[3]").status, SignalStatus::Error);
  EXPECT_EQ(val("buttons[2]").status, SignalStatus::Valid);
  d = emcy(0x0000, {0x00, 0x00, 0xFF, 0xFF, 0xFF});  // §12.4 0000h error reset
  EXPECT_FALSE(d.error);
  EXPECT_EQ(val("buttons[3]").status, SignalStatus::Valid);
  // Button 11 = 006Bh, the last of Table 6.
  EXPECT_EQ(emcy(0x1000, {0x6B, 0x00, 0xFF, 0xFF, 0xFF}).affected, (std::vector<std::size_t>{idx("buttons[11]")}));
}

// Table 6 0002h "Parameter Checksum Error CRC32. This error is also set until first parameter
// saving process": by EMCY every input is in doubt until the 4001h read-back at the next boot
// decides (a never-saved grip sends it at power-on; at run time it means corrupt parameters).
TEST_F(ElobauDriverTest, EmcyParameterChecksum0002hFaultsEveryInputUntilTheReadBack) {
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  auto d = emcy(0x1000, {0x02, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(d.text.rfind("elobau 4001h 0002h: Parameter Checksum Error", 0), 0u) << d.text;
  EXPECT_TRUE(d.error);
  EXPECT_EQ(d.affected.size(), ElobauMfgDriver::kFirstLed) << "every input";
  EXPECT_EQ(val("x").status, SignalStatus::Error);
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  EXPECT_EQ(val("buttons[1]").status, SignalStatus::Error) << "a PDO is no evidence";
  std::string error;
  drv->begin_boot();
  ASSERT_TRUE(drv->on_boot_read(0x4001, 0, std::vector<std::uint8_t>{0x00, 0x00}, error));
  EXPECT_FALSE(drv->any_fault()) << "4001h = 0 at the next boot ends it";
  // The CAN communication warnings of §12.4 ("0x81xx: Communication") fault nothing, also the
  // 81xxh codes the document does not list.
  for (const std::uint16_t code : {0x8110, 0x8120, 0x8140, 0x8130, 0x81FF}) {
    d = emcy(code, {0x01, 0x00, 0xFF, 0xFF, 0xFF});
    EXPECT_FALSE(d.error) << code;
    EXPECT_TRUE(d.affected.empty()) << code;
  }
  EXPECT_FALSE(drv->any_fault());
}

// Driver::next_deadline() (subdevices/driver.hpp) is kept between calls, for the event loop asks
// after every frame: whatever changes its answer must change it — the proof of life, a PDO, and
// a signal no longer watched (faulted, stale) with no watch changed.
TEST_F(ElobauDriverTest, TheNextDeadlineFollowsThePdosAndTheStatusOfTheSignals) {
  EXPECT_EQ(drv->next_deadline(), std::nullopt) << "not proven alive: nothing is due";
  drv->set_alive_since(t);
  const Duration d = drv->freshness(idx("x"));
  ASSERT_GT(d.count(), 0);
  EXPECT_EQ(drv->next_deadline(), t + d) << "TPDO #0 is due one deadline after the proof of life";
  t += 10ms;
  drv->pdo_received(0x191, t);
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  EXPECT_EQ(drv->next_deadline(), t + d);
  // Every input faulted (§12.4, 4001h 0002h): none is left to mark stale, so no wake-up is due.
  emcy(0x1000, {0x02, 0x00, 0xFF, 0xFF, 0xFF});
  ASSERT_EQ(val("x").status, SignalStatus::Error);
  EXPECT_EQ(drv->next_deadline(), std::nullopt);
}

// The direction that matters for safety: a signal watched again through its status alone (a
// fault cleared, the next PDO's value: no watch changed) makes its PDO's deadline due again.
TEST_F(ElobauDriverTest, ASignalWatchedAgainAfterItsFaultMakesItsDeadlineDueAgain) {
  drv->set_alive_since(t);
  drv->pdo_received(0x191, t);
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  const auto due = drv->next_deadline();
  ASSERT_TRUE(due);
  emcy(0x1000, {0x02, 0x00, 0xFF, 0xFF, 0xFF});  // every input faulted: nothing due
  ASSERT_EQ(drv->next_deadline(), std::nullopt);
  std::string error;
  drv->begin_boot();
  ASSERT_TRUE(drv->on_boot_read(0x4001, 0, std::vector<std::uint8_t>{0x00, 0x00}, error)) << error;
  ASSERT_FALSE(drv->any_fault());
  t += 1ms;
  tpdo0({0x0B, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});  // on_frame only: no pdo_received()
  ASSERT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(drv->next_deadline(), due);
}

TEST_F(ElobauDriverTest, AnOverdueSignalMarkedStaleIsNoLongerDueUntilItsNextPdo) {
  drv->set_alive_since(t);
  drv->pdo_received(0x191, t);
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  const Duration d = drv->freshness(idx("x"));
  const auto due = drv->next_deadline();
  ASSERT_EQ(due, t + d);
  drv->advance(*due);
  EXPECT_EQ(val("x").status, SignalStatus::Stale);
  EXPECT_EQ(drv->next_deadline(), std::nullopt) << "every signal of the overdue PDO is stale already";
  t = *due + 5ms;
  drv->pdo_received(0x191, t);
  tpdo0({0x0B, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(drv->next_deadline(), t + d);
}

// A frame that repeats a signal's value is evidence only for the PDO that carries it: channel 2
// (TPDO #1) repeating X once TPDO #0 is overdue makes X Stale, although value and status are
// those already shown (Driver::update's inline path must not keep them Valid).
TEST_F(ElobauDriverTest, AnUnchangedValueRepeatedPastItsPdosDeadlineIsStale) {
  drv->set_alive_since(t);
  drv->pdo_received(0x191, t);
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  const Duration d = drv->freshness(idx("x"));
  const auto before = changes.size();
  t += d - 1ms;
  tpdo1({0x0A, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});  // on_frame only: no pdo_received()
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(val("x").timestamp, t) << "a repeated value moves only its time";
  EXPECT_EQ(changes.size(), before);
  t += 1ms;  // TPDO #0's deadline
  tpdo1({0x0A, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Stale);
  EXPECT_EQ(val("x").value, 10);
}

// A never-saved grip (4001h = 0002h read back at boot): with 4001h holding one code and no 0000h
// while an error lasts (§12.4), no other error could be seen to end. parameter_checksum: refuse
// (the default) refuses the node, the reason saying how to commission it.
TEST_F(ElobauDriverTest, NeverSavedGripIsRefusedAtBootWithTheCommissioningStep) {
  std::string error;
  drv->begin_boot();
  EXPECT_FALSE(drv->on_boot_read(0x4001, 0, std::vector<std::uint8_t>{0x02, 0x00}, error));
  EXPECT_NE(error.find("4001h reads 0002h"), std::string::npos) << error;
  EXPECT_NE(error.find("w 0x1010 1 u32 0x65766173"), std::string::npos) << error;
  EXPECT_NE(error.find("parameter_checksum: save"), std::string::npos) << error;
  EXPECT_FALSE(drv->restart_after_configuration());
}

// Table 14: 4001h holds one code. An error raised at boot after the never-saved 0002h hides it
// from the read-back; the 0002h EMCY seen between boot-up and operational counts instead.
TEST_F(ElobauDriverTest, NeverSavedGripIsRefusedWhenALaterErrorHidesItFrom4001h) {
  std::string error;
  drv->on_offline(t);
  drv->begin_boot();
  (void)emcy(0x1000, {0x02, 0x00, 0xFF, 0xFF, 0xFF});  // Table 5: 4001h = 0002h, at power-on
  (void)emcy(0x1000, {0x01, 0x00, 0xFF, 0xFF, 0xFF});  // then 0001h: 4001h now reads 0001h
  EXPECT_FALSE(drv->on_boot_read(0x4001, 0, std::vector<std::uint8_t>{0x01, 0x00}, error));
  EXPECT_NE(error.find("4001h 0002h came at boot (4001h now reads 0001h)"), std::string::npos) << error;
  EXPECT_NE(error.find("w 0x1010 1 u32 0x65766173"), std::string::npos) << error;
}

// parameter_checksum: save: §8 "write "save" (0x65766173) into the object 0x1010.1. Restart the
// joystick after saving procedure" — the save ends the configuration, the restart follows; 0002h
// still read after that is a corrupt memory, refused.
class ElobauSaveTest : public ElobauDriverTest {
 protected:
  ElobauSaveTest() : ElobauDriverTest(DriverOptions{{{"parameter_checksum", "save"}}}) {}
};
TEST_F(ElobauSaveTest, NeverSavedGripIsSavedOnceAndRestarted) {
  std::string error;
  drv->begin_boot();
  ASSERT_TRUE(drv->on_boot_read(0x4001, 0, std::vector<std::uint8_t>{0x02, 0x00}, error)) << error;
  const auto w = drv->configuration();
  ASSERT_FALSE(w.empty());
  EXPECT_EQ(w.back().index, 0x1010);
  EXPECT_EQ(w.back().sub, 1);
  EXPECT_EQ(w.back().data, (std::vector<std::uint8_t>{0x73, 0x61, 0x76, 0x65})) << "\"save\", §8";
  EXPECT_TRUE(drv->restart_after_configuration());
  EXPECT_TRUE(drv->any_fault()) << "until the restarted grip reads 4001h = 0";
  // Restarted: the next boot configures without a save.
  drv->begin_boot();
  EXPECT_FALSE(drv->restart_after_configuration());
  EXPECT_FALSE(drv->on_boot_read(0x4001, 0, std::vector<std::uint8_t>{0x02, 0x00}, error)) << "0002h after the save";
  EXPECT_NE(error.find("corrupt"), std::string::npos) << error;
  drv->begin_boot();
  ASSERT_TRUE(drv->on_boot_read(0x4001, 0, std::vector<std::uint8_t>{0x00, 0x00}, error));
  EXPECT_FALSE(drv->any_fault());
  EXPECT_NE(drv->configuration().back().index, 0x1010);
}

TEST(ElobauOptions, ParameterChecksumTakesRefuseOrSave) {
  std::string err;
  EXPECT_EQ(make_elobau_mfg_driver(kNode, {}, DriverOptions{{{"parameter_checksum", "warning"}}}, err), nullptr);
  EXPECT_NE(err.find("parameter_checksum 'warning' must be 'refuse' or 'save'"), std::string::npos) << err;
  auto d = make_elobau_mfg_driver(kNode, {}, DriverOptions{{{"parameter_checksum", "save"}}}, err);
  ASSERT_NE(d, nullptr) << err;
  EXPECT_TRUE(static_cast<ElobauMfgDriver&>(*d).options().save_unsaved);
}

// 2100h:01h/02h "Configuration 8_1 / 16_9" (0: button not available; default 63): a button the
// grip does not have is NotAvailable, whatever its TPDO bit (the not-available value 2100h:0Ah);
// the mapping file's sdo list writing 2100h:01h is taken too.
TEST_F(ElobauDriverTest, ButtonsTheGripDoesNotHaveAreNotAvailable) {
  std::string error;
  drv->begin_boot();
  const auto reads = drv->boot_reads();
  EXPECT_NE(std::find(reads.begin(), reads.end(), std::pair<std::uint16_t, std::uint8_t>{0x2100, 0x01}), reads.end());
  EXPECT_NE(std::find(reads.begin(), reads.end(), std::pair<std::uint16_t, std::uint8_t>{0x2100, 0x02}), reads.end());
  ASSERT_TRUE(drv->on_boot_read(0x2100, 0x01, std::vector<std::uint8_t>{63}, error));
  ASSERT_TRUE(drv->on_boot_read(0x2100, 0x02, std::vector<std::uint8_t>{0x00}, error));
  tpdo0({0x00, 0x00, 0x00, 0x00, 0x00, 0x21, 0x00, 0xFF});
  EXPECT_EQ(val("buttons[1]").status, SignalStatus::Valid);
  EXPECT_EQ(val("buttons[6]").value, 1);
  EXPECT_EQ(val("buttons[7]").status, SignalStatus::NotAvailable);
  EXPECT_EQ(val("buttons[16]").status, SignalStatus::NotAvailable);
  EXPECT_EQ(val("presence").status, SignalStatus::NotAvailable) << "button 12";
  drv->apply_boot_writes({SdoWrite{0x2100, 0x01, {0xFF}, {}}, SdoWrite{0x2100, 0x02, {0x08}, {}}});
  tpdo0({0x00, 0x00, 0x00, 0x00, 0x00, 0x80, 0x08, 0xFF});
  EXPECT_EQ(val("buttons[8]").status, SignalStatus::Valid);
  EXPECT_EQ(val("buttons[8]").value, 1);
  EXPECT_EQ(val("presence").value, 1);
  EXPECT_EQ(val("buttons[9]").status, SignalStatus::NotAvailable);
  // An answer of the wrong length tells nothing: the node is refused.
  drv->begin_boot();
  EXPECT_FALSE(drv->on_boot_read(0x2100, 0x01, std::vector<std::uint8_t>{0x3F, 0x00}, error));
  EXPECT_FALSE(drv->on_boot_read_abort(0x2100, 0x01, canopen::SdoAbortCode::ObjectDoesNotExist));
}

// 0001h "Application Program Checksum Error": the whole device is in doubt.
TEST_F(ElobauDriverTest, EmcyChecksumErrorPutsEveryInputInErrorUntilReset) {
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  auto d = emcy(0x1000, {0x01, 0x00, 0xFF, 0xFF, 0xFF});  // Table 6 0001h
  EXPECT_EQ(d.text, "elobau 4001h 0001h: Application Program Checksum Error");
  EXPECT_EQ(d.affected.size(), 22u);
  EXPECT_EQ(val("x").status, SignalStatus::Error);
  EXPECT_EQ(val("buttons[1]").status, SignalStatus::Error);
  EXPECT_EQ(val("buttons[1]").value, 0);
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Error) << "a PDO does not vouch for a corrupt parameter set";
  emcy(0x0000, {0x00, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(val("x").value, 10);
  EXPECT_EQ(val("buttons[1]").value, 1);
}

TEST_F(ElobauDriverTest, EmcyOneByteCodeWithFfFillerIsDecodedToo) {
  // Table 5 fills unused manufacturer bytes with FFh; "uses only the 1st byte".
  auto d = emcy(0x1000, {0x11, 0xFF, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(d.text, "elobau 4001h 0011h: X Axis, Signal 2, Out Of Range");
}

TEST_F(ElobauDriverTest, EmcyUnknownCodesAreCountedAndIgnored) {
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  auto d = emcy(0x1000, {0x03, 0x00, 0xFF, 0xFF, 0xFF});  // Table 6: 0003h "not used"
  EXPECT_FALSE(d.error);
  d = emcy(0x1000, {0x13, 0x00, 0xFF, 0xFF, 0xFF});
  d = emcy(0x5000, {0x00, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(drv->counters().unknown_emcy, 3u);
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
}

TEST_F(ElobauDriverTest, EmcyCommunicationNoticesInvalidateNothing) {
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  auto d = emcy(0x8140, {0x03, 0xFF, 0xFF, 0xFF, 0xFF});  // §12.4: count of bus-offs in byte 3
  EXPECT_FALSE(d.error);
  EXPECT_EQ(d.text, "elobau EMCY 8140h: recovered from bus off (count 3)");
  EXPECT_FALSE(emcy(0x8120, {}).error);
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(drv->counters().unknown_emcy, 0u);
}

// §14.3 Table 9 + Table 13: 2 bits per LED, 00 off, 01 on, 10 blink, 11 no change.
TEST_F(ElobauDriverTest, LedCommandsCarryTheWholeStateWithNoChangeElsewhere) {
  ASSERT_TRUE(drv->set_output(idx("leds[1]"), 1, t));  // button 1 LED 1 on: byte 0 bits 0,1 = 01
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], CanFrame(0x211, {0xFD, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF}));
  ASSERT_TRUE(drv->set_output(idx("leds[4]"), 2, t));  // button 2 LED 2 blink: byte 0 bits 6,7 = 10
  EXPECT_EQ(sent.back(), CanFrame(0x211, {0xBD, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF}));
  ASSERT_TRUE(drv->set_output(idx("leds[10]"), 0, t));  // button 5 LED 2 off: byte 2 bits 2,3 = 00
  EXPECT_EQ(sent.back(), CanFrame(0x211, {0xBD, 0xFF, 0xF3, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF}));
  EXPECT_EQ(val("leds[4]").value, 2);
  EXPECT_EQ(val("leds[4]").status, SignalStatus::Valid);
}

TEST_F(ElobauDriverTest, ThumbWheelLedsFollowTheMaskBitOrder) {
  // 2200h:0Ah bit 10 = wheel A LED 2-2 (RPDO byte 5 bits 0,1); bit 14 = wheel A LED 1+3
  // (byte 5 bits 4,5); bit 13 = wheel B LED 2-1 (byte 6 bits 2,3); bit 15 = wheel B LED 1+3
  // (byte 6 bits 4,5).
  drv->set_output(idx("leds[11]"), 1, t);
  EXPECT_EQ(sent.back(), CanFrame(0x211, {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFD, 0xFF, 0xFF}));
  drv->set_output(idx("leds[15]"), 0, t);
  EXPECT_EQ(sent.back(), CanFrame(0x211, {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xCD, 0xFF, 0xFF}));
  drv->set_output(idx("leds[14]"), 2, t);
  drv->set_output(idx("leds[16]"), 1, t);
  EXPECT_EQ(sent.back(), CanFrame(0x211, {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xCD, 0xDB, 0xFF}));
}

TEST_F(ElobauDriverTest, BadOutputsSendNothingAndRepeatsAreNotResent) {
  EXPECT_FALSE(drv->set_output(idx("leds[1]"), 3, t));  // 11 is "no change", not a state
  EXPECT_FALSE(drv->set_output(idx("leds[1]"), -1, t));
  EXPECT_FALSE(drv->set_output(idx("x"), 1, t));
  EXPECT_FALSE(drv->set_output(999, 1, t));
  EXPECT_TRUE(sent.empty());
  drv->set_output(idx("leds[2]"), 1, t);
  drv->set_output(idx("leds[2]"), 1, t);
  EXPECT_EQ(sent.size(), 1u) << "§14.3: cyclic update is not necessary";
}

TEST_F(ElobauDriverTest, OnlineAgainResendsTheLedState) {
  drv->set_output(idx("leds[3]"), 1, t);  // byte 0 bits 4,5 = 01
  drv->on_offline(t);
  drv->on_online(t);
  ASSERT_EQ(sent.size(), 2u);
  EXPECT_EQ(sent.back(), CanFrame(0x211, {0xDF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF}));
}

TEST_F(ElobauDriverTest, LedTimeoutEmcyMarksLedsUntilReset) {
  drv->set_output(idx("leds[1]"), 1, t);
  auto d = emcy(0x1000, {0x70, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(d.text, "elobau 4001h 0070h: LED Message Timeout");
  EXPECT_EQ(d.affected.size(), 16u);
  EXPECT_EQ(val("leds[1]").status, SignalStatus::Error);
  EXPECT_EQ(val("leds[1]").value, 1);
  emcy(0x0000, {});
  EXPECT_EQ(val("leds[1]").status, SignalStatus::Valid);
}

TEST_F(ElobauDriverTest, ConfigurationPinsCodesTimersAndErrorBehaviour) {
  const auto w = drv->configuration();
  auto find = [&w](std::uint16_t i, std::uint8_t s) -> const SdoWrite* {
    for (const auto& x : w)
      if (x.index == i && x.sub == s) return &x;
    return nullptr;
  };
  ASSERT_TRUE(find(0x1801, 5));  // Table 14: 1801h:05 event timer, U16 ms
  EXPECT_EQ(find(0x1801, 5)->data, (std::vector<std::uint8_t>{100, 0}));
  ASSERT_TRUE(find(0x1800, 5));
  ASSERT_TRUE(find(0x4000, 0));  // §12.2: 1 = no state change, error value sent
  EXPECT_EQ(find(0x4000, 0)->data, (std::vector<std::uint8_t>{1}));
  ASSERT_TRUE(find(0x2004, 0x1B));
  EXPECT_EQ(find(0x2004, 0x1B)->data, (std::vector<std::uint8_t>{126}));
  EXPECT_EQ(find(0x2002, 0x1C)->data, (std::vector<std::uint8_t>{127}));
  EXPECT_EQ(find(0x2100, 0x09)->data, (std::vector<std::uint8_t>{0}));
  EXPECT_FALSE(find(0x1017, 0)) << "heartbeat is the network manager's";
  EXPECT_FALSE(find(0x1800, 2)) << "transmission type is ro (Table 14)";
  const auto id = drv->expected_identity();
  EXPECT_EQ(id.vendor_id, 0x000000B4u);  // Table 14 1018h:01
  EXPECT_EQ(id.device_type, 0u);
}

TEST_F(ElobauDriverTest, EmcyErrorShowsBeforeTheFirstPdoAndResetReturnsToOffline) {
  // §12.3: an EMCY may arrive before any TPDO (e.g. right after NMT start).
  emcy(0x1000, {0x10, 0x00, 0xFF, 0xFF, 0xFF});
  emcy(0x1000, {0x61, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Error);
  EXPECT_EQ(val("buttons[1]").status, SignalStatus::Error);
  EXPECT_EQ(val("y").status, SignalStatus::Offline);
  emcy(0x0000, {});
  EXPECT_EQ(val("x").status, SignalStatus::Offline) << "no data yet: not Valid";
  EXPECT_EQ(val("buttons[1]").status, SignalStatus::Offline);
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
  EXPECT_EQ(val("buttons[1]").value, 1);
}

TEST_F(ElobauDriverTest, AxisEmcyWithoutErrorValueInPdoClearsOnTheNextGoodPair) {
  // 0012h "signal difference too high" is "function not implemented" (Table 6): if it comes,
  // the PDOs may not carry 126; the next agreeing pair ends it.
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  emcy(0x1000, {0x12, 0x00, 0xFF, 0xFF, 0xFF});
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Error) << "channel 1 alone does not clear it";
  tpdo1({0x0A, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_EQ(val("x").status, SignalStatus::Valid);
}

// 4001h "Error Code" (Table 14) read back at every (re)start decides the faults latched before:
// 0 clears them (a grip that rebooted sends no error reset), a Table 6 code faults what its EMCY
// would; going offline and back keeps them meanwhile.
TEST_F(ElobauDriverTest, ReadBackOf4001hAtBootDecidesTheLatchedFaults) {
  tpdo0({0x0A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0xFF});
  emcy(0x1000, {0x63, 0x00, 0xFF, 0xFF, 0xFF});  // button 3 timeout
  ASSERT_TRUE(drv->faulted(idx("buttons[3]")));
  drv->on_offline(t);
  drv->on_online(t);
  EXPECT_TRUE(drv->faulted(idx("buttons[3]"))) << "offline/online is no evidence";
  drv->on_application_reset(t);
  EXPECT_TRUE(drv->faulted(idx("buttons[3]"))) << "the read-back decides, not the boot-up";
  drv->begin_boot();
  const auto reads = drv->boot_reads();
  ASSERT_EQ(reads.size(), 3u);
  EXPECT_EQ(reads[0], (std::pair<std::uint16_t, std::uint8_t>{0x4001, 0}));
  std::string error;
  // Still the button timeout: kept.
  ASSERT_TRUE(drv->on_boot_read(0x4001, 0, std::vector<std::uint8_t>{0x63, 0x00}, error));
  ASSERT_TRUE(drv->on_boot_read(0x2100, 0x01, std::vector<std::uint8_t>{63}, error));
  ASSERT_TRUE(drv->on_boot_read(0x2100, 0x02, std::vector<std::uint8_t>{0}, error));
  EXPECT_TRUE(drv->boot_reads().empty());
  EXPECT_TRUE(drv->faulted(idx("buttons[3]")));
  // Next start: no error any more.
  drv->begin_boot();
  ASSERT_TRUE(drv->on_boot_read(0x4001, 0, std::vector<std::uint8_t>{0x00, 0x00}, error));
  EXPECT_FALSE(drv->any_fault());
  drv->on_online(t);
  tpdo0({0x0A, 0x00, 0x04, 0x00, 0x00, 0x04, 0x00, 0xFF});
  EXPECT_EQ(val("buttons[3]").status, SignalStatus::Valid);
  EXPECT_EQ(val("buttons[3]").value, 1);
  // A code read back that the gateway never saw as EMCY: Y axis signal 1 out of range.
  drv->begin_boot();
  ASSERT_TRUE(drv->on_boot_read(0x4001, 0, std::vector<std::uint8_t>{0x20, 0x00}, error));
  EXPECT_TRUE(drv->faulted(idx("y")));
  EXPECT_FALSE(drv->faulted(idx("x")));
  // The unsaved-parameters code read back: the node is refused (parameter_checksum: refuse).
  drv->begin_boot();
  ASSERT_TRUE(drv->on_boot_read(0x4001, 0, std::vector<std::uint8_t>{0x00, 0x00}, error));
  drv->begin_boot();
  EXPECT_FALSE(drv->on_boot_read(0x4001, 0, std::vector<std::uint8_t>{0x02, 0x00}, error));
}

// An axis EMCY is cleared by a good channel pair received after it, never by the channel-1
// value from before it: X 50 %, EMCY 4001h 0010h "X axis signal 1 out of range", then a TPDO #1
// that agrees with the old TPDO #0 leaves X faulted until a fresh TPDO #0 and #1 agree.
TEST_F(ElobauDriverTest, AnAxisFaultIsClearedOnlyByAPairReceivedAfterIt) {
  tpdo0({0x32, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  emcy(0x1000, {0x10, 0x00, 0xFF, 0xFF, 0xFF});
  ASSERT_TRUE(drv->faulted(idx("x")));
  tpdo1({0x32, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_TRUE(drv->faulted(idx("x"))) << "channel 1 from before the EMCY is no evidence";
  EXPECT_EQ(val("x").status, SignalStatus::Error);
  tpdo0({0x32, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF});
  tpdo1({0x32, 0x00, 0x00, 0x00, 0x00, 0xFF, 0xFF, 0xFF});
  EXPECT_FALSE(drv->faulted(idx("x")));
}

// 4001h is UNSIGNED16: an answer of another length is no evidence, the faults stay.
TEST_F(ElobauDriverTest, AReadBackOfTheWrongLengthLeavesTheFaults) {
  emcy(0x1000, {0x63, 0x00, 0xFF, 0xFF, 0xFF});
  ASSERT_TRUE(drv->any_fault());
  std::string error;
  for (const auto& bad : {std::vector<std::uint8_t>{}, std::vector<std::uint8_t>{0x00}}) {
    drv->begin_boot();
    ASSERT_TRUE(drv->on_boot_read(0x4001, 0, bad, error));
    EXPECT_TRUE(drv->any_fault()) << bad.size() << " bytes";
  }
}

}  // namespace
}  // namespace oegw::subdevices
