// SdoServer in remote (routed) mode, frame by frame: the SDO network indication (CiA 301 v4.2
// §7.2.4.3, CiA 302-7) and every transfer handed to a fake SdoRemote. Server node-ID 3: requests
// on 603h, responses on 583h. Where a real SdoClient is the host, its frames go straight to the
// server and back; `wire` records both directions.
#include <gtest/gtest.h>

#include <array>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "canopen/301/crc16.hpp"
#include "canopen/301/sdo_client.hpp"
#include "canopen/301/sdo_remote.hpp"
#include "canopen/301/sdo_server.hpp"
#include "canopen/state.hpp"
#include "sdo_test_support.hpp"

using namespace oegw::canopen;
using namespace sdo_test;
using namespace std::chrono_literals;

namespace oegw::canopen {
inline void PrintTo(const SdoTarget& t, std::ostream* os) {
  *os << "{network " << int{t.network} << ", node " << int{t.node} << "}";
}
}  // namespace oegw::canopen

namespace {

constexpr std::uint32_t kRx = 0x603;
constexpr std::uint32_t kTx = 0x583;
constexpr SdoTarget kNode20{2, 0x20};

// Records what the server asks; answers when the test says so (or at once, `sync`).
class FakeRemote : public SdoRemote {
 public:
  struct Call {
    bool upload = true;
    SdoTarget target;
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    std::vector<std::uint8_t> data;  // download
    TimePoint now;                   // the time the server passed on
    Ticket ticket = 0;
    Done done;
  };
  struct Cancel {
    Ticket ticket;
    SdoAbortCode why;
    friend bool operator==(const Cancel&, const Cancel&) = default;
  };

  std::vector<SdoTarget> selects;
  SdoAbortCode select_code = SdoAbortCode::None;
  Selection select_as = Selection::Remote;
  std::vector<Call> calls;
  std::vector<Cancel> cancels;
  // Answer every transfer from inside upload()/download() with this.
  std::optional<std::pair<SdoAbortCode, std::vector<std::uint8_t>>> sync;

  SdoAbortCode select(const SdoTarget& target, Selection& selection) override {
    selects.push_back(target);
    selection = select_as;
    return select_code;
  }
  Ticket upload(const SdoTarget& target, std::uint16_t index, std::uint8_t sub, TimePoint now, Done done) override {
    return start(Call{true, target, index, sub, {}, now, next_++, std::move(done)});
  }
  Ticket download(const SdoTarget& target, std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                  bool /*size_indicated*/, TimePoint now, Done done) override {
    return start(Call{false, target, index, sub, {data.begin(), data.end()}, now, next_++, std::move(done)});
  }
  void cancel(Ticket ticket, SdoAbortCode why) override { cancels.push_back({ticket, why}); }

  // Calls the done of call i (a copy: it may start further calls).
  void answer(std::size_t i, SdoAbortCode code, std::vector<std::uint8_t> data = {}) {
    ASSERT_LT(i, calls.size());
    const Done done = calls[i].done;
    done(code, std::move(data));
  }
  void answer_last(SdoAbortCode code, std::vector<std::uint8_t> data = {}) {
    ASSERT_FALSE(calls.empty());
    answer(calls.size() - 1, code, std::move(data));
  }

 private:
  Ticket start(Call c) {
    const Ticket t = c.ticket;
    calls.push_back(std::move(c));
    if (sync) {
      const Done done = calls.back().done;
      done(sync->first, sync->second);
    }
    return t;
  }
  Ticket next_ = 100;
};

class SdoRemoteTest : public ::testing::Test {
 protected:
  TestDictionary dict;
  FakeRemote remote;
  std::vector<CanFrame> out;
  TimePoint t{std::chrono::seconds(100)};
  SdoServer server{dict.od, [this](const CanFrame& f) { out.push_back(f); }, NodeId{3}};

  void SetUp() override { server.set_remote(&remote); }

