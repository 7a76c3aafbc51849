// The CANopen manager's SDO side (canopen/master.hpp): which client takes an answer, what its
// next deadline is, and a client added while the master advances its clients. CiA 301 §7.2.4
// (SDO), §7.3.5 (the default COB-IDs 580h/600h + node-ID).
#include "canopen/master.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <vector>

namespace oegw::canopen {
namespace {

using namespace std::chrono_literals;

const TimePoint t0{Duration{10'000'000}};

struct Fixture {
  ObjectDictionary od;
  std::vector<CanFrame> sent;
  std::vector<CanFrame> other;
  Master master{od, [this](const CanFrame& f) { sent.push_back(f); }, MasterConfig{.sdo_timeout = 100ms}};
  Fixture() {
    master.on_other_frame = [this](const CanFrame& f, TimePoint) { other.push_back(f); };
  }
  // An expedited upload answer (CiA 301 §7.2.4.3.5) of 1000h:00 = 4 bytes.
  static CanFrame answer(std::uint32_t cob) { return CanFrame(cob, {0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4}); }
};

TEST(MasterSdo, AnAnswerGoesToTheClientOfItsCobIdAlsoAfterTheClientWasMoved) {
  Fixture f;
  std::vector<int> done;
  for (const std::uint8_t node : {0x05, 0x20, 0x40})
    f.master.sdo(NodeId{node}).upload(0x1000, 0, [&done, node](SdoAbortCode code, std::vector<std::uint8_t>) {
      done.push_back(code == SdoAbortCode::None ? node : -node);
    });
  f.master.advance(t0);
  ASSERT_EQ(f.sent.size(), 3u) << "each client's request on 600h + its node-ID";
  EXPECT_TRUE(f.master.on_frame(Fixture::answer(0x5A0), t0));
  EXPECT_EQ(done, std::vector<int>{0x20});
  // Node 40h's client moved to 5F0h/670h: its request is aborted (no frame), the answer on
  // its old COB-ID is nobody's, the one on its new COB-ID its own.
  f.master.sdo(NodeId{0x40}).set_cob_ids(CobId{0x670}, CobId{0x5F0});
  EXPECT_EQ(done.back(), -0x40);
  f.master.sdo(NodeId{0x40}).upload(0x1000, 0, [&done](SdoAbortCode code, std::vector<std::uint8_t>) {
    done.push_back(code == SdoAbortCode::None ? 0x41 : -0x41);
  });
  f.master.advance(t0 + 1ms);
  EXPECT_EQ(f.sent.back().id, 0x670u);
  EXPECT_FALSE(f.master.on_frame(Fixture::answer(0x5C0), t0 + 2ms));
  ASSERT_EQ(f.other.size(), 1u) << "an answer on a COB-ID no client has is another frame";
  EXPECT_EQ(f.other[0].id, 0x5C0u);
  EXPECT_TRUE(f.master.on_frame(Fixture::answer(0x5F0), t0 + 2ms));
  EXPECT_EQ(done.back(), 0x41);
  EXPECT_TRUE(f.master.on_frame(Fixture::answer(0x585), t0 + 3ms));
  EXPECT_EQ(done.back(), 0x05);
  // An extended frame with the same 11 bits is not the client's.
  CanFrame ext = Fixture::answer(0x585);
  ext.extended = true;
  EXPECT_FALSE(f.master.on_frame(ext, t0 + 4ms));
}

// The master skips its clients for a frame on a COB-ID none of them answers on (a PDO); which
// COB-IDs they answer on it learns again whenever a client is made or moved, also after frames
// were already sorted — and an extended response COB-ID is heard too (CiA 301 §7.2.4.1: any
// COB-ID the SDO parameters 1280h.. name, 29-bit included).
TEST(MasterSdo, AClientMadeOrMovedAfterFramesWereSortedGetsItsAnswers) {
  Fixture f;
  std::vector<int> done;
  const auto ask = [&](std::uint8_t node, int tag) {
    f.master.sdo(NodeId{node}).upload(0x1000, 0, [&done, tag](SdoAbortCode code, std::vector<std::uint8_t>) {
      done.push_back(code == SdoAbortCode::None ? tag : -tag);
    });
  };
  ask(0x05, 5);
  f.master.advance(t0);
  EXPECT_FALSE(f.master.on_frame(CanFrame(0x185, {1, 2}), t0));  // a PDO: nobody's answer
  EXPECT_TRUE(f.master.on_frame(Fixture::answer(0x585), t0));
  EXPECT_EQ(done, std::vector<int>{5});
  ask(0x06, 6);  // a client made after the first frames
  f.master.advance(t0 + 1ms);
  EXPECT_TRUE(f.master.on_frame(Fixture::answer(0x586), t0 + 1ms));
  EXPECT_EQ(done.back(), 6);
  // Node 7's client answers on an extended COB-ID, set after frames were sorted.
  (void)f.master.sdo(NodeId{0x07});
  EXPECT_FALSE(f.master.on_frame(CanFrame(0x186, {1}), t0 + 2ms));
  f.master.sdo(NodeId{0x07}).set_cob_ids(CobId{0x607}, CobId{CobId::kExtendedBit | 0x1234567u});
  ask(0x07, 7);
  f.master.advance(t0 + 3ms);
  CanFrame ext = Fixture::answer(0x1234567);
  ext.extended = true;
  CanFrame other_ext = Fixture::answer(0x1234568);
  other_ext.extended = true;
  EXPECT_FALSE(f.master.on_frame(other_ext, t0 + 3ms));
  EXPECT_FALSE(f.master.on_frame(Fixture::answer(0x587), t0 + 3ms)) << "its old COB-ID is nobody's";
  EXPECT_TRUE(f.master.on_frame(ext, t0 + 3ms));
  EXPECT_EQ(done.back(), 7);
  ASSERT_EQ(f.other.size(), 4u);  // 185h, 186h, the other extended frame, 587h
  EXPECT_TRUE(f.other[2].extended);
  EXPECT_EQ(f.other[2].id, 0x1234568u);
}

// CanFrame's fields are public: a frame built field by field with an identifier past 7FFh and
// no `extended` flag is nobody's answer, and is not read as an index past the 11-bit table.
TEST(MasterSdo, AStandardFrameWithAnIdentifierPast7FFhIsNobodysAnswer) {
  Fixture f;
  (void)f.master.sdo(NodeId{0x05});
  CanFrame odd = Fixture::answer(0x585);
  odd.id = 0x1585;
  EXPECT_FALSE(f.master.on_frame(odd, t0));
  ASSERT_EQ(f.other.size(), 1u);
  EXPECT_EQ(f.other[0].id, 0x1585u);
}

TEST(MasterSdo, TheNextDeadlineIsTheSoonestOfTheClientsWithWorkOnly) {
  Fixture f;
  for (const std::uint8_t node : {0x01, 0x02, 0x03}) (void)f.master.sdo(NodeId{node});
  f.master.advance(t0);
  EXPECT_EQ(f.master.next_deadline(), std::nullopt) << "idle clients: no deadline";
  f.master.sdo(NodeId{0x02}).upload(0x1000, 0, [](SdoAbortCode, std::vector<std::uint8_t>) {});
  EXPECT_EQ(f.master.next_deadline(), t0) << "a queued request is due now (its start)";
  f.master.advance(t0 + 5ms);
  EXPECT_EQ(f.master.next_deadline(), t0 + 5ms + 100ms) << "in flight: its time-out";
  f.master.advance(t0 + 105ms);
  EXPECT_EQ(f.master.next_deadline(), std::nullopt) << "timed out: idle again";
}

// next_deadline() asks only the clients with work (SdoWorkList), which advance() prunes: a
// client dropped as idle is asked again once another client's answer queues a request to it.
TEST(MasterSdo, AClientDroppedAsIdleIsAskedAgainWithItsNextRequest) {
  Fixture f;
  SdoClient& a = f.master.sdo(NodeId{0x01});
  SdoClient& b = f.master.sdo(NodeId{0x02});
  int a_answers = 0;
  const auto count_a = [&a_answers](SdoAbortCode code, std::vector<std::uint8_t>) {
    if (code == SdoAbortCode::None) ++a_answers;
  };
  a.upload(0x1000, 0, count_a);
  f.master.advance(t0);
  EXPECT_EQ(f.master.next_deadline(), t0 + 100ms);
  EXPECT_TRUE(f.master.on_frame(Fixture::answer(0x581), t0 + 1ms));
  EXPECT_EQ(a_answers, 1);
  f.master.advance(t0 + 2ms);  // a is idle: dropped from the clients asked
  EXPECT_EQ(f.master.next_deadline(), std::nullopt);
  b.upload(0x1000, 0, [&](SdoAbortCode, std::vector<std::uint8_t>) { a.upload(0x1000, 0, count_a); });
  f.master.advance(t0 + 3ms);
  EXPECT_EQ(f.master.next_deadline(), t0 + 103ms) << "b's request in flight";
  EXPECT_TRUE(f.master.on_frame(Fixture::answer(0x582), t0 + 4ms));
  const auto due = f.master.next_deadline();
  ASSERT_TRUE(due) << "a's request, queued from b's callback, has a deadline";
  EXPECT_LE(*due, t0 + 4ms) << "due now";
  f.master.advance(t0 + 5ms);
  EXPECT_EQ(f.sent.back().id, 0x601u);
  EXPECT_EQ(f.master.next_deadline(), t0 + 105ms);
}

// A callback run from advance() (a time-out) may make a client for another node: every client
// that was there is still advanced in that pass, none twice.
TEST(MasterSdo, AClientMadeByACallbackDuringAdvanceSkipsNoOtherClient) {
  Fixture f;
  std::vector<std::uint8_t> timed_out;
  for (const std::uint8_t node : {0x10, 0x20, 0x30, 0x40}) {
    f.master.sdo(NodeId{node}).upload(0x1000, 0, [&f, &timed_out, node](SdoAbortCode code, std::vector<std::uint8_t>) {
      if (code != SdoAbortCode::Timeout) return;
      timed_out.push_back(node);
      // Nodes 15h and 16h sort before those still to be advanced.
      if (node == 0x10)
        for (const std::uint8_t n : {0x15, 0x16}) (void)f.master.sdo(NodeId{n});
    });
  }
  f.master.advance(t0);
  ASSERT_EQ(f.sent.size(), 4u);
  f.master.advance(t0 + 100ms);
  EXPECT_EQ(timed_out, (std::vector<std::uint8_t>{0x10, 0x20, 0x30, 0x40}));
  EXPECT_EQ(f.master.next_deadline(), std::nullopt);
}

// ... and a client made before the one whose callback made it does not have that one advanced
// again in the same pass: a request it queued then (a 0 ms time-out) starts in this pass and
// times out in the next, not at once.
TEST(MasterSdo, AClientMadeBeforeTheOneAdvancedDoesNotHaveItAdvancedTwice) {
  Fixture f;
  std::vector<SdoAbortCode> second;
  SdoClient& c40 = f.master.sdo(NodeId{0x40});
  c40.upload(0x1000, 0, [&](SdoAbortCode code, std::vector<std::uint8_t>) {
    if (code != SdoAbortCode::Timeout) return;
    (void)f.master.sdo(NodeId{0x15});  // sorts before 40h: clients_ is rebuilt, 40h moves
    c40.upload_within(0x1000, 0, 0ms, [&](SdoAbortCode c2, std::vector<std::uint8_t>) { second.push_back(c2); });
  });
  f.master.advance(t0);
  f.master.advance(t0 + 100ms);
  EXPECT_TRUE(second.empty()) << "40h advanced once in this pass: its new request started, not timed out";
  EXPECT_EQ(f.master.next_deadline(), t0 + 100ms);
  f.master.advance(t0 + 100ms);
  EXPECT_EQ(second, std::vector<SdoAbortCode>{SdoAbortCode::Timeout});
}

}  // namespace
}  // namespace oegw::canopen
