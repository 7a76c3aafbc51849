// The log of `oegw run` without a cost to the buses
// (docs/reference/limits.md#can-first-what-the-event-loop-does-beside-the-buses): while a DaemonLog
// lives, spdlog's default logger hands each line to a bounded queue that a thread of its own writes
// out (to the same sinks, in the same format); the event loop never waits for journald or a
// terminal that does not read. A full queue drops its oldest line (spdlog's overrun_oldest),
// counted in dropped(). The thread blocks every signal (the loop takes SIGTERM through its
// signalfd, which a thread that did not block it would get instead).
#pragma once

#include <cstddef>
#include <memory>

namespace spdlog {
class logger;
namespace details {
class thread_pool;
}
}  // namespace spdlog

namespace oegw::gateway {

class DaemonLog {
 public:
  static constexpr std::size_t kQueueLines = 8192;
  explicit DaemonLog(std::size_t queue_lines = kQueueLines);
  // Writes what is queued, then puts the synchronous logger back.
  ~DaemonLog();
  DaemonLog(const DaemonLog&) = delete;
  DaemonLog& operator=(const DaemonLog&) = delete;

  [[nodiscard]] std::size_t dropped() const;

 private:
  std::shared_ptr<spdlog::logger> previous_;
  std::shared_ptr<spdlog::details::thread_pool> pool_;
};

}  // namespace oegw::gateway