  // Sends one request and returns what the server answered to it.
  std::vector<CanFrame> rx(std::initializer_list<std::uint8_t> bytes) {
    out.clear();
    EXPECT_TRUE(server.on_frame(CanFrame(kRx, bytes), t));
    return out;
  }
  std::vector<CanFrame> rx(const CanFrame& f) {
    out.clear();
    server.on_frame(f, t);
    return out;
  }
  // What the server sends when the remote answers call i (outside on_frame).
  std::vector<CanFrame> answer(std::size_t i, SdoAbortCode code, std::vector<std::uint8_t> data = {}) {
    out.clear();
    remote.answer(i, code, std::move(data));
    return out;
  }
  std::vector<CanFrame> answer(SdoAbortCode code, std::vector<std::uint8_t> data = {}) {
    return answer(remote.calls.size() - 1, code, std::move(data));
  }
  // Names node 20h of network 2 as the target.
  void select_node20() {
    ASSERT_EQ(rx({0xE0, 0, 0, 0, 2, 0x20, 0, 0}), tx({0xE0, 0, 0, 0, 2, 0x20, 0, 0}));
    ASSERT_EQ(server.target(), kNode20);
  }
  static std::vector<CanFrame> tx(std::initializer_list<std::uint8_t> bytes) { return {CanFrame(kTx, bytes)}; }
  static std::vector<CanFrame> aborted(std::uint16_t index, std::uint8_t sub, SdoAbortCode code) {
    return {abort_frame(kTx, index, sub, code)};
  }
  static std::vector<CanFrame> none() { return {}; }
};

// ---------------------------------------------------------------------------------------------
// The network indication

TEST(SdoRemoteNoRemote, NetworkIndicationWithoutARemoteIsAnUnknownCommandAsBefore) {
  TestDictionary dict;
  std::vector<CanFrame> out;
  SdoServer server{dict.od, [&](const CanFrame& f) { out.push_back(f); }, NodeId{3}};
  const TimePoint t{std::chrono::seconds(1)};
  server.on_frame(CanFrame(kRx, {0xE0, 0, 0, 0, 2, 0x20, 0, 0}), t);
  EXPECT_EQ(out, (std::vector<CanFrame>{abort_frame(kTx, 0, 0, SdoAbortCode::UnknownCommandSpecifier)}));
  EXPECT_EQ(server.target(), std::nullopt);
  // During a transfer it is a wrong command for that transfer, as before.
  out.clear();
  server.on_frame(CanFrame(kRx, {0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}), t);
  out.clear();
  server.on_frame(CanFrame(kRx, {0xE0, 0, 0, 0, 2, 0x20, 0, 0}), t);
  EXPECT_EQ(out, (std::vector<CanFrame>{abort_frame(kTx, 0x1008, 0, SdoAbortCode::UnknownCommandSpecifier)}));
}

TEST(SdoRemoteNoRemote, BoundChannelWithoutARemoteRefusesEveryTransfer) {
  TestDictionary dict;
  std::vector<CanFrame> out;
  SdoServer server{dict.od, [&](const CanFrame& f) { out.push_back(f); }, NodeId{3}};
  server.bind(kNode20);
  server.on_frame(CanFrame(kRx, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), TimePoint{});
  EXPECT_EQ(out, (std::vector<CanFrame>{abort_frame(kTx, 0x1000, 0, SdoAbortCode::ResourceNotAvailable)}));
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoRemoteTest, NetworkIndicationIsEchoedAndNamesTheTarget) {
  EXPECT_EQ(server.target(), std::nullopt);
  // Bytes 6..7 are reserved: echoed whatever they hold.
  EXPECT_EQ(rx({0xE0, 0, 0, 0, 2, 0x20, 0xAA, 0x55}), tx({0xE0, 0, 0, 0, 2, 0x20, 0xAA, 0x55}));
  EXPECT_EQ(remote.selects, (std::vector<SdoTarget>{kNode20}));
  EXPECT_EQ(server.target(), kNode20);
  EXPECT_FALSE(server.busy());
  EXPECT_TRUE(remote.calls.empty());
  // Reserved bits in byte 0 are not checked; the answer is E0h.
  EXPECT_EQ(rx({0xE5, 0, 0, 0, 2, 0x21, 0, 0}), tx({0xE0, 0, 0, 0, 2, 0x21, 0, 0}));
  EXPECT_EQ(server.target(), (SdoTarget{2, 0x21}));
}

// Run-time state (SdoServer::export_state): the target a network indication named goes on for
// the next transfers of a copy, with when and by which request it was named; a fresh server
// reads its own dictionary.
TEST_F(SdoRemoteTest, TheRedirectANetworkIndicationMadeCarriesOverInTheState) {
  select_node20();
  StateWriter w;
  server.export_state(w);
  std::vector<CanFrame> sent;
  SdoServer copy{dict.od, [&](const CanFrame& f) { sent.push_back(f); }, NodeId{3}};
  copy.set_remote(&remote);
  std::vector<std::string> changes;
  copy.on_redirect = [&](const auto&, const auto& after, SdoServer::RedirectChange) {
    changes.push_back(after ? "to " + std::to_string(after->target.node) : "none");
  };
  copy.import_state(StateReader::parse(w.text()));
  EXPECT_TRUE(changes.empty()) << "an import tells nobody";
  EXPECT_EQ(copy.target(), kNode20);
  ASSERT_TRUE(copy.redirect());
  EXPECT_EQ(copy.redirect()->since, t);
  EXPECT_EQ(copy.redirect()->request, (std::array<std::uint8_t, 8>{0xE0, 0, 0, 0, 2, 0x20, 0, 0}));
  copy.on_frame(CanFrame(kRx, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), t);
  ASSERT_EQ(remote.calls.size(), 1u);
  EXPECT_EQ(remote.calls[0].target, kNode20);
  EXPECT_TRUE(sent.empty()) << "the remote's answer is awaited";
  SdoServer fresh{dict.od, [&](const CanFrame& f) { sent.push_back(f); }, NodeId{3}};
  fresh.set_remote(&remote);
  fresh.on_frame(CanFrame(kRx, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), t);
  EXPECT_EQ(remote.calls.size(), 1u);
  EXPECT_EQ(sent.size(), 1u) << "answered from its own dictionary";
  // A transfer under way is not state.
  EXPECT_THROW(copy.export_state(w), std::logic_error);
}

TEST_F(SdoRemoteTest, NetworkIndicationNamingTheServerItselfReturnsToTheOwnDictionary) {
  select_node20();
  remote.select_as = SdoRemote::Selection::Local;
  EXPECT_EQ(rx({0xE0, 0, 0, 0, 1, 3, 0, 0}), tx({0xE0, 0, 0, 0, 1, 3, 0, 0}));
  EXPECT_EQ(remote.selects.back(), (SdoTarget{1, 3}));
  EXPECT_EQ(server.target(), std::nullopt);
  // Served from the own dictionary again.
  EXPECT_EQ(rx({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), tx({0x43, 0x00, 0x10, 0x00, 0x96, 0x01, 0x08, 0x00}));
  EXPECT_TRUE(remote.calls.empty());
}

TEST_F(SdoRemoteTest, RefusedNetworkIndicationIsAbortedWithTheRemotesCodeAndKeepsTheTarget) {
  select_node20();
  remote.select_code = SdoAbortCode::NoDataAvailable;
  EXPECT_EQ(rx({0xE0, 0, 0, 0, 9, 0x7F, 0, 0}), aborted(0, 0, SdoAbortCode::NoDataAvailable));
  EXPECT_EQ(server.target(), kNode20);
  // A refused first indication leaves the own dictionary.
  server.reset();
  EXPECT_EQ(rx({0xE0, 0, 0, 0, 9, 0x7F, 0, 0}), aborted(0, 0, SdoAbortCode::NoDataAvailable));
  EXPECT_EQ(server.target(), std::nullopt);
}

TEST_F(SdoRemoteTest, ShortNetworkIndicationIsAProtocolError) {
  EXPECT_EQ(rx(CanFrame(kRx, {0xE0, 0, 0, 0, 2, 0x20})), aborted(0, 0, SdoAbortCode::UnknownCommandSpecifier));
  EXPECT_TRUE(remote.selects.empty());
  EXPECT_EQ(server.target(), std::nullopt);
}

TEST_F(SdoRemoteTest, BoundChannelRefusesNetworkIndicationsAndUnbindReturnsToTheOwnDictionary) {
  server.bind(SdoTarget{2, 0x21});
  EXPECT_EQ(server.target(), (SdoTarget{2, 0x21}));
  EXPECT_EQ(rx({0xE0, 0, 0, 0, 2, 0x20, 0, 0}), aborted(0, 0, SdoAbortCode::CannotTransferLocalControl));
  EXPECT_TRUE(remote.selects.empty());
  EXPECT_EQ(rx({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), none());
  ASSERT_EQ(remote.calls.size(), 1u);
  EXPECT_EQ(remote.calls[0].target, (SdoTarget{2, 0x21}));
  EXPECT_EQ(answer(SdoAbortCode::None, {1, 2, 3, 4}), tx({0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4}));
  // A reset keeps the binding.
  server.reset();
  EXPECT_EQ(server.target(), (SdoTarget{2, 0x21}));
  server.bind(std::nullopt);
  EXPECT_EQ(server.target(), std::nullopt);
  EXPECT_EQ(rx({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), tx({0x43, 0x00, 0x10, 0x00, 0x96, 0x01, 0x08, 0x00}));
  // Unbound, network indications are served again.
  EXPECT_EQ(rx({0xE0, 0, 0, 0, 2, 0x20, 0, 0}), tx({0xE0, 0, 0, 0, 2, 0x20, 0, 0}));
}

TEST_F(SdoRemoteTest, NetworkIndicationAbandonsALocalTransferSilently) {
  EXPECT_EQ(rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}), tx({0x41, 0x08, 0x10, 0x00, 16, 0, 0, 0}));
  EXPECT_TRUE(server.busy());
  EXPECT_EQ(rx({0xE0, 0, 0, 0, 2, 0x20, 0, 0}), tx({0xE0, 0, 0, 0, 2, 0x20, 0, 0}));
  EXPECT_FALSE(server.busy());
  // The old transfer's next segment request is a wrong command now.
  EXPECT_EQ(rx({0x60, 0, 0, 0, 0, 0, 0, 0}), aborted(0, 0, SdoAbortCode::UnknownCommandSpecifier));
}

TEST_F(SdoRemoteTest, TargetPersistsAcrossTransfersUntilReset) {
  select_node20();
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(rx({0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0}), none());
    EXPECT_EQ(answer(SdoAbortCode::None, {0x2A, 0, 0, 0}), tx({0x43, 0x18, 0x10, 0x01, 0x2A, 0, 0, 0}));
  }
  ASSERT_EQ(remote.calls.size(), 3u);
  for (const auto& c : remote.calls) {
    EXPECT_TRUE(c.upload);
    EXPECT_EQ(c.target, kNode20);
    EXPECT_EQ(c.index, 0x1018);
    EXPECT_EQ(c.sub, 1);
  }
  server.reset();
  EXPECT_EQ(server.target(), std::nullopt);
  EXPECT_EQ(rx({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), tx({0x43, 0x00, 0x10, 0x00, 0x96, 0x01, 0x08, 0x00}));
  EXPECT_EQ(remote.calls.size(), 3u);
}

TEST_F(SdoRemoteTest, SetCobIdsEndsTheTarget) {
  select_node20();
  server.set_cob_ids(CobId(0x604), CobId(0x584));
  EXPECT_EQ(server.target(), std::nullopt);
}

// redirect(): the target a network indication named, when and by which request; on_redirect
// tells each change with its cause. A bound channel is never a redirect.
TEST_F(SdoRemoteTest, TheRedirectRecordsTargetTimeAndRequestAndEachChangeIsReported) {
  using Change = SdoServer::RedirectChange;
  struct Seen {
    std::optional<SdoTarget> before, after;
    Change why;
  };
  std::vector<Seen> seen;
  server.on_redirect = [&](const auto& before, const auto& after, Change why) {
    seen.push_back({before ? std::optional(before->target) : std::nullopt,
                    after ? std::optional(after->target) : std::nullopt, why});
  };
  EXPECT_EQ(server.redirect(), std::nullopt);
  rx({0xE0, 0, 0, 0, 2, 0x20, 0, 0});
  ASSERT_TRUE(server.redirect().has_value());
  EXPECT_EQ(server.redirect()->target, kNode20);
  EXPECT_EQ(server.redirect()->since, t);
  EXPECT_EQ(server.redirect()->request, (std::array<std::uint8_t, 8>{0xE0, 0, 0, 0, 2, 0x20, 0, 0}));
  // Another node, later: a change, with its own time and request.
  t += 2s;
  rx({0xE1, 0, 0, 0, 2, 0x21, 0, 0});
  EXPECT_EQ(server.redirect()->since, t);
  EXPECT_EQ(server.redirect()->request[0], 0xE1);
  // A refused indication changes nothing and reports nothing.
  remote.select_code = SdoAbortCode::ObjectDoesNotExist;
  rx({0xE0, 0, 0, 0, 9, 0x21, 0, 0});
  remote.select_code = SdoAbortCode::None;
  // Naming the server itself ends it; a second end is no change.
  remote.select_as = SdoRemote::Selection::Local;
  rx({0xE0, 0, 0, 0, 0, 0, 0, 0});
  rx({0xE0, 0, 0, 0, 0, 0, 0, 0});
  EXPECT_EQ(server.redirect(), std::nullopt);
  remote.select_as = SdoRemote::Selection::Remote;
  // Ended by reset(), by other COB-IDs, and by the same COB-IDs set again (a reset).
  rx({0xE0, 0, 0, 0, 2, 0x20, 0, 0});
  server.reset();
  rx({0xE0, 0, 0, 0, 2, 0x20, 0, 0});
  server.set_cob_ids(CobId(kRx), CobId(kTx));
  rx({0xE0, 0, 0, 0, 2, 0x20, 0, 0});
  server.set_cob_ids(CobId(0x604), CobId(0x584));
  // Binding is configuration: it ends a redirect, and the bound target is none.
  server.set_cob_ids(CobId(kRx), CobId(kTx));
  rx({0xE0, 0, 0, 0, 2, 0x20, 0, 0});
  server.bind(kNode20);
  EXPECT_EQ(server.redirect(), std::nullopt);
  EXPECT_EQ(server.target(), kNode20);
  const SdoTarget n21{2, 0x21};
  const std::vector<std::tuple<std::optional<SdoTarget>, std::optional<SdoTarget>, Change>> want =
      {{std::nullopt, kNode20, Change::Indication},  {kNode20, n21, Change::Indication},
       {n21, std::nullopt, Change::Indication},      {std::nullopt, kNode20, Change::Indication},
       {kNode20, std::nullopt, Change::Reset},       {std::nullopt, kNode20, Change::Indication},
       {kNode20, std::nullopt, Change::Reset},       {std::nullopt, kNode20, Change::Indication},
       {kNode20, std::nullopt, Change::CobIds},      {std::nullopt, kNode20, Change::Indication},
       {kNode20, std::nullopt, Change::Reconfigured}};
  ASSERT_EQ(seen.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(seen[i].before, std::get<0>(want[i])) << i;
    EXPECT_EQ(seen[i].after, std::get<1>(want[i])) << i;
    EXPECT_EQ(seen[i].why, std::get<2>(want[i])) << i;
  }
}

// ---------------------------------------------------------------------------------------------
// Uploads

TEST_F(SdoRemoteTest, ExpeditedUploadIsAnsweredWhenTheRemoteIsDone) {
  select_node20();
  EXPECT_EQ(rx({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), none());
  EXPECT_TRUE(server.busy());
  ASSERT_EQ(remote.calls.size(), 1u);
  EXPECT_TRUE(remote.calls[0].upload);
  EXPECT_EQ(remote.calls[0].target, kNode20);
  EXPECT_EQ(remote.calls[0].index, 0x1000);
  EXPECT_EQ(remote.calls[0].sub, 0);
  EXPECT_EQ(remote.calls[0].now, t);  // the remote's time-outs run from the request's frame
  // The answer goes out at once, outside on_frame/advance: the size from the data (2 bytes: 4Bh).
  EXPECT_EQ(answer(SdoAbortCode::None, {0x91, 0x01}), tx({0x4B, 0x00, 0x10, 0x00, 0x91, 0x01, 0, 0}));
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoRemoteTest, SynchronousDoneIsAnsweredInTheSameFrame) {
  select_node20();
  remote.sync.emplace(SdoAbortCode::None, std::vector<std::uint8_t>{0x91, 0x01, 0x0F, 0x00});
  EXPECT_EQ(rx({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), tx({0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x0F, 0x00}));
  EXPECT_FALSE(server.busy());
  remote.sync.emplace(SdoAbortCode::ObjectDoesNotExist, std::vector<std::uint8_t>{});
  EXPECT_EQ(rx({0x40, 0x00, 0x30, 0x00, 0, 0, 0, 0}), aborted(0x3000, 0, SdoAbortCode::ObjectDoesNotExist));
  remote.sync.emplace(SdoAbortCode::None, std::vector<std::uint8_t>{});
  EXPECT_EQ(rx({0x23, 0x00, 0x20, 0x00, 1, 2, 3, 4}), tx({0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0}));
  EXPECT_TRUE(remote.cancels.empty());
  // A late second call of a done already used is ignored.
  out.clear();
  remote.answer(0, SdoAbortCode::None, {1});
  EXPECT_EQ(out, none());
}

TEST_F(SdoRemoteTest, SegmentedUploadFromTheRemotesData) {
  select_node20();
  EXPECT_EQ(rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}), none());
  EXPECT_EQ(answer(SdoAbortCode::None, bytes_of("MCB-402 node")), tx({0x41, 0x08, 0x10, 0x00, 12, 0, 0, 0}));
  EXPECT_EQ(rx({0x60, 0, 0, 0, 0, 0, 0, 0}), tx({0x00, 'M', 'C', 'B', '-', '4', '0', '2'}));
  EXPECT_EQ(rx({0x70, 0, 0, 0, 0, 0, 0, 0}), tx({0x15, ' ', 'n', 'o', 'd', 'e', 0, 0}));  // n = 2, c = 1
  EXPECT_FALSE(server.busy());
  EXPECT_EQ(remote.calls.size(), 1u);
}

TEST_F(SdoRemoteTest, EmptyUploadIsSegmentedWithSizeZero) {
  select_node20();
  rx({0x40, 0x00, 0x21, 0x00, 0, 0, 0, 0});
  EXPECT_EQ(answer(SdoAbortCode::None, {}), tx({0x41, 0x00, 0x21, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(rx({0x60, 0, 0, 0, 0, 0, 0, 0}), tx({0x0F, 0, 0, 0, 0, 0, 0, 0}));
}

TEST_F(SdoRemoteTest, BlockUploadFromTheRemotesData) {
  select_node20();
  EXPECT_EQ(rx({0xA4, 0x08, 0x10, 0x00, 127, 0, 0, 0}), none());
  ASSERT_EQ(remote.calls.size(), 1u);
  EXPECT_TRUE(remote.calls[0].upload);
  EXPECT_EQ(answer(SdoAbortCode::None, bytes_of("OEGW test device")), tx({0xC6, 0x08, 0x10, 0x00, 16, 0, 0, 0}));
  EXPECT_EQ(rx({0xA3, 0, 0, 0, 0, 0, 0, 0}), (std::vector<CanFrame>{
                                                 CanFrame(kTx, {0x01, 'O', 'E', 'G', 'W', ' ', 't', 'e'}),
                                                 CanFrame(kTx, {0x02, 's', 't', ' ', 'd', 'e', 'v', 'i'}),
                                                 CanFrame(kTx, {0x83, 'c', 'e', 0, 0, 0, 0, 0}),
                                             }));
  const std::uint16_t crc = crc16_ccitt(bytes_of("OEGW test device"));
  EXPECT_EQ(rx({0xA2, 3, 127, 0, 0, 0, 0, 0}),
            tx({0xD5, static_cast<std::uint8_t>(crc), static_cast<std::uint8_t>(crc >> 8), 0, 0, 0, 0, 0}));
  EXPECT_EQ(rx({0xA1, 0, 0, 0, 0, 0, 0, 0}), none());
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoRemoteTest, BlockUploadProtocolSwitchUsesTheRemotesDataSize) {
  select_node20();
  // pst = 4: 4 bytes or fewer -> a normal (expedited) upload answer.
  EXPECT_EQ(rx({0xA4, 0x00, 0x10, 0x00, 127, 4, 0, 0}), none());
  EXPECT_EQ(answer(SdoAbortCode::None, {1, 2, 3, 4}), tx({0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4}));
  EXPECT_FALSE(server.busy());
  // 5 bytes, above the threshold: block upload.
  EXPECT_EQ(rx({0xA4, 0x00, 0x10, 0x00, 127, 4, 0, 0}), none());
  EXPECT_EQ(answer(SdoAbortCode::None, {1, 2, 3, 4, 5}), tx({0xC6, 0x00, 0x10, 0x00, 5, 0, 0, 0}));
  // pst = 8, 5 bytes: a segmented upload answer.
  server.reset();
  select_node20();
  EXPECT_EQ(rx({0xA4, 0x00, 0x10, 0x00, 127, 8, 0, 0}), none());
  EXPECT_EQ(answer(SdoAbortCode::None, {1, 2, 3, 4, 5}), tx({0x41, 0x00, 0x10, 0x00, 5, 0, 0, 0}));
}

TEST_F(SdoRemoteTest, BlockUploadWithABadBlockSizeIsRefusedBeforeAskingTheRemote) {
  select_node20();
  EXPECT_EQ(rx({0xA4, 0x08, 0x10, 0x00, 0, 0, 0, 0}), aborted(0x1008, 0, SdoAbortCode::InvalidBlockSize));
  EXPECT_EQ(rx({0xA4, 0x08, 0x10, 0x00, 128, 0, 0, 0}), aborted(0x1008, 0, SdoAbortCode::InvalidBlockSize));
  EXPECT_TRUE(remote.calls.empty());
}

// ---------------------------------------------------------------------------------------------
// Downloads

TEST_F(SdoRemoteTest, ExpeditedDownloadIsConfirmedWhenTheRemoteIsDone) {
  select_node20();
  EXPECT_EQ(rx({0x2B, 0x01, 0x20, 0x00, 0xEF, 0xBE, 0, 0}), none());
  ASSERT_EQ(remote.calls.size(), 1u);
  EXPECT_FALSE(remote.calls[0].upload);
  EXPECT_EQ(remote.calls[0].target, kNode20);
  EXPECT_EQ(remote.calls[0].index, 0x2001);
  EXPECT_EQ(remote.calls[0].sub, 0);
  EXPECT_EQ(remote.calls[0].data, (std::vector<std::uint8_t>{0xEF, 0xBE}));
  EXPECT_EQ(answer(SdoAbortCode::None), tx({0x60, 0x01, 0x20, 0x00, 0, 0, 0, 0}));
  // The own dictionary is untouched.
  EXPECT_EQ(dict.value(0x2001), encode<std::uint16_t>(0xBEEF));
  // e = 1, s = 0: the size is unknown here, all four bytes go to the remote.
  EXPECT_EQ(rx({0x22, 0x01, 0x20, 0x00, 0x11, 0x22, 0x33, 0x44}), none());
  EXPECT_EQ(remote.calls[1].data, (std::vector<std::uint8_t>{0x11, 0x22, 0x33, 0x44}));
  // The remote's refusal, passed on unchanged.
  EXPECT_EQ(answer(SdoAbortCode::LengthTooHigh), aborted(0x2001, 0, SdoAbortCode::LengthTooHigh));
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoRemoteTest, SegmentedDownloadGoesToTheRemoteWithTheLastSegment) {
  select_node20();
  EXPECT_EQ(rx({0x21, 0x00, 0x21, 0x00, 10, 0, 0, 0}), tx({0x60, 0x00, 0x21, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(rx({0x00, 1, 2, 3, 4, 5, 6, 7}), tx({0x20, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_TRUE(remote.calls.empty());
  const TimePoint first = t;
  t += std::chrono::milliseconds(40);
  EXPECT_EQ(rx({0x19, 8, 9, 10, 0, 0, 0, 0}), none());  // toggle 1, n = 4, c = 1
  ASSERT_EQ(remote.calls.size(), 1u);
  EXPECT_FALSE(remote.calls[0].upload);
  // The transfer starts at the last segment's time, not the first's.
  EXPECT_EQ(remote.calls[0].now, t);
  EXPECT_NE(remote.calls[0].now, first);
  EXPECT_EQ(remote.calls[0].index, 0x2100);
  EXPECT_EQ(remote.calls[0].data, (std::vector<std::uint8_t>{1, 2, 3, 4, 5, 6, 7, 8, 9, 10}));
  EXPECT_EQ(answer(SdoAbortCode::None), tx({0x30, 0, 0, 0, 0, 0, 0, 0}));  // the last segment's toggle
  EXPECT_FALSE(server.busy());
  EXPECT_TRUE(dict.value(0x2100).empty());
}

TEST_F(SdoRemoteTest, SegmentedDownloadRefusedByTheRemote) {
  select_node20();
  rx({0x21, 0x00, 0x21, 0x00, 3, 0, 0, 0});
  EXPECT_EQ(rx({0x09, 1, 2, 3, 0, 0, 0, 0}), none());
  EXPECT_EQ(answer(SdoAbortCode::WriteOfReadOnly), aborted(0x2100, 0, SdoAbortCode::WriteOfReadOnly));
}

TEST_F(SdoRemoteTest, BlockDownloadGoesToTheRemoteAfterTheCrcCheck) {
  select_node20();
  const auto data = pattern(10);
  EXPECT_EQ(rx({0xC6, 0x00, 0x21, 0x00, 10, 0, 0, 0}), tx({0xA4, 0x00, 0x21, 0x00, 127, 0, 0, 0}));
  rx(CanFrame(kRx, {0x01, data[0], data[1], data[2], data[3], data[4], data[5], data[6]}));
  EXPECT_EQ(rx(CanFrame(kRx, {0x82, data[7], data[8], data[9], 0, 0, 0, 0})), tx({0xA2, 2, 127, 0, 0, 0, 0, 0}));
  const std::uint16_t crc = crc16_ccitt(data);
  // n = 4 unused bytes: C1h | 4 << 2 = D1h.
  const CanFrame end(kRx, {0xD1, static_cast<std::uint8_t>(crc), static_cast<std::uint8_t>(crc >> 8), 0, 0, 0, 0, 0});
  EXPECT_TRUE(remote.calls.empty());
  EXPECT_EQ(rx(end), none());
  ASSERT_EQ(remote.calls.size(), 1u);
  EXPECT_EQ(remote.calls[0].data, data);
  EXPECT_EQ(answer(SdoAbortCode::None), tx({0xA1, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoRemoteTest, BlockDownloadCrcErrorNeverReachesTheRemote) {
  select_node20();
  rx({0xC6, 0x00, 0x21, 0x00, 3, 0, 0, 0});
  rx({0x81, 1, 2, 3, 0, 0, 0, 0});
  EXPECT_EQ(rx({0xD1, 0x12, 0x34, 0, 0, 0, 0, 0}), aborted(0x2100, 0, SdoAbortCode::CrcError));
  EXPECT_TRUE(remote.calls.empty());
}

TEST_F(SdoRemoteTest, OversizeRemoteDownloadIsOutOfMemory) {
  // 2001h is an UNSIGNED16 in the own dictionary: its size does not matter for a remote target.
  select_node20();
  constexpr auto kMax = static_cast<std::uint32_t>(SdoServer::kMaxRemoteDownload);
  static_assert(kMax == 1u << 20);
  const auto le = [](std::uint32_t v, int i) { return static_cast<std::uint8_t>(v >> (8 * i)); };
  const std::uint32_t over = kMax + 1;
  EXPECT_EQ(rx({0x21, 0x01, 0x20, 0x00, le(over, 0), le(over, 1), le(over, 2), le(over, 3)}),
            aborted(0x2001, 0, SdoAbortCode::OutOfMemory));
  EXPECT_EQ(rx({0xC6, 0x01, 0x20, 0x00, le(over, 0), le(over, 1), le(over, 2), le(over, 3)}),
            aborted(0x2001, 0, SdoAbortCode::OutOfMemory));
  // Exactly the cap is accepted.
  EXPECT_EQ(rx({0x21, 0x01, 0x20, 0x00, le(kMax, 0), le(kMax, 1), le(kMax, 2), le(kMax, 3)}),
            tx({0x60, 0x01, 0x20, 0x00, 0, 0, 0, 0}));
  // No size announced: the cap is reached segment by segment.
  EXPECT_EQ(rx({0x20, 0x01, 0x20, 0x00, 0, 0, 0, 0}), tx({0x60, 0x01, 0x20, 0x00, 0, 0, 0, 0}));
  bool toggle = false;
  std::size_t sent = 0;
  while (sent + 7 <= kMax) {
    ASSERT_EQ(rx({static_cast<std::uint8_t>(toggle ? 0x10 : 0x00), 1, 2, 3, 4, 5, 6, 7}).size(), 1u);
    toggle = !toggle;
    sent += 7;
  }
  EXPECT_EQ(rx({static_cast<std::uint8_t>(toggle ? 0x10 : 0x00), 1, 2, 3, 4, 5, 6, 7}),
            aborted(0x2001, 0, SdoAbortCode::OutOfMemory));
  EXPECT_TRUE(remote.calls.empty());
}

// ---------------------------------------------------------------------------------------------
// Aborts and cancellation

TEST_F(SdoRemoteTest, RemoteAbortCodesArePassedOnUnchanged) {
  select_node20();
  rx({0x40, 0x18, 0x10, 0x04, 0, 0, 0, 0});
  EXPECT_EQ(answer(SdoAbortCode::SubIndexDoesNotExist), aborted(0x1018, 4, SdoAbortCode::SubIndexDoesNotExist));
  rx({0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0});
  // The remote side's time-out.
  EXPECT_EQ(answer(SdoAbortCode::Timeout), aborted(0x1018, 1, SdoAbortCode::Timeout));
  // A code this project has no name for.
  rx({0xA4, 0x08, 0x10, 0x00, 127, 0, 0, 0});
  EXPECT_EQ(answer(static_cast<SdoAbortCode>(0x12345678)), aborted(0x1008, 0, static_cast<SdoAbortCode>(0x12345678)));
  EXPECT_FALSE(server.busy());
  EXPECT_TRUE(remote.cancels.empty());
}

TEST_F(SdoRemoteTest, ServerTimeoutDoesNotRunWhileWaitingForTheRemote) {
  select_node20();
  rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});
  EXPECT_EQ(server.next_deadline(), std::nullopt);
  out.clear();
  server.advance(t + 60s);
  EXPECT_EQ(out, none());
  EXPECT_TRUE(server.busy());
  // The answer starts the client time-out: due at once, armed by the next advance().
  EXPECT_EQ(answer(SdoAbortCode::None, bytes_of("long name")), tx({0x41, 0x08, 0x10, 0x00, 9, 0, 0, 0}));
  EXPECT_EQ(server.next_deadline(), t + 60s);  // the last time given
  server.advance(t + 61s);
  EXPECT_EQ(server.next_deadline(), t + 61s + SdoServer::kDefaultTimeout);
  out.clear();
  server.advance(t + 61s + SdoServer::kDefaultTimeout - 1ms);
  EXPECT_EQ(out, none());
  server.advance(t + 61s + SdoServer::kDefaultTimeout);
  EXPECT_EQ(out, aborted(0x1008, 0, SdoAbortCode::Timeout));
}

TEST_F(SdoRemoteTest, ClientAbortCancelsTheRemoteTransferSilently) {
  select_node20();
  rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});
  const auto ticket = remote.calls[0].ticket;
  EXPECT_EQ(rx(abort_frame(kRx, 0x1008, 0, SdoAbortCode::Timeout)), none());
  EXPECT_EQ(remote.cancels, (std::vector<FakeRemote::Cancel>{{ticket, SdoAbortCode::Timeout}}));
  EXPECT_FALSE(server.busy());
  // The late done of the cancelled ticket is ignored.
  EXPECT_EQ(answer(0, SdoAbortCode::None, {1, 2, 3, 4}), none());
  EXPECT_EQ(server.target(), kNode20);
  // A short abort frame carries no code: cancelled with 0800 0000h.
  rx({0x2F, 0x00, 0x20, 0x00, 0x40, 0, 0, 0});
  EXPECT_EQ(rx(CanFrame(kRx, {0x80, 0x00, 0x20})), none());
  EXPECT_EQ(remote.cancels.back(), (FakeRemote::Cancel{remote.calls[1].ticket, SdoAbortCode::GeneralError}));
}

TEST_F(SdoRemoteTest, NewRequestWhileWaitingIsRefusedAndCancelsTheRemoteTransfer) {
  select_node20();
  rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});
  // A new initiate: aborted with its own multiplexer.
  EXPECT_EQ(rx({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), aborted(0x1000, 0, SdoAbortCode::ResourceNotAvailable));
  EXPECT_EQ(remote.cancels,
            (std::vector<FakeRemote::Cancel>{{remote.calls[0].ticket, SdoAbortCode::ResourceNotAvailable}}));
  EXPECT_EQ(remote.calls.size(), 1u);  // the new request was not served
  EXPECT_FALSE(server.busy());
  EXPECT_EQ(answer(0, SdoAbortCode::None, {1}), none());
  // Any other frame: aborted with the pending transfer's multiplexer.
  rx({0x2F, 0x00, 0x20, 0x00, 0x40, 0, 0, 0});
  EXPECT_EQ(rx({0x60, 0, 0, 0, 0, 0, 0, 0}), aborted(0x2000, 0, SdoAbortCode::ResourceNotAvailable));
  EXPECT_EQ(remote.cancels.back(), (FakeRemote::Cancel{remote.calls[1].ticket, SdoAbortCode::ResourceNotAvailable}));
  // A network indication is a new request too (multiplexer 0); the target does not change.
  rx({0xC2, 0x00, 0x21, 0x00, 1, 0, 0, 0});  // block download of 1 byte, no CRC
  EXPECT_EQ(rx({0x81, 0x42, 0, 0, 0, 0, 0, 0}), tx({0xA2, 1, 127, 0, 0, 0, 0, 0}));
  EXPECT_EQ(rx({0xD9, 0, 0, 0, 0, 0, 0, 0}), none());  // end, n = 6
  ASSERT_EQ(remote.calls.size(), 3u);
  EXPECT_EQ(rx({0xE0, 0, 0, 0, 2, 0x21, 0, 0}), aborted(0, 0, SdoAbortCode::ResourceNotAvailable));
  EXPECT_EQ(remote.cancels.back(), (FakeRemote::Cancel{remote.calls[2].ticket, SdoAbortCode::ResourceNotAvailable}));
  EXPECT_EQ(remote.selects.size(), 1u);
  EXPECT_EQ(server.target(), kNode20);
  // A short frame is a protocol error in every state: 0504 0001h, for the remote too.
  rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});
  EXPECT_EQ(rx(CanFrame(kRx, {0x40, 0x00, 0x10})), aborted(0x1008, 0, SdoAbortCode::UnknownCommandSpecifier));
  EXPECT_EQ(remote.cancels.back(), (FakeRemote::Cancel{remote.calls[3].ticket, SdoAbortCode::UnknownCommandSpecifier}));
  EXPECT_EQ(remote.cancels.size(), 4u);
}

TEST_F(SdoRemoteTest, ResetAndSetCobIdsCancelThePendingTransfer) {
  select_node20();
  rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});
  out.clear();
  server.reset();
  EXPECT_EQ(out, none());
  EXPECT_EQ(remote.cancels, (std::vector<FakeRemote::Cancel>{{remote.calls[0].ticket, SdoAbortCode::GeneralError}}));
  EXPECT_FALSE(server.busy());
  EXPECT_EQ(server.target(), std::nullopt);
  EXPECT_EQ(answer(0, SdoAbortCode::None, {1}), none());

  select_node20();
  rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});
  out.clear();
  server.set_cob_ids(CobId(0x604), CobId(0x584));
  EXPECT_EQ(out, none());
  EXPECT_EQ(remote.cancels.back(), (FakeRemote::Cancel{remote.calls[1].ticket, SdoAbortCode::GeneralError}));
  EXPECT_EQ(server.target(), std::nullopt);
  EXPECT_EQ(answer(1, SdoAbortCode::None, {1}), none());

  // A bound channel stays bound, its pending transfer is cancelled all the same.
  server.set_cob_ids(CobId(kRx), CobId(kTx));
  server.bind(kNode20);
  rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});
  server.reset();
  EXPECT_EQ(remote.cancels.size(), 3u);
  EXPECT_EQ(server.target(), kNode20);
  // Nothing is cancelled when nothing is pending.
  server.reset();
  server.set_remote(nullptr);
  EXPECT_EQ(remote.cancels.size(), 3u);
}

TEST_F(SdoRemoteTest, DestroyingTheServerCancelsThePendingTransfer) {
  {
    SdoServer other{dict.od, [](const CanFrame&) {}, NodeId{4}};
    other.set_remote(&remote);
    other.bind(kNode20);
    other.on_frame(CanFrame(0x604, {0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}), t);
    ASSERT_EQ(remote.calls.size(), 1u);
  }
  EXPECT_EQ(remote.cancels, (std::vector<FakeRemote::Cancel>{{remote.calls[0].ticket, SdoAbortCode::GeneralError}}));
}

TEST_F(SdoRemoteTest, DoneOfAReplacedTransferIsIgnored) {
  select_node20();
  rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});
  rx(abort_frame(kRx, 0x1008, 0, SdoAbortCode::GeneralError));
  rx({0x40, 0x09, 0x10, 0x00, 0, 0, 0, 0});
  ASSERT_EQ(remote.calls.size(), 2u);
  EXPECT_EQ(answer(0, SdoAbortCode::None, {1, 2}), none());
  EXPECT_TRUE(server.busy());
  EXPECT_EQ(answer(1, SdoAbortCode::None, {1, 2}), tx({0x4B, 0x09, 0x10, 0x00, 1, 2, 0, 0}));
}

