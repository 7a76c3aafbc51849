// SYNC producer/consumer (CiA 301 §7.2.5, objects 1005h/1006h/1007h/1019h).
#include "canopen/301/sync.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace oegw::canopen {
namespace {

using namespace std::chrono_literals;

struct SyncFixture : ::testing::Test {
  ObjectDictionary od;
  std::vector<CanFrame> sent;
  std::vector<std::uint8_t> counters;
  TimePoint t0{Duration{1'000'000}};

  SyncService make(SyncConfig cfg = {}) {
    return SyncService(
        od, [this](const CanFrame& f) { sent.push_back(f); }, cfg);
  }
};

TEST_F(SyncFixture, InstallsObjectsWithDefaults) {
  SyncService s(od, [](const CanFrame&) {});
  EXPECT_EQ(od.get<std::uint32_t>(0x1005, 0), 0x80u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1006, 0), 0u);
  EXPECT_EQ(od.get<std::uint8_t>(0x1019, 0), 0u);
  EXPECT_EQ(od.find(0x1007), nullptr);
  EXPECT_FALSE(s.producer());
  EXPECT_FALSE(s.next_deadline().has_value());
}

// Novotechnik §3 (pre-defined connection set): "SYNC 0x080"; §3.2 "SYNC Consumer".
TEST_F(SyncFixture, ConsumerDeliversSyncWithAndWithoutCounter) {
  SyncService s(od, [this](const CanFrame& f) { sent.push_back(f); });
  std::vector<TimePoint> times;
  s.set_handler([&](std::uint8_t c, TimePoint now) {
    counters.push_back(c);
    times.push_back(now);
  });
  EXPECT_TRUE(s.on_frame(CanFrame(0x080, {}), t0));
  EXPECT_TRUE(s.on_frame(CanFrame(0x080, {0x05}), t0 + 10ms));
  EXPECT_FALSE(s.on_frame(CanFrame(0x081, {}), t0 + 20ms));  // an EMCY, not a SYNC
  EXPECT_FALSE(s.on_frame(CanFrame::remote(0x080, 0), t0 + 20ms));
  EXPECT_EQ(counters, (std::vector<std::uint8_t>{0, 5}));
  EXPECT_EQ(times.back(), t0 + 10ms);
  EXPECT_EQ(s.last_sync(), t0 + 10ms);
  EXPECT_TRUE(sent.empty());
}

TEST_F(SyncFixture, UnexpectedLengthReports8240) {
  SyncService s(od, [](const CanFrame&) {});
  std::vector<std::uint16_t> errors;
  s.on_length_error = [&](std::uint16_t code) { errors.push_back(code); };
  s.set_handler([&](std::uint8_t c, TimePoint) { counters.push_back(c); });
  EXPECT_TRUE(s.on_frame(CanFrame(0x080, {}), t0));
  EXPECT_TRUE(errors.empty());
  EXPECT_TRUE(s.on_frame(CanFrame(0x080, {3}), t0));  // counter not configured (1019h = 0)
  EXPECT_EQ(errors, (std::vector<std::uint16_t>{0x8240}));
  ASSERT_EQ(od.write(0x1019, 0, std::vector<std::uint8_t>{8}), SdoAbortCode::None);
  EXPECT_TRUE(s.on_frame(CanFrame(0x080, {4}), t0));
  EXPECT_TRUE(s.on_frame(CanFrame(0x080, {}), t0));  // counter missing
  EXPECT_EQ(errors.size(), 2u);
  EXPECT_EQ(counters, (std::vector<std::uint8_t>{0, 3, 4, 0}));
}

TEST_F(SyncFixture, ConsumerFollowsCobIdChange) {
  SyncService s(od, [](const CanFrame&) {});
  s.set_handler([&](std::uint8_t c, TimePoint) { counters.push_back(c); });
  ASSERT_EQ(od.write(0x1005, 0, encode<std::uint32_t>(0x90)), SdoAbortCode::None);
  EXPECT_FALSE(s.on_frame(CanFrame(0x080, {}), t0));
  EXPECT_TRUE(s.on_frame(CanFrame(0x090, {}), t0));
  EXPECT_EQ(counters.size(), 1u);
}

TEST_F(SyncFixture, ProducerEmitsEveryPeriodWithoutCounter) {
  SyncService s = make({.cob_id = 0x40000080, .period_us = 10'000});
  s.set_handler([&](std::uint8_t c, TimePoint) { counters.push_back(c); });
  ASSERT_TRUE(s.producer());
  ASSERT_TRUE(s.next_deadline().has_value());
  s.advance(t0);  // starts production at t0
  EXPECT_TRUE(sent.empty());
  EXPECT_EQ(s.next_deadline(), t0 + 10ms);
  s.advance(t0 + 9999us);
  EXPECT_TRUE(sent.empty());
  s.advance(t0 + 10ms);
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], CanFrame(0x080, {}));
  EXPECT_EQ(s.next_deadline(), t0 + 20ms);
  s.advance(t0 + 20ms);
  EXPECT_EQ(sent.size(), 2u);
  // The producer's own PDOs are synchronised too.
  EXPECT_EQ(counters, (std::vector<std::uint8_t>{0, 0}));
  // A producer does not consume a SYNC on its own ID.
  EXPECT_FALSE(s.on_frame(CanFrame(0x080, {}), t0 + 21ms));
}

