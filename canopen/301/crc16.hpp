// CRC-16-CCITT as used by the SDO block transfer (CiA 301 §7.2.4.3.16): polynomial
// x^16 + x^12 + x^5 + 1 (0x1021), initial value 0, no reflection, no final XOR — the variant
// also known as CRC-16/XMODEM. "123456789" gives 0x31C3.
#pragma once

#include <cstdint>
#include <span>

namespace oegw::canopen {

// `crc` continues a previous computation, so data may be fed in pieces.
[[nodiscard]] std::uint16_t crc16_ccitt(std::span<const std::uint8_t> data, std::uint16_t crc = 0);

}  // namespace oegw::canopen
