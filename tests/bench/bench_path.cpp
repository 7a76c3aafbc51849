// oegw_bench_path: the whole SocketCAN-like path of `oegw run`, natively, against the floor.
//
// This kernel has no AF_CAN and the VM tier's guest is emulated (TCG), so neither can judge
// whether `oegw run` is within reach of a minimal forwarder. Here every path runs natively on
// AF_UNIX SOCK_SEQPACKET socketpairs carrying CAN_RAW's struct can_frame
// (canopen/io/seqpacket_transport.hpp), each forwarder in a thread of its own:
//
//  * floor       a blocking read of the grip's TPDO #0 (191h) and a write of its translation,
//                CiA 852 TPDO 1 (1A0h: x, y INTEGER16, deadband and scaling as the gateway's):
//                the least a translator must do;
//  * floor_loop  the same work the way an event loop must do it: epoll_wait, one clock reading,
//                every pending frame in one recvmmsg with its kernel stamp, all answers in one
//                sendmmsg (tests/vm/can_floor.c `loop`, on this transport);
//  * oegw_grip   `oegw run`'s serving (gateway/serve_gateway.hpp: its event loop, receive
//                stamps, timers, batching, the gateway) on tests/fixtures/one_grip.yaml, the
//                elobau grip (node 11h) simulated downstream (subdevices/sim, a thread with its
//                own event loop on the downstream socketpair, the grip's own TPDOs off);
//  * oegw_full   the same on full_fe_set.yaml: 48 simulated sub-devices, their heartbeats and
//                PDOs the background; the grip grip1 feeds joystick.1;
//  * oegw_rec    oegw_grip with the black box on (the mapping file's `record` defaults, into the
//                bench's temporary folder): its CPU counts the writer thread ("oegw-record") too,
//                so oegw_rec/oegw_grip is recording's price on the whole path.
// The control socket and publishing are off, and the black box but in oegw_rec: the CAN path
// alone (as tests/fixtures/vm_syscalls.yaml). The host's part (1800h:01 = 1A0h, 6423h TRUE, NMT start) is
// sent by hand on the upstream socketpair, as vm_latency's cansend does. The sub-devices'
// heartbeat consumer time is 1 s instead of 1.5 x 100 ms: the simulators share the machine, and
// one held off by 50 ms would otherwise be reset as lost; the gateway's fault EMCYs seen during
// the measurements are counted and printed (0: no figure includes a fault).
//
// Latency: the prober sends the grip's TPDO #0 (x alternating 0 and 10..99 %, so every frame
// changes what a translator sends) and waits up to 200 ms for the frame that translates it (x
// checked). The latency is the answer's kernel receive stamp (SO_TIMESTAMPNS: taken when the
// forwarder sent it) minus CLOCK_REALTIME read just before the prober's send, so the prober's
// own wake-up does not count. One frame per period at each rate (1,000 and 8,000 frames/s; a
// sample whose answer is later than a period delays the next), the paths in turn: bursts of 50 ms
// per path, a fresh random order (seeded) each cycle, so a swing of the shared machine falls on
// every path alike; ROUNDS x SAMPLES per path and rate. Each gateway gets a frame at least every
// 100 ms meanwhile (its grip's freshness deadline is 300 ms), answered but not measured.
//
// CPU: each path in turn gets 8,000 frames/s (open loop: the frames due at each wake-up of the
// pacer in one sendmmsg) for CPU_S seconds: the forwarder thread's CPU time
// (pthread_getcpuclockid) per frame sent; then as long again with its system calls counted by
// `perf stat -t TID -e raw_syscalls:sys_enter,...` (the kernel's tracepoints, enabled only for
// that window through perf's control pipe; where perf is missing: "n/a"; --perf-events adds
// events, e.g. context-switches or a uprobe on malloc). user_%: the kernel's split of that CPU
// time (/proc/self/task/TID/stat, clock ticks). Idle: a gateway's CPU per second while it gets
// only the 10 frames/s that keep it fresh (its heartbeats, the full cab's 48 sub-devices), so the
// per-frame figure can be read without it ("net").
//
// --pin: the prober on CPU 0 and every forwarder on CPU 1. Unpinned, the scheduler puts a
// forwarder on the prober's CPU (a hand-over) or the other (a wake-up across CPUs) and keeps it
// there for seconds; in this machine's VM the two differ by ~30 us, so the round medians of one
// path jump between two levels. Pinned, every path is woken across CPUs alike.
//
// Targets reported (never asserted; the machine is shared): oegw median <= 1.1 x the floor's,
// p99 <= 1.2 x, p99.9 <= 1.5 x, CPU per frame <= 1.1 x, <= 3 system calls per frame.
// Exit 0; 1 if a path does not forward (25 misses in a row, or no answer in warm-up) or a cab
// does not boot; 64 for a bad command line.
//
//   oegw_bench_path [--rounds N] [--samples N] [--rates R,R] [--cpu-seconds S] [--cabs grip,full,rec]
//                   [--no-perf] [--perf-events E,E] [--pin] [--seed N] [--verbose]
#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <spawn.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "canopen/io/event_loop.hpp"
#include "canopen/io/seqpacket_transport.hpp"
#include "gateway/daemon_log.hpp"
#include "gateway/serve_gateway.hpp"
#include "rig/cab_rig.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "tests/bench/gateway_rig.hpp"
#include "tests/fixtures/kernel_frame.hpp"