TEST_F(SdoRemoteTest, SetRemoteNullCancelsAndReturnsToTheOwnDictionary) {
  select_node20();
  rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});
  server.set_remote(nullptr);
  EXPECT_EQ(remote.cancels, (std::vector<FakeRemote::Cancel>{{remote.calls[0].ticket, SdoAbortCode::GeneralError}}));
  EXPECT_EQ(server.target(), std::nullopt);
  EXPECT_EQ(rx({0xE0, 0, 0, 0, 2, 0x20, 0, 0}), aborted(0, 0, SdoAbortCode::UnknownCommandSpecifier));
}

// ---------------------------------------------------------------------------------------------
// A real SdoClient as the host, against the routed server

struct HostResult {
  SdoAbortCode code = SdoAbortCode::GeneralError;
  std::vector<std::uint8_t> data;
  int calls = 0;
};

class SdoRemoteHostTest : public ::testing::Test {
 protected:
  TestDictionary dict;
  FakeRemote remote;
  TimePoint now{std::chrono::seconds(10)};
  std::vector<CanFrame> wire;
  SdoClientConfig cfg = SdoClientConfig::for_node(NodeId{3});
  std::optional<SdoServer> server;
  std::optional<SdoClient> host;

  void make() {
    server.emplace(
        dict.od,
        [this](const CanFrame& f) {
          wire.push_back(f);
          host->on_frame(f, now);
        },
        NodeId{3});
    host.emplace(
        [this](const CanFrame& f) {
          wire.push_back(f);
          server->on_frame(f, now);
        },
        cfg);
    server->set_remote(&remote);
    server->bind(kNode20);
  }
  SdoClient::Callback into(HostResult& r) {
    return [&r](SdoAbortCode c, std::vector<std::uint8_t> d) {
      r.code = c;
      r.data = std::move(d);
      ++r.calls;
    };
  }
  // The frames a local server sends for the same request on the same data: the routed server
  // must look exactly like it.
  std::vector<CanFrame> local_wire(std::uint16_t index, const std::vector<std::uint8_t>& value, bool upload,
                                   SdoTransfer mode, const std::vector<std::uint8_t>& download = {}) {
    TestDictionary d;
    d.od.find(index, 0)->value = value;
    std::vector<CanFrame> w;
    std::optional<SdoClient> c;
    SdoServer s(
        d.od,
        [&](const CanFrame& f) {
          w.push_back(f);
          c->on_frame(f, now);
        },
        NodeId{3});
    c.emplace(
        [&](const CanFrame& f) {
          w.push_back(f);
          s.on_frame(f, now);
        },
        cfg);
    HostResult r;
    if (upload) {
      c->upload(index, 0, into(r), mode);
    } else {
      c->download(index, 0, download, into(r), mode);
    }
    c->advance(now);
    EXPECT_EQ(r.calls, 1);
    EXPECT_EQ(r.code, SdoAbortCode::None);
    return w;
  }
};

