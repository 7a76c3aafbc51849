// SdoServer, frame by frame (CiA 301 §7.2.4.3). Node-ID 3: requests on 603h, responses on 583h.
#include "canopen/301/sdo_server.hpp"

#include <gtest/gtest.h>

#include "canopen/301/crc16.hpp"
#include "sdo_test_support.hpp"

using namespace oegw::canopen;
using namespace sdo_test;
using namespace std::chrono_literals;

namespace {

constexpr std::uint32_t kRx = 0x603;
constexpr std::uint32_t kTx = 0x583;

class SdoServerTest : public ::testing::Test {
 protected:
  TestDictionary dict;
  std::vector<CanFrame> out;
  TimePoint t{std::chrono::seconds(100)};
  SdoServer server{dict.od, [this](const CanFrame& f) { out.push_back(f); }, NodeId{3}};

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
  static std::vector<CanFrame> tx(std::initializer_list<std::uint8_t> bytes) { return {CanFrame(kTx, bytes)}; }
  static std::vector<CanFrame> aborted(std::uint16_t index, std::uint8_t sub, SdoAbortCode code) {
    return {abort_frame(kTx, index, sub, code)};
  }
  static std::vector<CanFrame> none() { return {}; }
};

// ---------------------------------------------------------------------------------------------
// Reference-document vectors

// Novotechnik CANopen sensor protocol, §7.1 "SDO Download", example "object index 0x1010
// subindex 01 'store all parameters'": 600h+ID 23 10 10 01 73 61 76 65 -> 580h+ID 60 10 10 01 00..
TEST_F(SdoServerTest, NovotechnikStoreAllParameters) {
  EXPECT_EQ(rx({0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76, 0x65}), tx({0x60, 0x10, 0x10, 0x01, 0, 0, 0, 0}));
  EXPECT_EQ(dict.stores, 1);
}

// Novotechnik §7.1, "restore all parameters": 23 11 10 01 6C 6F 61 64 -> 60 11 10 01 00 00 00 00.
TEST_F(SdoServerTest, NovotechnikRestoreAllParameters) {
  EXPECT_EQ(rx({0x23, 0x11, 0x10, 0x01, 0x6C, 0x6F, 0x61, 0x64}), tx({0x60, 0x11, 0x10, 0x01, 0, 0, 0, 0}));
  EXPECT_EQ(dict.restores, 1);
}

// Novotechnik §7.1, "object index 0x2000 'set new node-ID' with 0x40":
// 2F 00 20 00 40 00 00 00 -> 60 00 20 00 00 00 00 00.
TEST_F(SdoServerTest, NovotechnikSetNodeId) {
  EXPECT_EQ(rx({0x2F, 0x00, 0x20, 0x00, 0x40, 0, 0, 0}), tx({0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(dict.value(0x2000), (std::vector<std::uint8_t>{0x40}));
}

// Novotechnik §7.3 "SDO Abort" (abort frame 0x80 index sub code) and CiA 301 §7.5.2.13: a
// wrong signature on 1010h is refused (our hook answers 0x08000020, as the MCB-402 manual
// §"1010h" describes) and nothing is stored.
TEST_F(SdoServerTest, NovotechnikWrongSignatureIsRefused) {
  EXPECT_EQ(rx({0x23, 0x10, 0x10, 0x01, 0x6B, 0x69, 0x6C, 0x6C}), aborted(0x1010, 1, SdoAbortCode::CannotTransfer));
  EXPECT_EQ(dict.stores, 0);
  EXPECT_EQ(dict.value(0x1010, 1), encode<std::uint32_t>(1));
}

// Novotechnik §7.2 "SDO Upload": 40 index sub -> 0x43 (4 bytes), 0x47 (3), 0x4B (2), 0x4F (1).
TEST_F(SdoServerTest, NovotechnikExpeditedUploadCommandBytes) {
  EXPECT_EQ(rx({0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), tx({0x43, 0x00, 0x10, 0x00, 0x96, 0x01, 0x08, 0x00}));
  EXPECT_EQ(rx({0x40, 0x02, 0x20, 0x00, 0, 0, 0, 0}), tx({0x47, 0x02, 0x20, 0x00, 0x01, 0x02, 0x03, 0x00}));
  EXPECT_EQ(rx({0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0}), tx({0x4B, 0x01, 0x20, 0x00, 0xEF, 0xBE, 0x00, 0x00}));
  EXPECT_EQ(rx({0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0}), tx({0x4F, 0x00, 0x20, 0x00, 0x01, 0x00, 0x00, 0x00}));
  // 1010h:01 reads 1: "store on command only" (MCB-402 manual, 1010h).
  EXPECT_EQ(rx({0x40, 0x10, 0x10, 0x01, 0, 0, 0, 0}), tx({0x43, 0x10, 0x10, 0x01, 0x01, 0x00, 0x00, 0x00}));
}

// MCB-402 manual (003_44a28fc862638d35.txt), §4 "Using in a non CANOPEN network", node 03h:
// "Write : 603 22 01 18 05 aa bb 00 00  0xbbaa = duration in ms" (TPDO2 event timer, listed in
// §5 as 1801h:05 rw). 0x22 = expedited, size not indicated, into an UNSIGNED16: the server takes
// the object's 2 bytes.
TEST_F(SdoServerTest, Mcb402EventTimerWrite) {
  EXPECT_EQ(rx({0x22, 0x01, 0x18, 0x05, 0xE8, 0x03, 0x00, 0x00}), tx({0x60, 0x01, 0x18, 0x05, 0, 0, 0, 0}));
  EXPECT_EQ(dict.od.get<std::uint16_t>(0x1801, 5), 1000);
  EXPECT_EQ(rx({0x40, 0x01, 0x18, 0x05, 0, 0, 0, 0}), tx({0x4B, 0x01, 0x18, 0x05, 0xE8, 0x03, 0, 0}));
}

// ---------------------------------------------------------------------------------------------
// Expedited

TEST_F(SdoServerTest, ExpeditedDownloadWithSizeIndicated) {
  EXPECT_EQ(rx({0x2B, 0x01, 0x20, 0x00, 0x34, 0x12, 0xFF, 0xFF}), tx({0x60, 0x01, 0x20, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(dict.od.get<std::uint16_t>(0x2001, 0), 0x1234);  // bytes beyond n are not taken
  EXPECT_FALSE(server.busy());
  EXPECT_EQ(server.next_deadline(), std::nullopt);
}

TEST_F(SdoServerTest, ExpeditedSizeVersusObjectLength) {
  // 3 bytes (0x27) into an UNSIGNED16: too long; 1 byte (0x2F): too short. Value unchanged.
  EXPECT_EQ(rx({0x27, 0x01, 0x20, 0x00, 1, 2, 3, 0}), aborted(0x2001, 0, SdoAbortCode::LengthTooHigh));
  EXPECT_EQ(rx({0x2F, 0x01, 0x20, 0x00, 1, 0, 0, 0}), aborted(0x2001, 0, SdoAbortCode::LengthTooLow));
  EXPECT_EQ(dict.od.get<std::uint16_t>(0x2001, 0), 0xBEEF);
}

TEST_F(SdoServerTest, ObjectDictionaryAbortCodesArePassedThrough) {
  EXPECT_EQ(rx({0x40, 0x34, 0x12, 0x00, 0, 0, 0, 0}), aborted(0x1234, 0, SdoAbortCode::ObjectDoesNotExist));
  EXPECT_EQ(rx({0x40, 0x01, 0x18, 0x03, 0, 0, 0, 0}), aborted(0x1801, 3, SdoAbortCode::SubIndexDoesNotExist));
  EXPECT_EQ(rx({0x40, 0x04, 0x20, 0x00, 0, 0, 0, 0}), aborted(0x2004, 0, SdoAbortCode::ReadOfWriteOnly));
  EXPECT_EQ(rx({0x23, 0x00, 0x10, 0x00, 1, 2, 3, 4}), aborted(0x1000, 0, SdoAbortCode::WriteOfReadOnly));
  EXPECT_EQ(rx({0x23, 0x03, 0x20, 0x00, 0xE9, 0x03, 0, 0}), aborted(0x2003, 0, SdoAbortCode::ValueTooHigh));
  EXPECT_EQ(dict.od.get<std::uint32_t>(0x2003, 0), 10u);
  EXPECT_EQ(rx({0x23, 0x03, 0x20, 0x00, 0xE8, 0x03, 0, 0}), tx({0x60, 0x03, 0x20, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(dict.od.get<std::uint32_t>(0x2003, 0), 1000u);
  // Segmented/block initiates check existence and access before any data is sent.
  EXPECT_EQ(rx({0x21, 0x00, 0x10, 0x00, 8, 0, 0, 0}), aborted(0x1000, 0, SdoAbortCode::WriteOfReadOnly));
  EXPECT_EQ(rx({0xC6, 0x99, 0x20, 0x00, 8, 0, 0, 0}), aborted(0x2099, 0, SdoAbortCode::ObjectDoesNotExist));
  EXPECT_EQ(rx({0xA4, 0x04, 0x20, 0x00, 127, 0, 0, 0}), aborted(0x2004, 0, SdoAbortCode::ReadOfWriteOnly));
}

// ---------------------------------------------------------------------------------------------
// Segmented

TEST_F(SdoServerTest, SegmentedUpload) {
  // "OEGW test device": 16 bytes -> 7 + 7 + 2.
  EXPECT_EQ(rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}), tx({0x41, 0x08, 0x10, 0x00, 16, 0, 0, 0}));
  EXPECT_TRUE(server.busy());
  EXPECT_EQ(rx({0x60, 0, 0, 0, 0, 0, 0, 0}), tx({0x00, 'O', 'E', 'G', 'W', ' ', 't', 'e'}));
  EXPECT_EQ(rx({0x70, 0, 0, 0, 0, 0, 0, 0}), tx({0x10, 's', 't', ' ', 'd', 'e', 'v', 'i'}));
  EXPECT_EQ(rx({0x60, 0, 0, 0, 0, 0, 0, 0}), tx({0x0B, 'c', 'e', 0, 0, 0, 0, 0}));  // n = 5, c = 1
  EXPECT_FALSE(server.busy());
}

// A change of the server's owner ends a transfer in progress with an abort naming its object
// (CiA 301 §7.2.4.3.17); an idle server sends nothing, and the next transfer starts afresh.
TEST_F(SdoServerTest, AbortInProgressTellsTheClientAndLeavesAnIdleServerSilent) {
  out.clear();
  server.abort_in_progress(SdoAbortCode::CannotTransferDeviceState);
  EXPECT_EQ(out, none());
  rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});
  rx({0x60, 0, 0, 0, 0, 0, 0, 0});
  ASSERT_TRUE(server.busy());
  out.clear();
  server.abort_in_progress(SdoAbortCode::CannotTransferDeviceState);
  EXPECT_EQ(out, aborted(0x1008, 0, SdoAbortCode::CannotTransferDeviceState));
  EXPECT_FALSE(server.busy());
  EXPECT_EQ(rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}), tx({0x41, 0x08, 0x10, 0x00, 16, 0, 0, 0}));
}

TEST_F(SdoServerTest, SegmentedUploadOfEmptyValue) {
  EXPECT_EQ(rx({0x40, 0x00, 0x21, 0x00, 0, 0, 0, 0}), tx({0x41, 0x00, 0x21, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(rx({0x60, 0, 0, 0, 0, 0, 0, 0}), tx({0x0F, 0, 0, 0, 0, 0, 0, 0}));  // n = 7, c = 1
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoServerTest, SegmentedUploadToggleError) {
  rx({0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});
  rx({0x60, 0, 0, 0, 0, 0, 0, 0});
  EXPECT_EQ(rx({0x60, 0, 0, 0, 0, 0, 0, 0}), aborted(0x1008, 0, SdoAbortCode::ToggleBitNotAlternated));
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoServerTest, SegmentedDownloadIsWrittenOnlyAtTheEnd) {
  const auto before = dict.value(0x2100);
  EXPECT_EQ(rx({0x21, 0x00, 0x21, 0x00, 10, 0, 0, 0}), tx({0x60, 0x00, 0x21, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(rx({0x00, 1, 2, 3, 4, 5, 6, 7}), tx({0x20, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(dict.value(0x2100), before);                                         // not yet
  EXPECT_EQ(rx({0x19, 8, 9, 10, 0, 0, 0, 0}), tx({0x30, 0, 0, 0, 0, 0, 0, 0}));  // t=1, n=4, c=1
  EXPECT_EQ(dict.value(0x2100), (std::vector<std::uint8_t>{1, 2, 3, 4, 5, 6, 7, 8, 9, 10}));
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoServerTest, SegmentedDownloadOfEmptyValue) {
  EXPECT_EQ(rx({0x21, 0x01, 0x21, 0x00, 0, 0, 0, 0}), tx({0x60, 0x01, 0x21, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(rx({0x0F, 0, 0, 0, 0, 0, 0, 0}), tx({0x20, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_TRUE(dict.value(0x2101).empty());
}

TEST_F(SdoServerTest, SegmentedDownloadToggleErrorChangesNothing) {
  rx({0x21, 0x00, 0x21, 0x00, 14, 0, 0, 0});
  rx({0x00, 1, 2, 3, 4, 5, 6, 7});
  EXPECT_EQ(rx({0x01, 8, 9, 10, 11, 12, 13, 14}), aborted(0x2100, 0, SdoAbortCode::ToggleBitNotAlternated));
  EXPECT_TRUE(dict.value(0x2100).empty());
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoServerTest, SegmentedDownloadAnnouncedSizeVersusObject) {
  // Fixed-size UNSIGNED16 announced as 3 or 1 bytes; a 10-byte string cap announced as 11.
  EXPECT_EQ(rx({0x21, 0x01, 0x20, 0x00, 3, 0, 0, 0}), aborted(0x2001, 0, SdoAbortCode::LengthTooHigh));
  EXPECT_EQ(rx({0x21, 0x01, 0x20, 0x00, 1, 0, 0, 0}), aborted(0x2001, 0, SdoAbortCode::LengthTooLow));
  EXPECT_EQ(rx({0x21, 0x01, 0x21, 0x00, 11, 0, 0, 0}), aborted(0x2101, 0, SdoAbortCode::LengthTooHigh));
  EXPECT_EQ(rx({0x21, 0x01, 0x21, 0x00, 0xFF, 0xFF, 0xFF, 0xFF}), aborted(0x2101, 0, SdoAbortCode::LengthTooHigh));
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoServerTest, SegmentedDownloadDataDisagreeingWithAnnouncedSize) {
  // Announced 5, sends 7: mismatch as soon as it overflows.
  rx({0x21, 0x01, 0x21, 0x00, 5, 0, 0, 0});
  EXPECT_EQ(rx({0x01, 1, 2, 3, 4, 5, 6, 7}), aborted(0x2101, 0, SdoAbortCode::LengthMismatch));
  // Announced 5, sends 3 and ends.
  rx({0x21, 0x01, 0x21, 0x00, 5, 0, 0, 0});
  EXPECT_EQ(rx({0x09, 1, 2, 3, 0, 0, 0, 0}), aborted(0x2101, 0, SdoAbortCode::LengthMismatch));
  EXPECT_EQ(dict.value(0x2101), bytes_of("abc"));
}

TEST_F(SdoServerTest, SegmentedDownloadWithoutSizeIsCappedAtMaxSize) {
  EXPECT_EQ(rx({0x20, 0x01, 0x21, 0x00, 0, 0, 0, 0}), tx({0x60, 0x01, 0x21, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(rx({0x00, 1, 2, 3, 4, 5, 6, 7}), tx({0x20, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(rx({0x10, 8, 9, 10, 11, 12, 13, 14}), aborted(0x2101, 0, SdoAbortCode::OutOfMemory));
  EXPECT_EQ(dict.value(0x2101), bytes_of("abc"));
  // A fixed-size object without announced size: more than its size is "too long".
  rx({0x20, 0x01, 0x20, 0x00, 0, 0, 0, 0});
  EXPECT_EQ(rx({0x0B, 1, 2, 0, 0, 0, 0, 0}), tx({0x20, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(dict.od.get<std::uint16_t>(0x2001, 0), 0x0201);
  rx({0x20, 0x01, 0x20, 0x00, 0, 0, 0, 0});
  EXPECT_EQ(rx({0x09, 1, 2, 3, 0, 0, 0, 0}), aborted(0x2001, 0, SdoAbortCode::LengthTooHigh));
  EXPECT_EQ(dict.od.get<std::uint16_t>(0x2001, 0), 0x0201);
}

TEST_F(SdoServerTest, SegmentedDownloadRefusedByHookChangesNothing) {
  rx({0x21, 0x02, 0x21, 0x00, 3, 0, 0, 0});
  EXPECT_EQ(rx({0x09, 1, 2, 3, 0, 0, 0, 0}), aborted(0x2102, 0, SdoAbortCode::InvalidValue));
  EXPECT_TRUE(dict.value(0x2102).empty());
  EXPECT_FALSE(server.busy());
}

// ---------------------------------------------------------------------------------------------
// Protocol errors

TEST_F(SdoServerTest, UnknownCommandSpecifier) {
  // ccs = 7 does not exist; without a transfer the abort echoes the frame's multiplexer.
  EXPECT_EQ(rx({0xE0, 0x00, 0x10, 0x00, 0, 0, 0, 0}), aborted(0x1000, 0, SdoAbortCode::UnknownCommandSpecifier));
  // Segment requests without a transfer.
  EXPECT_EQ(rx({0x60, 0x00, 0x10, 0x00, 0, 0, 0, 0}), aborted(0x1000, 0, SdoAbortCode::UnknownCommandSpecifier));
  EXPECT_EQ(rx({0x00, 0x01, 0x02, 0x03, 0, 0, 0, 0}), aborted(0x0201, 3, SdoAbortCode::UnknownCommandSpecifier));
  // Block sub-commands without a block transfer.
  EXPECT_EQ(rx({0xA3, 0, 0, 0, 0, 0, 0, 0}), aborted(0, 0, SdoAbortCode::UnknownCommandSpecifier));
  EXPECT_EQ(rx({0xC1, 0, 0, 0, 0, 0, 0, 0}), aborted(0, 0, SdoAbortCode::UnknownCommandSpecifier));
}

TEST_F(SdoServerTest, WrongCommandDuringTransferAbortsIt) {
  rx({0x21, 0x00, 0x21, 0x00, 10, 0, 0, 0});
  // An upload segment request in a segmented download.
  EXPECT_EQ(rx({0x60, 0, 0, 0, 0, 0, 0, 0}), aborted(0x2100, 0, SdoAbortCode::UnknownCommandSpecifier));
  EXPECT_FALSE(server.busy());
  EXPECT_EQ(rx({0x00, 1, 2, 3, 4, 5, 6, 7}), aborted(0x0201, 3, SdoAbortCode::UnknownCommandSpecifier));
  EXPECT_TRUE(dict.value(0x2100).empty());
}

// CiA 301 §7.2.4.3: every SDO frame has 8 data bytes. A shorter one is answered 0x05040001.
TEST_F(SdoServerTest, ShortFramesAreProtocolErrors) {
  EXPECT_EQ(rx({0x40, 0x00, 0x10, 0x00}), aborted(0x1000, 0, SdoAbortCode::UnknownCommandSpecifier));
  EXPECT_EQ(rx({0x23, 0x10, 0x10, 0x01, 0x73, 0x61, 0x76}), aborted(0x1010, 1, SdoAbortCode::UnknownCommandSpecifier));
  EXPECT_EQ(dict.stores, 0);
  EXPECT_EQ(rx({0x40, 0x00}), aborted(0, 0, SdoAbortCode::UnknownCommandSpecifier));
  EXPECT_EQ(rx({}), aborted(0, 0, SdoAbortCode::UnknownCommandSpecifier));
  // During a transfer: aborted with the transfer's multiplexer, nothing written.
  rx({0x21, 0x00, 0x21, 0x00, 3, 0, 0, 0});
  EXPECT_EQ(rx({0x09, 1, 2, 3}), aborted(0x2100, 0, SdoAbortCode::UnknownCommandSpecifier));
  EXPECT_FALSE(server.busy());
  EXPECT_TRUE(dict.value(0x2100).empty());
}

TEST_F(SdoServerTest, ClientAbortIsNeverAnswered) {
  EXPECT_EQ(rx({0x80, 0x00, 0x10, 0x00, 0, 0, 0, 0x08}), none());  // no transfer
  rx({0x21, 0x00, 0x21, 0x00, 10, 0, 0, 0});
  rx({0x00, 1, 2, 3, 4, 5, 6, 7});
  EXPECT_EQ(rx({0x80, 0x00, 0x21, 0x00, 0, 0, 0, 0x08}), none());
  EXPECT_FALSE(server.busy());
  EXPECT_TRUE(dict.value(0x2100).empty());
  rx({0x21, 0x00, 0x21, 0x00, 10, 0, 0, 0});
  EXPECT_EQ(rx({0x80, 0x00}), none());  // even a short one
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoServerTest, AnyAbortCommandByteEndsTheTransfer) {
  // ccs = 4 with reserved bits set is still an abort (CiA 301 §7.2.4.3.17).
  rx({0x21, 0x00, 0x21, 0x00, 10, 0, 0, 0});
  EXPECT_EQ(rx({0x9F, 0x00, 0x21, 0x00, 0, 0, 0, 0x08}), none());
  EXPECT_FALSE(server.busy());
  // Inside a block download sub-block 0x81 is "last segment, sequence number 1".
  rx({0xC2, 0x00, 0x21, 0x00, 2, 0, 0, 0});
  EXPECT_EQ(rx({0x81, 0xAA, 0xBB, 0, 0, 0, 0, 0}), tx({0xA2, 1, 127, 0, 0, 0, 0, 0}));
  EXPECT_EQ(rx({0xD5, 0, 0, 0, 0, 0, 0, 0}), tx({0xA1, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(dict.value(0x2100), (std::vector<std::uint8_t>{0xAA, 0xBB}));
}

TEST_F(SdoServerTest, RemoteFramesAreIgnored) {
  out.clear();
  EXPECT_TRUE(server.on_frame(CanFrame::remote(kRx, 8), t));
  EXPECT_EQ(out, none());
}

TEST_F(SdoServerTest, OtherIdsAreNotConsumed) {
  out.clear();
  EXPECT_FALSE(server.on_frame(CanFrame(0x604, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), t));
  EXPECT_FALSE(server.on_frame(CanFrame(kTx, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), t));
  EXPECT_EQ(out, none());
}

TEST_F(SdoServerTest, TimeoutAbortsAndFreesTheServer) {
  EXPECT_EQ(server.next_deadline(), std::nullopt);
  rx({0x21, 0x00, 0x21, 0x00, 10, 0, 0, 0});
  EXPECT_EQ(server.next_deadline(), t + 1s);
  t += 500ms;
  rx({0x00, 1, 2, 3, 4, 5, 6, 7});
  EXPECT_EQ(server.next_deadline(), t + 1s);  // rearmed by each request
  out.clear();
  server.advance(t + 999ms);
  EXPECT_EQ(out, none());
  EXPECT_TRUE(server.busy());
  server.advance(t + 1s);
  EXPECT_EQ(out, aborted(0x2100, 0, SdoAbortCode::Timeout));
  EXPECT_FALSE(server.busy());
  EXPECT_EQ(server.next_deadline(), std::nullopt);
  EXPECT_TRUE(dict.value(0x2100).empty());
  t += 2s;
  EXPECT_EQ(rx({0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0}), tx({0x4F, 0x00, 0x20, 0x00, 0x01, 0, 0, 0}));
}

TEST_F(SdoServerTest, CustomTimeout) {
  SdoServer fast(
      dict.od, [this](const CanFrame& f) { out.push_back(f); }, CobId(0x610), CobId(0x590), 50ms);
  fast.on_frame(CanFrame(0x610, {0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}), t);
  EXPECT_EQ(fast.next_deadline(), t + 50ms);
  out.clear();
  fast.advance(t + 50ms);
  EXPECT_EQ(out, (std::vector<CanFrame>{abort_frame(0x590, 0x1008, 0, SdoAbortCode::Timeout)}));
}

TEST_F(SdoServerTest, NewInitiateAbandonsTheOldTransferSilently) {
  rx({0x21, 0x00, 0x21, 0x00, 10, 0, 0, 0});
  rx({0x00, 1, 2, 3, 4, 5, 6, 7});
  // The client starts over with an upload: answered, no abort frame for the old transfer.
  EXPECT_EQ(rx({0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0}), tx({0x4F, 0x00, 0x20, 0x00, 0x01, 0, 0, 0}));
  EXPECT_FALSE(server.busy());
  // The old transfer's last segment has nothing to belong to.
  EXPECT_EQ(rx({0x19, 8, 9, 10, 0, 0, 0, 0}), aborted(0x0908, 10, SdoAbortCode::UnknownCommandSpecifier));
  EXPECT_TRUE(dict.value(0x2100).empty());
  // Same with a new segmented download replacing an old one: only the new data lands.
  rx({0x21, 0x00, 0x21, 0x00, 10, 0, 0, 0});
  rx({0x00, 1, 2, 3, 4, 5, 6, 7});
  EXPECT_EQ(rx({0x21, 0x00, 0x21, 0x00, 2, 0, 0, 0}), tx({0x60, 0x00, 0x21, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(rx({0x0B, 0xAA, 0xBB, 0, 0, 0, 0, 0}), tx({0x20, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(dict.value(0x2100), (std::vector<std::uint8_t>{0xAA, 0xBB}));
}

TEST_F(SdoServerTest, ResetDropsTransferWithoutAFrame) {
  rx({0x21, 0x00, 0x21, 0x00, 10, 0, 0, 0});
  out.clear();
  server.reset();
  EXPECT_EQ(out, none());
  EXPECT_FALSE(server.busy());
  EXPECT_EQ(server.next_deadline(), std::nullopt);
}

TEST_F(SdoServerTest, SetCobIdsMovesTheChannel) {
  rx({0x21, 0x00, 0x21, 0x00, 10, 0, 0, 0});
  server.set_cob_ids(CobId(0x640), CobId(0x5C0));
  EXPECT_FALSE(server.busy());
  out.clear();
  EXPECT_FALSE(server.on_frame(CanFrame(kRx, {0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0}), t));
  EXPECT_TRUE(server.on_frame(CanFrame(0x640, {0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0}), t));
  EXPECT_EQ(out, (std::vector<CanFrame>{CanFrame(0x5C0, {0x4F, 0x00, 0x20, 0x00, 0x01, 0, 0, 0})}));
  // Bit 31 set: the channel is not valid, the server is disabled.
  server.set_cob_ids(CobId(0x80000640), CobId(0x5C0));
  out.clear();
  EXPECT_FALSE(server.on_frame(CanFrame(0x640, {0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0}), t));
  EXPECT_EQ(out, none());
}

// ---------------------------------------------------------------------------------------------
// Block download (CiA 301 §7.2.4.3.9 - .14)

TEST_F(SdoServerTest, BlockDownloadWithCrc) {
  const auto data = pattern(20);
  // cc = 1, s = 1, size 20 -> sc = 1, blksize 127.
  EXPECT_EQ(rx({0xC6, 0x00, 0x21, 0x00, 20, 0, 0, 0}), tx({0xA4, 0x00, 0x21, 0x00, 127, 0, 0, 0}));
  EXPECT_EQ(rx({0x01, data[0], data[1], data[2], data[3], data[4], data[5], data[6]}), none());
  EXPECT_EQ(rx({0x02, data[7], data[8], data[9], data[10], data[11], data[12], data[13]}), none());
  // Last segment (c = 1) carries 6 bytes: the sub-block is acknowledged at once.
  EXPECT_EQ(rx({0x83, data[14], data[15], data[16], data[17], data[18], data[19], 0}),
            tx({0xA2, 3, 127, 0, 0, 0, 0, 0}));
  EXPECT_TRUE(dict.value(0x2100).empty());  // not before the end
  const std::uint16_t crc = crc16_ccitt(data);
  // End: n = 1 unused byte -> 0xC1 | 1 << 2.
  EXPECT_EQ(rx({0xC5, static_cast<std::uint8_t>(crc), static_cast<std::uint8_t>(crc >> 8), 0, 0, 0, 0, 0}),
            tx({0xA1, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(dict.value(0x2100), data);
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoServerTest, BlockDownloadInSeveralSubBlocksWithoutCrc) {
  server.set_block_size(2);
  const auto data = pattern(30);  // 5 segments: 2 + 2 + 1
  EXPECT_EQ(rx({0xC2, 0x00, 0x21, 0x00, 30, 0, 0, 0}), tx({0xA4, 0x00, 0x21, 0x00, 2, 0, 0, 0}));
  std::size_t p = 0;
  const auto seg = [&](std::uint8_t seq, bool last) {
    CanFrame f(kRx, {seq, 0, 0, 0, 0, 0, 0, 0});
    if (last) f.data[0] |= 0x80;
    for (int i = 1; i < 8 && p < data.size(); ++i) f.data[static_cast<std::size_t>(i)] = data[p++];
    return rx(f);
  };
  EXPECT_EQ(seg(1, false), none());
  EXPECT_EQ(seg(2, false), tx({0xA2, 2, 2, 0, 0, 0, 0, 0}));
  EXPECT_EQ(seg(1, false), none());
  EXPECT_EQ(seg(2, false), tx({0xA2, 2, 2, 0, 0, 0, 0, 0}));
  EXPECT_EQ(seg(1, true), tx({0xA2, 1, 2, 0, 0, 0, 0, 0}));
  // CRC field ignored without cc: 0xC1 | 5 << 2 (2 bytes used in the last segment).
  EXPECT_EQ(rx({0xD5, 0xDE, 0xAD, 0, 0, 0, 0, 0}), tx({0xA1, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(dict.value(0x2100), data);
}

TEST_F(SdoServerTest, BlockDownloadCrcErrorChangesNothing) {
  rx({0xC6, 0x00, 0x21, 0x00, 3, 0, 0, 0});
  EXPECT_EQ(rx({0x81, 1, 2, 3, 0, 0, 0, 0}), tx({0xA2, 1, 127, 0, 0, 0, 0, 0}));
  const std::uint16_t good = crc16_ccitt(std::vector<std::uint8_t>{1, 2, 3});
  const auto bad = static_cast<std::uint16_t>(good ^ 0x0100);
  EXPECT_EQ(rx({0xD1, static_cast<std::uint8_t>(bad), static_cast<std::uint8_t>(bad >> 8), 0, 0, 0, 0, 0}),
            aborted(0x2100, 0, SdoAbortCode::CrcError));
  EXPECT_TRUE(dict.value(0x2100).empty());
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoServerTest, BlockDownloadInvalidSequenceNumbers) {
  server.set_block_size(4);
  rx({0xC2, 0x00, 0x21, 0x00, 40, 0, 0, 0});
  EXPECT_EQ(rx({0x05, 1, 2, 3, 4, 5, 6, 7}), aborted(0x2100, 0, SdoAbortCode::InvalidSequenceNumber));
  rx({0xC2, 0x00, 0x21, 0x00, 40, 0, 0, 0});
  EXPECT_EQ(rx({0x00, 1, 2, 3, 4, 5, 6, 7}), aborted(0x2100, 0, SdoAbortCode::InvalidSequenceNumber));
  EXPECT_TRUE(dict.value(0x2100).empty());
  EXPECT_FALSE(server.busy());
}

// CiA 301 §7.2.4.3.9: a lost segment is not fatal; the server acknowledges the last one it got
// in sequence and the client retransmits from there.
TEST_F(SdoServerTest, BlockDownloadLostSegmentIsRetransmitted) {
  server.set_block_size(3);
  const auto data = pattern(21);  // 3 full segments
  rx({0xC2, 0x00, 0x21, 0x00, 21, 0, 0, 0});
  EXPECT_EQ(rx({0x01, data[0], data[1], data[2], data[3], data[4], data[5], data[6]}), none());
  // Segment 2 is lost; 3 (the last) arrives.
  EXPECT_EQ(rx({0x83, data[14], data[15], data[16], data[17], data[18], data[19], data[20]}),
            tx({0xA2, 1, 3, 0, 0, 0, 0, 0}));
  EXPECT_TRUE(server.busy());
  EXPECT_EQ(rx({0x01, data[7], data[8], data[9], data[10], data[11], data[12], data[13]}), none());
  EXPECT_EQ(rx({0x82, data[14], data[15], data[16], data[17], data[18], data[19], data[20]}),
            tx({0xA2, 2, 3, 0, 0, 0, 0, 0}));
  EXPECT_EQ(rx({0xC1, 0, 0, 0, 0, 0, 0, 0}), tx({0xA1, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(dict.value(0x2100), data);
}

TEST_F(SdoServerTest, BlockDownloadSizeChecks) {
  // Announced size larger than the object allows.
  EXPECT_EQ(rx({0xC2, 0x01, 0x21, 0x00, 11, 0, 0, 0}), aborted(0x2101, 0, SdoAbortCode::LengthTooHigh));
  EXPECT_EQ(rx({0xC2, 0x01, 0x20, 0x00, 1, 0, 0, 0}), aborted(0x2001, 0, SdoAbortCode::LengthTooLow));
  // End frame disagrees with the announced size (3 announced, end says 2 used of 7).
  rx({0xC2, 0x00, 0x21, 0x00, 3, 0, 0, 0});
  rx({0x81, 1, 2, 3, 0, 0, 0, 0});
  EXPECT_EQ(rx({0xD5, 0, 0, 0, 0, 0, 0, 0}), aborted(0x2100, 0, SdoAbortCode::LengthMismatch));
  // More segments than the announced size can fill.
  rx({0xC2, 0x00, 0x21, 0x00, 3, 0, 0, 0});
  EXPECT_EQ(rx({0x01, 1, 2, 3, 4, 5, 6, 7}), none());
  EXPECT_EQ(rx({0x02, 1, 2, 3, 4, 5, 6, 7}), aborted(0x2100, 0, SdoAbortCode::LengthMismatch));
  // No size announced: the 10-byte cap of 2101h is exceeded by the third segment.
  rx({0xC0, 0x01, 0x21, 0x00, 0, 0, 0, 0});
  EXPECT_EQ(rx({0x01, 1, 2, 3, 4, 5, 6, 7}), none());
  EXPECT_EQ(rx({0x02, 1, 2, 3, 4, 5, 6, 7}), none());
  EXPECT_EQ(rx({0x03, 1, 2, 3, 4, 5, 6, 7}), aborted(0x2101, 0, SdoAbortCode::OutOfMemory));
  EXPECT_TRUE(dict.value(0x2100).empty());
  EXPECT_EQ(dict.value(0x2101), bytes_of("abc"));
}

TEST_F(SdoServerTest, BlockDownloadRefusedByObjectDictionary) {
  rx({0xC2, 0x02, 0x21, 0x00, 3, 0, 0, 0});
  rx({0x81, 1, 2, 3, 0, 0, 0, 0});
  EXPECT_EQ(rx({0xD1, 0, 0, 0, 0, 0, 0, 0}), aborted(0x2102, 0, SdoAbortCode::InvalidValue));
  EXPECT_TRUE(dict.value(0x2102).empty());
}

TEST_F(SdoServerTest, BlockDownloadWrongCommandAtEnd) {
  rx({0xC2, 0x00, 0x21, 0x00, 3, 0, 0, 0});
  rx({0x81, 1, 2, 3, 0, 0, 0, 0});
  EXPECT_EQ(rx({0xA3, 0, 0, 0, 0, 0, 0, 0}), aborted(0x2100, 0, SdoAbortCode::UnknownCommandSpecifier));
  EXPECT_FALSE(server.busy());
}

// ---------------------------------------------------------------------------------------------
// Block upload (CiA 301 §7.2.4.3.15 - .16)

TEST_F(SdoServerTest, BlockUploadWithCrc) {
  // 1008h "OEGW test device", 16 bytes: 3 segments (7, 7, 2).
  EXPECT_EQ(rx({0xA4, 0x08, 0x10, 0x00, 127, 0, 0, 0}), tx({0xC6, 0x08, 0x10, 0x00, 16, 0, 0, 0}));
  EXPECT_EQ(rx({0xA3, 0, 0, 0, 0, 0, 0, 0}), (std::vector<CanFrame>{
                                                 CanFrame(kTx, {0x01, 'O', 'E', 'G', 'W', ' ', 't', 'e'}),
                                                 CanFrame(kTx, {0x02, 's', 't', ' ', 'd', 'e', 'v', 'i'}),
                                                 CanFrame(kTx, {0x83, 'c', 'e', 0, 0, 0, 0, 0}),
                                             }));
  const std::uint16_t crc = crc16_ccitt(bytes_of("OEGW test device"));
  // End: n = 5 unused -> 0xC1 | 5 << 2 = 0xD5.
  EXPECT_EQ(rx({0xA2, 3, 127, 0, 0, 0, 0, 0}),
            tx({0xD5, static_cast<std::uint8_t>(crc), static_cast<std::uint8_t>(crc >> 8), 0, 0, 0, 0, 0}));
  EXPECT_TRUE(server.busy());
  EXPECT_EQ(rx({0xA1, 0, 0, 0, 0, 0, 0, 0}), none());
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoServerTest, BlockUploadWithoutCrcSendsZeroCrc) {
  EXPECT_EQ(rx({0xA0, 0x00, 0x10, 0x00, 127, 0, 0, 0}), tx({0xC6, 0x00, 0x10, 0x00, 4, 0, 0, 0}));
  EXPECT_EQ(rx({0xA3, 0, 0, 0, 0, 0, 0, 0}), tx({0x81, 0x96, 0x01, 0x08, 0x00, 0, 0, 0}));
  EXPECT_EQ(rx({0xA2, 1, 127, 0, 0, 0, 0, 0}), tx({0xCD, 0, 0, 0, 0, 0, 0, 0}));  // n = 3
}

TEST_F(SdoServerTest, BlockUploadOfEmptyValue) {
  EXPECT_EQ(rx({0xA4, 0x00, 0x21, 0x00, 127, 0, 0, 0}), tx({0xC6, 0x00, 0x21, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(rx({0xA3, 0, 0, 0, 0, 0, 0, 0}), tx({0x81, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(rx({0xA2, 1, 127, 0, 0, 0, 0, 0}), tx({0xDD, 0, 0, 0, 0, 0, 0, 0}));  // n = 7, CRC of nothing = 0
}

TEST_F(SdoServerTest, BlockUploadSubBlocksAndRetransmission) {
  dict.od.find(0x2100, 0)->value = pattern(35);  // 5 segments
  const auto data = pattern(35);
  const auto seg = [&](std::uint8_t seq, std::size_t from, bool last = false) {
    CanFrame f(kTx, {static_cast<std::uint8_t>(seq | (last ? 0x80 : 0)), 0, 0, 0, 0, 0, 0, 0});
    for (std::size_t i = 0; i < 7 && from + i < data.size(); ++i) f.data[1 + i] = data[from + i];
    return f;
  };
  EXPECT_EQ(rx({0xA0, 0x00, 0x21, 0x00, 2, 0, 0, 0}), tx({0xC6, 0x00, 0x21, 0x00, 35, 0, 0, 0}));
  EXPECT_EQ(rx({0xA3, 0, 0, 0, 0, 0, 0, 0}), (std::vector<CanFrame>{seg(1, 0), seg(2, 7)}));
  // The client got only segment 1 and asks for 3 per sub-block from now on.
  EXPECT_EQ(rx({0xA2, 1, 3, 0, 0, 0, 0, 0}), (std::vector<CanFrame>{seg(1, 7), seg(2, 14), seg(3, 21)}));
  EXPECT_EQ(rx({0xA2, 3, 3, 0, 0, 0, 0, 0}), (std::vector<CanFrame>{seg(1, 28, true)}));
  EXPECT_EQ(rx({0xA2, 1, 3, 0, 0, 0, 0, 0}), tx({0xC1, 0, 0, 0, 0, 0, 0, 0}));  // n = 0
}

TEST_F(SdoServerTest, BlockUploadBlockSizeAndSequenceChecks) {
  EXPECT_EQ(rx({0xA4, 0x08, 0x10, 0x00, 0, 0, 0, 0}), aborted(0x1008, 0, SdoAbortCode::InvalidBlockSize));
  EXPECT_EQ(rx({0xA4, 0x08, 0x10, 0x00, 128, 0, 0, 0}), aborted(0x1008, 0, SdoAbortCode::InvalidBlockSize));
  rx({0xA4, 0x08, 0x10, 0x00, 127, 0, 0, 0});
  rx({0xA3, 0, 0, 0, 0, 0, 0, 0});
  EXPECT_EQ(rx({0xA2, 4, 127, 0, 0, 0, 0, 0}), aborted(0x1008, 0, SdoAbortCode::InvalidSequenceNumber));
  rx({0xA4, 0x08, 0x10, 0x00, 127, 0, 0, 0});
  rx({0xA3, 0, 0, 0, 0, 0, 0, 0});
  EXPECT_EQ(rx({0xA2, 1, 0, 0, 0, 0, 0, 0}), aborted(0x1008, 0, SdoAbortCode::InvalidBlockSize));
  // Anything but the start command after the initiate.
  rx({0xA4, 0x08, 0x10, 0x00, 127, 0, 0, 0});
  EXPECT_EQ(rx({0xA2, 0, 127, 0, 0, 0, 0, 0}), aborted(0x1008, 0, SdoAbortCode::UnknownCommandSpecifier));
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoServerTest, BlockUploadProtocolSwitchThreshold) {
  // pst = 16: 4 bytes <= 16 -> expedited answer; 16 bytes <= 16 -> segmented; pst = 15 -> block.
  EXPECT_EQ(rx({0xA4, 0x00, 0x10, 0x00, 127, 16, 0, 0}), tx({0x43, 0x00, 0x10, 0x00, 0x96, 0x01, 0x08, 0x00}));
  EXPECT_FALSE(server.busy());
  EXPECT_EQ(rx({0xA4, 0x08, 0x10, 0x00, 127, 16, 0, 0}), tx({0x41, 0x08, 0x10, 0x00, 16, 0, 0, 0}));
  EXPECT_EQ(rx({0x60, 0, 0, 0, 0, 0, 0, 0}), tx({0x00, 'O', 'E', 'G', 'W', ' ', 't', 'e'}));
  EXPECT_EQ(rx({0xA4, 0x08, 0x10, 0x00, 127, 15, 0, 0}), tx({0xC6, 0x08, 0x10, 0x00, 16, 0, 0, 0}));
}

TEST_F(SdoServerTest, BlockUploadTimesOutWaitingForAck) {
  rx({0xA4, 0x08, 0x10, 0x00, 127, 0, 0, 0});
  rx({0xA3, 0, 0, 0, 0, 0, 0, 0});
  out.clear();
  server.advance(t + 1s);
  EXPECT_EQ(out, aborted(0x1008, 0, SdoAbortCode::Timeout));
  EXPECT_FALSE(server.busy());
}

TEST_F(SdoServerTest, ExtendedCobIds) {
  SdoServer ext(
      dict.od, [this](const CanFrame& f) { out.push_back(f); }, CobId(0x20000603u | 0x10000),
      CobId(0x20000583u | 0x10000));
  out.clear();
  CanFrame base(0x603, {0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
  EXPECT_FALSE(ext.on_frame(base, t));  // 11-bit frame, 29-bit channel
  CanFrame ef(0x10603, {0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});
  EXPECT_TRUE(ext.on_frame(ef, t));
  ASSERT_EQ(out.size(), 1u);
  EXPECT_TRUE(out[0].extended);
  EXPECT_EQ(out[0].id, 0x10583u);
}

}  // namespace
