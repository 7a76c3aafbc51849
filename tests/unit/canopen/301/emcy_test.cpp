// Emergency producer/consumer (CiA 301 §7.2.7, objects 1001h, 1003h, 1014h, 1015h, 1028h).
#include "canopen/301/emcy.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace oegw::canopen {
namespace {

using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

class EmcyFixture : public ::testing::Test {
 protected:
  ObjectDictionary od;
  std::vector<CanFrame> sent;
  TimePoint t0{Duration{2'000'000}};
  FrameSink sink() {
    return [this](const CanFrame& f) { sent.push_back(f); };
  }
};

TEST_F(EmcyFixture, InstallsObjects) {
  EmcyProducer p(od, sink(), NodeId{0x11}, {.history_size = 4});
  EXPECT_EQ(od.get<std::uint32_t>(0x1014, 0), 0x91u);  // 80h + node-ID
  EXPECT_EQ(od.get<std::uint16_t>(0x1015, 0), 0u);
  EXPECT_EQ(od.get<std::uint8_t>(0x1001, 0), 0u);
  EXPECT_EQ(od.get<std::uint8_t>(0x1003, 0), 0u);
  EXPECT_NE(od.find(0x1003, 4), nullptr);
  EXPECT_EQ(od.find(0x1003, 5), nullptr);
}

// Novotechnik §9.1 "Emergency Messages": "0x5000 1 0 0 Device Hardware Fault ... If the internal
// error bit is reset to 0, an EMCY with 0x0000 is sent"; COB-ID 0x80 + node-ID, DLC 8, error
// code in bytes 0-1, error register (1001h) in byte 2.
TEST_F(EmcyFixture, NovotechnikHardwareFaultAndReset) {
  EmcyProducer p(od, sink(), NodeId{0x01});
  EXPECT_TRUE(p.raise(0x5000, 0x00, t0));
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], CanFrame(0x081, {0x00, 0x50, 0x01, 0, 0, 0, 0, 0}));
  EXPECT_EQ(od.get<std::uint8_t>(0x1001, 0), 0x01u);
  EXPECT_TRUE(p.clear(0x5000, t0 + 1ms));
  ASSERT_EQ(sent.size(), 2u);
  EXPECT_EQ(sent[1], CanFrame(0x081, {0x00, 0x00, 0x00, 0, 0, 0, 0, 0}));
  EXPECT_EQ(od.get<std::uint8_t>(0x1001, 0), 0x00u);
  EXPECT_FALSE(p.clear(0x5000, t0 + 2ms));
  EXPECT_EQ(sent.size(), 2u);
}

TEST_F(EmcyFixture, ManufacturerFieldAndRegisterBits) {
  EmcyProducer p(od, sink(), NodeId{0x05});
  EXPECT_TRUE(p.raise(0x8130, 0x10, {1, 2, 3, 4, 5}, t0));  // life guard error, communication bit
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], CanFrame(0x085, {0x30, 0x81, 0x11, 1, 2, 3, 4, 5}));
  EXPECT_FALSE(p.raise(0x8130, 0x10, t0)) << "already active";
  EXPECT_EQ(sent.size(), 1u);
  EXPECT_TRUE(p.raise(0x4210, 0x08, t0));  // temperature
  EXPECT_EQ(od.get<std::uint8_t>(0x1001, 0), 0x19u);
  // One error gone, one left: register updated, no reset EMCY.
  EXPECT_TRUE(p.clear(0x8130, t0));
  EXPECT_EQ(od.get<std::uint8_t>(0x1001, 0), 0x09u);
  EXPECT_EQ(sent.size(), 2u);
  EXPECT_TRUE(p.active(0x4210));
  EXPECT_FALSE(p.active(0x8130));
  EXPECT_TRUE(p.clear(0x4210, t0));
  ASSERT_EQ(sent.size(), 3u);
  EXPECT_EQ(get_u16(sent[2].data.data()), 0x0000);
}

