// Dynamic PDO mapping by OD writes (CiA 301 §7.3.5 mapping procedure, §7.5.2.35..38) and the
// write rules of the PDO communication parameters, with their SDO abort codes.
#include <gtest/gtest.h>

#include <vector>

#include "canopen/301/pdo.hpp"

namespace oegw::canopen {
namespace {

using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

class PdoMappingFixture : public ::testing::Test {
 protected:
  ObjectDictionary od;
  std::vector<CanFrame> sent;
  TimePoint t0{Duration{1'000'000}};

  PdoMappingFixture() {
    // Novotechnik §4.2 / §8.2 mappable objects: 6020h:01 position (32 bit), 6030h:01 speed (16 bit).
    od.add_array(0x6020, "Position value", DataType::Unsigned32, Access::ReadOnly, 1, {0, 0, 0, 0}, true);
    od.add_array(0x6030, "Speed value", DataType::Integer16, Access::ReadOnly, 1, {0, 0}, true);
    od.add_var(0x2002, "Temperature", DataType::Integer16, Access::ReadOnly, {0, 0}, true);
    od.add_var(0x2100, "Not mappable", DataType::Unsigned8, Access::ReadWrite, {0}, false);
    od.add_var(0x2200, "Output", DataType::Unsigned8, Access::ReadWrite, {0}, true);
    od.add_var(0x2201, "Wide output", DataType::Unsigned32, Access::ReadWrite, {0, 0, 0, 0}, true);
    // Novotechnik §4.1: 1800/1 0x40000180 + node-ID, 1800/2 0xFE, 1A00 capacity 5, default
    // mapping 60200120h, 60300110h. Node-ID 1.
    install_tpdo(od, 1,
                 {.cob_id = 0x40000181,
                  .transmission_type = 0xFE,
                  .mapping = {0x60200120, 0x60300110},
                  .mapping_capacity = 5});
    install_rpdo(od, 1, {.cob_id = 0x80000201, .transmission_type = 0xFF, .mapping = {0x22000008}});
  }

