// Mcb402Driver frame by frame. Vectors: reference/003_44a28fc862638d35.txt, "MCB-402 CANOPEN
// Controller for joystick" v1.0 — [MCB §4] "Using in a non CANOPEN network" (frames 183/283/603),
// [CO4013 ...] the CO4013A chapter 5 sections named in each test.
#include <gtest/gtest.h>

#include <vector>

#include "canopen/301/emcy.hpp"
#include "canopen/301/sdo_client.hpp"
#include "subdevices/families.hpp"
#include "subdevices/mcb402.hpp"

using namespace oegw::subdevices;
using oegw::canopen::CanFrame;
using oegw::canopen::EmcyConsumer;
using oegw::canopen::ObjectDictionary;
using oegw::canopen::SdoAbortCode;
using oegw::canopen::SdoClient;
using oegw::canopen::TimePoint;
using namespace std::chrono_literals;

namespace {

constexpr NodeId kNode{0x03};  // [MCB §4] "the MCB402 is configured at address 0x03"
constexpr std::size_t kX = 0, kY = 1, kZ = 2, kT = 3;
constexpr std::size_t button(std::size_t n) { return mcb402::kFirstButton + n - 1; }
constexpr std::size_t led(std::size_t n) { return mcb402::kFirstLed + n - 1; }

class Mcb402Test : public ::testing::Test {
 protected:
  Mcb402Test() { make({}); }

  // `options` plus the required button_bits (the document's table as printed) unless given.
  void make(DriverOptions options) {
    if (!options.get("button_bits")) options.values.emplace_back("button_bits", "1,2,3,4,5,7,6");
    std::string error;
    driver_ = make_mcb402_driver(
        kNode, [this](const CanFrame& f) { sent_.push_back(f); }, options, error);
    ASSERT_NE(driver_, nullptr) << error;
    driver_->on_change = [this](std::size_t i, const SignalValue&) { changes_.push_back(i); };
    emcy_ = std::make_unique<EmcyConsumer>(od_, [this](const oegw::canopen::EmcyMessage& m, TimePoint now) {
      decoded_.push_back(driver_->on_emcy(m, now));
    });
  }
  TimePoint at(int ms) const { return TimePoint{} + std::chrono::milliseconds(ms); }
  bool frame(const CanFrame& f, int ms = 0) { return driver_->on_frame(f, at(ms)); }
  // EMCY frames go through the real consumer, as the Master hands them over.
  void emcy(const CanFrame& f, int ms = 0) { ASSERT_TRUE(emcy_->on_frame(f, at(ms))); }
  const SignalValue& v(std::size_t i) const { return driver_->value(i); }
  Mcb402Driver& mcb() { return dynamic_cast<Mcb402Driver&>(*driver_); }

