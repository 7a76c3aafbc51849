// Work beside the buses that may take long or block (reading and checking a file, opening a
// transport) run in a thread of its own, its result taken on the event loop through an eventfd,
// so that the loop serves its buses meanwhile
// (docs/reference/limits.md#can-first-what-the-event-loop-does-beside-the-buses).
//
//   BackgroundWork<Parsed> parsing;
//   parsing.start(loop, [path] { return parse(path); },                      // in its thread
//                 [](std::optional<Parsed> p, const std::string& failure) {  // on the loop
//                   ...
//                 });
//
// One piece of work at a time. The thread is started with the caller's signal mask: the signals
// a loop takes (EventLoop::handle_signals, which blocks them) stay blocked in it; it may run at a
// nicer value than the loop and be named (Options). Destroying the object while the work runs
// does not wait for it (settle() waits a bounded time): the thread ends on its own and drops its
// result. Where no thread or eventfd can be had (the process at its limits), the work either runs
// on the loop instead, as a posted callback (slower for the buses, never lost), or fails with the
// reason (Options::if_no_thread).
#pragma once

#include <poll.h>
#include <pthread.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <system_error>
#include <thread>
#include <utility>

#include "canopen/io/event_loop.hpp"
#include "canopen/io/nice.hpp"

namespace oegw::canopen::io {

template <class Result>
class BackgroundWork {
 public:
  using Work = std::function<Result()>;
  // The result, or nullopt with what the work threw (its what(), or "unknown error").
  using Done = std::function<void(std::optional<Result> result, const std::string& failure)>;
  enum class IfNoThread : std::uint8_t {
    RunOnLoop,  // the work runs on the loop (posted)
    Fail,       // `done` gets the reason (posted): the work is not run
  };
  struct Options {
    int nice_above = 0;  // run_nicer(nice_above) in the thread
    std::string name;    // the thread's name (top -H, /proc/PID/task/TID/comm), at most 15 bytes
    IfNoThread if_no_thread = IfNoThread::RunOnLoop;
  };

  BackgroundWork() = default;
  BackgroundWork(const BackgroundWork&) = delete;
  BackgroundWork& operator=(const BackgroundWork&) = delete;
  ~BackgroundWork() {
    unwatch();
    if (thread_.joinable()) thread_.detach();
  }

  [[nodiscard]] bool busy() const { return shared_ != nullptr; }

  // Starts `work`; `done` runs on `loop` with its outcome (`done` may start the next work).
  // False, and nothing started, while an earlier work has not been done.
  bool start(EventLoop& loop, Work work, Done done, Options options = {}) {
    if (busy()) return false;
    loop_ = &loop;
    done_ = std::move(done);
    shared_ = std::make_shared<Shared>();
    shared_->work = std::move(work);
    std::string no_thread;
    try {
      shared_->event_fd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
      if (shared_->event_fd < 0) throw std::system_error(errno, std::generic_category(), "eventfd");
      watch_ = loop.watch(shared_->event_fd, events::kReadable, [this](std::uint32_t) { take(); });
      thread_ = std::thread([s = shared_, o = options] {
        if (!o.name.empty()) (void)::pthread_setname_np(::pthread_self(), o.name.substr(0, 15).c_str());
        if (o.nice_above > 0) run_nicer(o.nice_above);
        run(*s);
        const std::uint64_t one = 1;
        [[maybe_unused]] const auto n = ::write(s->event_fd, &one, sizeof one);
      });
      return true;
    } catch (const std::system_error& e) {  // no eventfd, no watch or no thread: below
      no_thread = e.what();
    } catch (...) {  // out of memory: nothing started
      unwatch();
      forget();
      throw;
    }
    unwatch();
    const bool on_loop = options.if_no_thread == IfNoThread::RunOnLoop;
    loop.post([this, w = std::weak_ptr<Shared>(shared_), on_loop, no_thread] {
      const auto s = w.lock();
      if (!s) return;  // this object was destroyed meanwhile: nobody waits for the outcome
      if (on_loop) {
        run(*s);
      } else {
        const std::lock_guard lock(s->m);
        s->failure = "cannot start a thread for it: " + no_thread;
      }
      take();
    });
    return true;
  }

  // Waits up to `bound` for the work under way in its thread to end, its outcome dropped: before
  // a process exits (its static objects must not go while the thread still uses them). Only
  // where the loop is not needed meanwhile. True if no work runs any more.
  bool settle(std::chrono::milliseconds bound) {
    if (!thread_.joinable()) return !busy();
    pollfd p{shared_->event_fd, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(bound.count())) <= 0) return false;
    thread_.join();
    unwatch();
    forget();
    return true;
  }

 private:
  struct Shared {
    Work work;
    std::mutex m;
    std::optional<Result> result;
    std::string failure;
    int event_fd = -1;
    Shared() = default;
    Shared(const Shared&) = delete;
    Shared& operator=(const Shared&) = delete;
    ~Shared() {
      if (event_fd >= 0) ::close(event_fd);
    }
  };

  static void run(Shared& s) {
    std::optional<Result> r;
    std::string failure;
    try {
      r.emplace(s.work());
    } catch (const std::exception& e) {
      failure = e.what();
    } catch (...) {
      failure = "unknown error";
    }
    const std::lock_guard lock(s.m);
    s.result = std::move(r);
    s.failure = std::move(failure);
  }

  // On the loop: the work is over (its thread has handed its outcome over and ends now).
  void take() {
    unwatch();
    if (thread_.joinable()) thread_.join();
    std::optional<Result> r;
    std::string failure;
    {
      const std::lock_guard lock(shared_->m);
      r = std::move(shared_->result);
      failure = std::move(shared_->failure);
    }
    Done done = std::move(done_);
    forget();
    done(std::move(r), failure);
  }

  void unwatch() {
    if (watch_ != 0) loop_->unwatch(watch_);
    watch_ = 0;
  }

  void forget() {
    shared_.reset();
    done_ = nullptr;
  }

  EventLoop* loop_ = nullptr;
  Done done_;
  std::shared_ptr<Shared> shared_;
  EventLoop::WatchId watch_ = 0;
  std::thread thread_;
};

}  // namespace oegw::canopen::io
