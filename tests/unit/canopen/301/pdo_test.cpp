// PDO transmission and reception (CiA 301 §7.2.2, objects 1400h..1BFFh), frame by frame.
#include "canopen/301/pdo.hpp"

#include "canopen/301/emcy.hpp"
#include "canopen/301/sync.hpp"

#include <gtest/gtest.h>

#include <utility>
#include <vector>

namespace oegw::canopen {
namespace {

using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

class PdoFixture : public ::testing::Test {
 protected:
  ObjectDictionary od;
  std::vector<CanFrame> sent;
  std::vector<std::pair<std::uint16_t, std::uint16_t>> length_errors;
  std::vector<std::uint16_t> timeouts;
  TimePoint t0{Duration{5'000'000}};

  PdoFixture() {
    // MCB-402 §5 (operation mode 4): 6000h input bytes, 6401h signed 16-bit axes, 6200h outputs.
    od.add_array(0x6000, "Read input 8-bit", DataType::Unsigned8, Access::ReadOnly, 4, {0}, true);
    od.add_array(0x6401, "Read analogue input 16-bit", DataType::Integer16, Access::ReadOnly, 4, {0, 0}, true);
    od.add_array(0x6200, "Write output 8-bit", DataType::Unsigned8, Access::ReadWrite, 2, {0}, true);
    od.add_var(0x2000, "Mappable u32", DataType::Unsigned32, Access::ReadWrite, {0, 0, 0, 0}, true);
    od.add_var(0x2010, "Flag A", DataType::Boolean, Access::ReadWrite, {0}, true);
    od.add_var(0x2011, "Flag B", DataType::Boolean, Access::ReadWrite, {0}, true);
  }

  std::unique_ptr<PdoService> make() {
    auto s = std::make_unique<PdoService>(od, [this](const CanFrame& f) { sent.push_back(f); });
    s->on_length_error = [this](std::uint16_t n, std::uint16_t code) { length_errors.emplace_back(n, code); };
    s->on_rpdo_timeout = [this](std::uint16_t n) { timeouts.push_back(n); };
    return s;
  }

  // TPDO 1 of node 5 mapping the three MCB-402 input bytes 6000h:01..03 (MCB-402 §5, "Example":
  // 1A00.01 = 60000108h, 1A00.02 = 60000208h, 1A00.03 = 60000308h).
  PdoParameters tpdo1(std::uint8_t type) {
    PdoParameters p;
    p.cob_id = 0x40000185;  // valid, no RTR
    p.transmission_type = type;
    p.mapping = {0x60000108, 0x60000208, 0x60000308};
    return p;
  }

