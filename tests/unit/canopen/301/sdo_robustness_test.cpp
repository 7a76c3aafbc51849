// SdoServer fed with garbage: every command byte, every DLC, random payloads (fixed seed),
// interleaved with valid transfers. Checks concrete outcomes: which frame comes back, with which
// abort code and multiplexer, that the object dictionary changes only with a confirmed download,
// and that the server is never stuck for longer than its timeout.
#include <gtest/gtest.h>

#include <cstdio>
#include <random>
#include <set>

#include "canopen/301/sdo_client.hpp"
#include "canopen/301/sdo_server.hpp"
#include "sdo_test_support.hpp"

using namespace oegw::canopen;
using namespace sdo_test;
using namespace std::chrono_literals;

namespace {

constexpr std::uint32_t kRx = 0x603;
constexpr std::uint32_t kTx = 0x583;

const std::set<std::uint32_t> kKnownCodes = {0x05030000, 0x05040000, 0x05040001, 0x05040002, 0x05040003,
                                             0x05040004, 0x05040005, 0x06010000, 0x06010001, 0x06010002,
                                             0x06020000, 0x06070010, 0x06070012, 0x06070013, 0x06090011,
                                             0x06090030, 0x06090031, 0x06090032, 0x08000020};

// Objects that exist in the test dictionary, to aim random initiates at.
const std::vector<std::pair<std::uint16_t, std::uint8_t>> kObjects = {{0x1000, 0}, {0x1008, 0}, {0x1010, 1},
                                                                      {0x1801, 5}, {0x2000, 0}, {0x2001, 0},
                                                                      {0x2002, 0}, {0x2003, 0}, {0x2004, 0},
                                                                      {0x2100, 0}, {0x2101, 0}, {0x2102, 0},
                                                                      {0x1801, 7}, {0x3333, 0}};

bool is_initiate(std::uint8_t cmd) {
  const int ccs = cmd >> 5;
  return ccs == 1 || ccs == 2 || (ccs == 5 && (cmd & 3) == 0) || (ccs == 6 && (cmd & 1) == 0);
}

std::uint32_t code_of(const CanFrame& f) { return get_u32(f.data.data() + 4); }
std::uint32_t mux_of(const std::uint8_t* d) { return static_cast<std::uint32_t>(get_u16(d + 1)) << 8 | d[3]; }

class SdoRobustness : public ::testing::Test {
 protected:
  TestDictionary dict;
  std::vector<CanFrame> out;
  TimePoint t{std::chrono::seconds(10)};
  SdoServer server{dict.od, [this](const CanFrame& f) { out.push_back(f); }, NodeId{3}};
  std::mt19937 rng{20261121};
  int od_writes = 0;
  Subscription od_writes_obs;

  void SetUp() override {
    od_writes_obs = dict.od.add_observer([this](std::uint16_t, std::uint8_t, Origin) { ++od_writes; });
  }

  std::vector<CanFrame> send(const CanFrame& f) {
    out.clear();
    EXPECT_TRUE(server.on_frame(f, t));
    return out;
  }
  std::vector<CanFrame> send(std::initializer_list<std::uint8_t> b) { return send(CanFrame(kRx, b)); }

  CanFrame random_frame(std::uint8_t cmd, std::uint8_t dlc, bool aim) {
    CanFrame f;
    f.id = kRx;
    f.dlc = dlc;
    for (auto& b : f.data) b = static_cast<std::uint8_t>(rng());
    f.data[0] = cmd;
    if (aim) {
      const auto& [index, sub] = kObjects[rng() % kObjects.size()];
      put_u16(f.data.data() + 1, index);
      f.data[3] = sub;
      if (rng() % 2) f.data[4] = static_cast<std::uint8_t>(rng() % 130);  // plausible sizes/blksizes
      if (rng() % 2) f.data[5] = f.data[6] = f.data[7] = 0;
    }
    return f;
  }

  // A complete valid transfer still works: expedited upload of 1000h.
  void expect_healthy() {
    EXPECT_FALSE(server.busy());
    EXPECT_EQ(send({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}),
              (std::vector<CanFrame>{CanFrame(kTx, {0x43, 0x00, 0x10, 0x00, 0x96, 0x01, 0x08, 0x00})}));
  }

