// What the SDO server (block download) and the SDO client (block upload) share: the receiving
// side of a block transfer's sub-blocks (CiA 301 §7.2.4.3.9 and §7.2.4.3.12).
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

namespace oegw::canopen::sdo_block {

inline constexpr std::size_t kSegmentData = 7;  // data bytes per segment

// A size rounded up to whole segments (at least one).
inline std::size_t round_up_segments(std::size_t n) {
  return std::max<std::size_t>(kSegmentData, (n + kSegmentData - 1) / kSegmentData * kSegmentData);
}

class SubBlockReceiver {
 public:
  enum class Outcome : std::uint8_t {
    Ok,           // stored (or ignored as a repeat/out-of-order segment, to be re-sent)
    BadSequence,  // sequence number 0 or above the block size: abort 0504 0003h
    Overflow,     // more data than `capacity` allows: the caller picks the abort code
  };
  struct Result {
    Outcome outcome = Outcome::Ok;
    // The acknowledgement to send when the sub-block is complete: A2h, ackseq, blksize.
    std::optional<std::array<std::uint8_t, 8>> ack;
  };

  void start(std::uint8_t blksize) {
    blksize_ = blksize;
    expected_seq_ = 1;
    last_received_ = false;
  }
  [[nodiscard]] std::uint8_t blksize() const { return blksize_; }
  // The segment with the "no more segments" bit has been stored: the end frame comes next.
  [[nodiscard]] bool finished() const { return last_received_; }

  // One segment frame `d` (8 bytes). Stores its 7 data bytes in `buffer` if it is the one
  // expected; a missing or repeated segment is skipped so that the acknowledgement makes the
  // sender retransmit from the last good one. `capacity` bounds the buffer (rounded up to
  // whole segments: the unused bytes of the last one are only known at the end).
  Result segment(const std::uint8_t* d, std::vector<std::uint8_t>& buffer, std::size_t capacity) {
    const std::uint8_t seq = d[0] & 0x7F;
    const bool last = (d[0] & 0x80) != 0;
    if (seq == 0 || seq > blksize_) return {Outcome::BadSequence, std::nullopt};
    if (seq == expected_seq_) {
      if (buffer.size() + kSegmentData > round_up_segments(capacity)) return {Outcome::Overflow, std::nullopt};
      buffer.insert(buffer.end(), d + 1, d + 1 + kSegmentData);
      ++expected_seq_;
      last_received_ = last;
    }
    if (seq != blksize_ && !last) return {};
    const auto ackseq = static_cast<std::uint8_t>(expected_seq_ - 1);
    if (!last_received_) expected_seq_ = 1;
    return {Outcome::Ok, std::array<std::uint8_t, 8>{0xA2, ackseq, blksize_, 0, 0, 0, 0, 0}};
  }

 private:
  std::uint8_t blksize_ = 0;
  std::uint8_t expected_seq_ = 1;
  bool last_received_ = false;
};

// The sending side of a block transfer's sub-blocks (CiA 301 §7.2.4.3.9 and §7.2.4.3.12): the
// SDO client's block download and the SDO server's block upload.
class SubBlockSender {
 public:
  enum class Ack : std::uint8_t {
    Continue,      // send the next sub-block (from the first segment not acknowledged)
    Done,          // the last segment was acknowledged: send end_frame() next
    BadSequence,   // ackseq above what was sent: abort 0504 0003h
    BadBlockSize,  // new block size 0 or above the maximum: abort 0504 0002h
  };

  void start(std::uint8_t blksize) {
    blksize_ = blksize;
    pos_ = 0;
    sent_ = 0;
    last_ = false;
  }

  // Sends up to blksize segments of `data` from the first one not yet acknowledged.
  template <class Send>
  void send_sub_block(const std::vector<std::uint8_t>& data, Send&& send) {
    std::size_t p = pos_;
    sent_ = 0;
    last_ = false;
    while (sent_ < blksize_ && !last_) {
      const std::size_t n = std::min(kSegmentData, data.size() - p);
      last_ = p + n == data.size();
      ++sent_;
      std::array<std::uint8_t, 8> out{};
      out[0] = static_cast<std::uint8_t>(sent_ | (last_ ? 0x80 : 0x00));
      std::copy_n(data.begin() + static_cast<std::ptrdiff_t>(p), n, out.begin() + 1);
      p += n;
      send(out);
    }
  }

  // The receiver's acknowledgement frame `d` (A2h, ackseq, blksize) for `size` bytes in all.
  Ack acknowledge(const std::uint8_t* d, std::size_t size, std::uint8_t max_blksize) {
    const std::uint8_t ackseq = d[1];
    const std::uint8_t blksize = d[2];
    if (ackseq > sent_) return Ack::BadSequence;
    if (blksize == 0 || blksize > max_blksize) return Ack::BadBlockSize;
    if (ackseq == sent_ && last_) return Ack::Done;
    pos_ = std::min(size, pos_ + std::size_t{ackseq} * kSegmentData);  // resend from ackseq + 1
    blksize_ = blksize;
    return Ack::Continue;
  }

  // The end-of-block frame: C1h with the unused bytes of the last segment, and the CRC.
  static std::array<std::uint8_t, 8> end_frame(std::size_t size, std::uint16_t crc) {
    const std::size_t in_last = size == 0 ? 0 : (size - 1) % kSegmentData + 1;
    std::array<std::uint8_t, 8> out{};
    out[0] = static_cast<std::uint8_t>(0xC1 | ((kSegmentData - in_last) << 2));
    out[1] = static_cast<std::uint8_t>(crc);
    out[2] = static_cast<std::uint8_t>(crc >> 8);
    return out;
  }

 private:
  std::uint8_t blksize_ = 0;
  std::size_t pos_ = 0;    // first byte not yet acknowledged
  std::uint8_t sent_ = 0;  // segments in the sub-block just sent
  bool last_ = false;      // it carried the last segment
};

}  // namespace oegw::canopen::sdo_block
