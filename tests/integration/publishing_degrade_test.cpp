// Publishing degrades, the gateway runs
// (docs/guides/dds-lcm.md#publishing-degrades-the-gateway-runs; gateway/publisher_link.hpp): a
// transport the machine cannot carry at start leaves the gateway running, is reported and logged
// once, is opened again with back-off, and once it opens its samples flow and its commands are
// taken — without a restart. The transports are fakes whose factory fails as often as the test
// says, on a simulated clock (Attempts::Inline); one test runs an attempt in its thread and shows
// the loop going on meanwhile.
#include <gtest/gtest.h>

#include <future>
#include <memory>
#include <string>
#include <vector>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "gateway/gateway.hpp"
#include "gateway/publishing.hpp"
#include "publish/publish_errors.hpp"
#include "tests/fixtures/fixtures.hpp"
#include "virtual_network.hpp"

using namespace oegw;
using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
using gateway::PublisherLink;

namespace {

// A transport that only counts what it is given; the test drives its commands.
struct FakeTransport final : gateway::Publisher {
  int* samples;
  explicit FakeTransport(int* s) : samples(s) {}
  void publish(const gateway::JoystickSample&) override { ++*samples; }
  void publish(const gateway::PedalSample&) override { ++*samples; }
  void publish(const gateway::WheelSample&) override { ++*samples; }
  void publish(const gateway::EncoderSample&) override { ++*samples; }
  void publish(const gateway::ButtonClusterSample&) override { ++*samples; }
  void publish(const gateway::GatewayStatus&) override { ++*samples; }
};

// publishing_grip.yaml's gateway (DDS and LCM on, period 50 ms) on a simulated loop.
class PublishingDegrade : public ::testing::Test {
 protected:
  PublishingDegrade() : loop_(clock_) {
    EXPECT_TRUE(loaded_.ok()) << loaded_.error_text();
    gateway::GatewayOptions opt;
    opt.store_path = "";
    gw_ = std::make_unique<gateway::Gateway>(*loaded_.config, up_.sink("gateway"), down_.sink("gateway"), opt);
  }
  // A factory failing `failures` times with PublishUnavailable(`why`), then opening a fake
  // that counts into `samples`; `attempts` counts the calls.
  static PublisherLink::Factory flaky(int failures, std::string why, int* attempts, int* samples,
                                      gateway::Publisher** opened = nullptr) {
    return [=]() -> std::unique_ptr<gateway::Publisher> {
      if (++*attempts <= failures) throw publish::PublishUnavailable(why);
      auto t = std::make_unique<FakeTransport>(samples);
      if (opened != nullptr) *opened = t.get();
      return t;
    };
  }

