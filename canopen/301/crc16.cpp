#include "canopen/301/crc16.hpp"

#include <array>

namespace oegw::canopen {

namespace {

constexpr std::array<std::uint16_t, 256> make_table() {
  std::array<std::uint16_t, 256> t{};
  for (unsigned i = 0; i < 256; ++i) {
    auto c = static_cast<std::uint16_t>(i << 8);
    for (int b = 0; b < 8; ++b) {
      c = static_cast<std::uint16_t>((c & 0x8000u) ? ((c << 1) ^ 0x1021u) : (c << 1));
    }
    t[i] = c;
  }
  return t;
}

constexpr auto kTable = make_table();

}  // namespace

std::uint16_t crc16_ccitt(std::span<const std::uint8_t> data, std::uint16_t crc) {
  for (const std::uint8_t b : data) {
    crc = static_cast<std::uint16_t>((crc << 8) ^ kTable[static_cast<std::uint8_t>((crc >> 8) ^ b)]);
  }
  return crc;
}

}  // namespace oegw::canopen
