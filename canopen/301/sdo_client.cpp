#include "canopen/301/sdo_client.hpp"

#include <algorithm>
#include <array>
#include <stdexcept>

#include "canopen/301/crc16.hpp"
#include "canopen/301/sdo_block.hpp"
#include "canopen/state.hpp"

namespace oegw::canopen {

namespace {

using sdo_block::kSegmentData;
using sdo_block::round_up_segments;
constexpr std::uint8_t kAbort = 0x80;

}  // namespace

SdoClientConfig SdoClientConfig::for_node(NodeId server) {
  SdoClientConfig c;
  c.request_cob = CobId(cob::kSdoRx + server.value());
  c.response_cob = CobId(cob::kSdoTx + server.value());
  return c;
}

SdoClient::SdoClient(FrameSink sink, SdoClientConfig config) : sink_(std::move(sink)), cfg_(config) {
  cfg_.block_size = std::clamp<std::uint8_t>(cfg_.block_size, 1, 127);
}

SdoClient::Ticket SdoClient::upload(std::uint16_t index, std::uint8_t sub, Callback callback, SdoTransfer mode) {
  const Ticket ticket = next_ticket();
  queue_.push_back(Request{true, index, sub, {}, std::move(callback), mode, ticket});
  join_work_list();
  return ticket;
}

SdoClient::Ticket SdoClient::upload_within(std::uint16_t index, std::uint8_t sub, Duration timeout, Callback callback) {
  const Ticket ticket = next_ticket();
  queue_.push_back(Request{true, index, sub, {}, std::move(callback), SdoTransfer::Auto, ticket, timeout});
  join_work_list();
  return ticket;
}

SdoClient::Ticket SdoClient::download(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data,
                                      Callback callback, SdoTransfer mode) {
  const Ticket ticket = next_ticket();
  queue_.push_back(Request{false, index, sub, std::move(data), std::move(callback), mode, ticket});
  join_work_list();
  return ticket;
}

SdoClient::Ticket SdoClient::next_ticket() {
  if (++last_ticket_ == 0) ++last_ticket_;
  return last_ticket_;
}

void SdoClient::set_work_list(SdoWorkList* list) {
  if (work_list_ != nullptr && work_list_ != list) work_list_->leave(*this);
  work_list_ = list;
  if (!idle()) join_work_list();
}

void SdoClient::join_work_list() {
  if (work_list_ != nullptr) work_list_->join(*this);
}

bool SdoClient::cancel(Ticket ticket, SdoAbortCode code) {
  if (ticket == 0) return false;
  if (code == SdoAbortCode::None) code = SdoAbortCode::GeneralError;
  if (state_ != State::Idle && current_.ticket == ticket) {
    abort(code);
    pump();
    return true;
  }
  const auto first = queue_.begin() + static_cast<std::ptrdiff_t>(queue_head_);
  const auto it = std::find_if(first, queue_.end(), [ticket](const Request& r) { return r.ticket == ticket; });
  if (it == queue_.end()) return false;
  done_.push_back(Done{std::move(it->callback), code, {}});
  queue_.erase(it);
  if (queue_head_ == queue_.size()) {
    queue_.clear();
    queue_head_ = 0;
  }
  pump();
  return true;
}

void SdoClient::advance(TimePoint now) {
  now_ = now;
  if (state_ != State::Idle && now >= deadline_) abort(SdoAbortCode::Timeout);
  pump();
}

bool SdoClient::on_frame(const CanFrame& frame, TimePoint now) {
  if (!answers_on(frame)) return false;
  now_ = now;
  if (!frame.rtr && state_ != State::Idle) {
    if (stale(frame)) {
      ++stale_answers_;  // an earlier request's late answer: not this one's, which is still awaited
    } else {
      handle(frame);
      deadline_ = now + step_timeout();
    }
  }
  pump();
  return true;
}

void SdoClient::set_cob_ids(CobId request, CobId response) {
  cfg_.request_cob = request;
  cfg_.response_cob = response;
  if (cob_changes_ != nullptr) ++*cob_changes_;
  if (state_ != State::Idle) finish(SdoAbortCode::GeneralError);
  pump();
}

void SdoClient::cancel_all(SdoAbortCode code) {
  if (state_ != State::Idle) abort(code);
  for (std::size_t i = queue_head_; i < queue_.size(); ++i)
    done_.push_back(Done{std::move(queue_[i].callback), code, {}});
  queue_.clear();
  queue_head_ = 0;
  pump();
}

void SdoClient::cancel_queued(SdoAbortCode code) {
  // The requester of the transfer in flight is answered now; the transfer itself stays on the
  // wire (the client busy, its answer or time-out dropped), see the header.
  if (state_ != State::Idle && current_.callback) done_.push_back(Done{std::move(current_.callback), code, {}});
  current_.callback = nullptr;
  for (std::size_t i = queue_head_; i < queue_.size(); ++i)
    done_.push_back(Done{std::move(queue_[i].callback), code, {}});
  queue_.clear();
  queue_head_ = 0;
  pump();
}

void SdoClient::start(TimePoint now) {
  current_ = std::move(queue_[queue_head_++]);
  if (queue_head_ == queue_.size()) {
    queue_.clear();  // keeps the capacity: queueing a request does not allocate
    queue_head_ = 0;
  } else if (queue_head_ >= 64 && queue_head_ * 2 >= queue_.size()) {
    // Never drained (always a request waiting): drop the started half.
    queue_.erase(queue_.begin(), queue_.begin() + static_cast<std::ptrdiff_t>(queue_head_));
    queue_head_ = 0;
  }
  deadline_ = now + step_timeout();
  buffer_.clear();
  pos_ = 0;
  toggle_ = false;
  crc_ = false;
  const auto lo = static_cast<std::uint8_t>(current_.index);
  const auto hi = static_cast<std::uint8_t>(current_.index >> 8);
  const std::uint8_t sub = current_.sub;
  if (current_.upload) {
    if (current_.mode == SdoTransfer::Block) {
      state_ = State::BlockUploadInitiate;
      send({static_cast<std::uint8_t>(0xA0 | (cfg_.crc ? 0x04 : 0x00)), lo, hi, sub, cfg_.block_size, cfg_.pst, 0, 0});
    } else {
      state_ = State::UploadInitiate;
      send({0x40, lo, hi, sub, 0, 0, 0, 0});
    }
    return;
  }
  size_ = current_.data.size();
  const bool block = current_.mode == SdoTransfer::Block ||
                     (current_.mode == SdoTransfer::Auto && cfg_.block_threshold != 0 && size_ >= cfg_.block_threshold);
  if (block) {
    state_ = State::BlockDownloadInitiate;
    std::array<std::uint8_t, 8> out{static_cast<std::uint8_t>(0xC2 | (cfg_.crc ? 0x04 : 0x00)), lo, hi, sub};
    put_u32(out.data() + 4, static_cast<std::uint32_t>(size_));
    send(out);
    return;
  }
  state_ = State::DownloadInitiate;
  if (current_.mode == SdoTransfer::ExpeditedUnsized && size_ == 4) {
    std::array<std::uint8_t, 8> out{0x22, lo, hi, sub};
    std::copy(current_.data.begin(), current_.data.end(), out.begin() + 4);
    pos_ = size_;
    send(out);
    return;
  }
  if ((current_.mode == SdoTransfer::Auto || current_.mode == SdoTransfer::ExpeditedUnsized) && size_ >= 1 &&
      size_ <= 4) {
    std::array<std::uint8_t, 8> out{static_cast<std::uint8_t>(0x23 | ((4 - size_) << 2)), lo, hi, sub};
    std::copy(current_.data.begin(), current_.data.end(), out.begin() + 4);
    pos_ = size_;  // all data went with the initiate request
    send(out);
    return;
  }
  std::array<std::uint8_t, 8> out{0x21, lo, hi, sub};
  put_u32(out.data() + 4, static_cast<std::uint32_t>(size_));
  send(out);
}

bool SdoClient::stale(const CanFrame& f) const {
  // Only an initiate answer (or an abort) names its object; a segment names none.
  const bool initiate = state_ == State::UploadInitiate || state_ == State::DownloadInitiate ||
                        state_ == State::BlockDownloadInitiate || state_ == State::BlockUploadInitiate;
  if (!initiate || f.dlc != 8) return false;
  const std::uint8_t scs = f.data[0] >> 5;
  // Upload (2), download (3), block download (5), block upload (6) initiate answers and aborts
  // (4) carry the request's multiplexor (CiA 301 §7.2.4.3.3 ff., §7.2.4.3.17).
  if (scs != 2 && scs != 3 && scs != 4 && scs != 5 && scs != 6) return false;
  return !mux_matches(f.data.data());
}

bool SdoClient::mux_matches(const std::uint8_t* d) const {
  return get_u16(d + 1) == current_.index && d[3] == current_.sub;
}

void SdoClient::handle(const CanFrame& f) {
  const std::uint8_t* d = f.data.data();
  // The server aborted: scs = 4; in a block upload sub-block only 0x80 (0x81.. are segments).
  const bool sub_block = state_ == State::BlockUploadSubBlock;
  if (f.dlc >= 1 && (sub_block ? d[0] == kAbort : (d[0] >> 5) == 4)) {
    finish(f.dlc == 8 ? static_cast<SdoAbortCode>(get_u32(d + 4)) : SdoAbortCode::GeneralError);
    return;
  }
  if (f.dlc < 8) return abort(SdoAbortCode::UnknownCommandSpecifier);  // see SdoServer: DLC is always 8
  const std::uint8_t cmd = d[0];
  const auto scs = static_cast<std::uint8_t>(cmd >> 5);
  switch (state_) {
    case State::UploadInitiate:
      if (scs == 2) return on_upload_initiate(d);
      break;
    case State::UploadSegment:
      if (scs == 0) return on_upload_segment(d);
      break;
    case State::DownloadInitiate:
      if (scs == 3) return on_download_initiate(d);
      break;
    case State::DownloadSegment:
      if (scs == 1) return on_download_segment(d);
      break;
    case State::BlockDownloadInitiate:
      if ((cmd & 0xE3) == 0xA0) return on_block_download_initiate(d);
      break;
    case State::BlockDownloadAck:
      if ((cmd & 0xE3) == 0xA2) return on_block_download_ack(d);
      break;
    case State::BlockDownloadEnd:
      if ((cmd & 0xE3) == 0xA1) return finish(SdoAbortCode::None);
      break;
    case State::BlockUploadInitiate:
      if ((cmd & 0xE1) == 0xC0) return on_block_upload_initiate(d);
      if (scs == 2) return on_upload_initiate(d);  // the server switched protocol (pst)
      break;
    case State::BlockUploadSubBlock: return on_block_upload_segment(d);
    case State::BlockUploadEnd:
      if ((cmd & 0xE1) == 0xC1) return on_block_upload_end(d);
      break;
    case State::Idle: return;
  }
  abort(SdoAbortCode::UnknownCommandSpecifier);
}

void SdoClient::on_upload_initiate(const std::uint8_t* d) {
  if (!mux_matches(d)) return abort(SdoAbortCode::GeneralError);
  const std::uint8_t cmd = d[0];
  size_indicated_ = (cmd & 0x01) != 0;
  if ((cmd & 0x02) != 0) {  // expedited
    const std::size_t n = size_indicated_ ? 4u - ((cmd >> 2) & 0x03u) : 4u;
    buffer_.assign(d + 4, d + 4 + n);
    return finish(SdoAbortCode::None);
  }
  size_ = get_u32(d + 4);
  if (size_indicated_ && size_ > cfg_.max_upload_size) return abort(SdoAbortCode::OutOfMemory);
  if (size_indicated_) buffer_.reserve(size_);  // one allocation, not one per doubling
  toggle_ = false;
  state_ = State::UploadSegment;
  send({0x60, 0, 0, 0, 0, 0, 0, 0});
}

void SdoClient::on_upload_segment(const std::uint8_t* d) {
  const std::uint8_t cmd = d[0];
  if (((cmd & 0x10) != 0) != toggle_) return abort(SdoAbortCode::ToggleBitNotAlternated);
  const std::size_t n = kSegmentData - ((cmd >> 1) & 0x07u);
  const std::size_t cap = size_indicated_ ? size_ : cfg_.max_upload_size;
  if (buffer_.size() + n > cap) {
    return abort(size_indicated_ ? SdoAbortCode::LengthMismatch : SdoAbortCode::OutOfMemory);
  }
  buffer_.insert(buffer_.end(), d + 1, d + 1 + n);
  if ((cmd & 0x01) != 0) {
    if (size_indicated_ && buffer_.size() != size_) return abort(SdoAbortCode::LengthMismatch);
    return finish(SdoAbortCode::None);
  }
  toggle_ = !toggle_;
  send({static_cast<std::uint8_t>(0x60 | (toggle_ ? 0x10 : 0x00)), 0, 0, 0, 0, 0, 0, 0});
}

void SdoClient::on_download_initiate(const std::uint8_t* d) {
  if (!mux_matches(d)) return abort(SdoAbortCode::GeneralError);
  if (pos_ == size_ && size_ != 0) return finish(SdoAbortCode::None);  // expedited: done
  state_ = State::DownloadSegment;
  toggle_ = false;
  send_download_segment();
}

void SdoClient::send_download_segment() {
  const std::size_t n = std::min(kSegmentData, size_ - pos_);
  last_in_block_ = pos_ + n == size_;
  std::array<std::uint8_t, 8> out{};
  out[0] = static_cast<std::uint8_t>((toggle_ ? 0x10 : 0x00) | ((kSegmentData - n) << 1) | (last_in_block_ ? 1 : 0));
  std::copy_n(current_.data.begin() + static_cast<std::ptrdiff_t>(pos_), n, out.begin() + 1);
  pos_ += n;
  send(out);
}

void SdoClient::on_download_segment(const std::uint8_t* d) {
  if (((d[0] & 0x10) != 0) != toggle_) return abort(SdoAbortCode::ToggleBitNotAlternated);
  if (last_in_block_) return finish(SdoAbortCode::None);
  toggle_ = !toggle_;
  send_download_segment();
}

void SdoClient::on_block_download_initiate(const std::uint8_t* d) {
  if (!mux_matches(d)) return abort(SdoAbortCode::GeneralError);
  crc_ = cfg_.crc && (d[0] & 0x04) != 0;
  if (d[4] == 0 || d[4] > 127) return abort(SdoAbortCode::InvalidBlockSize);
  tx_block_.start(d[4]);
  send_download_sub_block();
}

void SdoClient::send_download_sub_block() {
  state_ = State::BlockDownloadAck;
  tx_block_.send_sub_block(current_.data, [this](const std::array<std::uint8_t, 8>& out) { send(out); });
}

void SdoClient::on_block_download_ack(const std::uint8_t* d) {
  using Ack = sdo_block::SubBlockSender::Ack;
  switch (tx_block_.acknowledge(d, size_, 127)) {
    case Ack::BadSequence: return abort(SdoAbortCode::InvalidSequenceNumber);
    case Ack::BadBlockSize: return abort(SdoAbortCode::InvalidBlockSize);
    case Ack::Done:
      state_ = State::BlockDownloadEnd;
      return send(sdo_block::SubBlockSender::end_frame(size_, crc_ ? crc16_ccitt(current_.data) : 0));
    case Ack::Continue: return send_download_sub_block();
  }
}

void SdoClient::on_block_upload_initiate(const std::uint8_t* d) {
  if (!mux_matches(d)) return abort(SdoAbortCode::GeneralError);
  crc_ = cfg_.crc && (d[0] & 0x04) != 0;
  size_indicated_ = (d[0] & 0x02) != 0;
  size_ = get_u32(d + 4);
  if (size_indicated_ && size_ > cfg_.max_upload_size) return abort(SdoAbortCode::OutOfMemory);
  if (size_indicated_) buffer_.reserve(round_up_segments(size_));  // segments carry 7 bytes each
  rx_block_.start(cfg_.block_size);
  state_ = State::BlockUploadSubBlock;
  send({0xA3, 0, 0, 0, 0, 0, 0, 0});
}

void SdoClient::on_block_upload_segment(const std::uint8_t* d) {
  const auto r = rx_block_.segment(d, buffer_, size_indicated_ ? size_ : cfg_.max_upload_size);
  if (r.outcome == sdo_block::SubBlockReceiver::Outcome::BadSequence) return abort(SdoAbortCode::InvalidSequenceNumber);
  if (r.outcome == sdo_block::SubBlockReceiver::Outcome::Overflow)
    return abort(size_indicated_ ? SdoAbortCode::LengthMismatch : SdoAbortCode::OutOfMemory);
  if (!r.ack) return;
  if (rx_block_.finished()) state_ = State::BlockUploadEnd;
  send(*r.ack);
}

void SdoClient::on_block_upload_end(const std::uint8_t* d) {
  const std::size_t unused = (d[0] >> 2) & 0x07u;
  const std::size_t total = buffer_.size() - unused;  // at least one segment was received
  if (size_indicated_ && total != size_) return abort(SdoAbortCode::LengthMismatch);
  buffer_.resize(total);
  if (crc_ && crc16_ccitt(buffer_) != get_u16(d + 1)) return abort(SdoAbortCode::CrcError);
  send({0xA1, 0, 0, 0, 0, 0, 0, 0});
  finish(SdoAbortCode::None);
}

void SdoClient::finish(SdoAbortCode code) {
  std::vector<std::uint8_t> data;
  if (code == SdoAbortCode::None && current_.upload) data = std::move(buffer_);
  done_.push_back(Done{std::move(current_.callback), code, std::move(data)});
  state_ = State::Idle;
  buffer_.clear();
  current_ = Request{};
}

void SdoClient::abort(SdoAbortCode code) {
  std::array<std::uint8_t, 8> out{kAbort, static_cast<std::uint8_t>(current_.index),
                                  static_cast<std::uint8_t>(current_.index >> 8), current_.sub};
  put_u32(out.data() + 4, static_cast<std::uint32_t>(code));
  send(out);
  finish(code);
}

void SdoClient::send(const std::array<std::uint8_t, 8>& bytes) {
  if (!cfg_.request_cob.valid()) return;
  CanFrame f;
  f.id = cfg_.request_cob.can_id();
  f.extended = cfg_.request_cob.extended();
  f.dlc = 8;
  f.data = bytes;
  outbox_.push_back(f);
}

void SdoClient::send(std::initializer_list<std::uint8_t> bytes) {
  std::array<std::uint8_t, 8> out{};
  std::copy(bytes.begin(), bytes.end(), out.begin());
  send(out);
}

// Sends queued frames, runs finished callbacks, starts the next request. Re-entrant calls (a
// server wired straight to the sink answering at once, a callback queueing a request) only add
// work; the outermost call does it, in order.
void SdoClient::pump() {
  if (pumping_) return;
  pumping_ = true;
  for (;;) {
    if (outbox_head_ < outbox_.size()) {
      const CanFrame f = outbox_[outbox_head_++];
      if (outbox_head_ == outbox_.size()) {
        outbox_.clear();  // keeps the capacity: no allocation per frame
        outbox_head_ = 0;
      }
      if (sink_) sink_(f);
    } else if (done_head_ < done_.size()) {
      Done d = std::move(done_[done_head_++]);
      if (done_head_ == done_.size()) {
        done_.clear();
        done_head_ = 0;
      }
      if (d.callback) d.callback(d.code, std::move(d.data));
    } else if (state_ == State::Idle && queued() != 0 && paced_start()) {
      start(now_);
    } else {
      break;
    }
  }
  // Nothing left to start (every cancel pumps): a later request has not waited.
  if (queued() == 0) waited_for_pacer_ = false;
  pumping_ = false;
}

bool SdoClient::paced_start() {
  if (pacer_ == nullptr) return true;
  const bool ok = pacer_->try_start(now_, waited_for_pacer_);
  waited_for_pacer_ = !ok;
  return ok;
}

void SdoClient::export_state(StateWriter& w) const {
  if (!idle() || outbox_head_ != outbox_.size() || done_head_ != done_.size()) {
    throw std::logic_error("SdoClient::export_state while a transfer is under way");
  }
  w.put("now", now_);
  w.put("last_ticket", last_ticket_);
  w.put("stale_answers", stale_answers_);
  w.put("waited_for_pacer", waited_for_pacer_);
}

void SdoClient::import_state(const StateReader& r) {
  if (!idle()) throw std::logic_error("SdoClient::import_state while a transfer is under way");
  const TimePoint now = r.time("now");
  const auto last_ticket = r.get<Ticket>("last_ticket");
  const auto stale_answers = r.get<std::uint64_t>("stale_answers");
  waited_for_pacer_ = r.get<bool>("waited_for_pacer");
  now_ = now;
  last_ticket_ = last_ticket;
  stale_answers_ = stale_answers;
}

}  // namespace oegw::canopen
