// SdoClient against a scripted server. Server node-ID 5: requests on 605h, responses on 585h.
#include "canopen/301/sdo_client.hpp"

#include <gtest/gtest.h>

#include "canopen/301/crc16.hpp"
#include "sdo_test_support.hpp"

using namespace oegw::canopen;
using namespace sdo_test;
using namespace std::chrono_literals;

namespace {

constexpr std::uint32_t kReq = 0x605;
constexpr std::uint32_t kResp = 0x585;

struct Result {
  SdoAbortCode code;
  std::vector<std::uint8_t> data;
  friend bool operator==(const Result&, const Result&) = default;
};

class SdoClientTest : public ::testing::Test {
 protected:
  std::vector<CanFrame> out;
  std::vector<Result> results;
  TimePoint t{std::chrono::seconds(50)};
  SdoClientConfig cfg = SdoClientConfig::for_node(NodeId{5});
  std::optional<SdoClient> client;

  void SetUp() override { make(); }
  void make() {
    client.emplace([this](const CanFrame& f) { out.push_back(f); }, cfg);
  }
  SdoClient::Callback record() {
    return [this](SdoAbortCode c, std::vector<std::uint8_t> d) { results.push_back({c, std::move(d)}); };
  }
  std::vector<CanFrame> go() {
    out.clear();
    client->advance(t);
    return out;
  }
  // Delivers a server frame and returns the client's answer.
  std::vector<CanFrame> srv(std::initializer_list<std::uint8_t> bytes) {
    out.clear();
    EXPECT_TRUE(client->on_frame(CanFrame(kResp, bytes), t));
    return out;
  }
  std::vector<CanFrame> srv(const CanFrame& f) {
    out.clear();
    client->on_frame(f, t);
    return out;
  }
  static std::vector<CanFrame> req(std::initializer_list<std::uint8_t> bytes) { return {CanFrame(kReq, bytes)}; }
  static std::vector<CanFrame> none() { return {}; }
  static std::vector<CanFrame> aborted(std::uint16_t index, std::uint8_t sub, SdoAbortCode code) {
    return {abort_frame(kReq, index, sub, code)};
  }
  static Result ok(std::vector<std::uint8_t> d = {}) { return {SdoAbortCode::None, std::move(d)}; }
  static Result failed(SdoAbortCode c) { return {c, {}}; }
};

TEST_F(SdoClientTest, DefaultCobIdsForNode) {
  EXPECT_EQ(cfg.request_cob.can_id(), 0x605u);
  EXPECT_EQ(cfg.response_cob.can_id(), 0x585u);
}

TEST_F(SdoClientTest, RequestStartsOnAdvanceAndNextDeadlineSaysSo) {
  EXPECT_EQ(client->next_deadline(), std::nullopt);
  client->upload(0x1000, 0, record());
  EXPECT_TRUE(out.empty());  // queued, nothing sent yet
  ASSERT_TRUE(client->next_deadline().has_value());
  EXPECT_LE(*client->next_deadline(), t);  // due now
  EXPECT_EQ(go(), req({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(client->next_deadline(), t + 1s);
  EXPECT_TRUE(client->busy());
}

// The owner's work list (SdoWorkList): a client is on it from its request until it is found
// idle, once however many requests it has, and a client made busy before it was given the list
// joins at once.
TEST_F(SdoClientTest, AClientIsOnTheWorkListFromItsRequestUntilFoundIdle) {
  SdoWorkList list;
  client->upload(0x1000, 0, record());
  client->set_work_list(&list);
  EXPECT_EQ(list.clients(), std::vector<SdoClient*>{&*client}) << "queued before it had the list";
  client->download(0x2000, 1, {1}, record());
  list.prune();
  EXPECT_EQ(list.clients().size(), 1u) << "two requests queued: listed once, kept";
  EXPECT_EQ(go(), req({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(srv({0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4}), req({0x2F, 0x00, 0x20, 0x01, 1, 0, 0, 0}));
  list.prune();
  EXPECT_EQ(list.clients().size(), 1u) << "its second request in flight";
  EXPECT_EQ(srv({0x60, 0x00, 0x20, 0x01, 0, 0, 0, 0}), none());
  EXPECT_TRUE(client->idle());
  list.prune();
  EXPECT_TRUE(list.clients().empty()) << "idle: dropped";
  client->upload(0x1000, 0, record());
  EXPECT_EQ(list.clients(), std::vector<SdoClient*>{&*client}) << "its next request: on the list again";
  EXPECT_EQ(results.size(), 2u);
  SdoWorkList other;
  client->set_work_list(&other);
  EXPECT_TRUE(list.clients().empty()) << "moved: it left the first list";
  EXPECT_EQ(other.clients(), std::vector<SdoClient*>{&*client}) << "with its request queued";
  client->set_work_list(nullptr);
  EXPECT_TRUE(other.clients().empty());
}

// SDO pacing (canopen/301/sdo_pacer.hpp). The gap from the bit rate, worked out by hand: an
// 8-byte standard data frame is 98 stuffable bits (SOF, 11-bit ID, RTR, IDE, r0, DLC 4, 64
// data bits, CRC 15), at worst one stuff bit after every 4 of them but the first: 24; then CRC
// delimiter, ACK slot and delimiter, EOF 7 and the intermission 3: 135 bits. A request and its
// answer: 270 bits.
TEST(SdoPacer, TheGapKeepsRequestAndAnswerWithinTheShare) {
  EXPECT_EQ(SdoPacer::gap_for(250'000, 0.5), Duration{2160});  // 270 bits at 4 us, twice
  EXPECT_EQ(SdoPacer::gap_for(1'000'000, 1.0), Duration{270});
  EXPECT_EQ(SdoPacer::gap_for(125'000, 0.85), Duration{2542});  // 2160 / 0.85, rounded up
  EXPECT_EQ(SdoPacer::gap_for(250'000, 0.0), Duration{0});
  EXPECT_EQ(SdoPacer::gap_for(0, 0.5), Duration{0});
  EXPECT_FALSE(SdoPacer{}.paced());
}

// delayed_starts counts the requests that waited for the gap, each once however often it was
// refused: two clients refused during one gap are two; a request that found the slot free is
// none, and so is one whose waiting predecessor was cancelled.
TEST(SdoPacer, CountsEachRequestThatWaitedForTheGapOnce) {
  const TimePoint t0{std::chrono::seconds(7)};
  SdoPacer pacer{2ms};
  std::vector<CanFrame> out;
  SdoClient a([&](const CanFrame& f) { out.push_back(f); }, NodeId{5});
  SdoClient b([&](const CanFrame& f) { out.push_back(f); }, NodeId{6});
  SdoClient c([&](const CanFrame& f) { out.push_back(f); }, NodeId{7});
  for (SdoClient* x : {&a, &b, &c}) x->set_pacer(&pacer);
  const auto ignore = [](SdoAbortCode, std::vector<std::uint8_t>) {};
  a.upload(0x1000, 0, ignore);
  a.advance(t0);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(pacer.delayed_starts(), 0u) << "the slot was free";
  b.upload(0x1000, 0, ignore);
  c.upload(0x1000, 0, ignore);
  for (const auto t : {t0 + 500us, t0 + 1ms, t0 + 1999us}) {
    b.advance(t);
    c.advance(t);
  }
  EXPECT_EQ(out.size(), 1u);
  EXPECT_EQ(pacer.delayed_starts(), 0u) << "nothing started yet";
  b.advance(t0 + 2ms);
  c.advance(t0 + 2ms);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(pacer.delayed_starts(), 1u) << "b waited, refused four times: one";
  c.advance(t0 + 4ms);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(pacer.delayed_starts(), 2u) << "c waited too";
  // a's next request is refused, then withdrawn; the one after it, an hour later, did not wait.
  ASSERT_TRUE(a.on_frame(CanFrame(0x585, {0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x0F, 0x00}), t0 + 5ms));
  const auto ticket = a.upload(0x1018, 1, ignore);
  a.advance(t0 + 5ms);
  EXPECT_EQ(out.size(), 3u) << "refused: c took the slot at 4 ms";
  EXPECT_TRUE(a.cancel(ticket, SdoAbortCode::GeneralError));
  a.upload(0x1018, 2, ignore);
  a.advance(t0 + std::chrono::hours(1));
  ASSERT_EQ(out.size(), 4u);
  EXPECT_EQ(pacer.delayed_starts(), 2u) << "the withdrawn request's wait is not the new one's";
  SdoPacer none;
  EXPECT_TRUE(none.try_start(t0, true));
  EXPECT_TRUE(none.try_start(t0));
  EXPECT_EQ(none.delayed_starts(), 1u) << "counted as the caller says";
}

// Two clients on one pacer (a master's clients toward two nodes), their servers answering at
// once: the second request starts one gap after the first, not when the first is answered, and
// next_deadline() names that time; a segment within a transfer is not held back.
TEST(SdoPacer, ClientsSharingAPacerStartTheirRequestsAGapApart) {
  const TimePoint t0{std::chrono::seconds(50)};
  SdoPacer pacer{2ms};
  std::vector<CanFrame> out;
  SdoClient a([&](const CanFrame& f) { out.push_back(f); }, NodeId{5});
  SdoClient b([&](const CanFrame& f) { out.push_back(f); }, NodeId{6});
  a.set_pacer(&pacer);
  b.set_pacer(&pacer);
  int done = 0;
  const auto count = [&done](SdoAbortCode c, std::vector<std::uint8_t>) { done += c == SdoAbortCode::None; };
  a.upload(0x1000, 0, count);
  a.upload(0x1018, 1, count);
  b.upload(0x1000, 0, count);
  a.advance(t0);
  b.advance(t0);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].id, 0x605u);
  EXPECT_EQ(b.next_deadline(), t0 + 2ms) << "b's request waits for the pacer's next slot";
  // a's answer at once: its next request is paced too.
  ASSERT_TRUE(a.on_frame(CanFrame(0x585, {0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x0F, 0x00}), t0 + 300us));
  EXPECT_EQ(out.size(), 1u);
  EXPECT_EQ(a.next_deadline(), t0 + 2ms);
  b.advance(t0 + 2ms);
  a.advance(t0 + 2ms);  // b took the slot: a waits another gap
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[1].id, 0x606u);
  EXPECT_EQ(a.next_deadline(), t0 + 4ms);
  a.advance(t0 + 4ms);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out[2].id, 0x605u);
  EXPECT_EQ(out[2].data[1], 0x18);
  EXPECT_EQ(done, 1);
}

// Novotechnik §7.2: 0x40 read command answered with 0x43 (4 bytes).
TEST_F(SdoClientTest, ExpeditedUpload) {
  client->upload(0x1000, 0, record());
  go();
  EXPECT_EQ(srv({0x43, 0x00, 0x10, 0x00, 0x96, 0x01, 0x08, 0x00}), none());
  EXPECT_EQ(results, (std::vector<Result>{ok({0x96, 0x01, 0x08, 0x00})}));
  EXPECT_FALSE(client->busy());
  EXPECT_EQ(client->next_deadline(), std::nullopt);
}

TEST_F(SdoClientTest, ExpeditedUploadSizes) {
  client->upload(0x2000, 0, record());
  client->upload(0x2001, 0, record());
  client->upload(0x2002, 0, record());
  go();
  // Each response immediately starts the next queued request.
  EXPECT_EQ(srv({0x4F, 0x00, 0x20, 0x00, 0x11, 0xFF, 0xFF, 0xFF}), req({0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(srv({0x4B, 0x01, 0x20, 0x00, 0x11, 0x22, 0xFF, 0xFF}), req({0x40, 0x02, 0x20, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(srv({0x42, 0x02, 0x20, 0x00, 1, 2, 3, 4}), none());  // size not indicated: 4 bytes
  EXPECT_EQ(results, (std::vector<Result>{ok({0x11}), ok({0x11, 0x22}), ok({1, 2, 3, 4})}));
}

// Novotechnik §7.1: "store all parameters" is 23 10 10 01 73 61 76 65, confirmed by 60 10 10 01.
TEST_F(SdoClientTest, ExpeditedDownloadNovotechnikStore) {
  client->download(0x1010, 1, encode<std::uint32_t>(kSaveSignature), record());
  EXPECT_EQ(go(), req({0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65}));
  EXPECT_EQ(srv({0x60, 0x10, 0x10, 0x01, 0, 0, 0, 0}), none());
  EXPECT_EQ(results, (std::vector<Result>{ok()}));
}

// ExpeditedUnsized: e = 1, s = 0 (CiA 301 §7.2.4.3.3), as the MCB-402 document writes its SDOs
// ("603 22 01 18 05 aa bb 00 00"); other sizes go as Auto would send them.
TEST_F(SdoClientTest, ExpeditedDownloadWithoutSize) {
  client->download(0x1801, 5, {0x14, 0x00, 0x00, 0x00}, record(), SdoTransfer::ExpeditedUnsized);
  EXPECT_EQ(go(), req({0x22, 0x01, 0x18, 0x05, 0x14, 0x00, 0x00, 0x00}));
  client->download(0x2001, 0, {1, 2}, record(), SdoTransfer::ExpeditedUnsized);
  EXPECT_EQ(srv({0x60, 0x01, 0x18, 0x05, 0, 0, 0, 0}), req({0x2B, 0x01, 0x20, 0x00, 1, 2, 0, 0}));
  EXPECT_EQ(srv({0x60, 0x01, 0x20, 0x00, 0, 0, 0, 0}), none());
  EXPECT_EQ(results, (std::vector<Result>{ok(), ok()}));
}

TEST_F(SdoClientTest, ExpeditedDownloadCommandBytes) {
  client->download(0x2000, 0, {0x40}, record());
  EXPECT_EQ(go(), req({0x2F, 0x00, 0x20, 0x00, 0x40, 0, 0, 0}));  // Novotechnik §7.1 node-ID example
  client->download(0x2001, 0, {1, 2}, record());
  EXPECT_EQ(srv({0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0}), req({0x2B, 0x01, 0x20, 0x00, 1, 2, 0, 0}));
  client->download(0x2002, 0, {1, 2, 3}, record());
  EXPECT_EQ(srv({0x60, 0x01, 0x20, 0x00, 0, 0, 0, 0}), req({0x27, 0x02, 0x20, 0x00, 1, 2, 3, 0}));
  EXPECT_EQ(srv({0x60, 0x02, 0x20, 0x00, 0, 0, 0, 0}), none());
  EXPECT_EQ(results, (std::vector<Result>{ok(), ok(), ok()}));
}

TEST_F(SdoClientTest, SegmentedDownload) {
  client->download(0x2100, 0, pattern(10), record());
  const auto d = pattern(10);
  EXPECT_EQ(go(), req({0x21, 0x00, 0x21, 0x00, 10, 0, 0, 0}));
  EXPECT_EQ(srv({0x60, 0x00, 0x21, 0x00, 0, 0, 0, 0}), req({0x00, d[0], d[1], d[2], d[3], d[4], d[5], d[6]}));
  EXPECT_EQ(srv({0x20, 0, 0, 0, 0, 0, 0, 0}), req({0x19, d[7], d[8], d[9], 0, 0, 0, 0}));  // t=1 n=4 c=1
  EXPECT_TRUE(results.empty());
  EXPECT_EQ(srv({0x30, 0, 0, 0, 0, 0, 0, 0}), none());
  EXPECT_EQ(results, (std::vector<Result>{ok()}));
}

TEST_F(SdoClientTest, EmptyAndForcedSegmentedDownloads) {
  client->download(0x2100, 0, {}, record());
  client->download(0x2001, 0, {1, 2}, record(), SdoTransfer::Segmented);
  EXPECT_EQ(go(), req({0x21, 0x00, 0x21, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(srv({0x60, 0x00, 0x21, 0x00, 0, 0, 0, 0}), req({0x0F, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(srv({0x20, 0, 0, 0, 0, 0, 0, 0}), req({0x21, 0x01, 0x20, 0x00, 2, 0, 0, 0}));
  EXPECT_EQ(srv({0x60, 0x01, 0x20, 0x00, 0, 0, 0, 0}), req({0x0B, 1, 2, 0, 0, 0, 0, 0}));
  EXPECT_EQ(srv({0x20, 0, 0, 0, 0, 0, 0, 0}), none());
  EXPECT_EQ(results, (std::vector<Result>{ok(), ok()}));
}

TEST_F(SdoClientTest, SegmentedDownloadToggleError) {
  client->download(0x2100, 0, pattern(10), record());
  go();
  srv({0x60, 0x00, 0x21, 0x00, 0, 0, 0, 0});
  EXPECT_EQ(srv({0x30, 0, 0, 0, 0, 0, 0, 0}), aborted(0x2100, 0, SdoAbortCode::ToggleBitNotAlternated));
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::ToggleBitNotAlternated)}));
}

TEST_F(SdoClientTest, SegmentedUpload) {
  client->upload(0x1008, 0, record());
  go();
  EXPECT_EQ(srv({0x41, 0x08, 0x10, 0x00, 9, 0, 0, 0}), req({0x60, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(srv({0x00, 'O', 'E', 'G', 'W', ' ', 'd', 'e'}), req({0x70, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(srv({0x1B, 'v', '1', 0, 0, 0, 0, 0}), none());  // t=1 n=5 c=1
  EXPECT_EQ(results, (std::vector<Result>{ok(bytes_of("OEGW dev1"))}));
}

TEST_F(SdoClientTest, SegmentedUploadErrors) {
  // Toggle not alternated by the server.
  client->upload(0x1008, 0, record());
  go();
  srv({0x41, 0x08, 0x10, 0x00, 20, 0, 0, 0});
  EXPECT_EQ(srv({0x10, 1, 2, 3, 4, 5, 6, 7}), aborted(0x1008, 0, SdoAbortCode::ToggleBitNotAlternated));
  // Last segment arrives early: less data than announced.
  client->upload(0x1008, 0, record());
  go();
  srv({0x41, 0x08, 0x10, 0x00, 20, 0, 0, 0});
  EXPECT_EQ(srv({0x01, 1, 2, 3, 4, 5, 6, 7}), aborted(0x1008, 0, SdoAbortCode::LengthMismatch));
  // More data than announced.
  client->upload(0x1008, 0, record());
  go();
  srv({0x41, 0x08, 0x10, 0x00, 3, 0, 0, 0});
  EXPECT_EQ(srv({0x00, 1, 2, 3, 4, 5, 6, 7}), aborted(0x1008, 0, SdoAbortCode::LengthMismatch));
  // Announced size beyond max_upload_size.
  client->upload(0x1008, 0, record());
  go();
  EXPECT_EQ(srv({0x41, 0x08, 0x10, 0x00, 0, 0, 0x20, 0}), aborted(0x1008, 0, SdoAbortCode::OutOfMemory));
  EXPECT_EQ(results,
            (std::vector<Result>{failed(SdoAbortCode::ToggleBitNotAlternated), failed(SdoAbortCode::LengthMismatch),
                                 failed(SdoAbortCode::LengthMismatch), failed(SdoAbortCode::OutOfMemory)}));
}

TEST_F(SdoClientTest, ServerAbortIsReportedAndNotAnswered) {
  client->download(0x1010, 1, encode<std::uint32_t>(0x6C6C696B), record());
  go();
  EXPECT_EQ(srv(abort_frame(kResp, 0x1010, 1, SdoAbortCode::CannotTransfer)), none());
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::CannotTransfer)}));
  EXPECT_FALSE(client->busy());
}

TEST_F(SdoClientTest, ServerAbortDuringSegmentedUpload) {
  client->upload(0x1008, 0, record());
  go();
  srv({0x41, 0x08, 0x10, 0x00, 20, 0, 0, 0});
  EXPECT_EQ(srv(abort_frame(kResp, 0x1008, 0, SdoAbortCode::Timeout)), none());
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::Timeout)}));
}

TEST_F(SdoClientTest, TimeoutAbortsReportsAndStartsTheNext) {
  client->upload(0x1000, 0, record());
  client->upload(0x1001, 0, record());
  go();
  out.clear();
  client->advance(t + 999ms);
  EXPECT_TRUE(out.empty());
  EXPECT_TRUE(results.empty());
  client->advance(t + 1s);
  EXPECT_EQ(out, (std::vector<CanFrame>{abort_frame(kReq, 0x1000, 0, SdoAbortCode::Timeout),
                                        CanFrame(kReq, {0x40, 0x01, 0x10, 0x00, 0, 0, 0, 0})}));
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::Timeout)}));
  EXPECT_EQ(client->next_deadline(), t + 2s);
}

// upload_within(): that request alone is awaited its own time-out; the next one the client's.
TEST_F(SdoClientTest, UploadWithinHasItsOwnTimeout) {
  client->upload_within(0x1000, 0, 100ms, record());
  client->upload(0x1001, 0, record());
  go();
  out.clear();
  client->advance(t + 99ms);
  EXPECT_TRUE(out.empty());
  client->advance(t + 100ms);
  EXPECT_EQ(out, (std::vector<CanFrame>{abort_frame(kReq, 0x1000, 0, SdoAbortCode::Timeout),
                                        CanFrame(kReq, {0x40, 0x01, 0x10, 0x00, 0, 0, 0, 0})}));
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::Timeout)}));
  EXPECT_EQ(client->next_deadline(), t + 100ms + 1s) << "the next request: SdoClientConfig::timeout";
}

TEST_F(SdoClientTest, EachServerFrameRearmsTheTimeout) {
  cfg.timeout = 100ms;
  make();
  client->upload(0x1008, 0, record());
  go();
  t += 90ms;
  srv({0x41, 0x08, 0x10, 0x00, 20, 0, 0, 0});
  EXPECT_EQ(client->next_deadline(), t + 100ms);
  out.clear();
  client->advance(t + 99ms);
  EXPECT_TRUE(out.empty());
  client->advance(t + 100ms);
  EXPECT_EQ(out, aborted(0x1008, 0, SdoAbortCode::Timeout));
}

TEST_F(SdoClientTest, OneTransferInFlightRequestsServedInOrder) {
  std::vector<int> order;
  client->download(0x2000, 0, {7}, [&](SdoAbortCode c, std::vector<std::uint8_t>) {
    EXPECT_EQ(c, SdoAbortCode::None);
    order.push_back(1);
  });
  client->upload(0x2001, 0, [&](SdoAbortCode, std::vector<std::uint8_t>) { order.push_back(2); });
  client->upload(0x2002, 0, [&](SdoAbortCode, std::vector<std::uint8_t>) { order.push_back(3); });
  EXPECT_EQ(client->queued(), 3u);
  EXPECT_EQ(go().size(), 1u);  // one initiate only
  EXPECT_EQ(client->queued(), 2u);
  out.clear();
  client->advance(t + 10ms);  // nothing else goes out while the first is in flight
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(srv({0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0}), req({0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0}));
  srv({0x4B, 0x01, 0x20, 0x00, 1, 2, 0, 0});
  srv({0x47, 0x02, 0x20, 0x00, 1, 2, 3, 0});
  EXPECT_EQ(order, (std::vector<int>{1, 2, 3}));
}

TEST_F(SdoClientTest, CallbackMayQueueTheNextRequest) {
  client->upload(0x2000, 0, [&](SdoAbortCode, std::vector<std::uint8_t> d) {
    client->download(0x2000, 0, {static_cast<std::uint8_t>(d.at(0) + 1)}, record());
  });
  go();
  EXPECT_EQ(srv({0x4F, 0x00, 0x20, 0x00, 0x41, 0, 0, 0}), req({0x2F, 0x00, 0x20, 0x00, 0x42, 0, 0, 0}));
}

TEST_F(SdoClientTest, ProtocolErrorsFromTheServer) {
  // Wrong command for the state.
  client->upload(0x1008, 0, record());
  go();
  EXPECT_EQ(srv({0x60, 0x08, 0x10, 0x00, 0, 0, 0, 0}), aborted(0x1008, 0, SdoAbortCode::UnknownCommandSpecifier));
  // A short frame.
  client->upload(0x1008, 0, record());
  go();
  EXPECT_EQ(srv({0x43, 0x08, 0x10, 0x00}), aborted(0x1008, 0, SdoAbortCode::UnknownCommandSpecifier));
  EXPECT_EQ(results.size(), 2u);
  EXPECT_EQ(results[1], failed(SdoAbortCode::UnknownCommandSpecifier));
}

// An answer naming another object while a request awaits its initiate answer is an earlier
// request's late answer (e.g. after its time-out): dropped and counted, the time-out not
// re-armed, and the request's own answer completes it — not one request off, not aborted.
TEST_F(SdoClientTest, AnAnswerForAnotherObjectIsStaleAndDropped) {
  cfg.timeout = 100ms;
  make();
  client->upload(0x1008, 0, record());
  go();
  t += 50ms;
  EXPECT_EQ(srv({0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x0F, 0x00}), none()) << "1000h's late answer";
  EXPECT_EQ(srv(abort_frame(kResp, 0x1001, 0, SdoAbortCode::Timeout)), none()) << "a late abort of 1001h";
  EXPECT_TRUE(results.empty());
  EXPECT_EQ(client->stale_answers(), 2u);
  EXPECT_EQ(client->next_deadline(), t - 50ms + 100ms) << "not re-armed by a stale answer";
  EXPECT_EQ(srv({0x4F, 0x08, 0x10, 0x00, 0x41, 0, 0, 0}), none());
  EXPECT_EQ(results, (std::vector<Result>{ok({0x41})}));
}

TEST_F(SdoClientTest, FramesWhileIdleOrOnOtherIdsAreIgnored) {
  EXPECT_EQ(srv({0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4}), none());
  EXPECT_FALSE(client->on_frame(CanFrame(0x586, {0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4}), t));
  EXPECT_FALSE(client->on_frame(CanFrame(kReq, {0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4}), t));
  EXPECT_TRUE(results.empty());
}

TEST_F(SdoClientTest, CancelAll) {
  client->upload(0x1000, 0, record());
  client->upload(0x1001, 0, record());
  go();
  out.clear();
  client->cancel_all(SdoAbortCode::CannotTransferDeviceState);
  EXPECT_EQ(out, aborted(0x1000, 0, SdoAbortCode::CannotTransferDeviceState));
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::CannotTransferDeviceState),
                                          failed(SdoAbortCode::CannotTransferDeviceState)}));
  EXPECT_FALSE(client->busy());
  EXPECT_EQ(client->queued(), 0u);
}

TEST_F(SdoClientTest, SetCobIdsFailsTheTransferInFlightAndMovesTheChannel) {
  client->upload(0x1000, 0, record());
  client->upload(0x1000, 0, record());
  go();
  out.clear();
  client->set_cob_ids(CobId(0x641), CobId(0x5C1));
  // The first is failed without a frame (the server is on another channel now); the second starts there.
  EXPECT_EQ(out, (std::vector<CanFrame>{CanFrame(0x641, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0})}));
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::GeneralError)}));
  EXPECT_FALSE(client->on_frame(CanFrame(kResp, {0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4}), t));
  EXPECT_TRUE(client->on_frame(CanFrame(0x5C1, {0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4}), t));
  EXPECT_EQ(results.back(), ok({1, 2, 3, 4}));
}