// CiA 301 §7.5.2.13: 1003h newest at sub-index 1, sub-index 0 = number of errors; writing 0
// clears; any other value is refused with 0609 0030h.
TEST_F(EmcyFixture, PredefinedErrorFieldHistory) {
  EmcyProducer p(od, sink(), NodeId{0x05}, {.history_size = 3});
  p.raise(0x1000, 0, t0);
  p.raise(0x2310, 0x02, t0);
  EXPECT_EQ(od.get<std::uint8_t>(0x1003, 0), 2u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1003, 1), 0x2310u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1003, 2), 0x1000u);
  p.raise(0x3100, 0x04, t0);
  p.raise(0x4210, 0x08, t0);
  EXPECT_EQ(od.get<std::uint8_t>(0x1003, 0), 3u) << "capped at the field size";
  EXPECT_EQ(od.get<std::uint32_t>(0x1003, 1), 0x4210u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1003, 3), 0x2310u) << "the oldest fell off";
  p.clear(0x4210, t0);
  EXPECT_EQ(od.get<std::uint8_t>(0x1003, 0), 3u) << "clearing an error does not touch the history";

  EXPECT_EQ(od.write(0x1003, 0, Bytes{2}), SdoAbortCode::InvalidValue);
  EXPECT_EQ(od.write(0x1003, 1, encode<std::uint32_t>(0)), SdoAbortCode::WriteOfReadOnly);
  EXPECT_EQ(od.get<std::uint8_t>(0x1003, 0), 3u);
  ASSERT_EQ(od.write(0x1003, 0, Bytes{0}), SdoAbortCode::None);
  EXPECT_EQ(od.get<std::uint8_t>(0x1003, 0), 0u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1003, 1), 0u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1003, 3), 0u);
  p.raise(0x5000, 0, t0);
  EXPECT_EQ(od.get<std::uint8_t>(0x1003, 0), 1u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1003, 1), 0x5000u);
}

// MCB-402 §5 1015h: "Inhibit Time for emergency messages. If the Inhibit Time is set to 0, inhibit
// delay is disabled. The Inhibit Time is a multiple of 100usec".
TEST_F(EmcyFixture, InhibitTimeQueuesInOrder) {
  EmcyProducer p(od, sink(), NodeId{0x03}, {.inhibit_time = 50});  // 5 ms
  p.raise(0x1000, 0, t0);
  p.raise(0x2000, 0, t0 + 1ms);
  p.raise(0x3000, 0, t0 + 2ms);
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(p.next_deadline(), t0 + 5ms);
  p.advance(t0 + 4999us);
  EXPECT_EQ(sent.size(), 1u);
  p.advance(t0 + 5ms);
  ASSERT_EQ(sent.size(), 2u);
  EXPECT_EQ(get_u16(sent[1].data.data()), 0x2000);
  EXPECT_EQ(p.next_deadline(), t0 + 10ms);
  p.advance(t0 + 12ms);
  ASSERT_EQ(sent.size(), 3u);
  EXPECT_EQ(get_u16(sent[2].data.data()), 0x3000);
  EXPECT_FALSE(p.next_deadline().has_value());
  // After a quiet period the next one goes out at once.
  p.raise(0x4000, 0, t0 + 30ms);
  EXPECT_EQ(sent.size(), 4u);
  // 0 disables the inhibit time.
  ASSERT_EQ(od.write(0x1015, 0, encode<std::uint16_t>(0)), SdoAbortCode::None);
  p.raise(0x5000, 0, t0 + 30ms);
  EXPECT_EQ(sent.size(), 5u);
}

TEST_F(EmcyFixture, QueueLimitDrops) {
  EmcyProducer p(od, sink(), NodeId{0x03}, {.inhibit_time = 10, .queue_limit = 1});
  p.raise(0x1000, 0, t0);
  p.raise(0x2000, 0, t0);
  p.raise(0x3000, 0, t0);
  EXPECT_EQ(p.dropped(), 1u);
  p.advance(t0 + 1ms);
  p.advance(t0 + 2ms);
  ASSERT_EQ(sent.size(), 2u);
  EXPECT_EQ(get_u16(sent[1].data.data()), 0x2000);
}

