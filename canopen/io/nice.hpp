// A thread's nice value: how threads beside the event loop (canopen/io/background_work.hpp, the
// black box's writer) yield the CPU to it.
#pragma once

#include <sys/resource.h>

#include <algorithm>
#include <cerrno>

namespace oegw::canopen::io {

// The largest nice value, the lowest priority a thread can take (setpriority(2)).
inline constexpr int kMaxNice = 19;

// How much nicer than the event loop the threads beside it run (run_nicer): the black box's
// writer, a reload's reading.
inline constexpr int kNiceBesideTheLoop = 10;

// Makes the calling thread's nice value `above` the process's (at most kMaxNice). CAN first: a
// thread beside the event loop (a writer, a reading) lets the loop preempt it sooner when a bus
// frame wakes it, most of all on a one-core controller, and still gets its share of a busy CPU.
// Per thread on Linux (setpriority with 0 names the calling thread); raising one's own nice value
// needs no privilege.
inline void run_nicer(int above) {
  errno = 0;
  const int base = ::getpriority(PRIO_PROCESS, 0);
  if (errno == 0) (void)::setpriority(PRIO_PROCESS, 0, std::min(base + above, kMaxNice));
}

}  // namespace oegw::canopen::io