  void set_input(std::uint8_t sub, std::uint8_t v) {
    ASSERT_EQ(od.set<std::uint8_t>(0x6000, sub, v), SdoAbortCode::None);
  }
};

TEST_F(PdoFixture, InstallCreatesCommunicationAndMappingObjects) {
  PdoParameters p = tpdo1(255);
  p.inhibit_time = 7;
  p.event_timer = 9;
  p.sync_start = 2;
  install_tpdo(od, 1, p);
  install_rpdo(od, 34, {.cob_id = 0x80000222, .mapping = {0x62000108}});
  EXPECT_EQ(od.get<std::uint32_t>(0x1800, 1), 0x40000185u);
  EXPECT_EQ(od.get<std::uint8_t>(0x1800, 2), 255u);
  EXPECT_EQ(od.get<std::uint16_t>(0x1800, 3), 7u);
  EXPECT_EQ(od.get<std::uint16_t>(0x1800, 5), 9u);
  EXPECT_EQ(od.get<std::uint8_t>(0x1800, 6), 2u);
  EXPECT_EQ(od.get<std::uint8_t>(0x1800, 0), 6u);  // highest sub-index
  EXPECT_EQ(od.get<std::uint8_t>(0x1A00, 0), 3u);  // number of mapped objects, not highest sub-index
  EXPECT_EQ(od.get<std::uint32_t>(0x1A00, 2), 0x60000208u);
  EXPECT_NE(od.find(0x1A00, 8), nullptr);
  EXPECT_EQ(od.find(0x1A00, 9), nullptr);
  // RPDO 34 = 1421h/1621h; an RPDO has no inhibit time and no SYNC start value.
  EXPECT_EQ(od.get<std::uint32_t>(0x1421, 1), 0x80000222u);
  EXPECT_EQ(od.find(0x1421, 3), nullptr);
  EXPECT_EQ(od.find(0x1421, 6), nullptr);
  EXPECT_EQ(od.get<std::uint8_t>(0x1621, 0), 1u);
  auto svc = make();
  ASSERT_NE(svc->tpdo(1), nullptr);
  ASSERT_NE(svc->rpdo(34), nullptr);
  EXPECT_EQ(svc->tpdo(2), nullptr);
  EXPECT_EQ(svc->tpdo(1)->dlc(), 3u);
}

// CiA 852 §12.1: type FFh TPDOs are sent on entering Operational and when mapped data change.
TEST_F(PdoFixture, EventDrivenSendsOnOperationalAndOnChangeOnly) {
  install_tpdo(od, 1, tpdo1(255));
  auto svc = make();
  set_input(1, 0x11);
  svc->advance(t0);
  EXPECT_TRUE(sent.empty()) << "nothing outside Operational";
  EXPECT_FALSE(svc->next_deadline().has_value());

  svc->set_operational(true, t0);
  ASSERT_TRUE(svc->next_deadline().has_value());
  svc->advance(t0);
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], CanFrame(0x185, {0x11, 0x00, 0x00}));

  set_input(3, 0xA5);
  svc->advance(t0 + 1ms);
  ASSERT_EQ(sent.size(), 2u);
  EXPECT_EQ(sent[1], CanFrame(0x185, {0x11, 0x00, 0xA5}));

  set_input(3, 0xA5);  // same value rewritten: not a change
  svc->advance(t0 + 2ms);
  EXPECT_EQ(sent.size(), 2u);
  EXPECT_FALSE(svc->next_deadline().has_value());

  od.set<std::uint8_t>(0x6000, 4, 0x77);  // not mapped
  svc->advance(t0 + 3ms);
  EXPECT_EQ(sent.size(), 2u);

  svc->set_operational(false, t0 + 4ms);
  set_input(1, 0x22);
  svc->advance(t0 + 5ms);
  EXPECT_EQ(sent.size(), 2u);
}

TEST_F(PdoFixture, RequestSendsEvenWithoutChange) {
  install_tpdo(od, 1, tpdo1(254));
  auto svc = make();
  svc->set_operational(true, t0);
  svc->advance(t0);
  ASSERT_EQ(sent.size(), 1u);
  svc->tpdo(1)->request();
  svc->advance(t0 + 1ms);
  EXPECT_EQ(sent.size(), 2u);
  svc->tpdo(1)->request(t0 + 2ms);  // immediate form
  EXPECT_EQ(sent.size(), 3u);
}

// CiA 301 §7.5.2.37 sub-index 3 (Novotechnik §4.1 1800/3: "Inhibit Time in (multiples of) 100 µs").
TEST_F(PdoFixture, InhibitTimeDelaysAndSendsLatestValue) {
  PdoParameters p = tpdo1(255);
  p.inhibit_time = 100;  // 10 ms
  install_tpdo(od, 1, p);
  auto svc = make();
  svc->set_operational(true, t0);
  svc->advance(t0);
  ASSERT_EQ(sent.size(), 1u);

  set_input(1, 1);
  svc->advance(t0 + 1ms);
  EXPECT_EQ(sent.size(), 1u) << "inhibited";
  EXPECT_EQ(svc->next_deadline(), t0 + 10ms);
  set_input(1, 2);
  svc->advance(t0 + 5ms);
  set_input(1, 3);
  svc->advance(t0 + 9999us);
  EXPECT_EQ(sent.size(), 1u);
  svc->advance(t0 + 10ms);
  ASSERT_EQ(sent.size(), 2u);
  EXPECT_EQ(sent[1], CanFrame(0x185, {3, 0, 0})) << "the latest value, once";
  svc->advance(t0 + 30ms);
  EXPECT_EQ(sent.size(), 2u);
  // A change long after the inhibit time goes out at once.
  set_input(1, 4);
  svc->advance(t0 + 31ms);
  EXPECT_EQ(sent.size(), 3u);
}

