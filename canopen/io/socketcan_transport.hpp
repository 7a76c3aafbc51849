// Linux SocketCAN (CAN_RAW) transport.
//
//   auto can = SocketCanTransport::open("can0", {.filters = std::vector<CanFilter>{{0x580, 0x780}}});
//   watch_transport(loop, *can);        // the loop calls can->poll_readable() when readable
//
// * Non-blocking socket; send() never blocks: a full TX queue (ENOBUFS) drops the frame, counts
//   it in counters().tx_dropped and returns SendStatus::QueueFull.
// * CAN_RAW_FILTER from the options (default: everything); CAN_RAW_ERR_FILTER so the controller
//   state comes in as error frames, decoded to BusEvents; CAN_RAW_LOOPBACK on (other programs on
//   this host, e.g. candump, see our frames), CAN_RAW_RECV_OWN_MSGS off (we do not).
// * Receive timestamps: SO_TIMESTAMPNS, taken by the kernel when the frame arrived. The kernel
//   gives CLOCK_REALTIME, while TimePoint is CLOCK_MONOTONIC; StampMapper subtracts the offset
//   between the two, sampled every 100 ms. So a backlog drained late still carries its arrival
//   times. If the realtime clock was stepped (a stamp more than 1 s ahead or 10 s behind) the
//   offset is sampled again, and the time of reading is used if that does not explain it.
// * Reading: recvmmsg(), up to 64 frames per call, and no clock reading of its own when the
//   event loop's clock is set (watch_transport): per wake-up one read, not one per frame plus
//   the EAGAIN that ends it.
// * SO_RXQ_OVFL: frames the kernel dropped because we read too slowly -> counters().rx_dropped.
//
// Opening failures throw CanOpenError (one policy for every open problem), whose what() names the
// problem, e.g. "no such CAN interface 'can7'".
#pragma once

#include <linux/can.h>
#include <linux/can/error.h>
#include <sys/socket.h>
#include <time.h>

#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "canopen/io/can_transport.hpp"

namespace oegw::canopen::io {

// One receive filter: a frame matches if (frame id & mask) == (id & mask) and its format
// (11/29-bit) is that of `extended`. Data and remote frames both match, unless `data_only`:
// then remote frames never do. `invert` matches everything else. Several filters are OR-ed, or
// AND-ed with SocketCanOptions::join_filters (so inverted filters exclude several identifiers).
struct CanFilter {
  std::uint32_t id = 0;
  std::uint32_t mask = 0;
  bool extended = false;
  bool invert = false;
  bool data_only = false;
};

// Filters that pass every frame but the data frames on `cob_ids` (remote frames on them still
// pass): for SocketCanOptions::join_filters = true. An empty list gives nullopt (every frame).
[[nodiscard]] std::optional<std::vector<CanFilter>> all_but_data_frames_on(const std::vector<CobId>& cob_ids);

// The error classes received by default: controller state, bus-off, restarts, TX timeouts,
// protocol/transceiver errors and missing ACKs. Not lost arbitration nor bus errors, which can
// flood.
inline constexpr std::uint32_t kDefaultCanErrorMask =
    CAN_ERR_TX_TIMEOUT | CAN_ERR_CRTL | CAN_ERR_PROT | CAN_ERR_TRX | CAN_ERR_ACK | CAN_ERR_BUSOFF | CAN_ERR_RESTARTED;

struct SocketCanOptions {
  // nullopt: receive every frame. An empty list: receive no data frames (error frames only).
  std::optional<std::vector<CanFilter>> filters;
  // CAN_RAW_JOIN_FILTERS (Linux 4.1): a frame must match every filter rather than one of them.
  // Error frames then stop coming once there are two filters or more (net/can/raw.c counts the
  // error mask as one more receiver, which an error frame alone matches): for a reader that does
  // not need them (oegw-sim's acceptance filter).
  bool join_filters = false;
  std::uint32_t error_mask = kDefaultCanErrorMask;  // CAN_ERR_* classes; 0 = no error frames
  bool loopback = true;                             // CAN_RAW_LOOPBACK
  bool receive_own = false;                         // CAN_RAW_RECV_OWN_MSGS
  std::size_t max_batch = kDefaultMaxBatch;         // frames read per poll_readable() call
  // (4,096 was tried: in the TCG guest the gateway then read fewer than half as many
  // frames a second at 6,000 frames/s in as with 256.)
  static constexpr std::size_t kDefaultMaxBatch = 256;
  // The socket's receive buffer (SO_RCVBUF), 0: the kernel's default. The default (212,992 bytes,
  // net.core.rmem_default) holds only ~200 frames (each costs its sk_buff, ~1 KB): 25 ms of a
  // 1 Mbit/s bus. A reader the scheduler holds off longer loses frames, heartbeats among them
  // (at 6,000 frames/s in the TCG guest the kernel dropped 56 % of the grip's frames
  // before the gateway read them; 3-11 % with this buffer). The default here, 4 MiB as the
  // kernel counts it, holds ~4,000 frames: half a second of a full 1 Mbit/s bus. It trades lost
  // frames for late ones; a frame read late keeps its kernel stamp, from which the freshness
  // deadlines count, so a reader that far behind still finds its inputs overdue.
  // Set with SO_RCVBUFFORCE (CAP_NET_ADMIN, which `oegw run` has for the bit rates), else
  // SO_RCVBUF, which the kernel caps at net.core.rmem_max; rx_buffer_bytes() says what it got.
  std::size_t rx_buffer_bytes = kDefaultRxBufferBytes;
  static constexpr std::size_t kDefaultRxBufferBytes = std::size_t{4} << 20;
};

class CanOpenError : public std::runtime_error {
 public:
  enum class Reason {
    NoKernelSupport,  // no PF_CAN (or no CAN_RAW) in this kernel
    InvalidName,      // empty or too long for an interface name
    NoSuchInterface,
    NotCanInterface,  // exists, but its hardware type is not ARPHRD_CAN
    InterfaceDown,
    SystemError,  // anything else: see error()
  };
  CanOpenError(Reason reason, int error, const std::string& message)
      : std::runtime_error(message), reason_(reason), error_(error) {}
  [[nodiscard]] Reason reason() const { return reason_; }
  [[nodiscard]] int error() const { return error_; }  // errno, where one applies