namespace {

using namespace oegw;
using canopen::CanFrame;
using canopen::TimePoint;

constexpr canid_t kGripTpdo0 = 0x191;      // elobau grip node 11h, TPDO #0
constexpr canid_t kJoystickTpdo1 = 0x1A0;  // CiA 852 TPDO 1 of the gateway (node 20h) as the host sets it
constexpr std::uint8_t kGatewayNode = 0x20;
constexpr int kMissesInARow = 25;  // a path that misses this many in a row is left out, and fails the run

// ---- time and frames ----------------------------------------------------------------------

std::int64_t clock_ns(clockid_t id) {
  timespec t{};
  ::clock_gettime(id, &t);
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
}
std::int64_t mono_ns() { return clock_ns(CLOCK_MONOTONIC); }
std::int64_t real_ns() { return clock_ns(CLOCK_REALTIME); }

void sleep_until_ns(std::int64_t t) {
  timespec ts{static_cast<time_t>(t / 1'000'000'000), static_cast<long>(t % 1'000'000'000)};
  while (::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

using oegw::fixtures::kernel_frame;

// The i-th stimulus: the grip's TPDO #0 with x (byte 0, S8 %) alternating 0 and 10..99 %, as
// tests/vm/can_probe.c's, so that every frame changes the translation.
::can_frame stimulus(unsigned i) {
  ::can_frame f = kernel_frame(kGripTpdo0, {0, 0, 0, 0, 0, 0, 0, 0});
  f.data[0] = (i & 1) != 0 ? static_cast<std::uint8_t>(10 + (i / 2) % 90) : 0;
  return f;
}

// The joystick axis a grip percentage becomes: deadband 2 % (one_grip.yaml), 100 % = 32767
// (mapping/translate.cpp: llround(v * scale)).
std::int16_t joystick_axis(std::int8_t percent) {
  if (percent >= -2 && percent <= 2) return 0;
  const long v = std::lround(percent * (32767.0 / 100.0));
  return static_cast<std::int16_t>(std::clamp<long>(v, -32767, 32767));
}

bool is_answer(const ::can_frame& got, const ::can_frame& sent) {
  if (got.can_id != kJoystickTpdo1 || got.len != 8) return false;
  const auto x = static_cast<std::int16_t>(got.data[0] | (got.data[1] << 8));
  return x == joystick_axis(static_cast<std::int8_t>(sent.data[0]));
}

// The floors' translation: TPDO 1 with x and y (bytes 0-3), the rest 0.
::can_frame translate(const ::can_frame& in) {
  ::can_frame out = kernel_frame(kJoystickTpdo1, {0, 0, 0, 0, 0, 0, 0, 0});
  const std::int16_t x = joystick_axis(static_cast<std::int8_t>(in.data[0]));
  const std::int16_t y = joystick_axis(static_cast<std::int8_t>(in.data[1]));
  out.data[0] = static_cast<std::uint8_t>(x & 0xFF);
  out.data[1] = static_cast<std::uint8_t>((x >> 8) & 0xFF);
  out.data[2] = static_cast<std::uint8_t>(y & 0xFF);
  out.data[3] = static_cast<std::uint8_t>((y >> 8) & 0xFF);
  return out;
}

void set_timestamps(int fd) {
  const int on = 1;
  if (::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) != 0)
    throw std::runtime_error(std::string("setsockopt(SO_TIMESTAMPNS): ") + std::strerror(errno));
}

// One frame from `fd` with its kernel stamp (ns, CLOCK_REALTIME; 0 without one), waiting up to
// timeout_ms: 1 got one, 0 timeout, -1 error or end of stream.
int recv_stamped(int fd, ::can_frame& f, std::int64_t& stamp, int timeout_ms) {
  pollfd p{fd, POLLIN, 0};
  const int r = ::poll(&p, 1, timeout_ms);
  if (r <= 0) return r < 0 && errno == EINTR ? 0 : r;
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timespec))];
  iovec iov{&f, sizeof f};
  msghdr m{};
  m.msg_iov = &iov;
  m.msg_iovlen = 1;
  m.msg_control = control;
  m.msg_controllen = sizeof control;
  const ssize_t n = ::recvmsg(fd, &m, MSG_DONTWAIT);
  if (n < 0) return errno == EAGAIN || errno == EINTR ? 0 : -1;
  if (n != static_cast<ssize_t>(sizeof f)) return -1;  // the end of the stream, or not a frame
  stamp = 0;
  for (cmsghdr* c = CMSG_FIRSTHDR(&m); c != nullptr; c = CMSG_NXTHDR(&m, c)) {
    if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS) {
      timespec t;
      std::memcpy(&t, CMSG_DATA(c), sizeof t);
      stamp = static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
    }
  }
  return 1;
}

constexpr canid_t kGatewayEmcy = 0x80 + kGatewayNode;

// An EMCY of the gateway with an error (not the 0000h of a fault cleared): a sub-device's fault,
// which puts its inputs at fault values: a run with one measured a fault, not the path.
bool is_fault_emcy(const ::can_frame& f) {
  return f.can_id == kGatewayEmcy && f.len >= 2 && (f.data[0] != 0 || f.data[1] != 0);
}

// Reads and drops what is queued on `fd`; returns how many frames with CAN-ID `count_id`; the
// gateway's fault EMCYs among them counted in *faults.
std::uint64_t drain(int fd, canid_t count_id = kJoystickTpdo1, std::uint64_t* faults = nullptr) {
  std::uint64_t n = 0;
  ::can_frame f[64];
  mmsghdr h[64];
  iovec iov[64];
  for (;;) {
    for (int i = 0; i < 64; ++i) {
      iov[i] = iovec{&f[i], sizeof f[i]};
      h[i] = mmsghdr{};
      h[i].msg_hdr.msg_iov = &iov[i];
      h[i].msg_hdr.msg_iovlen = 1;
    }
    const int r = ::recvmmsg(fd, h, 64, MSG_DONTWAIT, nullptr);
    if (r <= 0) return n;
    for (int i = 0; i < r; ++i) {
      if (h[i].msg_len != sizeof(::can_frame)) continue;
      if (f[i].can_id == count_id) ++n;
      if (faults != nullptr && is_fault_emcy(f[i])) ++*faults;
    }
    if (r < 64) return n;
  }
}

pid_t this_tid() { return static_cast<pid_t>(::gettid()); }

// ---- the floors ---------------------------------------------------------------------------

// A blocking read and a write per frame, nothing else; ends when the stimulus end closes.
void floor_blocking(int in, int out) {
  ::can_frame f;
  for (;;) {
    if (::read(in, &f, sizeof f) != static_cast<ssize_t>(sizeof f)) return;
    if (f.can_id != kGripTpdo0) continue;
    const ::can_frame o = translate(f);
    if (::write(out, &o, sizeof o) != static_cast<ssize_t>(sizeof o)) return;
  }
}

// The floor as an event loop: epoll_wait, a clock reading, one recvmmsg (kernel stamps in the
// control data, read as oegw's transport reads them), one sendmmsg.
void floor_loop(int in, int out) {
  constexpr int kBatch = 64;
  const int ep = ::epoll_create1(EPOLL_CLOEXEC);
  epoll_event ev{};
  ev.events = EPOLLIN;
  if (ep < 0 || ::epoll_ctl(ep, EPOLL_CTL_ADD, in, &ev) != 0) {
    std::fprintf(stderr, "floor_loop: epoll: %s\n", std::strerror(errno));
    return;
  }
  static thread_local ::can_frame frames[kBatch], answers[kBatch];
  static thread_local iovec iov[kBatch], out_iov[kBatch];
  static thread_local mmsghdr msgs[kBatch], out_msgs[kBatch];
  alignas(cmsghdr) static thread_local char control[kBatch][CMSG_SPACE(sizeof(timespec))];
  for (;;) {
    epoll_event events[8];
    if (::epoll_wait(ep, events, 8, -1) < 0) continue;
    volatile std::int64_t now = mono_ns();
    (void)now;
    for (int i = 0; i < kBatch; ++i) {
      iov[i] = iovec{&frames[i], sizeof frames[i]};
      msgs[i] = mmsghdr{};
      msgs[i].msg_hdr.msg_iov = &iov[i];
      msgs[i].msg_hdr.msg_iovlen = 1;
      msgs[i].msg_hdr.msg_control = control[i];
      msgs[i].msg_hdr.msg_controllen = sizeof control[i];
    }
    const int n = ::recvmmsg(in, msgs, kBatch, MSG_DONTWAIT, nullptr);
    if (n == 0) break;  // end of stream
    if (n < 0) continue;
    int k = 0;
    bool ended = false;
    for (int i = 0; i < n; ++i) {
      if (msgs[i].msg_len == 0) {
        ended = true;
        break;
      }
      std::int64_t stamp = 0;
      for (cmsghdr* c = CMSG_FIRSTHDR(&msgs[i].msg_hdr); c != nullptr; c = CMSG_NXTHDR(&msgs[i].msg_hdr, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS) {
          timespec t;
          std::memcpy(&t, CMSG_DATA(c), sizeof t);
          stamp = static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
        }
      }
      (void)stamp;
      if (msgs[i].msg_len != sizeof(::can_frame) || frames[i].can_id != kGripTpdo0) continue;
      answers[k] = translate(frames[i]);
      out_iov[k] = iovec{&answers[k], sizeof answers[k]};
      out_msgs[k] = mmsghdr{};
      out_msgs[k].msg_hdr.msg_iov = &out_iov[k];
      out_msgs[k].msg_hdr.msg_iovlen = 1;
      ++k;
    }
    if (k > 0 && ::sendmmsg(out, out_msgs, static_cast<unsigned>(k), 0) != k) break;
    if (ended) break;
  }
  ::close(ep);
}