TEST_F(SdoRemoteHostTest, UploadsInEveryModeLookLikeALocalServer) {
  struct Case {
    const char* what;
    std::vector<std::uint8_t> value;
    SdoTransfer mode;
    bool crc;
    std::uint8_t pst;
  };
  const std::vector<Case> cases{
      {"expedited", {0x91, 0x01, 0x0F, 0x00}, SdoTransfer::Auto, true, 0},
      {"segmented string", bytes_of("Novotechnik RFC-4800"), SdoTransfer::Auto, true, 0},
      {"block with CRC", pattern(300), SdoTransfer::Block, true, 0},
      {"block without CRC", pattern(300), SdoTransfer::Block, false, 0},
      {"block, switched to expedited", {1, 2, 3}, SdoTransfer::Block, true, 16},
      {"block, switched to segmented", pattern(12), SdoTransfer::Block, true, 16},
      {"block, at the switch threshold", pattern(16), SdoTransfer::Block, true, 16},
      {"block above the switch threshold", pattern(17), SdoTransfer::Block, true, 16},
  };
  for (const Case& c : cases) {
    for (const bool sync : {false, true}) {
      SCOPED_TRACE(std::string(c.what) + (sync ? ", answered at once" : ", answered later"));
      cfg.crc = c.crc;
      cfg.pst = c.pst;
      make();
      wire.clear();
      remote.calls.clear();
      remote.sync.reset();
      if (sync) remote.sync.emplace(SdoAbortCode::None, c.value);
      HostResult r;
      host->upload(0x2100, 0, into(r), c.mode);
      host->advance(now);
      ASSERT_EQ(remote.calls.size(), 1u);
      EXPECT_EQ(remote.calls[0].index, 0x2100);
      if (!sync) {
        EXPECT_EQ(r.calls, 0);
        remote.answer(0, SdoAbortCode::None, c.value);
      }
      EXPECT_EQ(r.calls, 1);
      EXPECT_EQ(r.code, SdoAbortCode::None);
      EXPECT_EQ(r.data, c.value);
      EXPECT_EQ(wire, local_wire(0x2100, c.value, true, c.mode));
      EXPECT_FALSE(server->busy());
    }
  }
}