  // Every frame the server sends: on its tx COB-ID, 8 bytes, and an abort carries a known code.
  void check_output_shape(const std::vector<CanFrame>& frames) {
    for (const CanFrame& f : frames) {
      EXPECT_EQ(f.id, kTx);
      EXPECT_EQ(f.dlc, 8);
      if (f.data[0] == 0x80) {
        EXPECT_TRUE(kKnownCodes.count(code_of(f))) << f.to_string();
      }
    }
  }
};

// From idle, every command byte with every DLC.
TEST_F(SdoRobustness, EveryCommandByteEveryDlcFromIdle) {
  for (int cmd = 0; cmd < 256; ++cmd) {
    for (std::uint8_t dlc = 0; dlc <= 8; ++dlc) {
      for (int rep = 0; rep < 4; ++rep) {
        SCOPED_TRACE(::testing::Message() << "cmd " << cmd << " dlc " << int{dlc} << " rep " << rep);
        const CanFrame f = random_frame(static_cast<std::uint8_t>(cmd), dlc, rep % 2 == 0);
        const int writes_before = od_writes;
        const auto r = send(f);
        check_output_shape(r);
        const std::uint8_t* d = f.data.data();
        const bool abort_cmd = dlc >= 1 && (cmd >> 5) == 4;
        if (dlc == 0) {
          ASSERT_EQ(r.size(), 1u);
          EXPECT_EQ(r[0], abort_frame(kTx, 0, 0, SdoAbortCode::UnknownCommandSpecifier));
        } else if (abort_cmd) {
          EXPECT_TRUE(r.empty());
        } else if (dlc < 8) {
          ASSERT_EQ(r.size(), 1u);
          EXPECT_EQ(r[0].data[0], 0x80);
          EXPECT_EQ(code_of(r[0]), 0x05040001u);
          const std::uint16_t index = dlc >= 3 ? get_u16(d + 1) : 0;
          EXPECT_EQ(get_u16(r[0].data.data() + 1), index);
          EXPECT_EQ(r[0].data[3], dlc >= 4 ? d[3] : 0);
        } else if (!is_initiate(static_cast<std::uint8_t>(cmd))) {
          ASSERT_EQ(r.size(), 1u);
          EXPECT_EQ(r[0], abort_frame(kTx, get_u16(d + 1), d[3], SdoAbortCode::UnknownCommandSpecifier));
        } else {
          // An initiate: exactly one answer about the same multiplexer, of the matching kind.
          ASSERT_EQ(r.size(), 1u);
          const std::uint8_t a = r[0].data[0];
          EXPECT_EQ(mux_of(r[0].data.data()), mux_of(d));
          const int ccs = cmd >> 5;
          if (a != 0x80) {
            if (ccs == 1) {
              EXPECT_EQ(a, 0x60);
            }
            if (ccs == 2) {
              EXPECT_TRUE(a == 0x41 || (a & 0xF3) == 0x43) << int{a};
            }
            if (ccs == 5) {
              EXPECT_TRUE(a == 0xC6 || a == 0x41 || (a & 0xF3) == 0x43) << int{a};
            }
            if (ccs == 6) {
              EXPECT_EQ(r[0], CanFrame(kTx, {0xA4, d[1], d[2], d[3], 127, 0, 0, 0}));
            }
          }
          if (ccs == 5 && (d[4] == 0 || d[4] > 127) && a == 0x80) {
            const auto c = code_of(r[0]);
            EXPECT_TRUE(c == 0x05040002u || c == 0x06020000u || c == 0x06090011u || c == 0x06010001u) << c;
          }
          if (mux_of(d) == 0x333300) {
            EXPECT_EQ(r[0], abort_frame(kTx, 0x3333, 0, SdoAbortCode::ObjectDoesNotExist));
          }
        }
        // The dictionary only ever changes with a confirmed expedited download.
        if (od_writes != writes_before) {
          ASSERT_EQ(r.size(), 1u);
          EXPECT_EQ(r[0].data[0], 0x60);
          EXPECT_EQ(cmd & 0xE2, 0x22);
        }
        // Whatever state that left, the server is free again after its timeout.
        if (server.busy()) {
          ASSERT_TRUE(server.next_deadline().has_value());
          EXPECT_EQ(*server.next_deadline(), t + SdoServer::kDefaultTimeout);
          out.clear();
          server.advance(t + SdoServer::kDefaultTimeout);
          ASSERT_EQ(out.size(), 1u);
          EXPECT_EQ(out[0].data[0], 0x80);
          EXPECT_EQ(code_of(out[0]), 0x05040000u);
          t += SdoServer::kDefaultTimeout;
        }
        expect_healthy();
        t += 1ms;
      }
    }
  }
}

// Sets up each transfer state, then feeds each of the 256 command bytes (DLC 8) and checks the
// state machine's answer.
TEST_F(SdoRobustness, EveryCommandByteInEveryTransferState) {
  enum class S {
    DownloadSegmented,
    UploadSegmented,
    BlockDownloadSubBlock,
    BlockDownloadEnd,
    BlockUploadStart,
    BlockUploadAck,
    BlockUploadEnd
  };
  const auto enter = [&](S s) {
    dict.od.find(0x2100, 0)->value = pattern(16);
    switch (s) {
      case S::DownloadSegmented: send({0x20, 0x00, 0x21, 0x00, 0, 0, 0, 0}); break;
      case S::UploadSegmented: send({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}); break;
      case S::BlockDownloadSubBlock: send({0xC0, 0x00, 0x21, 0x00, 0, 0, 0, 0}); break;
      case S::BlockDownloadEnd:
        send({0xC0, 0x00, 0x21, 0x00, 0, 0, 0, 0});
        send({0x81, 1, 2, 3, 4, 5, 6, 7});
        break;
      case S::BlockUploadStart: send({0xA0, 0x00, 0x21, 0x00, 127, 0, 0, 0}); break;
      case S::BlockUploadAck:
        send({0xA0, 0x00, 0x21, 0x00, 127, 0, 0, 0});
        send({0xA3, 0, 0, 0, 0, 0, 0, 0});
        break;
      case S::BlockUploadEnd:
        send({0xA0, 0x00, 0x21, 0x00, 127, 0, 0, 0});
        send({0xA3, 0, 0, 0, 0, 0, 0, 0});
        send({0xA2, 3, 127, 0, 0, 0, 0, 0});
        break;
    }
    ASSERT_TRUE(server.busy());
  };
  for (const S s : {S::DownloadSegmented, S::UploadSegmented, S::BlockDownloadSubBlock, S::BlockDownloadEnd,
                    S::BlockUploadStart, S::BlockUploadAck, S::BlockUploadEnd}) {
    for (int c = 0; c < 256; ++c) {
      const auto cmd = static_cast<std::uint8_t>(c);
      SCOPED_TRACE(::testing::Message() << "state " << static_cast<int>(s) << " cmd " << c);
      enter(s);
      const std::uint16_t idx = s == S::UploadSegmented ? 0x1008 : 0x2100;
      const auto unknown_here = abort_frame(kTx, idx, 0, SdoAbortCode::UnknownCommandSpecifier);
      // New initiates aim at 2000h:00 (UNSIGNED8) with sizes that make every kind acceptable.
      const CanFrame f(kRx, {cmd, 0x00, 0x20, 0x00, 1, 0, 0, 0});
      const int writes_before = od_writes;
      const auto r = send(f);
      check_output_shape(r);
      const int ccs = c >> 5;
      if (s == S::BlockDownloadSubBlock) {
        const int seq = c & 0x7F;
        const bool last = (c & 0x80) != 0;
        if (c == 0x80) {
          EXPECT_TRUE(r.empty());
          EXPECT_FALSE(server.busy());
        } else if (seq == 0) {
          EXPECT_EQ(r, std::vector<CanFrame>{abort_frame(kTx, 0x2100, 0, SdoAbortCode::InvalidSequenceNumber)});
        } else if (last || seq == 127) {
          // Acknowledged up to the last in-sequence segment (this one if it is number 1).
          EXPECT_EQ(r, std::vector<CanFrame>{
                           CanFrame(kTx, {0xA2, static_cast<std::uint8_t>(seq == 1 ? 1 : 0), 127, 0, 0, 0, 0, 0})});
          EXPECT_TRUE(server.busy());
        } else {
          EXPECT_TRUE(r.empty());
          EXPECT_TRUE(server.busy());
        }
      } else if (ccs == 4) {
        EXPECT_TRUE(r.empty());
        EXPECT_FALSE(server.busy());
      } else if (is_initiate(cmd)) {
        ASSERT_EQ(r.size(), 1u);
        EXPECT_EQ(get_u16(r[0].data.data() + 1), 0x2000);  // answers the new request, not the old
        const bool expedited_sized = ccs == 1 && (c & 3) == 3;
        if (expedited_sized && ((c >> 2) & 3) != 3) {
          // 2..4 bytes into an UNSIGNED8.
          EXPECT_EQ(r[0], abort_frame(kTx, 0x2000, 0, SdoAbortCode::LengthTooHigh));
        } else {
          EXPECT_NE(r[0].data[0], 0x80) << r[0].to_string();
        }
      } else {
        bool valid = false;
        switch (s) {
          case S::DownloadSegmented:
            if (ccs == 0) {
              valid = true;
              if (c & 0x10) {
                EXPECT_EQ(r, std::vector<CanFrame>{abort_frame(kTx, 0x2100, 0, SdoAbortCode::ToggleBitNotAlternated)});
              } else {
                EXPECT_EQ(r, std::vector<CanFrame>{CanFrame(kTx, {0x20, 0, 0, 0, 0, 0, 0, 0})});
                EXPECT_EQ(server.busy(), (c & 1) == 0);
                if (c & 1) {  // last segment: 7 - n bytes of the frame written
                  const std::size_t n = 7u - ((static_cast<unsigned>(c) >> 1) & 7u);
                  EXPECT_EQ(dict.value(0x2100),
                            (std::vector<std::uint8_t>(f.data.begin() + 1,
                                                       f.data.begin() + 1 + static_cast<std::ptrdiff_t>(n))));
                }
              }
            }
            break;
          case S::UploadSegmented:
            if (ccs == 3) {
              valid = true;
              if (c & 0x10) {
                EXPECT_EQ(r, std::vector<CanFrame>{abort_frame(kTx, 0x1008, 0, SdoAbortCode::ToggleBitNotAlternated)});
              } else {
                EXPECT_EQ(r, std::vector<CanFrame>{CanFrame(kTx, {0x00, 'O', 'E', 'G', 'W', ' ', 't', 'e'})});
              }
            }
            break;
          case S::BlockDownloadEnd:
            if ((c & 0xE1) == 0xC1) {
              valid = true;
              EXPECT_EQ(r, std::vector<CanFrame>{CanFrame(kTx, {0xA1, 0, 0, 0, 0, 0, 0, 0})});
              const std::size_t used = 7u - ((static_cast<unsigned>(c) >> 2) & 7u);
              const std::vector<std::uint8_t> seven{1, 2, 3, 4, 5, 6, 7};
              EXPECT_EQ(dict.value(0x2100),
                        std::vector<std::uint8_t>(seven.begin(), seven.begin() + static_cast<std::ptrdiff_t>(used)));
            }
            break;
          case S::BlockUploadStart:
            if ((c & 0xE3) == 0xA3) {
              valid = true;
              ASSERT_EQ(r.size(), 3u);
              EXPECT_EQ(r[2].data[0], 0x83);
            }
            break;
          case S::BlockUploadAck:
            if ((c & 0xE3) == 0xA2) {
              valid = true;
              // ackseq 0x00 in byte 1 (f.data[1] is 0): retransmit the whole sub-block; byte 2
              // (0x20) is the new block size.
              ASSERT_EQ(r.size(), 3u);
              EXPECT_EQ(r[0].data[0], 0x01);
            }
            break;
          case S::BlockUploadEnd:
            if ((c & 0xE3) == 0xA1) {
              valid = true;
              EXPECT_TRUE(r.empty());
              EXPECT_FALSE(server.busy());
            }
            break;
          case S::BlockDownloadSubBlock: break;
        }
        if (!valid) {
          EXPECT_EQ(r, std::vector<CanFrame>{unknown_here});
          EXPECT_FALSE(server.busy());
        }
      }
      if (s != S::DownloadSegmented && s != S::BlockDownloadEnd && !is_initiate(cmd)) {
        EXPECT_EQ(od_writes, writes_before);
      }
      server.reset();
      t += 1ms;
    }
  }
}

// Long random storms of mostly plausible frames, with valid client transfers in between.
TEST_F(SdoRobustness, RandomStormsNeverStickBeyondTheTimeout) {
  int rounds_ok = 0;
  int busy_seen = 0, commits_seen = 0, timeouts_seen = 0, aborts_seen = 0;
  for (int round = 0; round < 200; ++round) {
    SCOPED_TRACE(round);
    for (int i = 0; i < 60; ++i) {
      std::uint8_t cmd = static_cast<std::uint8_t>(rng());
      const std::uint8_t plausible[] = {0x00, 0x10, 0x01, 0x11, 0x20, 0x21, 0x22, 0x23, 0x2F,
                                        0x40, 0x60, 0x70, 0xA0, 0xA4, 0xA3, 0xA2, 0xA1, 0xC0,
                                        0xC2, 0xC6, 0xC1, 0x01, 0x02, 0x03, 0x81, 0x82, 0x80};
      if (rng() % 4 != 0) cmd = plausible[rng() % sizeof plausible];
      const std::uint8_t dlc = rng() % 10 == 0 ? static_cast<std::uint8_t>(rng() % 8) : 8;
      const CanFrame f = random_frame(cmd, dlc, rng() % 2 == 0);
      const int writes_before = od_writes;
      const auto r = send(f);
      check_output_shape(r);
      EXPECT_LE(r.size(), 127u);
      if (od_writes != writes_before) {
        // Committed only together with the confirmation of the download.
        ASSERT_FALSE(r.empty());
        const std::uint8_t a = r.back().data[0];
        EXPECT_TRUE(a == 0x60 || (a & 0xEF) == 0x20 || a == 0xA1) << r.back().to_string();
        ++commits_seen;
      }
      for (const auto& fr : r) aborts_seen += fr.data[0] == 0x80 ? 1 : 0;
      if (server.busy()) {
        ++busy_seen;
        ASSERT_TRUE(server.next_deadline().has_value());
        EXPECT_LE(*server.next_deadline(), t + SdoServer::kDefaultTimeout);
      }
      t += std::chrono::milliseconds(rng() % 10 == 0 ? 1000 + rng() % 500 : rng() % 300);
      out.clear();
      server.advance(t);
      check_output_shape(out);
      for (const auto& fr : out) {
        EXPECT_EQ(code_of(fr), 0x05040000u);  // advance() only ever sends timeout aborts
        ++timeouts_seen;
      }
    }
    // At most one timeout later the server is free and a full transfer goes through.
    t += SdoServer::kDefaultTimeout;
    server.advance(t);
    EXPECT_FALSE(server.busy());
    const auto data = pattern(30 + static_cast<std::size_t>(round), static_cast<std::uint8_t>(round));
    SdoAbortCode down = SdoAbortCode::GeneralError;
    std::vector<std::uint8_t> read_back;
    SdoClient pair([this](const CanFrame& f) { server.on_frame(f, t); }, SdoClientConfig::for_node(NodeId{3}));
    // The fixture's server sends to `out`; relay that to the client until quiet.
    pair.download(
        0x2100, 0, data, [&](SdoAbortCode c, std::vector<std::uint8_t>) { down = c; },
        static_cast<SdoTransfer>(round % 3));
    pair.upload(
        0x2100, 0, [&](SdoAbortCode, std::vector<std::uint8_t> d) { read_back = std::move(d); },
        static_cast<SdoTransfer>((round + 1) % 3));
    out.clear();
    pair.advance(t);
    for (int guard = 0; guard < 1000 && !out.empty(); ++guard) {
      const auto batch = std::move(out);
      out.clear();
      for (const auto& fr : batch) pair.on_frame(fr, t);
    }
    EXPECT_EQ(down, SdoAbortCode::None);
    EXPECT_EQ(read_back, data);
    if (down == SdoAbortCode::None && read_back == data) ++rounds_ok;
  }
  EXPECT_EQ(rounds_ok, 200);
  // The storm really exercised the state machine.
  EXPECT_GT(busy_seen, 500);
  EXPECT_GT(commits_seen, 100);
  EXPECT_GT(timeouts_seen, 10);
  EXPECT_GT(aborts_seen, 1000);
  std::printf("storm: busy %d, commits %d, timeouts %d, aborts %d\n", busy_seen, commits_seen, timeouts_seen,
              aborts_seen);
}

}  // namespace
