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
//
// Remote (routed) mode, for multi-level networking (CiA 302-7; the SDO network indication of
// CiA 301 v4.2 §7.2.4.3, frame layout in sdo_remote.hpp). With an SdoRemote installed
// (set_remote), a network indication names the channel's target; a channel may also be bound to
// one by configuration (bind). While the target is another node:
//  * The client's transfers (expedited, segmented, block, both directions, the block-upload
//    protocol switch) run on the state machines above, but the object dictionary is replaced by
//    the remote. An initiate upload or block upload asks the remote for the value and is
//    answered only when it arrives, in the mode and with the size the data gives (expedited up
//    to 4 bytes, pst compared with the data size). A download is handed to the remote whole,
//    where a local one would be written: the expedited initiate (with s = 0 all four bytes go,
//    the object's size being unknown here), the last segment, the block end after the CRC
//    check; that frame's response (initiate response, last segment response with its toggle,
//    block end response) is sent when the remote confirms. A download carries at most
//    kMaxRemoteDownload bytes (more: 0504 0005h); object checks are the remote server's.
//  * A remote's abort code is sent to the client unchanged, with the transfer's index/sub.
//  * While the remote works, this server's client time-out does not run (the remote side has
//    its own and reports it as an abort code). The client's abort frame cancels the remote
//    transfer with the client's code and is not answered. Any other frame is "a request while
//    another is in flight": the remote transfer is cancelled and the client is answered with
//    0x060A0023 "resource not available: SDO connection" (index/sub of the new request if it is
//    an initiate or a network indication, else the pending transfer's; it is not served), or
//    0x05040001 for a frame shorter than 8 bytes, as in every state. The remote's answer may
//    come at any time, from inside upload()/download() or later from another bus's frame
//    handling: it is sent at once. After it the client time-out starts: next_deadline() reports
//    "due now" until advance() arms it.
//  * The target stays for every transfer until another network indication names one (a refused
//    indication keeps the old target), the COB-IDs change or reset() (NMT reset communication):
//    then the own dictionary is the target again. redirect() tells the target a network
//    indication named, since when and by which request; on_redirect reports each change (a
//    redirect names a sub-device on a channel any client may use: a second client on it reads
//    that node believing it reads this server). reset(), set_cob_ids(), bind() and
//    set_remote() cancel a pending remote transfer with 0x08000000 and send nothing (as a
//    local transfer is dropped silently). A bound channel keeps its target across reset() and
//    refuses network indications with 0x08000021; bound without an SdoRemote it refuses every
//    transfer with 0x060A0023. Without an SdoRemote a network indication is an unknown command
//    (0x05040001), as for any server without multi-level networking.
//  * A network indication (like an initiate) abandons a transfer in progress silently.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <initializer_list>
#include <optional>
#include <vector>

#include "canopen/301/object_dictionary.hpp"
#include "canopen/301/sdo_block.hpp"
#include "canopen/301/sdo_remote.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

class StateWriter;  // canopen/state.hpp
class StateReader;

class SdoServer {
 public:
  static constexpr Duration kDefaultTimeout = std::chrono::seconds(1);
  static constexpr std::uint8_t kMaxBlockSize = 127;
  // Transfer buffer capacity kept between transfers (larger buffers are released at the end).
  static constexpr std::size_t kKeptBufferCapacity = 4096;
  // Most bytes a download to a remote target may carry (the remote's SDO client holds them too).
  static constexpr std::size_t kMaxRemoteDownload = std::size_t{1} << 20;

  // rx: client -> server (default 0x600 + node-ID); tx: server -> client (0x580 + node-ID).
  SdoServer(ObjectDictionary& od, FrameSink sink, CobId rx, CobId tx, Duration timeout = kDefaultTimeout);
  // The default SDO channel of the pre-defined connection set (CiA 301 §7.3.5).
  SdoServer(ObjectDictionary& od, FrameSink sink, NodeId node, Duration timeout = kDefaultTimeout);
  // A pending remote transfer holds a callback to this server: it is cancelled here. Do not
  // move a server while a remote transfer is pending (busy() with a target()).
  ~SdoServer();
  SdoServer(SdoServer&&) = default;
  SdoServer& operator=(SdoServer&&) = delete;

