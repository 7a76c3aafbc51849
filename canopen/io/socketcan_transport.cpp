#include "canopen/io/socketcan_transport.hpp"

#include "canopen/io/interface_name.hpp"

#include <fcntl.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <net/if_arp.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <utility>

#include "canopen/io/clock.hpp"

namespace oegw::canopen::io {

namespace {

std::string errno_text(int e) { return std::strerror(e); }

// Closes on scope exit unless released.
class FdGuard {
 public:
  explicit FdGuard(int fd) : fd_(fd) {}
  FdGuard(const FdGuard&) = delete;
  FdGuard& operator=(const FdGuard&) = delete;
  ~FdGuard() {
    if (fd_ >= 0) ::close(fd_);
  }
  [[nodiscard]] int get() const { return fd_; }
  int release() { return std::exchange(fd_, -1); }

 private:
  int fd_;
};

void fill_ifreq(ifreq& ifr, const std::string& name) {
  std::memset(&ifr, 0, sizeof ifr);
  std::memcpy(ifr.ifr_name, name.data(), name.size());  // length checked by the caller
}

void validate_name(const std::string& name) {
  if (!interface_name_problem(name).empty()) {
    throw CanOpenError(CanOpenError::Reason::InvalidName, EINVAL, "invalid CAN interface name '" + name + "'");
  }
}

template <class T>
void set_option(int fd, int level, int option, const T* value, std::size_t size, const char* option_name,
                const std::string& interface) {
  if (::setsockopt(fd, level, option, value, static_cast<socklen_t>(size)) != 0) {
    const int e = errno;
    throw CanOpenError(CanOpenError::Reason::SystemError, e,
                       std::string("setsockopt(") + option_name + ") on CAN interface '" + interface +
                           "': " + errno_text(e));
  }
}

// SocketCanOptions::filters and join_filters on socket `fd`; nullopt: every frame (CAN_RAW's own
// default, one filter with mask 0).
void apply_filters(int fd, const std::optional<std::vector<CanFilter>>& filters, bool join,
                   const std::string& interface) {
  std::vector<::can_filter> k;
  if (filters) {
    k.reserve(filters->size());
    for (const CanFilter& f : *filters) k.push_back(socketcan::to_kernel(f));
  } else {
    k.push_back(::can_filter{0, 0});
  }
  const int on = join && filters ? 1 : 0;
  set_option(fd, SOL_CAN_RAW, CAN_RAW_JOIN_FILTERS, &on, sizeof on, "CAN_RAW_JOIN_FILTERS", interface);
  set_option(fd, SOL_CAN_RAW, CAN_RAW_FILTER, k.data(), k.size() * sizeof(::can_filter), "CAN_RAW_FILTER", interface);
}

// SocketCanOptions::rx_buffer_bytes: SO_RCVBUFFORCE (CAP_NET_ADMIN: past net.core.rmem_max),
// else SO_RCVBUF (capped at rmem_max). Both take half the kernel's figure: the kernel doubles
// the value for its sk_buff overhead (socket(7)). Never fatal: the default buffer still works,
// only with less slack. True if the socket got less than asked.
bool set_rx_buffer(int fd, std::size_t bytes) {
  if (bytes == 0) return false;
  const int half = static_cast<int>(std::min<std::size_t>(bytes / 2, std::size_t{1} << 30));
  if (::setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &half, sizeof half) == 0) return false;
  (void)::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &half, sizeof half);
  int got = 0;
  socklen_t len = sizeof got;
  return ::getsockopt(fd, SOL_SOCKET, SO_RCVBUF, &got, &len) != 0 || got < 2 * half;
}

// At most this many frames wait for end_batch(): one sendmmsg() each (a wake-up that sends more,
// e.g. a SYNC with many RPDOs behind it, sends every kMaxHeld).
constexpr std::size_t kMaxHeld = 64;

}  // namespace

// ---- interface probing --------------------------------------------------------------------

