// Novotechnik406Driver frame by frame. Document: the Novotechnik "CANopen" sensor protocol
// ("Novotechnik CANopen", V02 21.01.25), sections cited as §n.
#include "subdevices/novotechnik_406.hpp"

#include <gtest/gtest.h>

#include <algorithm>

#include <chrono>
#include <vector>

#include "subdevices/families.hpp"

using namespace oegw::subdevices;
using namespace std::chrono_literals;
using oegw::canopen::CanFrame;
using oegw::canopen::EmcyMessage;
using oegw::canopen::NodeId;
using oegw::canopen::SdoAbortCode;
using oegw::canopen::TimePoint;

namespace {

constexpr NodeId kNode{0x7F};  // §3.1: standard models 127 = 0x7F
constexpr std::uint32_t kTpdo1 = 0x180 + 0x7F;

class Novotechnik406Test : public ::testing::Test {
 protected:
  Novotechnik406Test() : driver_(kNode, [this](const CanFrame& f) { sent_.push_back(f); }, {}) {
    driver_.on_change = [this](std::size_t i, const SignalValue& v) { changes_.emplace_back(i, v); };
  }
  TimePoint t(int ms) const { return TimePoint{} + std::chrono::milliseconds(ms); }
  // TPDO1 as configuration() maps it: position, speed, CAM state, work area state. Six bytes
  // (position and speed) are sent with CAM and work area 00h.
  bool pdo(std::initializer_list<std::uint8_t> bytes, int ms = 1) {
    std::vector<std::uint8_t> b(bytes);
    if (b.size() == 6) b.insert(b.end(), {0x00, 0x00});
    return driver_.on_frame(CanFrame(kTpdo1, b), t(ms));
  }
  bool raw_pdo(std::initializer_list<std::uint8_t> bytes, int ms = 1) {
    return driver_.on_frame(CanFrame(kTpdo1, bytes), t(ms));
  }
  DecodedEmcy emcy(std::uint16_t code, std::uint8_t reg, std::uint8_t b3, std::uint8_t b4 = 0, std::uint8_t b7 = 0,
                   int ms = 2) {
    EmcyMessage m{kNode, code, reg, {b3, b4, 0, 0, b7}};
    return driver_.on_emcy(m, t(ms));
  }
  const SignalValue& pos() const { return driver_.value(Novotechnik406Driver::kPosition); }
  const SignalValue& spd() const { return driver_.value(Novotechnik406Driver::kSpeed); }

