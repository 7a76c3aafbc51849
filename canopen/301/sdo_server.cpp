#include "canopen/301/sdo_server.hpp"

#include "canopen/301/sdo_block.hpp"

#include <algorithm>
#include <array>
#include <stdexcept>

#include "canopen/301/crc16.hpp"
#include "canopen/state.hpp"

namespace oegw::canopen {

namespace {

using sdo_block::kSegmentData;
using sdo_block::round_up_segments;

bool matches(CobId cob, const CanFrame& f) {
  return cob.valid() && f.id == cob.can_id() && f.extended == cob.extended();
}

// Client command specifiers (CiA 301 §7.2.4.3, ccs = bits 7..5 of byte 0).
constexpr std::uint8_t kCcsDownloadSegment = 0;
constexpr std::uint8_t kCcsInitiateDownload = 1;
constexpr std::uint8_t kCcsInitiateUpload = 2;
constexpr std::uint8_t kCcsUploadSegment = 3;
constexpr std::uint8_t kCcsBlockUpload = 5;
constexpr std::uint8_t kCcsBlockDownload = 6;
constexpr std::uint8_t kCcsNetworkIndication = 7;  // see sdo_remote.hpp for the frame layout
constexpr std::uint8_t kAbort = 0x80;

bool is_initiate(std::uint8_t cmd) {
  const auto ccs = static_cast<std::uint8_t>(cmd >> 5);
  return ccs == kCcsInitiateDownload || ccs == kCcsInitiateUpload || (ccs == kCcsBlockUpload && (cmd & 0x03) == 0) ||
         (ccs == kCcsBlockDownload && (cmd & 0x01) == 0);
}

}  // namespace

SdoServer::SdoServer(ObjectDictionary& od, FrameSink sink, CobId rx, CobId tx, Duration timeout)
    : od_(od), sink_(std::move(sink)), rx_(rx), tx_(tx), timeout_(timeout) {}

SdoServer::SdoServer(ObjectDictionary& od, FrameSink sink, NodeId node, Duration timeout)
    : SdoServer(od, std::move(sink), CobId(cob::kSdoRx + node.value()), CobId(cob::kSdoTx + node.value()), timeout) {}

SdoServer::~SdoServer() { cancel_remote(SdoAbortCode::GeneralError); }

void SdoServer::set_cob_ids(CobId rx, CobId tx) {
  const bool changed = rx != rx_ || tx != tx_;
  rx_ = rx;
  tx_ = tx;
  cancel_remote(SdoAbortCode::GeneralError);
  drop();
  set_redirect(std::nullopt, changed ? RedirectChange::CobIds : RedirectChange::Reset);
}

void SdoServer::reset() {
  cancel_remote(SdoAbortCode::GeneralError);
  drop();
  set_redirect(std::nullopt, RedirectChange::Reset);
}

void SdoServer::abort_in_progress(SdoAbortCode code) {
  if (state_ == State::Idle) return;
  cancel_remote(code);
  abort_transfer(code);
  flush();
}

void SdoServer::set_remote(SdoRemote* remote) {
  cancel_remote(SdoAbortCode::GeneralError);
  drop();
  set_redirect(std::nullopt, RedirectChange::Reconfigured);
  remote_ = remote;
}

void SdoServer::bind(std::optional<SdoTarget> target) {
  cancel_remote(SdoAbortCode::GeneralError);
  drop();
  set_redirect(std::nullopt, RedirectChange::Reconfigured);
  bound_ = target;
}

std::optional<SdoTarget> SdoServer::target() const {
  if (bound_) return bound_;
  if (selected_) return selected_->target;
  return std::nullopt;
}

void SdoServer::set_redirect(std::optional<Redirect> next, RedirectChange why) {
  if (!selected_ && !next) return;
  std::optional<Redirect> before = std::move(selected_);
  selected_ = std::move(next);
  if (on_redirect) on_redirect(before, selected_, why);
}

void SdoServer::set_block_size(std::uint8_t blksize) {
  block_size_ = std::clamp<std::uint8_t>(blksize, 1, kMaxBlockSize);
}

std::optional<TimePoint> SdoServer::next_deadline() const {
  if (state_ == State::Idle || state_ == State::RemoteWait) return std::nullopt;
  if (arm_deadline_) return now_;  // the remote answered: due now, advance() starts the time-out
  return deadline_;
}

void SdoServer::advance(TimePoint now) {
  now_ = now;
  if (arm_deadline_) {
    arm_deadline_ = false;
    deadline_ = now + timeout_;
  }
  if (state_ != State::Idle && state_ != State::RemoteWait && now >= deadline_) abort_transfer(SdoAbortCode::Timeout);
  flush();
}

bool SdoServer::on_frame(const CanFrame& frame, TimePoint now) {
  if (!matches(rx_, frame)) return false;
  now_ = now;
  const bool nested = handling_;
  handling_ = true;
  if (!frame.rtr) handle(frame);  // SDO never uses remote frames: ignore them
  handling_ = nested;
  if (state_ != State::Idle && state_ != State::RemoteWait) {
    deadline_ = now + timeout_;
    arm_deadline_ = false;
  }
  flush();
  return true;
}

void SdoServer::handle(const CanFrame& f) {
  const std::uint8_t* d = f.data.data();
  if (state_ == State::RemoteWait) return frame_while_waiting(f);
  // An abort (ccs = 4, the other bits reserved) is never answered (CiA 301 §7.2.4.3.17). In a
  // block download sub-block 0x81..0x9F are last segments; 0x80 would be "last segment,
  // sequence number 0", which is not a valid segment, so there it is the abort.
  const bool sub_block = state_ == State::BlockDownloadSubBlock;
  if (f.dlc >= 1 && (sub_block ? d[0] == kAbort : (d[0] >> 5) == 4)) {
    drop();
    return;
  }
  if (f.dlc < 8) {
    if (state_ != State::Idle) {
      abort_transfer(SdoAbortCode::UnknownCommandSpecifier);
    } else {
      abort(f.dlc >= 3 ? get_u16(d + 1) : 0, f.dlc >= 4 ? d[3] : 0, SdoAbortCode::UnknownCommandSpecifier);
    }
    return;
  }
  if (state_ == State::BlockDownloadSubBlock) {
    block_download_segment(d);
    return;
  }
  const std::uint8_t cmd = d[0];
  if ((cmd >> 5) == kCcsNetworkIndication && remote_ != nullptr) {
    drop();  // like an initiate, it abandons whatever was in progress
    network_indication(d);
    return;
  }
  if (is_initiate(cmd)) {
    drop();  // a new initiate abandons whatever was in progress (see header)
    if (target()) {
      if (remote_ == nullptr) return abort(get_u16(d + 1), d[3], SdoAbortCode::ResourceNotAvailable);
      routed_ = true;
    }
    switch (cmd >> 5) {
      case kCcsInitiateDownload: initiate_download(d); break;
      case kCcsInitiateUpload: initiate_upload(d); break;
      case kCcsBlockUpload: initiate_block_upload(d); break;
      default: initiate_block_download(d); break;
    }
    return;
  }
  const auto ccs = static_cast<std::uint8_t>(cmd >> 5);
  switch (state_) {
    case State::DownloadSegmented:
      if (ccs == kCcsDownloadSegment) return download_segment(d);
      break;
    case State::UploadSegmented:
      if (ccs == kCcsUploadSegment) return upload_segment(d);
      break;
    case State::BlockDownloadEnd:
      if ((cmd & 0xE1) == 0xC1) return block_download_end(d);
      break;
    case State::BlockUploadStart:
      if ((cmd & 0xE3) == 0xA3) return send_upload_sub_block();
      break;
    case State::BlockUploadAck:
      if ((cmd & 0xE3) == 0xA2) return block_upload_ack(d);
      break;
    case State::BlockUploadEnd:
      if ((cmd & 0xE3) == 0xA1) return drop();  // transfer complete
      break;
    case State::Idle: abort(get_u16(d + 1), d[3], SdoAbortCode::UnknownCommandSpecifier); return;
    case State::BlockDownloadSubBlock:
    case State::RemoteWait:  // handled above
      break;
  }
  abort_transfer(SdoAbortCode::UnknownCommandSpecifier);
}

SdoAbortCode SdoServer::check_announced_size(std::uint32_t size) const {
  if (routed_) return size > kMaxRemoteDownload ? SdoAbortCode::OutOfMemory : SdoAbortCode::None;
  const SubObject* s = od_.find(index_, sub_);
  const std::size_t n = fixed_size(s->type);
  if (n != 0) {
    if (size > n) return SdoAbortCode::LengthTooHigh;
    if (size < n) return SdoAbortCode::LengthTooLow;
  } else if (size > s->max_size) {
    return SdoAbortCode::LengthTooHigh;
  }
  return SdoAbortCode::None;
}

SdoAbortCode SdoServer::overflow_code() const {
  // More data than announced: length mismatch. No size announced: a fixed-size object is "too
  // long" (what the object dictionary would say), a string/DOMAIN has outgrown the buffer cap.
  if (size_indicated_) return SdoAbortCode::LengthMismatch;
  if (routed_) return SdoAbortCode::OutOfMemory;
  const SubObject* s = od_.find(index_, sub_);
  if (s != nullptr && fixed_size(s->type) != 0) return SdoAbortCode::LengthTooHigh;
  return SdoAbortCode::OutOfMemory;
}

void SdoServer::initiate_download(const std::uint8_t* d) {
  const std::uint8_t cmd = d[0];
  index_ = get_u16(d + 1);
  sub_ = d[3];
  if (routed_) return initiate_remote_download(d);
  if (const SdoAbortCode c = od_.check_write(index_, sub_); c != SdoAbortCode::None) return abort_transfer(c);
  const SubObject* s = od_.find(index_, sub_);
  const std::size_t fixed = fixed_size(s->type);
  const bool expedited = (cmd & 0x02) != 0;
  size_indicated_ = (cmd & 0x01) != 0;
  if (expedited) {
    // e=1, s=0: "unspecified number of bytes" — take the object's size (the MCB-402 writes its
    // UNSIGNED16 event timer with 0x22 and four data bytes), or all four for variable types.
    std::size_t n = 4;
    if (size_indicated_) {
      n = 4u - ((cmd >> 2) & 0x03u);
    } else if (fixed != 0 && fixed < 4) {
      n = fixed;
    }
    const SdoAbortCode c = od_.write(index_, sub_, std::span<const std::uint8_t>(d + 4, n));
    if (c != SdoAbortCode::None) return abort_transfer(c);
    send({0x60, d[1], d[2], d[3], 0, 0, 0, 0});
    return;
  }
  begin_segmented_download(d, fixed != 0 ? fixed : s->max_size);
}

void SdoServer::begin_segmented_download(const std::uint8_t* d, std::size_t unsized_capacity) {
  if (size_indicated_) {
    size_ = get_u32(d + 4);
    if (const SdoAbortCode c = check_announced_size(static_cast<std::uint32_t>(size_)); c != SdoAbortCode::None)
      return abort_transfer(c);
    capacity_ = size_;
  } else {
    capacity_ = unsized_capacity;
  }
  buffer_.clear();
  toggle_ = false;
  state_ = State::DownloadSegmented;
  send({0x60, d[1], d[2], d[3], 0, 0, 0, 0});
}

void SdoServer::download_segment(const std::uint8_t* d) {
  const std::uint8_t cmd = d[0];
  if (((cmd & 0x10) != 0) != toggle_) return abort_transfer(SdoAbortCode::ToggleBitNotAlternated);
  const std::size_t n = kSegmentData - ((cmd >> 1) & 0x07u);
  if (buffer_.size() + n > capacity_) return abort_transfer(overflow_code());
  buffer_.insert(buffer_.end(), d + 1, d + 1 + n);
  const auto response = static_cast<std::uint8_t>(0x20 | (toggle_ ? 0x10 : 0x00));
  toggle_ = !toggle_;
  if ((cmd & 0x01) != 0) {
    if (size_indicated_ && buffer_.size() != size_) return abort_transfer(SdoAbortCode::LengthMismatch);
    if (routed_) return start_remote_download(RemoteStep::LastSegment, response);
    const SdoAbortCode c = od_.write(index_, sub_, buffer_);
    if (c != SdoAbortCode::None) return abort_transfer(c);
    drop();
  }
  send({response, 0, 0, 0, 0, 0, 0, 0});
}

void SdoServer::initiate_upload(const std::uint8_t* d) {
  index_ = get_u16(d + 1);
  sub_ = d[3];
  if (routed_) return start_remote_upload(RemoteStep::Upload);
  buffer_.clear();
  if (const SdoAbortCode c = od_.read(index_, sub_, buffer_); c != SdoAbortCode::None) return abort_transfer(c);
  respond_upload_initiate();
}

void SdoServer::respond_upload_initiate() {
  const auto lo = static_cast<std::uint8_t>(index_);
  const auto hi = static_cast<std::uint8_t>(index_ >> 8);
  if (!buffer_.empty() && buffer_.size() <= 4) {
    std::array<std::uint8_t, 8> out{};
    out[0] = static_cast<std::uint8_t>(0x43 | ((4 - buffer_.size()) << 2));
    out[1] = lo;
    out[2] = hi;
    out[3] = sub_;
    std::copy(buffer_.begin(), buffer_.end(), out.begin() + 4);
    drop();
    send(out);
    return;
  }
  size_ = buffer_.size();
  pos_ = 0;
  toggle_ = false;
  state_ = State::UploadSegmented;
  std::array<std::uint8_t, 8> out{0x41, lo, hi, sub_, 0, 0, 0, 0};
  put_u32(out.data() + 4, static_cast<std::uint32_t>(size_));
  send(out);
}

void SdoServer::upload_segment(const std::uint8_t* d) {
  if (((d[0] & 0x10) != 0) != toggle_) return abort_transfer(SdoAbortCode::ToggleBitNotAlternated);
  const std::size_t n = std::min(kSegmentData, size_ - pos_);
  const bool last = pos_ + n == size_;
  std::array<std::uint8_t, 8> out{};
  out[0] = static_cast<std::uint8_t>((toggle_ ? 0x10 : 0x00) | ((kSegmentData - n) << 1) | (last ? 0x01 : 0x00));
  std::copy_n(buffer_.begin() + static_cast<std::ptrdiff_t>(pos_), n, out.begin() + 1);
  pos_ += n;
  toggle_ = !toggle_;
  if (last) drop();
  send(out);
}

void SdoServer::initiate_block_download(const std::uint8_t* d) {
  const std::uint8_t cmd = d[0];
  index_ = get_u16(d + 1);
  sub_ = d[3];
  const SubObject* s = nullptr;
  if (!routed_) {
    if (const SdoAbortCode c = od_.check_write(index_, sub_); c != SdoAbortCode::None) return abort_transfer(c);
    s = od_.find(index_, sub_);
  }
  size_indicated_ = (cmd & 0x02) != 0;
  if (size_indicated_) {
    size_ = get_u32(d + 4);
    if (const SdoAbortCode c = check_announced_size(static_cast<std::uint32_t>(size_)); c != SdoAbortCode::None)
      return abort_transfer(c);
    capacity_ = size_;
  } else if (routed_) {
    capacity_ = kMaxRemoteDownload;
  } else {
    const std::size_t fixed = fixed_size(s->type);
    capacity_ = fixed != 0 ? fixed : s->max_size;
  }
  crc_ = (cmd & 0x04) != 0;
  buffer_.clear();
  rx_block_.start(block_size_);
  state_ = State::BlockDownloadSubBlock;
  send({0xA4, d[1], d[2], d[3], rx_block_.blksize(), 0, 0, 0});  // sc = 1: the server can check a CRC
}

void SdoServer::block_download_segment(const std::uint8_t* d) {
  const auto r = rx_block_.segment(d, buffer_, capacity_);
  if (r.outcome == sdo_block::SubBlockReceiver::Outcome::BadSequence)
    return abort_transfer(SdoAbortCode::InvalidSequenceNumber);
  if (r.outcome == sdo_block::SubBlockReceiver::Outcome::Overflow) return abort_transfer(overflow_code());
  if (!r.ack) return;
  if (rx_block_.finished()) state_ = State::BlockDownloadEnd;
  send(*r.ack);
}

void SdoServer::block_download_end(const std::uint8_t* d) {
  const std::size_t unused = (d[0] >> 2) & 0x07u;
  const std::size_t total = buffer_.size() - unused;  // buffer_ holds at least one segment here
  if (size_indicated_ && total != size_) return abort_transfer(SdoAbortCode::LengthMismatch);
  buffer_.resize(total);
  if (crc_ && crc16_ccitt(buffer_) != get_u16(d + 1)) return abort_transfer(SdoAbortCode::CrcError);
  if (routed_) return start_remote_download(RemoteStep::BlockDownloadEnd, 0xA1);
  const SdoAbortCode c = od_.write(index_, sub_, buffer_);
  if (c != SdoAbortCode::None) return abort_transfer(c);
  drop();
  send({0xA1, 0, 0, 0, 0, 0, 0, 0});
}

void SdoServer::initiate_block_upload(const std::uint8_t* d) {
  index_ = get_u16(d + 1);
  sub_ = d[3];
  const std::uint8_t blksize = d[4];
  const std::uint8_t pst = d[5];
  const bool crc = (d[0] & 0x04) != 0;
  if (routed_) {
    // Checked before the remote is asked: a remote transfer is not started for nothing.
    if (blksize == 0 || blksize > kMaxBlockSize) return abort_transfer(SdoAbortCode::InvalidBlockSize);
    block_upload_ = {blksize, pst, crc};
    return start_remote_upload(RemoteStep::BlockUpload);
  }
  buffer_.clear();
  if (const SdoAbortCode c = od_.read(index_, sub_, buffer_); c != SdoAbortCode::None) return abort_transfer(c);
  if (blksize == 0 || blksize > kMaxBlockSize) return abort_transfer(SdoAbortCode::InvalidBlockSize);
  respond_block_upload_initiate({blksize, pst, crc});
}

void SdoServer::respond_block_upload_initiate(BlockUploadRequest request) {
  if (request.pst != 0 && buffer_.size() <= request.pst) {
    respond_upload_initiate();  // protocol switch: answer as a normal upload
    return;
  }
  crc_ = request.crc;
  tx_block_.start(request.blksize);
  size_ = buffer_.size();
  state_ = State::BlockUploadStart;
  std::array<std::uint8_t, 8>
      out{0xC6, static_cast<std::uint8_t>(index_), static_cast<std::uint8_t>(index_ >> 8), sub_, 0, 0, 0,
          0};  // sc = 1, s = 1
  put_u32(out.data() + 4, static_cast<std::uint32_t>(size_));
  send(out);
}

void SdoServer::send_upload_sub_block() {
  state_ = State::BlockUploadAck;
  tx_block_.send_sub_block(buffer_, [this](const std::array<std::uint8_t, 8>& out) { send(out); });
}

void SdoServer::block_upload_ack(const std::uint8_t* d) {
  using Ack = sdo_block::SubBlockSender::Ack;
  switch (tx_block_.acknowledge(d, size_, kMaxBlockSize)) {
    case Ack::BadSequence: return abort_transfer(SdoAbortCode::InvalidSequenceNumber);
    case Ack::BadBlockSize: return abort_transfer(SdoAbortCode::InvalidBlockSize);
    case Ack::Done:
      state_ = State::BlockUploadEnd;
      return send(sdo_block::SubBlockSender::end_frame(size_, crc_ ? crc16_ccitt(buffer_) : 0));
    case Ack::Continue: return send_upload_sub_block();
  }
}

void SdoServer::abort(std::uint16_t index, std::uint8_t sub, SdoAbortCode code) {
  drop();
  std::array<std::uint8_t, 8>
      out{kAbort, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0};
  put_u32(out.data() + 4, static_cast<std::uint32_t>(code));
  send(out);
}

// ---------------------------------------------------------------------------------------------
// Remote (routed) mode

void SdoServer::network_indication(const std::uint8_t* d) {
  if (bound_) return abort(get_u16(d + 1), d[3], SdoAbortCode::CannotTransferLocalControl);
  const SdoTarget target{d[4], d[5]};
  SdoRemote::Selection selection = SdoRemote::Selection::Local;
  if (const SdoAbortCode c = remote_->select(target, selection); c != SdoAbortCode::None)
    return abort(get_u16(d + 1), d[3], c);
  if (selection == SdoRemote::Selection::Remote) {
    set_redirect(Redirect{target, now_, {d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7]}}, RedirectChange::Indication);
  } else {
    set_redirect(std::nullopt, RedirectChange::Indication);
  }
  send({0xE0, d[1], d[2], d[3], d[4], d[5], d[6], d[7]});
}

