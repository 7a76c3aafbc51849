#include "canopen/io/socketcan_transport.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <linux/can/error.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "tests/fixtures/kernel_frame.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
using ::testing::ElementsAre;
using ::testing::IsEmpty;

namespace {

using oegw::fixtures::kernel_frame;

// ---- frame conversion ---------------------------------------------------------------------

TEST(SocketCanConversion, StandardDataFrameBothWays) {
  const CanFrame f{0x601, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}};
  const ::can_frame k = socketcan::to_kernel(f);
  EXPECT_EQ(k.can_id, 0x601u) << "no EFF/RTR/ERR flag on an 11-bit data frame";
  EXPECT_EQ(k.len, 8);
  EXPECT_EQ(k.data[0], 0x40);
  EXPECT_EQ(k.data[2], 0x10);
  const auto back = socketcan::from_kernel(k);
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(*back, f);
  EXPECT_FALSE(back->extended);
  EXPECT_FALSE(back->rtr);
}

TEST(SocketCanConversion, ExtendedIdentifierSetsAndReadsTheEffFlag) {
  const CanFrame f{0x18FF1234, {0xAA}};
  ASSERT_TRUE(f.extended);
  const ::can_frame k = socketcan::to_kernel(f);
  EXPECT_EQ(k.can_id, 0x18FF1234u | CAN_EFF_FLAG);
  EXPECT_EQ(k.len, 1);
  const auto back = socketcan::from_kernel(k);
  ASSERT_TRUE(back);
  EXPECT_TRUE(back->extended);
  EXPECT_EQ(back->id, 0x18FF1234u);
  EXPECT_EQ(back->to_string(), "18FF1234#AA");
}

TEST(SocketCanConversion, ExtendedFrameWithASmallIdKeepsItsFormat) {
  CanFrame f{0x123, {}};
  f.extended = true;  // 29-bit frame whose id happens to fit 11 bits
  const ::can_frame k = socketcan::to_kernel(f);
  EXPECT_EQ(k.can_id, 0x123u | CAN_EFF_FLAG);
  const auto back = socketcan::from_kernel(k);
  ASSERT_TRUE(back);
  EXPECT_TRUE(back->extended);
  EXPECT_EQ(back->id, 0x123u);
}

TEST(SocketCanConversion, RemoteFramesCarryDlcButNoData) {
  CanFrame f = CanFrame::remote(0x701, 1);
  f.data[0] = 0x55;  // must not leak onto the wire
  const ::can_frame k = socketcan::to_kernel(f);
  EXPECT_EQ(k.can_id, 0x701u | CAN_RTR_FLAG);
  EXPECT_EQ(k.len, 1);
  EXPECT_EQ(k.data[0], 0);
  ::can_frame in = kernel_frame(0x1ABCDEF0 | CAN_EFF_FLAG | CAN_RTR_FLAG, {});
  in.len = 4;
  in.data[0] = 0x99;  // garbage in an RTR frame is ignored
  const auto back = socketcan::from_kernel(in);
  ASSERT_TRUE(back);
  EXPECT_TRUE(back->rtr);
  EXPECT_TRUE(back->extended);
  EXPECT_EQ(back->id, 0x1ABCDEF0u);
  EXPECT_EQ(back->dlc, 4);
  EXPECT_EQ(back->data[0], 0);
  EXPECT_EQ(back->to_string(), "1ABCDEF0#R4");
}

TEST(SocketCanConversion, ErrorFramesAreNotDataFrames) {
  const ::can_frame err = kernel_frame(CAN_ERR_FLAG | CAN_ERR_BUSOFF, {0, 0, 0, 0, 0, 0, 0, 0});
  EXPECT_TRUE(socketcan::is_error_frame(err));
  EXPECT_FALSE(socketcan::from_kernel(err).has_value());
  EXPECT_FALSE(socketcan::is_error_frame(kernel_frame(0x7FF, {})));
}

TEST(SocketCanConversion, OversizedKernelLengthIsClampedTo8) {
  ::can_frame k = kernel_frame(0x100, {1, 2, 3, 4, 5, 6, 7, 8});
  k.len = 15;
  const auto back = socketcan::from_kernel(k);
  ASSERT_TRUE(back);
  EXPECT_EQ(back->dlc, 8);
}