// MCB-402 §4 "Using in a non CANopen network": "Write : 603 22 01 18 05 aa bb 00 00 0xbbaa =
// duration in ms. The MCB402 returns now the values of axis each 0xbbaa ms : 283 aa bb cc dd ee
// ff gg hh", axes X Y Z T signed 16-bit little endian ("The word for X axis is 0xbbaa").
TEST_F(PdoFixture, Mcb402EventTimerExample) {
  install_tpdo(od, 2,
               {.cob_id = 0x40000283,
                .transmission_type = 255,
                .mapping = {0x64010110, 0x64010210, 0x64010310, 0x64010410}});
  auto svc = make();
  od.set<std::int16_t>(0x6401, 1, 0x7FFF);                // X pushed to 5 V
  od.set<std::int16_t>(0x6401, 2, std::int16_t{-32768});  // Y pulled to 0 V: 0x8000
  od.set<std::int16_t>(0x6401, 3, 0x1234);
  svc->set_operational(true, t0);  // "000 01 03" starts the node
  svc->advance(t0);
  ASSERT_EQ(sent.size(), 1u);
  const CanFrame expected(0x283, {0xFF, 0x7F, 0x00, 0x80, 0x34, 0x12, 0x00, 0x00});
  EXPECT_EQ(sent[0], expected);
  EXPECT_FALSE(svc->next_deadline().has_value()) << "no event timer yet";

  // 1801h:05 = 0x0064 = 100 ms (the SDO server hands the OD the UNSIGNED16's two bytes).
  ASSERT_EQ(od.write(0x1801, 5, Bytes{0x64, 0x00}), SdoAbortCode::None);
  svc->advance(t0 + 3ms);  // the loop calls advance after the SDO write; the timer starts here
  EXPECT_EQ(sent.size(), 1u) << "a new event timer is not a data change";
  od.set<std::int16_t>(0x6401, 1, 0x7FFF);  // rewritten, unchanged
  svc->advance(t0 + 4ms);
  EXPECT_EQ(sent.size(), 1u);
  EXPECT_EQ(svc->next_deadline(), t0 + 103ms);
  svc->advance(t0 + 102ms);
  EXPECT_EQ(sent.size(), 1u);
  svc->advance(t0 + 103ms);
  ASSERT_EQ(sent.size(), 2u);
  EXPECT_EQ(sent[1], expected) << "sent although nothing changed";
  svc->advance(t0 + 203ms);
  EXPECT_EQ(sent.size(), 3u);
  // A change-driven transmission restarts the timer.
  od.set<std::int16_t>(0x6401, 4, 1);
  svc->advance(t0 + 250ms);
  ASSERT_EQ(sent.size(), 4u);
  EXPECT_EQ(svc->next_deadline(), t0 + 350ms);
  svc->advance(t0 + 303ms);
  EXPECT_EQ(sent.size(), 4u);
  svc->advance(t0 + 350ms);
  EXPECT_EQ(sent.size(), 5u);
  // Event timer 0 stops the cyclic transmission.
  ASSERT_EQ(od.write(0x1801, 5, Bytes{0x00, 0x00}), SdoAbortCode::None);
  svc->advance(t0 + 351ms);
  svc->advance(t0 + 2s);
  EXPECT_EQ(sent.size(), 5u);
}