  std::unique_ptr<Driver> driver_;
  std::vector<CanFrame> sent_;
  std::vector<std::size_t> changes_;
  ObjectDictionary od_;
  std::unique_ptr<EmcyConsumer> emcy_;
  std::vector<DecodedEmcy> decoded_;
};

TEST_F(Mcb402Test, SignalListNamesKindsAndRanges) {
  const auto& s = driver_->signals();
  ASSERT_EQ(s.size(), 15u);
  const char* names[] = {"x",          "y",          "z",          "t",          "buttons[1]",
                         "buttons[2]", "buttons[3]", "buttons[4]", "buttons[5]", "buttons[6]",
                         "buttons[7]", "leds[1]",    "leds[2]",    "leds[3]",    "leds[4]"};
  for (std::size_t i = 0; i < s.size(); ++i) EXPECT_EQ(s[i].name, names[i]);
  // [MCB §4]: 0 V = 0x8000, 2.5 V = 0x0000, 5 V = 0x7FFF.
  for (std::size_t a = 0; a < 4; ++a) {
    EXPECT_EQ(s[a].kind, SignalKind::Axis);
    EXPECT_EQ(s[a].min, -32768);
    EXPECT_EQ(s[a].max, 32767);
    EXPECT_EQ(s[a].neutral, 0);
    EXPECT_EQ(s[a].unit, "raw16");
  }
  for (std::size_t b = 1; b <= 7; ++b) EXPECT_EQ(s[button(b)].kind, SignalKind::Button);
  for (std::size_t l = 1; l <= 4; ++l) EXPECT_TRUE(s[led(l)].output());
  EXPECT_EQ(driver_->find_signal("buttons[7]"), button(7));
  EXPECT_EQ(driver_->family(), "mcb402");
  for (std::size_t i = 0; i < s.size(); ++i) EXPECT_EQ(v(i).status, SignalStatus::Offline);
}

TEST_F(Mcb402Test, ConsumesTpdo1AndTpdo2OfItsNode) {
  // [MCB §4] "0x183 = 0x180 + address", "283 aa bb ...".
  EXPECT_EQ(driver_->consumed_cob_ids(), (std::vector<std::uint32_t>{0x183, 0x283}));
}

TEST_F(Mcb402Test, ExpectedIdentityFromTheDictionaryChapter) {
  // [CO4013 Index 1000] CO4013A4 = 0107 0191h; [CO4013 Index 1018] vendor 58h, product 0104 0131h.
  const auto id = driver_->expected_identity();
  EXPECT_EQ(id.device_type, 0x01070191u);
  EXPECT_EQ(id.vendor_id, 0x58u);
  EXPECT_EQ(id.product_code, 0x01040131u);
  EXPECT_FALSE(id.revision.has_value()) << "the document gives no revision value";
  EXPECT_FALSE(id.serial.has_value()) << "1018h has sub-indices 1..3 only";
}

TEST_F(Mcb402Test, ConfigurationWritesTheEventTimerAsTheDocumentsExample) {
  make({{{"event_timer_ms", "500"}}});
  const auto writes = driver_->configuration();
  // Sent through a real SDO client, as the Master does at boot.
  std::vector<CanFrame> out;
  SdoClient client([&out](const CanFrame& f) { out.push_back(f); }, kNode);
  int done = 0;
  for (const auto& w : writes) {
    client.download(w.index, w.sub, w.data, [&done](SdoAbortCode c, std::vector<std::uint8_t>) {
      EXPECT_EQ(c, SdoAbortCode::None);
      ++done;
    });
  }
  for (std::size_t i = 0; i < writes.size(); ++i) {
    client.advance(at(static_cast<int>(i)));
    ASSERT_EQ(out.size(), i + 1);
    const CanFrame& req = out.back();
    ASSERT_TRUE(client.on_frame(CanFrame(0x583, {0x60, req.data[1], req.data[2], req.data[3], 0, 0, 0, 0}),
                                at(static_cast<int>(i))));
  }
  EXPECT_EQ(done, static_cast<int>(writes.size()));
  // [MCB §4] "Write : 603 22 01 18 05 aa bb 00 00   0xbbaa = duration in ms": 500 ms = 0x01F4.
  // The client indicates the size (2Bh: expedited, 2 bytes) where the example leaves it open (22h);
  // the index, sub-index and data bytes are the example's.
  bool found = false;
  for (const CanFrame& f : out) {
    if (f.data[1] == 0x01 && f.data[2] == 0x18 && f.data[3] == 0x05) {
      found = true;
      EXPECT_EQ(f.id, 0x603u);
      EXPECT_EQ(f.dlc, 8);
      EXPECT_EQ(f.data[0], 0x2B);
      const std::vector<std::uint8_t> doc{0x22, 0x01, 0x18, 0x05, 0xF4, 0x01, 0x00, 0x00};
      EXPECT_EQ(std::vector<std::uint8_t>(f.data.begin() + 1, f.data.end()),
                std::vector<std::uint8_t>(doc.begin() + 1, doc.end()))
          << f.to_string();
    }
  }
  EXPECT_TRUE(found);
  // The transmission type is written first (the event timer only acts in types 254/255,
  // [CO4013 "Description of transmission type"]), then the timer.
  auto pos = [&writes](std::uint16_t index, std::uint8_t sub) {
    for (std::size_t i = 0; i < writes.size(); ++i)
      if (writes[i].index == index && writes[i].sub == sub) return static_cast<int>(i);
    return -1;
  };
  ASSERT_GE(pos(0x1801, 2), 0);
  EXPECT_LT(pos(0x1801, 2), pos(0x1801, 5));
  EXPECT_EQ(writes[static_cast<std::size_t>(pos(0x1801, 2))].data, (std::vector<std::uint8_t>{0xFF}));
  EXPECT_EQ(writes[static_cast<std::size_t>(pos(0x1800, 5))].data, (std::vector<std::uint8_t>{100, 0}));
  // Polarity pinned: 6000h is "inverted level because active low" — 1 = pressed only while 6002h:03 = 0.
  ASSERT_GE(pos(0x6002, 3), 0);
  EXPECT_EQ(writes[static_cast<std::size_t>(pos(0x6002, 3))].data, (std::vector<std::uint8_t>{0x00}));
  ASSERT_GE(pos(0x6202, 1), 0);
  for (std::uint8_t a = 1; a <= 4; ++a) {
    ASSERT_GE(pos(0x6431, a), 0) << "6431h offset would make 6401h unsigned";
    EXPECT_EQ(writes[static_cast<std::size_t>(pos(0x6431, a))].data.size(), 4u) << "INTEGER32";
  }
}

TEST_F(Mcb402Test, DefaultEventTimerIsTwentyMilliseconds) {
  int seen = 0;
  for (const auto& w : driver_->configuration()) {
    if (w.index == 0x1801 && w.sub == 5) {
      EXPECT_EQ(w.data, (std::vector<std::uint8_t>{20, 0}));
      ++seen;
    }
  }
  EXPECT_EQ(seen, 1);
}

TEST_F(Mcb402Test, Tpdo2AxesAreSignedLittleEndianWords) {
  // [MCB §4] "283 aa bb cc dd ee ff gg hh Axis X Y Z T (signed 16 bits) ... neutral 0x0000, 5V
  // 0x7FFF, 0V 0x8000. The word for X axis is 0xbbaa."
  EXPECT_TRUE(frame(CanFrame(0x283, {0xFF, 0x7F, 0x00, 0x80, 0x00, 0x00, 0x34, 0x12}), 5));
  EXPECT_EQ(v(kX).value, 32767);
  EXPECT_EQ(v(kY).value, -32768);
  EXPECT_EQ(v(kZ).value, 0);
  EXPECT_EQ(v(kT).value, 0x1234);
  for (std::size_t a = 0; a < 4; ++a) {
    EXPECT_EQ(v(a).status, SignalStatus::Valid);
    EXPECT_EQ(v(a).timestamp, at(5));
  }
  EXPECT_EQ(changes_, (std::vector<std::size_t>{kX, kY, kZ, kT}));
  changes_.clear();
  EXPECT_TRUE(frame(CanFrame(0x283, {0xFF, 0x7F, 0x00, 0x80, 0x01, 0x00, 0x34, 0x12}), 6));
  EXPECT_EQ(changes_, (std::vector<std::size_t>{kZ})) << "on_change only for what changed";
  EXPECT_EQ(v(kZ).value, 1);
}

TEST_F(Mcb402Test, Tpdo1ButtonBitsAsTheDocumentsTable) {
  // [MCB §4] "183 00 00 cc 0 — when pressed, the corresponding bit is set to 1";
  // "Bit of cc 7 6 5 4 3 2 1 0 / N° BP 6 7 5 4 3 2 1".
  const std::uint8_t bit_of[8] = {0, 1, 2, 3, 4, 5, 7, 6};  // index = BP number
  for (std::size_t bp = 1; bp <= 7; ++bp) {
    const auto cc = static_cast<std::uint8_t>(1u << bit_of[bp]);
    ASSERT_TRUE(frame(CanFrame(0x183, {0x00, 0x00, cc, 0x00})));
    for (std::size_t b = 1; b <= 7; ++b) {
      EXPECT_EQ(v(button(b)).value, b == bp ? 1 : 0) << "cc=" << int(cc) << " BP" << b;
      EXPECT_EQ(v(button(b)).status, SignalStatus::Valid);
    }
  }
  // Bit 0 is no button; bytes 0, 1, 3 (memory, direction, IN11..IN8) carry none.
  ASSERT_TRUE(frame(CanFrame(0x183, {0xFF, 0xFF, 0x01, 0xFF})));
  for (std::size_t b = 1; b <= 7; ++b) EXPECT_EQ(v(button(b)).value, 0);
  ASSERT_TRUE(frame(CanFrame(0x183, {0x00, 0x00, 0xFE, 0x00})));
  for (std::size_t b = 1; b <= 7; ++b) EXPECT_EQ(v(button(b)).value, 1);
}

TEST_F(Mcb402Test, ActiveHighOnTheWireIsNotInvertedAgain) {
  // [CO4013 Index 6000 sub 3] "inverted level because active low": the controller inverts the
  // pins, so 00h = nothing pressed (the document's power-on example "183 00 00 cc 0").
  ASSERT_TRUE(frame(CanFrame(0x183, {0x00, 0x00, 0x00, 0x00})));
  for (std::size_t b = 1; b <= 7; ++b) {
    EXPECT_EQ(v(button(b)).value, 0);
    EXPECT_EQ(v(button(b)).status, SignalStatus::Valid);
  }
}

TEST_F(Mcb402Test, ButtonBitsOptionOverridesTheTable) {
  make({{{"button_bits", "0,1,2,3,4,5,6"}}});
  ASSERT_TRUE(frame(CanFrame(0x183, {0x00, 0x00, 0x41, 0x00})));
  EXPECT_EQ(v(button(1)).value, 1);
  EXPECT_EQ(v(button(7)).value, 1);
  EXPECT_EQ(v(button(6)).value, 0);
}

TEST_F(Mcb402Test, WrongLengthAndForeignFramesAreCountedAndIgnored) {
  ASSERT_TRUE(frame(CanFrame(0x283, {0x10, 0x00, 0x20, 0x00, 0x30, 0x00, 0x40, 0x00})));
  ASSERT_TRUE(frame(CanFrame(0x183, {0x00, 0x00, 0x02, 0x00})));
  changes_.clear();
  EXPECT_TRUE(frame(CanFrame(0x283, {0xFF, 0x7F, 0xFF, 0x7F, 0xFF, 0x7F})));  // 6 bytes
  EXPECT_TRUE(frame(CanFrame(0x183, {0x00, 0x00, 0xFE})));                    // 3 bytes
  EXPECT_TRUE(frame(CanFrame(0x183, {0x00, 0x00, 0xFE, 0x00, 0x00})));        // 5 bytes
  EXPECT_EQ(driver_->counters().wrong_length, 3u);
  EXPECT_FALSE(frame(CanFrame(0x184, {0x00, 0x00, 0xFE, 0x00})));  // another node
  EXPECT_FALSE(frame(CanFrame(0x203, {0x01})));                    // our own RPDO
  EXPECT_FALSE(frame(CanFrame::remote(0x283, 8)));
  EXPECT_EQ(driver_->counters().unknown_cob, 3u);
  EXPECT_TRUE(changes_.empty());
  EXPECT_EQ(v(kX).value, 0x10);
  EXPECT_EQ(v(button(1)).value, 1);
  EXPECT_EQ(v(button(2)).value, 0);
}

TEST_F(Mcb402Test, CableBreakEmcyPutsThatAxisInErrorUntilReset) {
  ASSERT_TRUE(frame(CanFrame(0x283, {0x00, 0x10, 0x00, 0x20, 0x00, 0x30, 0x00, 0x40}), 1));
  // [CO4013 "Emergency Messages"] cable break detection "20 31 81 00 8x 00 00 00", bit1 = y-axis.
  emcy(CanFrame(0x83, {0x20, 0x31, 0x81, 0x00, 0x82, 0x00, 0x00, 0x00}), 2);
  ASSERT_EQ(decoded_.size(), 1u);
  EXPECT_EQ(decoded_[0].code, 0x3120);
  EXPECT_TRUE(decoded_[0].error);
  EXPECT_EQ(decoded_[0].affected, (std::vector<std::size_t>{kY}));
  EXPECT_EQ(v(kY).status, SignalStatus::Error);
  EXPECT_EQ(v(kY).value, 0) << "neutral";
  EXPECT_EQ(v(kX).status, SignalStatus::Valid);
  EXPECT_EQ(mcb().broken_axes(), 0x02);
  // The broken axis keeps sending something: never passed through.
  ASSERT_TRUE(frame(CanFrame(0x283, {0x00, 0x11, 0x00, 0x80, 0x00, 0x31, 0x00, 0x41}), 3));
  EXPECT_EQ(v(kY).status, SignalStatus::Error);
  EXPECT_EQ(v(kY).value, 0);
  EXPECT_EQ(v(kX).value, 0x1100);
  EXPECT_EQ(v(kX).status, SignalStatus::Valid);
  // Error reset (CiA 301 0000h): the latch is released, the next TPDO2 value is good.
  emcy(CanFrame(0x83, {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}), 4);
  EXPECT_FALSE(decoded_.back().error);
  EXPECT_EQ(mcb().broken_axes(), 0);
  EXPECT_EQ(v(kY).status, SignalStatus::Error) << "no fresh value yet";
  ASSERT_TRUE(frame(CanFrame(0x283, {0x00, 0x11, 0x00, 0x21, 0x00, 0x31, 0x00, 0x41}), 5));
  EXPECT_EQ(v(kY).status, SignalStatus::Valid);
  EXPECT_EQ(v(kY).value, 0x2100);
}

TEST_F(Mcb402Test, CableBreakBitsAreORedAndASmallerSetReleasesAxes) {
  ASSERT_TRUE(frame(CanFrame(0x283, {1, 0, 2, 0, 3, 0, 4, 0})));
  // [CO4013 "Emergency Messages"] bit0 x, bit1 y, bit2 z, bit3 w; "combined with a logical or".
  emcy(CanFrame(0x83, {0x20, 0x31, 0x81, 0x00, 0x89, 0x00, 0x00, 0x00}));
  EXPECT_EQ(decoded_.back().affected, (std::vector<std::size_t>{kX, kT}));
  EXPECT_EQ(v(kX).status, SignalStatus::Error);
  EXPECT_EQ(v(kT).status, SignalStatus::Error);
  EXPECT_EQ(v(kY).status, SignalStatus::Valid);
  emcy(CanFrame(0x83, {0x20, 0x31, 0x81, 0x00, 0x88, 0x00, 0x00, 0x00}));  // X repaired, T still broken
  EXPECT_EQ(mcb().broken_axes(), 0x08);
  ASSERT_TRUE(frame(CanFrame(0x283, {5, 0, 6, 0, 7, 0, 8, 0})));
  EXPECT_EQ(v(kX).status, SignalStatus::Valid);
  EXPECT_EQ(v(kX).value, 5);
  EXPECT_EQ(v(kT).status, SignalStatus::Error);
  EXPECT_EQ(v(kT).value, 0);
}

TEST_F(Mcb402Test, UndecodableCableBreakByteFailsAllAxes) {
  ASSERT_TRUE(frame(CanFrame(0x283, {1, 0, 2, 0, 3, 0, 4, 0})));
  emcy(CanFrame(0x83, {0x20, 0x31, 0x81, 0x00, 0x00, 0x00, 0x00, 0x00}));  // no axis bit, no 8xh
  EXPECT_EQ(driver_->counters().unknown_emcy, 1u);
  for (std::size_t a = 0; a < 4; ++a) {
    EXPECT_EQ(v(a).status, SignalStatus::Error);
    EXPECT_EQ(v(a).value, 0);
  }
  emcy(CanFrame(0x83, {0x20, 0x31, 0x81, 0x00, 0x42, 0x00, 0x00, 0x00}));  // high nibble not 8
  EXPECT_EQ(driver_->counters().unknown_emcy, 2u);
  EXPECT_EQ(mcb().broken_axes(), 0x0F);
}

// [CO4013 "Emergency Messages"] Life-Guarding Error "30 81 11 ...", CAN Bus in Error Warning state
// "00 81 11 ..." (also sent at every power-on, [MCB §4] "083 00 81 11 0"), Return from CAN Bus OFF
// "40 81 11 ...": CAN communication warnings, reported, faulting nothing.
TEST_F(Mcb402Test, CommunicationWarningEmcysFaultNothing) {
  ASSERT_TRUE(frame(CanFrame(0x283, {1, 0, 2, 0, 3, 0, 4, 0})));
  ASSERT_TRUE(frame(CanFrame(0x183, {0, 0, 0x02, 0})));
  for (const std::uint8_t lo : {0x30, 0x00, 0x40}) {
    emcy(CanFrame(0x83, {lo, 0x81, 0x11, 0x00, 0x00, 0x00, 0x00, 0x00}));
    EXPECT_FALSE(decoded_.back().error) << int(lo);
    EXPECT_TRUE(decoded_.back().affected.empty()) << int(lo);
    EXPECT_NE(decoded_.back().text.find("warning"), std::string::npos) << decoded_.back().text;
  }
  EXPECT_EQ(driver_->counters().unknown_emcy, 0u);
  EXPECT_FALSE(driver_->any_fault());
  EXPECT_EQ(v(kX).status, SignalStatus::Valid);
  EXPECT_EQ(v(kX).value, 1);
  EXPECT_EQ(v(button(1)).status, SignalStatus::Valid);
  EXPECT_EQ(v(button(1)).value, 1);
}

// CiA 301 Table 26 81xxh "communication": the codes the document does not list (8110h overrun,
// 8120h error passive) are warnings like its own three, as the elobau and CiA 401 drivers take
// them; neither counted as unknown nor faulting.
TEST_F(Mcb402Test, Every81xxhIsACommunicationWarning) {
  ASSERT_TRUE(frame(CanFrame(0x283, {1, 0, 2, 0, 3, 0, 4, 0})));
  for (const std::uint8_t lo : {0x10, 0x20, 0x50, 0xFF}) {
    emcy(CanFrame(0x83, {lo, 0x81, 0x11, 0x00, 0x00, 0x00, 0x00, 0x00}));
    EXPECT_FALSE(decoded_.back().error) << int(lo);
    EXPECT_TRUE(decoded_.back().affected.empty()) << int(lo);
  }
  EXPECT_EQ(driver_->counters().unknown_emcy, 0u);
  EXPECT_FALSE(driver_->any_fault());
  EXPECT_EQ(v(kX).status, SignalStatus::Valid);
}

// The document shows no error reset after a cable break ([CO4013 "Emergency Messages"]): while
// one is latched, the driver has 1001h read (fault_poll, every 250 ms); bit 7 "device error"
// clear ends it. An answer to a request sent before a newer break is no evidence of its end.
TEST_F(Mcb402Test, CableBreakEndsOnA1001hReadWithoutTheDeviceError) {
  EXPECT_FALSE(driver_->fault_poll()) << "nothing to poll without a fault";
  ASSERT_TRUE(frame(CanFrame(0x283, {1, 0, 2, 0, 3, 0, 4, 0})));
  emcy(CanFrame(0x83, {0x20, 0x31, 0x81, 0x00, 0x81, 0x00, 0x00, 0x00}), 1);
  const auto poll = driver_->fault_poll();
  ASSERT_TRUE(poll);
  EXPECT_EQ(poll->index, 0x1001);
  EXPECT_EQ(poll->sub, 0);
  EXPECT_EQ(poll->period, 250ms);
  driver_->on_fault_poll_sent();
  EXPECT_EQ(driver_->on_fault_poll(std::vector<std::uint8_t>{0x81}, at(2)), "") << "still broken";
  EXPECT_TRUE(driver_->faulted(kX));
  // A request out, then a break of Y: its answer (00h, of before Y broke?) is no evidence.
  driver_->on_fault_poll_sent();
  emcy(CanFrame(0x83, {0x20, 0x31, 0x81, 0x00, 0x83, 0x00, 0x00, 0x00}), 3);
  EXPECT_EQ(driver_->on_fault_poll(std::vector<std::uint8_t>{0x00}, at(4)), "");
  EXPECT_TRUE(driver_->faulted(kY));
  // Two bytes: 1001h is UNSIGNED8 here, no evidence.
  driver_->on_fault_poll_sent();
  EXPECT_EQ(driver_->on_fault_poll(std::vector<std::uint8_t>{0x00, 0x00}, at(5)), "");
  EXPECT_TRUE(driver_->faulted(kX));
  // The board keeps the power-on warning's 11h (generic + communication): no device error.
  driver_->on_fault_poll_sent();
  const std::string said = driver_->on_fault_poll(std::vector<std::uint8_t>{0x11}, at(6));
  EXPECT_NE(said.find("1001h read 11h: no device error"), std::string::npos) << said;
  EXPECT_FALSE(driver_->any_fault());
  EXPECT_FALSE(driver_->fault_poll());
  ASSERT_TRUE(frame(CanFrame(0x283, {1, 0, 2, 0, 3, 0, 4, 0}), 7));
  EXPECT_EQ(v(kX).status, SignalStatus::Valid);
}

// An undocumented error code ends on a 1001h that shows no error but communication (bits 0 and 4):
// bit 7 clear alone is not enough (the code may have set another bit).
TEST_F(Mcb402Test, UndocumentedErrorEndsOnA1001hWithNothingButCommunication) {
  emcy(CanFrame(0x83, {0x00, 0x50, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00}), 1);
  ASSERT_TRUE(driver_->fault_poll());
  driver_->on_fault_poll_sent();
  EXPECT_EQ(driver_->on_fault_poll(std::vector<std::uint8_t>{0x03}, at(2)), "");
  EXPECT_TRUE(driver_->any_fault());
  driver_->on_fault_poll_sent();
  EXPECT_NE(driver_->on_fault_poll(std::vector<std::uint8_t>{0x11}, at(3)), "");
  EXPECT_FALSE(driver_->any_fault());
  // At boot the same: 1001h = 03h keeps it.
  emcy(CanFrame(0x83, {0x00, 0x50, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00}), 4);
  std::string error;
  driver_->begin_boot();
  ASSERT_TRUE(driver_->on_boot_read(0x1001, 0, std::vector<std::uint8_t>{0x03}, error));
  EXPECT_TRUE(driver_->any_fault());
}

// A code the document does not list: what it affects is unknown, so every input is faulted
// until the error reset 0000h.
TEST_F(Mcb402Test, UnknownErrorEmcyIsCountedAndFaultsEveryInputUntilTheErrorReset) {
  ASSERT_TRUE(frame(CanFrame(0x283, {1, 0, 2, 0, 3, 0, 4, 0})));
  emcy(CanFrame(0x83, {0x00, 0x50, 0x81, 0x00, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(driver_->counters().unknown_emcy, 1u);
  EXPECT_TRUE(decoded_.back().error);
  EXPECT_EQ(decoded_.back().affected.size(), mcb402::kAxes + mcb402::kButtons);
  EXPECT_EQ(v(kX).status, SignalStatus::Error);
  ASSERT_TRUE(frame(CanFrame(0x283, {1, 0, 2, 0, 3, 0, 4, 0})));
  EXPECT_EQ(v(kX).status, SignalStatus::Error) << "a PDO is no evidence";
  emcy(CanFrame(0x83, {0, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_FALSE(driver_->any_fault());
  ASSERT_TRUE(frame(CanFrame(0x283, {1, 0, 2, 0, 3, 0, 4, 0})));
  EXPECT_EQ(v(kX).status, SignalStatus::Valid);
}

TEST_F(Mcb402Test, LedsSendTheWholeRememberedOutputByte) {
  // [CO4013 "Operation mode 4"] RPDO1 = 6200h:01, bits 0..3 = OUT0..OUT3.
  EXPECT_TRUE(driver_->set_output(led(1), 1, at(1)));
  EXPECT_TRUE(driver_->set_output(led(3), 1, at(2)));
  EXPECT_TRUE(driver_->set_output(led(4), 1, at(3)));
  EXPECT_TRUE(driver_->set_output(led(1), 0, at(4)));
  ASSERT_EQ(sent_.size(), 4u);
  EXPECT_EQ(sent_[0], CanFrame(0x203, {0x01}));
  EXPECT_EQ(sent_[1], CanFrame(0x203, {0x05}));
  EXPECT_EQ(sent_[2], CanFrame(0x203, {0x0D}));
  EXPECT_EQ(sent_[3], CanFrame(0x203, {0x0C}));
  EXPECT_EQ(v(led(3)).value, 1);
  EXPECT_EQ(v(led(1)).value, 0);
  // Out of range, or not an output: refused, nothing sent.
  EXPECT_FALSE(driver_->set_output(led(2), 2, at(5)));
  EXPECT_FALSE(driver_->set_output(led(2), -1, at(5)));
  EXPECT_FALSE(driver_->set_output(kX, 1, at(5)));
  EXPECT_FALSE(driver_->set_output(button(1), 1, at(5)));
  EXPECT_FALSE(driver_->set_output(99, 1, at(5)));
  EXPECT_EQ(sent_.size(), 4u);
  EXPECT_EQ(mcb().output_byte(), 0x0C);
}

TEST_F(Mcb402Test, OfflineMarksInputsAndOnlineResendsOutputs) {
  ASSERT_TRUE(frame(CanFrame(0x283, {1, 0, 2, 0, 3, 0, 4, 0})));
  ASSERT_TRUE(driver_->set_output(led(2), 1, at(0)));
  sent_.clear();
  driver_->on_offline(at(10));
  for (std::size_t i = 0; i < led(1); ++i) {
    EXPECT_EQ(v(i).status, SignalStatus::Offline);
    EXPECT_EQ(v(i).value, 0);
  }
  EXPECT_EQ(v(led(2)).value, 1) << "outputs keep their command";
  driver_->on_online(at(20));
  ASSERT_EQ(sent_.size(), 1u);
  EXPECT_EQ(sent_[0], CanFrame(0x203, {0x02})) << "a rebooted board starts with 6200h = 0";
  EXPECT_EQ(v(kX).status, SignalStatus::Offline) << "inputs wait for a PDO";
}

// The cable-break latch survives going offline and back (a heartbeat loss repeats no EMCY), and
// the boot-up itself; what decides it is the error register 1001h read back at every (re)start
// ([CO4013 Index 1001] bit 7 "Device Error"): clear after a repair and reboot, kept otherwise.
TEST_F(Mcb402Test, CableBreakLatchSurvivesOfflineUntilThe1001hReadBack) {
  emcy(CanFrame(0x83, {0x20, 0x31, 0x81, 0x00, 0x81, 0x00, 0x00, 0x00}));
  driver_->on_offline(at(1));
  driver_->on_online(at(2));
  ASSERT_TRUE(frame(CanFrame(0x283, {1, 0, 2, 0, 3, 0, 4, 0}), 3));
  EXPECT_EQ(v(kX).status, SignalStatus::Error);
  EXPECT_EQ(v(kY).status, SignalStatus::Valid);
  // Restart with the cable still broken: 1001h = 81h keeps it.
  driver_->on_offline(at(4));
  driver_->on_application_reset(at(4));
  driver_->begin_boot();
  auto reads = driver_->boot_reads();
  ASSERT_EQ(reads.size(), 1u);
  EXPECT_EQ(reads[0], (std::pair<std::uint16_t, std::uint8_t>{0x1001, 0}));
  std::string error;
  ASSERT_TRUE(driver_->on_boot_read(0x1001, 0, std::vector<std::uint8_t>{0x81}, error));
  EXPECT_TRUE(driver_->boot_reads().empty());
  driver_->on_online(at(5));
  ASSERT_TRUE(frame(CanFrame(0x283, {1, 0, 2, 0, 3, 0, 4, 0}), 6));
  EXPECT_EQ(v(kX).status, SignalStatus::Error);
  EXPECT_EQ(mcb().broken_axes(), 0x01);
  // Repaired and rebooted: 1001h = 00h (no device error), the latch goes.
  driver_->on_offline(at(7));
  driver_->begin_boot();
  ASSERT_TRUE(driver_->on_boot_read(0x1001, 0, std::vector<std::uint8_t>{0x00}, error));
  EXPECT_FALSE(driver_->any_fault());
  EXPECT_EQ(mcb().broken_axes(), 0x00);
  driver_->on_online(at(8));
  ASSERT_TRUE(frame(CanFrame(0x283, {1, 0, 2, 0, 3, 0, 4, 0}), 9));
  EXPECT_EQ(v(kX).status, SignalStatus::Valid);
  EXPECT_EQ(v(kX).value, 1);
  // Only the communication bit (a warning at power-on, 1001h = 11h): no device error.
  emcy(CanFrame(0x83, {0x20, 0x31, 0x81, 0x00, 0x82, 0x00, 0x00, 0x00}), 10);
  driver_->begin_boot();
  ASSERT_TRUE(driver_->on_boot_read(0x1001, 0, std::vector<std::uint8_t>{0x11}, error));
  EXPECT_FALSE(driver_->any_fault());
  // A device error the gateway never saw as EMCY (it went before the gateway listened): which
  // axis is unknown, so all four.
  driver_->begin_boot();
  ASSERT_TRUE(driver_->on_boot_read(0x1001, 0, std::vector<std::uint8_t>{0x81}, error));
  for (const std::size_t a : {kX, kY, kZ, kT}) EXPECT_TRUE(driver_->faulted(a)) << a;
  EXPECT_FALSE(driver_->faulted(button(1)));
  // A refused read is no evidence: the faults stay, the boot goes on.
  driver_->begin_boot();
  EXPECT_TRUE(driver_->on_boot_read_abort(0x1001, 0, SdoAbortCode::ObjectDoesNotExist));
  EXPECT_TRUE(driver_->boot_reads().empty());
  EXPECT_TRUE(driver_->faulted(kX));
}

// 1001h is UNSIGNED8: an answer of another length (none, two bytes) is no evidence, and the
// latch stays (it once read an empty answer as "no device error").
TEST_F(Mcb402Test, AReadBackOfTheWrongLengthLeavesTheLatch) {
  emcy(CanFrame(0x83, {0x20, 0x31, 0x81, 0x00, 0x81, 0x00, 0x00, 0x00}));
  ASSERT_TRUE(driver_->any_fault());
  std::string error;
  for (const auto& bad : {std::vector<std::uint8_t>{}, std::vector<std::uint8_t>{0x00, 0x00}}) {
    driver_->begin_boot();
    ASSERT_TRUE(driver_->on_boot_read(0x1001, 0, bad, error));
    EXPECT_TRUE(driver_->any_fault()) << bad.size() << " bytes";
  }
}

// [CO4013 Index 2180] "CAN Restart Time ... If the restart time is set to 0 automatic restart of the
// device in case of bus off is prohibited" (default 0): written at configuration.
TEST_F(Mcb402Test, ConfigurationWritesTheCanRestartTime) {
  auto find = [this] {
    for (const auto& w : driver_->configuration())
      if (w.index == 0x2180 && w.sub == 0) return w.data;
    return std::vector<std::uint8_t>{};
  };
  EXPECT_EQ(find(), (std::vector<std::uint8_t>{0xE8, 0x03})) << "1000 ms, UNSIGNED16";
  make({{{"can_restart_ms", "250"}}});
  EXPECT_EQ(find(), (std::vector<std::uint8_t>{250, 0}));
  std::string error;
  EXPECT_EQ(make_mcb402_driver(
                kNode, [](const CanFrame&) {}, {{{"can_restart_ms", "0"}, {"button_bits", "1,2,3,4,5,7,6"}}}, error),
            nullptr);
  EXPECT_NE(error.find("can_restart_ms"), std::string::npos);
}

// What is wrong with a button_bits value is named: the bit given twice with both positions, a
// number that is no bit, the count.
TEST(Mcb402ButtonBits, ARefusalNamesWhatIsWrong) {
  std::string why;
  EXPECT_FALSE(parse_button_bits("1,2,3,3,4,5,6", why));
  EXPECT_EQ(why, "bit 3 is given twice, at positions 3 and 4 (BP3 and BP4)");
  EXPECT_FALSE(parse_button_bits("6/1/2/3/4/5/6", why));
  EXPECT_EQ(why, "bit 6 is given twice, at positions 1 and 7 (BP1 and BP7)");
  EXPECT_FALSE(parse_button_bits("1,2,3,4,5,6,8", why));
  EXPECT_EQ(why, "'8' at position 7 (BP7) is not a bit number 0..7");
  EXPECT_FALSE(parse_button_bits("1,2,3,4,5,6", why));
  EXPECT_EQ(why, "6 numbers for 7 push buttons");
  EXPECT_FALSE(parse_button_bits("0,1,2,3,4,5,6,7", why));
  EXPECT_EQ(why, "8 numbers for 7 push buttons");
  EXPECT_EQ(parse_button_bits(" 1, 2,3,4,5,7,6", why), (mcb402::ButtonBits{1, 2, 3, 4, 5, 7, 6}));
}

TEST_F(Mcb402Test, OptionsAreCheckedAndUnknownOnesRefused) {
  std::string error;
  auto sink = [](const CanFrame&) {};
  EXPECT_EQ(make_mcb402_driver(kNode, sink, {{{"event_timer_ms", "0"}, {"button_bits", "1,2,3,4,5,7,6"}}}, error),
            nullptr);
  EXPECT_NE(error.find("event_timer_ms"), std::string::npos);
  EXPECT_EQ(make_mcb402_driver(kNode, sink, {{{"event_timer_ms", "65536"}, {"button_bits", "1,2,3,4,5,7,6"}}}, error),
            nullptr);
  EXPECT_EQ(make_mcb402_driver(kNode, sink, {{{"event_timer_ms", "2x"}, {"button_bits", "1,2,3,4,5,7,6"}}}, error),
            nullptr);
  EXPECT_EQ(make_mcb402_driver(kNode, sink, {{{"button_timer_ms", "-1"}, {"button_bits", "1,2,3,4,5,7,6"}}}, error),
            nullptr);
  EXPECT_EQ(make_mcb402_driver(kNode, sink, {{{"button_bits", "1,2,3,4,5,6"}}}, error), nullptr);
  EXPECT_EQ(make_mcb402_driver(kNode, sink, {{{"button_bits", "1,2,3,4,5,6,6"}}}, error), nullptr);
  EXPECT_EQ(make_mcb402_driver(kNode, sink, {{{"button_bits", "1,2,3,4,5,6,8"}}}, error), nullptr);
  EXPECT_EQ(make_mcb402_driver(kNode, sink, {{{"button_bits", "0,1,2,3,4,5,6,7"}}}, error), nullptr);
  EXPECT_EQ(make_mcb402_driver(kNode, sink, {{{"heartbeat", "100"}, {"button_bits", "1,2,3,4,5,7,6"}}}, error),
            nullptr);
  EXPECT_NE(error.find("unknown option 'heartbeat'"), std::string::npos);
  EXPECT_EQ(make_mcb402_driver(NodeId{0}, sink, {}, error), nullptr);
  auto d =
      make_mcb402_driver(kNode, sink,
                         {{{"event_timer_ms", "65535"}, {"button_timer_ms", "0"}, {"button_bits", "1/2/3/4/5/7/6"}}},
                         error);
  ASSERT_NE(d, nullptr) << error;
  const auto& o = dynamic_cast<Mcb402Driver&>(*d).options();
  EXPECT_EQ(o.event_timer_ms, 65535);
  EXPECT_EQ(o.button_timer_ms, 0);
  EXPECT_EQ(o.button_bits, (mcb402::ButtonBits{1, 2, 3, 4, 5, 7, 6})) << "'/' separates as ',' does";
}

// The bit order has no default (the document's table is damaged): a missing button_bits names
// the setting and the commissioning step that fills it.
TEST_F(Mcb402Test, ButtonBitsAreARequiredCommissioningChoice) {
  std::string error;
  auto sink = [](const CanFrame&) {};
  EXPECT_EQ(make_mcb402_driver(kNode, sink, {}, error), nullptr);
  EXPECT_EQ(error, mcb402::kButtonBitsMissing);
  EXPECT_NE(error.find("button_bits is required"), std::string::npos);
  EXPECT_NE(error.find("press BP1..BP7 one at a time"), std::string::npos);
  EXPECT_EQ(make_mcb402_driver(kNode, sink, {{{"event_timer_ms", "50"}}}, error), nullptr);
  EXPECT_EQ(error, mcb402::kButtonBitsMissing);
  EXPECT_EQ(make_mcb402_driver(kNode, sink, {{{"button_bits", ""}}}, error), nullptr);
  EXPECT_NE(error.find("button_bits '': '' at position 1 (BP1) is not a bit number 0..7"), std::string::npos) << error;
  EXPECT_NE(make_mcb402_driver(kNode, sink, {{{"button_bits", "6, 5, 4, 3, 2, 1, 0"}}}, error), nullptr) << error;
}

}  // namespace