InterfaceInfo probe_interface(const std::string& name) {
  validate_name(name);
  // Any socket can ask about interfaces; AF_UNIX works even without CAN support in the kernel.
  FdGuard s(::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0));
  if (s.get() < 0) {
    const int e = errno;
    throw CanOpenError(CanOpenError::Reason::SystemError, e, "cannot query network interfaces: " + errno_text(e));
  }
  InterfaceInfo info;
  ifreq ifr;
  fill_ifreq(ifr, name);
  if (::ioctl(s.get(), SIOCGIFINDEX, &ifr) != 0) {
    const int e = errno;
    if (e == ENODEV) return info;
    throw CanOpenError(CanOpenError::Reason::SystemError, e,
                       "cannot query network interface '" + name + "': " + errno_text(e));
  }
  info.exists = true;
  info.index = ifr.ifr_ifindex;
  fill_ifreq(ifr, name);
  if (::ioctl(s.get(), SIOCGIFHWADDR, &ifr) == 0) info.is_can = ifr.ifr_hwaddr.sa_family == ARPHRD_CAN;
  fill_ifreq(ifr, name);
  if (::ioctl(s.get(), SIOCGIFFLAGS, &ifr) == 0) info.up = (ifr.ifr_flags & IFF_UP) != 0;
  return info;
}

int check_can_interface(const std::string& name) {
  const InterfaceInfo info = probe_interface(name);
  if (!info.exists) {
    throw CanOpenError(CanOpenError::Reason::NoSuchInterface, ENODEV, "no such CAN interface '" + name + "'");
  }
  if (!info.is_can) {
    throw CanOpenError(CanOpenError::Reason::NotCanInterface, ENODEV,
                       "interface '" + name + "' is not a CAN interface");
  }
  if (!info.up) {
    throw CanOpenError(CanOpenError::Reason::InterfaceDown, ENETDOWN, "interface '" + name + "' is down");
  }
  return info.index;
}

// ---- conversions --------------------------------------------------------------------------