TEST_F(PdoFixture, EventTimerElapsingDuringInhibitWaitsForIt) {
  PdoParameters p = tpdo1(255);
  p.inhibit_time = 50;  // 5 ms
  p.event_timer = 3;    // 3 ms (a misconfiguration Novotechnik §8.2 warns about)
  install_tpdo(od, 1, p);
  auto svc = make();
  svc->set_operational(true, t0);
  svc->advance(t0);
  ASSERT_EQ(sent.size(), 1u);
  svc->advance(t0 + 3ms);
  EXPECT_EQ(sent.size(), 1u);
  EXPECT_EQ(svc->next_deadline(), t0 + 5ms);
  svc->advance(t0 + 5ms);
  EXPECT_EQ(sent.size(), 2u);
}

// MCB-402 §5 "Description of transmission type": "A transmission type of zero means that the
// message shall be transmitted synchronously with the SYNC object but not periodically but only
// in case of data change."
TEST_F(PdoFixture, Type0SendsAtSyncOnlyAfterChange) {
  install_tpdo(od, 1, tpdo1(0));
  auto svc = make();
  svc->set_operational(true, t0);
  svc->advance(t0);
  EXPECT_TRUE(sent.empty());
  svc->on_sync(0, t0 + 1ms);
  ASSERT_EQ(sent.size(), 0u) << "nothing changed since start";
  set_input(2, 9);
  svc->advance(t0 + 2ms);
  EXPECT_TRUE(sent.empty()) << "waits for SYNC";
  svc->on_sync(0, t0 + 3ms);
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], CanFrame(0x185, {0, 9, 0}));
  svc->on_sync(0, t0 + 4ms);
  EXPECT_EQ(sent.size(), 1u);
  svc->tpdo(1)->request();
  svc->on_sync(0, t0 + 5ms);
  EXPECT_EQ(sent.size(), 2u);
}

// "A value between 1 and 240 means that the PDO is transferred synchronously and cyclically, the
// transmission type indicating the number of SYNC signals" (MCB-402 §5).
TEST_F(PdoFixture, CyclicSyncEveryNth) {
  install_tpdo(od, 1, tpdo1(3));
  auto svc = make();
  svc->set_operational(true, t0);
  std::vector<int> at;
  for (int i = 1; i <= 7; ++i) {
    const std::size_t before = sent.size();
    svc->on_sync(0, t0 + i * 1ms);
    if (sent.size() != before) at.push_back(i);
  }
  EXPECT_EQ(at, (std::vector<int>{3, 6}));
  EXPECT_FALSE(svc->next_deadline().has_value());
}

TEST_F(PdoFixture, SyncStartValueDelaysFirstTransmission) {
  PdoParameters p = tpdo1(2);
  p.sync_start = 3;
  install_tpdo(od, 1, p);
  auto svc = make();
  svc->set_operational(true, t0);
  std::vector<int> at;
  for (std::uint8_t c = 1; c <= 8; ++c) {
    const std::size_t before = sent.size();
    svc->on_sync(c, t0 + c * 1ms);
    if (sent.size() != before) at.push_back(c);
  }
  EXPECT_EQ(at, (std::vector<int>{3, 5, 7}));
}

TEST_F(PdoFixture, SyncStartValueIgnoredWithoutCounter) {
  PdoParameters p = tpdo1(2);
  p.sync_start = 3;
  install_tpdo(od, 1, p);
  auto svc = make();
  svc->set_operational(true, t0);
  svc->on_sync(0, t0);
  svc->on_sync(0, t0 + 1ms);
  EXPECT_EQ(sent.size(), 1u);
}

