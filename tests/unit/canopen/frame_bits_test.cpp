// Frame lengths on the wire (canopen/frame_bits.hpp, ISO 11898-1 §10.4 frame format, §10.5 bit
// stuffing, §10.4.2.6 CRC-15). Each expected value below is worked out in the comment: the
// destuffed bits SOF..CRC, where the stuff bits go (a run of five equal bits is followed by one
// of the other value, which starts the next run), then + 13 fixed bits (CRC delimiter, ACK slot,
// ACK delimiter, EOF 7, intermission 3).
#include "canopen/frame_bits.hpp"

#include <gtest/gtest.h>

using namespace oegw::canopen;

namespace {

TEST(FrameBits, SyncHasFourStuffBits) {
  // SYNC 080h, DLC 0 (CiA 301 §7.2.5). Destuffed, 34 bits:
  //   SOF 0 | ID 000 1000 0000 | RTR IDE r0 000 | DLC 0000 | CRC 001110000000101 (1C05h)
  // Runs: "0000" (SOF + 000), "1", then 7 + 3 + 4 zeros + the CRC's "00" = 16 zeros: a stuff
  // bit after each 5 (the stuff bit starts the next run): 3, 1 zero left; "111"; 7 zeros: 1
  // stuff bit; "101". 4 stuff bits: 34 + 4 + 13 = 51.
  const CanFrame sync{0x080, {}};
  EXPECT_EQ(can_crc15(sync), 0x1C05);
  EXPECT_EQ(frame_stuff_bits(sync), 4u);
  EXPECT_EQ(frame_bits(sync), 51u);
}

TEST(FrameBits, NmtStartAllHasFiveStuffBits) {
  // NMT 000h 01 00 (start, all nodes; CiA 301 §7.2.8.3.1.1). 34 + 16 = 50 destuffed bits:
  //   0 | 00000000000 | 000 | 0010 | 00000001 00000000 | CRC 110000110010111 (6197h)
  // Runs: SOF + ID + RTR IDE r0 + DLC's "00" = 17 zeros: 3 stuff bits, 2 left; "1"; DLC's last
  // "0" + 7 zeros of 01h = 8 zeros: 1 stuff bit; "1"; 8 zeros of 00h: 1 stuff bit; the CRC
  // starts "11". 5 stuff bits: 50 + 5 + 13 = 68.
  const CanFrame nmt{0x000, {0x01, 0x00}};
  EXPECT_EQ(can_crc15(nmt), 0x6197);
  EXPECT_EQ(frame_stuff_bits(nmt), 5u);
  EXPECT_EQ(frame_bits(nmt), 68u);
}

TEST(FrameBits, HeartbeatsOfOneNodeDifferByTheirStateByte) {
  // CiA 301 §7.2.8.3.2, 34 + 8 = 42 destuffed bits each.
  // 701h 05: 0 | 11100000001 | 000 | 0001 | 00000101 | CRC 100110100001110 (4D0Eh). Zero runs:
  //   the ID's 7 (1 stuff bit), RTR IDE r0 + DLC's 000 = 6 (1), the data's 5 (1), the CRC's
  //   longest 4 (none): 3 stuff bits -> 42 + 3 + 13 = 58.
  // 701h 00 (the boot-up): ... | 0001 | 00000000 | CRC 101000001011000 (5058h). The ID's 7 (1),
  //   the 6 (1), the data's 8 (1), the CRC's 5 (1): 4 stuff bits -> 59.
  EXPECT_EQ(can_crc15(CanFrame{0x701, {0x05}}), 0x4D0E);
  EXPECT_EQ(frame_bits(CanFrame{0x701, {0x05}}), 58u);
  EXPECT_EQ(can_crc15(CanFrame{0x701, {0x00}}), 0x5058);
  EXPECT_EQ(frame_bits(CanFrame{0x701, {0x00}}), 59u);
}

TEST(FrameBits, AnSdoRequestOfEightBytes) {
  // SDO upload initiate of 1000h to node 1: 601h 40 00 10 00 00 00 00 00 (CiA 301 §7.2.4.3.6),
  // 34 + 64 = 98 destuffed bits, CRC 191Ah. Stuffed, with the stuff bits in brackets:
  //   01100000[1]000100010000100000[1]00000[1]00000[1]00100000[1]00000[1]00000[1]00000[1]00000[1]
  //   00000[1]00000[1]00000[1]00000[1]01100100011010
  // (SOF, ID 11000000001, 000, DLC 1000, 01000000 00000000 00010000 then five zero bytes and
  // the CRC 001100100011010: every run of 5 zeros is cut by a stuff bit.)
  // 13 stuff bits: 98 + 13 + 13 = 124.
  const CanFrame sdo{0x601, {0x40, 0x00, 0x10, 0, 0, 0, 0, 0}};
  EXPECT_EQ(can_crc15(sdo), 0x191A);
  EXPECT_EQ(frame_stuff_bits(sdo), 13u);
  EXPECT_EQ(frame_bits(sdo), 124u);
}

TEST(FrameBits, TheWorstCaseBoundsEveryFrame) {
  // 8 bytes, 11-bit: 34 + 64 = 98 stuffable bits, at most floor(97 / 4) = 24 stuff bits:
  // 98 + 24 + 13 = 135. 0 bytes: 34 + floor(33 / 4) = 8 + 13 = 55. 29-bit, 8 bytes: 54 + 64 =
  // 118, floor(117 / 4) = 29: 118 + 29 + 13 = 160.
  EXPECT_EQ(frame_bits_worst_case(8), 135u);
  EXPECT_EQ(frame_bits_worst_case(0), 55u);
  EXPECT_EQ(frame_bits_worst_case(8, true), 160u);
  // An all-zero 8-byte frame at ID 000h is close to it (16 stuff bits: 98 + 16 + 13 = 127), and
  // the all-ones at 7FFh too (15: 126); no frame exceeds the bound.
  EXPECT_EQ(frame_bits(CanFrame{0x000, {0, 0, 0, 0, 0, 0, 0, 0}}), 127u);
  EXPECT_EQ(frame_bits(CanFrame{0x7FF, {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF}}), 126u);
  for (std::uint32_t id = 0; id < 0x800; id += 7) {
    for (std::uint8_t n = 0; n <= 8; ++n) {
      CanFrame f;
      f.id = id;
      f.dlc = n;
      for (std::uint8_t i = 0; i < n; ++i) f.data[i] = static_cast<std::uint8_t>((id * 31 + i * 17) & 0xFF);
      EXPECT_LE(frame_bits(f), frame_bits_worst_case(n)) << f.to_string();
      EXPECT_GE(frame_bits(f), 47u + 8u * n) << f.to_string();  // never shorter than unstuffed
    }
  }
}

TEST(FrameBits, ARemoteFrameHasNoDataField) {
  // 123h remote, DLC 0: 0 | 00100100011 | RTR 1 | IDE r0 00 | DLC 0000 | CRC 001101110011101
  // (1B9Dh). The longest zero run: IDE r0 DLC + the CRC's "00" = 8 zeros: 1 stuff bit; every
  // other run is shorter than 5. 34 + 1 + 13 = 48.
  const CanFrame r = CanFrame::remote(0x123, 0);
  EXPECT_EQ(can_crc15(r), 0x1B9D);
  EXPECT_EQ(frame_bits(r), 48u);
  // With DLC 8 the data field is still absent: only the DLC bits change.
  EXPECT_LT(frame_bits(CanFrame::remote(0x123, 8)), frame_bits_worst_case(0) + 1);
}

TEST(FrameBits, ArbitrationOrdersByIdentifierThenRtrThenFormat) {
  EXPECT_LT(arbitration_key(CanFrame{0x000, {1, 0}}), arbitration_key(CanFrame{0x080, {}}));
  EXPECT_LT(arbitration_key(CanFrame{0x181, {}}), arbitration_key(CanFrame{0x182, {}}));
  EXPECT_LT(arbitration_key(CanFrame{0x181, {}}), arbitration_key(CanFrame::remote(0x181, 0)));
  CanFrame ext;
  ext.id = 0x181u << 18;  // the same base identifier, 29-bit
  ext.extended = true;
  EXPECT_LT(arbitration_key(CanFrame{0x181, {}}), arbitration_key(ext));
  EXPECT_LT(arbitration_key(ext), arbitration_key(CanFrame{0x182, {}}));
}

}  // namespace