void SdoServer::initiate_remote_download(const std::uint8_t* d) {
  const std::uint8_t cmd = d[0];
  size_indicated_ = (cmd & 0x01) != 0;
  if ((cmd & 0x02) != 0) {
    // Expedited. With s = 0 the object's size is unknown here: the four bytes go on as an
    // expedited download without size (SdoRemote::download), the remote server decides.
    const std::size_t n = size_indicated_ ? 4u - ((cmd >> 2) & 0x03u) : 4u;
    buffer_.assign(d + 4, d + 4 + n);
    return start_remote_download(RemoteStep::ExpeditedDownload, 0x60);
  }
  begin_segmented_download(d, kMaxRemoteDownload);
}

void SdoServer::start_remote_upload(RemoteStep step) {
  const SdoTarget target = *this->target();
  state_ = State::RemoteWait;
  step_ = step;
  const std::uint32_t generation = ++remote_generation_;
  const SdoRemote::Ticket ticket = remote_->upload(target, index_, sub_, now_, remote_done(generation));
  if (state_ == State::RemoteWait && remote_generation_ == generation) ticket_ = ticket;
}

void SdoServer::start_remote_download(RemoteStep step, std::uint8_t response) {
  const SdoTarget target = *this->target();
  state_ = State::RemoteWait;
  step_ = step;
  remote_response_ = response;
  const std::uint32_t generation = ++remote_generation_;
  const bool unsized = step == RemoteStep::ExpeditedDownload && !size_indicated_;
  const SdoRemote::Ticket ticket =
      remote_->download(target, index_, sub_, buffer_, !unsized, now_, remote_done(generation));
  if (state_ == State::RemoteWait && remote_generation_ == generation) ticket_ = ticket;
}