  SimulatedClock clock_;
  EventLoop loop_;
  mapping::LoadResult loaded_ = mapping::load_config_text(fixtures::mapping_file("publishing_grip.yaml"), "test.yaml",
                                                          gateway::driver_catalogue());
  oegw::testing::VirtualNetwork down_, up_;
  std::unique_ptr<gateway::Gateway> gw_;
  std::vector<std::string> log_;
  PublisherLink::Log log() {
    return [this](bool up, const std::string& text) { log_.push_back((up ? "up: " : "down: ") + text); };
  }
};

TEST_F(PublishingDegrade, AnLcmWithoutRouteIsReportedRetriedWithBackOffAndFlowsOnceItOpens) {
  int dds_attempts = 0, dds_samples = 0, lcm_attempts = 0, lcm_samples = 0;
  gateway::Publisher* lcm = nullptr;
  const std::string why = "publish.lcm.url: no route to 224.0.0.1 (Network is unreachable)";
  gateway::GatewayPublishing pub(
      *gw_, loaded_.config->publish, [this] { return loop_.now(); },
      {flaky(0, "", &dds_attempts, &dds_samples), flaky(3, why, &lcm_attempts, &lcm_samples, &lcm)}, log());
  pub.run_on(
      loop_, [] {}, PublisherLink::Attempts::Inline);
  // Running, DDS publishing, LCM down: reported, logged once.
  EXPECT_GT(dds_samples, 0);
  EXPECT_EQ(lcm_samples, 0);
  EXPECT_EQ(lcm_attempts, 1);
  ASSERT_EQ(pub.transports().size(), 2u);
  EXPECT_TRUE(pub.transports()[0].up);
  const gateway::TransportState down = pub.transports()[1];
  EXPECT_EQ(down.name, "lcm");
  EXPECT_FALSE(down.up);
  EXPECT_EQ(down.reason, why);
  EXPECT_EQ(down.failures, 1u);
  EXPECT_EQ(down.next_attempt_in, std::optional<Duration>(1s));
  EXPECT_EQ(pub.degraded(), std::vector<std::string>{"lcm down: " + why});
  ASSERT_EQ(log_.size(), 1u);
  EXPECT_EQ(log_[0].rfind("down: lcm down: " + why + "; the gateway runs without it", 0), 0u) << log_[0];

  // Attempts 1 s, then 2 s, then 4 s after the failure before: at 1, 3 and 7 s.
  const TimePoint t0 = loop_.now();
  loop_.advance_to(t0 + 999ms);
  EXPECT_EQ(lcm_attempts, 1);
  loop_.advance_to(t0 + 1s);
  EXPECT_EQ(lcm_attempts, 2);
  loop_.advance_to(t0 + 2999ms);
  EXPECT_EQ(lcm_attempts, 2);
  loop_.advance_to(t0 + 3s);
  EXPECT_EQ(lcm_attempts, 3);
  EXPECT_EQ(pub.transports()[1].failures, 3u);
  EXPECT_EQ(log_.size(), 1u) << "logged once, not at every attempt";
  loop_.advance_to(t0 + 6999ms);
  EXPECT_EQ(lcm_samples, 0) << "nothing queued for it while down";
  loop_.advance_to(t0 + 7s);
  EXPECT_EQ(lcm_attempts, 4);
  ASSERT_TRUE(pub.transports()[1].up);
  EXPECT_TRUE(pub.degraded().empty());
  ASSERT_EQ(log_.size(), 2u);
  EXPECT_EQ(log_[1], "up: lcm up again after 3 failed attempts");
  // The status at once; every FE within one publish period (50 ms).
  EXPECT_GE(lcm_samples, 1);
  const int at_up = lcm_samples;
  loop_.advance_by(50ms);
  EXPECT_GE(lcm_samples, at_up + static_cast<int>(gw_->fes().size()) - 2) << "the input FEs republished";
  // Its commands are taken again: an LCM command for indicators.2 (sources canopen, dds) is
  // refused and counted — it reached the gateway.
  ASSERT_NE(lcm, nullptr);
  ASSERT_TRUE(lcm->on_indicator_command);
  lcm->on_indicator_command(gateway::IndicatorCommand{2, 0x3});
  EXPECT_EQ(gw_->refused_commands(), 1u);
  // No attempt more once it is up.
  loop_.advance_by(60s);
  EXPECT_EQ(lcm_attempts, 4);
}

TEST_F(PublishingDegrade, TheBackOffDoublesToTenSeconds) {
  EXPECT_EQ(PublisherLink::backoff(1), 1s);
  EXPECT_EQ(PublisherLink::backoff(2), 2s);
  EXPECT_EQ(PublisherLink::backoff(3), 4s);
  EXPECT_EQ(PublisherLink::backoff(4), 8s);
  EXPECT_EQ(PublisherLink::backoff(5), 10s);
  EXPECT_EQ(PublisherLink::backoff(1000), 10s);
}

// Bad configuration is still refused at start: only the machine's state degrades.
TEST_F(PublishingDegrade, ABadSettingIsRefusedAtStart) {
  int dds_attempts = 0, dds_samples = 0;
  const PublisherLink::Factory bad = []() -> std::unique_ptr<gateway::Publisher> {
    throw publish::PublishConfigError("publish.lcm.url: \"239.255.76.67:7667\" does not parse");
  };
  try {
    gateway::GatewayPublishing pub(
        *gw_, loaded_.config->publish, [this] { return loop_.now(); }, {flaky(0, "", &dds_attempts, &dds_samples), bad},
        log());
    FAIL() << "started with a bad setting";
  } catch (const publish::PublishConfigError& e) {
    EXPECT_EQ(std::string(e.what()), "publish.lcm.url: \"239.255.76.67:7667\" does not parse");
  }
  EXPECT_TRUE(log_.empty());
}

// An attempt on the running loop runs in a thread of its own: however long it takes to open
// (liblcm's self-test can wait 10 s), the loop goes on serving its timers (the buses' work);
// its outcome is taken on the loop when it comes.
TEST_F(PublishingDegrade, ARetryRunsBesideTheLoopNotInIt) {
  int dds_attempts = 0, dds_samples = 0, lcm_samples = 0;
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  int lcm_attempts = 0;
  const PublisherLink::Factory slow = [&lcm_attempts, &lcm_samples, released]() -> std::unique_ptr<gateway::Publisher> {
    if (++lcm_attempts == 1) throw publish::PublishUnavailable("no route");
    released.wait();  // opening blocks until the test lets it go
    return std::make_unique<FakeTransport>(&lcm_samples);
  };
  gateway::GatewayPublishing pub(
      *gw_, loaded_.config->publish, [this] { return loop_.now(); }, {flaky(0, "", &dds_attempts, &dds_samples), slow},
      log());
  pub.run_on(loop_, [] {});  // Attempts::InThread
  int ticks = 0;
  loop_.call_every(loop_.now(), 10ms, [&ticks] { ++ticks; });
  loop_.advance_by(1s);  // the retry starts in its thread and blocks there
  const int before = ticks;
  loop_.advance_by(500ms);
  for (int i = 0; i < 10; ++i) loop_.run_once(0ms);
  EXPECT_GE(ticks, before + 50) << "the loop ran on while the attempt was blocked";
  EXPECT_FALSE(pub.transports()[1].up);
  EXPECT_EQ(pub.transports()[1].next_attempt_in, std::nullopt) << "an attempt is running";
  release.set_value();
  for (int i = 0; i < 1000 && !pub.transports()[1].up; ++i) loop_.run_once(10ms);
  EXPECT_TRUE(pub.transports()[1].up);
  EXPECT_GE(lcm_samples, 1);
}

}  // namespace
