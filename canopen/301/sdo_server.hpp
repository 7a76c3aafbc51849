// SDO server (CiA 301 §7.2.4): gives an SDO client access to the object dictionary.
//
// Supports expedited, segmented and block download and upload (block with CRC-16-CCITT when the
// client asks for it, and the block-upload protocol switch threshold). "Sans I/O": frames and
// the current time come in as arguments, frames go out through the FrameSink, timers run in
// advance(now).
//
// Behaviour worth knowing:
//  * Downloads are atomic. Segmented and block downloads are buffered and written to the object
//    dictionary only when the last segment (or the block end) arrives; an abort, a timeout or a
//    refused write leaves the object dictionary untouched. The buffer is capped at the object's
//    fixed size, or SubObject::max_size for strings and DOMAINs.
//  * A frame whose DLC is below 8 is a protocol error (CiA 301 §7.2.4.3: every SDO frame carries
//    8 data bytes). The server answers 0x05040001 "command specifier not valid or unknown": the
//    command byte of a short frame cannot be interpreted as a valid SDO command, and 301 has no
//    more specific code for a malformed frame. An abort frame from the client (ccs = 4: 0x80..0x9F)
//    is never answered, whatever its DLC: it just ends the transfer.
//  * An initiate request that arrives during a transfer abandons the old transfer silently
//    (nothing is written, no abort frame is sent for it — the client has obviously given up on
//    it, and an abort frame would be read as the answer to its new request) and is then served.
//  * During a block download sub-block, every frame other than an abort (0x80) is a segment.
//    A sequence number 0 or above the block size aborts with 0x05040003; a missing or repeated
//    segment is ignored and the sub-block acknowledged up to the last good one, so that the
//    client retransmits (CiA 301 §7.2.4.3.9).
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <initializer_list>
#include <optional>
#include <vector>

#include "canopen/301/object_dictionary.hpp"
#include "canopen/301/sdo_block.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

class SdoServer {
 public:
  static constexpr Duration kDefaultTimeout = std::chrono::seconds(1);
  static constexpr std::uint8_t kMaxBlockSize = 127;
  // Transfer buffer capacity kept between transfers (larger buffers are released at the end).
  static constexpr std::size_t kKeptBufferCapacity = 4096;

  // rx: client -> server (default 0x600 + node-ID); tx: server -> client (0x580 + node-ID).
  SdoServer(ObjectDictionary& od, FrameSink sink, CobId rx, CobId tx, Duration timeout = kDefaultTimeout);
  // The default SDO channel of the pre-defined connection set (CiA 301 §7.3.5).
  SdoServer(ObjectDictionary& od, FrameSink sink, NodeId node, Duration timeout = kDefaultTimeout);

  // True if the frame is on the server's rx COB-ID (it is then consumed, even if malformed).
  bool on_frame(const CanFrame& frame, TimePoint now);
  // Aborts the transfer with 0x05040000 when the client has been silent for the timeout.
  void advance(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const;

  // 1200h:01/02 changed. A transfer in progress is dropped silently. An invalid COB-ID (bit 31)
  // disables the server.
  void set_cob_ids(CobId rx, CobId tx);
  // Drops any transfer silently (NMT reset communication, ...).
  void reset();
  // Sub-block size offered to a block-download client (1..127; default 127).
  void set_block_size(std::uint8_t blksize);

  [[nodiscard]] bool busy() const { return state_ != State::Idle; }
  [[nodiscard]] CobId rx_cob_id() const { return rx_; }
  [[nodiscard]] CobId tx_cob_id() const { return tx_; }

 private:
  enum class State : std::uint8_t {
    Idle,
    DownloadSegmented,
    UploadSegmented,
    BlockDownloadSubBlock,
    BlockDownloadEnd,
    BlockUploadStart,
    BlockUploadAck,
    BlockUploadEnd,
  };

  void handle(const CanFrame& f);
  void initiate_download(const std::uint8_t* d);
  void initiate_upload(const std::uint8_t* d);
  void initiate_block_download(const std::uint8_t* d);
  void initiate_block_upload(const std::uint8_t* d);
  void download_segment(const std::uint8_t* d);
  void upload_segment(const std::uint8_t* d);
  void block_download_segment(const std::uint8_t* d);
  void block_download_end(const std::uint8_t* d);
  void block_upload_ack(const std::uint8_t* d);
  void send_upload_sub_block();
  void respond_upload_initiate();
  // Validates the size announced by an initiate download request against the object.
  [[nodiscard]] SdoAbortCode check_announced_size(std::uint32_t size) const;
  // The code for "more data than fits" during a segmented/block download.
  [[nodiscard]] SdoAbortCode overflow_code() const;
  void commit_download();

  void abort(std::uint16_t index, std::uint8_t sub, SdoAbortCode code);
  void abort_transfer(SdoAbortCode code) { abort(index_, sub_, code); }
  void drop();
  void send(std::initializer_list<std::uint8_t> bytes);
  void send(const std::array<std::uint8_t, 8>& bytes);
  void flush();

  ObjectDictionary& od_;
  FrameSink sink_;
  CobId rx_;
  CobId tx_;
  Duration timeout_;
  std::uint8_t block_size_ = kMaxBlockSize;

  State state_ = State::Idle;
  TimePoint deadline_{};
  std::uint16_t index_ = 0;
  std::uint8_t sub_ = 0;
  std::vector<std::uint8_t> buffer_;
  bool size_indicated_ = false;
  std::size_t size_ = 0;       // announced size (download) or value size (upload)
  std::size_t capacity_ = 0;   // most bytes the download may carry
  std::size_t pos_ = 0;        // segmented upload: next byte to send
  bool toggle_ = false;
  bool crc_ = false;           // block transfer: both sides use the CRC
  sdo_block::SubBlockReceiver rx_block_;  // block download: receiving side
  sdo_block::SubBlockSender tx_block_;    // block upload: sending side

  std::vector<CanFrame> outbox_;  // sent by flush()
  bool flushing_ = false;
};

}  // namespace oegw::canopen
