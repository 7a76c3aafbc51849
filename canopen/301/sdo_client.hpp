// SDO client (CiA 301 §7.2.4): reads and writes the object dictionary of one SDO server.
//
// Requests are queued FIFO; one transfer is in flight at a time and the next starts when it
// finishes. "Sans I/O": upload()/download() only queue a request. Transfers are started, and
// timers run, in advance(now) and on_frame(now); next_deadline() reports "due now" (the last
// time the client was given) while a queued request waits to start, so an event loop that
// honours next_deadline() starts it at once.
//
// Transfer choice for a download: expedited for 1..4 bytes, segmented otherwise, block when the
// request asks for it or its size reaches SdoClientConfig::block_threshold. An upload is a normal
// upload (the server picks expedited or segmented) unless the request asks for block transfer.
//
// Every request ends with exactly one callback: SdoAbortCode::None and the data (empty for a
// download), or the abort code — the server's, or the one this client sent (0x05040000 on
// timeout, ...). Callbacks run after the frame or timer that finished the transfer has been fully
// handled; they may queue further requests.
//
// upload()/download() return a ticket naming the request; cancel(ticket, code) withdraws it: a
// queued request is removed, the one in flight is aborted on the bus with `code`; its callback
// is then called once with `code`.
#pragma once

#include <algorithm>
#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <initializer_list>
#include <optional>
#include <vector>

#include "canopen/301/sdo_block.hpp"
#include "canopen/301/sdo_pacer.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

struct SdoClientConfig {
  CobId request_cob;   // client -> server (0x600 + node-ID)
  CobId response_cob;  // server -> client (0x580 + node-ID)
  Duration timeout = std::chrono::seconds(1);
  // Downloads of at least this many bytes use block transfer; 0 = only when a request asks.
  std::size_t block_threshold = 0;
  std::uint8_t block_size = 127;           // sub-block size asked for in a block upload (1..127)
  std::uint8_t pst = 0;                    // block upload protocol switch threshold (0 = no switch)
  bool crc = true;                         // ask for the block-transfer CRC
  std::size_t max_upload_size = 1u << 20;  // larger uploads abort with 0x05040005

  // The default SDO channel of a server node (CiA 301 §7.3.5).
  static SdoClientConfig for_node(NodeId server);
};

enum class SdoTransfer : std::uint8_t {
  Auto,       // see above
  Segmented,  // never expedited (for the odd server that wants it; also handy in tests)
  Block,
  // Download only: expedited without size indication (e = 1, s = 0, CiA 301 §7.2.4.3.3) of
  // exactly four bytes, the server taking as many as its object has (what a gateway relays when
  // its own client sent it so). Other sizes are sent as Auto.
  ExpeditedUnsized,
};

class SdoWorkList;
class StateWriter;  // canopen/state.hpp
class StateReader;

class SdoClient {
 public:
  using Callback = std::function<void(SdoAbortCode code, std::vector<std::uint8_t> data)>;
  // Names one request: unique per client (counting from 1, wrapping past 0), never 0.
  using Ticket = std::uint32_t;

  SdoClient(FrameSink sink, SdoClientConfig config);
  SdoClient(FrameSink sink, NodeId server) : SdoClient(std::move(sink), SdoClientConfig::for_node(server)) {}
  // An owner's indexes (response COB-IDs, work list) point to its clients: none is copied.
  SdoClient(const SdoClient&) = delete;
  SdoClient& operator=(const SdoClient&) = delete;

  Ticket upload(std::uint16_t index, std::uint8_t sub, Callback callback, SdoTransfer mode = SdoTransfer::Auto);
  // As upload(), but this request's answer is awaited `timeout` (each step of it) instead of
  // SdoClientConfig::timeout: a probe that must not hold the channel as long as a real
  // transfer may (the network manager's boot-up probe). A late answer after its abort is the
  // caller's to expect: the next request to the same object reads it as its own, a request to
  // another object drops it (stale_answers()).
  Ticket upload_within(std::uint16_t index, std::uint8_t sub, Duration timeout, Callback callback);
  Ticket download(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data, Callback callback,
                  SdoTransfer mode = SdoTransfer::Auto);