TEST_F(SdoClientTest, ServerAbortWithReservedBitsAndShortAbort) {
  client->upload(0x1000, 0, record());
  client->upload(0x1000, 0, record());
  go();
  EXPECT_EQ(srv({0x81, 0x00, 0x10, 0x00, 0x00, 0x00, 0x02, 0x06}), req({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(srv({0x80, 0x00, 0x10}), none());  // short: code unknown, reported as general error
  EXPECT_EQ(results,
            (std::vector<Result>{failed(SdoAbortCode::ObjectDoesNotExist), failed(SdoAbortCode::GeneralError)}));
}

// ---------------------------------------------------------------------------------------------
// Block transfer

TEST_F(SdoClientTest, BlockDownloadWithCrc) {
  const auto d = pattern(20);
  client->download(0x2100, 0, d, record(), SdoTransfer::Block);
  EXPECT_EQ(go(), req({0xC6, 0x00, 0x21, 0x00, 20, 0, 0, 0}));
  EXPECT_EQ(srv({0xA4, 0x00, 0x21, 0x00, 127, 0, 0, 0}),
            (std::vector<CanFrame>{
                CanFrame(kReq, {0x01, d[0], d[1], d[2], d[3], d[4], d[5], d[6]}),
                CanFrame(kReq, {0x02, d[7], d[8], d[9], d[10], d[11], d[12], d[13]}),
                CanFrame(kReq, {0x83, d[14], d[15], d[16], d[17], d[18], d[19], 0}),
            }));
  const std::uint16_t crc = crc16_ccitt(d);
  EXPECT_EQ(srv({0xA2, 3, 127, 0, 0, 0, 0, 0}),
            req({0xC5, static_cast<std::uint8_t>(crc), static_cast<std::uint8_t>(crc >> 8), 0, 0, 0, 0, 0}));
  EXPECT_TRUE(results.empty());
  EXPECT_EQ(srv({0xA1, 0, 0, 0, 0, 0, 0, 0}), none());
  EXPECT_EQ(results, (std::vector<Result>{ok()}));
}

TEST_F(SdoClientTest, BlockDownloadWithoutServerCrcRetransmitsAndFollowsBlockSize) {
  cfg.block_threshold = 8;  // by threshold, not per request
  make();
  const auto d = pattern(15);  // 3 segments
  client->download(0x2100, 0, d, record());
  EXPECT_EQ(go(), req({0xC6, 0x00, 0x21, 0x00, 15, 0, 0, 0}));
  // Server without CRC support, blksize 2.
  EXPECT_EQ(srv({0xA0, 0x00, 0x21, 0x00, 2, 0, 0, 0}),
            (std::vector<CanFrame>{
                CanFrame(kReq, {0x01, d[0], d[1], d[2], d[3], d[4], d[5], d[6]}),
                CanFrame(kReq, {0x02, d[7], d[8], d[9], d[10], d[11], d[12], d[13]}),
            }));
  // Only segment 1 arrived: resend from segment 2, renumbered from 1.
  EXPECT_EQ(srv({0xA2, 1, 2, 0, 0, 0, 0, 0}), (std::vector<CanFrame>{
                                                  CanFrame(kReq, {0x01, d[7], d[8], d[9], d[10], d[11], d[12], d[13]}),
                                                  CanFrame(kReq, {0x82, d[14], 0, 0, 0, 0, 0, 0}),
                                              }));
  EXPECT_EQ(srv({0xA2, 2, 2, 0, 0, 0, 0, 0}), req({0xD9, 0, 0, 0, 0, 0, 0, 0}));  // n = 6, no CRC
  srv({0xA1, 0, 0, 0, 0, 0, 0, 0});
  EXPECT_EQ(results, (std::vector<Result>{ok()}));
}

TEST_F(SdoClientTest, BlockDownloadBadServerAnswers) {
  client->download(0x2100, 0, pattern(20), record(), SdoTransfer::Block);
  go();
  EXPECT_EQ(srv({0xA4, 0x00, 0x21, 0x00, 0, 0, 0, 0}), aborted(0x2100, 0, SdoAbortCode::InvalidBlockSize));
  client->download(0x2100, 0, pattern(20), record(), SdoTransfer::Block);
  go();
  srv({0xA4, 0x00, 0x21, 0x00, 127, 0, 0, 0});
  EXPECT_EQ(srv({0xA2, 4, 127, 0, 0, 0, 0, 0}), aborted(0x2100, 0, SdoAbortCode::InvalidSequenceNumber));
  client->download(0x2100, 0, pattern(20), record(), SdoTransfer::Block);
  go();
  srv({0xA4, 0x00, 0x21, 0x00, 127, 0, 0, 0});
  EXPECT_EQ(srv({0xA2, 3, 128, 0, 0, 0, 0, 0}), aborted(0x2100, 0, SdoAbortCode::InvalidBlockSize));
  EXPECT_EQ(results,
            (std::vector<Result>{failed(SdoAbortCode::InvalidBlockSize), failed(SdoAbortCode::InvalidSequenceNumber),
                                 failed(SdoAbortCode::InvalidBlockSize)}));
}

TEST_F(SdoClientTest, BlockUploadWithCrc) {
  const auto d = bytes_of("OEGW test device");
  client->upload(0x1008, 0, record(), SdoTransfer::Block);
  EXPECT_EQ(go(), req({0xA4, 0x08, 0x10, 0x00, 127, 0, 0, 0}));
  EXPECT_EQ(srv({0xC6, 0x08, 0x10, 0x00, 16, 0, 0, 0}), req({0xA3, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(srv({0x01, 'O', 'E', 'G', 'W', ' ', 't', 'e'}), none());
  EXPECT_EQ(srv({0x02, 's', 't', ' ', 'd', 'e', 'v', 'i'}), none());
  EXPECT_EQ(srv({0x83, 'c', 'e', 0, 0, 0, 0, 0}), req({0xA2, 3, 127, 0, 0, 0, 0, 0}));
  const std::uint16_t crc = crc16_ccitt(d);
  EXPECT_TRUE(results.empty());
  EXPECT_EQ(srv({0xD5, static_cast<std::uint8_t>(crc), static_cast<std::uint8_t>(crc >> 8), 0, 0, 0, 0, 0}),
            req({0xA1, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(results, (std::vector<Result>{ok(d)}));
}

TEST_F(SdoClientTest, BlockUploadCrcErrorAndLostSegment) {
  cfg.block_size = 3;
  make();
  client->upload(0x1008, 0, record(), SdoTransfer::Block);
  EXPECT_EQ(go(), req({0xA4, 0x08, 0x10, 0x00, 3, 0, 0, 0}));
  srv({0xC6, 0x08, 0x10, 0x00, 16, 0, 0, 0});
  EXPECT_EQ(srv({0x01, 'O', 'E', 'G', 'W', ' ', 't', 'e'}), none());
  // Segment 2 lost: the last of the sub-block is acknowledged with ackseq = 1.
  EXPECT_EQ(srv({0x83, 'c', 'e', 0, 0, 0, 0, 0}), req({0xA2, 1, 3, 0, 0, 0, 0, 0}));
  EXPECT_EQ(srv({0x01, 's', 't', ' ', 'd', 'e', 'v', 'i'}), none());
  EXPECT_EQ(srv({0x82, 'c', 'e', 0, 0, 0, 0, 0}), req({0xA2, 2, 3, 0, 0, 0, 0, 0}));
  EXPECT_EQ(srv({0xD5, 0x12, 0x34, 0, 0, 0, 0, 0}), aborted(0x1008, 0, SdoAbortCode::CrcError));
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::CrcError)}));
}

TEST_F(SdoClientTest, BlockUploadSequenceAndSizeErrors) {
  client->upload(0x1008, 0, record(), SdoTransfer::Block);
  go();
  srv({0xC6, 0x08, 0x10, 0x00, 16, 0, 0, 0});
  EXPECT_EQ(srv({0x00, 1, 2, 3, 4, 5, 6, 7}), aborted(0x1008, 0, SdoAbortCode::InvalidSequenceNumber));
  client->upload(0x1008, 0, record(), SdoTransfer::Block);
  go();
  srv({0xC2, 0x08, 0x10, 0x00, 5, 0, 0, 0});
  srv({0x81, 1, 2, 3, 4, 5, 6, 7});
  EXPECT_EQ(srv({0xC1, 0, 0, 0, 0, 0, 0, 0}), aborted(0x1008, 0, SdoAbortCode::LengthMismatch));  // 7 != 5
  EXPECT_EQ(results,
            (std::vector<Result>{failed(SdoAbortCode::InvalidSequenceNumber), failed(SdoAbortCode::LengthMismatch)}));
}

TEST_F(SdoClientTest, BlockUploadProtocolSwitch) {
  cfg.pst = 16;
  cfg.crc = false;
  make();
  client->upload(0x1000, 0, record(), SdoTransfer::Block);
  EXPECT_EQ(go(), req({0xA0, 0x00, 0x10, 0x00, 127, 16, 0, 0}));
  EXPECT_EQ(srv({0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4}), none());
  client->upload(0x1008, 0, record(), SdoTransfer::Block);
  go();
  EXPECT_EQ(srv({0x41, 0x08, 0x10, 0x00, 2, 0, 0, 0}), req({0x60, 0, 0, 0, 0, 0, 0, 0}));
  srv({0x0B, 'h', 'i', 0, 0, 0, 0, 0});
  EXPECT_EQ(results, (std::vector<Result>{ok({1, 2, 3, 4}), ok(bytes_of("hi"))}));
}

// ---------------------------------------------------------------------------------------------
// Tickets and cancel()

TEST_F(SdoClientTest, TicketsAreUniqueAndNeverZero) {
  const SdoClient::Ticket a = client->upload(0x1000, 0, record());
  const SdoClient::Ticket b = client->download(0x2000, 0, {1}, record());
  const SdoClient::Ticket c = client->upload(0x1000, 0, record(), SdoTransfer::Block);
  EXPECT_NE(a, 0u);
  EXPECT_NE(a, b);
  EXPECT_NE(b, c);
  EXPECT_NE(a, c);
}

TEST_F(SdoClientTest, CancelQueuedRequestRemovesItWithoutAFrame) {
  client->upload(0x1000, 0, record());
  const SdoClient::Ticket second = client->upload(0x1001, 0, record());
  client->upload(0x1002, 0, record());
  EXPECT_EQ(go(), req({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}));
  out.clear();
  EXPECT_TRUE(client->cancel(second, SdoAbortCode::CannotTransferLocalControl));
  EXPECT_EQ(out, none());
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::CannotTransferLocalControl)}));
  EXPECT_EQ(client->queued(), 1u);
  EXPECT_TRUE(client->busy());
  // Its callback is not called again, and the others go on in order.
  EXPECT_EQ(srv({0x4F, 0x00, 0x10, 0x00, 7, 0, 0, 0}), req({0x40, 0x02, 0x10, 0x00, 0, 0, 0, 0}));
  srv({0x4F, 0x02, 0x10, 0x00, 9, 0, 0, 0});
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::CannotTransferLocalControl), ok({7}), ok({9})}));
  EXPECT_FALSE(client->cancel(second, SdoAbortCode::GeneralError));
}