TEST(SocketCanConversion, StandardIdBitsAboveElevenAreNotInterpretedForSff) {
  // The kernel never delivers this, but the conversion must not turn stray bits into an id.
  const auto back = socketcan::from_kernel(kernel_frame(0x0000F123, {}));
  ASSERT_TRUE(back);
  EXPECT_EQ(back->id, 0x123u);
  EXPECT_FALSE(back->extended);
}

TEST(SocketCanFilter, ComparesFrameFormatButNotRtr) {
  const ::can_filter sff = socketcan::to_kernel(CanFilter{0x580, 0x780});
  EXPECT_EQ(sff.can_id, 0x580u);
  EXPECT_EQ(sff.can_mask, 0x780u | CAN_EFF_FLAG);
  EXPECT_EQ(sff.can_mask & CAN_RTR_FLAG, 0u);
  const ::can_filter eff = socketcan::to_kernel(CanFilter{0x18FF0000, 0x1FFF0000, true});
  EXPECT_EQ(eff.can_id, 0x18FF0000u | CAN_EFF_FLAG);
  EXPECT_EQ(eff.can_mask, 0x1FFF0000u | CAN_EFF_FLAG);
  const ::can_filter inv = socketcan::to_kernel(CanFilter{0x700, 0x780, false, true});
  EXPECT_EQ(inv.can_id, 0x700u | CAN_INV_FILTER);
}

// oegw-sim's acceptance filter (join_filters): every frame passes but a data frame on one of the
// COB-IDs; a remote frame on it and the other format's frame with the same number still pass.
TEST(SocketCanFilter, AllButDataFramesOnExcludesExactlyThoseDataFrames) {
  EXPECT_FALSE(all_but_data_frames_on({}));  // nothing to exclude: every frame
  const auto filters = all_but_data_frames_on({CobId{0x191}, CobId{0x20000291}});
  ASSERT_TRUE(filters);
  ASSERT_EQ(filters->size(), 2u);
  // The kernel's rule (net/can/af_can.c): a filter matches when (id & mask) == (can_id & mask),
  // an inverted one when it does not; with CAN_RAW_JOIN_FILTERS a frame must match them all.
  const auto passes = [&](canid_t id) {
    for (const CanFilter& f : *filters) {
      const ::can_filter k = socketcan::to_kernel(f);
      const bool equal = (id & k.can_mask) == (k.can_id & ~CAN_INV_FILTER & k.can_mask);
      if (equal == ((k.can_id & CAN_INV_FILTER) != 0)) return false;
    }
    return true;
  };
  EXPECT_FALSE(passes(0x191));
  EXPECT_TRUE(passes(0x191 | CAN_RTR_FLAG));  // a remote request for the TPDO still reaches it
  EXPECT_TRUE(passes(0x191 | CAN_EFF_FLAG));
  EXPECT_TRUE(passes(0x192));
  EXPECT_FALSE(passes(0x291 | CAN_EFF_FLAG));
  EXPECT_TRUE(passes(0x291));
  EXPECT_TRUE(passes(0x000));
  EXPECT_TRUE(passes(0x611));
}

// ---- error frames -------------------------------------------------------------------------

struct ErrorCase {
  const char* name;
  canid_t classes;
  std::uint8_t ctrl;  // data[1]
  std::vector<BusEvent> expected;
};

class SocketCanErrorDecoding : public ::testing::TestWithParam<ErrorCase> {};

TEST_P(SocketCanErrorDecoding, MapsErrorClassesToBusEvents) {
  const ErrorCase& c = GetParam();
  ::can_frame k = kernel_frame(CAN_ERR_FLAG | c.classes, {0, c.ctrl, 0, 0, 0, 0, 0, 0});
  EXPECT_EQ(socketcan::decode_error_frame(k), c.expected);
}