TEST_F(EmcyFixture, InvalidCobIdSendsNothingButRecords) {
  EmcyProducer p(od, sink(), NodeId{0x03});
  ASSERT_EQ(od.write(0x1014, 0, encode<std::uint32_t>(0x80000083)), SdoAbortCode::None);
  p.raise(0x1000, 0, t0);
  EXPECT_TRUE(sent.empty());
  EXPECT_EQ(od.get<std::uint8_t>(0x1001, 0), 1u);
  EXPECT_EQ(od.get<std::uint8_t>(0x1003, 0), 1u);
}

TEST_F(EmcyFixture, CobIdChangeWhileValidRefused) {
  EmcyProducer p(od, sink(), NodeId{0x03});
  EXPECT_EQ(od.write(0x1014, 0, encode<std::uint32_t>(0x93)), SdoAbortCode::InvalidValue);
  ASSERT_EQ(od.write(0x1014, 0, encode<std::uint32_t>(0x80000083)), SdoAbortCode::None);
  ASSERT_EQ(od.write(0x1014, 0, encode<std::uint32_t>(0x93)), SdoAbortCode::None);
  p.raise(0x1000, 0, t0);
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0].id, 0x93u);
}

// ---- Event EMCYs (report): sent once, 1001h untouched, through the same 1015h queue -----------

// 1015h = 1000 (100 ms): two reports made together leave 100 ms apart, in order, and a raise
// made meanwhile queues behind them (one queue for both kinds).
TEST_F(EmcyFixture, ReportGoesThroughTheInhibitQueue) {
  EmcyProducer p(od, sink(), NodeId{0x20}, {.inhibit_time = 1000});
  EXPECT_TRUE(p.report(0x1000, {0x11, 0x00, 0x21, 0x00, 0xFF}, 0x11, t0));
  EXPECT_TRUE(p.report(0x3120, {0x03, 0x81, 0x00, 0x81, 0x00}, 0x03, t0));
  EXPECT_TRUE(p.raise(0x7000, 0x00, {0x11, 'r', 'i', 'g', 'h'}, t0 + 10ms, 0x11));
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], CanFrame(0x0A0, {0x00, 0x10, 0x00, 0x11, 0x00, 0x21, 0x00, 0xFF}));
  EXPECT_EQ(p.next_deadline(), t0 + 100ms);
  p.advance(t0 + 99ms);
  EXPECT_EQ(sent.size(), 1u) << "held back by 1015h";
  p.advance(t0 + 100ms);
  ASSERT_EQ(sent.size(), 2u);
  EXPECT_EQ(sent[1], CanFrame(0x0A0, {0x20, 0x31, 0x00, 0x03, 0x81, 0x00, 0x81, 0x00}))
      << "byte 2: 1001h when the report was made (no error then)";
  EXPECT_EQ(p.next_deadline(), t0 + 200ms);
  p.advance(t0 + 200ms);
  ASSERT_EQ(sent.size(), 3u);
  EXPECT_EQ(sent[2], CanFrame(0x0A0, {0x00, 0x70, 0x01, 0x11, 'r', 'i', 'g', 'h'}));
  EXPECT_FALSE(p.next_deadline().has_value());
}

// 1003h: newest first, entry = code | info << 16; raise() takes the same info; an error reset
// (0000h) is no error and is not recorded.
TEST_F(EmcyFixture, ReportIsRecordedIn1003hWithItsInfo) {
  EmcyProducer p(od, sink(), NodeId{0x20}, {.history_size = 4});
  EXPECT_TRUE(p.raise(0x7000, 0x00, {0x11, 'r', 'i', 'g', 'h'}, t0, 0x11));
  EXPECT_TRUE(p.report(0x7000, {0x03, 'l', 'e', 'f', 't'}, 0x03, t0));
  EXPECT_TRUE(p.report(0x5051, {0x7F, 0x01, 0x00, 0x00, 0x00}, 0x7F, t0));
  EXPECT_TRUE(p.report(EmcyProducer::kErrorReset, {0x7F, 0x00, 0x00, 0x00, 0x00}, 0x7F, t0));
  EXPECT_EQ(sent.size(), 4u) << "the error reset is sent";
  EXPECT_EQ(od.get<std::uint8_t>(0x1003, 0), 3u) << "but not recorded";
  EXPECT_EQ(od.get<std::uint32_t>(0x1003, 1), 0x007F5051u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1003, 2), 0x00037000u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1003, 3), 0x00117000u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1003, 4), 0u);
  p.raise(0x8130, 0x10, t0);  // no info: 0
  EXPECT_EQ(od.get<std::uint32_t>(0x1003, 1), 0x8130u);
}