SdoRemote::Done SdoServer::remote_done(std::uint32_t generation) {
  return [this, generation](SdoAbortCode code, std::vector<std::uint8_t> data) {
    on_remote_done(generation, code, std::move(data));
  };
}

void SdoServer::on_remote_done(std::uint32_t generation, SdoAbortCode code, std::vector<std::uint8_t> data) {
  if (state_ != State::RemoteWait || generation != remote_generation_) return;  // cancelled or replaced
  ++remote_generation_;
  state_ = State::Idle;
  if (code != SdoAbortCode::None) {
    abort_transfer(code);
  } else {
    switch (step_) {
      case RemoteStep::Upload:
        buffer_ = std::move(data);
        respond_upload_initiate();
        break;
      case RemoteStep::BlockUpload:
        buffer_ = std::move(data);
        respond_block_upload_initiate(block_upload_);
        break;
      case RemoteStep::ExpeditedDownload:
        drop();
        send({remote_response_, static_cast<std::uint8_t>(index_), static_cast<std::uint8_t>(index_ >> 8), sub_, 0, 0,
              0, 0});
        break;
      case RemoteStep::LastSegment:
      case RemoteStep::BlockDownloadEnd:
        drop();
        send({remote_response_, 0, 0, 0, 0, 0, 0, 0});
        break;
    }
  }
  if (handling_) return;  // inside on_frame: it sets the deadline and flushes
  if (state_ != State::Idle) arm_deadline_ = true;
  flush();
}

