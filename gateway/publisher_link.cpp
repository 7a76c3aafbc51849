#include "gateway/publisher_link.hpp"

#include <algorithm>

#include "publish/publish_errors.hpp"

namespace oegw::gateway {

PublisherLink::PublisherLink(std::string name, Factory factory)
    : name_(std::move(name)), factory_(std::move(factory)) {}

PublisherLink::~PublisherLink() {
  if (loop_ != nullptr) {
    if (transport_watch_ != 0) loop_->unwatch(transport_watch_);
    if (retry_timer_ != 0) loop_->cancel(retry_timer_);
  }
  // An attempt still opening is not waited for (it may take liblcm's 10 s): its thread ends on
  // its own and drops what it opened (BackgroundWork).
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
  // Never on the loop (liblcm's self-test may take 10 s): without a thread the attempt fails and
  // is retried as any other.
  attempt_.start(*loop_, factory_,
                 [this](std::optional<std::unique_ptr<Publisher>> opened, const std::string& failure) {
                   std::unique_ptr<Publisher> p = opened ? std::move(*opened) : nullptr;
                   outcome(std::move(p), failure.empty() && !p ? "no transport" : failure);
                 },
                 {.name = "oegw-" + name_, .if_no_thread = decltype(attempt_)::IfNoThread::Fail});
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
