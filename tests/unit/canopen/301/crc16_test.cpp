#include "canopen/301/crc16.hpp"

#include <gtest/gtest.h>

#include <string_view>

using namespace oegw::canopen;

namespace {

std::span<const std::uint8_t> as_bytes(std::string_view s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

// CRC-16/XMODEM check value (poly 0x1021, init 0, no reflection): the CRC CiA 301 §7.2.4.3.16
// prescribes for SDO block transfer.
TEST(Crc16Ccitt, CheckValue) { EXPECT_EQ(crc16_ccitt(as_bytes("123456789")), 0x31C3); }

TEST(Crc16Ccitt, EmptyIsInitialValue) { EXPECT_EQ(crc16_ccitt({}), 0x0000); }

TEST(Crc16Ccitt, CanBeFedInPieces) {
  const std::uint16_t first = crc16_ccitt(as_bytes("1234"));
  EXPECT_EQ(crc16_ccitt(as_bytes("56789"), first), 0x31C3);
}

TEST(Crc16Ccitt, SingleBytesMatchBitwiseDefinition) {
  // 'A' = 0x41: known CRC-16/XMODEM value 0x58E5; a single zero byte keeps 0.
  EXPECT_EQ(crc16_ccitt(as_bytes("A")), 0x58E5);
  const std::uint8_t zero[1] = {0};
  EXPECT_EQ(crc16_ccitt(zero), 0x0000);
}

}  // namespace