namespace socketcan {

::can_frame to_kernel(const CanFrame& frame) {
  ::can_frame k;
  std::memset(&k, 0, sizeof k);
  k.can_id = frame.extended ? ((frame.id & CAN_EFF_MASK) | CAN_EFF_FLAG) : (frame.id & CAN_SFF_MASK);
  if (frame.rtr) k.can_id |= CAN_RTR_FLAG;
  k.len = std::min<std::uint8_t>(frame.dlc, CAN_MAX_DLEN);
  if (!frame.rtr) std::copy_n(frame.data.begin(), k.len, k.data);
  return k;
}

std::optional<CanFrame> from_kernel(const ::can_frame& k) {
  if (is_error_frame(k)) return std::nullopt;
  CanFrame f;
  f.extended = (k.can_id & CAN_EFF_FLAG) != 0;
  f.id = k.can_id & (f.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
  f.rtr = (k.can_id & CAN_RTR_FLAG) != 0;
  f.dlc = std::min<std::uint8_t>(k.len, CAN_MAX_DLEN);
  if (!f.rtr) std::copy_n(k.data, f.dlc, f.data.begin());
  return f;
}

std::vector<BusEvent> decode_error_frame(const ::can_frame& k) {
  std::vector<BusEvent> events;
  if (!is_error_frame(k)) return events;
  auto add = [&events](BusEvent e) {
    if (std::find(events.begin(), events.end(), e) == events.end()) events.push_back(e);
  };
  const canid_t cls = k.can_id & CAN_ERR_MASK;
  // The class bits carry details in data[] only with CAN_ERR_DLC bytes; a short error frame
  // still reports its classes.
  const std::uint8_t ctrl = k.len > 1 ? k.data[1] : 0;
  if (cls & CAN_ERR_TX_TIMEOUT) add(BusEvent::TxTimeout);
  if (cls & CAN_ERR_LOSTARB) add(BusEvent::LostArbitration);
  if (cls & CAN_ERR_CRTL) {
    if (ctrl & (CAN_ERR_CRTL_RX_OVERFLOW | CAN_ERR_CRTL_TX_OVERFLOW)) add(BusEvent::ControllerOverflow);
    if (ctrl & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) add(BusEvent::ErrorWarning);
    if (ctrl & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) add(BusEvent::ErrorPassive);
    if (ctrl & CAN_ERR_CRTL_ACTIVE) add(BusEvent::ErrorActive);
  }
  if (cls & CAN_ERR_PROT) add(BusEvent::ProtocolError);
  if (cls & CAN_ERR_TRX) add(BusEvent::TransceiverError);
  if (cls & CAN_ERR_ACK) add(BusEvent::NoAck);
  if (cls & CAN_ERR_BUSOFF) add(BusEvent::BusOff);
  if (cls & CAN_ERR_BUSERROR) add(BusEvent::BusError);
  if (cls & CAN_ERR_RESTARTED) add(BusEvent::Restarted);
  return events;
}

::can_filter to_kernel(const CanFilter& filter) {
  ::can_filter k{};
  const canid_t id_mask = filter.extended ? CAN_EFF_MASK : CAN_SFF_MASK;
  k.can_id = (filter.id & id_mask) | (filter.extended ? CAN_EFF_FLAG : 0U);
  // Always compare the frame format; the RTR bit (clear: a data frame) only for data_only.
  k.can_mask = (filter.mask & id_mask) | CAN_EFF_FLAG | (filter.data_only ? CAN_RTR_FLAG : 0U);
  if (filter.invert) k.can_id |= CAN_INV_FILTER;
  return k;
}

void StampMapper::sample(const timespec& realtime, TimePoint monotonic) {
  // The same seconds + nanoseconds -> microseconds as the monotonic clock's (clock.hpp).
  offset_us_ = time_point_from_monotonic(realtime.tv_sec, realtime.tv_nsec).time_since_epoch().count() -
               monotonic.time_since_epoch().count();
  sampled_at_ = monotonic;
  sampled_ = true;
}

std::optional<TimePoint> StampMapper::map(const timespec& stamp, TimePoint now) const {
  if (!sampled_) return std::nullopt;
  const TimePoint t = time_point_from_monotonic(stamp.tv_sec, stamp.tv_nsec) - Duration{offset_us_};
  if (t > now) return t - now <= kAhead ? std::optional<TimePoint>(now) : std::nullopt;
  if (now - t > kMaxAge) return std::nullopt;
  return t;
}

}  // namespace socketcan

std::optional<std::vector<CanFilter>> all_but_data_frames_on(const std::vector<CobId>& cob_ids) {
  if (cob_ids.empty()) return std::nullopt;
  std::vector<CanFilter> filters;
  filters.reserve(cob_ids.size());
  for (const CobId cob : cob_ids) {
    filters.push_back(CanFilter{.id = cob.can_id(),
                                .mask = 0x1FFFFFFFu,
                                .extended = cob.extended(),
                                .invert = true,
                                .data_only = true});
  }
  return filters;
}

// ---- the transport ------------------------------------------------------------------------

std::unique_ptr<SocketCanTransport> SocketCanTransport::open(const std::string& interface, SocketCanOptions options) {
  validate_name(interface);
  FdGuard s(::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW));
  if (s.get() < 0) {
    const int e = errno;
    if (e == EAFNOSUPPORT) {
      throw CanOpenError(CanOpenError::Reason::NoKernelSupport, e,
                         "kernel has no CAN support (socket(PF_CAN): " + errno_text(e) + ")");
    }
    if (e == EPROTONOSUPPORT) {
      throw CanOpenError(CanOpenError::Reason::NoKernelSupport, e,
                         "kernel has no CAN_RAW support (socket(PF_CAN, CAN_RAW): " + errno_text(e) + ")");
    }
    throw CanOpenError(CanOpenError::Reason::SystemError, e, "cannot create a CAN socket: " + errno_text(e));
  }
  const int index = check_can_interface(interface);