TEST_F(SdoRemoteHostTest, DownloadsInEveryModeReachTheRemoteWhole) {
  struct Case {
    const char* what;
    std::vector<std::uint8_t> value;
    SdoTransfer mode;
    bool crc;
  };
  const std::vector<Case> cases{
      {"expedited", {0x11, 0x22}, SdoTransfer::Auto, true},
      {"segmented", bytes_of("elobau joystick"), SdoTransfer::Auto, true},
      {"forced segmented, 2 bytes", {0x11, 0x22}, SdoTransfer::Segmented, true},
      {"block with CRC", pattern(900), SdoTransfer::Block, true},
      {"block without CRC", pattern(900), SdoTransfer::Block, false},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    cfg.crc = c.crc;
    make();
    wire.clear();
    remote.calls.clear();
    HostResult r;
    host->download(0x2100, 0, c.value, into(r), c.mode);
    host->advance(now);
    ASSERT_EQ(remote.calls.size(), 1u);
    EXPECT_FALSE(remote.calls[0].upload);
    EXPECT_EQ(remote.calls[0].target, kNode20);
    EXPECT_EQ(remote.calls[0].data, c.value);
    EXPECT_EQ(r.calls, 0);  // the last answer waits for the remote
    const std::size_t before = wire.size();
    remote.answer(0, SdoAbortCode::None);
    EXPECT_EQ(wire.size(), before + 1);
    EXPECT_EQ(r.calls, 1);
    EXPECT_EQ(r.code, SdoAbortCode::None);
    EXPECT_EQ(wire, local_wire(0x2100, {}, false, c.mode, c.value));
    EXPECT_TRUE(dict.value(0x2100).empty());
  }
}