// A report leaves 1001h and the active errors alone; byte 2 carries 1001h as it is.
TEST_F(EmcyFixture, ReportLeavesTheErrorRegisterUnchanged) {
  EmcyProducer p(od, sink(), NodeId{0x20});
  EXPECT_TRUE(p.report(0x1000, {0x11, 0x80, 0x01, 0x02, 0x03}, 0x11, t0));
  EXPECT_EQ(sent.back().data[2], 0x00);
  EXPECT_EQ(od.get<std::uint8_t>(0x1001, 0), 0x00u);
  EXPECT_EQ(p.active_count(), 0u);
  EXPECT_FALSE(p.active(0x1000));
  p.raise(0x8130, 0x10, t0);
  EXPECT_TRUE(p.report(0x3120, {0x03, 0x81, 0x00, 0x81, 0x00}, 0x03, t0));
  EXPECT_EQ(sent.back().data[2], 0x11) << "the producer's own 1001h";
  EXPECT_EQ(od.get<std::uint8_t>(0x1001, 0), 0x11u);
  EXPECT_EQ(p.active_count(), 1u);
  EXPECT_FALSE(p.active(0x3120));
  // A reported code is not active: clearing it is refused.
  EXPECT_FALSE(p.clear(0x3120, t0));
  p.clear(0x8130, t0);
  EXPECT_EQ(get_u16(sent.back().data.data()), 0x0000) << "the last active error's reset";
}

// 1014h bit 31: nothing goes out (report returns false), 1003h still records it.
TEST_F(EmcyFixture, ReportSilencedByCobIdBit31) {
  EmcyProducer p(od, sink(), NodeId{0x20});
  ASSERT_EQ(od.write(0x1014, 0, encode<std::uint32_t>(0x800000A0)), SdoAbortCode::None);
  EXPECT_FALSE(p.report(0x1000, {0x11, 0, 0, 0, 0}, 0x11, t0));
  EXPECT_TRUE(sent.empty());
  EXPECT_EQ(od.get<std::uint32_t>(0x1003, 1), 0x00111000u);
  EXPECT_EQ(p.dropped(), 0u) << "not a queue overflow";
}

// A full inhibit queue drops the report and counts it.
TEST_F(EmcyFixture, ReportIntoAFullQueueIsDroppedAndCounted) {
  EmcyProducer p(od, sink(), NodeId{0x20}, {.inhibit_time = 10, .queue_limit = 2});
  EXPECT_TRUE(p.report(0x1000, {}, 1, t0));   // sent
  EXPECT_TRUE(p.report(0x2000, {}, 2, t0));   // queued
  EXPECT_TRUE(p.raise(0x3000, 0, t0));        // queued
  EXPECT_FALSE(p.report(0x4000, {}, 4, t0));  // no room
  EXPECT_EQ(p.dropped(), 1u);
  p.advance(t0 + 1ms);
  p.advance(t0 + 2ms);
  p.advance(t0 + 3ms);
  ASSERT_EQ(sent.size(), 3u);
  EXPECT_EQ(get_u16(sent[1].data.data()), 0x2000);
  EXPECT_EQ(get_u16(sent[2].data.data()), 0x3000);
}