  if (options.filters) apply_filters(s.get(), options.filters, options.join_filters, interface);
  const can_err_mask_t err_mask = options.error_mask & CAN_ERR_MASK;
  set_option(s.get(), SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask, "CAN_RAW_ERR_FILTER", interface);
  const int loopback = options.loopback ? 1 : 0;
  set_option(s.get(), SOL_CAN_RAW, CAN_RAW_LOOPBACK, &loopback, sizeof loopback, "CAN_RAW_LOOPBACK", interface);
  const int own = options.receive_own ? 1 : 0;
  set_option(s.get(), SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &own, sizeof own, "CAN_RAW_RECV_OWN_MSGS", interface);
  const int on = 1;
  set_option(s.get(), SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on, "SO_TIMESTAMPNS", interface);
  set_option(s.get(), SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on, "SO_RXQ_OVFL", interface);
  const bool capped = set_rx_buffer(s.get(), options.rx_buffer_bytes);

  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = index;
  if (::bind(s.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    const int e = errno;
    if (e == ENODEV) {
      throw CanOpenError(CanOpenError::Reason::NoSuchInterface, e, "no such CAN interface '" + interface + "'");
    }
    if (e == ENETDOWN) {
      throw CanOpenError(CanOpenError::Reason::InterfaceDown, e, "interface '" + interface + "' is down");
    }
    throw CanOpenError(CanOpenError::Reason::SystemError, e,
                       "cannot bind to CAN interface '" + interface + "': " + errno_text(e));
  }
  std::unique_ptr<SocketCanTransport> t(
      new SocketCanTransport(s.release(), interface, index, std::max<std::size_t>(options.max_batch, 1)));
  t->rx_buffer_capped_ = capped;
  return t;
}

void SocketCanTransport::set_filters(const std::optional<std::vector<CanFilter>>& filters, bool join) {
  apply_filters(fd(), filters, join, interface_);
}

std::size_t SocketCanTransport::rx_buffer_bytes() const {
  int v = 0;
  socklen_t len = sizeof v;
  if (::getsockopt(fd(), SOL_SOCKET, SO_RCVBUF, &v, &len) != 0 || v < 0) return 0;
  return static_cast<std::size_t>(v);
}

std::unique_ptr<SocketCanTransport> SocketCanTransport::adopt(int fd, std::string interface, std::size_t max_batch) {
  if (fd < 0) throw std::invalid_argument("SocketCanTransport::adopt: invalid file descriptor");
  prepare_adopted(fd);
  return std::unique_ptr<SocketCanTransport>(
      new SocketCanTransport(fd, std::move(interface), 0, std::max<std::size_t>(max_batch, 1)));
}

SocketCanTransport::SocketCanTransport(int fd, std::string interface, int index, std::size_t max_batch)
    : CanFrameSocket(fd, max_batch), interface_(std::move(interface)), index_(index) {}

// ---- the I/O both sockets share -----------------------------------------------------------

CanFrameSocket::~CanFrameSocket() {
  if (fd_ >= 0) ::close(fd_);
}

CanFrameSocket::CanFrameSocket(int fd, std::size_t max_batch)
    : fd_(fd), max_batch_(std::max<std::size_t>(max_batch, 1)) {
  // One recvmmsg() takes up to 64 frames (a full classical frame is 16 bytes): with max_batch
  // above that, poll_readable() reads again only while the previous call filled every slot.
  const std::size_t n = std::min<std::size_t>(max_batch_, 64);
  slots_.resize(n);
  headers_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    Slot& s = slots_[i];
    s.iov = iovec{&s.frame, sizeof s.frame};
    msghdr& h = headers_[i].msg_hdr;
    h = msghdr{};
    h.msg_iov = &s.iov;
    h.msg_iovlen = 1;
    h.msg_control = s.control;
  }
}

void CanFrameSocket::prepare_adopted(int fd) {
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) ::fcntl(fd, F_SETFL, flags | O_NONBLOCK);
  const int on = 1;
  (void)::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on);
  (void)::setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on);
}

SendResult CanFrameSocket::send(const CanFrame& frame) {
  if (!is_valid_frame(frame)) {
    ++counters_.errors;
    return {SendStatus::InvalidFrame, 0};
  }
  const ::can_frame k = socketcan::to_kernel(frame);
  if (batching_) {
    held_.push_back(k);
    if (held_.size() >= kMaxHeld) send_held();
    return {};
  }
  const ssize_t n = ::send(fd_, &k, sizeof k, MSG_DONTWAIT | MSG_NOSIGNAL);
  if (n == static_cast<ssize_t>(sizeof k)) {
    ++counters_.tx_frames;
    return {};
  }
  const int e = n < 0 ? errno : EIO;
  if (e == ENOBUFS || e == EAGAIN) {
    ++counters_.tx_dropped;
    return {SendStatus::QueueFull, e};
  }
  ++counters_.errors;
  if (e == ENETDOWN) return {SendStatus::InterfaceDown, e};
  return {SendStatus::Error, e};
}