// ---- one path: how the prober reaches a forwarder -------------------------------------------

struct Path {
  std::string name;
  bool gateway = false;  // needs frames to stay fresh; measured against the floors
  int tx = -1;           // the prober writes stimuli here
  int rx = -1;           // and reads the translations here (SO_TIMESTAMPNS)
  std::atomic<pid_t> tid{0};
  pthread_t thread{};
  bool has_thread = false;
  unsigned i = 0;              // its stimulus count
  std::int64_t last_sent = 0;  // mono ns
  bool dead = false;
  int misses_in_a_row = 0;
  // per rate: latencies (us), misses, per-round medians, achieved rate
  struct RateResult {
    std::vector<double> lat;
    std::vector<double> round_medians;
    std::uint64_t missed = 0;
    double busy_s = 0;
  };
  std::map<int, RateResult> by_rate;
  // CPU windows at the full rate
  double cpu_ns = 0, idle_cpu_ns = 0, idle_s = 0;
  std::uint64_t user_ticks = 0, system_ticks = 0;  // the kernel's split of the CPU windows
  std::uint64_t cpu_frames = 0, cpu_answers = 0, perf_frames = 0;
  std::map<std::string, std::uint64_t> syscalls;  // perf event -> count over its windows
  bool perf_ok = false;
  std::string perf_note;
  std::uint64_t faults = 0;  // the gateway's fault EMCYs seen (is_fault_emcy)
  // A thread of the process whose CPU time is the path's too (its name, /proc/self/task/*/comm):
  // the black box's writer ("oegw-record") for the cab that records.
  std::string helper_thread;
};

// Never blocks: a forwarder that stops reading must not stop the prober (the blocking floor
// would otherwise wait on the prober's reading while the prober waits on its).
bool send_frame(int fd, const ::can_frame& f) {
  return ::send(fd, &f, sizeof f, MSG_NOSIGNAL | MSG_DONTWAIT) == static_cast<ssize_t>(sizeof f);
}

// Waits for the translation of `sent` on p.rx; its stamp in *stamp.
bool wait_answer(Path& p, const ::can_frame& sent, std::int64_t& stamp, int timeout_ms) {
  const std::int64_t end = mono_ns() + static_cast<std::int64_t>(timeout_ms) * 1'000'000;
  for (;;) {
    const int left = static_cast<int>((end - mono_ns()) / 1'000'000);
    if (left < 0) return false;
    ::can_frame got;
    const int r = recv_stamped(p.rx, got, stamp, left);
    if (r < 0) return false;
    if (r == 1 && is_fault_emcy(got)) ++p.faults;
    if (r == 1 && is_answer(got, sent)) return true;
  }
}

// One sample: the stimulus, its answer; the latency in us, or nullopt (missed).
std::optional<double> sample(Path& p, int timeout_ms = 200) {
  (void)drain(p.rx, kJoystickTpdo1, &p.faults);
  const ::can_frame sent = stimulus(p.i++);
  const std::int64_t t0 = real_ns();
  if (!send_frame(p.tx, sent)) return std::nullopt;
  p.last_sent = mono_ns();
  std::int64_t stamp = 0;
  if (!wait_answer(p, sent, stamp, timeout_ms)) {
    if (++p.misses_in_a_row >= kMissesInARow) p.dead = true;
    return std::nullopt;
  }
  p.misses_in_a_row = 0;
  if (stamp == 0) stamp = real_ns();  // no kernel stamp: the time it was read
  return static_cast<double>(stamp - t0) / 1000.0;
}

// Every gateway path but `except` that got nothing for 100 ms gets a frame, and what it sent
// upstream meanwhile is read and dropped: the grip's freshness deadline (300 ms) never fires
// because of the bench, and the upstream queue never fills while another path is measured.
void keep_fresh(std::vector<Path*>& paths, const Path* except) {
  const std::int64_t now = mono_ns();
  for (Path* p : paths) {
    if (p == except || !p->gateway || p->dead || now - p->last_sent < 100'000'000) continue;
    (void)drain(p->rx, kJoystickTpdo1, &p->faults);
    if (send_frame(p->tx, stimulus(p->i++))) p->last_sent = now;
  }
}

// Until five answers in a row, a frame every 20 ms; false after `seconds`.
bool warm_up(Path& p, double seconds) {
  const std::int64_t end = mono_ns() + static_cast<std::int64_t>(seconds * 1e9);
  for (int run = 0; run < 5;) {
    if (mono_ns() > end) return false;
    run = sample(p, 20).has_value() ? run + 1 : 0;
  }
  p.misses_in_a_row = 0;
  p.dead = false;
  return true;
}

// ---- a forwarder's thread CPU and system calls ----------------------------------------------