INSTANTIATE_TEST_SUITE_P(
    Table, SocketCanErrorDecoding,
    ::testing::Values(
        ErrorCase{"BusOff", CAN_ERR_BUSOFF, 0, {BusEvent::BusOff}},
        ErrorCase{"Restarted", CAN_ERR_RESTARTED, 0, {BusEvent::Restarted}},
        ErrorCase{"TxTimeout", CAN_ERR_TX_TIMEOUT, 0, {BusEvent::TxTimeout}},
        ErrorCase{"RxWarning", CAN_ERR_CRTL, CAN_ERR_CRTL_RX_WARNING, {BusEvent::ErrorWarning}},
        ErrorCase{"TxWarning", CAN_ERR_CRTL, CAN_ERR_CRTL_TX_WARNING, {BusEvent::ErrorWarning}},
        ErrorCase{"RxPassive", CAN_ERR_CRTL, CAN_ERR_CRTL_RX_PASSIVE, {BusEvent::ErrorPassive}},
        ErrorCase{"TxPassive", CAN_ERR_CRTL, CAN_ERR_CRTL_TX_PASSIVE, {BusEvent::ErrorPassive}},
        ErrorCase{"Active", CAN_ERR_CRTL, CAN_ERR_CRTL_ACTIVE, {BusEvent::ErrorActive}},
        ErrorCase{"RxOverflow", CAN_ERR_CRTL, CAN_ERR_CRTL_RX_OVERFLOW, {BusEvent::ControllerOverflow}},
        ErrorCase{"TxOverflow", CAN_ERR_CRTL, CAN_ERR_CRTL_TX_OVERFLOW, {BusEvent::ControllerOverflow}},
        ErrorCase{"CrtlUnspecified", CAN_ERR_CRTL, 0, {}},
        ErrorCase{"CtrlBitsIgnoredWithoutCrtlClass", CAN_ERR_ACK, CAN_ERR_CRTL_TX_PASSIVE, {BusEvent::NoAck}},
        ErrorCase{"WarningAndPassiveTogetherNoDuplicates",
                  CAN_ERR_CRTL,
                  CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING | CAN_ERR_CRTL_TX_PASSIVE,
                  {BusEvent::ErrorWarning, BusEvent::ErrorPassive}},
        ErrorCase{"Protocol", CAN_ERR_PROT, 0, {BusEvent::ProtocolError}},
        ErrorCase{"Transceiver", CAN_ERR_TRX, 0, {BusEvent::TransceiverError}},
        ErrorCase{"LostArbitration", CAN_ERR_LOSTARB, 0, {BusEvent::LostArbitration}},
        ErrorCase{"BusError", CAN_ERR_BUSERROR, 0, {BusEvent::BusError}},
        ErrorCase{"BusOffAfterPassiveInOrder",
                  CAN_ERR_BUSOFF | CAN_ERR_CRTL | CAN_ERR_TX_TIMEOUT,
                  CAN_ERR_CRTL_TX_PASSIVE,
                  {BusEvent::TxTimeout, BusEvent::ErrorPassive, BusEvent::BusOff}},
        ErrorCase{"RestartedAndActive",
                  CAN_ERR_RESTARTED | CAN_ERR_CRTL,
                  CAN_ERR_CRTL_ACTIVE,
                  {BusEvent::ErrorActive, BusEvent::Restarted}}),
    [](const ::testing::TestParamInfo<ErrorCase>& p) { return std::string(p.param.name); });

TEST(SocketCanErrorDecodingMisc, DataFrameDecodesToNoEvents) {
  EXPECT_THAT(socketcan::decode_error_frame(kernel_frame(CAN_ERR_BUSOFF, {0, 0})), IsEmpty())
      << "without CAN_ERR_FLAG the id is just an id";
}

TEST(SocketCanErrorDecodingMisc, ShortErrorFrameDoesNotReadPastLen) {
  ::can_frame k = kernel_frame(CAN_ERR_FLAG | CAN_ERR_CRTL | CAN_ERR_BUSOFF, {});
  k.data[1] = CAN_ERR_CRTL_TX_PASSIVE;  // beyond len: must be ignored
  EXPECT_THAT(socketcan::decode_error_frame(k), ElementsAre(BusEvent::BusOff));
}

// ---- timestamps ---------------------------------------------------------------------------

