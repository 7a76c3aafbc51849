// A classical CAN frame (ISO 11898-1), independent of any transport.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <span>
#include <string>

#include "canopen/types.hpp"

namespace oegw::canopen {

struct CanFrame {
  std::uint32_t id = 0;   // 11-bit, or 29-bit when `extended`
  std::uint8_t dlc = 0;   // 0..8
  bool rtr = false;       // remote transmission request
  bool extended = false;  // 29-bit identifier
  std::array<std::uint8_t, 8> data{};

  CanFrame() = default;
  CanFrame(std::uint32_t can_id, std::initializer_list<std::uint8_t> bytes);
  CanFrame(std::uint32_t can_id, std::span<const std::uint8_t> bytes);
  static CanFrame remote(std::uint32_t can_id, std::uint8_t dlc);

  [[nodiscard]] std::span<const std::uint8_t> payload() const { return {data.data(), dlc}; }
  friend bool operator==(const CanFrame& a, const CanFrame& b);

  // "601#2310100173617665" — the candump/cansend notation, used in logs and tests.
  [[nodiscard]] std::string to_string() const;
};

// Where a service puts the frames it wants sent. Services never own a socket ("sans I/O").
using FrameSink = std::function<void(const CanFrame&)>;

// Little-endian helpers: CANopen is little endian on the wire (CiA 301 §7.1.2).
inline std::uint16_t get_u16(const std::uint8_t* p) { return static_cast<std::uint16_t>(p[0] | (p[1] << 8)); }
inline std::uint32_t get_u32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8) |
         (static_cast<std::uint32_t>(p[2]) << 16) | (static_cast<std::uint32_t>(p[3]) << 24);
}
inline void put_u16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
inline void put_u32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}

}  // namespace oegw::canopen