// A thread's user and system time as the kernel splits it (/proc/self/task/TID/stat utime,
// stime: clock ticks, so only a long window tells them apart).
std::pair<std::uint64_t, std::uint64_t> thread_user_system_ticks(pid_t tid) {
  std::ifstream in("/proc/self/task/" + std::to_string(tid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto close = text.rfind(')');  // the command name may hold spaces
  if (close == std::string::npos) return {0, 0};
  std::stringstream rest(text.substr(close + 2));
  std::string field;
  std::uint64_t utime = 0, stime = 0;
  for (int i = 3; rest >> field; ++i) {  // field 3 is the state
    if (i == 14) utime = std::strtoull(field.c_str(), nullptr, 10);
    if (i == 15) {
      stime = std::strtoull(field.c_str(), nullptr, 10);
      break;
    }
  }
  return {utime, stime};
}

std::int64_t thread_cpu_ns(pthread_t t) {
  clockid_t id;
  if (::pthread_getcpuclockid(t, &id) != 0) return 0;
  return clock_ns(id);
}

// The CPU time of every thread of this process named `comm`: the kernel's per-thread CPU clock
// of a thread id, as glibc's pthread_getcpuclockid makes it for its own threads
// (MAKE_THREAD_CPUCLOCK(tid, CPUCLOCK_SCHED): ~tid << 3 | 4 | 2).
std::int64_t named_threads_cpu_ns(const std::string& comm) {
  std::int64_t sum = 0;
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator("/proc/self/task", ec)) {
    std::ifstream f(e.path() / "comm");
    std::string name;
    if (!std::getline(f, name) || name != comm) continue;
    const auto tid = static_cast<clockid_t>(std::strtol(e.path().filename().c_str(), nullptr, 10));
    sum += clock_ns(static_cast<clockid_t>((~tid) * 8) | 6);
  }
  return sum;
}

// The path's CPU time: its forwarder thread and its helper thread, if it has one.
std::int64_t path_cpu_ns(const Path& p) {
  return thread_cpu_ns(p.thread) + (p.helper_thread.empty() ? 0 : named_threads_cpu_ns(p.helper_thread));
}

// `perf stat -t TID` on the kernel's system call tracepoints, counting only between enable() and
// disable() (perf's --control pipe, each command acknowledged), so what is counted is exactly a
// window of the bench's choosing.
class SyscallCounter {
 public:
  static constexpr const char* kEvents[] = {"raw_syscalls:sys_enter",         "syscalls:sys_enter_epoll_wait",
                                            "syscalls:sys_enter_epoll_pwait", "syscalls:sys_enter_recvmmsg",
                                            "syscalls:sys_enter_sendmmsg",    "syscalls:sys_enter_read",
                                            "syscalls:sys_enter_write",       "syscalls:sys_enter_timerfd_settime",
                                            "syscalls:sys_enter_recvmsg",     "syscalls:sys_enter_sendto",
                                            "syscalls:sys_enter_recvfrom"};

  // nullptr with `why` when perf cannot be started.
  // `extra`: more perf events to count in the same windows (--perf-events), e.g. context-switches
  // or a uprobe on malloc (`perf probe -x libc.so.6 --add malloc` first: probe_libc:malloc).
  static std::unique_ptr<SyscallCounter> attach(pid_t tid, const std::string& out_file, const std::string& extra,
                                                std::string& why) {
    // Both pipes close-on-exec but for perf's ends, which it is handed open (the bench spawns
    // from this thread only).
    int ctl[2], ack[2];
    if (::pipe2(ctl, O_CLOEXEC) != 0 || ::pipe2(ack, O_CLOEXEC) != 0) {
      why = "pipe failed";
      return nullptr;
    }
    ::fcntl(ctl[0], F_SETFD, 0);
    ::fcntl(ack[1], F_SETFD, 0);
    std::string events;
    for (const char* e : kEvents) events += (events.empty() ? "" : ",") + std::string(e);
    if (!extra.empty()) events += "," + extra;
    const std::string control = "fd:" + std::to_string(ctl[0]) + "," + std::to_string(ack[1]);
    const std::string tid_s = std::to_string(tid);
    std::vector<std::string> args{"perf", "stat", "-x", ",",         "-e",    events, "-t",
                                  tid_s,  "-D",   "-1", "--control", control, "-o",   out_file};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&fa, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
    pid_t pid = -1;
    const int r = ::posix_spawnp(&pid, "perf", &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    ::close(ctl[0]);
    ::close(ack[1]);
    if (r != 0) {
      ::close(ctl[1]);
      ::close(ack[0]);
      why = std::string("perf: ") + std::strerror(r);
      return nullptr;
    }
    std::unique_ptr<SyscallCounter> c(new SyscallCounter(pid, ctl[1], ack[0], out_file));
    // The first command answered: perf is attached and listening.
    if (!c->command("disable")) {
      why = "perf stat did not start (no tracepoints? see perf_event_paranoid)";
      return nullptr;
    }
    return c;
  }
  ~SyscallCounter() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
    if (ctl_ >= 0) ::close(ctl_);
    if (ack_ >= 0) ::close(ack_);
  }
  bool enable() { return command("enable"); }
  bool disable() { return command("disable"); }
  // Stops perf and reads its counts (event -> count); empty when it wrote none.
  std::map<std::string, std::uint64_t> finish() {
    std::map<std::string, std::uint64_t> counts;
    ::kill(pid_, SIGINT);
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
    std::ifstream in(out_file_);
    std::string line;
    while (std::getline(in, line)) {
      if (line.empty() || line[0] == '#') continue;
      std::vector<std::string> fields;
      std::stringstream ss(line);
      for (std::string f; std::getline(ss, f, ',');) fields.push_back(f);
      if (fields.size() < 3 || fields[0].empty() || fields[0][0] == '<') continue;
      counts[fields[2]] = std::strtoull(fields[0].c_str(), nullptr, 10);
    }
    std::filesystem::remove(out_file_);
    return counts;
  }

 private:
  SyscallCounter(pid_t pid, int ctl, int ack, std::string out)
      : pid_(pid), ctl_(ctl), ack_(ack), out_file_(std::move(out)) {}
  bool command(const char* what) {
    const std::string line = std::string(what) + "\n";
    if (::write(ctl_, line.data(), line.size()) != static_cast<ssize_t>(line.size())) return false;
    pollfd p{ack_, POLLIN, 0};
    if (::poll(&p, 1, 10'000) != 1) return false;
    char buf[16];
    return ::read(ack_, buf, sizeof buf) > 0;
  }
  pid_t pid_;
  int ctl_, ack_;
  std::string out_file_;
};

// ---- a cab: `oegw run`'s serving and the simulators, each a thread ----------------------------

class Cab {
 public:
  // `record`: the black box on, into that folder (the mapping file's record section's defaults).
  Cab(std::string name, mapping::Config config, const std::filesystem::path& store,
      const std::filesystem::path& record = {})
      : name_(std::move(name)), config_(std::move(config)) {
    config_.upstream.store = store.string();
    config_.control.enabled = false;  // the CAN path alone (tests/fixtures/vm_syscalls.yaml)
    config_.record.enabled = !record.empty();
    if (!record.empty()) config_.record.dir = record.string();
    config_.publish.dds.enabled = false;
    config_.publish.lcm.enabled = false;
    // The simulators share this machine with the paths measured: a heartbeat held off by more
    // than 50 ms (the consumer time 1.5 x 100 ms) would be taken for a lost device, reset and
    // booted again, its inputs at fault values meanwhile (seen at load average 6 here). 1 s
    // keeps the bench measuring the path rather than the simulators' scheduling.
    for (auto& sub : config_.subdevices)
      if (sub.heartbeat_ms != 0) sub.heartbeat_timeout_ms = std::max<std::uint16_t>(sub.heartbeat_timeout_ms, 1000);
    grip_ = config_.functional_elements.front().fields.front().subdevice;
    devices_config_ = config_;  // the simulators' thread reads its own copy
    int up[2], down[2];
    canopen::io::SeqpacketCanTransport::make_socketpair(up);
    canopen::io::SeqpacketCanTransport::make_socketpair(down);
    gw_up_ = canopen::io::SeqpacketCanTransport::adopt(up[0]);
    gw_down_ = canopen::io::SeqpacketCanTransport::adopt(down[0]);
    devices_ = canopen::io::SeqpacketCanTransport::adopt(down[1]);
    host_ = up[1];  // the prober's: blocking, stamped
    set_timestamps(host_);
    stimuli_ = ::dup(down[1]);  // the prober's stimuli go where the devices' frames go
    stop_devices_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  }
  ~Cab() {
    stop();
    for (int fd : {host_, stimuli_, stop_devices_})
      if (fd >= 0) ::close(fd);
  }

  void start() {
    gateway_ = std::thread([this] {
      tid_ = this_tid();
      canopen::io::EventLoop loop;
      loop.handle_signals({SIGINT, SIGTERM, SIGHUP, SIGUSR1});
      serving_ = true;
      try {
        exit_status_ =
            gateway::serve_gateway(name_ + ".yaml", config_, loop, gateway::GatewayBuses{*gw_up_, *gw_down_});
      } catch (const std::exception& e) {
        std::fprintf(stderr, "%s: serve_gateway: %s\n", name_.c_str(), e.what());
        exit_status_ = 1;
      }
      serving_ = false;
    });
    devices_thread_ = std::thread([this] {
      try {
        run_devices();
      } catch (const std::exception& e) {  // e.g. a simulator that cannot be built: the cab never gets ready
        std::fprintf(stderr, "%s: simulators: %s\n", name_.c_str(), e.what());
      }
    });
  }

  void stop() {
    if (gateway_.joinable()) {
      // serve_gateway's own stop: SIGTERM through its loop's signalfd (this thread's, directed).
      while (!serving_ && exit_status_ < 0) std::this_thread::yield();
      if (exit_status_ < 0) ::pthread_kill(gateway_.native_handle(), SIGTERM);
      gateway_.join();
    }
    if (devices_thread_.joinable()) {
      const std::uint64_t one = 1;
      (void)!::write(stop_devices_, &one, sizeof one);
      devices_thread_.join();
    }
  }

  // The host's part, by hand (vm_latency's cansend): TPDO 1 on 1A0h, 6423h TRUE, NMT start.
  bool configure_host(std::string& why) {
    if (!sdo_download(0x1800, 1, {0xA0, 0x01, 0x00, 0x00}, why)) return false;
    if (!sdo_download(0x6423, 0, {0x01}, why)) return false;
    return send_frame(host_, kernel_frame(0x000, {0x01, kGatewayNode}));
  }

  [[nodiscard]] bool devices_operational() const { return operational_; }
  [[nodiscard]] int device_count() const { return device_count_; }
  [[nodiscard]] int exit_status() const { return exit_status_; }
  [[nodiscard]] const std::string& name() const { return name_; }
  [[nodiscard]] bool records() const { return config_.record.enabled; }
  [[nodiscard]] int host_fd() const { return host_; }
  [[nodiscard]] int stimuli_fd() const { return stimuli_; }
  [[nodiscard]] pid_t gateway_tid() const { return tid_; }
  [[nodiscard]] pthread_t gateway_thread() { return gateway_.native_handle(); }

 private:
  // The sub-devices of the mapping file simulated (rig/cab_rig.hpp add_cab_simulators) on
  // their own loop, the grip's TPDOs off (the prober sends them: vm_latency's `grip pdo off`).
  // Their heartbeats say when every one is operational.
  void run_devices() {
    canopen::io::EventLoop loop;
    std::map<std::uint32_t, std::uint8_t> states;
    subdevices::sim::SimBench bench([&](const CanFrame& f) {
      if (!f.extended && f.id > 0x700 && f.id <= 0x77F && f.dlc == 1) {
        states[f.id] = f.data[0] & 0x7F;
        const bool all = static_cast<int>(states.size()) == device_count_ &&
                         std::all_of(states.begin(), states.end(), [](const auto& s) { return s.second == 0x05; });
        operational_ = all;
      }
      (void)devices_->send(f);
    });
    oegw::rig::add_cab_simulators(bench, devices_config_);
    device_count_ = static_cast<int>(bench.size());
    canopen::io::ServiceDriver driver(loop, bench);
    devices_->set_receiver([&](const CanFrame& f, TimePoint t) {
      bench.on_frame(f, t);
      driver.rearm();
    });
    const auto watch = canopen::io::watch_transport(loop, *devices_);
    loop.watch(stop_devices_, canopen::io::events::kReadable, [&](std::uint32_t) { loop.stop(); });
    bench.start(loop.now());
    const std::string reply = bench.command(grip_ + " pdo off", loop.now());
    if (reply.rfind("ok", 0) != 0)
      std::fprintf(stderr, "%s: '%s pdo off': %s\n", name_.c_str(), grip_.c_str(), reply.c_str());
    driver.rearm();
    loop.run();
    loop.unwatch(watch);
    devices_->set_receiver({});
  }

  // An expedited SDO download to the gateway (CiA 301 §7.2.4.3.3), answered within 1 s; three tries.
  bool sdo_download(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data, std::string& why) {
    const auto n = static_cast<std::uint8_t>(data.size());
    ::can_frame req = kernel_frame(0x600 + kGatewayNode, {0, 0, 0, 0, 0, 0, 0, 0});
    req.data[0] = static_cast<std::uint8_t>(0x23 | ((4 - n) << 2));
    req.data[1] = static_cast<std::uint8_t>(index & 0xFF);
    req.data[2] = static_cast<std::uint8_t>(index >> 8);
    req.data[3] = sub;
    std::copy(data.begin(), data.end(), req.data + 4);
    for (int attempt = 0; attempt < 3; ++attempt) {
      if (!send_frame(host_, req)) break;
      const std::int64_t end = mono_ns() + 1'000'000'000;
      while (mono_ns() < end) {
        ::can_frame got;
        std::int64_t stamp;
        if (recv_stamped(host_, got, stamp, 100) != 1 || got.can_id != 0x580u + kGatewayNode) continue;
        if (got.data[1] != req.data[1] || got.data[2] != req.data[2] || got.data[3] != sub) continue;
        if (got.data[0] == 0x60) return true;
        char text[96];
        std::snprintf(text, sizeof text, "SDO download %04Xh:%02X aborted %02X%02X%02X%02Xh", index, sub, got.data[7],
                      got.data[6], got.data[5], got.data[4]);
        why = text;
        return false;
      }
    }
    char text[64];
    std::snprintf(text, sizeof text, "SDO download %04Xh:%02X not answered", index, sub);
    why = text;
    return false;
  }

  std::string name_;
  mapping::Config config_;  // the gateway thread's
  mapping::Config devices_config_;
  std::string grip_;
  std::unique_ptr<canopen::io::SeqpacketCanTransport> gw_up_, gw_down_, devices_;
  int host_ = -1, stimuli_ = -1, stop_devices_ = -1;
  std::thread gateway_, devices_thread_;
  std::atomic<pid_t> tid_{0};
  std::atomic<bool> serving_{false};
  std::atomic<int> exit_status_{-1};
  std::atomic<bool> operational_{false};
  std::atomic<int> device_count_{-1};
};

// ---- figures ------------------------------------------------------------------------------

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const auto k = static_cast<std::size_t>(std::ceil(p / 100.0 * static_cast<double>(v.size())));
  return v[std::min(v.size() - 1, k == 0 ? 0 : k - 1)];
}

std::string load_average() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  in >> a >> b >> c;
  return a + " " + b + " " + c;
}

struct Options {
  int rounds = 4;
  int samples = 2000;
  std::vector<int> rates{1000, 8000};
  double cpu_seconds = 1.0;
  bool grip = true, full = true, rec = true;
  bool perf = true;
  bool pin = false;         // the prober on CPU 0, every forwarder on CPU 1
  std::string perf_events;  // more events for the perf windows, printed per frame
  unsigned seed = 1;
  bool verbose = false;
};

std::vector<int> parse_list(const char* text) {
  std::vector<int> out;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) out.push_back(std::atoi(item.c_str()));
  return out;
}

