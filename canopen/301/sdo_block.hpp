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
    Ok,              // stored (or ignored as a repeat/out-of-order segment, to be re-sent)
    BadSequence,     // sequence number 0 or above the block size: abort 0504 0003h
    Overflow,        // more data than `capacity` allows: the caller picks the abort code
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

}  // namespace oegw::canopen::sdo_block