  std::vector<CanFrame> sent_;
  std::vector<std::pair<std::size_t, SignalValue>> changes_;
  Novotechnik406Driver driver_;
};

TEST_F(Novotechnik406Test, SignalListNamesUnitsAndRanges) {
  const auto& s = driver_.signals();
  ASSERT_EQ(s.size(), 4u);
  EXPECT_EQ(s[0].name, "position");
  EXPECT_EQ(s[0].kind, SignalKind::Position);
  EXPECT_EQ(s[0].unit, "counts");
  EXPECT_EQ(s[0].min, INT32_MIN);
  EXPECT_EQ(s[0].max, INT32_MAX);
  EXPECT_EQ(s[0].neutral, 0);
  EXPECT_EQ(s[1].name, "speed");
  EXPECT_EQ(s[1].kind, SignalKind::Speed);
  EXPECT_EQ(s[1].unit, "0.1 deg/s");  // §3.4 "Resolution speed 0,1°/s"
  EXPECT_EQ(s[1].min, INT16_MIN);
  EXPECT_EQ(s[1].max, INT16_MAX);
  EXPECT_EQ(s[2].name, "cams");
  EXPECT_EQ(s[3].name, "work_area");
  for (std::size_t i = 0; i < s.size(); ++i) EXPECT_EQ(driver_.value(i).status, SignalStatus::Offline);
  EXPECT_EQ(driver_.consumed_cob_ids(), std::vector<std::uint32_t>{kTpdo1});  // §3.1 PDO1 (Tx) 180h + node
}

// §4.1 1A00h: entry 1 = 60200120h (position, 32 bit), entry 2 = 60300110h (speed, 16 bit),
// little endian (CiA 301): position 0x00012345 = 74565, speed 0xFF38 = -200 (-20.0 °/s).
TEST_F(Novotechnik406Test, Tpdo1LayoutPositionThenSpeed) {
  EXPECT_TRUE(pdo({0x45, 0x23, 0x01, 0x00, 0x38, 0xFF}, 5));
  EXPECT_EQ(pos().value, 74565);
  EXPECT_EQ(pos().status, SignalStatus::Valid);
  EXPECT_EQ(pos().timestamp, t(5));
  EXPECT_EQ(spd().value, -200);
  EXPECT_EQ(spd().status, SignalStatus::Valid);
  // The far end of the default range, 650Ah:03 = 002BFFFFh, and a negative position after preset.
  EXPECT_TRUE(pdo({0xFF, 0xFF, 0x2B, 0x00, 0xFF, 0x7F}));
  EXPECT_EQ(pos().value, 0x2BFFFF);
  EXPECT_EQ(spd().value, 32767);
  EXPECT_TRUE(pdo({0xF0, 0xFF, 0xFF, 0xFF, 0x00, 0x80}));
  EXPECT_EQ(pos().value, -16);
  EXPECT_EQ(spd().value, -32768);
}

// Bytes 6 and 7: 6300h:01 CAM state (bits 0..3 = CAM 1..4) and 6400h:01 work area state (§5.7.1:
// bit 0 out of range, bit 1 overflow, bit 2 underflow), as the objects code them; a bit beyond is
// not their coding (Error).
TEST_F(Novotechnik406Test, CamsAndWorkAreaComeInTpdo1) {
  ASSERT_TRUE(raw_pdo({1, 0, 0, 0, 0, 0, 0x05, 0x04}));
  EXPECT_EQ(driver_.value(Novotechnik406Driver::kCams).value, 5);
  EXPECT_EQ(driver_.value(Novotechnik406Driver::kCams).status, SignalStatus::Valid);
  EXPECT_EQ(driver_.value(Novotechnik406Driver::kWorkArea).value, 4);
  EXPECT_EQ(driver_.value(Novotechnik406Driver::kWorkArea).status, SignalStatus::Valid);
  ASSERT_TRUE(raw_pdo({1, 0, 0, 0, 0, 0, 0x10, 0x08}));
  EXPECT_EQ(driver_.value(Novotechnik406Driver::kCams).status, SignalStatus::Error);
  EXPECT_EQ(driver_.value(Novotechnik406Driver::kWorkArea).status, SignalStatus::Error);
  // A marker position: the states derived from it are in doubt too.
  ASSERT_TRUE(raw_pdo({0xFC, 0xFF, 0xFF, 0x7F, 0, 0, 0x01, 0x00}));
  EXPECT_EQ(driver_.value(Novotechnik406Driver::kCams).status, SignalStatus::Error);
  EXPECT_EQ(driver_.value(Novotechnik406Driver::kWorkArea).status, SignalStatus::Error);
}

// §9.1: 5051h/1/0 measurement error "position value 0x7FFFFFFC"; §9 "speed value is set to 0x0000".
TEST_F(Novotechnik406Test, FaultMarker7FFFFFFCIsErrorWithNeutralAndRecovers) {
  ASSERT_TRUE(pdo({0x10, 0x00, 0x00, 0x00, 0x05, 0x00}, 1));
  changes_.clear();
  ASSERT_TRUE(pdo({0xFC, 0xFF, 0xFF, 0x7F, 0x00, 0x00}, 2));
  EXPECT_EQ(pos().status, SignalStatus::Error);
  EXPECT_EQ(pos().value, 0);
  EXPECT_EQ(spd().status, SignalStatus::Error);
  EXPECT_EQ(spd().value, 0);
  EXPECT_EQ(driver_.last_error_position(), 0x7FFFFFFCu);
  EXPECT_EQ(changes_.size(), 4u);  // on_change fired for all four (cams and work area derive from the position)
  ASSERT_TRUE(pdo({0x11, 0x00, 0x00, 0x00, 0x06, 0x00}, 3));
  EXPECT_EQ(pos().status, SignalStatus::Valid);
  EXPECT_EQ(pos().value, 0x11);
  EXPECT_EQ(spd().value, 6);
  EXPECT_FALSE(driver_.last_error_position().has_value());
}

// §9.1 5051h/1/1 and /2/1: "Out of range (+)", position value 0x7FFFFFF8.
TEST_F(Novotechnik406Test, OverflowMarker7FFFFFF8IsError) {
  ASSERT_TRUE(pdo({0xF8, 0xFF, 0xFF, 0x7F, 0x00, 0x00}));
  EXPECT_EQ(pos().status, SignalStatus::Error);
  EXPECT_EQ(pos().value, 0);
  EXPECT_EQ(driver_.last_error_position(), 0x7FFFFFF8u);
}

// §9.1 5051h/1/2 and /2/2: "Out of range (-)", position value 0x80000008.
TEST_F(Novotechnik406Test, UnderflowMarker80000008IsError) {
  ASSERT_TRUE(pdo({0x08, 0x00, 0x00, 0x80, 0x00, 0x00}));
  EXPECT_EQ(pos().status, SignalStatus::Error);
  EXPECT_EQ(spd().status, SignalStatus::Error);
  EXPECT_EQ(driver_.last_error_position(), 0x80000008u);
}

TEST_F(Novotechnik406Test, ReservedMarkerBandIsErrorButNeighboursAreNot) {
  EXPECT_TRUE(Novotechnik406Driver::is_error_position(0x7FFFFFF0));
  EXPECT_TRUE(Novotechnik406Driver::is_error_position(INT32_MAX));
  EXPECT_TRUE(Novotechnik406Driver::is_error_position(INT32_MIN));
  EXPECT_TRUE(Novotechnik406Driver::is_error_position(static_cast<std::int32_t>(0x8000000Fu)));
  EXPECT_FALSE(Novotechnik406Driver::is_error_position(0x7FFFFFEF));
  EXPECT_FALSE(Novotechnik406Driver::is_error_position(static_cast<std::int32_t>(0x80000010u)));
  // §9 prose "0x7FF0" lies inside the measuring range: a valid position, not a marker.
  EXPECT_FALSE(Novotechnik406Driver::is_error_position(0x7FF0));
  ASSERT_TRUE(pdo({0xF0, 0x7F, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(pos().status, SignalStatus::Valid);
  EXPECT_EQ(pos().value, 0x7FF0);
}

TEST_F(Novotechnik406Test, WrongLengthAndForeignCobAreCountedAndIgnored) {
  ASSERT_TRUE(pdo({0x10, 0, 0, 0, 0, 0}));
  EXPECT_TRUE(raw_pdo({0x20, 0, 0, 0, 0}));     // 5 bytes: ours, but wrong length
  EXPECT_TRUE(raw_pdo({0x20, 0, 0, 0, 0, 0}));  // the §4.1 default mapping's 6: not what configuration() maps
  EXPECT_EQ(driver_.counters().wrong_length, 2u);
  EXPECT_EQ(pos().value, 0x10);
  EXPECT_FALSE(driver_.on_frame(CanFrame(0x280 + 0x7F, {0x30, 0, 0, 0, 0, 0}), t(3)));  // TPDO2: not consumed
  EXPECT_EQ(driver_.counters().unknown_cob, 1u);
  EXPECT_EQ(pos().value, 0x10);
}

// §9.1 table, decoded to texts.
TEST_F(Novotechnik406Test, EmcyTableDecodesEveryRow) {
  struct Row {
    std::uint16_t code;
    std::uint8_t reg, b3;
    const char* needle;
    bool error;
  };
  const Row rows[] = {
      {0x1000, 1, 0, "unknown error", true},
      {0x3100, 1, 0, "supply voltage fault", true},
      {0x3100, 1, 1, "supply voltage overrun", false},
      {0x3100, 1, 2, "supply voltage underrun", false},
      {0x4210, 1, 1, "temperature overrun", false},
      {0x4210, 1, 2, "temperature underrun", false},
      {0x5000, 1, 0, "device hardware fault", true},
      {0x5000, 0, 0, "life guarding", false},
      {0x5000, 0, 1, "maintenance required", false},
      {0x5000, 1, 2, "ASIC", true},
      {0x5000, 2, 0, "memory lost", true},
      {0x5051, 1, 0, "measurement error", true},
      {0x5051, 1, 1, "Out of range (+)", true},
      {0x5051, 1, 2, "Out of range (-)", true},
      {0x5051, 2, 1, "overflow warning", true},
      {0x5051, 2, 2, "underflow warning", true},
      {0x6000, 1, 0, "software fault", true},
      {0x6000, 2, 0, "insufficient event timer", false},
      {0x8110, 1, 0, "CAN controller overflow", false},
      {0x8110, 2, 0, "CAN buffer overflow", false},
      {0x8120, 0, 0, "error passive", false},
      {0x8140, 0, 0, "bus-off", false},
  };
  for (const Row& r : rows) {
    const DecodedEmcy d = emcy(r.code, r.reg, r.b3);
    EXPECT_NE(d.text.find(r.needle), std::string::npos) << d.text;
    EXPECT_EQ(d.error, r.error) << d.text;
    EXPECT_EQ(d.code, r.code);
    if (r.error) EXPECT_EQ(d.affected, (std::vector<std::size_t>{0, 1, 2, 3})) << d.text;
    else EXPECT_TRUE(d.affected.empty()) << d.text;
  }
  EXPECT_EQ(driver_.counters().unknown_emcy, 0u);
}

TEST_F(Novotechnik406Test, ErrorEmcyFaultsPositionAndResetEmcyClearsIt) {
  ASSERT_TRUE(pdo({0x34, 0x12, 0, 0, 0x0A, 0}, 1));
  const DecodedEmcy d = emcy(0x5000, 1, 0);  // device hardware fault
  EXPECT_TRUE(d.error);
  EXPECT_EQ(pos().status, SignalStatus::Error);
  EXPECT_EQ(pos().value, 0);
  EXPECT_EQ(spd().status, SignalStatus::Error);
  const DecodedEmcy r = emcy(0x0000, 0, 0, 0, 0, 3);  // "Sensor error resetted, no error"
  EXPECT_FALSE(r.error);
  EXPECT_NE(pos().status, SignalStatus::Error);
  EXPECT_EQ(pos().value, 0);  // nothing vouched for until the next TPDO1
  ASSERT_TRUE(pdo({0x35, 0x12, 0, 0, 0, 0}, 4));
  EXPECT_EQ(pos().status, SignalStatus::Valid);
  EXPECT_EQ(pos().value, 0x1235);
}

// §9.1 5051h/1/1: "If the internal error bit is reset to 0, an EMCY with 0x0000 (valid position)".
TEST_F(Novotechnik406Test, ValidPositionEmcy5051ClearsError) {
  (void)emcy(0x5051, 1, 1);
  ASSERT_EQ(pos().status, SignalStatus::Error);
  const DecodedEmcy d = emcy(0x5051, 0, 0);
  EXPECT_NE(d.text.find("valid position"), std::string::npos);
  EXPECT_NE(pos().status, SignalStatus::Error);
}

TEST_F(Novotechnik406Test, WarningEmcyLeavesPositionValid) {
  ASSERT_TRUE(pdo({0x01, 0, 0, 0, 0, 0}));
  (void)emcy(0x4210, 1, 1);
  EXPECT_EQ(pos().status, SignalStatus::Valid);
  EXPECT_EQ(pos().value, 1);
}

// A stack that ORs bit 0 / other 1001h bits into byte 2: 5051h/3/1 still faults the position.
TEST_F(Novotechnik406Test, EmcyWithOtherRegisterBitsStillDecodedOnSafeSide) {
  const DecodedEmcy d = emcy(0x5051, 0x03, 1);
  EXPECT_TRUE(d.error);
  EXPECT_EQ(pos().status, SignalStatus::Error);
  const DecodedEmcy h = emcy(0x5000, 0x11, 0);  // ambiguous among 5000h/x/0: the fault wins
  EXPECT_TRUE(h.error);
}

TEST_F(Novotechnik406Test, UnknownEmcyCountedAndIgnored) {
  ASSERT_TRUE(pdo({0x01, 0, 0, 0, 0, 0}));
  const DecodedEmcy d = emcy(0xFF00, 1, 0);
  EXPECT_FALSE(d.error);
  EXPECT_EQ(driver_.counters().unknown_emcy, 1u);
  EXPECT_EQ(pos().status, SignalStatus::Valid);
  (void)emcy(0x5051, 1, 7);  // a byte 3 the table does not list
  EXPECT_EQ(driver_.counters().unknown_emcy, 2u);
  EXPECT_EQ(pos().status, SignalStatus::Valid);
}

// §9.1 9080h "Byte 4: bits of changed CAM channel 1-4, Byte 7: status bits" and 9090h "state:
// status bits in Byte 7" (coded "according to 0x6400", or "0: Valid, 1: underflow, 2: overflow":
// the document gives both) are decoded to text only: `cams` and `work_area` come in TPDO1.
TEST_F(Novotechnik406Test, CamAndWorkAreaEmcysAreTextOnly) {
  ASSERT_TRUE(raw_pdo({1, 0, 0, 0, 0, 0, 0x01, 0x00}));
  DecodedEmcy d = emcy(0x9080, 1, 0, /*b4 changed*/ 0x02, /*b7 state*/ 0x03);
  EXPECT_FALSE(d.error);
  EXPECT_NE(d.text.find("changed 0x2, state 0x3"), std::string::npos) << d.text;
  EXPECT_EQ(driver_.value(Novotechnik406Driver::kCams).value, 1) << "the EMCY does not overwrite 6300h";
  d = emcy(0x9090, 1, 0, 0, 0x01);
  EXPECT_FALSE(d.error);
  EXPECT_NE(d.text.find("byte 7 = 01h"), std::string::npos) << d.text;
  EXPECT_EQ(driver_.value(Novotechnik406Driver::kWorkArea).value, 0);
  EXPECT_EQ(driver_.counters().unknown_emcy, 0u);
}

TEST_F(Novotechnik406Test, OfflineMarksEverythingOfflineWithNeutral) {
  ASSERT_TRUE(pdo({0x01, 0x02, 0, 0, 0x03, 0}));
  driver_.on_offline(t(9));
  EXPECT_EQ(pos().status, SignalStatus::Offline);
  EXPECT_EQ(pos().value, 0);
  EXPECT_EQ(spd().value, 0);
}

// §4.1 1000h 00020196h, 1018h:01 0182h.
TEST_F(Novotechnik406Test, ExpectedIdentityVendorOnlyUnlessProductCodeGiven) {
  const ExpectedIdentity id = driver_.expected_identity();
  EXPECT_EQ(id.vendor_id, 0x0182u);
  EXPECT_EQ(id.device_type, 0x00020196u);
  EXPECT_FALSE(id.product_code.has_value());
  std::string error;
  auto d = make_novotechnik_406_driver(kNode, {}, DriverOptions{{{"product_code", "0x0BB9"}}}, error);
  ASSERT_NE(d, nullptr) << error;
  EXPECT_EQ(d->expected_identity().product_code, 0x0BB9u);  // §4.1: series MC1-2800
}

// §4.1 1800h / 1A00h and the §8.2 re-mapping procedure, step by step.
TEST_F(Novotechnik406Test, ConfigurationFollowsTheMappingProcedure) {
  std::string error;
  auto d = make_novotechnik_406_driver(kNode, {}, DriverOptions{{{"event_timer_ms", "50"}}}, error);
  ASSERT_NE(d, nullptr) << error;
  auto w = d->configuration();
  ASSERT_EQ(w.size(), 15u);
  auto is = [](const SdoWrite& s, std::uint16_t idx, std::uint8_t sub, std::vector<std::uint8_t> data) {
    return s.index == idx && s.sub == sub && s.data == data;
  };
  EXPECT_TRUE(is(w[0], 0x1800, 1, {0xFF, 0x01, 0x00, 0xC0}));  // §8.2 step 1: C0000xxxh
  EXPECT_TRUE(is(w[1], 0x1800, 2, {0xFE}));                    // 254: event timer
  EXPECT_TRUE(is(w[2], 0x1800, 3, {0x00, 0x00}));
  EXPECT_TRUE(is(w[3], 0x1800, 5, {0x32, 0x00}));  // 50 ms
  EXPECT_TRUE(is(w[4], 0x1A00, 0, {0x00}));        // step 2
  // Step 3, the document's frames: 23 00 1A 01 20 01 20 60 and 23 00 1A 02 10 01 30 60; then the
  // §8.2 mappable CAM state (6300h/1) and work area (6400h/1), 8 bit each.
  EXPECT_TRUE(is(w[5], 0x1A00, 1, {0x20, 0x01, 0x20, 0x60}));
  EXPECT_TRUE(is(w[6], 0x1A00, 2, {0x10, 0x01, 0x30, 0x60}));
  EXPECT_TRUE(is(w[7], 0x1A00, 3, {0x08, 0x01, 0x00, 0x63}));
  EXPECT_TRUE(is(w[8], 0x1A00, 4, {0x08, 0x01, 0x00, 0x64}));
  EXPECT_TRUE(is(w[9], 0x1A00, 0, {0x04}));                     // step 4
  EXPECT_TRUE(is(w[10], 0x1800, 1, {0xFF, 0x01, 0x00, 0x40}));  // step 5: 40000xxxh
  // §4.3 2104h "EMCY behaviour" 0: all events active, whatever the sensor stored.
  EXPECT_TRUE(is(w[11], 0x2104, 0, {0x00}));
  // §4.1 1029h "Error Behaviour": communication error 0 (pre-operational), measurement error
  // 1 "no change of NMT-mode" (the sensor stays operational and reports the error).
  EXPECT_TRUE(is(w[12], 0x1029, 1, {0x00}));
  EXPECT_TRUE(is(w[13], 0x1029, 2, {0x01}));
  EXPECT_TRUE(is(w[14], 0x1801, 1, {0xFF, 0x02, 0x00, 0xC0}));  // TPDO2 (unused) off: C00002FFh
  // A sensor without 6020h (§4.2 lists none) refuses the entry 60200120h: 6004h "Position value
  // channel 1", §8.2's first mappable object, in its stead (once; then refused: no alternative).
  const auto instead = d->instead_of_refused(w[5], SdoAbortCode::ObjectDoesNotExist);
  ASSERT_TRUE(instead);
  EXPECT_TRUE(is(*instead, 0x1A00, 1, {0x20, 0x00, 0x04, 0x60}));
  EXPECT_FALSE(d->instead_of_refused(*instead, SdoAbortCode::ObjectDoesNotExist));
  EXPECT_FALSE(d->instead_of_refused(w[6], SdoAbortCode::ObjectDoesNotExist))
      << "another refused write refuses the node";
  EXPECT_TRUE(is(d->configuration()[5], 0x1A00, 1, {0x20, 0x00, 0x04, 0x60})) << "kept for the next boots";
}

// Each family's freshness floor (docs/reference/drivers.md#freshness-floors): 3 x the 10 ms event
// timer is raised to 200 ms, overridable (0: none); pdo_timeout_ms is taken as written.
TEST(Novotechnik406Freshness, DerivedDeadlineHasAFloor) {
  std::string error;
  auto d = make_novotechnik_406_driver(kNode, {}, {}, error);
  ASSERT_NE(d, nullptr) << error;
  EXPECT_EQ(d->freshness(Novotechnik406Driver::kPosition), std::chrono::milliseconds(200));
  d = make_novotechnik_406_driver(kNode, {}, DriverOptions{{{"freshness_floor_ms", "0"}}}, error);
  EXPECT_EQ(d->freshness(Novotechnik406Driver::kPosition), std::chrono::milliseconds(30));
  d = make_novotechnik_406_driver(kNode, {}, DriverOptions{{{"event_timer_ms", "100"}}}, error);
  EXPECT_EQ(d->freshness(Novotechnik406Driver::kPosition), std::chrono::milliseconds(300)) << "above the floor";
  d = make_novotechnik_406_driver(kNode, {}, {}, error);
  d->set_pdo_timeout(std::chrono::milliseconds(50));
  EXPECT_EQ(d->freshness(Novotechnik406Driver::kPosition), std::chrono::milliseconds(50))
      << "pdo_timeout_ms as written";
}

// Faults latched by an error EMCY: a good TPDO1 does not end them, the clear code does; going
// offline keeps them; 6503h "Alarms" (§10.2) read back at every (re)start decides them.
TEST_F(Novotechnik406Test, PositionFaultLatchedUntilClearCodeOr6503hReadBack) {
  ASSERT_TRUE(pdo({0x10, 0, 0, 0, 0, 0}));
  // §9.1 5051h/1/1 position overflow error "Reset via Position Error Reset".
  DecodedEmcy d = emcy(0x5051, 1, 1);
  EXPECT_TRUE(d.error);
  EXPECT_TRUE(driver_.faulted(Novotechnik406Driver::kPosition));
  ASSERT_TRUE(pdo({0x10, 0, 0, 0, 0, 0}));
  EXPECT_EQ(pos().status, SignalStatus::Error) << "an ordinary position is no evidence";
  driver_.on_offline(t(3));
  driver_.on_application_reset(t(3));
  driver_.on_online(t(3));
  EXPECT_TRUE(driver_.faulted(Novotechnik406Driver::kPosition));
  driver_.begin_boot();
  const auto reads = driver_.boot_reads();
  ASSERT_EQ(reads.size(), 2u);
  EXPECT_EQ(reads[0], (std::pair<std::uint16_t, std::uint8_t>{0x6503, 0}));
  EXPECT_EQ(reads[1], (std::pair<std::uint16_t, std::uint8_t>{0x6505, 0}));
  std::string error;
  ASSERT_TRUE(driver_.on_boot_read(0x6503, 0, std::vector<std::uint8_t>{0x00, 0x20}, error));  // bit 13
  ASSERT_TRUE(driver_.on_boot_read(0x6505, 0, std::vector<std::uint8_t>{0x00, 0x00}, error));
  EXPECT_TRUE(driver_.boot_reads().empty());
  EXPECT_TRUE(driver_.faulted(Novotechnik406Driver::kPosition));
  // §9.1 5051h/0/0 "Valid position" clears it; the next TPDO1 brings the value.
  d = emcy(0x5051, 0, 0);
  EXPECT_FALSE(d.error);
  EXPECT_FALSE(driver_.any_fault());
  ASSERT_TRUE(pdo({0x10, 0, 0, 0, 0, 0}));
  EXPECT_EQ(pos().status, SignalStatus::Valid);
  // A fault the sensor cleared while unseen: 6503h = 0 at the next start clears it too.
  (void)emcy(0x5000, 1, 0);
  ASSERT_TRUE(driver_.any_fault());
  driver_.begin_boot();
  ASSERT_TRUE(driver_.on_boot_read(0x6503, 0, std::vector<std::uint8_t>{0x00, 0x00}, error));
  EXPECT_FALSE(driver_.any_fault());
  // The position error reset command: 2100h = 1 (§4.1, Bool W 0x01).
  const auto c = driver_.command("position_error_reset");
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].index, 0x2100);
  EXPECT_EQ(c[0].sub, 0);
  EXPECT_EQ(c[0].data, std::vector<std::uint8_t>{0x01});
  EXPECT_TRUE(driver_.command("reboot").empty());
  EXPECT_EQ(driver_.commands(), std::vector<std::string>{"position_error_reset"});
}

// Each read-back clears only what it shows: a supply voltage fault (3100h/1/0) is in 6505h
// bit 4 (§10.3), not in the 6503h alarms; an answer of the wrong length, or a refused read, is
// no evidence either way.
TEST_F(Novotechnik406Test, ReadBackClearsOnlyWhatItShows) {
  ASSERT_TRUE(pdo({0x10, 0, 0, 0, 0, 0}));
  (void)emcy(0x3100, 1, 0);
  ASSERT_TRUE(driver_.faulted(Novotechnik406Driver::kPosition));
  std::string error;
  driver_.begin_boot();
  ASSERT_TRUE(driver_.on_boot_read(0x6503, 0, std::vector<std::uint8_t>{0x00, 0x00}, error));
  EXPECT_TRUE(driver_.faulted(Novotechnik406Driver::kPosition)) << "6503h says nothing of the supply";
  ASSERT_TRUE(driver_.on_boot_read_abort(0x6505, 0, oegw::canopen::SdoAbortCode::ObjectDoesNotExist));
  EXPECT_TRUE(driver_.faulted(Novotechnik406Driver::kPosition)) << "a refused 6505h is no evidence";
  EXPECT_TRUE(driver_.boot_reads().empty());
  driver_.begin_boot();
  ASSERT_TRUE(driver_.on_boot_read(0x6505, 0, std::vector<std::uint8_t>{0x10, 0x00}, error));  // bit 4 still set
  EXPECT_TRUE(driver_.faulted(Novotechnik406Driver::kPosition));
  driver_.begin_boot();
  ASSERT_TRUE(driver_.on_boot_read(0x6505, 0, std::vector<std::uint8_t>{0x00, 0x20}, error));  // a speed warning only
  EXPECT_FALSE(driver_.any_fault()) << "6505h without bit 4: the supply is back";
  // A position alarm, then a read-back of one byte, and of none: the latch stays.
  (void)emcy(0x5051, 1, 1);
  for (const auto& bad : {std::vector<std::uint8_t>{0x00}, std::vector<std::uint8_t>{}}) {
    driver_.begin_boot();
    ASSERT_TRUE(driver_.on_boot_read(0x6503, 0, bad, error));
    EXPECT_TRUE(driver_.faulted(Novotechnik406Driver::kPosition)) << bad.size() << " bytes";
  }
  // 6505h = 0 says nothing of the position alarms.
  ASSERT_TRUE(driver_.on_boot_read(0x6505, 0, std::vector<std::uint8_t>{0x00, 0x00}, error));
  EXPECT_TRUE(driver_.faulted(Novotechnik406Driver::kPosition));
}

// A clear code ends only the faults it is the clear of (§9.1): 5051h/0/0 "valid position" ends a
// position error, not a device fault (5000h/2/0 memory lost, 5000h/1/0 hardware, 6000h software)
// nor the supply voltage fault, whose end is 0000h "sensor error resetted, no error".
TEST_F(Novotechnik406Test, ValidPositionDoesNotEndDeviceOrSupplyFaults) {
  struct Case {
    std::uint16_t code;
    std::uint8_t reg, b3;
  };
  for (const Case c :
       {Case{0x5000, 2, 0}, Case{0x5000, 1, 0}, Case{0x6000, 1, 0}, Case{0x1000, 1, 0}, Case{0x3100, 1, 0}}) {
    SCOPED_TRACE(testing::Message() << std::hex << c.code << "/" << int{c.reg} << "/" << int{c.b3});
    ASSERT_TRUE(pdo({0x10, 0, 0, 0, 0, 0}));
    ASSERT_TRUE(emcy(c.code, c.reg, c.b3).error);
    (void)emcy(0x5051, 1, 0);  // a measurement error besides
    const DecodedEmcy valid = emcy(0x5051, 0, 0);
    EXPECT_FALSE(valid.error);
    EXPECT_NE(valid.text.find("stays until 0000h"), std::string::npos) << valid.text;
    EXPECT_TRUE(driver_.faulted(Novotechnik406Driver::kPosition));
    EXPECT_TRUE(driver_.faulted(Novotechnik406Driver::kSpeed));
    ASSERT_TRUE(pdo({0x10, 0, 0, 0, 0, 0}));
    EXPECT_EQ(pos().status, SignalStatus::Error);
    (void)emcy(0x0000, 0, 0);
    EXPECT_FALSE(driver_.any_fault());
    ASSERT_TRUE(pdo({0x10, 0, 0, 0, 0, 0}));
    EXPECT_EQ(pos().status, SignalStatus::Valid);
  }
  // The measurement error alone ends with "valid position".
  (void)emcy(0x5051, 1, 0);
  ASSERT_TRUE(driver_.any_fault());
  (void)emcy(0x5051, 0, 0);
  EXPECT_FALSE(driver_.any_fault());
}

TEST_F(Novotechnik406Test, FactoryRefusesBadOptions) {
  std::string error;
  EXPECT_EQ(make_novotechnik_406_driver(kNode, {}, DriverOptions{{{"event_timer_ms", "0"}}}, error), nullptr);
  EXPECT_NE(error.find("event_timer_ms"), std::string::npos);
  EXPECT_EQ(make_novotechnik_406_driver(kNode, {}, DriverOptions{{{"event_timer_ms", "70000"}}}, error), nullptr);
  EXPECT_EQ(make_novotechnik_406_driver(kNode, {}, DriverOptions{{{"transmission_type", "253"}}}, error), nullptr);
  EXPECT_EQ(make_novotechnik_406_driver(kNode, {}, DriverOptions{{{"product_code", "0x1234"}}}, error), nullptr);
  EXPECT_EQ(make_novotechnik_406_driver(kNode, {}, DriverOptions{{{"colour", "red"}}}, error), nullptr);
  EXPECT_NE(error.find("unknown option"), std::string::npos);
  auto d = make_novotechnik_406_driver(kNode, {}, DriverOptions{{{"transmission_type", "255"}}}, error);
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->configuration()[1].data, std::vector<std::uint8_t>{0xFF});
}

TEST_F(Novotechnik406Test, NoOutputs) {
  EXPECT_FALSE(driver_.set_output(0, 1, t(1)));
  EXPECT_TRUE(sent_.empty());
}

}  // namespace