TEST_F(SyncFixture, ProducerCounterWrapsAtOverflowValue) {
  SyncService s = make({.cob_id = 0x40000080, .period_us = 1000, .counter_overflow = 3});
  s.set_handler([&](std::uint8_t c, TimePoint) { counters.push_back(c); });
  s.advance(t0);
  for (int i = 1; i <= 5; ++i) s.advance(t0 + i * 1ms);
  ASSERT_EQ(sent.size(), 5u);
  EXPECT_EQ(sent[0], CanFrame(0x080, {1}));
  EXPECT_EQ(sent[2], CanFrame(0x080, {3}));
  EXPECT_EQ(sent[3], CanFrame(0x080, {1}));
  EXPECT_EQ(counters, (std::vector<std::uint8_t>{1, 2, 3, 1, 2}));
}

TEST_F(SyncFixture, PeriodWrittenAtRuntimeStartsProduction) {
  SyncService s = make({.cob_id = 0x40000080});
  EXPECT_FALSE(s.next_deadline().has_value());
  s.advance(t0);
  ASSERT_EQ(od.write(0x1006, 0, encode<std::uint32_t>(5000)), SdoAbortCode::None);
  ASSERT_TRUE(s.next_deadline().has_value());
  EXPECT_LE(*s.next_deadline(), t0);  // "call advance() now" to pick up the new period
  s.advance(t0 + 1ms);
  EXPECT_EQ(s.next_deadline(), t0 + 6ms);
  s.advance(t0 + 6ms);
  EXPECT_EQ(sent.size(), 1u);
  ASSERT_EQ(od.write(0x1006, 0, encode<std::uint32_t>(0)), SdoAbortCode::None);
  s.advance(t0 + 20ms);
  EXPECT_EQ(sent.size(), 1u);
  EXPECT_FALSE(s.next_deadline().has_value());
}

// The service reads 1005h/1006h through slots: an object replaced in the dictionary after the
// service was built (no path does it today; a future one must call reload(), and the service's
// write hooks go with the old object) is the one it reads, never the freed one.
TEST_F(SyncFixture, ReadsTheCommunicationObjectsAgainWhenTheyAreReplaced) {
  SyncService s = make({.cob_id = 0x40000080, .period_us = 5000});
  s.advance(t0);
  s.advance(t0 + 5ms);
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent.back().id, 0x80u);
  od.add_var(0x1005, "COB-ID SYNC", DataType::Unsigned32, Access::ReadWrite, encode<std::uint32_t>(0x40000081));
  od.add_var(0x1006, "Communication cycle period", DataType::Unsigned32, Access::ReadWrite,
             encode<std::uint32_t>(2000));
  s.reload();
  s.advance(t0 + 6ms);
  EXPECT_EQ(s.next_deadline(), t0 + 8ms) << "the new period";
  s.advance(t0 + 8ms);
  ASSERT_EQ(sent.size(), 2u);
  EXPECT_EQ(sent.back().id, 0x81u) << "the new COB-ID";
  od.add_var(0x1006, "Communication cycle period", DataType::Unsigned32, Access::ReadWrite, encode<std::uint32_t>(0));
  EXPECT_FALSE(s.producer()) << "period 0: no longer the producer";
}

// CiA 301 §7.5.2.41: 1019h only 0 or 2..240, and only while 1006h is 0.
TEST_F(SyncFixture, CounterOverflowWriteRules) {
  SyncService s = make({.cob_id = 0x40000080, .period_us = 1000});
  EXPECT_EQ(od.write(0x1019, 0, std::vector<std::uint8_t>{1}), SdoAbortCode::InvalidValue);
  EXPECT_EQ(od.write(0x1019, 0, std::vector<std::uint8_t>{241}), SdoAbortCode::InvalidValue);
  EXPECT_EQ(od.write(0x1019, 0, std::vector<std::uint8_t>{10}), SdoAbortCode::CannotTransferDeviceState);
  ASSERT_EQ(od.write(0x1006, 0, encode<std::uint32_t>(0)), SdoAbortCode::None);
  EXPECT_EQ(od.write(0x1019, 0, std::vector<std::uint8_t>{10}), SdoAbortCode::None);
}

TEST_F(SyncFixture, CobIdChangeRefusedWhileProducing) {
  SyncService s = make({.cob_id = 0x40000080, .period_us = 1000});
  EXPECT_EQ(od.write(0x1005, 0, encode<std::uint32_t>(0x40000090)), SdoAbortCode::InvalidValue);
  EXPECT_EQ(od.write(0x1005, 0, encode<std::uint32_t>(0x00000080)), SdoAbortCode::None);  // stop producing
  EXPECT_EQ(od.write(0x1005, 0, encode<std::uint32_t>(0x40000090)), SdoAbortCode::None);
}

TEST_F(SyncFixture, WindowLength) {
  SyncService s = make({.window = true, .window_us = 500});
  EXPECT_FALSE(s.in_window(t0));  // no SYNC yet
  s.on_frame(CanFrame(0x080, {}), t0);
  EXPECT_TRUE(s.in_window(t0 + 500us));
  EXPECT_FALSE(s.in_window(t0 + 501us));
}

}  // namespace
}  // namespace oegw::canopen
