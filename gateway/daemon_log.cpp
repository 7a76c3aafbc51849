#include "gateway/daemon_log.hpp"

#include <signal.h>

#include <spdlog/async.h>
#include <spdlog/async_logger.h>
#include <spdlog/spdlog.h>

namespace oegw::gateway {

DaemonLog::DaemonLog(std::size_t queue_lines) : previous_(spdlog::default_logger()) {
  pool_ = std::make_shared<spdlog::details::thread_pool>(queue_lines, 1, [] {
    sigset_t all;
    sigfillset(&all);
    ::pthread_sigmask(SIG_BLOCK, &all, nullptr);
  });
  auto logger =
      std::make_shared<spdlog::async_logger>(previous_->name(), previous_->sinks().begin(), previous_->sinks().end(),
                                             pool_, spdlog::async_overflow_policy::overrun_oldest);
  logger->set_level(previous_->level());
  spdlog::set_default_logger(std::move(logger));
}

DaemonLog::~DaemonLog() {
  spdlog::set_default_logger(previous_);
  // The pool's queue is first in, first out: its destructor writes every line before its stop.
  pool_.reset();
}

std::size_t DaemonLog::dropped() const { return pool_ ? pool_->overrun_counter() : 0; }

}  // namespace oegw::gateway