void SdoServer::frame_while_waiting(const CanFrame& f) {
  const std::uint8_t* d = f.data.data();
  if (f.dlc >= 1 && (d[0] >> 5) == 4) {  // the client's abort: passed on, never answered
    const auto code = f.dlc == 8 ? static_cast<SdoAbortCode>(get_u32(d + 4)) : SdoAbortCode::GeneralError;
    cancel_remote(code == SdoAbortCode::None ? SdoAbortCode::GeneralError : code);
    drop();
    return;
  }
  // Anything else ends the wait: the remote transfer is cancelled with the code the client gets.
  std::uint16_t index = index_;
  std::uint8_t sub = sub_;
  SdoAbortCode code = SdoAbortCode::UnknownCommandSpecifier;  // a short frame, as in any state
  if (f.dlc >= 8) {
    code = SdoAbortCode::ResourceNotAvailable;
    if (is_initiate(d[0]) || (d[0] >> 5) == kCcsNetworkIndication) {  // a new request: its multiplexer
      index = get_u16(d + 1);
      sub = d[3];
    }
  }
  cancel_remote(code);
  abort(index, sub, code);
}

void SdoServer::cancel_remote(SdoAbortCode why) {
  if (state_ != State::RemoteWait) return;
  ++remote_generation_;
  state_ = State::Idle;
  remote_->cancel(ticket_, why);
}