// StampMapper: one sampled offset (realtime - monotonic) maps every stamp; no clock per frame.
TEST(SocketCanTimestamp, SubtractsTheSampledOffset) {
  socketcan::StampMapper m;
  EXPECT_TRUE(m.needs_sample(TimePoint{10s}));
  EXPECT_FALSE(m.map(timespec{1'700'000'000, 0}, TimePoint{10s})) << "no offset yet";
  m.sample(timespec{1'700'000'000, 350'500'000}, TimePoint{10s});  // realtime 1.7e9 s + 350.5 ms = mono 10 s
  const timespec stamp{1'700'000'000, 100'000'000};                // 250.5 ms before
  EXPECT_EQ(m.map(stamp, TimePoint{10s}), TimePoint{10s - 250500us});
  EXPECT_EQ(m.map(stamp, TimePoint{10s + 50ms}), TimePoint{10s - 250500us}) << "the same stamp read later";
  const timespec across_second{1'699'999'999, 950'000'000};  // 400.5 ms before, a second earlier
  EXPECT_EQ(m.map(across_second, TimePoint{10s}), TimePoint{10s - 400500us});
  EXPECT_FALSE(m.needs_sample(TimePoint{10s + 99ms}));
  EXPECT_TRUE(m.needs_sample(TimePoint{10s + 100ms})) << "re-sampled every 100 ms (NTP slew)";
}

TEST(SocketCanTimestamp, AFrameAfterTheWakeUpIsNowAndAStepIsRefused) {
  socketcan::StampMapper m;
  m.sample(timespec{1'700'000'000, 0}, TimePoint{10s});
  // Arrived 3 ms after the wake-up `now` was read at (the loop holds its clock): it is `now`.
  EXPECT_EQ(m.map(timespec{1'700'000'000, 3'000'000}, TimePoint{10s}), TimePoint{10s});
  // Further ahead than 1 s, or older than 10 s: the realtime clock was stepped since the sample.
  EXPECT_FALSE(m.map(timespec{1'700'000'002, 0}, TimePoint{10s})) << "forward step";
  EXPECT_FALSE(m.map(timespec{1'699'999'989, 0}, TimePoint{10s})) << "backward step";
  m.sample(timespec{1'700'000'005, 0}, TimePoint{10s});  // after a 5 s forward step
  EXPECT_EQ(m.map(timespec{1'700'000'004, 900'000'000}, TimePoint{10s}), TimePoint{9900ms});
}

// ---- opening ------------------------------------------------------------------------------

bool kernel_has_can() {
  const int s = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
  if (s >= 0) {
    ::close(s);
    return true;
  }
  return errno != EAFNOSUPPORT;
}

std::string open_error(const std::string& name, CanOpenError::Reason* reason = nullptr) {
  try {
    auto t = SocketCanTransport::open(name);
    return "opened";
  } catch (const CanOpenError& e) {
    if (reason) *reason = e.reason();
    return e.what();
  }
}

TEST(SocketCanOpen, NamesTheMissingKernelSupportOrTheMissingInterface) {
  CanOpenError::Reason reason{};
  if (!kernel_has_can()) {
    // This build machine: no AF_CAN at all. The socket is created first, so every name fails
    // the same way, before any interface lookup.
    EXPECT_EQ(open_error("vcan0", &reason),
              "kernel has no CAN support (socket(PF_CAN): Address family not supported by protocol)");
    EXPECT_EQ(reason, CanOpenError::Reason::NoKernelSupport);
    EXPECT_EQ(open_error("oegwnope0"),
              "kernel has no CAN support (socket(PF_CAN): Address family not supported by protocol)");
  } else {
    // A kernel with CAN (the test VM): the interface is what is missing.
    EXPECT_EQ(open_error("oegwnope0", &reason), "no such CAN interface 'oegwnope0'");
    EXPECT_EQ(reason, CanOpenError::Reason::NoSuchInterface);
    EXPECT_EQ(open_error("lo", &reason), "interface 'lo' is not a CAN interface");
    EXPECT_EQ(reason, CanOpenError::Reason::NotCanInterface);
  }
}

TEST(SocketCanOpen, RejectsImpossibleInterfaceNames) {
  CanOpenError::Reason reason{};
  EXPECT_EQ(open_error("", &reason), "invalid CAN interface name ''");
  EXPECT_EQ(reason, CanOpenError::Reason::InvalidName);
  EXPECT_EQ(open_error("a_name_far_too_long_for_linux"), "invalid CAN interface name 'a_name_far_too_long_for_linux'");
  // The kernel's rule (dev_valid_name), the one oegw check applies: "." and "..", any white space.
  for (const char* bad : {".", "..", "can\r0", "can\v0", "can/0", "can:0"}) {
    EXPECT_EQ(open_error(bad, &reason), std::string("invalid CAN interface name '") + bad + "'") << bad;
    EXPECT_EQ(reason, CanOpenError::Reason::InvalidName) << bad;
  }
}

TEST(SocketCanInterfaceCheck, MissingInterface) {
  EXPECT_FALSE(probe_interface("oegwnope0").exists);
  try {
    check_can_interface("oegwnope0");
    FAIL() << "must throw";
  } catch (const CanOpenError& e) {
    EXPECT_STREQ(e.what(), "no such CAN interface 'oegwnope0'");
    EXPECT_EQ(e.reason(), CanOpenError::Reason::NoSuchInterface);
  }
}

TEST(SocketCanInterfaceCheck, LoopbackIsNotACanInterface) {
  const InterfaceInfo lo = probe_interface("lo");
  ASSERT_TRUE(lo.exists) << "every Linux network namespace has lo";
  EXPECT_GT(lo.index, 0);
  EXPECT_FALSE(lo.is_can);
  try {
    check_can_interface("lo");
    FAIL() << "must throw";
  } catch (const CanOpenError& e) {
    EXPECT_STREQ(e.what(), "interface 'lo' is not a CAN interface");
    EXPECT_EQ(e.reason(), CanOpenError::Reason::NotCanInterface);
  }
}

// ---- the read/write path, over a datagram socketpair standing in for CAN_RAW ----------------
// A CAN_RAW socket exchanges one struct can_frame per datagram; an AF_UNIX datagram socketpair
// does the same, so everything past open() is exercised here without AF_CAN.

struct FakeCanSocket {
  int peer = -1;
  std::unique_ptr<SocketCanTransport> transport;
  explicit FakeCanSocket(std::size_t max_batch = 256) {
    int fds[2];
    if (::socketpair(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0, fds) != 0) throw std::runtime_error("socketpair");
    transport = SocketCanTransport::adopt(fds[0], "fake0", max_batch);
    peer = fds[1];
  }
  ~FakeCanSocket() { ::close(peer); }
  void inject(const ::can_frame& k) const { ASSERT_EQ(::send(peer, &k, sizeof k, 0), static_cast<ssize_t>(sizeof k)); }
};

TEST(SocketCanTransportIo, ReceivesFramesWithKernelTimestampsAndEventsSeparately) {
  FakeCanSocket s;
  std::vector<std::pair<std::string, TimePoint>> frames;
  std::vector<BusEvent> events;
  s.transport->set_receiver([&](const CanFrame& f, TimePoint t) { frames.emplace_back(f.to_string(), t); });
  s.transport->set_event_handler([&](BusEvent e) { events.push_back(e); });
  SteadyClock clock;
  const TimePoint before = clock.now();
  s.inject(kernel_frame(0x181, {0x01, 0x02}));
  s.inject(kernel_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, {0, CAN_ERR_CRTL_TX_PASSIVE, 0, 0, 0, 0, 0, 0}));
  s.inject(kernel_frame(0x18FF0001 | CAN_EFF_FLAG, {0xFF}));
  s.inject(kernel_frame(CAN_ERR_FLAG | CAN_ERR_BUSOFF, {0, 0, 0, 0, 0, 0, 0, 0}));
  s.transport->poll_readable();
  const TimePoint after = clock.now();
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].first, "181#0102");
  EXPECT_EQ(frames[1].first, "18FF0001#FF");
  for (const auto& [text, t] : frames) {
    EXPECT_GE(t, before - 1ms) << text;  // arrival time, mapped to the monotonic clock
    EXPECT_LE(t, after) << text;
  }
  EXPECT_THAT(events, ElementsAre(BusEvent::ErrorPassive, BusEvent::BusOff));
  EXPECT_EQ(s.transport->counters().rx_frames, 2u);
  EXPECT_EQ(s.transport->counters().error_frames, 2u);
  s.transport->poll_readable();  // nothing left: returns at once, no double delivery
  EXPECT_EQ(frames.size(), 2u);
}

TEST(SocketCanTransportIo, ABacklogKeepsItsArrivalTimesNotTheReadTime) {
  FakeCanSocket s;
  std::vector<TimePoint> stamps;
  s.transport->set_receiver([&](const CanFrame&, TimePoint t) { stamps.push_back(t); });
  EventLoop idle;  // nothing watched: run_once(timeout) just waits the timeout out
  SteadyClock clock;
  const TimePoint sent = clock.now();
  s.inject(kernel_frame(0x181, {}));
  idle.run_once(30ms);
  const TimePoint read_start = clock.now();
  ASSERT_GE(read_start - sent, 30ms);
  s.transport->poll_readable();
  ASSERT_EQ(stamps.size(), 1u);
  EXPECT_GE(stamps[0], sent - 1ms);
  EXPECT_LT(stamps[0], read_start - 20ms) << "stamped when read, not when it arrived";
}

TEST(SocketCanTransportIo, SkipsDatagramsOfTheWrongSizeAndCountsThem) {
  FakeCanSocket s;
  int frames = 0;
  s.transport->set_receiver([&](const CanFrame&, TimePoint) { ++frames; });
  const char junk[5] = {1, 2, 3, 4, 5};
  ASSERT_EQ(::send(s.peer, junk, sizeof junk, 0), 5);
  s.inject(kernel_frame(0x100, {}));
  s.transport->poll_readable();
  EXPECT_EQ(frames, 1);
  EXPECT_EQ(s.transport->counters().errors, 1u);
}

TEST(SocketCanTransportIo, ReadsAtMostMaxBatchFramesPerPoll) {
  FakeCanSocket s(2);
  int frames = 0;
  s.transport->set_receiver([&](const CanFrame&, TimePoint) { ++frames; });
  for (int i = 0; i < 3; ++i) s.inject(kernel_frame(0x100, {}));
  s.transport->poll_readable();
  EXPECT_EQ(frames, 2);
  s.transport->poll_readable();
  EXPECT_EQ(frames, 3);
}

// recvmmsg takes 64 frames per call: a backlog larger than that arrives whole and in order.
TEST(SocketCanTransportIo, ABacklogBeyondOneBatchArrivesInOrder) {
  FakeCanSocket s;
  std::vector<std::uint32_t> ids;
  std::vector<TimePoint> stamps;
  s.transport->set_receiver([&](const CanFrame& f, TimePoint t) {
    ids.push_back(f.id);
    stamps.push_back(t);
  });
  for (std::uint32_t i = 0; i < 200; ++i) s.inject(kernel_frame(0x100 + i, {}));
  s.transport->poll_readable();
  ASSERT_EQ(ids.size(), 200u);
  for (std::uint32_t i = 0; i < 200; ++i) EXPECT_EQ(ids[i], 0x100 + i);
  EXPECT_TRUE(std::is_sorted(stamps.begin(), stamps.end()));
  s.transport->poll_readable();
  EXPECT_EQ(ids.size(), 200u);
}

// Through the event loop the transport stamps with the loop's held wake-up time as `now`: no
// frame is later than what every callback of that wake-up sees as the time.
TEST(SocketCanTransportIo, StampsAreNeverAfterTheLoopsNow) {
  FakeCanSocket s;
  EventLoop loop;
  std::vector<std::pair<TimePoint, TimePoint>> got;  // (stamp, loop.now() in the receiver)
  s.transport->set_receiver([&](const CanFrame&, TimePoint t) { got.emplace_back(t, loop.now()); });
  (void)watch_transport(loop, *s.transport);
  for (int i = 0; i < 5; ++i) s.inject(kernel_frame(0x181, {}));
  loop.run_once(1s);
  ASSERT_EQ(got.size(), 5u);
  for (const auto& [stamp, now] : got) {
    EXPECT_LE(stamp, now);
    EXPECT_EQ(now, got[0].second) << "one instant per wake-up";
  }
}

TEST(SocketCanTransportIo, SendWritesOneKernelFramePerCall) {
  FakeCanSocket s;
  ASSERT_TRUE(s.transport->send(CanFrame{0x18FF1234, {0xDE, 0xAD}}).ok());
  ::can_frame k;
  ASSERT_EQ(::recv(s.peer, &k, sizeof k, MSG_DONTWAIT), static_cast<ssize_t>(sizeof k));
  EXPECT_EQ(k.can_id, 0x18FF1234u | CAN_EFF_FLAG);
  EXPECT_EQ(k.len, 2);
  EXPECT_EQ(k.data[0], 0xDE);
  EXPECT_EQ(k.data[1], 0xAD);
  EXPECT_EQ(s.transport->counters().tx_frames, 1u);
}

// A batch: held until end_batch(), then all of them, in order, in one sendmmsg().
TEST(SocketCanTransportIo, ABatchGoesOutTogetherAtItsEnd) {
  FakeCanSocket s;
  s.transport->begin_batch();
  for (std::uint32_t i = 0; i < 3; ++i) ASSERT_TRUE(s.transport->send(CanFrame{0x181 + i, {std::uint8_t(i)}}).ok());
  ::can_frame k;
  EXPECT_LT(::recv(s.peer, &k, sizeof k, MSG_DONTWAIT), 0) << "held until the batch ends";
  EXPECT_EQ(s.transport->counters().tx_frames, 0u);
  s.transport->end_batch();
  for (std::uint32_t i = 0; i < 3; ++i) {
    ASSERT_EQ(::recv(s.peer, &k, sizeof k, MSG_DONTWAIT), static_cast<ssize_t>(sizeof k));
    EXPECT_EQ(k.can_id, 0x181 + i);
    EXPECT_EQ(k.data[0], i);
  }
  EXPECT_EQ(s.transport->counters().tx_frames, 3u);
  ASSERT_TRUE(s.transport->send(CanFrame{0x200, {}}).ok());  // after the batch: at once
  EXPECT_EQ(::recv(s.peer, &k, sizeof k, MSG_DONTWAIT), static_cast<ssize_t>(sizeof k));
}

TEST(SocketCanTransportIo, ABatchIntoAFullQueueCountsWhatItDropped) {
  FakeCanSocket s;
  int fit = 0;
  while (s.transport->send(CanFrame{0x181, {1}}).ok() && fit < 1'000'000) ++fit;  // fill the queue
  const std::uint64_t dropped = s.transport->counters().tx_dropped;
  s.transport->begin_batch();
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(s.transport->send(CanFrame{0x182, {2}}).ok());
  s.transport->end_batch();
  EXPECT_EQ(s.transport->counters().tx_dropped, dropped + 5);
  EXPECT_EQ(s.transport->counters().errors, 0u) << "a full queue is not an error";
}

// Through the loop: what one wake-up sends leaves when its dispatch ends; an unwatch inside the
// wake-up sends what the transport held.
TEST(SocketCanTransportIo, TheLoopBatchesWhatAWakeUpSends) {
  FakeCanSocket s;
  EventLoop loop;
  std::size_t seen_by_peer_during_dispatch = 99;
  s.transport->set_receiver([&](const CanFrame& f, TimePoint) {
    (void)s.transport->send(CanFrame{f.id + 1, {}});
    (void)s.transport->send(CanFrame{f.id + 2, {}});
    int pending = 0;
    ::ioctl(s.peer, FIONREAD, &pending);
    seen_by_peer_during_dispatch = static_cast<std::size_t>(pending);
  });
  const EventLoop::WatchId id = watch_transport(loop, *s.transport);
  s.inject(kernel_frame(0x100, {}));
  loop.run_once(1s);
  EXPECT_EQ(seen_by_peer_during_dispatch, 0u);
  ::can_frame k;
  for (std::uint32_t want : {0x101u, 0x102u}) {
    ASSERT_EQ(::recv(s.peer, &k, sizeof k, MSG_DONTWAIT), static_cast<ssize_t>(sizeof k));
    EXPECT_EQ(k.can_id, want);
  }
  s.transport->set_receiver([&](const CanFrame&, TimePoint) {
    (void)s.transport->send(CanFrame{0x300, {}});
    loop.unwatch(id);
  });
  s.inject(kernel_frame(0x100, {}));
  loop.run_once(1s);
  ASSERT_EQ(::recv(s.peer, &k, sizeof k, MSG_DONTWAIT), static_cast<ssize_t>(sizeof k)) << "sent at the unwatch";
  EXPECT_EQ(k.can_id, 0x300u);
  ASSERT_TRUE(s.transport->send(CanFrame{0x301, {}}).ok());
  EXPECT_EQ(::recv(s.peer, &k, sizeof k, MSG_DONTWAIT), static_cast<ssize_t>(sizeof k)) << "no batch left open";
}

TEST(SocketCanTransportIo, InvalidFrameIsRefusedWithoutWriting) {
  FakeCanSocket s;
  CanFrame bad{0x100, {}};
  bad.dlc = 9;
  EXPECT_EQ(s.transport->send(bad).status, SendStatus::InvalidFrame);
  ::can_frame k;
  EXPECT_LT(::recv(s.peer, &k, sizeof k, MSG_DONTWAIT), 0);
  EXPECT_EQ(s.transport->counters().tx_frames, 0u);
}

TEST(SocketCanTransportIo, FullTxQueueDropsAndCountsInsteadOfBlocking) {
  FakeCanSocket s;
  SendResult r;
  int sent = 0;
  while ((r = s.transport->send(CanFrame{0x181, {1}})).ok() && sent < 1'000'000) ++sent;
  EXPECT_EQ(r.status, SendStatus::QueueFull) << "after " << sent << " frames";
  EXPECT_EQ(r.error, EAGAIN);
  EXPECT_EQ(s.transport->counters().tx_dropped, 1u);
  EXPECT_EQ(s.transport->counters().tx_frames, static_cast<std::uint64_t>(sent));
  EXPECT_EQ(s.transport->counters().errors, 0u) << "a full queue is not an error";
}

TEST(SocketCanTransportIo, EventLoopPollsTheTransportWhenReadable) {
  FakeCanSocket s;
  EventLoop loop;
  std::vector<std::string> got;
  s.transport->set_receiver([&](const CanFrame& f, TimePoint) { got.push_back(f.to_string()); });
  EXPECT_NE(watch_transport(loop, *s.transport), 0u);
  EXPECT_EQ(loop.run_once(0us), 0u);
  s.inject(kernel_frame(0x701, {0x7F}));
  loop.run_once(1s);
  EXPECT_THAT(got, ElementsAre("701#7F"));
}

TEST(SocketCanTransportIo, AdoptRejectsABadDescriptor) {
  EXPECT_THROW((void)SocketCanTransport::adopt(-1, "x"), std::invalid_argument);
}

// ---- send validation (no socket needed) ---------------------------------------------------

TEST(CanTransportHelpers, FrameValidity) {
  EXPECT_TRUE(is_valid_frame(CanFrame{0x7FF, {}}));
  CanFrame f{0x7FF, {}};
  f.id = 0x800;
  EXPECT_FALSE(is_valid_frame(f));
  f.extended = true;
  EXPECT_TRUE(is_valid_frame(f));
  f.id = 0x20000000;
  EXPECT_FALSE(is_valid_frame(f));
  CanFrame g{0x100, {}};
  g.dlc = 9;
  EXPECT_FALSE(is_valid_frame(g));
}

TEST(CanTransportHelpers, NamesForLogs) {
  EXPECT_EQ(to_string(BusEvent::BusOff), "bus off");
  EXPECT_EQ(to_string(BusEvent::ErrorPassive), "error passive");
  EXPECT_EQ(to_string(SendStatus::QueueFull), "TX queue full, frame dropped");
}

}  // namespace
