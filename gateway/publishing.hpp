// The gateway's functional elements on DDS and/or LCM (the mapping file's `publish:`): every
// input FE is published on change and at least every period (publish/publish_schedule),
// with the gateway status; indicator and display commands come back into the gateway from the
// sources each FE takes (mapping file `sources`; among them the last writer wins —
// docs/guides/dds-lcm.md#who-commands-the-indicators-and-displays).
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <utility>
#include <variant>
#include <vector>

#include "canopen/io/event_loop.hpp"
#include "gateway/fe_samples.hpp"
#include "gateway/gateway.hpp"
#include "gateway/publisher_link.hpp"
#include "mapping/config.hpp"
#include "publish/dds_security.hpp"
#include "publish/publish_schedule.hpp"

namespace oegw::gateway {

// Hands every sample to each transport.
class FanOut final : public ForwardingPublisher<FanOut> {
 public:
  void add(Publisher* p) { outs_.push_back(p); }
  [[nodiscard]] bool empty() const { return outs_.empty(); }
  [[nodiscard]] const std::vector<Publisher*>& outputs() const { return outs_; }

 private:
  friend class ForwardingPublisher<FanOut>;
  template <class S>
  void forward(const S& s) {
    for (auto* p : outs_) p->publish(s);
  }
  std::vector<Publisher*> outs_;
};

// publish.dds.security as the DDS publisher takes it (the paths resolved by the loader).
[[nodiscard]] publish::DdsSecuritySettings dds_security_settings(const mapping::DdsSecurityConfig& c);
// Every problem of publish.dds.security's files (dds_security.hpp) at its setting's place in the
// mapping file: `oegw check` and `oegw run` refuse the file with them, before anything starts.
[[nodiscard]] std::vector<mapping::Diagnostic> dds_security_errors(const mapping::Config& c);

// How each transport is opened: the real DDS and LCM publishers for `config`, or a test's fakes.
// A factory owns what it uses (an attempt may run in a thread of its own).
struct PublisherFactories {
  PublisherLink::Factory dds, lcm;
};
[[nodiscard]] PublisherFactories real_publishers(const mapping::PublishConfig& config);

// One transport's state for `oegw status` and systemd's STATUS=
// (docs/guides/dds-lcm.md#publishing-degrades-the-gateway-runs).
struct TransportState {
  std::string name;  // "dds", "lcm"
  bool up = false;
  std::string reason;                                // why it is down
  std::uint32_t failures = 0;                        // attempts failed since it was last up
  canopen::Duration down_for{};                      // how long it has been down
  std::optional<canopen::Duration> next_attempt_in;  // while down
};

class GatewayPublishing {
 public:
  // Opens the transports `config` enables; throws PublishConfigError naming the setting that
  // cannot be applied (nothing is left open then). A transport the machine cannot carry now
  // (PublishUnavailable) is left down, reported and opened again once run_on() has given a loop
  // (gateway/publisher_link.hpp). `clock` gives the loop's time.
  GatewayPublishing(Gateway& gateway, const mapping::PublishConfig& config, std::function<canopen::TimePoint()> clock,
                    PublisherFactories factories = {}, PublisherLink::Log log = {});
  ~GatewayPublishing();
  GatewayPublishing(const GatewayPublishing&) = delete;
  GatewayPublishing& operator=(const GatewayPublishing&) = delete;

  [[nodiscard]] bool active() const { return !fan_.empty(); }
  // A reload (gateway/reload.hpp): detach() while the old gateway still runs (its changes still
  // waiting are published), attach() publishes the new one's FEs at once (their fault values
  // while its sub-devices boot) and its status. The transports stay: readers keep their writers.
  void detach();
  void attach(Gateway& gw);
  // The transports that are up, for a caller without a loop to watch fd() and call poll()
  // (commands in); run_on() watches them itself.
  [[nodiscard]] std::vector<Publisher*> publishers() const;
  // Each configured transport, up or down.
  [[nodiscard]] std::vector<TransportState> transports() const;
  // "lcm down: <reason>" for each transport down (systemd's STATUS=); empty when all are up.
  [[nodiscard]] std::vector<std::string> degraded() const;
  // Republishes what is due and the gateway status; call every period (or at next_due()).
  void tick();
  [[nodiscard]] std::int64_t period_us() const { return schedule_.period_us(); }
  [[nodiscard]] std::uint64_t published() const { return schedule_.published(); }

  // The sample of one FE as the gateway holds it now (also used by tests). Once run_on() has
  // given it a loop, a change is published at the end of the loop's wake-up (a posted flush,
  // after the wake-up's timers, before its CAN sends), and the axes' changes one wake-up reads
  // merge into one sample per FE with the latest values: a backlog of hundreds of frames (a
  // gateway that has fallen behind) publishes each moving axis once, not once per frame
  // (at 5,000 grip frames/s, every one a change, publishing each on DDS and LCM kept the
  // gateway so far behind that the grip's PDOs came in stale). Discrete changes are never
  // merged away: a sample whose status, buttons, switches or memory bits differ from the one
  // waiting goes out first, so a press and release read together both reach the reader.
  void publish_fe(mapping::FeId fe);

  // Runs on `loop`: each transport's fd is polled for commands and tick() every period; after
  // each, `rearm` (the gateway's ServiceDriver::rearm: a command may move a watchdog deadline).
  // A transport that is down is opened again from the loop (`attempts`: in a thread of its own,
  // or inline for a test on a simulated clock).
  void run_on(canopen::io::EventLoop& loop, std::function<void()> rearm,
              PublisherLink::Attempts attempts = PublisherLink::Attempts::InThread);

 private:
  using Sample = FeSample;
  [[nodiscard]] std::int64_t now_us() const;
  [[nodiscard]] std::optional<Sample> sample_of(mapping::FeId fe) const;
  void send(const Sample& s);
  void flush();
  void publish_status();

  canopen::io::EventLoop* loop_ = nullptr;  // set by run_on(): changes coalesce per wake-up
  // The FEs changed in this wake-up, in order of change, each with its latest sample.
  std::vector<std::pair<mapping::FeId, Sample>> changed_;
  bool flush_posted_ = false;
  std::shared_ptr<bool> alive_ = std::make_shared<bool>(true);  // a posted flush outliving us does nothing

  Gateway* gw_;
  std::function<canopen::TimePoint()> clock_;
  std::vector<std::unique_ptr<PublisherLink>> links_;  // dds, then lcm (those enabled)
  FanOut fan_;
  publish::PublishSchedule schedule_;
  std::uint32_t status_seq_ = 0;
};

}  // namespace oegw::gateway
