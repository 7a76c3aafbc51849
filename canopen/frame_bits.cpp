#include "canopen/frame_bits.hpp"

#include <array>

namespace oegw::canopen {

namespace {

// The frame's bits from SOF to the end of the data field (before the CRC), destuffed; at most
// 1 + 32 + 6 + 64 = 103 bits for a 29-bit frame with 8 bytes.
struct RawBits {
  std::array<std::uint8_t, 128> bit{};
  std::uint32_t size = 0;
  void push(std::uint32_t value, int width) {
    for (int i = width - 1; i >= 0; --i) bit[size++] = static_cast<std::uint8_t>((value >> i) & 1u);
  }
};

RawBits head_bits(const CanFrame& f) {
  RawBits b;
  b.push(0, 1);  // SOF, dominant
  if (!f.extended) {
    b.push(f.id & 0x7FFu, 11);
    b.push(f.rtr ? 1 : 0, 1);
    b.push(0, 1);  // IDE dominant: 11-bit
    b.push(0, 1);  // r0
  } else {
    b.push((f.id >> 18) & 0x7FFu, 11);  // base identifier: the 11 most significant bits
    b.push(1, 1);                       // SRR, recessive
    b.push(1, 1);                       // IDE recessive: 29-bit
    b.push(f.id & 0x3FFFFu, 18);        // identifier extension
    b.push(f.rtr ? 1 : 0, 1);
    b.push(0, 1);  // r1
    b.push(0, 1);  // r0
  }
  b.push(f.dlc & 0x0Fu, 4);
  if (!f.rtr) {
    const int n = f.dlc > 8 ? 8 : f.dlc;  // a DLC of 9..15 means 8 bytes (§10.4.2.4)
    for (int i = 0; i < n; ++i) b.push(f.data[static_cast<std::size_t>(i)], 8);
  }
  return b;
}

std::uint16_t crc15_of(const RawBits& b) {
  // §10.4.2.6: shift each bit in; when the bit out of the register differs from the next
  // bit, XOR the generator.
  std::uint16_t crc = 0;
  for (std::uint32_t i = 0; i < b.size; ++i) {
    const bool next = ((crc >> 14) & 1u) != b.bit[i];
    crc = static_cast<std::uint16_t>((crc << 1) & 0x7FFFu);
    if (next) crc ^= 0x4599u;
  }
  return crc;
}

}  // namespace

std::uint16_t can_crc15(const CanFrame& frame) { return crc15_of(head_bits(frame)); }

std::uint32_t frame_stuff_bits(const CanFrame& frame) {
  RawBits b = head_bits(frame);
  b.push(crc15_of(b), 15);  // the CRC sequence is stuffed too
  std::uint32_t stuffed = 0;
  std::uint8_t last = 2;  // no previous bit
  int run = 0;
  for (std::uint32_t i = 0; i < b.size; ++i) {
    if (b.bit[i] == last) {
      ++run;
    } else {
      last = b.bit[i];
      run = 1;
    }
    if (run == 5) {
      ++stuffed;  // the inserted bit has the other value and starts a new run of one
      last = static_cast<std::uint8_t>(1 - last);
      run = 1;
    }
  }
  return stuffed;
}

std::uint32_t frame_bits(const CanFrame& frame) {
  const std::uint32_t head = head_bits(frame).size;
  return head + 15 + frame_stuff_bits(frame) + kFrameTailBits;
}

std::uint32_t frame_bits_worst_case(std::uint8_t data_bytes, bool extended) {
  const std::uint32_t n = data_bytes > 8 ? 8 : data_bytes;
  const std::uint32_t stuffable = (extended ? 54u : 34u) + 8 * n;  // SOF .. CRC sequence
  return stuffable + kFrameTailBits + (stuffable - 1) / 4;
}

std::uint64_t arbitration_key(const CanFrame& f) {
  // SOF is always dominant; compare the bits after it as a 32-bit number, most significant first.
  // 11-bit: ID(11) RTR IDE=0, then zeros (two 11-bit frames never get further).
  // 29-bit: ID-A(11) SRR=1 IDE=1 ID-B(18) RTR.
  if (!f.extended)
    return (static_cast<std::uint64_t>(f.id & 0x7FFu) << 21) | (static_cast<std::uint64_t>(f.rtr ? 1 : 0) << 20);
  return (static_cast<std::uint64_t>((f.id >> 18) & 0x7FFu) << 21) | (1ull << 20) | (1ull << 19) |
         (static_cast<std::uint64_t>(f.id & 0x3FFFFu) << 1) | (f.rtr ? 1u : 0u);
}

}  // namespace oegw::canopen
