// How the real-time event loop waits where the kernel allows it: one io_uring (liburing) through
// which every bus socket's datagrams arrive already read, and which also tells when the loop's
// epoll descriptor (everything that is not a bus: timers' signals, the control socket, eventfds)
// has something.
//
// Why: with epoll a frame costs epoll_wait, then a recvmmsg on the socket, then the answer's
// sendmmsg: three system calls where a blocking forwarder needs two (read, write). Here each
// socket has a multishot recvmsg (IORING_OP_RECVMSG with IORING_RECV_MULTISHOT, Linux 6.0) taking
// buffers from a ring of its own (provided buffers, 5.19): the kernel reads each datagram into a
// buffer as it arrives, and one io_uring_enter that waits returns every datagram received since
// the last. Ancillary data (SO_TIMESTAMPNS stamps, SO_RXQ_OVFL counts) comes with each, as
// recvmsg gives it. What a wake-up sends is queued as sends (IORING_OP_SEND, MSG_DONTWAIT: a full
// queue refuses at once, as sendmmsg did, and nothing waits in the kernel to be sent out of
// order) that the next io_uring_enter makes before it waits; a sent one posts no completion
// (IOSQE_CQE_SKIP_SUCCESS, 5.17), so it wakes nothing. A frame in and its answer out: one system
// call, where the blocking forwarder makes two.
//
// The epoll descriptor is watched by a one-shot poll (IORING_OP_POLL_ADD) armed again after each
// time the loop read it: a level-triggered descriptor the loop left readable is then reported
// again at once, as epoll_wait would have (a multishot poll would report only new wake-ups).
// The loop's next timer is an absolute CLOCK_MONOTONIC timeout request (IORING_OP_TIMEOUT with
// IORING_TIMEOUT_ABS), moved by IORING_OP_TIMEOUT_REMOVE's update (5.11) only when the next timer
// changes: as the timerfd was, but submitted with the wait, and without reading the clock.
//
// open() returns nullptr, with the reason, where io_uring cannot do this: a kernel before 6.0 or
// without io_uring, kernel.io_uring_disabled, a seccomp filter (container runtimes often refuse
// io_uring), qemu-user (the cross tier), or OEGW_IO_URING=off in the environment. The loop then
// waits with epoll_wait and each socket is read and written by its owner: same behaviour, two
// system calls more per wake-up. A time namespace that offsets CLOCK_MONOTONIC also chooses epoll:
// io_uring's absolute timeouts do not follow the offset (timerfd's do).
#pragma once

#include <linux/time_types.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "canopen/io/datagram.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen::io {

class UringReceiver {
 public:
  using OnDatagram = std::function<void(const ReceivedDatagram&)>;

  // A ring that also polls `epoll_fd`; nullptr where io_uring cannot be used here, *why saying why
  // (the kernel's test is made once per process).
  [[nodiscard]] static std::unique_ptr<UringReceiver> open(int epoll_fd, std::string* why);
  UringReceiver(const UringReceiver&) = delete;
  UringReceiver& operator=(const UringReceiver&) = delete;
  ~UringReceiver();

  // Receives `fd`'s datagrams from the next wait() on, each handed to `fn` by dispatch(). `key`:
  // unique, not 0, below 2^32. Throws std::system_error if the kernel refuses the socket's
  // buffers, or (EEXIST) if `fd` is received already.
  void add(std::uint64_t key, int fd, DatagramSpec spec, OnDatagram fn, std::function<void(int)> on_send_failed = {});
  // Queues `size` bytes (copied) to be sent on `key`'s socket with send(MSG_DONTWAIT) by the
  // next wait() or flush(), in the order queued: the kernel sends them before it waits, in the
  // same system call. Only a refusal comes back (to `on_send_failed` of add()): a success posts
  // no completion, so it wakes nothing. NotQueued for an unknown key or more than 80 bytes; Full
  // when 1,024 datagrams wait already.
  DatagramSend send(std::uint64_t key, const void* data, std::size_t size);
  // Submits the queued datagrams now (one io_uring_enter) if there are any.
  void flush();
  // Stops receiving: `fn` is not called again, the request is cancelled at once. Datagrams the
  // kernel already read into the socket's buffers and not yet handed over are dropped with it
  // (epoll would have left them in the socket). False if there is no such key.
  bool remove(std::uint64_t key);

  // Submits what is queued and waits up to `timeout` (nullopt: until something happens; zero:
  // not at all) for a datagram or the epoll descriptor readable.
  void wait(std::optional<Duration> timeout);
  // Hands every datagram received so far to its socket's `fn`, in the order received; sets
  // `epoll_ready` when the epoll descriptor became readable (the loop reads it, then calls
  // poll_again()). Returns how many datagrams and errors it handed over.
  std::size_t dispatch(bool& epoll_ready);
  // Arms the epoll descriptor's poll again (submitted by the next wait()).
  void poll_again();
  // Where the loop's next timer is (nullopt: none): the wait ends then at the latest. Submitted
  // by the next wait(); nothing to submit if it did not change.
  void set_timer(std::optional<TimePoint> at);

 private:
  struct Socket;
  struct Ring;
  explicit UringReceiver(int epoll_fd);
  void arm(Socket& s);
  void arm_poll();
  void take(std::uint64_t key, int res, std::uint32_t flags, std::size_t& handed);
  void release(Socket& s);
  void forget_sends_of(std::uint64_t key);

  std::unique_ptr<Ring> ring_;
  int epoll_fd_;
  bool poll_armed_ = false;
  std::optional<TimePoint> timer_;  // where the timeout request is, if there is one
  std::uint64_t timer_generation_ = 0;
  __kernel_timespec timer_at_{};      // the request's time (the kernel reads it at submission)
  __kernel_timespec timer_update_{};  // an update's
  std::unordered_map<std::uint64_t, std::unique_ptr<Socket>> sockets_;
  std::vector<std::unique_ptr<Socket>> retired_;  // removed, their request not yet ended
  std::vector<std::uint16_t> free_groups_;        // buffer group ids given back
  std::uint16_t next_group_ = 0;
  int dispatching_ = 0;  // dispatch() calls under way (a callback may run the loop again)
  // Datagrams queued by send(), kept until the kernel took their submissions (it copies them as
  // it sends them, inline: MSG_DONTWAIT never leaves one waiting for the socket).
  struct SendSlot {
    alignas(16) std::byte bytes[80];
  };
  std::vector<SendSlot> send_slots_;
  std::size_t sends_queued_ = 0;
  bool sends_unsubmitted_ = false;
  void submitted();  // after a submission: the slots are free once the kernel took every entry
};

// True if /proc/self/timens_offsets' text offsets CLOCK_MONOTONIC (time_namespaces(7)): the
// kernel's absolute io_uring timeouts do not follow the offset, so the loop then waits with epoll.
[[nodiscard]] bool monotonic_offset_in(std::string_view timens_offsets);

}  // namespace oegw::canopen::io
