// The DDS and LCM publishers against subscribers in another process (the example programs), the
// commands coming back, lcm-logger recording a session, and the errors for bad settings.
// All traffic stays on this host: Cyclone DDS's loopback-only configuration, LCM with ttl=0.
// The process runs in a private network namespace (private_network.hpp): lo only.
// Each test uses its own DDS partition / LCM channel prefix (by pid) so parallel runs do not mix.
#include <gtest/gtest.h>
#include <lcm/lcm.h>
#include <poll.h>
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <vector>

#include "dds/dds.h"
#include "oegw.h"
#include "oegw/display_command_t.hpp"
#include "oegw/indicator_command_t.hpp"
#include "publish/dds_publisher.hpp"
#include "publish/lcm_publisher.hpp"
#include "publish/lcm_url.hpp"
#include "publish/publish_schedule.hpp"
#include "tests/publish/child_process.hpp"
#include "tests/publish/private_network.hpp"
#include "tests/publish/subscriber_lines.hpp"

namespace oegw::gateway {
namespace {

using namespace std::chrono_literals;
using test::ChildProcess;
using test::line_of;
using test::without_rx;

// Forwards to a transport and remembers what went out.
struct Tee : Publisher {
  Publisher& out;
  std::vector<JoystickSample> joy;
  explicit Tee(Publisher& o) : out(o) {}
  void publish(const JoystickSample& s) override {
    joy.push_back(s);
    out.publish(s);
  }
  void publish(const PedalSample& s) override { out.publish(s); }
  void publish(const WheelSample& s) override { out.publish(s); }
  void publish(const EncoderSample& s) override { out.publish(s); }
  void publish(const ButtonClusterSample& s) override { out.publish(s); }
  void publish(const GatewayStatus& s) override { out.publish(s); }
};

// A joystick moving, standing still for a period, losing a button, then its device going quiet
// (stale) and offline: drives `sched` with a simulated clock; `after_each` runs after every step.
void move_joystick(publish::PublishSchedule& sched, const std::function<void()>& after_each) {
  std::int64_t t = 1'000'000;
  JoystickSample s;
  s.h.instance = 3;
  s.h.status = FeStatus::Valid;
  for (int i = 0; i < 8; ++i) {
    s.x = static_cast<std::int16_t>(i * 4000);
    s.y = static_cast<std::int16_t>(-i * 1000);
    s.z = static_cast<std::int16_t>(i % 2);
    s.buttons = static_cast<std::uint8_t>(1u << i);
    s.memory = static_cast<std::uint8_t>(i & 7);
    s.h.timestamp_us = t;
    sched.update(s, t);
    after_each();
    t += 10'000;
  }
  t += sched.period_us();
  sched.tick(t);  // still: republished, same values
  after_each();
  s.h.status = FeStatus::Stale;
  sched.update(s, t + 1);
  after_each();
  s.x = s.y = s.z = 0;  // fault value: neutral
  s.buttons = 0;
  s.h.status = FeStatus::Offline;
  sched.update(s, t + 2);
  after_each();
}

std::string unique(const char* base) { return std::string(base) + std::to_string(::getpid()); }

// Waits (bounded) until `ready` holds, handing the publisher's commands meanwhile.
bool wait_for(const std::function<bool()>& ready, std::chrono::milliseconds limit = 10s) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (!ready()) {
    if (std::chrono::steady_clock::now() > end) return false;
    ::poll(nullptr, 0, 5);
  }
  return true;
}

TEST(DdsPublisher, ASubscriberInAnotherProcessReceivesExactlyWhatIsPublished) {
  publish::DdsSettings s;
  s.partition = unique("oegw-test-");
  publish::DdsPublisher dds(s);
  ChildProcess sub({OEGW_DDS_SUBSCRIBER, "--count", "11", "--timeout", "30", "--partition", s.partition});
  ASSERT_EQ(sub.read_line(10s), "ready");
  ASSERT_TRUE(wait_for([&] { return dds.joystick_readers() >= 1; })) << "the subscriber was not discovered";

  Tee tee(dds);
  publish::PublishSchedule sched(tee, 100'000);
  std::size_t checked = 0;
  move_joystick(sched, [&] {
    // One sample per step; the reader keeps the last one per instance, so take each before the next.
    for (; checked < tee.joy.size(); ++checked) {
      auto l = sub.read_line(10s);
      ASSERT_TRUE(l.has_value()) << "sample " << checked << " not received";
      EXPECT_EQ(without_rx(*l), line_of(tee.joy[checked]));
    }
  });
  ASSERT_EQ(tee.joy.size(), 11u);
  EXPECT_EQ(tee.joy.back().h.status, FeStatus::Offline);
  EXPECT_EQ(tee.joy.back().h.seq, 11u);
  EXPECT_EQ(sub.wait(), 0);
}

TEST(LcmPublisher, ASubscriberInAnotherProcessReceivesExactlyWhatIsPublished) {
  publish::LcmSettings s;
  s.channel_prefix = unique("T") + "_";
  publish::LcmPublisher lcm(s);
  ChildProcess sub(
      {OEGW_LCM_SUBSCRIBER, "--count", "11", "--timeout", "30", "--channel", s.channel_prefix + "JOYSTICK_[0-9]+"});
  ASSERT_EQ(sub.read_line(10s), "ready");

  Tee tee(lcm);
  publish::PublishSchedule sched(tee, 100'000);
  std::size_t checked = 0;
  move_joystick(sched, [&] {
    for (; checked < tee.joy.size(); ++checked) {
      auto l = sub.read_line(10s);
      ASSERT_TRUE(l.has_value()) << "sample " << checked << " not received";
      EXPECT_EQ(without_rx(*l), line_of(tee.joy[checked]));
    }
  });
  ASSERT_EQ(tee.joy.size(), 11u);
  EXPECT_EQ(tee.joy.back().h.status, FeStatus::Offline);
  EXPECT_EQ(sub.wait(), 0);
}

TEST(LcmPublisher, LcmLoggerRecordsASessionThatDecodesWithTheProjectsTypes) {
  const std::string file = ::testing::TempDir() + unique("oegw-session-") + ".lcmlog";
  std::remove(file.c_str());
  publish::LcmSettings s;
  s.channel_prefix = unique("L") + "_";
  publish::LcmPublisher lcm(s);
  // (Debian's lcm-logger 1.3.1 lists -l but only takes the long form --lcm-url=.)
  ChildProcess logger({OEGW_LCM_LOGGER, "-q", "-f", "--flush-interval=10", "--lcm-url=" + s.url,
                       "--channel=" + s.channel_prefix + ".*", file});
  // lcm-logger says nothing when it is listening: send a probe until the log file has it.
  JoystickSample probe;
  probe.h.instance = 99;
  ASSERT_TRUE(wait_for([&] {
    lcm.publish(probe);
    struct stat st {};
    return ::stat(file.c_str(), &st) == 0 && st.st_size > 0;
  })) << "lcm-logger did not record";

  Tee tee(lcm);
  publish::PublishSchedule sched(tee, 100'000);
  move_joystick(sched, [] {});
  GatewayStatus gs;
  gs.seq = 1;
  gs.upstream_state = "operational";
  gs.subdevices.push_back({"right_grip", 0x11, "operational", {0x1000, 0x00, {0x21, 0x00, 0xFF, 0xFF, 0xFF}, 4100}, 2});
  // What it said at boot: 1018h:01 and :04, 1008h, 1001h (present bits 0, 3, 4, 7); the rest absent.
  gs.subdevices.back().identity = {0x0000012E, 0, 0, 0x00ABCDEF, "MFG grip", "", "", 0x01, 0x99};
  gs.subdevices.push_back({"pedal", 0x30, "missing", {}, 0});
  gs.active_emcys = {0x8130};
  gs.refused_commands = 2;
  gs.upstream_emcys.push_back({0x05, {0x8130, 0x11, {1, 2, 3, 4, 5}, 5000}, 1});
  lcm.publish(gs);
  // The logger writes in arrival order and flushes (at most every 10 ms) when a message comes in:
  // probes keep it flushing; once the status (the last session message) is in the file, so is the rest.
  const std::string status_channel = s.channel_prefix + "STATUS";
  ASSERT_TRUE(wait_for([&] {
    lcm.publish(probe);
    std::ifstream in(file, std::ios::binary);
    const std::string content((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return content.find(status_channel) != std::string::npos;
  })) << "the status did not reach the log";
  logger.signal(SIGINT);
  logger.wait();

  ChildProcess dec({OEGW_LCM_LOG_DECODE, file, s.channel_prefix});
  std::vector<std::string> lines;
  while (auto l = dec.read_line(10s)) lines.push_back(*l);
  EXPECT_EQ(dec.wait(), 0);
  std::vector<std::string> joy_lines;
  for (const auto& l : lines)
    if (l.rfind("joystick instance=3 ", 0) == 0) joy_lines.push_back(l);
  ASSERT_EQ(joy_lines.size(), tee.joy.size());
  for (std::size_t i = 0; i < joy_lines.size(); ++i) EXPECT_EQ(joy_lines[i], line_of(tee.joy[i]));
  // The status line, then one per sub-device and per upstream node (examples/lcm_log_decode.cpp).
  const auto status = std::find(lines.begin(), lines.end(),
                                "status seq=1 upstream=operational subdevices=2 emcys=1 refused=2 active=8130h");
  ASSERT_NE(status, lines.end());
  ASSERT_GE(lines.end() - status, 4);
  // Each sub-device with what its `present` mask says it had at boot (and only that).
  EXPECT_EQ(
      status[1],
      "  subdevice right_grip node=11h state=operational emcys=2 last=1000h reg=00h msef=21 00 ff ff ff ts_us=4100"
      " vendor=0000012Eh serial=00ABCDEFh name=\"MFG grip\" err=01h");
  EXPECT_EQ(
      status[2],
      "  subdevice pedal node=30h state=missing emcys=0 last=0000h reg=00h msef=00 00 00 00 00 ts_us=0 identity=none");
  EXPECT_EQ(status[3], "  upstream_emcy node=05h emcys=1 last=8130h reg=11h msef=01 02 03 04 05 ts_us=5000");
  // The summary (the joystick count includes the probes).
  const std::string rest = " pedal=0 wheel=0 encoder=0 buttons=0 indicators=0 display=0 status=1 other=0 bad=0";
  ASSERT_GE(lines.back().size(), rest.size());
  EXPECT_EQ(lines.back().substr(lines.back().size() - rest.size()), rest) << lines.back();
  std::remove(file.c_str());
}

TEST(DdsPublisher, CommandsSentOverDdsReachTheCallbacks) {
  publish::DdsSettings s;
  s.partition = unique("oegw-cmd-");
  publish::DdsPublisher dds(s);
  std::vector<IndicatorCommand> ind;
  std::vector<DisplayCommand> disp;
  dds.on_indicator_command = [&](const IndicatorCommand& c) { ind.push_back(c); };
  dds.on_display_command = [&](const DisplayCommand& c) { disp.push_back(c); };

  // The machine application's side: its own participant, writers on the command topics.
  const dds_entity_t pp = dds_create_participant(s.domain, nullptr, nullptr);
  ASSERT_GT(pp, 0);
  dds_qos_t* pq = dds_create_qos();
  dds_qset_partition1(pq, s.partition.c_str());
  const dds_entity_t pub = dds_create_publisher(pp, pq, nullptr);
  dds_delete_qos(pq);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  const dds_entity_t ti = dds_create_topic(pp, &oegw_IndicatorCommand_desc, "oegw/indicators", nullptr, nullptr);
  const dds_entity_t td = dds_create_topic(pp, &oegw_DisplayCommand_desc, "oegw/display", nullptr, nullptr);
  const dds_entity_t wi = dds_create_writer(pub, ti, q, nullptr);
  const dds_entity_t wd = dds_create_writer(pub, td, q, nullptr);
  dds_delete_qos(q);
  ASSERT_GT(wi, 0);
  ASSERT_GT(wd, 0);
  const auto matched = [](dds_entity_t w) {
    dds_publication_matched_status_t st{};
    return dds_get_publication_matched_status(w, &st) == 0 && st.current_count > 0;
  };
  ASSERT_TRUE(wait_for([&] { return matched(wi) && matched(wd); }));

  const oegw_IndicatorCommand ic{2, 0x8000000000000005ULL};
  oegw_DisplayCommand dc{};
  dc.instance = 1;
  for (int k = 0; k < 12; ++k) dc.parameters[k] = static_cast<std::int16_t>(k * 100 - 300);
  ASSERT_EQ(dds_write(wi, &ic), 0);
  ASSERT_EQ(dds_write(wd, &dc), 0);
  for (std::uint8_t instance = 3; instance <= 5; ++instance) {  // more waiting than one poll takes
    const oegw_IndicatorCommand more{instance, 1};
    ASSERT_EQ(dds_write(wi, &more), 0);
  }
  // One command per poll
  // (docs/reference/limits.md#can-first-what-the-event-loop-does-beside-the-buses); the fd is
  // signalled again while more wait, so a loop that polls only when it is readable still takes
  // every one.
  std::size_t most_per_poll = 0;
  ASSERT_TRUE(wait_for([&] {
    pollfd p{dds.fd(), POLLIN, 0};
    if (::poll(&p, 1, 0) > 0) {
      const std::size_t before = ind.size() + disp.size();
      dds.poll();
      most_per_poll = std::max(most_per_poll, ind.size() + disp.size() - before);
    }
    return ind.size() == 4 && !disp.empty();
  })) << "commands not received (fd "
      << dds.fd() << "): " << ind.size() << " indicator commands";
  EXPECT_EQ(most_per_poll, 1u);
  EXPECT_EQ(ind[0].instance, 2);
  EXPECT_EQ(ind[0].indicators, 0x8000000000000005ULL);
  EXPECT_EQ(disp[0].instance, 1);
  for (std::size_t k = 0; k < 12; ++k) EXPECT_EQ(disp[0].parameters[k], static_cast<int>(k) * 100 - 300);
  dds_delete(pp);
}

// The machine application's side of a DDS test: a participant of its own in the publisher's
// domain and partition.
struct DdsApp {
  dds_entity_t pp = 0, sub = 0;
  explicit DdsApp(const publish::DdsSettings& s) {
    pp = dds_create_participant(s.domain, nullptr, nullptr);
    dds_qos_t* pq = dds_create_qos();
    dds_qset_partition1(pq, s.partition.c_str());
    sub = dds_create_subscriber(pp, pq, nullptr);
    dds_delete_qos(pq);
  }
  ~DdsApp() { dds_delete(pp); }
  DdsApp(const DdsApp&) = delete;
  DdsApp& operator=(const DdsApp&) = delete;
};

TEST(DdsPublisher, AReaderAskingForThePeriodAsDeadlineSeesTheJoystickStop) {
  publish::DdsSettings s;
  s.partition = unique("oegw-deadline-");
  s.period_us = 20'000;
  publish::DdsPublisher dds(s);
  DdsApp app(s);
  const dds_entity_t t = dds_create_topic(app.pp, &oegw_Joystick_desc, "oegw/joystick", nullptr, nullptr);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(10));
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  dds_qset_deadline(q, DDS_USECS(s.period_us));  // what the gateway offers: compatible
  const dds_entity_t r = dds_create_reader(app.sub, t, q, nullptr);
  dds_delete_qos(q);
  ASSERT_GT(r, 0);
  ASSERT_TRUE(wait_for([&] { return dds.joystick_readers() >= 1; }));

  JoystickSample j;
  j.h.instance = 5;
  j.h.seq = 1;
  dds.publish(j);
  ASSERT_TRUE(wait_for([&] {
    void* p[1] = {nullptr};
    dds_sample_info_t si[1];
    const int n = dds_take(r, p, si, 1, 1);
    if (n > 0) dds_return_loan(r, p, n);
    return n > 0;
  }));
  // Nothing more is published: the reader is told the instance missed its deadline.
  dds_requested_deadline_missed_status_t st{};
  ASSERT_TRUE(wait_for([&] { return dds_get_requested_deadline_missed_status(r, &st) == 0 && st.total_count > 0; }))
      << "no deadline-missed status";
}

TEST(DdsPublisher, ALateReaderGetsTheLastGatewayStatus) {
  publish::DdsSettings s;
  s.partition = unique("oegw-status-");
  publish::DdsPublisher dds(s);
  GatewayStatus gs;
  gs.timestamp_us = 123;
  gs.seq = 7;
  gs.upstream_state = "operational";
  gs.subdevices = {{"right_grip", 0x11, "operational"},
                   {"left_grip", 0x03, "missing", {0x3120, 0x81, {0x00, 0x82, 0x00, 0x00, 0x00}, 987654}, 3}};
  gs.active_emcys = {0x8130, 0xFF01};
  gs.refused_commands = 3;
  gs.upstream_emcys = {{0x05, {0xFF01, 0x80, {9, 8, 7, 6, 5}, 1234}, 7}, {0x7E, {0x0000, 0x00, {}, 2345}, 1}};
  // The boot diagnostics: a string longer than the IDL's string<32> is cut.
  gs.subdevices[0].identity = {0xB4, 0x00010003, 0, 0, "JST", "0.00", std::string(40, 'v'), 0x01, 0x7F};
  dds.publish(gs);  // before any reader exists

  DdsApp app(s);
  const dds_entity_t t = dds_create_topic(app.pp, &oegw_GatewayStatus_desc, "oegw/status", nullptr, nullptr);
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(10));
  dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
  const dds_entity_t r = dds_create_reader(app.sub, t, q, nullptr);
  dds_delete_qos(q);
  ASSERT_GT(r, 0);
  void* p[1] = {nullptr};
  dds_sample_info_t si[1];
  int n = 0;
  ASSERT_TRUE(wait_for([&] { return (n = dds_take(r, p, si, 1, 1)) > 0; })) << "the status did not arrive";
  const auto* m = static_cast<const oegw_GatewayStatus*>(p[0]);
  EXPECT_EQ(m->seq, 7u);
  EXPECT_EQ(m->timestamp_us, 123);
  EXPECT_STREQ(m->upstream_state, "operational");
  ASSERT_EQ(m->subdevices._length, 2u);
  EXPECT_STREQ(m->subdevices._buffer[1].name, "left_grip");
  EXPECT_EQ(m->subdevices._buffer[1].node_id, 0x03);
  EXPECT_STREQ(m->subdevices._buffer[1].state, "missing");
  ASSERT_EQ(m->active_emcys._length, 2u);
  EXPECT_EQ(m->active_emcys._buffer[0], 0x8130);
  EXPECT_EQ(m->active_emcys._buffer[1], 0xFF01);
  EXPECT_EQ(m->refused_commands, 3u);
  // Each sub-device's last EMCY and count (zeros before the first), the EMCYs consumed upstream.
  const auto& none = m->subdevices._buffer[0];
  EXPECT_EQ(none.last_emcy.code, 0);
  EXPECT_EQ(none.last_emcy.timestamp_us, 0);
  EXPECT_EQ(none.emcy_count, 0u);
  EXPECT_EQ(none.identity.vendor_id, 0xB4u);
  EXPECT_EQ(none.identity.product_code, 0x00010003u);
  EXPECT_STREQ(none.identity.device_name, "JST");
  EXPECT_STREQ(none.identity.hardware_version, "0.00");
  EXPECT_EQ(std::string(none.identity.software_version), std::string(32, 'v'));
  EXPECT_EQ(none.identity.error_register, 0x01);
  EXPECT_EQ(none.identity.present, 0x7F);
  const auto& mcb = m->subdevices._buffer[1];
  EXPECT_EQ(mcb.identity.present, 0) << "nothing read yet";
  EXPECT_EQ(mcb.last_emcy.code, 0x3120);
  EXPECT_EQ(mcb.last_emcy.error_register, 0x81);
  EXPECT_EQ(std::vector<std::uint8_t>(mcb.last_emcy.msef, mcb.last_emcy.msef + 5),
            (std::vector<std::uint8_t>{0, 0x82, 0, 0, 0}));
  EXPECT_EQ(mcb.last_emcy.timestamp_us, 987654);
  EXPECT_EQ(mcb.emcy_count, 3u);
  ASSERT_EQ(m->upstream_emcys._length, 2u);
  const auto& u = m->upstream_emcys._buffer[0];
  EXPECT_EQ(u.node_id, 0x05);
  EXPECT_EQ(u.last.code, 0xFF01);
  EXPECT_EQ(u.last.error_register, 0x80);
  EXPECT_EQ(std::vector<std::uint8_t>(u.last.msef, u.last.msef + 5), (std::vector<std::uint8_t>{9, 8, 7, 6, 5}));
  EXPECT_EQ(u.last.timestamp_us, 1234);
  EXPECT_EQ(u.count, 7u);
  EXPECT_EQ(m->upstream_emcys._buffer[1].node_id, 0x7E);
  EXPECT_EQ(m->upstream_emcys._buffer[1].count, 1u);
  dds_return_loan(r, p, n);
}

TEST(LcmPublisher, CommandsSentOverLcmReachTheCallbacks) {
  publish::LcmSettings s;
  s.channel_prefix = unique("C") + "_";
  publish::LcmPublisher lcm(s);
  std::vector<IndicatorCommand> ind;
  std::vector<DisplayCommand> disp;
  lcm.on_indicator_command = [&](const IndicatorCommand& c) { ind.push_back(c); };
  lcm.on_display_command = [&](const DisplayCommand& c) { disp.push_back(c); };

  lcm_t* app = lcm_create(s.url.c_str());
  ASSERT_NE(app, nullptr);
  oegw::indicator_command_t ic;
  ic.instance = 4;
  ic.indicators = static_cast<std::int64_t>(0x8000000000000003ULL);
  oegw::display_command_t dc;
  dc.instance = 8;
  for (int k = 0; k < 12; ++k) dc.parameters[k] = static_cast<std::int16_t>(-k);
  const auto send = [&](const std::string& ch, const auto& m) {
    std::vector<std::uint8_t> buf(static_cast<std::size_t>(m.getEncodedSize()));
    m.encode(buf.data(), 0, static_cast<int>(buf.size()));
    lcm_publish(app, ch.c_str(), buf.data(), static_cast<unsigned>(buf.size()));
  };
  send(s.channel_prefix + "INDICATORS_4", ic);
  send(s.channel_prefix + "DISPLAY_8", dc);
  send(s.channel_prefix + "JOYSTICK_1", dc);  // not a command channel: ignored
  // One message per poll
  // (docs/reference/limits.md#can-first-what-the-event-loop-does-beside-the-buses); liblcm's fd
  // stays readable while more wait.
  std::size_t most_per_poll = 0;
  ASSERT_TRUE(wait_for([&] {
    pollfd p{lcm.fd(), POLLIN, 0};
    if (::poll(&p, 1, 0) > 0) {
      const std::size_t before = ind.size() + disp.size();
      lcm.poll();
      most_per_poll = std::max(most_per_poll, ind.size() + disp.size() - before);
    }
    return !ind.empty() && !disp.empty();
  }));
  EXPECT_EQ(most_per_poll, 1u);
  lcm_destroy(app);
  EXPECT_EQ(ind.size(), 1u);
  EXPECT_EQ(ind[0].instance, 4);
  EXPECT_EQ(ind[0].indicators, 0x8000000000000003ULL);
  EXPECT_EQ(disp[0].instance, 8);
  for (std::size_t k = 0; k < 12; ++k) EXPECT_EQ(disp[0].parameters[k], -static_cast<int>(k));
}

// What a publisher's constructor throws: a bad setting (PublishConfigError), or with `unavailable`
// set what the machine cannot carry now (PublishUnavailable;
// docs/guides/dds-lcm.md#publishing-degrades-the-gateway-runs).
std::string error_of(const std::function<void()>& f, bool* unavailable = nullptr) {
  try {
    f();
  } catch (const publish::PublishUnavailable& e) {
    std::fprintf(stderr, "unavailable: %s\n", e.what());
    if (unavailable != nullptr) *unavailable = true;
    return e.what();
  } catch (const publish::PublishConfigError& e) {
    std::fprintf(stderr, "refused: %s\n", e.what());
    return e.what();
  }
  return "(no error)";
}

TEST(PublishSettings, ADdsDomainThatCannotBeCreatedIsNamed) {
  publish::DdsSettings s;
  s.domain = 300;  // beyond Cyclone's 0..230
  const std::string e = error_of([&] { publish::DdsPublisher p(s); });
  EXPECT_EQ(e.rfind("publish.dds.domain: cannot create domain 300: ", 0), 0u) << e;
  EXPECT_NE(e.find("out of range"), std::string::npos) << e;  // Cyclone's reason, from its log
}

// An interface that is not there (yet) is the machine's state, not the setting's: oegw run starts
// without DDS and opens it when the interface appears.
TEST(PublishSettings, AMissingDdsInterfaceIsUnavailableAndNamed) {
  publish::DdsSettings s;
  s.domain = 3;
  s.network = "oegwnope0";
  bool unavailable = false;
  const std::string e = error_of([&] { publish::DdsPublisher p(s); }, &unavailable);
  EXPECT_TRUE(unavailable) << e;
  EXPECT_EQ(e.rfind("publish.dds.network: interface oegwnope0 is not on this machine (", 0), 0u) << e;
}

TEST(PublishSettings, AnLcmUrlThatDoesNotParseIsNamed) {
  publish::LcmSettings s;
  s.url = "239.255.76.67:7667";
  const std::string e = error_of([&] { publish::LcmPublisher p(s); });
  EXPECT_EQ(e.rfind("publish.lcm.url: \"239.255.76.67:7667\" does not parse", 0), 0u) << e;
}

TEST(PublishSettings, AnLcmUrlThatCannotBeOpenedIsNamed) {
  publish::LcmSettings s;
  s.url = "nosuchprovider://239.255.76.67:7667?ttl=0";
  const std::string e = error_of([&] { publish::LcmPublisher p(s); });
  EXPECT_EQ(e.rfind("publish.lcm.url: cannot open \"nosuchprovider://", 0), 0u) << e;
}

bool g_private_network = false;  // main(): this process has a network namespace of its own

// A controller whose only interface is lo, with no multicast route: liblcm cannot send to the
// group. The machine's state, not the URL's: unavailable, naming the command that adds a route.
TEST(PublishSettings, AnLcmGroupWithoutARouteIsUnavailableAndNamesTheCommand) {
  if (!g_private_network) GTEST_SKIP() << "needs its own network namespace (root) to take the route away";
  ASSERT_EQ(std::system("ip route del 224.0.0.0/4 dev lo"), 0);
  struct Restore {
    ~Restore() { EXPECT_EQ(std::system("ip route add 224.0.0.0/4 dev lo"), 0); }
  } restore;
  publish::LcmSettings s;  // udpm://224.0.0.1:7667?ttl=0
  bool unavailable = false;
  const std::string e = error_of([&] { publish::LcmPublisher p(s); }, &unavailable);
  EXPECT_TRUE(unavailable) << e;
  EXPECT_EQ(e,
            "publish.lcm.url: \"udpm://224.0.0.1:7667?ttl=0\": no route to 224.0.0.1 (Network is unreachable) — add "
            "one: ip route add 224.0.0.0/4 dev lo");
  EXPECT_EQ(publish::lcm_route_problem(s.url), "no route to 224.0.0.1 (Network is unreachable)");
}

TEST(PublishSettings, ABadLcmChannelPrefixIsNamed) {
  publish::LcmSettings s;
  s.channel_prefix = "OEGW .*";
  const std::string e = error_of([&] { publish::LcmPublisher p(s); });
  EXPECT_EQ(e.rfind("publish.lcm.channel_prefix: ", 0), 0u) << e;
}

TEST(PublishSettings, TheLoopbackDdsConfigurationKeepsTrafficOnThisHost) {
  const std::string xml = publish::dds_config_xml("loopback");
  EXPECT_NE(xml.find("<NetworkInterface name=\"lo\"/>"), std::string::npos);
  EXPECT_NE(xml.find("<AllowMulticast>false</AllowMulticast>"), std::string::npos);
  EXPECT_NE(xml.find("<Peer address=\"127.0.0.1\"/>"), std::string::npos);
  EXPECT_EQ(publish::LcmSettings{}.url, "udpm://224.0.0.1:7667?ttl=0");
  EXPECT_EQ(publish::DdsSettings{}.network, "loopback");
}

}  // namespace
}  // namespace oegw::gateway

int main(int argc, char** argv) {
  // Before gtest or any transport starts a thread: this process and the subscribers, lcm-logger
  // and decoder it starts see only a loopback interface.
  oegw::gateway::g_private_network = oegw::test::enter_private_network();
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