// "At transmission type 252, the data is updated (but not sent) immediately after reception of
// the SYNC object. At transmission type 253 the data is updated at the reception of the remote
// frame." (MCB-402 §5)
TEST_F(PdoFixture, Type252SamplesAtSyncSendsOnRtr) {
  PdoParameters p = tpdo1(252);
  p.cob_id = 0x185;  // bit 30 = 0: RTR allowed
  install_tpdo(od, 1, p);
  auto svc = make();
  svc->set_operational(true, t0);
  EXPECT_TRUE(svc->on_frame(CanFrame::remote(0x185, 3), t0));
  EXPECT_TRUE(sent.empty()) << "nothing sampled yet";
  set_input(1, 1);
  svc->on_sync(0, t0 + 1ms);
  EXPECT_TRUE(sent.empty());
  set_input(1, 2);
  EXPECT_TRUE(svc->on_frame(CanFrame::remote(0x185, 3), t0 + 2ms));
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], CanFrame(0x185, {1, 0, 0})) << "the value at the SYNC, not the current one";
}

TEST_F(PdoFixture, Type253SendsCurrentDataOnRtr) {
  PdoParameters p = tpdo1(253);
  p.cob_id = 0x185;
  install_tpdo(od, 1, p);
  auto svc = make();
  svc->set_operational(true, t0);
  set_input(1, 7);
  svc->advance(t0);
  svc->on_sync(0, t0);
  EXPECT_TRUE(sent.empty());
  EXPECT_TRUE(svc->on_frame(CanFrame::remote(0x185, 3), t0 + 1ms));
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], CanFrame(0x185, {7, 0, 0}));
}

TEST_F(PdoFixture, RtrIgnoredWhenCobIdForbidsIt) {
  install_tpdo(od, 1, tpdo1(253));  // 0x40000185: bit 30 = 1, no RTR
  auto svc = make();
  svc->set_operational(true, t0);
  EXPECT_FALSE(svc->on_frame(CanFrame::remote(0x185, 3), t0));
  EXPECT_TRUE(sent.empty());
}

TEST_F(PdoFixture, ExtendedCobId) {
  PdoParameters p = tpdo1(255);
  p.cob_id = 0x60012345;  // bit 29: 29-bit identifier
  install_tpdo(od, 1, p);
  auto svc = make();
  svc->set_operational(true, t0);
  svc->advance(t0);
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0].id, 0x12345u);
  EXPECT_TRUE(sent[0].extended);
}

TEST_F(PdoFixture, BitMappedBooleans) {
  install_tpdo(od, 1, {.cob_id = 0x40000185, .mapping = {0x20100001, 0x20110001, 0x60000108}});
  auto svc = make();
  od.set<std::uint8_t>(0x2011, 0, 1);
  od.set<std::uint8_t>(0x6000, 1, 0xFF);
  svc->set_operational(true, t0);
  svc->advance(t0);
  ASSERT_EQ(sent.size(), 1u);
  // bit 0 = 2010h, bit 1 = 2011h, bits 2..9 = 6000h:01.
  EXPECT_EQ(sent[0], CanFrame(0x185, {0xFE, 0x03}));
}

// --- RPDO ---------------------------------------------------------------------------------------

// MCB-402 §5 default mapping: "RPDO1 6200.01 General-Purpose Output".
TEST_F(PdoFixture, RpdoEventDrivenWritesAtOnceWithPdoOrigin) {
  install_rpdo(od, 1, {.cob_id = 0x205, .transmission_type = 255, .mapping = {0x62000108}});
  std::vector<Origin> origins;
  const Subscription obs = od.add_observer([&](std::uint16_t index, std::uint8_t, Origin o) {
    if (index == 0x6200) origins.push_back(o);
  });
  auto svc = make();
  int received = 0;
  svc->on_rpdo = [&](std::uint16_t n) { received += n; };
  EXPECT_TRUE(svc->on_frame(CanFrame(0x205, {0x0F}), t0));
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0u) << "not Operational";
  svc->set_operational(true, t0);
  EXPECT_TRUE(svc->on_frame(CanFrame(0x205, {0x0F}), t0));
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0x0Fu);
  EXPECT_EQ(origins, (std::vector<Origin>{Origin::Pdo}));
  EXPECT_EQ(received, 1);
  EXPECT_FALSE(svc->on_frame(CanFrame(0x206, {0x01}), t0));
}