 private:
  Reason reason_;
  int error_;
};

// What the kernel says about a network interface (without needing CAN support).
struct InterfaceInfo {
  bool exists = false;
  int index = 0;
  bool is_can = false;  // ARPHRD_CAN: can*, vcan*, vxcan*, slcan*
  bool up = false;      // IFF_UP
};
// Throws CanOpenError(InvalidName) for a bad name, CanOpenError(SystemError) if the kernel
// cannot be asked.
[[nodiscard]] InterfaceInfo probe_interface(const std::string& name);
// probe_interface(), then throws CanOpenError for a missing, non-CAN or down interface.
// Returns the interface index.
int check_can_interface(const std::string& name);

// Conversions to and from the kernel's struct can_frame (exposed for testing).
namespace socketcan {
// `frame` must satisfy is_valid_frame(); a remote frame carries no data.
[[nodiscard]] ::can_frame to_kernel(const CanFrame& frame);
// nullopt for an error frame (CAN_ERR_FLAG); a len above 8 is clamped to 8.
[[nodiscard]] std::optional<CanFrame> from_kernel(const ::can_frame& frame);
[[nodiscard]] inline bool is_error_frame(const ::can_frame& frame) { return (frame.can_id & CAN_ERR_FLAG) != 0; }
// The events an error frame reports, in CAN_ERR_* class bit order (TX timeout, lost arbitration,
// controller [overflow, warning, passive, active], protocol, transceiver, no ACK, bus-off, bus
// error, restarted), without duplicates.
[[nodiscard]] std::vector<BusEvent> decode_error_frame(const ::can_frame& frame);
[[nodiscard]] ::can_filter to_kernel(const CanFilter& filter);

// Maps CLOCK_REALTIME kernel receive stamps (SO_TIMESTAMPNS) to monotonic TimePoints through the
// offset realtime - monotonic, sampled at most every kResample instead of reading both clocks for
// every frame (two clock_gettime calls per frame). Between samples NTP's slew (at most
// 500 ppm) moves the true offset by 50 us at most. A stamp the offset cannot explain — more than
// kAhead after `now` or more than kMaxAge before it — means the realtime clock was stepped: map()
// returns nullopt, the caller samples again and retries, then falls back to `now`. A stamp up to
// kAhead after `now` is a frame that arrived after the wake-up `now` was read at: it is `now`.
class StampMapper {
 public:
  static constexpr Duration kResample{100'000};
  static constexpr Duration kAhead{1'000'000};
  static constexpr Duration kMaxAge{10'000'000};

  [[nodiscard]] bool needs_sample(TimePoint now) const { return !sampled_ || now - sampled_at_ >= kResample; }
  void sample(const timespec& realtime, TimePoint monotonic);
  [[nodiscard]] std::optional<TimePoint> map(const timespec& stamp, TimePoint now) const;

 private:
  bool sampled_ = false;
  TimePoint sampled_at_{};
  std::int64_t offset_us_ = 0;  // realtime - monotonic
};
}  // namespace socketcan

// The I/O of a socket that carries one struct can_frame per datagram, CAN_RAW's format: what
// SocketCanTransport (CAN_RAW) and SeqpacketCanTransport (canopen/io/seqpacket_transport.hpp, an
// AF_UNIX socketpair standing in for a bus where the kernel has no AF_CAN) share, so that both
// read, stamp and batch alike:
// * send() never blocks: a full TX queue (ENOBUFS/EAGAIN) drops the frame, counts it in
//   counters().tx_dropped and returns SendStatus::QueueFull. Between begin_batch() and
//   end_batch() it holds valid frames; end_batch() sends them with sendmmsg().
// * poll_readable(): recvmmsg(), up to 64 frames per call, up to max_batch per call of its own;
//   each frame stamped with its kernel receive time (SO_TIMESTAMPNS, StampMapper), else with
//   the loop's `now`; error frames (CAN_ERR_FLAG) decoded into BusEvents; SO_RXQ_OVFL's count
//   into counters().rx_dropped. A datagram that is not one struct can_frame (shorter, or cut:
//   MSG_TRUNC) is counted in counters().errors and not delivered.
// * A datagram of no bytes ends the stream: what a SOCK_SEQPACKET socket reads once its peer
//   closed (CAN_RAW never delivers one). Reported once as BusEvent::InterfaceDown (and one
//   counters().errors); nothing is read after it. The descriptor then stays readable: whoever
//   watches it must unwatch it.
class CanFrameSocket : public CanTransport {
 public:
  ~CanFrameSocket() override;  // closes the socket

