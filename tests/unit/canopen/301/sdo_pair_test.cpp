// An SdoClient and an SdoServer wired straight to each other: each one's sink calls the other's
// on_frame, with a manually driven clock. Checks that the two implementations agree in every mode.
#include <gtest/gtest.h>

#include <functional>
#include <tuple>

#include "canopen/301/sdo_client.hpp"
#include "canopen/301/sdo_server.hpp"
#include "sdo_test_support.hpp"

using namespace oegw::canopen;
using namespace sdo_test;
using namespace std::chrono_literals;

namespace {

struct Result {
  SdoAbortCode code = SdoAbortCode::GeneralError;
  std::vector<std::uint8_t> data;
  int calls = 0;
};

struct Pair {
  TestDictionary dict;
  TimePoint now{std::chrono::seconds(1)};
  std::size_t to_server = 0;
  std::size_t to_client = 0;
  // Return false to drop a frame on the wire.
  std::function<bool(const CanFrame&)> client_to_server = [](const CanFrame&) { return true; };
  std::function<bool(const CanFrame&)> server_to_client = [](const CanFrame&) { return true; };
  SdoServer server;
  SdoClient client;

  explicit Pair(SdoClientConfig cfg = SdoClientConfig::for_node(NodeId{9}))
      : server(
            dict.od,
            [this](const CanFrame& f) {
              ++to_client;
              if (server_to_client(f)) client.on_frame(f, now);
            },
            NodeId{9}),
        client(
            [this](const CanFrame& f) {
              ++to_server;
              if (client_to_server(f)) server.on_frame(f, now);
            },
            cfg) {}