  // True if the frame is on the response COB-ID.
  bool on_frame(const CanFrame& frame, TimePoint now);
  // Whether on_frame() takes `f` (the response COB-ID): inline, for a master that asks each of
  // its clients for every frame it receives.
  [[nodiscard]] bool answers_on(const CanFrame& f) const {
    return cfg_.response_cob.valid() && f.id == cfg_.response_cob.can_id() &&
           f.extended == cfg_.response_cob.extended();
  }
  void advance(TimePoint now);
  // Inline: a master asks each of its clients after every frame, and most are idle.
  [[nodiscard]] std::optional<TimePoint> next_deadline() const {
    if (state_ != State::Idle) return deadline_;
    // A queued request is waiting to start: due now, or when the pacer has a slot.
    if (queued() != 0) return pacer_ != nullptr ? std::max(now_, pacer_->next_free()) : now_;
    return std::nullopt;
  }

  // Changes the COB-IDs; a transfer in progress is aborted (0x08000000 to its callback, no frame).
  void set_cob_ids(CobId request, CobId response);
  // Sends an abort for the transfer in flight, if any, and fails it and every queued request
  // with `code`.
  void cancel_all(SdoAbortCode code = SdoAbortCode::GeneralError);
  // Fails every queued request with `code`, and the transfer in flight's requester at once too,
  // but lets that transfer run to its end on the wire (its answer, the server's abort, or the
  // time-out, all dropped) before the next request starts. CiA 301 SDO frames carry
  // no transaction number: after an abort, the server's late answer to the aborted request is
  // indistinguishable from an answer to the next one, so a caller that starts over with the
  // same server (a node that rebooted meanwhile) lets the old request finish first.
  void cancel_queued(SdoAbortCode code);
  // Withdraws one request: queued, it is removed; in flight, the abort frame with `code` is sent
  // (SdoAbortCode::None counts as 0x08000000). Its callback is called once with that code,
  // after this returns unless called from a callback. False (nothing done) if the ticket is
  // unknown or its transfer has finished.
  bool cancel(Ticket ticket, SdoAbortCode code);

  // Answers dropped as stale: while a request waits for its initiate answer, a frame naming
  // another object (index/sub-index) is an earlier request's late answer — one that timed out
  // or was cancelled, answered after its abort. CiA 301 SDO frames carry no transaction
  // number; the multiplexor the server echoes is all that tells them apart. Taking it for this
  // request's answer, or aborting this request over it, would put every later answer one request
  // off; it is dropped, and this request's own answer (or time-out) ends it.
  [[nodiscard]] std::uint64_t stale_answers() const { return stale_answers_; }

  // The pacer this client shares with the other clients on its bus (canopen/301/sdo_pacer.hpp),
  // or nullptr (the default): a queued request then starts when the client is idle and the
  // pacer has a slot free; next_deadline() reports that slot. Only a request's start is paced:
  // the segments of a transfer follow their answers.
  void set_pacer(SdoPacer* pacer) { pacer_ = pacer; }
  // Counted up by set_cob_ids(): an owner that indexes its clients by COB-ID (Master) sees that
  // its index is out of date.
  void set_cob_change_counter(std::uint64_t* counter) { cob_changes_ = counter; }
  // The owner's list of clients that may have work (see SdoWorkList): this client joins it when
  // a request is queued, at once if it has work already; it leaves a list it was on before.
  void set_work_list(SdoWorkList* list);
  // No transfer in flight and none queued: next_deadline() is nullopt and advance() does nothing.
  [[nodiscard]] bool idle() const { return state_ == State::Idle && queued() == 0; }

  // Run-time state (canopen/state.hpp) of an idle client: the last time given, the last ticket,
  // the stale-answer count and a pacer refusal still to count. A transfer under way is not
  // state: export and import throw std::logic_error unless idle(). The COB-IDs, time-out and
  // pacer are configuration. import_state throws StateError.
  void export_state(StateWriter& w) const;
  void import_state(const StateReader& r);

  [[nodiscard]] bool busy() const { return state_ != State::Idle; }
  [[nodiscard]] std::size_t queued() const { return queue_.size() - queue_head_; }
  [[nodiscard]] const SdoClientConfig& config() const { return cfg_; }

