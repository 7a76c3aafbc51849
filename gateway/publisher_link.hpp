// One publishing transport (DDS or LCM) that may be down
// (docs/guides/dds-lcm.md#publishing-degrades-the-gateway-runs). While the machine cannot carry it
// (PublishUnavailable: no route for the LCM group, the DDS interface missing) the gateway runs
// without it: its samples are dropped (nothing queues) and it is opened again with back-off — 1 s
// after the first failure, then 2, 4, 8 s, then every 10 s — until it opens; then samples flow
// again (the publish schedule republishes every FE each period) and its commands are taken again.
// Reported: up(), reason(), and on_log once when it goes down and once when it comes back.
//
// When the loop runs, each attempt runs in a thread of its own and its outcome is taken on the
// loop (canopen/io/background_work.hpp): opening can block (liblcm's self-test waits up to 10 s for its own message
// when a firewall drops it; Cyclone DDS creates its domain), and a retry must never hold a bus
// frame back (docs/reference/limits.md#can-first-what-the-event-loop-does-beside-the-buses). The
// thread has the loop thread's signal mask (the signals the loop takes stay blocked in it and in
// the threads the transport starts). Attempts::Inline runs them on the loop instead: tests, on a
// simulated clock.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "canopen/io/background_work.hpp"
#include "canopen/io/event_loop.hpp"
#include "gateway/fe_samples.hpp"

namespace oegw::gateway {

class PublisherLink final : public ForwardingPublisher<PublisherLink> {
 public:
  // Opens the transport; throws PublishUnavailable (the machine, retried) or PublishConfigError
  // (a setting: refused at start). It may run in another thread: it owns what it uses.
  using Factory = std::function<std::unique_ptr<Publisher>()>;
  enum class Attempts : std::uint8_t { InThread, Inline };
  // Text for the log: `up` false when it went down (once, with the reason), true when it opened
  // again after being down.
  using Log = std::function<void(bool up, const std::string& text)>;

  PublisherLink(std::string name, Factory factory);
  ~PublisherLink() override;
  PublisherLink(const PublisherLink&) = delete;
  PublisherLink& operator=(const PublisherLink&) = delete;

  // The first attempt, now, in the caller's thread: PublishConfigError propagates (`oegw run`
  // refuses to start); PublishUnavailable leaves the link down with its reason.
  void open(canopen::TimePoint now);
  // From now on on `loop`: the transport's fd is watched (poll(), then `after_poll`), and while
  // down the link is retried. `on_up` runs on the loop each time it opens after being down.
  void run_on(canopen::io::EventLoop& loop, Attempts attempts, std::function<void()> after_poll,
              std::function<void()> on_up);

  [[nodiscard]] const std::string& name() const { return name_; }  // "dds", "lcm"
  [[nodiscard]] bool up() const { return transport_ != nullptr; }
  [[nodiscard]] Publisher* transport() const { return transport_.get(); }  // null while down
  [[nodiscard]] const std::string& reason() const { return reason_; }      // why it is down ("" when up)
  [[nodiscard]] std::uint32_t failures() const { return failures_; }       // attempts failed since it was up
  [[nodiscard]] canopen::TimePoint down_since() const { return down_since_; }
  [[nodiscard]] std::optional<canopen::TimePoint> next_attempt() const { return next_attempt_; }
  [[nodiscard]] bool attempting() const { return attempt_.busy(); }  // one runs in its thread
  // The wait before the next attempt after `failures` failed ones: 1 s, 2, 4, 8, then 10 s.
  [[nodiscard]] static canopen::Duration backoff(std::uint32_t failures);

  Log on_log;

 private:
  friend class ForwardingPublisher<PublisherLink>;
  // Every sample: to the transport while it is up; dropped while it is down.
  template <class S>
  void forward(const S& s) {
    if (transport_) transport_->publish(s);
  }
  void attempt();  // at next_attempt_
  void outcome(std::unique_ptr<Publisher> opened, const std::string& failure);
  void became_up(std::unique_ptr<Publisher> opened);

  std::string name_;
  Factory factory_;
  std::unique_ptr<Publisher> transport_;
  std::string reason_;
  std::uint32_t failures_ = 0;
  canopen::TimePoint down_since_{};
  std::optional<canopen::TimePoint> next_attempt_;
  canopen::io::EventLoop* loop_ = nullptr;
  Attempts attempts_ = Attempts::InThread;
  std::function<void()> after_poll_, on_up_;
  canopen::io::EventLoop::WatchId transport_watch_ = 0;
  canopen::io::EventLoop::TimerId retry_timer_ = 0;
  canopen::io::BackgroundWork<std::unique_ptr<Publisher>> attempt_;  // the attempt in its thread
};

}  // namespace oegw::gateway