// The latency phase at `rate` (see the top of this file).
void measure_latency(std::vector<Path*>& paths, int rate, const Options& o, std::mt19937& rng) {
  const std::int64_t period = 1'000'000'000 / rate;
  const int burst = std::max(1, rate / 20);  // 50 ms
  // A gateway left without frames meanwhile (another cab's boot) holds its joystick at the error
  // value until x passes neutral again: answered again before it is measured.
  for (Path* p : paths)
    if (!p->dead && !warm_up(*p, 5)) p->dead = true;
  for (int round = 0; round < o.rounds; ++round) {
    std::map<Path*, int> left;
    std::map<Path*, std::vector<double>> this_round;
    for (Path* p : paths)
      if (!p->dead) left[p] = o.samples;
    for (;;) {
      std::vector<Path*> order;
      for (auto& [p, n] : left)
        if (n > 0 && !p->dead) order.push_back(p);
      if (order.empty()) break;
      std::shuffle(order.begin(), order.end(), rng);
      for (Path* p : order) {
        keep_fresh(paths, p);
        auto& r = p->by_rate[rate];
        const int n = std::min(burst, left[p]);
        std::int64_t next = mono_ns();
        const std::int64_t begun = next;
        for (int k = 0; k < n && !p->dead; ++k) {
          keep_fresh(paths, p);
          sleep_until_ns(next);
          const std::int64_t sent_at = mono_ns();
          if (const auto us = sample(*p)) {
            r.lat.push_back(*us);
            this_round[p].push_back(*us);
          } else {
            ++r.missed;
          }
          next = std::max(sent_at + period, next + period);
        }
        r.busy_s += static_cast<double>(mono_ns() - begun) / 1e9;
        left[p] -= n;
      }
    }
    for (auto& [p, v] : this_round) p->by_rate[rate].round_medians.push_back(percentile(v, 50));
  }
}

