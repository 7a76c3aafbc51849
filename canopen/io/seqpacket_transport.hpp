// A CAN transport over an AF_UNIX SOCK_SEQPACKET socket, for a kernel without AF_CAN: each
// frame one datagram holding the kernel's struct can_frame (16 bytes, as CAN_RAW carries it),
// read, stamped (SO_TIMESTAMPNS) and batched (recvmmsg/sendmmsg) by the same code as
// SocketCanTransport's (CanFrameSocket, socketcan_transport.hpp). So an event loop's whole path
// — wake-up, receive stamps, batching — runs natively where CAN does not (the benchmark
// tests/bench/bench_path.cpp runs `oegw run`'s serving on it).
//
//   auto [a, b] = SeqpacketCanTransport::pair();   // two ends of one "bus"
//   watch_transport(loop, *a);
//
// Two ends of a socketpair are a point-to-point link, not a bus: what one end sends only the other
// receives, with no arbitration, no acceptance filters, no loopback to other readers, no bit
// rate; what is queued is bounded by the socket buffers (a full one: SendStatus::QueueFull).
// SOCK_SEQPACKET rather than SOCK_DGRAM: a peer that closes its end is seen (the end of the
// stream, CanFrameSocket), where a datagram socket would wait on. Error frames (CAN_ERR_FLAG)
// the peer sends are decoded into BusEvents as CAN_RAW's are, so a peer can play the
// controller's reports.
#pragma once

#include <memory>

#include "canopen/io/socketcan_transport.hpp"

namespace oegw::canopen::io {

class SeqpacketCanTransport final : public CanFrameSocket {
 public:
  struct Pair {
    std::unique_ptr<SeqpacketCanTransport> a, b;
  };
  // A new socketpair, both ends transports. Throws std::system_error if it cannot be made.
  [[nodiscard]] static Pair pair(std::size_t max_batch = SocketCanOptions::kDefaultMaxBatch);
  // Takes ownership of one end of a SOCK_SEQPACKET socketpair (the other end may be read and
  // written as raw struct can_frame datagrams, e.g. by a benchmark's prober); made non-blocking,
  // SO_TIMESTAMPNS on where the socket takes it. Throws std::invalid_argument for fd < 0.
  [[nodiscard]] static std::unique_ptr<SeqpacketCanTransport> adopt(
      int fd, std::size_t max_batch = SocketCanOptions::kDefaultMaxBatch);
  // socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC): the two raw descriptors, for adopt().
  // Throws std::system_error.
  static void make_socketpair(int (&fds)[2]);

 private:
  SeqpacketCanTransport(int fd, std::size_t max_batch) : CanFrameSocket(fd, max_batch) {}
};

}  // namespace oegw::canopen::io