void SdoServer::drop() {
  state_ = State::Idle;
  routed_ = false;
  arm_deadline_ = false;
  buffer_.clear();
  // Keep a small buffer for the next transfer (every upload copies the value into it); give
  // back what a large DOMAIN transfer grew.
  if (buffer_.capacity() > kKeptBufferCapacity) buffer_.shrink_to_fit();
  size_indicated_ = false;
  crc_ = false;
}

void SdoServer::send(std::initializer_list<std::uint8_t> bytes) {
  std::array<std::uint8_t, 8> out{};
  std::copy(bytes.begin(), bytes.end(), out.begin());
  send(out);
}

void SdoServer::send(const std::array<std::uint8_t, 8>& bytes) {
  if (!tx_.valid()) return;
  CanFrame f;
  f.id = tx_.can_id();
  f.extended = tx_.extended();
  f.dlc = 8;
  f.data = bytes;
  outbox_.push_back(f);
}

// Frames are queued and sent once the state is settled. If the sink feeds a reply straight back
// (a client wired directly to this server), the nested call only queues, and this loop sends.
void SdoServer::flush() {
  if (flushing_) return;
  flushing_ = true;
  // By index: the nested calls append while we send. clear() keeps the capacity, so sending
  // does not allocate (a std::deque drained to empty frees and reallocates its chunk).
  for (std::size_t i = 0; i < outbox_.size(); ++i) {
    const CanFrame f = outbox_[i];
    if (sink_) sink_(f);
  }
  outbox_.clear();
  flushing_ = false;
}