// Open loop at `rate` to `p` for `seconds`: the frames due at each wake-up in one sendmmsg, the
// answers drained meanwhile. Returns the frames sent; answers counted into *answers.
std::uint64_t pace(std::vector<Path*>& paths, Path& p, int rate, double seconds, std::uint64_t& answers) {
  const std::int64_t period = 1'000'000'000 / rate;
  const std::int64_t start = mono_ns();
  const std::int64_t end = start + static_cast<std::int64_t>(seconds * 1e9);
  std::uint64_t sent = 0;
  ::can_frame f[256];
  mmsghdr h[256];
  iovec iov[256];
  for (std::int64_t now = start; now < end; now = mono_ns()) {
    const auto due = static_cast<std::uint64_t>((now - start) / period + 1);
    int n = 0;
    while (sent + static_cast<std::uint64_t>(n) < due && n < 256) {
      f[n] = stimulus(p.i + static_cast<unsigned>(n));
      iov[n] = iovec{&f[n], sizeof f[n]};
      h[n] = mmsghdr{};
      h[n].msg_hdr.msg_iov = &iov[n];
      h[n].msg_hdr.msg_iovlen = 1;
      ++n;
    }
    if (n > 0) {
      // What the forwarder's queue cannot take now is sent at the next wake-up (the numbering
      // follows what was sent, so every frame sent still changes x).
      const int r = ::sendmmsg(p.tx, h, static_cast<unsigned>(n), MSG_NOSIGNAL | MSG_DONTWAIT);
      if (r > 0) {
        sent += static_cast<std::uint64_t>(r);
        p.i += static_cast<unsigned>(r);
      }
      p.last_sent = now;
    }
    answers += drain(p.rx, kJoystickTpdo1, &p.faults);
    keep_fresh(paths, &p);
    sleep_until_ns(
        std::max(start + static_cast<std::int64_t>(sent) * period, mono_ns() + (n > 0 && sent < due ? period : 0)));
  }
  sleep_until_ns(mono_ns() + 20'000'000);  // the last answers
  answers += drain(p.rx, kJoystickTpdo1, &p.faults);
  return sent;
}

void measure_cpu(std::vector<Path*>& paths, const Options& o, std::mt19937& rng) {
  constexpr int kRate = 8000;
  std::map<Path*, std::unique_ptr<SyscallCounter>> perf;
  if (o.perf) {
    for (Path* p : paths) {
      if (p->dead) continue;
      std::string why;
      perf[p] = SyscallCounter::attach(p->tid, "/tmp/oegw_bench_path." + std::to_string(::getpid()) + "." + p->name,
                                       o.perf_events, why);
      if (!perf[p]) p->perf_note = why;
      keep_fresh(paths, nullptr);  // perf takes a while to start
    }
  }
  for (int round = 0; round < o.rounds; ++round) {
    std::vector<Path*> order;
    for (Path* p : paths)
      if (!p->dead) order.push_back(p);
    std::shuffle(order.begin(), order.end(), rng);
    for (Path* p : order) {
      if (!warm_up(*p, 5)) {
        p->dead = true;
        continue;
      }
      // Idle: only what keeps the gateways fresh (this one included: 10 frames/s).
      const std::int64_t idle_from = mono_ns();
      const std::int64_t idle_cpu = path_cpu_ns(*p);
      while (mono_ns() - idle_from < static_cast<std::int64_t>(o.cpu_seconds * 0.5e9)) {
        keep_fresh(paths, nullptr);
        (void)drain(p->rx);
        sleep_until_ns(mono_ns() + 10'000'000);
      }
      p->idle_cpu_ns += static_cast<double>(path_cpu_ns(*p) - idle_cpu);
      p->idle_s += static_cast<double>(mono_ns() - idle_from) / 1e9;
      // CPU at the full rate.
      std::uint64_t answers = 0;
      const auto ticks0 = thread_user_system_ticks(p->tid);
      const std::int64_t cpu0 = path_cpu_ns(*p);
      const std::uint64_t frames = pace(paths, *p, kRate, o.cpu_seconds, answers);
      p->cpu_ns += static_cast<double>(path_cpu_ns(*p) - cpu0);
      const auto ticks1 = thread_user_system_ticks(p->tid);
      p->user_ticks += ticks1.first - ticks0.first;
      p->system_ticks += ticks1.second - ticks0.second;
      p->cpu_frames += frames;
      p->cpu_answers += answers;
      // System calls at the full rate, perf counting.
      if (auto it = perf.find(p); it != perf.end() && it->second) {
        std::uint64_t a = 0;
        if (it->second->enable()) {
          p->perf_frames += pace(paths, *p, kRate, o.cpu_seconds, a);
          (void)it->second->disable();
        }
      }
    }
  }
  for (auto& [p, c] : perf) {
    if (!c) continue;
    p->syscalls = c->finish();
    p->perf_ok = p->syscalls.contains("raw_syscalls:sys_enter") && p->perf_frames > 0;
    if (!p->perf_ok && p->perf_note.empty()) p->perf_note = "perf counted nothing";
  }
}

void print_latency(const std::vector<Path*>& paths, int rate, const Options& o) {
  std::printf("\nlatency at %d frames/s (%d rounds x %d samples per path; in turn, bursts of %d), us:\n", rate,
              o.rounds, o.samples, std::max(1, rate / 20));
  std::printf("  %-11s %7s %5s %8s %8s %8s %8s %9s  %s\n", "path", "samples", "miss", "rate/s", "median", "p99",
              "p99.9", "worst", "round medians");
  std::map<std::string, const Path::RateResult*> r;
  for (const Path* p : paths) {
    const auto it = p->by_rate.find(rate);
    if (it == p->by_rate.end()) continue;
    const auto& x = it->second;
    r[p->name] = &x;
    std::string rounds;
    for (double m : x.round_medians) rounds += fmt::format(" {:.1f}", m);
    const double achieved = x.busy_s > 0 ? static_cast<double>(x.lat.size() + x.missed) / x.busy_s : 0;
    std::printf("  %-11s %7zu %5llu %8.0f %8.1f %8.1f %8.1f %9.1f %s\n", p->name.c_str(), x.lat.size(),
                static_cast<unsigned long long>(x.missed), achieved, percentile(x.lat, 50), percentile(x.lat, 99),
                percentile(x.lat, 99.9), x.lat.empty() ? NAN : *std::max_element(x.lat.begin(), x.lat.end()),
                rounds.c_str());
  }
  for (const char* g : {"oegw_grip", "oegw_full"}) {
    if (!r.contains(g)) continue;
    for (const char* f : {"floor", "floor_loop"}) {
      if (!r.contains(f)) continue;
      const auto& a = r[g]->lat;
      const auto& b = r[f]->lat;
      const double m = percentile(a, 50) / percentile(b, 50), p99 = percentile(a, 99) / percentile(b, 99),
                   p999 = percentile(a, 99.9) / percentile(b, 99.9);
      std::printf("  %s/%s: median %.2f (target <= 1.1: %s), p99 %.2f (<= 1.2: %s), p99.9 %.2f (<= 1.5: %s)\n", g, f, m,
                  m <= 1.1 ? "met" : "NOT met", p99, p99 <= 1.2 ? "met" : "NOT met", p999,
                  p999 <= 1.5 ? "met" : "NOT met");
    }
  }
  // The black box's price on the path: the same cab recording and not.
  if (r.contains("oegw_rec") && r.contains("oegw_grip")) {
    const auto& a = r["oegw_rec"]->lat;
    const auto& b = r["oegw_grip"]->lat;
    std::printf("  oegw_rec/oegw_grip (recording on/off): median %.2f, p99 %.2f, p99.9 %.2f\n",
                percentile(a, 50) / percentile(b, 50), percentile(a, 99) / percentile(b, 99),
                percentile(a, 99.9) / percentile(b, 99.9));
  }
}