// A full queue: a relayed EMCY (a gateway's remote EMCY) is dropped; the device's own EMCY takes
// the place of the oldest relayed one, so another node's flood never drops it.
TEST_F(EmcyFixture, OwnEmcysTakeThePlaceOfRelayedOnesInAFullQueue) {
  EmcyProducer p(od, sink(), NodeId{0x20}, {.inhibit_time = 10, .queue_limit = 2});
  EXPECT_TRUE(p.report(0x8140, {0x11}, 0x11, t0, true));   // sent
  EXPECT_TRUE(p.report(0x8140, {0x12}, 0x12, t0, true));   // queued
  EXPECT_TRUE(p.report(0x8140, {0x13}, 0x13, t0, true));   // queued: full
  EXPECT_FALSE(p.report(0x8140, {0x14}, 0x14, t0, true));  // relayed into a full queue: dropped
  EXPECT_TRUE(p.raise(0x7000, 0, {0x03}, t0, 0x03));       // own: replaces the relayed 12h one
  EXPECT_EQ(p.dropped(), 2u);
  for (int ms = 1; ms <= 3; ++ms) p.advance(t0 + std::chrono::milliseconds(ms));
  ASSERT_EQ(sent.size(), 3u);
  EXPECT_EQ(sent[1].data[3], 0x13);
  EXPECT_EQ(get_u16(sent[2].data.data()), 0x7000);
  // Own ones fill the queue: then an own one is dropped too (the queue limit holds).
  EXPECT_TRUE(p.raise(0x1000, 0, t0 + 3ms));  // sent
  EXPECT_TRUE(p.raise(0x2000, 0, t0 + 3ms));  // queued behind the inhibit time
  EXPECT_TRUE(p.raise(0x3000, 0, t0 + 3ms));  // queued: full
  EXPECT_TRUE(p.raise(0x4000, 0, t0 + 3ms));  // active, but the queue is full of own EMCYs
  EXPECT_EQ(p.dropped(), 3u);
  EXPECT_EQ(sent.size(), 4u);
}

// Consumer: Novotechnik §9.1 "0x5051 1 1 0 Position overflow error" from node 1.
TEST_F(EmcyFixture, ConsumerReportsNodeCodeRegisterAndField) {
  std::vector<EmcyMessage> got;
  EmcyConsumer c(od, [&](const EmcyMessage& m, TimePoint) { got.push_back(m); });
  EXPECT_EQ(od.get<std::uint32_t>(0x1028, 1), 0x81u);
  EXPECT_EQ(od.get<std::uint32_t>(0x1028, 127), 0xFFu);
  EXPECT_TRUE(c.on_frame(CanFrame(0x081, {0x51, 0x50, 0x01, 0x01, 0, 0, 0, 0}), t0));
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].node, NodeId{1});
  EXPECT_EQ(got[0].code, 0x5051);
  EXPECT_EQ(got[0].error_register, 0x01);
  EXPECT_EQ(got[0].msef, (EmcyManufacturerField{1, 0, 0, 0, 0}));
  EXPECT_FALSE(c.on_frame(CanFrame(0x080, {}), t0)) << "SYNC, not an EMCY";
  EXPECT_FALSE(c.on_frame(CanFrame(0x181, {1}), t0));
  // Disable node 1, move node 2 to another COB-ID.
  ASSERT_EQ(od.write(0x1028, 1, encode<std::uint32_t>(0x80000081)), SdoAbortCode::None);
  ASSERT_EQ(od.write(0x1028, 2, encode<std::uint32_t>(0x3F0)), SdoAbortCode::None);
  EXPECT_FALSE(c.on_frame(CanFrame(0x081, {0, 0x10, 1, 0, 0, 0, 0, 0}), t0));
  EXPECT_FALSE(c.on_frame(CanFrame(0x082, {0, 0x10, 1, 0, 0, 0, 0, 0}), t0));
  EXPECT_TRUE(c.on_frame(CanFrame(0x3F0, {0, 0x10, 1, 0, 0, 0, 0, 0}), t0));
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[1].node, NodeId{2});
  EXPECT_EQ(got[1].code, 0x1000);
}

TEST_F(EmcyFixture, ProducerToConsumerRoundTrip) {
  std::vector<EmcyMessage> got;
  EmcyConsumer c(od, [&](const EmcyMessage& m, TimePoint) { got.push_back(m); });
  ObjectDictionary dev;
  EmcyProducer p(
      dev, [&](const CanFrame& f) { c.on_frame(f, t0); }, NodeId{0x2A});
  p.raise(0xFF00, 0x80, {9, 8, 7, 6, 5}, t0);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].node, NodeId{0x2A});
  EXPECT_EQ(got[0].code, 0xFF00);
  EXPECT_EQ(got[0].error_register, 0x81);
  EXPECT_EQ(got[0].msef, (EmcyManufacturerField{9, 8, 7, 6, 5}));
}

}  // namespace
}  // namespace oegw::canopen
