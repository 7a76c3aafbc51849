// A datagram the event loop received for its owner (EventLoop::receive_datagrams): where the
// loop takes a socket's datagrams itself (io_uring, canopen/io/uring_receiver.hpp) instead of
// telling the owner that the socket is readable.
#pragma once

#include <sys/socket.h>

#include <cstddef>
#include <cstdint>
#include <functional>

namespace oegw::canopen::io {

// The most one datagram carries: `payload_bytes` of data (a longer one arrives cut, MSG_TRUNC)
// and `control_bytes` of ancillary data (cmsg: receive stamps, drop counts).
struct DatagramSpec {
  std::size_t payload_bytes = 0;
  std::size_t control_bytes = 0;
};

// One received datagram, or the error a receive failed with. `msg` is valid for the call only:
// msg->msg_iov[0] the payload (`length` bytes of it), msg_control/msg_controllen its ancillary
// data (CMSG_FIRSTHDR works), msg_flags the kernel's (MSG_TRUNC, MSG_CTRUNC). A datagram of no
// bytes is what a SOCK_SEQPACKET socket reads once its peer closed.
struct ReceivedDatagram {
  const msghdr* msg = nullptr;  // null when `error` is set
  std::size_t length = 0;
  int error = 0;  // errno of a failed receive (ENETDOWN: the interface went down)
};

// Sending through the loop's ring (EventLoop::send_datagram): what became of one datagram.
enum class DatagramSend : std::uint8_t {
  Queued,     // copied; sent in order when the loop next enters the kernel
  NotQueued,  // the loop does not send for this socket: the owner sends it itself
  Full,       // no room left this wake-up: dropped, as by a full TX queue
};
using DatagramSender = std::function<DatagramSend(const void* data, std::size_t size)>;

}  // namespace oegw::canopen::io