TEST_F(PdoFixture, RpdoSynchronousTakesEffectAtNextSync) {
  install_rpdo(od, 1, {.cob_id = 0x205, .transmission_type = 1, .mapping = {0x62000108, 0x62000208}});
  auto svc = make();
  svc->set_operational(true, t0);
  svc->on_frame(CanFrame(0x205, {1, 2}), t0);
  svc->on_frame(CanFrame(0x205, {3, 4}), t0 + 1ms);
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0u);
  svc->on_sync(0, t0 + 2ms);
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 3u) << "the last one received before the SYNC";
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 2), 4u);
  od.set<std::uint8_t>(0x6200, 1, 0);
  svc->on_sync(0, t0 + 3ms);
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0u) << "applied once";
}

// CiA 301 §7.2.2.1 / Table 26: EMCY 8210h "PDO not processed due to length error".
TEST_F(PdoFixture, RpdoTooShortReports8210AndIsNotProcessed) {
  install_rpdo(od, 3, {.cob_id = 0x405, .mapping = {0x62000108, 0x20000020}});
  auto svc = make();
  svc->set_operational(true, t0);
  EXPECT_TRUE(svc->on_frame(CanFrame(0x405, {1, 2, 3, 4}), t0));
  ASSERT_EQ(length_errors.size(), 1u);
  EXPECT_EQ(length_errors[0], (std::pair<std::uint16_t, std::uint16_t>{3, 0x8210}));
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0u);
  EXPECT_EQ(od.get<std::uint32_t>(0x2000, 0), 0u);
}

TEST_F(PdoFixture, RpdoTooLongUsesLeadingBytesAndReports8220) {
  install_rpdo(od, 1, {.cob_id = 0x205, .mapping = {0x62000108}});
  auto svc = make();
  svc->set_operational(true, t0);
  svc->on_frame(CanFrame(0x205, {0x5A, 0xEE}), t0);
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0x5Au);
  ASSERT_EQ(length_errors.size(), 1u);
  EXPECT_EQ(length_errors[0].second, 0x8220);
}

TEST_F(PdoFixture, RpdoDummyEntrySkipsBytes) {
  // MCB-402 §5: "The data type entries Index 0005 to 0007 ... may be mapped to PDOs in order to
  // define the appropriate space in the PDO."
  install_rpdo(od, 1, {.cob_id = 0x205, .mapping = {0x00060010, 0x62000108}});
  auto svc = make();
  svc->set_operational(true, t0);
  svc->on_frame(CanFrame(0x205, {0xAA, 0xBB, 0x42}), t0);
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0x42u);
  EXPECT_TRUE(length_errors.empty());
}

TEST_F(PdoFixture, RpdoEventTimerIsDeadlineMonitoring) {
  install_rpdo(od, 1, {.cob_id = 0x205, .event_timer = 50, .mapping = {0x62000108}});
  auto svc = make();
  svc->set_operational(true, t0);
  svc->advance(t0 + 1s);
  EXPECT_TRUE(timeouts.empty()) << "armed by the first reception only";
  EXPECT_FALSE(svc->next_deadline().has_value());
  svc->on_frame(CanFrame(0x205, {1}), t0 + 1s);
  EXPECT_EQ(svc->next_deadline(), t0 + 1050ms);
  svc->on_frame(CanFrame(0x205, {2}), t0 + 1040ms);  // re-arms
  svc->advance(t0 + 1050ms);
  EXPECT_TRUE(timeouts.empty());
  svc->advance(t0 + 1089ms);
  EXPECT_TRUE(timeouts.empty());
  svc->advance(t0 + 1090ms);
  EXPECT_EQ(timeouts, (std::vector<std::uint16_t>{1}));
  EXPECT_TRUE(svc->rpdo(1)->timed_out());
  svc->advance(t0 + 2s);
  EXPECT_EQ(timeouts.size(), 1u) << "reported once";
  svc->on_frame(CanFrame(0x205, {3}), t0 + 3s);
  EXPECT_FALSE(svc->rpdo(1)->timed_out());
}