  // True if the frame is on the server's rx COB-ID (it is then consumed, even if malformed).
  bool on_frame(const CanFrame& frame, TimePoint now);
  // Aborts the transfer with 0x05040000 when the client has been silent for the timeout.
  void advance(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const;

  // 1200h:01/02 changed. A transfer in progress is dropped silently (a remote one cancelled)
  // and the target is the own dictionary again unless bound. An invalid COB-ID (bit 31)
  // disables the server.
  void set_cob_ids(CobId rx, CobId tx);
  // Drops any transfer silently (NMT reset communication, ...), as set_cob_ids().
  void reset();
  // Where routed transfers go (nullptr, the default: network indications are unknown commands).
  // Drops any transfer (a remote one cancelled) and returns to the own dictionary unless bound.
  void set_remote(SdoRemote* remote);
  // Fixes the channel's target (a sub-device, by configuration); nullopt: the own dictionary,
  // network indications allowed. Drops any transfer (a remote one cancelled).
  void bind(std::optional<SdoTarget> target);
  // The node the channel's transfers go to; nullopt: the own dictionary.
  [[nodiscard]] std::optional<SdoTarget> target() const;
  // Ends a transfer in progress with an abort to its client (either side may abort at any time,
  // CiA 301 §7.2.4.3.17), a remote one cancelled toward its node with the same code; idle: nothing.
  // For a change of the server's owner (the gateway replaced at a reload) that would otherwise
  // drop the transfer silently and leave the client to its own time-out.
  void abort_in_progress(SdoAbortCode code);

  // The redirect an accepted network indication made (not a bind()): the target it named, when
  // (the `now` of its frame) and the request's eight bytes (CAN carries no sender: the request
  // is what names it).
  struct Redirect {
    SdoTarget target;
    TimePoint since{};
    std::array<std::uint8_t, 8> request{};
  };
  // What changed a redirect: a network indication (one began, named another node or the same
  // node again, or named the server itself and ended it), reset() (NMT reset communication,
  // reset node, entering stopped), set_cob_ids() with other COB-IDs, bind()/set_remote().
  enum class RedirectChange : std::uint8_t { Indication, Reset, CobIds, Reconfigured };
  [[nodiscard]] const std::optional<Redirect>& redirect() const { return selected_; }
  // Called after every change of redirect(): `before` and `after` (either may be empty, not
  // both). Not called when there was none and none follows.
  std::function<void(const std::optional<Redirect>& before, const std::optional<Redirect>& after, RedirectChange why)>
      on_redirect;
  // Sub-block size offered to a block-download client (1..127; default 127).
  void set_block_size(std::uint8_t blksize);

  [[nodiscard]] bool busy() const { return state_ != State::Idle; }

  // Run-time state (canopen/state.hpp) of an idle server: its COB-IDs (they follow the node-ID
  // and 1200h..127Fh), the redirect a network indication made, the remote generation. A
  // transfer under way is not state: export and import throw std::logic_error while busy().
  // The time-out, block size, bound target and remote are configuration. on_redirect is not
  // called. import_state throws StateError.
  void export_state(StateWriter& w) const;
  void import_state(const StateReader& r);
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
    RemoteWait,  // a transfer is with the remote; step_ says what to answer when it is done
  };
  enum class RemoteStep : std::uint8_t { Upload, BlockUpload, ExpeditedDownload, LastSegment, BlockDownloadEnd };
  struct BlockUploadRequest {
    std::uint8_t blksize = 0;
    std::uint8_t pst = 0;
    bool crc = false;
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
  void respond_block_upload_initiate(BlockUploadRequest request);
  void network_indication(const std::uint8_t* d);
  void initiate_remote_download(const std::uint8_t* d);
  // A segmented download's initiate, local or remote: the announced size checked (or, unsized,
  // `unsized_capacity` the most it may carry), then the initiate response.
  void begin_segmented_download(const std::uint8_t* d, std::size_t unsized_capacity);
  void start_remote_upload(RemoteStep step);
  void start_remote_download(RemoteStep step, std::uint8_t response);  // buffer_ holds the data
  SdoRemote::Done remote_done(std::uint32_t generation);
  void on_remote_done(std::uint32_t generation, SdoAbortCode code, std::vector<std::uint8_t> data);
  void frame_while_waiting(const CanFrame& f);
  void cancel_remote(SdoAbortCode why);  // a pending remote transfer, if any; state -> Idle
  // selected_ becomes `next`; on_redirect is told when there was one or is one now.
  void set_redirect(std::optional<Redirect> next, RedirectChange why);
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
  std::size_t size_ = 0;      // announced size (download) or value size (upload)
  std::size_t capacity_ = 0;  // most bytes the download may carry
  std::size_t pos_ = 0;       // segmented upload: next byte to send
  bool toggle_ = false;
  bool crc_ = false;                      // block transfer: both sides use the CRC
  sdo_block::SubBlockReceiver rx_block_;  // block download: receiving side
  sdo_block::SubBlockSender tx_block_;    // block upload: sending side

  std::vector<CanFrame> outbox_;  // sent by flush()
  bool flushing_ = false;

  // Remote mode.
  SdoRemote* remote_ = nullptr;
  std::optional<SdoTarget> bound_;    // bind()
  std::optional<Redirect> selected_;  // the last accepted network indication naming a node
  bool routed_ = false;               // the transfer in progress goes to the remote
  RemoteStep step_ = RemoteStep::Upload;
  BlockUploadRequest block_upload_;
  std::uint8_t remote_response_ = 0;  // command byte of the answer a download's done sends
  SdoRemote::Ticket ticket_ = 0;      // the pending remote transfer
  // Tells a done of the pending transfer from one of a transfer cancelled or replaced.
  std::uint32_t remote_generation_ = 0;
  bool handling_ = false;      // inside on_frame(): it flushes and sets the deadline
  bool arm_deadline_ = false;  // the remote answered: advance() starts the time-out
  TimePoint now_{};            // the last time given
};

}  // namespace oegw::canopen