  std::unique_ptr<PdoService> make() {
    return std::make_unique<PdoService>(od, [this](const CanFrame& f) { sent.push_back(f); });
  }
  SdoAbortCode w8(std::uint16_t i, std::uint8_t s, std::uint8_t v) { return od.write(i, s, Bytes{v}); }
  SdoAbortCode w16(std::uint16_t i, std::uint8_t s, std::uint16_t v) { return od.write(i, s, encode(v)); }
  SdoAbortCode w32(std::uint16_t i, std::uint8_t s, std::uint32_t v) { return od.write(i, s, encode(v)); }
};

// Novotechnik §8.2 "PDO Parameter Setting", steps 1..5, with the SDO data bytes of its examples:
// "0x600+Node-ID 8 Rx 0x23 0x00 0x1A 0x01 0x20 0x01 0x20 0x60" (1A00h:01 = 60200120h) and
// "... 0x23 0x00 0x1A 0x02 0x10 0x01 0x30 0x60" (1A00h:02 = 60300110h).
TEST_F(PdoMappingFixture, NovotechnikRemappingProcedure) {
  auto svc = make();
  svc->set_operational(true, t0);
  od.set<std::uint32_t>(0x6020, 1, 0x12345678);
  od.set<std::int16_t>(0x6030, 1, 0x0102);
  od.set<std::int16_t>(0x2002, 0, 0x0A0B);
  svc->advance(t0);
  ASSERT_EQ(sent.size(), 1u);
  EXPECT_EQ(sent.back(), CanFrame(0x181, {0x78, 0x56, 0x34, 0x12, 0x02, 0x01}));

  // Out of order: the PDO still exists.
  EXPECT_EQ(w8(0x1A00, 0, 0), SdoAbortCode::CannotTransferDeviceState);
  EXPECT_EQ(w32(0x1A00, 3, 0x20020010), SdoAbortCode::CannotTransferDeviceState);

  // Step 1: "the MSB of PDO COB-ID has to be set to 1 to deactivate it" (0x40000xxx -> 0xC0000xxx).
  ASSERT_EQ(w32(0x1800, 1, 0xC0000181), SdoAbortCode::None);
  EXPECT_FALSE(svc->tpdo(1)->active());
  // Mapping entries still refused while sub-index 0 is not 0.
  EXPECT_EQ(w32(0x1A00, 3, 0x20020010), SdoAbortCode::CannotTransferDeviceState);
  // Step 2: sub-index 0 of 1A00h = 0.
  ASSERT_EQ(w8(0x1A00, 0, 0), SdoAbortCode::None);
  // Step 3: the entries, as the SDO download data bytes 4..7 of the examples.
  ASSERT_EQ(od.write(0x1A00, 1, Bytes{0x20, 0x01, 0x20, 0x60}), SdoAbortCode::None);
  ASSERT_EQ(od.write(0x1A00, 2, Bytes{0x10, 0x01, 0x30, 0x60}), SdoAbortCode::None);
  ASSERT_EQ(w32(0x1A00, 3, 0x20020010), SdoAbortCode::None);
  // Step 4: sub-index 0 = number of entries.
  ASSERT_EQ(w8(0x1A00, 0, 3), SdoAbortCode::None);
  // Step 5: "For re-activating the PDO, the MSB of PDO COB-ID has to be set to 0."
  ASSERT_EQ(w32(0x1800, 1, 0x40000181), SdoAbortCode::None);
  EXPECT_TRUE(svc->tpdo(1)->active());
  EXPECT_EQ(svc->tpdo(1)->dlc(), 8u);
  svc->advance(t0 + 1ms);  // a PDO that becomes active in Operational sends once
  ASSERT_EQ(sent.size(), 2u);
  EXPECT_EQ(sent.back(), CanFrame(0x181, {0x78, 0x56, 0x34, 0x12, 0x02, 0x01, 0x0B, 0x0A}));
  // The new entry is watched for changes.
  od.set<std::int16_t>(0x2002, 0, 0x0A0C);
  svc->advance(t0 + 2ms);
  ASSERT_EQ(sent.size(), 3u);
  EXPECT_EQ(sent.back().data[6], 0x0C);
}

TEST_F(PdoMappingFixture, EntryForMissingObjectAborts0602) {
  auto svc = make();
  ASSERT_EQ(w32(0x1800, 1, 0xC0000181), SdoAbortCode::None);
  ASSERT_EQ(w8(0x1A00, 0, 0), SdoAbortCode::None);
  EXPECT_EQ(w32(0x1A00, 1, 0x30000020), SdoAbortCode::ObjectDoesNotExist);  // no 3000h
  EXPECT_EQ(w32(0x1A00, 1, 0x60200220), SdoAbortCode::ObjectDoesNotExist);  // no 6020h:02
  EXPECT_EQ(od.get<std::uint32_t>(0x1A00, 1), 0x60200120u) << "a refused write changes nothing";
}

TEST_F(PdoMappingFixture, SubIndex0ValidatesEntriesAgain) {
  auto svc = make();
  ASSERT_EQ(w32(0x1800, 1, 0xC0000181), SdoAbortCode::None);
  ASSERT_EQ(w8(0x1A00, 0, 0), SdoAbortCode::None);
  ASSERT_EQ(w32(0x1A00, 1, 0x20020010), SdoAbortCode::None);
  od.remove(0x2002);  // the mapped object disappears between step 3 and step 4
  EXPECT_EQ(w8(0x1A00, 0, 1), SdoAbortCode::ObjectDoesNotExist);
  EXPECT_EQ(od.get<std::uint8_t>(0x1A00, 0), 0u);
  // A zero entry within the count is not an object either.
  ASSERT_EQ(w32(0x1A00, 1, 0), SdoAbortCode::None);
  EXPECT_EQ(w8(0x1A00, 0, 1), SdoAbortCode::ObjectDoesNotExist);
}

TEST_F(PdoMappingFixture, NotMappableAborts0641) {
  auto svc = make();
  ASSERT_EQ(w32(0x1800, 1, 0xC0000181), SdoAbortCode::None);
  ASSERT_EQ(w8(0x1A00, 0, 0), SdoAbortCode::None);
  EXPECT_EQ(w32(0x1A00, 1, 0x21000008), SdoAbortCode::CannotBeMapped);  // pdo_mappable = false
  EXPECT_EQ(w32(0x1A00, 1, 0x60200110), SdoAbortCode::CannotBeMapped);  // 16 bits of a 32-bit object
  EXPECT_EQ(w32(0x1A00, 1, 0x00050008), SdoAbortCode::CannotBeMapped);  // dummy in a TPDO
  // An RPDO may not map a read-only object (it would write it).
  ASSERT_EQ(w8(0x1600, 0, 0), SdoAbortCode::None);  // RPDO 1 is invalid already
  EXPECT_EQ(w32(0x1600, 1, 0x60200120), SdoAbortCode::CannotBeMapped);
}

TEST_F(PdoMappingFixture, TooLongMappingAborts0642) {
  auto svc = make();
  ASSERT_EQ(w32(0x1800, 1, 0xC0000181), SdoAbortCode::None);
  ASSERT_EQ(w8(0x1A00, 0, 0), SdoAbortCode::None);
  ASSERT_EQ(w32(0x1A00, 1, 0x60200120), SdoAbortCode::None);
  ASSERT_EQ(w32(0x1A00, 2, 0x60200120), SdoAbortCode::None);
  ASSERT_EQ(w32(0x1A00, 3, 0x60300110), SdoAbortCode::None);
  EXPECT_EQ(w8(0x1A00, 0, 3), SdoAbortCode::MappingExceedsPdoLength);  // 80 bits
  EXPECT_EQ(w8(0x1A00, 0, 6), SdoAbortCode::MappingExceedsPdoLength);  // only 5 entries exist
  EXPECT_EQ(w8(0x1A00, 0, 2), SdoAbortCode::None);                     // exactly 64 bits
}

TEST_F(PdoMappingFixture, RpdoDummyMappingAllowed) {
  auto svc = make();
  ASSERT_EQ(w8(0x1600, 0, 0), SdoAbortCode::None);
  ASSERT_EQ(w32(0x1600, 1, 0x00070020), SdoAbortCode::None);            // UNSIGNED32 dummy
  ASSERT_EQ(w32(0x1600, 2, 0x22000008), SdoAbortCode::None);            // 2200h:00, 8 bits
  EXPECT_EQ(w32(0x1600, 3, 0x00070010), SdoAbortCode::CannotBeMapped);  // wrong dummy length
  ASSERT_EQ(w8(0x1600, 0, 2), SdoAbortCode::None);
  ASSERT_EQ(w32(0x1400, 1, 0x00000201), SdoAbortCode::None);
  svc->set_operational(true, t0);
  EXPECT_TRUE(svc->on_frame(CanFrame(0x201, {1, 2, 3, 4, 0x99}), t0));
  EXPECT_EQ(od.get<std::uint8_t>(0x2200, 0), 0x99u);
}

TEST_F(PdoMappingFixture, RemapChangesRpdoLayout) {
  auto svc = make();
  ASSERT_EQ(w32(0x1400, 1, 0x00000201), SdoAbortCode::None);
  svc->set_operational(true, t0);
  svc->on_frame(CanFrame(0x201, {0x11}), t0);
  EXPECT_EQ(od.get<std::uint8_t>(0x2200, 0), 0x11u);
  ASSERT_EQ(w32(0x1400, 1, 0x80000201), SdoAbortCode::None);
  EXPECT_FALSE(svc->on_frame(CanFrame(0x201, {0x22}), t0)) << "destroyed PDO";
  ASSERT_EQ(w8(0x1600, 0, 0), SdoAbortCode::None);
  ASSERT_EQ(w32(0x1600, 1, 0x22010020), SdoAbortCode::None);
  ASSERT_EQ(w8(0x1600, 0, 1), SdoAbortCode::None);
  ASSERT_EQ(w32(0x1400, 1, 0x00000301), SdoAbortCode::None);  // and a new COB-ID
  EXPECT_FALSE(svc->on_frame(CanFrame(0x201, {0x22}), t0));
  EXPECT_TRUE(svc->on_frame(CanFrame(0x301, {0x78, 0x56, 0x34, 0x12}), t0));
  EXPECT_EQ(od.get<std::uint32_t>(0x2201, 0), 0x12345678u);
}

// CiA 301 §7.5.2.35/37: bits 0..29 of a PDO COB-ID may not change while the PDO exists.
TEST_F(PdoMappingFixture, CobIdChangeWhileValidAborts0609_0030) {
  auto svc = make();
  EXPECT_EQ(w32(0x1800, 1, 0x40000182), SdoAbortCode::InvalidValue);
  EXPECT_EQ(w32(0x1800, 1, 0x60000181), SdoAbortCode::InvalidValue);  // 29-bit frame
  EXPECT_EQ(w32(0x1800, 1, 0x00000181), SdoAbortCode::None);          // bit 30 may change
  EXPECT_EQ(w32(0x1800, 1, 0x80000182), SdoAbortCode::None);          // invalidate and move
  EXPECT_EQ(w32(0x1800, 1, 0x00000182), SdoAbortCode::None);
  EXPECT_EQ(od.get<std::uint32_t>(0x1800, 1), 0x182u);
}

TEST_F(PdoMappingFixture, RestrictedCobIdsRefused) {
  auto svc = make();
  ASSERT_EQ(w32(0x1400, 1, 0x80000000), SdoAbortCode::None);  // invalid: anything goes
  for (std::uint32_t id : {0x000u, 0x07Fu, 0x101u, 0x180u, 0x581u, 0x601u, 0x6E0u, 0x701u, 0x7FFu})
    EXPECT_EQ(w32(0x1400, 1, id), SdoAbortCode::InvalidValue) << std::hex << id;
  EXPECT_EQ(w32(0x1400, 1, 0x181), SdoAbortCode::None);
}

TEST_F(PdoMappingFixture, TransmissionTypeRules) {
  auto svc = make();
  for (unsigned t = 241; t <= 251; ++t)
    EXPECT_EQ(w8(0x1800, 2, static_cast<std::uint8_t>(t)), SdoAbortCode::InvalidValue);
  EXPECT_EQ(w8(0x1800, 2, 252), SdoAbortCode::None);
  EXPECT_EQ(w8(0x1800, 2, 253), SdoAbortCode::None);
  EXPECT_EQ(w8(0x1800, 2, 240), SdoAbortCode::None);
  EXPECT_EQ(svc->tpdo(1)->transmission_type(), 240u);
  // MCB-402 §5: "These values [252/253] are only possible for transmit PDOs."
  EXPECT_EQ(w8(0x1400, 2, 252), SdoAbortCode::InvalidValue);
  EXPECT_EQ(w8(0x1400, 2, 253), SdoAbortCode::InvalidValue);
  EXPECT_EQ(w8(0x1400, 2, 0), SdoAbortCode::None);
}

TEST_F(PdoMappingFixture, InhibitAndSyncStartOnlyWhilePdoDestroyed) {
  auto svc = make();
  EXPECT_EQ(w16(0x1800, 3, 10), SdoAbortCode::InvalidValue);
  EXPECT_EQ(w8(0x1800, 6, 3), SdoAbortCode::InvalidValue);
  EXPECT_EQ(w16(0x1800, 5, 10), SdoAbortCode::None);  // the event timer may change any time
  ASSERT_EQ(w32(0x1800, 1, 0xC0000181), SdoAbortCode::None);
  EXPECT_EQ(w16(0x1800, 3, 10), SdoAbortCode::None);
  EXPECT_EQ(w8(0x1800, 6, 3), SdoAbortCode::None);
}

TEST_F(PdoMappingFixture, ReloadAfterResetToDefaults) {
  auto svc = make();
  ASSERT_EQ(w32(0x1800, 1, 0xC0000181), SdoAbortCode::None);
  EXPECT_FALSE(svc->tpdo(1)->cob_id().valid());
  od.reset_to_defaults(0x1000, 0x1FFF);  // NMT reset communication: runs no observers
  svc->reload();
  EXPECT_TRUE(svc->tpdo(1)->cob_id().valid());
  svc->set_operational(true, t0);
  svc->advance(t0);
  EXPECT_EQ(sent.size(), 1u);
}

}  // namespace
}  // namespace oegw::canopen
