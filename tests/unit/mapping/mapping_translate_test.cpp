// Signal -> functional-element value and FE value -> output signal (mapping/translate.hpp).
// Requirements: translation (elobau S8 percent, MCB-402 INTEGER16 scaled to INTEGER16
// with a documented full-scale convention and ±110 % detent; deadband, invert, clamp; buttons to
// bits; encoder INTEGER32/UNSIGNED32 to 6120h; indicator/display writes to outputs) and fault
// policy (fault value, neutral by default; neutral interlock until the axis is seen inside its
// deadband). Conventions: docs/reference/mapping-file.md#translation-translatehpp.
#include "mapping/translate.hpp"

#include <gtest/gtest.h>

#include <vector>

#include "tests/unit/canopen/state_twin.hpp"

namespace oegw::mapping {
namespace {

using subdevices::SignalInfo;
using subdevices::SignalKind;
using subdevices::SignalStatus;
using subdevices::SignalValue;

const SignalInfo kPercent{"x", SignalKind::Axis, -110, 110, 0, "percent"};  // elobau S8
const SignalInfo kRaw16{"x", SignalKind::Axis, -32768, 32767, 0, "raw16"};  // MCB-402
const SignalInfo kButton{"buttons[1]", SignalKind::Button, 0, 1, 0, "bits"};
const SignalInfo kEncoder{"position", SignalKind::Position, -2147483648LL, 2147483647LL, 0, "counts"};
const SignalInfo kEncoderU32{"position", SignalKind::Position, 0, 0xFFFFFFFFLL, 0, "counts"};
const SignalInfo kWide{"a", SignalKind::Analog, -100000, 100000, 0, "mV"};
const SignalInfo kLed{"leds[1]", SignalKind::Output, 0, 3, 0, "code"};
const SignalInfo kAout{"aout[1]", SignalKind::Output, -1000, 1000, 0, "raw16"};

FeField joystick_x() { return *find_fe_field({FeKind::Joystick, 1}, "x"); }
FeField joystick_button() { return *find_fe_field({FeKind::Joystick, 1}, "buttons[1]"); }
FeField encoder_position() { return *find_fe_field({FeKind::Encoder, 1}, "position"); }
FeField indicator() { return *find_fe_field({FeKind::IndicatorCluster, 1}, "indicator[1]"); }
FeField display_parameter() { return *find_fe_field({FeKind::Display, 1}, "parameter[1]"); }

SignalValue valid(std::int64_t v) { return {v, SignalStatus::Valid, {}}; }
SignalValue with(SignalStatus s, std::int64_t v = 0) { return {v, s, {}}; }

// ---- Scaling -------------------------------------------------------------------------------

TEST(MappingTranslate, ElobauPercentIsFullScaleAt100AndTheDetentIsClamped) {
  const auto p = resolve_input(kPercent, joystick_x(), {});
  EXPECT_DOUBLE_EQ(p.scale, 327.67);
  EXPECT_EQ(translate_input(p, 0), 0);
  EXPECT_EQ(translate_input(p, 100), 32767);
  EXPECT_EQ(translate_input(p, -100), -32767);
  EXPECT_EQ(translate_input(p, 50), 16384);     // 16383.5 rounds away from zero
  EXPECT_EQ(translate_input(p, -1), -328);      // -327.67
  EXPECT_EQ(translate_input(p, 110), 32767);    // detent: 36044 clamped to full scale
  EXPECT_EQ(translate_input(p, -110), -32767);  // symmetric: never -32768
}

TEST(MappingTranslate, RawInteger16PassesUnscaledOverItsWholeRange) {
  const auto p = resolve_input(kRaw16, joystick_x(), {});
  EXPECT_DOUBLE_EQ(p.scale, 1.0);
  for (std::int64_t v : {-32768, -32767, -1, 0, 1, 12345, 32767}) EXPECT_EQ(translate_input(p, v), v) << v;
}

TEST(MappingTranslate, WideSignalIsScaledSoItsLargerEndIsFullScale) {
  const auto p = resolve_input(kWide, joystick_x(), {});
  EXPECT_EQ(translate_input(p, 100000), 32767);
  EXPECT_EQ(translate_input(p, -100000), -32767);
  EXPECT_EQ(translate_input(p, 50000), 16384);
}

// 6120h is UNSIGNED32 (CiA 852 §9.4): an UNSIGNED32 counter passes as it is, a signed INTEGER32
// position keeps its 32-bit pattern (two's complement).
TEST(MappingTranslate, EncoderUnsigned32PassesAndInteger32KeepsItsBitPattern) {
  const auto p = resolve_input(kEncoder, encoder_position(), {});
  EXPECT_EQ(translate_input(p, 2147483647LL), 2147483647LL);
  EXPECT_EQ(translate_input(p, -2147483648LL), 0x80000000LL);
  EXPECT_EQ(translate_input(p, -1), 0xFFFFFFFFLL);
  EXPECT_EQ(translate_input(p, 70000), 70000);  // no INTEGER16 clamp on 6120h
  EXPECT_FALSE(p.interlock);                    // an absolute position has no neutral to wait for
  const auto u = resolve_input(kEncoderU32, encoder_position(), {});
  EXPECT_EQ(translate_input(u, 0xFFFFFFFFLL), 0xFFFFFFFFLL);
  EXPECT_EQ(translate_input(u, 0x80000000LL), 0x80000000LL);
  EXPECT_EQ(translate_input(u, 5), 5);
  EXPECT_EQ(u.clamp_min, 0);
  EXPECT_EQ(u.clamp_max, 0xFFFFFFFFLL);
}

TEST(MappingTranslate, ExplicitScaleOffsetAndClamp) {
  FieldOptions o;
  o.scale = 100.0;
  o.offset = 50;
  o.clamp = std::pair<std::int64_t, std::int64_t>(-5000, 8000);
  const auto p = resolve_input(kPercent, joystick_x(), o);
  EXPECT_EQ(translate_input(p, 10), 1050);
  EXPECT_EQ(translate_input(p, 100), 8000);    // 10050 clamped
  EXPECT_EQ(translate_input(p, -100), -5000);  // -9950 clamped
  EXPECT_EQ(p.neutral, 50);                    // the neutral goes through offset too
  EXPECT_EQ(p.fault, 50);                      // fault value defaults to that neutral
}

TEST(MappingTranslate, ScaleOneOnAPercentSignalUsesTheInteger16Range) {
  FieldOptions o;
  o.scale = 1.0;
  const auto p = resolve_input(kPercent, joystick_x(), o);
  EXPECT_EQ(translate_input(p, 110), 110);
  EXPECT_EQ(p.clamp_min, -32768);
}

// ---- Invert and deadband ------------------------------------------------------------------

TEST(MappingTranslate, InvertMirrorsAboutTheSignalsNeutral) {
  FieldOptions o;
  o.invert = true;
  const auto p = resolve_input(kPercent, joystick_x(), o);
  EXPECT_EQ(translate_input(p, 100), -32767);
  EXPECT_EQ(translate_input(p, -100), 32767);
  EXPECT_EQ(translate_input(p, 0), 0);
  // A pedal whose neutral is not 0: 0..100 with neutral 10 -> mirrored about 10.
  const SignalInfo pedal{"p", SignalKind::Axis, 0, 100, 10, "raw16"};
  const auto q = resolve_input(pedal, joystick_x(), o);
  EXPECT_EQ(translate_input(q, 30), -10);
  EXPECT_EQ(translate_input(q, 10), 10);
  // Raw16 -32768 inverted is +32768: clamped to 32767.
  EXPECT_EQ(translate_input(resolve_input(kRaw16, joystick_x(), o), -32768), 32767);
}

TEST(MappingTranslate, DeadbandInSignalUnitsSnapsToNeutral) {
  FieldOptions o;
  o.deadband = 2;
  const auto p = resolve_input(kPercent, joystick_x(), o);
  EXPECT_EQ(translate_input(p, 2), 0);
  EXPECT_EQ(translate_input(p, -2), 0);
  EXPECT_EQ(translate_input(p, 3), 983);  // 3 % -> 983.01: outside the band, no rescaling
  EXPECT_EQ(translate_input(p, -3), -983);
  EXPECT_TRUE(in_zero_position(p, -2));
  EXPECT_FALSE(in_zero_position(p, 3));
}

// ---- Buttons --------------------------------------------------------------------------------

TEST(MappingTranslate, ButtonsBecomeBitsInvertedOnRequest) {
  const auto p = resolve_input(kButton, joystick_button(), {});
  EXPECT_EQ(p.mode, InputParams::Mode::Bit);
  EXPECT_EQ(translate_input(p, 0), 0);
  EXPECT_EQ(translate_input(p, 1), 1);
  EXPECT_EQ(translate_input(p, 5), 1);  // any non-zero Digital value is "on"
  FieldOptions o;
  o.invert = true;  // a normally-closed contact
  const auto q = resolve_input(kButton, joystick_button(), o);
  EXPECT_EQ(translate_input(q, 0), 1);
  EXPECT_EQ(translate_input(q, 1), 0);
}

TEST(MappingTranslate, ButtonFaultValueIsReleasedAndButtonsAreNotInterlocked) {
  FieldTranslator t(resolve_input(kButton, joystick_button(), {}));
  EXPECT_EQ(t.value(), 0);
  EXPECT_EQ(t.update(valid(1)), 1);  // a held button counts at once: no interlock on bits
  EXPECT_EQ(t.update(with(SignalStatus::Offline, 1)), 0);
  EXPECT_EQ(t.update(valid(1)), 1);
}

TEST(MappingTranslate, BitPackedSignalsAreRecognisedByTheirRange) {
  EXPECT_EQ(bit_width({"in[1]", SignalKind::Digital, 0, 255, 0, "bits"}), 8u);
  EXPECT_EQ(bit_width({"in[1]", SignalKind::Digital, 0, 0xFFFF, 0, "bits"}), 16u);
  EXPECT_EQ(bit_width({"out[1]", SignalKind::Output, 0, 255, 0, "bits"}), 8u);
  EXPECT_EQ(bit_width(kButton), 0u);                                             // 0..1: one value
  EXPECT_EQ(bit_width(kLed), 0u);                                                // LED codes 0..3
  EXPECT_EQ(bit_width({"out[1]", SignalKind::Output, 0, 255, 0, "raw16"}), 0u);  // not "bits"
  EXPECT_EQ(bit_width({"in[1]", SignalKind::Digital, 0, 100, 0, "bits"}), 0u);   // not 2^n - 1
  EXPECT_EQ(bit_width({"a", SignalKind::Analog, 0, 255, 0, "bits"}), 0u);        // not Digital
}

TEST(MappingTranslate, OneBitOfAnInputByteFeedsAButton) {
  const SignalInfo byte{"in[1]", SignalKind::Digital, 0, 255, 0, "bits"};
  const auto p = resolve_input(byte, joystick_button(), {}, 3);
  EXPECT_EQ(translate_input(p, 0x08), 1);
  EXPECT_EQ(translate_input(p, 0xF7), 0);  // every other line on: still off
  FieldOptions o;
  o.invert = true;
  EXPECT_EQ(translate_input(resolve_input(byte, joystick_button(), o, 3), 0xF7), 1);
  // With the interlock on, a held line is counted only after its own bit was seen released.
  o = {};
  o.interlock = true;
  FieldTranslator t(resolve_input(byte, joystick_button(), o, 3));
  EXPECT_EQ(t.update(valid(0x08)), 0);
  EXPECT_EQ(t.update(valid(0x01)), 0);  // bit 3 released (other lines do not matter)
  EXPECT_FALSE(t.interlocked());
  EXPECT_EQ(t.update(valid(0x09)), 1);
}

// ---- Fault value and neutral interlock --------------------------------------------------------

TEST(MappingTranslate, StartsAtTheFaultValueAndInterlockedUntilSeenAtZero) {
  FieldOptions o;
  o.deadband = 2;
  FieldTranslator t(resolve_input(kPercent, joystick_x(), o));
  EXPECT_TRUE(t.interlocked());
  EXPECT_EQ(t.value(), 0);
  EXPECT_EQ(t.update(valid(50)), 0);  // booted deflected: held at neutral
  EXPECT_TRUE(t.interlocked());
  EXPECT_EQ(t.update(valid(3)), 0);  // just outside the deadband: still held
  EXPECT_EQ(t.update(valid(2)), 0);  // inside: released (and inside the deadband anyway)
  EXPECT_FALSE(t.interlocked());
  EXPECT_EQ(t.update(valid(50)), 16384);  // follows
}

TEST(MappingTranslate, EveryNonValidStatusGivesTheFaultValueAndReArmsTheInterlock) {
  for (auto s : {SignalStatus::Error, SignalStatus::NotAvailable, SignalStatus::Stale, SignalStatus::Offline}) {
    FieldOptions o;
    o.deadband = 1;
    o.fault = -1000;
    FieldTranslator t(resolve_input(kPercent, joystick_x(), o));
    t.update(valid(0));
    EXPECT_EQ(t.update(valid(100)), 32767);
    EXPECT_EQ(t.update(with(s, 100)), -1000) << to_string(s);  // the value carried is ignored
    EXPECT_TRUE(t.interlocked());
    EXPECT_EQ(t.update(valid(100)), 0) << to_string(s);  // back, still deflected: neutral, not fault
    EXPECT_EQ(t.update(valid(-60)), 0);
    EXPECT_EQ(t.update(valid(1)), 0);         // seen at zero
    EXPECT_EQ(t.update(valid(-60)), -19660);  // -19660.2
  }
}

// Run-time state (canopen/state.hpp): a copy given the state follows where the original does
// (released) and holds where it holds; a fresh translator is still locked.
TEST(MappingTranslate, ACopyGivenTheStateKeepsTheValueAndTheInterlock) {
  FieldOptions o;
  o.deadband = 2;
  const InputParams p = resolve_input(kPercent, joystick_x(), o);
  FieldTranslator a(p);
  a.update(valid(1));   // released
  a.update(valid(50));  // follows
  FieldTranslator b(p);
  canopen::test_support::copy_state(a, b);
  EXPECT_EQ(b.value(), 16384);
  EXPECT_FALSE(b.interlocked());
  FieldTranslator fresh(p);
  EXPECT_EQ(b.update(valid(-50)), a.update(valid(-50)));
  EXPECT_EQ(fresh.update(valid(-50)), 0);  // still locked
  // Locked again by a fault, and deflected since: the copy holds neutral too.
  a.update(with(SignalStatus::Stale));
  a.update(valid(40));
  FieldTranslator c(p);
  canopen::test_support::copy_state(a, c);
  EXPECT_TRUE(c.interlocked());
  EXPECT_EQ(c.update(valid(30)), 0);
}

TEST(MappingTranslate, AStateTheTranslationCannotGiveIsRefused) {
  FieldOptions o;
  o.fault = -1000;
  o.interlock = false;
  const FieldTranslator a(resolve_input(kPercent, joystick_x(), o));
  const std::string text = canopen::test_support::state_text(a);
  using canopen::test_support::refusal;
  using canopen::test_support::with_value;
  FieldTranslator b(a.params());
  EXPECT_EQ(refusal(b, with_value(text, "locked", "1")),
            "state: 'locked' is set on a field without the neutral interlock");
  EXPECT_EQ(refusal(b, with_value(text, "value", "40000")),
            "state: 'value' is no value this field's translation gives");
  EXPECT_EQ(refusal(b, with_value(text, "value", "-32767")), "accepted");  // the clamp's end
  FieldTranslator button(resolve_input(kButton, joystick_button(), {}));
  EXPECT_EQ(refusal(button, with_value(text, "value", "2")),
            "state: 'value' is no value this field's translation gives");
}

TEST(MappingTranslate, InterlockWithoutDeadbandNeedsExactNeutral) {
  FieldTranslator t(resolve_input(kRaw16, joystick_x(), {}));
  t.update(with(SignalStatus::Offline));
  EXPECT_EQ(t.update(valid(1)), 0);
  EXPECT_EQ(t.update(valid(-1)), 0);
  EXPECT_EQ(t.update(valid(0)), 0);
  EXPECT_EQ(t.update(valid(-1)), -1);
}

TEST(MappingTranslate, InterlockCanBeSwitchedOff) {
  FieldOptions o;
  o.interlock = false;
  FieldTranslator t(resolve_input(kRaw16, joystick_x(), o));
  EXPECT_FALSE(t.interlocked());
  EXPECT_EQ(t.update(valid(1000)), 1000);
  EXPECT_EQ(t.update(with(SignalStatus::Error)), 0);
  EXPECT_EQ(t.update(valid(1000)), 1000);
}

TEST(MappingTranslate, InterlockReleaseUsesTheRawValueBeforeInvertAndOffset) {
  FieldOptions o;
  o.deadband = 5;
  o.invert = true;
  o.offset = 100;
  FieldTranslator t(resolve_input(kRaw16, joystick_x(), o));
  EXPECT_EQ(t.value(), 100);            // neutral = 0 inverted + offset
  EXPECT_EQ(t.update(valid(-4)), 100);  // inside the band around the signal's neutral: released
  EXPECT_FALSE(t.interlocked());
  EXPECT_EQ(t.update(valid(-40)), 140);
}

// ---- Outputs ------------------------------------------------------------------------------------

TEST(MappingTranslate, IndicatorBitsDriveOutputsWithScaleInvertAndTheOutputsRange) {
  const auto p = resolve_output(kLed, indicator(), {});
  EXPECT_EQ(translate_output(p, 0), 0);
  EXPECT_EQ(translate_output(p, 1), 1);
  FieldOptions o;
  o.scale = 2;  // elobau LED code 2 for "on"
  EXPECT_EQ(translate_output(resolve_output(kLed, indicator(), o), 1), 2);
  o.scale = 5;  // beyond the LED's range: clamped to its max (3)
  EXPECT_EQ(translate_output(resolve_output(kLed, indicator(), o), 1), 3);
  FieldOptions inv;
  inv.invert = true;
  const auto q = resolve_output(kLed, indicator(), inv);
  EXPECT_EQ(translate_output(q, 0), 1);
  EXPECT_EQ(translate_output(q, 1), 0);
}

TEST(MappingTranslate, DisplayParametersDriveAnalogueOutputsClampedToTheirRange) {
  const auto p = resolve_output(kAout, display_parameter(), {});
  EXPECT_EQ(translate_output(p, 500), 500);
  EXPECT_EQ(translate_output(p, 30000), 1000);
  EXPECT_EQ(translate_output(p, -30000), -1000);
  FieldOptions o;
  o.scale = 0.5;
  o.offset = 10;
  o.invert = true;
  const auto q = resolve_output(kAout, display_parameter(), o);
  EXPECT_EQ(translate_output(q, 100), -40);  // -100 * 0.5 + 10
}

TEST(MappingTranslate, IndicatorBitsComposeABitPackedOutputByte) {
  const SignalInfo byte{"out[1]", SignalKind::Output, 0, 255, 0, "bits"};
  const auto b0 = resolve_output(byte, indicator(), {}, 0);
  const auto b5 = resolve_output(byte, indicator(), {}, 5);
  std::int64_t out = 0;
  out = apply_output(b5, 1, out);
  EXPECT_EQ(out, 0x20);
  out = apply_output(b0, 1, out);
  EXPECT_EQ(out, 0x21);
  out = apply_output(b5, 0, out);  // clears its own bit only
  EXPECT_EQ(out, 0x01);
  FieldOptions inv;
  inv.invert = true;
  EXPECT_EQ(apply_output(resolve_output(byte, indicator(), inv, 7), 1, 0xFF), 0x7F);
  // A whole-value output ignores `current`.
  EXPECT_EQ(apply_output(resolve_output(kLed, indicator(), {}), 1, 3), 1);
}

}  // namespace
}  // namespace oegw::mapping