// Only PDOs with a valid COB-ID and a mapping (TPDOs also event-driven) are walked after each
// frame; a parameter written while Operational must move a PDO into that set or out of it.
TEST_F(PdoFixture, ParametersWrittenWhileOperationalDecideWhichPdosRunOnTime) {
  PdoParameters sync_driven = tpdo1(1);
  sync_driven.event_timer = 100;
  install_tpdo(od, 1, sync_driven);
  install_tpdo(od, 2, {.cob_id = 0xC0000285, .transmission_type = 255, .mapping = {0x60000108}});
  install_rpdo(od, 1, {.cob_id = 0x80000205, .event_timer = 50, .mapping = {0x62000108}});
  auto svc = make();
  svc->set_operational(true, t0);
  svc->advance(t0);
  EXPECT_TRUE(sent.empty()) << "TPDO 1 runs on SYNC, TPDO 2 and RPDO 1 are not valid";
  EXPECT_FALSE(svc->next_deadline().has_value());

  // TPDO 1 made event-driven: its event timer (100 ms) starts.
  ASSERT_EQ(od.write(0x1800, 2, Bytes{0xFF}), SdoAbortCode::None);
  EXPECT_EQ(svc->next_deadline(), t0);
  svc->advance(t0 + 1ms);
  EXPECT_EQ(svc->next_deadline(), t0 + 101ms);
  svc->advance(t0 + 101ms);
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0].id, 0x185u);

  // TPDO 2 made valid while Operational: sent at once (CiA 852 §12.1).
  ASSERT_EQ(od.write(0x1801, 1, Bytes{0x85, 0x02, 0x00, 0x40}), SdoAbortCode::None);
  svc->advance(t0 + 102ms);
  ASSERT_EQ(sent.size(), 2u);
  EXPECT_EQ(sent[1].id, 0x285u);

  // RPDO 1 made valid: its deadline monitoring runs from the first reception.
  ASSERT_EQ(od.write(0x1400, 1, Bytes{0x05, 0x02, 0x00, 0x00}), SdoAbortCode::None);
  EXPECT_TRUE(svc->on_frame(CanFrame(0x205, {7}), t0 + 110ms));
  svc->advance(t0 + 160ms);
  EXPECT_EQ(timeouts, (std::vector<std::uint16_t>{1}));

  // TPDO 1 back on SYNC and TPDO 2 made invalid: neither is due any more.
  ASSERT_EQ(od.write(0x1800, 2, Bytes{0x01}), SdoAbortCode::None);
  ASSERT_EQ(od.write(0x1801, 1, Bytes{0x85, 0x02, 0x00, 0xC0}), SdoAbortCode::None);
  set_input(1, 0x42);
  svc->advance(t0 + 1s);
  EXPECT_EQ(sent.size(), 2u);
  EXPECT_FALSE(svc->next_deadline().has_value());

  // Outside Operational nothing runs; entering it again sends every event-driven TPDO (none).
  svc->set_operational(false, t0 + 2s);
  EXPECT_FALSE(svc->next_deadline().has_value());
  svc->set_operational(true, t0 + 3s);
  svc->advance(t0 + 3s);
  EXPECT_EQ(sent.size(), 2u);
}