void SdoServer::export_state(StateWriter& w) const {
  if (busy() || arm_deadline_ || !outbox_.empty()) {
    throw std::logic_error("SdoServer::export_state while a transfer is under way");
  }
  w.put("rx", rx_.raw());
  w.put("tx", tx_.raw());
  if (selected_) {
    w.put("redirect.network", selected_->target.network);
    w.put("redirect.node", selected_->target.node);
    w.put("redirect.since", selected_->since);
    w.put_bytes("redirect.request", selected_->request);
  }
  w.put("remote_generation", remote_generation_);
}

void SdoServer::import_state(const StateReader& r) {
  if (busy()) throw std::logic_error("SdoServer::import_state while a transfer is under way");
  const CobId rx{r.get<std::uint32_t>("rx")};
  const CobId tx{r.get<std::uint32_t>("tx")};
  std::optional<Redirect> selected;
  if (r.has("redirect.node")) {
    const StateReader s = r.in("redirect");
    Redirect redirect;
    // CiA 302-7: network 1..127 and node 1..127; a network indication naming the server itself
    // ends a redirect rather than making one.
    redirect.target.network = s.get<std::uint8_t>("network");
    redirect.target.node = s.get<std::uint8_t>("node");
    if (redirect.target.network < 1 || redirect.target.network > 127) s.fail("network", "is no network ID (1..127)");
    if (redirect.target.node < 1 || redirect.target.node > 127) s.fail("node", "is no node-ID (1..127)");
    redirect.since = s.time("since");
    const std::vector<std::uint8_t> request = s.bytes("request");
    if (request.size() != redirect.request.size()) s.fail("request", "is not the eight bytes of an SDO request");
    std::copy(request.begin(), request.end(), redirect.request.begin());
    selected = redirect;
  }
  const auto generation = r.get<std::uint32_t>("remote_generation");
  rx_ = rx;
  tx_ = tx;
  selected_ = selected;
  remote_generation_ = generation;
}

}  // namespace oegw::canopen
