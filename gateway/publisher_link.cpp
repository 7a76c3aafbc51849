#include "gateway/publisher_link.hpp"

#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <mutex>

#include "publish/publish_errors.hpp"

namespace oegw::gateway {

// What an attempt's thread hands back. Shared: a link destroyed while its thread still opens
// (liblcm's self-test) leaves this to the thread, which then drops what it opened.
struct PublisherLink::Attempt {
  std::mutex m;
  std::unique_ptr<Publisher> opened;
  std::string failure;
  int event_fd = -1;  // written once the outcome is there
  ~Attempt() {
    if (event_fd >= 0) ::close(event_fd);
  }
};

PublisherLink::PublisherLink(std::string name, Factory factory)
    : name_(std::move(name)), factory_(std::move(factory)) {}

PublisherLink::~PublisherLink() {
  if (loop_ != nullptr) {
    if (transport_watch_ != 0) loop_->unwatch(transport_watch_);
    if (attempt_watch_ != 0) loop_->unwatch(attempt_watch_);
    if (retry_timer_ != 0) loop_->cancel(retry_timer_);
  }
  // An attempt still opening is not waited for (it may take liblcm's 10 s): its thread ends on
  // its own and drops what it opened.
  if (thread_.joinable()) thread_.detach();
}

canopen::Duration PublisherLink::backoff(std::uint32_t failures) {
  const std::uint32_t doublings = std::min<std::uint32_t>(failures == 0 ? 0 : failures - 1, 4);
  return std::min<canopen::Duration>(std::chrono::seconds(1) * (1u << doublings), std::chrono::seconds(10));
}

void PublisherLink::open(canopen::TimePoint now) {
  try {
    became_up(factory_());
  } catch (const publish::PublishUnavailable& e) {
    down_since_ = now;
    outcome(nullptr, e.what());
  }
}

void PublisherLink::run_on(canopen::io::EventLoop& loop, Attempts attempts, std::function<void()> after_poll,
                           std::function<void()> on_up) {
  loop_ = &loop;
  attempts_ = attempts;
  after_poll_ = std::move(after_poll);
  on_up_ = std::move(on_up);
  if (transport_ && transport_->fd() >= 0)
    transport_watch_ = loop.watch(transport_->fd(), canopen::io::events::kReadable, [this](std::uint32_t) {
      transport_->poll();
      if (after_poll_) after_poll_();
    });
  if (!transport_ && next_attempt_) retry_timer_ = loop.call_at(*next_attempt_, [this] { attempt(); });
}

void PublisherLink::attempt() {
  retry_timer_ = 0;
  next_attempt_.reset();
  if (attempts_ == Attempts::Inline) {
    std::unique_ptr<Publisher> opened;
    std::string failure;
    try {
      opened = factory_();
    } catch (const std::exception& e) {  // PublishConfigError too: after the start, only retried
      failure = e.what();
    }
    return outcome(std::move(opened), failure);
  }
  auto a = std::make_shared<Attempt>();
  a->event_fd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (a->event_fd < 0) return outcome(nullptr, "cannot start an attempt (eventfd)");
  attempt_ = a;
  attempt_watch_ =
      loop_->watch(a->event_fd, canopen::io::events::kReadable, [this](std::uint32_t) { take_thread_outcome(); });
  thread_ = std::thread([a, factory = factory_] {
    std::unique_ptr<Publisher> opened;
    std::string failure;
    try {
      opened = factory();
    } catch (const std::exception& e) {
      failure = e.what();
    } catch (...) {
      failure = "unknown error";
    }
    std::lock_guard lock(a->m);
    a->opened = std::move(opened);
    a->failure = failure.empty() && !a->opened ? "no transport" : failure;
    const std::uint64_t one = 1;
    [[maybe_unused]] auto n = ::write(a->event_fd, &one, sizeof one);
  });
}

void PublisherLink::take_thread_outcome() {
  loop_->unwatch(attempt_watch_);
  attempt_watch_ = 0;
  thread_.join();  // it has handed its outcome over: it ends now
  std::unique_ptr<Publisher> opened;
  std::string failure;
  {
    std::lock_guard lock(attempt_->m);
    opened = std::move(attempt_->opened);
    failure = attempt_->failure;
  }
  attempt_.reset();
  outcome(std::move(opened), failure);
}

void PublisherLink::outcome(std::unique_ptr<Publisher> opened, const std::string& failure) {
  if (opened) {
    const std::uint32_t failed = failures_;
    became_up(std::move(opened));
    if (on_log)
      on_log(true, name_ + " up again after " + std::to_string(failed) + " failed attempt" + (failed == 1 ? "" : "s"));
    if (on_up_) on_up_();
    return;
  }
  const bool first = failures_ == 0;
  ++failures_;
  reason_ = failure;
  const canopen::TimePoint now = loop_ != nullptr ? loop_->now() : down_since_;
  if (first) {
    down_since_ = now;
    if (on_log)
      on_log(false, name_ + " down: " + failure + "; the gateway runs without it and opens it again every " +
                        "1 s doubling to 10 s until it opens");
  }
  next_attempt_ = now + backoff(failures_);
  if (loop_ != nullptr) retry_timer_ = loop_->call_at(*next_attempt_, [this] { attempt(); });
}

void PublisherLink::became_up(std::unique_ptr<Publisher> opened) {
  transport_ = std::move(opened);
  failures_ = 0;
  reason_.clear();
  next_attempt_.reset();
  // Commands arrive through this link whatever transport object carries them now.
  transport_->on_indicator_command = [this](const IndicatorCommand& c) {
    if (on_indicator_command) on_indicator_command(c);
  };
  transport_->on_display_command = [this](const DisplayCommand& c) {
    if (on_display_command) on_display_command(c);
  };
  if (loop_ != nullptr && transport_->fd() >= 0)
    transport_watch_ = loop_->watch(transport_->fd(), canopen::io::events::kReadable, [this](std::uint32_t) {
      transport_->poll();
      if (after_poll_) after_poll_();
    });
}

}  // namespace oegw::gateway