TEST_F(SdoClientTest, CancelInFlightAbortsOnTheBusAndStartsTheNext) {
  const SdoClient::Ticket first = client->upload(0x1008, 0, record());
  client->upload(0x1000, 0, record());
  go();
  EXPECT_EQ(srv({0x41, 0x08, 0x10, 0x00, 20, 0, 0, 0}), req({0x60, 0, 0, 0, 0, 0, 0, 0}));
  out.clear();
  EXPECT_TRUE(client->cancel(first, SdoAbortCode::ResourceNotAvailable));
  EXPECT_EQ(out, (std::vector<CanFrame>{abort_frame(kReq, 0x1008, 0, SdoAbortCode::ResourceNotAvailable),
                                        CanFrame(kReq, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0})}));
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::ResourceNotAvailable)}));
  EXPECT_FALSE(client->cancel(first, SdoAbortCode::ResourceNotAvailable));
  // The next request is served; the cancelled one gets no second callback.
  EXPECT_EQ(srv({0x4F, 0x00, 0x10, 0x00, 5, 0, 0, 0}), none());
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::ResourceNotAvailable), ok({5})}));
}

TEST_F(SdoClientTest, CancelQueuedLetsTheTransferInFlightEndSoItsLateAnswerCannotPassForTheNext) {
  // The network manager starting a node's configuration over (a second boot-up) while its
  // 1000h read is in flight: cancel_all() would abort it and send the new 1000h read, and the
  // server's answer to the first read, already on its way, would be taken for the second's and
  // the second's answer then for the next request's (a 08000000h abort in the middle of a boot).
  client->upload(0x1000, 0, record());
  client->upload(0x1018, 1, record());
  EXPECT_EQ(go(), req({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}));
  out.clear();
  client->cancel_queued(SdoAbortCode::CannotTransferDeviceState);
  EXPECT_EQ(out, none()) << "no abort on the bus";
  // Both requesters are answered at once (a host's remote SDO in flight must not wait for a node
  // the gateway took back): the one in flight first, then the queued 1018h:01.
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::CannotTransferDeviceState),
                                          failed(SdoAbortCode::CannotTransferDeviceState)}));
  EXPECT_TRUE(client->busy()) << "the transfer itself is still on the wire";
  client->upload(0x1000, 0, record());  // the new configuration's first read waits its turn
  EXPECT_EQ(go(), none());
  // The first read's answer ends the first transfer (dropped: no second callback), then the
  // second starts and its own answer is taken.
  EXPECT_EQ(srv({0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x0F, 0x00}), req({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(srv({0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x0F, 0x00}), none());
  EXPECT_EQ(results,
            (std::vector<Result>{failed(SdoAbortCode::CannotTransferDeviceState),
                                 failed(SdoAbortCode::CannotTransferDeviceState), ok({0x91, 0x01, 0x0F, 0x00})}));
  EXPECT_FALSE(client->busy());
  // Idle, it cancels what is queued and sends nothing.
  client->upload(0x1001, 0, record());
  client->cancel_queued(SdoAbortCode::GeneralError);
  EXPECT_EQ(go(), none());
  EXPECT_EQ(results.back(), failed(SdoAbortCode::GeneralError));
}

TEST_F(SdoClientTest, CancelOfUnknownOrFinishedTicketsDoesNothing) {
  EXPECT_FALSE(client->cancel(0, SdoAbortCode::GeneralError));
  EXPECT_FALSE(client->cancel(12345, SdoAbortCode::GeneralError));
  const SdoClient::Ticket done = client->upload(0x1000, 0, record());
  go();
  srv({0x4F, 0x00, 0x10, 0x00, 1, 0, 0, 0});
  out.clear();
  EXPECT_FALSE(client->cancel(done, SdoAbortCode::GeneralError));
  EXPECT_EQ(out, none());
  EXPECT_EQ(results, (std::vector<Result>{ok({1})}));
}

TEST_F(SdoClientTest, CancelWithoutACodeIsAGeneralError) {
  const SdoClient::Ticket t1 = client->download(0x2000, 0, {1}, record());
  go();
  out.clear();
  EXPECT_TRUE(client->cancel(t1, SdoAbortCode::None));
  EXPECT_EQ(out, aborted(0x2000, 0, SdoAbortCode::GeneralError));
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::GeneralError)}));
}

TEST_F(SdoClientTest, CancelFromACallback) {
  SdoClient::Ticket later = 0;
  client->upload(0x1000, 0, [&](SdoAbortCode, std::vector<std::uint8_t>) {
    EXPECT_TRUE(client->cancel(later, SdoAbortCode::NoDataAvailable));
  });
  later = client->upload(0x1001, 0, record());
  go();
  EXPECT_EQ(srv({0x4F, 0x00, 0x10, 0x00, 1, 0, 0, 0}), none());  // the second never starts
  EXPECT_EQ(results, (std::vector<Result>{failed(SdoAbortCode::NoDataAvailable)}));
  EXPECT_FALSE(client->busy());
  EXPECT_EQ(client->queued(), 0u);
}

}  // namespace
