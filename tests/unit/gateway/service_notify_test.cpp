// What `oegw run` tells systemd (gateway/service_notify.hpp), on a simulated clock with a
// recording notifier: READY=1 once, STATUS= only when its text changes, WATCHDOG=1 every half of
// the watchdog time-out from the event loop, STOPPING=1 once.
#include "gateway/service_notify.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"

namespace oegw::gateway {
namespace {

using canopen::NmtState;
using subdevices::NodeState;
using namespace std::chrono_literals;
using ::testing::ElementsAre;

struct Recorder final : Notifier {
  std::vector<std::string> sent;
  void notify(const std::string& state) override { sent.push_back(state); }
  [[nodiscard]] long count(const std::string& s) const { return std::count(sent.begin(), sent.end(), s); }
};

ServiceState cab(NmtState up, NodeState grip, NodeState pedal) {
  return {up, 0x20, {{"grip", grip}, {"pedal", pedal}}};
}

TEST(ServiceStatus, NamesTheUpstreamStateAndTheSubDevicesThatAreNotOperational) {
  EXPECT_EQ(status_line(cab(NmtState::Operational, NodeState::Operational, NodeState::Operational)),
            "upstream operational, node 20h; 2/2 sub-devices operational");
  EXPECT_EQ(status_line(cab(NmtState::PreOperational, NodeState::Missing, NodeState::Configuring)),
            "upstream pre-operational, node 20h; 0/2 sub-devices operational; grip missing, pedal configuring");
  EXPECT_EQ(status_line(cab(NmtState::Operational, NodeState::Operational, NodeState::Refused)),
            "upstream operational, node 20h; 1/2 sub-devices operational; pedal refused");
}

// A publishing transport the machine cannot carry now runs degraded
// (docs/guides/dds-lcm.md#publishing-degrades-the-gateway-runs): named after the sub-devices.
TEST(ServiceStatus, NamesAPublishingTransportThatIsDown) {
  ServiceState st = cab(NmtState::Operational, NodeState::Operational, NodeState::Missing);
  st.degraded = {"lcm down: no route to 224.0.0.1 (Network is unreachable)"};
  EXPECT_EQ(status_line(st),
            "upstream operational, node 20h; 1/2 sub-devices operational; pedal missing; lcm down: no "
            "route to 224.0.0.1 (Network is unreachable)");
}

TEST(ServiceNotify, ReadyOnceTheUpstreamDeviceIsPastInitialisationAndOnlyOnce) {
  Recorder r;
  ServiceNotify n(r, std::nullopt);
  const canopen::TimePoint t{};
  n.update(t, cab(NmtState::Initialisation, NodeState::Idle, NodeState::Idle));
  EXPECT_EQ(r.count("READY=1"), 0);
  n.update(t + 1s, cab(NmtState::PreOperational, NodeState::Idle, NodeState::Idle));
  n.update(t + 2s, cab(NmtState::Operational, NodeState::Idle, NodeState::Idle));
  EXPECT_EQ(r.count("READY=1"), 1);
  EXPECT_TRUE(n.ready());
}

// A reload (SIGHUP): RELOADING=1 with MONOTONIC_USEC= in one message (sd_notify(3); systemd 252
// ignores the field, 253's Type=notify-reload needs it), then READY=1 and the STATUS= line with
// the reload's note, which every later STATUS= keeps.
TEST(ServiceNotify, ReloadingThenReadyWithTheReloadsNoteInStatus) {
  Recorder r;
  ServiceNotify n(r, std::nullopt);
  const canopen::TimePoint t{std::chrono::seconds(12)};
  const auto up = cab(NmtState::Operational, NodeState::Operational, NodeState::Operational);
  n.update(t, up);
  r.sent.clear();
  n.reloading(t + 1500us);
  n.reloaded("last reload refused: 2 errors (journal)", up);
  EXPECT_THAT(r.sent, ElementsAre("RELOADING=1\nMONOTONIC_USEC=12001500", "READY=1",
                                  "STATUS=upstream operational, node 20h; 2/2 sub-devices operational; last reload "
                                  "refused: 2 errors (journal)"));
  r.sent.clear();
  n.update(t + 2s, cab(NmtState::Operational, NodeState::Missing, NodeState::Operational));
  EXPECT_THAT(r.sent, ElementsAre("STATUS=upstream operational, node 20h; 1/2 sub-devices operational; grip missing; "
                                  "last reload refused: 2 errors (journal)"));
  r.sent.clear();
  n.reloading(t + 3s);
  n.reloaded("", up);  // applied: the note goes
  EXPECT_THAT(r.sent, ElementsAre("RELOADING=1\nMONOTONIC_USEC=15000000", "READY=1",
                                  "STATUS=upstream operational, node 20h; 2/2 sub-devices operational"));
}

// A reload does not hide what runs degraded: the READY=1 that ends it is followed by a STATUS=
// naming a publishing transport still down beside the reload's note, and the line changes again
// when the transport comes up (docs/guides/dds-lcm.md#publishing-degrades-the-gateway-runs).
TEST(ServiceNotify, AfterAReloadStatusStillNamesAPublishingTransportThatIsDown) {
  Recorder r;
  ServiceNotify n(r, std::nullopt);
  const canopen::TimePoint t{std::chrono::seconds(3)};
  auto lcm_down = cab(NmtState::Operational, NodeState::Operational, NodeState::Operational);
  lcm_down.degraded = {"lcm down: no route to 224.0.0.1 (Network is unreachable)"};
  n.update(t, lcm_down);
  r.sent.clear();
  n.reloading(t + 1s);
  n.reloaded("last reload refused: 1 error (journal)", lcm_down);
  EXPECT_THAT(r.sent,
              ElementsAre("RELOADING=1\nMONOTONIC_USEC=4000000", "READY=1",
                          "STATUS=upstream operational, node 20h; 2/2 sub-devices operational; lcm down: no "
                          "route to 224.0.0.1 (Network is unreachable); last reload refused: 1 error (journal)"));
  r.sent.clear();
  n.reloading(t + 2s);
  n.reloaded("", lcm_down);  // applied: the note goes, the transport is still down
  EXPECT_THAT(r.sent, ElementsAre("RELOADING=1\nMONOTONIC_USEC=5000000", "READY=1",
                                  "STATUS=upstream operational, node 20h; 2/2 sub-devices operational; lcm down: no "
                                  "route to 224.0.0.1 (Network is unreachable)"));
  r.sent.clear();
  auto lcm_up = lcm_down;
  lcm_up.degraded.clear();
  n.update(t + 3s, lcm_up);
  EXPECT_THAT(r.sent, ElementsAre("STATUS=upstream operational, node 20h; 2/2 sub-devices operational"));
}

TEST(ServiceNotify, StatusIsSentWhenItChangesNotOnEveryUpdate) {
  Recorder r;
  ServiceNotify n(r, std::nullopt);
  canopen::TimePoint t{};
  const auto booting = cab(NmtState::PreOperational, NodeState::Configuring, NodeState::WaitingBootUp);
  const auto up = cab(NmtState::PreOperational, NodeState::Operational, NodeState::Operational);
  for (int i = 0; i < 5; ++i) n.update(t += 1s, booting);
  for (int i = 0; i < 5; ++i) n.update(t += 1s, up);
  n.update(t += 1s, booting);
  EXPECT_THAT(r.sent,
              ElementsAre("READY=1",
                          "STATUS=upstream pre-operational, node 20h; 0/2 sub-devices operational; grip configuring, "
                          "pedal waiting for boot-up",
                          "STATUS=upstream pre-operational, node 20h; 2/2 sub-devices operational",
                          "STATUS=upstream pre-operational, node 20h; 0/2 sub-devices operational; grip configuring, "
                          "pedal waiting for boot-up"));
}

TEST(ServiceNotify, WithoutAWatchdogNoWatchdogMessageAndAPollEverySecond) {
  Recorder r;
  ServiceNotify n(r, std::nullopt);
  EXPECT_EQ(n.poll_period(), canopen::Duration(1s));
  for (int i = 0; i < 10; ++i)
    n.update(canopen::TimePoint{} + i * 1s, cab(NmtState::Operational, NodeState::Idle, NodeState::Idle));
  EXPECT_EQ(r.count("WATCHDOG=1"), 0);
}

// systemd's WatchdogSec=5s: WATCHDOG_USEC=5000000, a ping every 2.5 s (sd_watchdog_enabled(3)).
TEST(ServiceNotify, TheEventLoopPingsTheWatchdogAtHalfItsTimeOut) {
  canopen::io::SimulatedClock clock;
  canopen::io::EventLoop loop(clock);
  Recorder r;
  ServiceNotify n(r, canopen::Duration(5s));
  EXPECT_EQ(n.poll_period(), canopen::Duration(1s));  // the STATUS line follows within a second
  const auto state = cab(NmtState::Operational, NodeState::Operational, NodeState::Operational);
  n.update(loop.now(), state);  // at start: the first ping
  loop.call_every(loop.now() + n.poll_period(), n.poll_period(), [&] { n.update(loop.now(), state); });
  loop.advance_by(10s);
  // t = 0, 3, 6, 9 s: the first poll at least 2.5 s after the last ping.
  EXPECT_EQ(r.count("WATCHDOG=1"), 4);
  // A short time-out is polled at half of it: WatchdogSec=1s -> every 500 ms.
  Recorder fast;
  ServiceNotify f(fast, canopen::Duration(1s));
  EXPECT_EQ(f.poll_period(), canopen::Duration(500ms));
  canopen::TimePoint t{};
  for (int i = 0; i <= 10; ++i) f.update(t + i * 500ms, state);
  EXPECT_EQ(fast.count("WATCHDOG=1"), 11);
}

TEST(ServiceNotify, AStuckLoopPingsOnceWhenItRunsAgainNotABurst) {
  Recorder r;
  ServiceNotify n(r, canopen::Duration(2s));
  const auto state = cab(NmtState::Operational, NodeState::Operational, NodeState::Operational);
  n.update(canopen::TimePoint{}, state);
  n.update(canopen::TimePoint{} + 30s, state);  // 30 s without a poll: systemd has restarted us by now
  EXPECT_EQ(r.count("WATCHDOG=1"), 2);
  n.update(canopen::TimePoint{} + 30s + 500ms, state);  // the next ping is a period after the late one
  EXPECT_EQ(r.count("WATCHDOG=1"), 2);
}

TEST(ServiceNotify, StoppingOnceAndNothingAfterIt) {
  Recorder r;
  ServiceNotify n(r, canopen::Duration(2s));
  n.stopping();
  n.stopping();
  n.update(canopen::TimePoint{} + 10s, cab(NmtState::Operational, NodeState::Operational, NodeState::Operational));
  EXPECT_THAT(r.sent, ElementsAre("STOPPING=1"));
}

// Not started by systemd: no NOTIFY_SOCKET, no WATCHDOG_USEC; nothing is sent, nothing fails.
TEST(SystemdNotifier, WithoutSystemdThereIsNoWatchdogAndNotifyingDoesNothing) {
  ::unsetenv("NOTIFY_SOCKET");
  ::unsetenv("WATCHDOG_USEC");
  EXPECT_EQ(systemd_watchdog_timeout(), std::nullopt);
  SystemdNotifier sd;
  sd.notify("READY=1");  // sd_notify returns 0: no socket to send to
  ::setenv("WATCHDOG_USEC", "4000000", 1);
  EXPECT_EQ(systemd_watchdog_timeout(), std::optional<canopen::Duration>(4s));
  ::setenv("WATCHDOG_PID", "1", 1);  // meant for another process: not ours
  EXPECT_EQ(systemd_watchdog_timeout(), std::nullopt);
  ::unsetenv("WATCHDOG_USEC");
  ::unsetenv("WATCHDOG_PID");
}

}  // namespace
}  // namespace oegw::gateway