void CanFrameSocket::end_batch() {
  batching_ = false;
  send_held();
}

// The held frames in order, in one sendmmsg() (more only if the kernel takes part of them, or
// after kMaxHeld). A full TX queue drops the rest, as send() would have dropped each.
void CanFrameSocket::send_held() {
  if (held_.empty()) return;
  if (datagram_sender_ && queue_held_in_ring()) return;
  const std::size_t n = held_.size();
  held_iov_.resize(n);
  held_headers_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    held_iov_[i] = iovec{&held_[i], sizeof(::can_frame)};
    held_headers_[i] = ::mmsghdr{};
    held_headers_[i].msg_hdr.msg_iov = &held_iov_[i];
    held_headers_[i].msg_hdr.msg_iovlen = 1;
  }
  std::size_t sent = 0;
  while (sent < n) {
    const int r =
        ::sendmmsg(fd_, held_headers_.data() + sent, static_cast<unsigned>(n - sent), MSG_DONTWAIT | MSG_NOSIGNAL);
    if (r > 0) {
      sent += static_cast<std::size_t>(r);
      counters_.tx_frames += static_cast<std::uint64_t>(r);
      continue;
    }
    const int e = r < 0 ? errno : EIO;
    if (e == EINTR) continue;
    if (e == ENOBUFS || e == EAGAIN) {
      counters_.tx_dropped += n - sent;
    } else {
      counters_.errors += n - sent;
    }
    break;
  }
  held_.clear();
}

// The held frames to the loop's ring, in order: true if it took them all (a frame it had no
// room for is dropped as a full TX queue drops it). False, nothing taken, if it does not send for
// this socket (unwatched): send_held() sends them itself.
bool CanFrameSocket::queue_held_in_ring() {
  for (std::size_t i = 0; i < held_.size(); ++i) {
    switch (datagram_sender_(&held_[i], sizeof(::can_frame))) {
      case DatagramSend::Queued: ++counters_.tx_frames; break;
      case DatagramSend::Full: ++counters_.tx_dropped; break;
      case DatagramSend::NotQueued:
        if (i == 0) return false;
        // Not seen: a sender stops taking only when its watch goes, never within a batch.
        held_.erase(held_.begin(), held_.begin() + static_cast<std::ptrdiff_t>(i));
        return false;
    }
  }
  held_.clear();
  return true;
}

void CanFrameSocket::datagram_send_failed(int error) {
  // Counted as taken when queued: now it is not.
  if (counters_.tx_frames > 0) --counters_.tx_frames;
  if (error == ENOBUFS || error == EAGAIN) {
    ++counters_.tx_dropped;
  } else {
    ++counters_.errors;
  }
}

void CanFrameSocket::sample_clocks() {
  timespec real_now{};
  timespec mono_now{};
  ::clock_gettime(CLOCK_REALTIME, &real_now);
  ::clock_gettime(CLOCK_MONOTONIC, &mono_now);
  stamps_.sample(real_now, time_point_from_monotonic(mono_now.tv_sec, mono_now.tv_nsec));
}

int CanFrameSocket::read_batch() {
  for (auto& h : headers_) {
    h.msg_hdr.msg_controllen = sizeof(Slot::control);  // the kernel overwrites it with what it wrote
    h.msg_hdr.msg_flags = 0;
    h.msg_len = 0;
  }
  for (;;) {
    const int n = ::recvmmsg(fd_, headers_.data(), static_cast<unsigned>(headers_.size()), MSG_DONTWAIT, nullptr);
    if (n >= 0) return n;
    const int e = errno;
    if (e == EINTR) continue;
    if (e == EAGAIN || e == EWOULDBLOCK) return -1;
    receive_failed(e);
    return -1;
  }
}