 private:
  enum class State : std::uint8_t {
    Idle,
    UploadInitiate,
    UploadSegment,
    DownloadInitiate,
    DownloadSegment,
    BlockDownloadInitiate,
    BlockDownloadAck,
    BlockDownloadEnd,
    BlockUploadInitiate,
    BlockUploadSubBlock,
    BlockUploadEnd,
  };
  struct Request {
    bool upload = true;
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    std::vector<std::uint8_t> data;
    Callback callback;
    SdoTransfer mode = SdoTransfer::Auto;
    Ticket ticket = 0;
    std::optional<Duration> timeout;  // upload_within(); else SdoClientConfig::timeout
  };
  struct Done {
    Callback callback;
    SdoAbortCode code;
    std::vector<std::uint8_t> data;
  };

  void start(TimePoint now);
  void handle(const CanFrame& f);
  void on_upload_initiate(const std::uint8_t* d);
  void on_upload_segment(const std::uint8_t* d);
  void on_download_initiate(const std::uint8_t* d);
  void on_download_segment(const std::uint8_t* d);
  void on_block_download_initiate(const std::uint8_t* d);
  void on_block_download_ack(const std::uint8_t* d);
  void on_block_upload_initiate(const std::uint8_t* d);
  void on_block_upload_segment(const std::uint8_t* d);
  void on_block_upload_end(const std::uint8_t* d);
  void send_download_segment();
  void send_download_sub_block();
  [[nodiscard]] bool mux_matches(const std::uint8_t* d) const;
  [[nodiscard]] bool stale(const CanFrame& f) const;  // see stale_answers()

  void finish(SdoAbortCode code);
  void abort(SdoAbortCode code);  // sends the abort frame, then finish(code)
  void send(const std::array<std::uint8_t, 8>& bytes);
  void send(std::initializer_list<std::uint8_t> bytes);
  void pump();
  // The pacer's leave for the next request (always without a pacer); a refusal is remembered so
  // that the request's start counts as delayed (SdoPacer::delayed_starts).
  bool paced_start();
  Ticket next_ticket();
  void join_work_list();
  [[nodiscard]] Duration step_timeout() const { return current_.timeout.value_or(cfg_.timeout); }

  FrameSink sink_;
  SdoClientConfig cfg_;
  std::vector<Request> queue_;  // requests queue_[queue_head_..] wait to start (see outbox_)
  std::size_t queue_head_ = 0;
  State state_ = State::Idle;
  Request current_;
  TimePoint now_{};
  TimePoint deadline_{};

  std::vector<std::uint8_t> buffer_;  // upload: received data
  bool size_indicated_ = false;
  std::size_t size_ = 0;
  std::size_t pos_ = 0;  // segmented download: next byte to send
  bool toggle_ = false;
  bool crc_ = false;
  bool last_in_block_ = false;            // segmented download: the segment just sent was the last
  sdo_block::SubBlockReceiver rx_block_;  // block upload: receiving side
  sdo_block::SubBlockSender tx_block_;    // block download: sending side

  // FIFOs drained by pump(): a vector read from a head index and cleared (capacity kept) once
  // drained, so that sending a frame or finishing a transfer does not allocate.
  std::vector<CanFrame> outbox_;
  std::size_t outbox_head_ = 0;
  std::vector<Done> done_;
  std::size_t done_head_ = 0;
  bool pumping_ = false;
  Ticket last_ticket_ = 0;
  std::uint64_t stale_answers_ = 0;
  SdoPacer* pacer_ = nullptr;
  bool waited_for_pacer_ = false;  // the next request was refused by the pacer
  std::uint64_t* cob_changes_ = nullptr;
  SdoWorkList* work_list_ = nullptr;
  bool listed_ = false;  // in work_list_
  friend class SdoWorkList;
};

// The clients of one owner that may have work: a client joins when a request is queued to it
// (the only way out of idle), the owner drops those it finds idle (prune()). A master asks its
// clients for their next deadline after every frame; with one client per sub-device, nearly all
// idle, asking only these saves a call per idle client and frame.
class SdoWorkList {
 public:
  [[nodiscard]] const std::vector<SdoClient*>& clients() const { return clients_; }
  void join(SdoClient& c) {
    if (c.listed_) return;
    c.listed_ = true;
    clients_.push_back(&c);
  }
  void leave(SdoClient& c) {
    if (!c.listed_) return;
    c.listed_ = false;
    std::erase(clients_, &c);
  }
  // Drops the idle clients (each joins again with its next request).
  void prune() {
    std::erase_if(clients_, [](SdoClient* c) {
      if (!c->idle()) return false;
      c->listed_ = false;
      return true;
    });
  }

 private:
  std::vector<SdoClient*> clients_;
};

}  // namespace oegw::canopen