  SdoClient::Callback into(Result& r) {
    return [&r](SdoAbortCode c, std::vector<std::uint8_t> d) {
      r.code = c;
      r.data = std::move(d);
      ++r.calls;
    };
  }
  void run() { client.advance(now); }
};

const char* mode_name(SdoTransfer m) {
  switch (m) {
    case SdoTransfer::Auto: return "Auto";
    case SdoTransfer::Segmented: return "Segmented";
    case SdoTransfer::Block: return "Block";
    case SdoTransfer::ExpeditedUnsized: return "ExpeditedUnsized";
  }
  return "?";
}

class SdoPairSizes : public ::testing::TestWithParam<std::tuple<SdoTransfer, std::size_t, bool>> {};

TEST_P(SdoPairSizes, DownloadThenUploadRoundTrips) {
  const auto [mode, size, crc] = GetParam();
  SdoClientConfig cfg = SdoClientConfig::for_node(NodeId{9});
  cfg.crc = crc;
  Pair p(cfg);
  const auto data = pattern(size, static_cast<std::uint8_t>(size));
  Result down;
  p.client.download(0x2100, 0, data, p.into(down), mode);
  p.run();
  ASSERT_EQ(down.calls, 1);
  EXPECT_EQ(down.code, SdoAbortCode::None);
  EXPECT_EQ(p.dict.value(0x2100), data);
  EXPECT_FALSE(p.server.busy());
  EXPECT_FALSE(p.client.busy());

  // Upload in the same mode (Segmented/Auto are both a normal upload on the client side).
  p.dict.od.find(0x2100, 0)->value = pattern(size, static_cast<std::uint8_t>(size + 100));
  Result up;
  p.client.upload(0x2100, 0, p.into(up), mode);
  p.run();
  ASSERT_EQ(up.calls, 1);
  EXPECT_EQ(up.code, SdoAbortCode::None);
  EXPECT_EQ(up.data, pattern(size, static_cast<std::uint8_t>(size + 100)));
  EXPECT_FALSE(p.server.busy());
  EXPECT_FALSE(p.client.busy());
  EXPECT_EQ(p.client.next_deadline(), std::nullopt);
  EXPECT_EQ(p.server.next_deadline(), std::nullopt);

  // Frame count shows which protocol ran: expedited = 1 + 1 each way.
  if (mode == SdoTransfer::Auto && size >= 1 && size <= 4) {
    EXPECT_EQ(p.to_server, 2u);
    EXPECT_EQ(p.to_client, 2u);
  }
}

INSTANTIATE_TEST_SUITE_P(AllModes, SdoPairSizes,
                         ::testing::Combine(::testing::Values(SdoTransfer::Auto, SdoTransfer::Segmented,
                                                              SdoTransfer::Block),
                                            ::testing::Values(0u, 1u, 4u, 5u, 7u, 8u, 889u), ::testing::Values(true)),
                         [](const auto& param_info) {
                           return std::string(mode_name(std::get<0>(param_info.param))) + "_" +
                                  std::to_string(std::get<1>(param_info.param)) + "bytes";
                         });

INSTANTIATE_TEST_SUITE_P(BlockWithoutCrc, SdoPairSizes,
                         ::testing::Combine(::testing::Values(SdoTransfer::Block), ::testing::Values(0u, 7u, 889u),
                                            ::testing::Values(false)),
                         [](const auto& param_info) {
                           return std::to_string(std::get<1>(param_info.param)) + "bytes";
                         });

TEST(SdoPair, SmallServerBlockSizeSplitsIntoSubBlocks) {
  Pair p;
  p.server.set_block_size(5);
  const auto data = pattern(889);
  Result down;
  p.client.download(0x2100, 0, data, p.into(down), SdoTransfer::Block);
  p.run();
  EXPECT_EQ(down.code, SdoAbortCode::None);
  EXPECT_EQ(p.dict.value(0x2100), data);
  // 127 segments in sub-blocks of 5 -> 26 acks, plus initiate response and end response.
  EXPECT_EQ(p.to_client, 28u);
}

TEST(SdoPair, SmallClientBlockSizeForUpload) {
  SdoClientConfig cfg = SdoClientConfig::for_node(NodeId{9});
  cfg.block_size = 4;
  Pair p(cfg);
  p.dict.od.find(0x2100, 0)->value = pattern(100);
  Result up;
  p.client.upload(0x2100, 0, p.into(up), SdoTransfer::Block);
  p.run();
  EXPECT_EQ(up.code, SdoAbortCode::None);
  EXPECT_EQ(up.data, pattern(100));
  // initiate, start, 15 segments -> 4 acks, end response.
  EXPECT_EQ(p.to_server, 1u + 1u + 4u + 1u);
}

TEST(SdoPair, LostBlockSegmentsAreRetransmitted) {
  Pair p;
  p.server.set_block_size(10);
  int seen = 0;
  // Drop the 3rd and the 14th block segment the client sends (once each).
  p.client_to_server = [&](const CanFrame& f) {
    const bool segment = (f.data[0] & 0x7F) != 0 && f.data[0] != 0xC6 && f.data[0] < 0xC0;
    if (!segment) return true;
    ++seen;
    return seen != 3 && seen != 14;
  };
  const auto data = pattern(200);
  Result down;
  p.client.download(0x2100, 0, data, p.into(down), SdoTransfer::Block);
  p.run();
  EXPECT_EQ(down.code, SdoAbortCode::None);
  EXPECT_EQ(p.dict.value(0x2100), data);
  EXPECT_GT(seen, 29);  // 29 segments, plus the retransmitted ones
}

TEST(SdoPair, LostBlockUploadSegmentsAreRetransmitted) {
  Pair p;
  int seen = 0;
  bool in_block = false;
  p.server_to_client = [&](const CanFrame& f) {
    if (f.data[0] == 0xC6) in_block = true;
    if (!in_block || f.data[0] == 0xC6 || (f.data[0] & 0xE3) == 0xC1) return true;
    ++seen;
    return seen != 5;
  };
  p.dict.od.find(0x2100, 0)->value = pattern(300);
  Result up;
  p.client.upload(0x2100, 0, p.into(up), SdoTransfer::Block);
  p.run();
  EXPECT_EQ(up.code, SdoAbortCode::None);
  EXPECT_EQ(up.data, pattern(300));
  EXPECT_EQ(seen, 43 + 39);  // 43 segments, then segments 5..43 again after the ack of 4
}

TEST(SdoPair, RefusedValuesComeBackAsTheirAbortCodeAndChangeNothing) {
  for (const SdoTransfer mode : {SdoTransfer::Auto, SdoTransfer::Segmented, SdoTransfer::Block}) {
    SCOPED_TRACE(mode_name(mode));
    Pair p;
    Result r1, r2, r3, r4, r5, r6;
    p.client.download(0x2102, 0, pattern(5), p.into(r1), mode);                   // hook: odd length
    p.client.download(0x2003, 0, encode<std::uint32_t>(1001), p.into(r2), mode);  // above high limit
    p.client.download(0x1000, 0, encode<std::uint32_t>(1), p.into(r3), mode);     // const
    p.client.download(0x2101, 0, pattern(11), p.into(r4), mode);                  // longer than max_size
    p.client.download(0x2001, 0, pattern(3), p.into(r5), mode);                   // UNSIGNED16 given 3
    p.client.download(0x1010, 1, bytes_of("kill"), p.into(r6), mode);             // wrong signature
    p.run();
    EXPECT_EQ(r1.code, SdoAbortCode::InvalidValue);
    EXPECT_EQ(r2.code, SdoAbortCode::ValueTooHigh);
    EXPECT_EQ(r3.code, SdoAbortCode::WriteOfReadOnly);
    EXPECT_EQ(r4.code, SdoAbortCode::LengthTooHigh);
    EXPECT_EQ(r5.code, SdoAbortCode::LengthTooHigh);
    EXPECT_EQ(r6.code, SdoAbortCode::CannotTransfer);
    EXPECT_TRUE(p.dict.value(0x2102).empty());
    EXPECT_EQ(p.dict.od.get<std::uint32_t>(0x2003, 0), 10u);
    EXPECT_EQ(p.dict.od.get<std::uint32_t>(0x1000, 0), 0x00080196u);
    EXPECT_EQ(p.dict.value(0x2101), bytes_of("abc"));
    EXPECT_EQ(p.dict.od.get<std::uint16_t>(0x2001, 0), 0xBEEF);
    EXPECT_EQ(p.dict.stores, 0);
    EXPECT_FALSE(p.server.busy());
    // And the channel still works afterwards.
    Result ok;
    p.client.download(0x2102, 0, pattern(6), p.into(ok), mode);
    p.run();
    EXPECT_EQ(ok.code, SdoAbortCode::None);
    EXPECT_EQ(p.dict.value(0x2102), pattern(6));
  }
}

TEST(SdoPair, ReadErrorsComeBackAsTheirAbortCode) {
  for (const SdoTransfer mode : {SdoTransfer::Auto, SdoTransfer::Block}) {
    Pair p;
    Result r1, r2, r3;
    p.client.upload(0x2004, 0, p.into(r1), mode);
    p.client.upload(0x3000, 0, p.into(r2), mode);
    p.client.upload(0x1801, 9, p.into(r3), mode);
    p.run();
    EXPECT_EQ(r1.code, SdoAbortCode::ReadOfWriteOnly);
    EXPECT_EQ(r2.code, SdoAbortCode::ObjectDoesNotExist);
    EXPECT_EQ(r3.code, SdoAbortCode::SubIndexDoesNotExist);
    EXPECT_TRUE(r1.data.empty());
  }
}

TEST(SdoPair, ProtocolSwitchThreshold) {
  SdoClientConfig cfg = SdoClientConfig::for_node(NodeId{9});
  cfg.pst = 20;
  Pair p(cfg);
  Result small, big;
  p.client.upload(0x1008, 0, p.into(small), SdoTransfer::Block);  // 16 bytes: switched to segmented
  p.run();
  EXPECT_EQ(small.data, bytes_of("OEGW test device"));
  EXPECT_EQ(p.to_client, 4u);  // initiate response + 3 segments
  p.dict.od.find(0x2100, 0)->value = pattern(21);
  p.client.upload(0x2100, 0, p.into(big), SdoTransfer::Block);
  p.run();
  EXPECT_EQ(big.data, pattern(21));
}

TEST(SdoPair, ClientTimeoutAbortReachesTheServer) {
  Pair p;
  p.server_to_client = [](const CanFrame& f) { return f.data[0] != 0x20; };  // lose the 1st segment ack
  Result r;
  p.client.download(0x2100, 0, pattern(20), p.into(r));
  p.run();
  EXPECT_TRUE(p.client.busy());
  EXPECT_TRUE(p.server.busy());
  // Both time out after 1 s; the client, advanced first, aborts and the server drops its transfer.
  p.now += 1s;
  p.client.advance(p.now);
  EXPECT_EQ(r.code, SdoAbortCode::Timeout);
  EXPECT_FALSE(p.server.busy());
  EXPECT_TRUE(p.dict.value(0x2100).empty());
  p.server_to_client = [](const CanFrame&) { return true; };
  Result again;
  p.client.download(0x2100, 0, pattern(20), p.into(again));
  p.run();
  EXPECT_EQ(again.code, SdoAbortCode::None);
  EXPECT_EQ(p.dict.value(0x2100), pattern(20));
}

TEST(SdoPair, ManyQueuedRequestsAllComplete) {
  Pair p;
  std::vector<Result> results(20);
  for (std::size_t i = 0; i < results.size(); ++i) {
    const auto mode = static_cast<SdoTransfer>(i % 3);
    if (i % 2 == 0) {
      p.client.download(0x2100, 0, pattern(i * 13), p.into(results[i]), mode);
    } else {
      p.client.upload(0x2100, 0, p.into(results[i]), mode);
    }
  }
  p.run();
  for (std::size_t i = 0; i < results.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(results[i].calls, 1);
    EXPECT_EQ(results[i].code, SdoAbortCode::None);
    if (i % 2 == 1) {
      EXPECT_EQ(results[i].data, pattern((i - 1) * 13));  // what the previous one wrote
    }
  }
}

TEST(SdoPair, RequestsQueuedFromCallbacksRunInOrderWhenTheQueueNeverEmpties) {
  Pair p;
  std::vector<int> order;
  int queued = 0;
  std::function<void()> queue_one = [&] {
    const int id = queued++;
    p.client.upload(0x1000, 0, [&, id](SdoAbortCode c, std::vector<std::uint8_t> d) {
      EXPECT_EQ(c, SdoAbortCode::None);
      EXPECT_EQ(d, encode<std::uint32_t>(0x00080196));
      order.push_back(id);
      if (queued < 300) {  // two more for each one done: the queue never drains
        queue_one();
        queue_one();
      }
    });
  };
  queue_one();
  queue_one();
  p.run();
  ASSERT_EQ(order.size(), static_cast<std::size_t>(queued));
  for (std::size_t i = 0; i < order.size(); ++i) ASSERT_EQ(order[i], static_cast<int>(i));
  EXPECT_EQ(p.client.queued(), 0u);
  EXPECT_FALSE(p.client.busy());
}

}  // namespace
