// Shared CiA 305 (LSS) definitions: command specifiers, the LSS address, the bit-timing table.
//
// Every LSS frame is 8 bytes: master -> slaves on 7E5h, slave -> master on 7E4h; byte 0 is the
// command specifier, multi-byte values are little endian from byte 1.
#pragma once

#include <cstdint>
#include <optional>

namespace oegw::canopen::lss {

namespace cs {
inline constexpr std::uint8_t kSwitchStateGlobal = 0x04;
inline constexpr std::uint8_t kConfigureNodeId = 0x11;
inline constexpr std::uint8_t kConfigureBitTiming = 0x13;
inline constexpr std::uint8_t kActivateBitTiming = 0x15;
inline constexpr std::uint8_t kStoreConfiguration = 0x17;
inline constexpr std::uint8_t kSwitchSelectiveVendor = 0x40;
inline constexpr std::uint8_t kSwitchSelectiveProduct = 0x41;
inline constexpr std::uint8_t kSwitchSelectiveRevision = 0x42;
inline constexpr std::uint8_t kSwitchSelectiveSerial = 0x43;
inline constexpr std::uint8_t kSwitchSelectiveResponse = 0x44;
inline constexpr std::uint8_t kIdentifyVendor = 0x46;
inline constexpr std::uint8_t kIdentifyProduct = 0x47;
inline constexpr std::uint8_t kIdentifyRevisionLow = 0x48;
inline constexpr std::uint8_t kIdentifyRevisionHigh = 0x49;
inline constexpr std::uint8_t kIdentifySerialLow = 0x4A;
inline constexpr std::uint8_t kIdentifySerialHigh = 0x4B;
inline constexpr std::uint8_t kIdentifyNonConfigured = 0x4C;
inline constexpr std::uint8_t kIdentifySlaveResponse = 0x4F;
inline constexpr std::uint8_t kIdentifyNonConfiguredResponse = 0x50;
// LSS fastscan (CiA 305 §8.4.4): byte 1..4 IDNumber, 5 BitChecked (0..31, or 80h: reset),
// 6 LSSSub, 7 LSSNext (0 vendor, 1 product, 2 revision, 3 serial); answered with 4Fh.
inline constexpr std::uint8_t kFastscan = 0x51;
inline constexpr std::uint8_t kFastscanReset = 0x80;
inline constexpr std::uint8_t kInquireVendor = 0x5A;
inline constexpr std::uint8_t kInquireProduct = 0x5B;
inline constexpr std::uint8_t kInquireRevision = 0x5C;
inline constexpr std::uint8_t kInquireSerial = 0x5D;
inline constexpr std::uint8_t kInquireNodeId = 0x5E;
}  // namespace cs

enum class Mode : std::uint8_t { Waiting = 0, Configuration = 1 };

// The LSS address: 1018h sub 1..4.
struct Address {
  std::uint32_t vendor = 0;
  std::uint32_t product = 0;
  std::uint32_t revision = 0;
  std::uint32_t serial = 0;
  friend bool operator==(const Address&, const Address&) = default;
};

// What "identify remote slave" matches: vendor and product exactly, revision and serial in
// inclusive ranges.
struct AddressRange {
  std::uint32_t vendor = 0;
  std::uint32_t product = 0;
  std::uint32_t revision_low = 0;
  std::uint32_t revision_high = 0xFFFFFFFF;
  std::uint32_t serial_low = 0;
  std::uint32_t serial_high = 0xFFFFFFFF;
};

// CiA 305 bit timing table 0 (the standard CiA table). Index 5 is reserved.
// Returns the bit rate in kbit/s, or nullopt for an index that is not in the table.
[[nodiscard]] constexpr std::optional<std::uint16_t> standard_bit_rate_kbit(std::uint8_t index) {
  switch (index) {
    case 0: return 1000;
    case 1: return 800;
    case 2: return 500;
    case 3: return 250;
    case 4: return 125;
    case 6: return 50;
    case 7: return 20;
    case 8: return 10;
    default: return std::nullopt;
  }
}

// The table-0 index of a bit rate in bit/s (1000000 -> 0, ..., 10000 -> 8); nullopt for a rate
// the table does not have.
[[nodiscard]] constexpr std::optional<std::uint8_t> standard_bit_timing_index(std::uint32_t bit_per_s) {
  for (std::uint8_t i = 0; i < 9; ++i) {
    const auto kbit = standard_bit_rate_kbit(i);
    if (kbit && std::uint32_t{*kbit} * 1000u == bit_per_s) return i;
  }
  return std::nullopt;
}

// A set of table-0 indexes as LssSlave takes it: bit i set = index i supported.
using BitTimings = std::uint16_t;
inline constexpr BitTimings kAllStandardBitTimings = 0x01DF;  // 0..8 without the reserved 5
// What a stored configuration may carry (read_lss_store): any table-0 index 0..9, the reserved
// 5 and the automatic 9 among them. A node takes it as stored, supported or not.
inline constexpr BitTimings kStorableBitTimings = 0x03FF;
// True when `index` (CiA 305 table 0) is one of `timings`.
[[nodiscard]] constexpr bool has_bit_timing(BitTimings timings, unsigned index) {
  return index < 16 && ((timings >> index) & 1u) != 0;
}

}  // namespace oegw::canopen::lss
