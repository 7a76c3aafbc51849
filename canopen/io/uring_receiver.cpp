#include "canopen/io/uring_receiver.hpp"

#include <liburing.h>
#include <poll.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <mutex>
#include <new>
#include <sstream>
#include <string_view>
#include <system_error>

namespace oegw::canopen::io {

namespace {

// user_data of the requests that are not a socket's (a socket's is its key, never 0).
constexpr std::uint64_t kPollKey = 0;
constexpr std::uint64_t kCancelKey = ~std::uint64_t{0};
constexpr std::uint64_t kTimerUpdateKey = ~std::uint64_t{0} - 1;
// A timeout request's: this tag and its generation (each new request one more), so that what is
// left of an earlier request is told from the current one's (sockets' keys are below 2^32).
constexpr std::uint64_t kTimerTag = std::uint64_t{0xFFFF'FFFE} << 32;
constexpr std::uint64_t kTimerGenerations = 0xFFFF'FFFF;
// A refused send's: this tag and its socket's key.
constexpr std::uint64_t kSendTag = std::uint64_t{0xFFFF'FFFD} << 32;
constexpr std::size_t kSendSlots = 1024;

// Buffers per socket: datagrams the kernel may read ahead of the loop. When all are in use the
// socket's request ends (ENOBUFS) and is armed again once the loop gave them back; the
// datagrams meanwhile wait in the socket's own receive queue, as with epoll.
constexpr unsigned kBuffers = 256;
constexpr unsigned kSubmissionEntries = 64;
constexpr unsigned kCompletionEntries = 1024;  // both sockets' buffers, the poll, cancellations

std::string error_text(int e) { return std::strerror(e); }

}  // namespace

bool monotonic_offset_in(std::string_view timens_offsets);

namespace {

// An anonymous, page-aligned mapping (a buffer ring must be page-aligned).
struct Mapping {
  void* at = MAP_FAILED;
  std::size_t bytes = 0;
  explicit Mapping(std::size_t n) : bytes(n) {
    at = ::mmap(nullptr, n, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  }
  Mapping(const Mapping&) = delete;
  Mapping& operator=(const Mapping&) = delete;
  ~Mapping() {
    if (at != MAP_FAILED) ::munmap(at, bytes);
  }
  [[nodiscard]] bool ok() const { return at != MAP_FAILED; }
};

int init_ring(io_uring& ring, unsigned cq_entries) {
  io_uring_params p{};
  // COOP_TASKRUN (5.19): a completion does not interrupt the loop while it runs; it is taken
  // at the next wait, which the loop makes anyway. Retried without it on an older kernel.
  p.flags = IORING_SETUP_CQSIZE | IORING_SETUP_COOP_TASKRUN;
  p.cq_entries = cq_entries;
  int r = io_uring_queue_init_params(kSubmissionEntries, &ring, &p);
  if (r == -EINVAL) {
    p = io_uring_params{};
    p.flags = IORING_SETUP_CQSIZE;
    p.cq_entries = cq_entries;
    r = io_uring_queue_init_params(kSubmissionEntries, &ring, &p);
  }
  return r;
}

// Whether this kernel and process can do what UringReceiver needs: a ring, waits with a
// timeout argument (IORING_FEAT_EXT_ARG, 5.11), and a multishot recvmsg from a buffer ring
// (6.0), tried on a socketpair. Empty if so, else why not.
std::string probe_kernel() {
  if (const char* v = std::getenv("OEGW_IO_URING"); v != nullptr && std::string_view(v) == "off") {
    return "OEGW_IO_URING=off";
  }
  if (std::ifstream offsets("/proc/self/timens_offsets"); offsets) {
    const std::string text((std::istreambuf_iterator<char>(offsets)), std::istreambuf_iterator<char>());
    if (monotonic_offset_in(text)) {
      return "a time namespace offsets CLOCK_MONOTONIC, which io_uring's absolute timeouts do not follow";
    }
  }
  io_uring ring{};
  if (const int r = init_ring(ring, kCompletionEntries); r < 0) return "io_uring_setup: " + error_text(-r);
  struct Exit {
    io_uring* r;
    ~Exit() { io_uring_queue_exit(r); }
  } exit_ring{&ring};
  if ((ring.features & IORING_FEAT_EXT_ARG) == 0) return "the kernel's io_uring has no wait timeout (Linux 5.11)";
  if ((ring.features & IORING_FEAT_NODROP) == 0) return "the kernel's io_uring may drop completions (Linux 5.5)";
  if ((ring.features & IORING_FEAT_CQE_SKIP) == 0) return "the kernel's io_uring cannot skip completions (Linux 5.17)";
  int fds[2];
  if (::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC | SOCK_NONBLOCK, 0, fds) != 0) {
    return "socketpair: " + error_text(errno);
  }
  struct Close {
    int* fds;
    ~Close() {
      ::close(fds[0]);
      ::close(fds[1]);
    }
  } close_fds{fds};
  constexpr unsigned kEntries = 2;
  Mapping ring_memory(4096);
  if (!ring_memory.ok()) return "mmap: " + error_text(errno);
  auto* br = static_cast<io_uring_buf_ring*>(ring_memory.at);
  io_uring_buf_reg reg{};
  reg.ring_addr = reinterpret_cast<std::uintptr_t>(br);
  reg.ring_entries = kEntries;
  reg.bgid = 0;
  if (const int r = io_uring_register_buf_ring(&ring, &reg, 0); r < 0) {
    return "the kernel's io_uring has no buffer rings (Linux 5.19): " + error_text(-r);
  }
  alignas(16) static thread_local char buffers[kEntries][128];
  io_uring_buf_ring_init(br);
  for (unsigned i = 0; i < kEntries; ++i) {
    io_uring_buf_ring_add(br, buffers[i], sizeof buffers[i], static_cast<unsigned short>(i),
                          io_uring_buf_ring_mask(kEntries), static_cast<int>(i));
  }
  io_uring_buf_ring_advance(br, kEntries);
  msghdr tmpl{};
  io_uring_sqe* sqe = io_uring_get_sqe(&ring);
  io_uring_prep_recvmsg_multishot(sqe, fds[0], &tmpl, 0);
  sqe->flags |= IOSQE_BUFFER_SELECT;
  sqe->buf_group = 0;
  io_uring_sqe_set_data64(sqe, 1);
  const char byte = 'x';
  if (::send(fds[1], &byte, 1, 0) != 1) return "send: " + error_text(errno);
  __kernel_timespec ts{.tv_sec = 1, .tv_nsec = 0};
  io_uring_cqe* cqe = nullptr;
  const int r = io_uring_submit_and_wait_timeout(&ring, &cqe, 1, &ts, nullptr);
  if (r < 0 || cqe == nullptr) return "io_uring_enter: " + error_text(r < 0 ? -r : EIO);
  const int res = cqe->res;
  const std::uint32_t flags = cqe->flags;
  if (res < 0) return "the kernel's io_uring has no multishot recvmsg (Linux 6.0): " + error_text(-res);
  if ((flags & IORING_CQE_F_MORE) == 0 || (flags & IORING_CQE_F_BUFFER) == 0) {
    return "the kernel's io_uring has no multishot recvmsg (Linux 6.0)";
  }
  return {};
}

}  // namespace

bool monotonic_offset_in(std::string_view timens_offsets) {
  std::istringstream lines{std::string(timens_offsets)};
  std::string clock;
  long long seconds = 0;
  long long nanoseconds = 0;
  while (lines >> clock >> seconds >> nanoseconds) {
    if ((clock == "monotonic" || clock == "1") && (seconds != 0 || nanoseconds != 0)) return true;
  }
  return false;
}

namespace {

const std::string& kernel_problem() {
  static std::once_flag once;
  static std::string problem;
  std::call_once(once, [] { problem = probe_kernel(); });
  return problem;
}

}  // namespace

struct UringReceiver::Ring {
  io_uring ring{};
};

struct UringReceiver::Socket {
  std::uint64_t key = 0;
  int fd = -1;
  OnDatagram fn;
  std::function<void(int)> on_send_failed;
  msghdr tmpl{};  // what recvmsg is asked for: no address, spec.control_bytes of ancillary data
  std::uint16_t group = 0;
  std::unique_ptr<Mapping> ring_memory;
  std::unique_ptr<std::byte[]> buffers;
  std::size_t buffer_bytes = 0;
  bool registered = false;
  bool armed = false;  // a request is (or is about to be) in the kernel
  bool ended = false;  // a datagram of no bytes: the peer closed

  [[nodiscard]] io_uring_buf_ring* br() const { return static_cast<io_uring_buf_ring*>(ring_memory->at); }
  [[nodiscard]] std::byte* buffer(unsigned id) const { return buffers.get() + std::size_t{id} * buffer_bytes; }
  void give_back(unsigned id) const {
    io_uring_buf_ring_add(br(), buffer(id), static_cast<unsigned>(buffer_bytes), static_cast<unsigned short>(id),
                          io_uring_buf_ring_mask(kBuffers), 0);
    io_uring_buf_ring_advance(br(), 1);
  }
};

std::unique_ptr<UringReceiver> UringReceiver::open(int epoll_fd, std::string* why) {
  const std::string& problem = kernel_problem();
  if (!problem.empty()) {
    if (why != nullptr) *why = problem;
    return nullptr;
  }
  std::unique_ptr<UringReceiver> r(new UringReceiver(epoll_fd));
  if (const int e = init_ring(r->ring_->ring, kCompletionEntries); e < 0) {
    if (why != nullptr) *why = "io_uring_setup: " + error_text(-e);
    r->ring_.reset();
    return nullptr;
  }
  r->arm_poll();
  return r;
}

UringReceiver::UringReceiver(int epoll_fd) : ring_(std::make_unique<Ring>()), epoll_fd_(epoll_fd) {}

UringReceiver::~UringReceiver() {
  // Ends every request; the buffers (Socket) go after it.
  if (ring_) io_uring_queue_exit(&ring_->ring);
}

namespace {

io_uring_sqe* next_sqe(io_uring& ring) {
  io_uring_sqe* sqe = io_uring_get_sqe(&ring);
  if (sqe != nullptr) return sqe;
  (void)io_uring_submit(&ring);  // the queue is full: what is in it goes now
  sqe = io_uring_get_sqe(&ring);
  if (sqe == nullptr) throw std::system_error(EBUSY, std::generic_category(), "io_uring: no submission entry");
  return sqe;
}

}  // namespace

void UringReceiver::arm_poll() {
  io_uring_sqe* sqe = next_sqe(ring_->ring);
  io_uring_prep_poll_add(sqe, epoll_fd_, POLLIN);
  io_uring_sqe_set_data64(sqe, kPollKey);
  poll_armed_ = true;
}

void UringReceiver::poll_again() {
  if (!poll_armed_) arm_poll();
}

namespace {

void to_timespec(TimePoint at, __kernel_timespec& spec) {
  const std::int64_t us = std::max<std::int64_t>(at.time_since_epoch().count(), 0);
  spec.tv_sec = us / 1'000'000;
  spec.tv_nsec = (us % 1'000'000) * 1'000;
}

}  // namespace

void UringReceiver::set_timer(std::optional<TimePoint> at) {
  if (at == timer_) return;
  const std::uint64_t current = kTimerTag | timer_generation_;
  if (!at) {
    io_uring_sqe* sqe = next_sqe(ring_->ring);
    io_uring_prep_timeout_remove(sqe, current, 0);
    io_uring_sqe_set_data64(sqe, kTimerUpdateKey);
    sqe->flags |= IOSQE_CQE_SKIP_SUCCESS;  // no completion, no wake-up, when it worked
  } else if (timer_) {
    // An update that finds no request (it expired meanwhile) fails; the request's own completion
    // (-ETIME) then clears timer_ and the next call arms anew.
    to_timespec(*at, timer_update_);
    io_uring_sqe* sqe = next_sqe(ring_->ring);
    io_uring_prep_timeout_update(sqe, &timer_update_, current, IORING_TIMEOUT_ABS);
    io_uring_sqe_set_data64(sqe, kTimerUpdateKey);
    sqe->flags |= IOSQE_CQE_SKIP_SUCCESS;
  } else {
    timer_generation_ = (timer_generation_ + 1) & kTimerGenerations;
    to_timespec(*at, timer_at_);
    io_uring_sqe* sqe = next_sqe(ring_->ring);
    io_uring_prep_timeout(sqe, &timer_at_, 0, IORING_TIMEOUT_ABS);
    io_uring_sqe_set_data64(sqe, kTimerTag | timer_generation_);
  }
  timer_ = at;
}

void UringReceiver::add(std::uint64_t key, int fd, DatagramSpec spec, OnDatagram fn,
                        std::function<void(int)> on_send_failed) {
  if (key == kPollKey || key > kTimerGenerations || sockets_.contains(key)) {
    throw std::system_error(EINVAL, std::generic_category(), "UringReceiver::add: bad key");
  }
  // Two requests on one socket would split its datagrams between them (epoll refuses it too).
  for (const auto& [k, other] : sockets_) {
    if (other->fd == fd)
      throw std::system_error(EEXIST, std::generic_category(), "UringReceiver::add: fd already added");
  }
  auto s = std::make_unique<Socket>();
  s->key = key;
  s->fd = fd;
  s->fn = std::move(fn);
  s->on_send_failed = std::move(on_send_failed);
  s->tmpl.msg_controllen = spec.control_bytes;
  // Each buffer: the kernel's header (io_uring_recvmsg_out), the ancillary data, the payload;
  // 16-byte aligned so the ancillary data's cmsghdr is aligned.
  const std::size_t raw = sizeof(io_uring_recvmsg_out) + spec.control_bytes + spec.payload_bytes;
  s->buffer_bytes = (raw + 15) / 16 * 16;
  s->buffers.reset(new (std::align_val_t{16}) std::byte[s->buffer_bytes * kBuffers]);
  s->ring_memory = std::make_unique<Mapping>(sizeof(io_uring_buf) * kBuffers);
  if (!s->ring_memory->ok()) throw std::system_error(errno, std::generic_category(), "mmap (io_uring buffer ring)");
  if (!free_groups_.empty()) {
    s->group = free_groups_.back();
    free_groups_.pop_back();
  } else {
    s->group = next_group_++;
  }
  io_uring_buf_reg reg{};
  reg.ring_addr = reinterpret_cast<std::uintptr_t>(s->ring_memory->at);
  reg.ring_entries = kBuffers;
  reg.bgid = s->group;
  if (const int r = io_uring_register_buf_ring(&ring_->ring, &reg, 0); r < 0) {
    free_groups_.push_back(s->group);
    throw std::system_error(-r, std::generic_category(), "io_uring_register_buf_ring");
  }
  s->registered = true;
  io_uring_buf_ring_init(s->br());
  for (unsigned i = 0; i < kBuffers; ++i) {
    io_uring_buf_ring_add(s->br(), s->buffer(i), static_cast<unsigned>(s->buffer_bytes), static_cast<unsigned short>(i),
                          io_uring_buf_ring_mask(kBuffers), static_cast<int>(i));
  }
  io_uring_buf_ring_advance(s->br(), kBuffers);
  arm(*s);
  sockets_.emplace(key, std::move(s));
}

DatagramSend UringReceiver::send(std::uint64_t key, const void* data, std::size_t size) {
  const auto it = sockets_.find(key);
  if (it == sockets_.end() || size > sizeof(SendSlot::bytes)) return DatagramSend::NotQueued;
  if (send_slots_.empty()) send_slots_.resize(kSendSlots);
  if (sends_queued_ == send_slots_.size()) return DatagramSend::Full;
  // Never throws: a wake-up's end (a destructor) sends through here. A full submission queue
  // the kernel does not take from (memory) drops the frame as a full TX queue would.
  io_uring_sqe* sqe = io_uring_get_sqe(&ring_->ring);
  if (sqe == nullptr) {
    (void)io_uring_submit(&ring_->ring);  // what is queued goes now (sent already, in order)
    sqe = io_uring_get_sqe(&ring_->ring);
    if (sqe == nullptr) return DatagramSend::Full;
  }
  SendSlot& slot = send_slots_[sends_queued_];
  std::memcpy(slot.bytes, data, size);
  io_uring_prep_send(sqe, it->second->fd, slot.bytes, size, MSG_DONTWAIT | MSG_NOSIGNAL);
  io_uring_sqe_set_data64(sqe, kSendTag | key);
  sqe->flags |= IOSQE_CQE_SKIP_SUCCESS;
  ++sends_queued_;
  sends_unsubmitted_ = true;
  return DatagramSend::Queued;
}

void UringReceiver::flush() {
  if (!sends_unsubmitted_) return;
  if (const int r = io_uring_submit(&ring_->ring); r < 0 && r != -EINTR && r != -EAGAIN && r != -EBUSY) {
    throw std::system_error(-r, std::generic_category(), "io_uring_enter");
  }
  submitted();
}

void UringReceiver::submitted() {
  // Every entry taken (the usual case): each send was made in the call, its bytes copied.
  if (io_uring_sq_ready(&ring_->ring) == 0) {
    sends_queued_ = 0;
    sends_unsubmitted_ = false;
  }
}

void UringReceiver::arm(Socket& s) {
  io_uring_sqe* sqe = next_sqe(ring_->ring);
  io_uring_prep_recvmsg_multishot(sqe, s.fd, &s.tmpl, 0);
  sqe->flags |= IOSQE_BUFFER_SELECT;
  sqe->buf_group = s.group;
  io_uring_sqe_set_data64(sqe, s.key);
  s.armed = true;
}

bool UringReceiver::remove(std::uint64_t key) {
  auto it = sockets_.find(key);
  if (it == sockets_.end()) return false;
  // Kept (retired_) until no dispatch is under way: its callback may be the one removing it, and
  // the kernel may still write into its buffers until its request ended. Datagrams already read
  // into them and not yet handed over go with it.
  retired_.push_back(std::move(it->second));
  sockets_.erase(it);
  Socket& s = *retired_.back();
  if (s.armed) {
    io_uring_sqe* sqe = next_sqe(ring_->ring);
    io_uring_prep_cancel64(sqe, key, 0);
    io_uring_sqe_set_data64(sqe, kCancelKey);
    sqe->flags |= IOSQE_CQE_SKIP_SUCCESS;
  } else {
    release(s);
  }
  // Submitted now, not at the next wait: the owner closes the socket next, and its number may be
  // reused before then — a request or a send submitted later would reach the new socket.
  if (io_uring_sq_ready(&ring_->ring) > 0) {
    (void)io_uring_submit(&ring_->ring);
    submitted();
    if (io_uring_sq_ready(&ring_->ring) > 0) forget_sends_of(key);
  }
  return true;
}

// What the kernel did not take of the queue (memory) and is `key`'s sends: made no-operations,
// which complete silently, so that nothing is sent on a descriptor about to be closed.
void UringReceiver::forget_sends_of(std::uint64_t key) {
  io_uring& ring = ring_->ring;
  const unsigned mask = *ring.sq.kring_mask;
  for (unsigned i = *ring.sq.khead; i != ring.sq.sqe_tail; ++i) {
    io_uring_sqe* sqe = &ring.sq.sqes[i & mask];
    if (sqe->opcode != IORING_OP_SEND || sqe->user_data != (kSendTag | key)) continue;
    io_uring_prep_nop(sqe);
    io_uring_sqe_set_data64(sqe, kCancelKey);
    sqe->flags |= IOSQE_CQE_SKIP_SUCCESS;
  }
}

void UringReceiver::release(Socket& s) {
  if (s.registered) {
    (void)io_uring_unregister_buf_ring(&ring_->ring, s.group);
    s.registered = false;
    free_groups_.push_back(s.group);
  }
}

void UringReceiver::wait(std::optional<Duration> timeout) {
  if (dispatching_ == 0) std::erase_if(retired_, [](const std::unique_ptr<Socket>& s) { return !s->armed; });
  __kernel_timespec ts{};
  __kernel_timespec* limit = nullptr;
  if (timeout) {
    const auto us = std::max<std::int64_t>(timeout->count(), 0);
    ts.tv_sec = us / 1'000'000;
    ts.tv_nsec = (us % 1'000'000) * 1'000;
    limit = &ts;
  }
  io_uring_cqe* cqe = nullptr;
  const int r = io_uring_submit_and_wait_timeout(&ring_->ring, &cqe, 1, limit, nullptr);
  // -EBADR: completions were lost for want of memory (NODROP's last resort); what remains is
  // taken as it comes, and a request that lost its end is armed again by the next error or by
  // nothing: the sockets' own queues still hold their datagrams.
  if (r == -EBADR) {
    // Completions were lost: the timeout's and the poll's may be among them. Armed anew (a
    // second poll or timeout at worst wakes the loop once more).
    timer_.reset();
    poll_armed_ = false;
    poll_again();
  }
  if (r >= 0 || r == -ETIME || r == -EINTR || r == -EAGAIN || r == -EBUSY || r == -EBADR) {
    submitted();
    return;
  }
  throw std::system_error(-r, std::generic_category(), "io_uring_enter");
}

std::size_t UringReceiver::dispatch(bool& epoll_ready) {
  std::size_t handed = 0;
  ++dispatching_;
  struct Depth {
    int& n;
    ~Depth() { --n; }
  } depth{dispatching_};
  // What is there now only: completions posted meanwhile wait for the next wake-up, so a socket
  // flooding the loop cannot keep it here.
  for (unsigned left = io_uring_cq_ready(&ring_->ring); left > 0; --left) {
    io_uring_cqe* cqe = nullptr;
    if (io_uring_peek_cqe(&ring_->ring, &cqe) != 0 || cqe == nullptr) break;
    const std::uint64_t key = io_uring_cqe_get_data64(cqe);
    const int res = cqe->res;
    const std::uint32_t flags = cqe->flags;
    io_uring_cqe_seen(&ring_->ring, cqe);
    if (key == kCancelKey) continue;
    if (key == kTimerUpdateKey) continue;
    if ((key & ~kTimerGenerations) == kSendTag) {
      // A send the kernel refused (a success posts nothing).
      const auto it = sockets_.find(key & kTimerGenerations);
      if (it != sockets_.end() && it->second->on_send_failed) it->second->on_send_failed(-res);
      continue;
    }
    if ((key & ~kTimerGenerations) == kTimerTag) {
      // The current request ended: expired (-ETIME), or cancelled (its thread exited) or failed.
      // Either way the next set_timer() arms anew; the loop runs its due timers after every
      // wake-up. A removed request is an earlier generation's: its end changes nothing.
      if (key == (kTimerTag | timer_generation_)) timer_.reset();
      continue;
    }
    if (key == kPollKey) {
      poll_armed_ = false;
      epoll_ready = true;
      continue;
    }
    take(key, res, flags, handed);
  }
  return handed;
}

void UringReceiver::take(std::uint64_t key, int res, std::uint32_t flags, std::size_t& handed) {
  const bool more = (flags & IORING_CQE_F_MORE) != 0;
  const auto it = sockets_.find(key);
  if (it == sockets_.end()) {
    // A removed socket's: it goes once its request has ended.
    if (more) return;
    for (const auto& r : retired_) {
      if (r->key != key || !r->armed) continue;
      r->armed = false;
      release(*r);  // deleted by the next wait()
      break;
    }
    return;
  }
  Socket& s = *it->second;
  if (!more) s.armed = false;
  const bool has_buffer = (flags & IORING_CQE_F_BUFFER) != 0;
  const unsigned id = flags >> IORING_CQE_BUFFER_SHIFT;
  // The buffer goes back to the kernel after the callback, also if it throws; a socket removed
  // meanwhile keeps its memory until its request ended (retired_).
  struct GiveBack {
    const Socket* s;
    unsigned id;
    bool give;
    ~GiveBack() {
      if (give) s->give_back(id);
    }
  } give_back{&s, id, has_buffer};
  if (res < 0) {
    // Armed again whatever the end: ENOBUFS (the buffers given back by now), ECANCELED (the
    // thread that submitted it exited, or the kernel ended it), an error reported below. An
    // error that persists comes back at each wake-up, as a level-triggered epoll would report it.
    if (!more) arm(s);
    if (res == -ENOBUFS || res == -ECANCELED) return;
    ReceivedDatagram failed{.msg = nullptr, .length = 0, .error = -res};
    ++handed;
    s.fn(failed);
    return;
  }
  if (!has_buffer) {
    if (!more) arm(s);
    return;
  }
  std::byte* buffer = s.buffer(id);
  io_uring_recvmsg_out* out = io_uring_recvmsg_validate(buffer, res, &s.tmpl);
  if (out == nullptr) {
    if (!more) arm(s);
    ReceivedDatagram failed{.msg = nullptr, .length = 0, .error = EMSGSIZE};
    ++handed;
    s.fn(failed);
    return;
  }
  iovec payload{io_uring_recvmsg_payload(out, &s.tmpl), io_uring_recvmsg_payload_length(out, res, &s.tmpl)};
  msghdr msg{};
  msg.msg_iov = &payload;
  msg.msg_iovlen = 1;
  // The kernel lays the buffer out by what was asked (the template's lengths), whatever it wrote.
  msg.msg_control =
      out->controllen > 0 ? static_cast<void*>(reinterpret_cast<char*>(out + 1) + s.tmpl.msg_namelen) : nullptr;
  msg.msg_controllen = out->controllen;
  msg.msg_flags = static_cast<int>(out->flags);
  if (!more) {
    // A datagram of no bytes ends a SOCK_SEQPACKET stream (its request ends with it); any other
    // end (the kernel may end a multishot request at any time) is armed again.
    if (out->payloadlen == 0) {
      s.ended = true;
    } else {
      arm(s);
    }
  }
  ++handed;
  s.fn(ReceivedDatagram{.msg = &msg, .length = payload.iov_len, .error = 0});
}

}  // namespace oegw::canopen::io