void print_cpu(const std::vector<Path*>& paths, const Options& o) {
  std::printf(
      "\nCPU and system calls at 8000 frames/s (%d rounds x %.1f s per path and measure; the forwarder's "
      "thread):\n",
      o.rounds, o.cpu_seconds);
  std::printf("  %-11s %9s %9s %12s %7s %12s %11s %10s  %s\n", "path", "frames", "answered", "cpu_us/frame", "user_%",
              "idle_cpu_%", "net_us/fr", "sys/frame",
              "per frame: epoll_wait recvmmsg sendmmsg timerfd_settime read write other");
  std::map<std::string, double> cpu, net, sys;
  for (const Path* p : paths) {
    if (p->cpu_frames == 0) continue;
    const double per = p->cpu_ns / 1000.0 / static_cast<double>(p->cpu_frames);
    const double idle_rate = p->idle_s > 0 ? p->idle_cpu_ns / p->idle_s : 0;  // ns per s
    const double window_s = o.cpu_seconds * o.rounds;
    const double per_net = (p->cpu_ns - idle_rate * window_s) / 1000.0 / static_cast<double>(p->cpu_frames);
    cpu[p->name] = per;
    net[p->name] = per_net;
    std::string breakdown = p->perf_note.empty() ? "" : "n/a (" + p->perf_note + ")";
    double total = NAN;
    if (p->perf_ok) {
      const auto f = static_cast<double>(p->perf_frames);
      auto get = [&](const char* e) {
        const auto it = p->syscalls.find(std::string("syscalls:sys_enter_") + e);
        return it == p->syscalls.end() ? 0.0 : static_cast<double>(it->second);
      };
      total = static_cast<double>(p->syscalls.at("raw_syscalls:sys_enter")) / f;
      const double epoll = get("epoll_wait") + get("epoll_pwait"), rx = get("recvmmsg"), tx = get("sendmmsg"),
                   tfd = get("timerfd_settime"), rd = get("read"), wr = get("write");
      const double other =
          static_cast<double>(p->syscalls.at("raw_syscalls:sys_enter")) - epoll - rx - tx - tfd - rd - wr;
      breakdown = fmt::format("{:.3f} {:.3f} {:.3f} {:.3f} {:.3f} {:.3f} {:.3f}", epoll / f, rx / f, tx / f, tfd / f,
                              rd / f, wr / f, other / f);
      for (const auto& [event, count] : p->syscalls)
        if (event.rfind("syscalls:", 0) != 0 && event.rfind("raw_syscalls:", 0) != 0)
          breakdown += fmt::format("; {} {:.3f}", event, static_cast<double>(count) / f);
      sys[p->name] = total;
    }
    const std::uint64_t ticks = p->user_ticks + p->system_ticks;
    const double user_share =
        ticks == 0 ? NAN : 100.0 * static_cast<double>(p->user_ticks) / static_cast<double>(ticks);
    std::printf("  %-11s %9llu %9llu %12.2f %7.0f %12.2f %11.2f %10.3f  %s\n", p->name.c_str(),
                static_cast<unsigned long long>(p->cpu_frames), static_cast<unsigned long long>(p->cpu_answers), per,
                user_share, idle_rate / 1e7, per_net, total, breakdown.c_str());
  }
  for (const char* g : {"oegw_grip", "oegw_full"}) {
    if (!cpu.contains(g)) continue;
    for (const char* f : {"floor", "floor_loop"}) {
      if (!cpu.contains(f)) continue;
      const double ratio = cpu[g] / cpu[f], ratio_net = net[g] / net[f];
      std::printf("  %s/%s: CPU per frame %.2f, net of idle %.2f (target <= 1.1: %s)", g, f, ratio, ratio_net,
                  ratio <= 1.1 ? "met" : "NOT met");
      if (sys.contains(g))
        std::printf("; system calls per frame %.3f (target <= 3: %s)", sys[g], sys[g] <= 3 ? "met" : "NOT met");
      std::printf("\n");
    }
  }
  // The black box's price (its writer thread counted with the loop's): target <= 1.2 x off.
  if (cpu.contains("oegw_rec") && cpu.contains("oegw_grip")) {
    const double ratio = cpu["oegw_rec"] / cpu["oegw_grip"], ratio_net = net["oegw_rec"] / net["oegw_grip"];
    std::printf("  oegw_rec/oegw_grip (recording on/off): CPU per frame %.2f, net of idle %.2f (target <= 1.2: %s)\n",
                ratio, ratio_net, ratio <= 1.2 ? "met" : "NOT met");
  }
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool more = i + 1 < argc;
    if (a == "--rounds" && more) o.rounds = std::max(1, std::atoi(argv[++i]));
    else if (a == "--samples" && more) o.samples = std::max(1, std::atoi(argv[++i]));
    else if (a == "--rates" && more) o.rates = parse_list(argv[++i]);
    else if (a == "--cpu-seconds" && more) o.cpu_seconds = std::atof(argv[++i]);
    else if (a == "--cabs" && more) {
      const std::string c = argv[++i];
      o.grip = c.find("grip") != std::string::npos;
      o.full = c.find("full") != std::string::npos;
      o.rec = c.find("rec") != std::string::npos;
    } else if (a == "--no-perf") o.perf = false;
    else if (a == "--perf-events" && more) o.perf_events = argv[++i];
    else if (a == "--pin") o.pin = true;
    else if (a == "--seed" && more) o.seed = static_cast<unsigned>(std::atoi(argv[++i]));
    else if (a == "--verbose") o.verbose = true;
    else {
      std::fprintf(
          stderr,
          "usage: %s [--rounds N] [--samples N] [--rates R,R] [--cpu-seconds S] [--cabs grip,full,rec] [--no-perf] "
          "[--perf-events E,E] [--pin] [--seed N] [--verbose]\n",
          argv[0]);
      return 64;
    }
  }
  if (std::any_of(o.rates.begin(), o.rates.end(), [](int r) { return r <= 0 || r > 100'000; }) ||
      !(o.cpu_seconds > 0)) {
    std::fprintf(stderr, "%s: --rates: 1..100000 frames/s each; --cpu-seconds: above 0\n", argv[0]);
    return 64;
  }
  // The daemon's log (a queue and a thread of its own); its start-up chatter only with --verbose.
  const gateway::DaemonLog log;
  spdlog::set_level(o.verbose ? spdlog::level::info : spdlog::level::warn);
  ::prctl(PR_SET_TIMERSLACK, 1UL);  // the pacer's sleeps end on time (default slack: 50 us)

  std::printf(
      "oegw_bench_path: native; AF_UNIX SOCK_SEQPACKET socketpairs carrying struct can_frame; %u CPUs; "
      "load average at start %s (a shared machine)\n",
      std::thread::hardware_concurrency(), load_average().c_str());
  std::fflush(stdout);

  char dir_template[] = "/tmp/oegw-bench-path.XXXXXX";
  const char* dir = ::mkdtemp(dir_template);
  if (dir == nullptr) {
    std::perror("mkdtemp");
    return 1;
  }
  int status = 0;
  {
    // The floors: each on two socketpairs of its own, blocking ends.
    std::vector<std::unique_ptr<Path>> owned;
    std::vector<std::thread> floors;
    std::vector<int> floor_fds;
    auto add_floor = [&](const char* name, void (*fn)(int, int)) {
      int in[2], out[2];
      canopen::io::SeqpacketCanTransport::make_socketpair(in);
      canopen::io::SeqpacketCanTransport::make_socketpair(out);
      set_timestamps(in[0]);  // the forwarder's input: stamped, as a CAN socket's
      set_timestamps(out[1]);
      auto p = std::make_unique<Path>();
      p->name = name;
      p->tx = in[1];
      p->rx = out[1];
      Path* raw = p.get();
      floors.emplace_back([raw, fn, a = in[0], b = out[0]] {
        raw->tid = this_tid();
        fn(a, b);
      });
      raw->thread = floors.back().native_handle();
      raw->has_thread = true;
      floor_fds.insert(floor_fds.end(), {in[0], in[1], out[0], out[1]});
      owned.push_back(std::move(p));
    };
    add_floor("floor", floor_blocking);
    add_floor("floor_loop", floor_loop);

    std::vector<std::unique_ptr<Cab>> cabs;
    try {
      if (o.grip)
        cabs.push_back(std::make_unique<Cab>("oegw_grip", bench::load_or_throw(bench::yaml_one_grip(), "one_grip.yaml"),
                                             std::filesystem::path(dir) / "grip.store"));
      if (o.full)
        cabs.push_back(std::make_unique<Cab>("oegw_full",
                                             bench::load_or_throw(bench::yaml_full_set(), "full_fe_set.yaml"),
                                             std::filesystem::path(dir) / "full.store"));
      if (o.rec)
        cabs.push_back(std::make_unique<Cab>("oegw_rec", bench::load_or_throw(bench::yaml_one_grip(), "one_grip.yaml"),
                                             std::filesystem::path(dir) / "rec.store",
                                             std::filesystem::path(dir) / "record"));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "oegw_bench_path: %s\n", e.what());
      status = 1;
    }
    for (auto& cab : cabs) {
      const std::int64_t t0 = mono_ns();
      cab->start();
      std::string why;
      bool ok = cab->configure_host(why);
      while (ok && !cab->devices_operational() && mono_ns() - t0 < 60'000'000'000)
        sleep_until_ns(mono_ns() + 10'000'000);
      if (ok && !cab->devices_operational()) {
        why = "sub-devices not all operational after 60 s";
        ok = false;
      }
      auto p = std::make_unique<Path>();
      p->name = cab->name();
      p->gateway = true;
      p->tx = cab->stimuli_fd();
      p->rx = cab->host_fd();
      p->tid = cab->gateway_tid();
      p->thread = cab->gateway_thread();
      p->has_thread = true;
      if (cab->records()) {
        p->helper_thread = "oegw-record";
        if (named_threads_cpu_ns(p->helper_thread) <= 0) {  // the writer's CPU would be missed
          why = "no thread named oegw-record (the black box's writer) to count";
          ok = false;
        }
      }
      if (ok && !warm_up(*p, 30)) {
        why = "no answer to the grip's TPDO within 30 s";
        ok = false;
      }
      std::printf("%s: %s in %.1f s (%d sub-devices operational)%s%s\n", cab->name().c_str(),
                  ok ? "ready" : "NOT ready", static_cast<double>(mono_ns() - t0) / 1e9, cab->device_count(),
                  ok ? "" : ": ", ok ? "" : why.c_str());
      std::fflush(stdout);
      if (!ok) {
        status = 1;
        p->dead = true;
      }
      owned.push_back(std::move(p));
    }
    std::vector<Path*> paths;
    for (auto& p : owned) paths.push_back(p.get());
    std::string tids;
    for (Path* p : paths) {
      if (p->dead) continue;
      while (p->tid == 0) std::this_thread::yield();
      tids += fmt::format(" {} {}", p->name, p->tid.load());
      if (!p->gateway && !warm_up(*p, 5)) {
        std::printf("%s: no answer\n", p->name.c_str());
        p->dead = true;
        status = 1;
      }
    }

    for (Path* p : paths) {  // what the boots left (a cab idle while the other booted) is not measured
      if (p->gateway) (void)drain(p->rx);
      p->faults = 0;
    }
    if (o.pin) {
      // Where the scheduler puts a forwarder beside the prober (the same CPU: a hand-over; the
      // other: a wake-up across) changes its latency by tens of microseconds here, and it keeps a
      // thread where it was for seconds: pinned, every path is woken across CPUs alike.
      auto pin = [](pthread_t t, int cpu) {
        cpu_set_t set;
        CPU_ZERO(&set);
        CPU_SET(cpu, &set);
        return ::pthread_setaffinity_np(t, sizeof set, &set) == 0;
      };
      bool ok = pin(::pthread_self(), 0);
      for (Path* p : paths) ok = pin(p->thread, 1) && ok;
      std::printf("pinned: the prober on CPU 0, the forwarders on CPU 1%s\n", ok ? "" : " (refused: not pinned)");
    }
    std::printf("forwarder threads (for strace -p / perf -t by hand):%s\n", tids.c_str());
    std::fflush(stdout);
    std::mt19937 rng(o.seed);
    for (int rate : o.rates) {
      measure_latency(paths, rate, o, rng);
      print_latency(paths, rate, o);
      std::fflush(stdout);
    }
    measure_cpu(paths, o, rng);
    print_cpu(paths, o);
    for (const Path* p : paths)
      if (p->gateway)
        std::printf("%s: %llu fault EMCYs during the measurements%s\n", p->name.c_str(),
                    static_cast<unsigned long long>(p->faults),
                    p->faults == 0 ? "" : " (a sub-device faulted: its figures include a fault and its recovery)");
    for (const Path* p : paths) {
      if (p->dead) {
        std::printf("%s: did not forward (%d misses in a row or no warm-up)\n", p->name.c_str(), kMissesInARow);
        status = 1;
      }
    }
    std::printf(
        "\nsystem calls counted by perf stat on the forwarder's thread (tracepoints raw_syscalls:sys_enter and "
        "syscalls:sys_enter_*), only while paced; load average at end %s\n",
        load_average().c_str());

    for (auto& cab : cabs) {
      cab->stop();
      if (cab->exit_status() != 0) {
        std::printf("%s: serve_gateway returned %d\n", cab->name().c_str(), cab->exit_status());
        status = 1;
      }
    }
    // The floors end at the end of their input stream.
    for (const auto& p : owned)
      if (!p->gateway) ::shutdown(p->tx, SHUT_WR);
    for (auto& t : floors) t.join();
    for (int fd : floor_fds) ::close(fd);
  }
  std::filesystem::remove_all(dir);
  return status;
}