void CanFrameSocket::end_of_stream() {
  ended_ = true;
  ++counters_.errors;
  deliver_event(BusEvent::InterfaceDown);
}

// Everything pending, in as few system calls as the kernel allows: one recvmmsg() per 64 frames
// (it returns what is queued, so a short batch needs no further call to see EAGAIN), no clock
// reading per frame (the loop's wake-up time and StampMapper's sampled offset).
void CanFrameSocket::poll_readable() {
  if (ended_) return;
  const TimePoint now = wake_up_time();
  bool resampled = false;
  std::size_t total = 0;
  while (total < max_batch_) {
    const int n = read_batch();
    if (n <= 0) return;
    total += static_cast<std::size_t>(n);
    for (int i = 0; i < n; ++i) {
      const auto& h = headers_[static_cast<std::size_t>(i)];
      if (!take(h.msg_hdr, h.msg_len, now, resampled)) return;
    }
    if (static_cast<std::size_t>(n) < headers_.size()) return;  // the queue is empty
  }
}

std::optional<DatagramSpec> CanFrameSocket::datagram_spec() const {
  return DatagramSpec{.payload_bytes = sizeof(::can_frame), .control_bytes = sizeof(Slot::control)};
}

void CanFrameSocket::take_datagram(const ReceivedDatagram& datagram) {
  if (ended_) return;
  if (datagram.msg == nullptr) {
    receive_failed(datagram.error);
    return;
  }
  bool resampled = false;
  (void)take(*datagram.msg, datagram.length, wake_up_time(), resampled);
}

TimePoint CanFrameSocket::wake_up_time() {
  const TimePoint now = clock_ != nullptr ? clock_->now() : SteadyClock().now();
  if (stamps_.needs_sample(now)) sample_clocks();
  return now;
}

void CanFrameSocket::receive_failed(int error) {
  ++counters_.errors;
  if (error == ENETDOWN) deliver_event(BusEvent::InterfaceDown);
}

// One datagram read: a frame to deliver with its stamp, an error frame's events, or the end of
// the stream (false: nothing after it is read).
bool CanFrameSocket::take(const msghdr& msg, std::size_t len, TimePoint now, bool& resampled) {
  if (len == 0) {  // the end of the stream: nothing after it is a frame
    end_of_stream();
    return false;
  }
  // CAN FD/XL are not enabled; a longer datagram arrives cut to a frame's size (MSG_TRUNC).
  if (len != sizeof(::can_frame) || (msg.msg_flags & MSG_TRUNC) != 0) {
    ++counters_.errors;
    return true;
  }
  ::can_frame frame;
  std::memcpy(&frame, msg.msg_iov[0].iov_base, sizeof frame);
  TimePoint stamp = now;
  msghdr m = msg;  // CMSG_NXTHDR takes it non-const
  for (cmsghdr* c = CMSG_FIRSTHDR(&m); c != nullptr; c = CMSG_NXTHDR(&m, c)) {
    if (c->cmsg_level != SOL_SOCKET) continue;
    if (c->cmsg_type == SCM_TIMESTAMPNS) {
      timespec ts;
      std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
      std::optional<TimePoint> t = stamps_.map(ts, now);
      if (!t && !resampled) {  // the realtime clock was stepped: sample once more
        sample_clocks();
        resampled = true;
        t = stamps_.map(ts, now);
      }
      stamp = t.value_or(now);
    } else if (c->cmsg_type == SO_RXQ_OVFL) {
      std::uint32_t dropped = 0;
      std::memcpy(&dropped, CMSG_DATA(c), sizeof dropped);
      counters_.rx_dropped = std::max<std::uint64_t>(counters_.rx_dropped, dropped);  // cumulative
    }
  }
  if (socketcan::is_error_frame(frame)) {
    for (BusEvent e : socketcan::decode_error_frame(frame)) deliver_event(e);
  } else if (auto f = socketcan::from_kernel(frame)) {
    deliver_frame(*f, stamp);
  }
  return true;
}

}  // namespace oegw::canopen::io