// A sent TPDO's callback that writes PDO parameters (here TPDO 1 disables itself) rebuilds the
// walked lists mid-walk: every other due PDO is still serviced in the same advance(), once.
TEST_F(PdoFixture, AParameterWrittenByASentTpdosCallbackSkipsNoOtherPdo) {
  for (std::uint16_t n = 1; n <= 3; ++n)
    install_tpdo(od, n, {.cob_id = 0x40000180u + n, .transmission_type = 255, .mapping = {0x60000108}});
  PdoService svc(od, [this](const CanFrame& f) {
    sent.push_back(f);
    if (f.id == 0x181) {
      EXPECT_EQ(od.write(0x1800, 1, Bytes{0x81, 0x01, 0x00, 0xC0}), SdoAbortCode::None);
    }
  });
  svc.set_operational(true, t0);
  svc.advance(t0);
  ASSERT_EQ(sent.size(), 3u);
  EXPECT_EQ(sent[0].id, 0x181u);
  EXPECT_EQ(sent[1].id, 0x182u);
  EXPECT_EQ(sent[2].id, 0x183u);
  svc.advance(t0 + 1ms);
  EXPECT_EQ(sent.size(), 3u);
}

TEST_F(PdoFixture, ManyPdosWithArbitraryCobIds) {
  // CiA 852 §12: up to 41 TPDOs and 34 RPDOs, COB-IDs beyond the pre-defined connection set.
  for (std::uint16_t n = 1; n <= 34; ++n) install_rpdo(od, n, {.cob_id = 0x300u + n, .mapping = {0x62000108}});
  auto svc = make();
  svc->set_operational(true, t0);
  EXPECT_TRUE(svc->on_frame(CanFrame(0x300 + 34, {0x34}), t0));
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0x34u);
  EXPECT_TRUE(svc->on_frame(CanFrame(0x300 + 17, {0x17}), t0));
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0x17u);
}

TEST_F(PdoFixture, RpdoValueRefusedByLimitsLeavesOtherEntriesApplied) {
  od.find(0x6200, 1)->high = std::uint64_t{0x0F};
  install_rpdo(od, 1, {.cob_id = 0x205, .mapping = {0x62000108, 0x62000208}});
  auto svc = make();
  svc->set_operational(true, t0);
  svc->on_frame(CanFrame(0x205, {0x10, 0x22}), t0);
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0u) << "0x10 is above the limit";
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 2), 0x22u);
}

// One node wired as the services' headers describe: its own SYNC producer (Novotechnik §3: SYNC
// 0x080) drives a synchronous TPDO and RPDO; an RPDO length error becomes EMCY 8210h.
TEST_F(PdoFixture, WiredWithSyncProducerAndEmcy) {
  install_tpdo(od, 1, tpdo1(2));
  install_rpdo(od, 1, {.cob_id = 0x205, .transmission_type = 0, .mapping = {0x62000108, 0x62000208}});
  auto svc = make();
  SyncService sync(od, [this](const CanFrame& f) { sent.push_back(f); },
                   {.cob_id = 0x40000080, .period_us = 10'000, .counter_overflow = 4});
  EmcyProducer emcy(
      od, [this](const CanFrame& f) { sent.push_back(f); }, NodeId{5});
  sync.set_handler([&](std::uint8_t counter, TimePoint now) { svc->on_sync(counter, now); });
  svc->on_length_error = [&](std::uint16_t, std::uint16_t code) { emcy.raise(code, 0x10, t0); };
  svc->set_operational(true, t0);
  sync.advance(t0);
  svc->on_frame(CanFrame(0x205, {7, 8}), t0 + 1ms);
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 0u);
  sync.advance(t0 + 10ms);  // SYNC 1: RPDO applied, TPDO (every 2nd) not yet
  EXPECT_EQ(od.get<std::uint8_t>(0x6200, 1), 7u);
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent[0], CanFrame(0x080, {1}));
  sync.advance(t0 + 20ms);  // SYNC 2: TPDO
  ASSERT_EQ(sent.size(), 3u);
  EXPECT_EQ(sent[1], CanFrame(0x080, {2}));
  EXPECT_EQ(sent[2].id, 0x185u);
  svc->on_frame(CanFrame(0x205, {1}), t0 + 21ms);  // one byte short
  ASSERT_EQ(sent.size(), 4u);
  EXPECT_EQ(sent[3], CanFrame(0x085, {0x10, 0x82, 0x11, 0, 0, 0, 0, 0}));
}

}  // namespace
}  // namespace oegw::canopen