TEST_F(SdoRemoteHostTest, RemoteRefusalReachesTheHostsCallback) {
  make();
  HostResult r;
  host->download(0x1017, 0, {0xE8, 0x03}, into(r));
  host->advance(now);
  remote.answer(0, SdoAbortCode::CannotTransferDeviceState);
  EXPECT_EQ(r.calls, 1);
  EXPECT_EQ(r.code, SdoAbortCode::CannotTransferDeviceState);
  EXPECT_EQ(wire.back(), abort_frame(kTx, 0x1017, 0, SdoAbortCode::CannotTransferDeviceState));
}

TEST_F(SdoRemoteHostTest, HostCancelReachesTheRemote) {
  make();
  HostResult r;
  const SdoClient::Ticket ticket = host->upload(0x1018, 1, into(r));
  host->advance(now);
  ASSERT_EQ(remote.calls.size(), 1u);
  EXPECT_TRUE(host->cancel(ticket, SdoAbortCode::CannotTransferLocalControl));
  EXPECT_EQ(r.calls, 1);
  EXPECT_EQ(r.code, SdoAbortCode::CannotTransferLocalControl);
  EXPECT_EQ(remote.cancels,
            (std::vector<FakeRemote::Cancel>{{remote.calls[0].ticket, SdoAbortCode::CannotTransferLocalControl}}));
  EXPECT_FALSE(server->busy());
}

}  // namespace
