// How long a classical CAN frame occupies the bus, in bits (ISO 11898-1:2015 §10.4 data/remote
// frame format, §10.5 bit stuffing, §10.4.2.6 CRC; CiA 301 runs on this data link layer).
//
// A data frame with an 11-bit identifier is, in order:
//   SOF 1 | identifier 11 | RTR 1 | IDE 1 | r0 1 | DLC 4 | data 8n | CRC sequence 15
//       | CRC delimiter 1 | ACK slot 1 | ACK delimiter 1 | end of frame 7
// followed by the intermission of 3 recessive bits before the next frame may start (§10.4.5).
// A 29-bit frame has SOF | base ID 11 | SRR 1 | IDE 1 | extension 18 | RTR 1 | r1 1 | r0 1 | DLC 4
// | data | CRC ... A remote frame carries no data field whatever its DLC.
// Bit stuffing (§10.5): from SOF to the end of the CRC sequence, after five consecutive bits of
// one value the transmitter inserts one bit of the other value; the stuff bit counts towards the
// next run. The fixed-form tail (CRC delimiter onwards) is not stuffed.
//
//   frame_bits(frame)            the frame's actual length: its real bits, its real CRC, its real
//                                stuff bits, plus the 3 intermission bits (what the bus is busy)
//   frame_bits_worst_case(n)     the most any frame with n data bytes can take: the stuffable
//                                region of L bits gets at most floor((L - 1) / 4) stuff bits
//                                (a run of 5, then every 4 bits, alternately), so 8n + 47 +
//                                floor((34 + 8n - 1) / 4) for an 11-bit identifier (135 for
//                                n = 8) and 8n + 67 + floor((54 + 8n - 1) / 4) for 29 bits (160).
//                                For predictions (oegw check's bus load), where the data is unknown.
#pragma once

#include <cstdint>

#include "canopen/can_frame.hpp"

namespace oegw::canopen {

// Bits after the stuffable region: CRC delimiter, ACK slot, ACK delimiter, EOF 7, intermission 3.
inline constexpr std::uint32_t kFrameTailBits = 1 + 1 + 1 + 7 + 3;
inline constexpr std::uint32_t kIntermissionBits = 3;

// The CRC-15 of ISO 11898-1 §10.4.2.6 (generator x^15+x^14+x^10+x^8+x^7+x^4+x^3+1, 4599h,
// initial value 0) over the destuffed bits SOF .. end of data.
[[nodiscard]] std::uint16_t can_crc15(const CanFrame& frame);

// The frame's length on the wire in bits, stuff bits and intermission included.
[[nodiscard]] std::uint32_t frame_bits(const CanFrame& frame);
// The number of stuff bits the transmitter inserts into this frame.
[[nodiscard]] std::uint32_t frame_stuff_bits(const CanFrame& frame);
// The longest a frame with `data_bytes` data bytes (0..8) can be, intermission included.
[[nodiscard]] std::uint32_t frame_bits_worst_case(std::uint8_t data_bytes, bool extended = false);

// The arbitration field as a number that orders frames by their priority on the bus: the
// lower value wins (ISO 11898-1 §10.8.3: dominant 0 wins bit by bit). An 11-bit data frame beats
// a remote frame of the same identifier (RTR), and an 11-bit frame beats a 29-bit frame of the
// same base identifier (SRR/IDE recessive).
[[nodiscard]] std::uint64_t arbitration_key(const CanFrame& frame);

}  // namespace oegw::canopen