  SendResult send(const CanFrame& frame) override;
  void begin_batch() override { batching_ = true; }
  void end_batch() override;
  [[nodiscard]] int fd() const override { return fd_; }
  void poll_readable() override;
  // Where the loop reads (io_uring): one struct can_frame and its stamp and drop count, each
  // handled as poll_readable() handles it.
  [[nodiscard]] std::optional<DatagramSpec> datagram_spec() const override;
  void take_datagram(const ReceivedDatagram& datagram) override;
  void datagram_send_failed(int error) override;

 protected:
  // Takes ownership of `fd` (non-blocking; the subclass sets its options).
  CanFrameSocket(int fd, std::size_t max_batch);
  // For a socket made elsewhere: non-blocking, SO_TIMESTAMPNS and SO_RXQ_OVFL on where the
  // socket takes them (qemu-user refuses SO_TIMESTAMPNS: frames are then stamped when read).
  static void prepare_adopted(int fd);

 private:
  // Reads up to the batch size in one recvmmsg(); returns how many it read, -1 to stop.
  int read_batch();
  TimePoint wake_up_time();  // the loop's "now"; the stamps' offset sampled again when due
  bool take(const msghdr& msg, std::size_t len, TimePoint now, bool& resampled);
  void receive_failed(int error);
  void sample_clocks();
  void send_held();
  bool queue_held_in_ring();
  void end_of_stream();

  // recvmmsg() buffers: one frame and its control data (timestamp, drop count) per slot.
  struct Slot {
    ::can_frame frame;
    iovec iov;
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timespec)) + CMSG_SPACE(sizeof(std::uint32_t))];
  };

  int fd_;
  std::size_t max_batch_;
  std::vector<Slot> slots_;
  std::vector<::mmsghdr> headers_;
  socketcan::StampMapper stamps_;
  bool batching_ = false;
  bool ended_ = false;             // a zero-length datagram was read: the peer is gone
  std::vector<::can_frame> held_;  // frames send() took during a batch
  std::vector<iovec> held_iov_;
  std::vector<::mmsghdr> held_headers_;
};

class SocketCanTransport final : public CanFrameSocket {
 public:
  // Throws CanOpenError, with messages such as:
  //   "kernel has no CAN support (socket(PF_CAN): Address family not supported by protocol)"
  //   "no such CAN interface 'can7'"
  //   "interface 'eth0' is not a CAN interface"
  //   "interface 'can0' is down"
  [[nodiscard]] static std::unique_ptr<SocketCanTransport> open(const std::string& interface,
                                                                SocketCanOptions options = {});
  // Takes ownership of an already bound CAN_RAW socket (e.g. one handed over by a privileged
  // helper or by systemd socket activation); `interface` is only used in messages. The fd is made
  // non-blocking and SO_TIMESTAMPNS/SO_RXQ_OVFL are enabled where the socket supports them; the
  // CAN_RAW options are left as the socket has them. Throws std::invalid_argument for fd < 0.
  [[nodiscard]] static std::unique_ptr<SocketCanTransport> adopt(
      int fd, std::string interface, std::size_t max_batch = SocketCanOptions::kDefaultMaxBatch);

  [[nodiscard]] const std::string& interface() const { return interface_; }
  [[nodiscard]] int interface_index() const { return index_; }  // 0 when adopted
  // The receive buffer the kernel grants the socket (getsockopt SO_RCVBUF, in the kernel's own
  // accounting: sk_buff overhead included), and whether it is less than SocketCanOptions asked.
  [[nodiscard]] std::size_t rx_buffer_bytes() const;
  [[nodiscard]] bool rx_buffer_capped() const { return rx_buffer_capped_; }
  // Replaces the receive filters while open (as SocketCanOptions::filters and join_filters);
  // frames already queued stay. Throws CanOpenError(SystemError) if the kernel refuses them.
  void set_filters(const std::optional<std::vector<CanFilter>>& filters, bool join);

 private:
  SocketCanTransport(int fd, std::string interface, int index, std::size_t max_batch);

  std::string interface_;
  int index_;
  bool rx_buffer_capped_ = false;
};

}  // namespace oegw::canopen::io
