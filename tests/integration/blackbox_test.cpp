// The black box end to end (docs/guides/black-box.md): the simulated cab of the demo on the
// virtual buses, its gateway recorded by the Recorder into real files through an incident —
// the grip's cable pulled, an MCB-402 cable break (EMCY 3120h), the host's heartbeat lost, the
// grip rebooted — then replayed from those files by a new gateway on the simulated clock.
// Nothing sleeps: the cab runs on a simulated clock, the Recorder's writer is waited for with
// flush().
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include <fmt/format.h>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "gateway/record/gateway_recorder.hpp"
#include "gateway/record/plot.hpp"
#include "gateway/record/recorder.hpp"
#include "gateway/record/recording_service.hpp"
#include "gateway/record/replay.hpp"
#include "rig/cab_rig.hpp"
#include "tests/fixtures/fixtures.hpp"
#include "tests/integration/cab_steps.hpp"

namespace oegw::gateway::record {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using canopen::CanFrame;

constexpr canopen::NodeId kGw{0x20};

class Blackbox : public ::testing::Test {
 protected:
  void SetUp() override {
    char tmpl[] = "/tmp/oegw-blackbox-test-XXXXXX";
    dir_ = ::mkdtemp(tmpl);
    config_ = oegw::testing::fixture_config("demo_cab.yaml");
    RecorderSettings s;
    s.dir = dir_ / "record";
    s.run = "20261205T140312Z";
    s.up_iface = "can0";
    s.down_iface = "can1";
    s.max_bytes = 4u << 20;
    s.segments = 40;  // 100 KiB a segment: the incident fills several
    s.wall_offset_us = [] { return std::int64_t{1'764'900'000'000'000}; };
    // The rig's instant buses: its gateway's SDO is not paced (CabRigOptions), and the replay
    // must know it; on the timed buses it is, as in oegw run.
    s.header = {timed_ ? "meta gateway sdo_bus_share=0.85" : "meta gateway sdo_bus_share=0"};
    s.states = true;  // as oegw run's RecordingService: each segment begins with the gateway's state
    recorder_ = std::make_unique<Recorder>(s);
    rig_ = std::make_unique<rig::CabRig>(config_, loop_,
                                         rig::CabRigOptions{.store = dir_ / "upstream.store", .timed_buses = timed_});
    tap_ = std::make_unique<GatewayRecorder>(*recorder_);
    states_ = std::make_unique<StateGiver>(*recorder_, *tap_);
    rig_->on_gateway = [this](Gateway& g) {
      gw_ = &g;
      g.set_tap(tap_.get());
    };
    rig_->from_devices = [this](const CanFrame& f) { return pulled_ && (f.id & 0x7F) == 0x11; };
    rig_->build();
    loop_.call_every(loop_.now() + StateGiver::kPoll, StateGiver::kPoll, [this] {
      if (!recording_) return;
      // The writer runs on real time, the cab on the simulated clock: it is waited for, so that
      // it has seen each segment's size when the loop looks.
      recorder_->flush();
      states_->offer(gw_, loop_.now());
    });
  }
  void TearDown() override {
    rig_.reset();
    tap_.reset();
    recorder_.reset();
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  void cmd(const std::string& line) { oegw::testing::cab_command(*rig_, line); }
  void sdo_write(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data) {
    oegw::testing::host_sdo_write(*rig_, kGw, index, sub, std::move(data));
  }
  void sweep(canopen::Duration d) { oegw::testing::sweep(*rig_, d); }

  // The recorded incident; the recording is complete when it returns.
  void incident() {
    rig_->power_on();
    rig_->run_for(3s);
    sdo_write(0x1800, 1, {0xA0, 0x01, 0x00, 0x00});  // TPDO 1 on 1A0h
    sdo_write(0x6423, 0, {1});
    if (store_then_reset_) sdo_write(0x1010, 1, {0x73, 0x61, 0x76, 0x65});  // "save": TPDO 1 on 1A0h, stored
    // The host's heartbeat (701h, 100 ms), consumed by the gateway (1016h:01, 250 ms).
    loop_.call_every(loop_.now(), 100ms, [this] {
      if (host_alive_) (void)rig_->host_port().send(CanFrame(0x701, {0x05}));
    });
    sdo_write(0x1016, 1, {0xFA, 0x00, 0x01, 0x00});
    rig_->host().nmt().start(kGw);
    sweep(1s);
    // The machine application's commands (DDS, LCM: the one an FE does not take is refused), a
    // sub-device command and an NMT command from the control socket: inputs replayed as recorded.
    (void)gw_->command_indicators(2, 0x05, loop_.now(), mapping::CommandSource::Dds);
    (void)gw_->command_indicators(2, 0x0A, loop_.now(), mapping::CommandSource::Lcm);
    (void)gw_->subdevice_command("seat_knob", "position_error_reset", loop_.now());
    (void)gw_->downstream_nmt(canopen::NodeId{0x30}, canopen::NmtCommand::EnterPreOperational, loop_.now());
    rig_->rearm();
    sweep(1s);
    pulled_ = true;  // the right grip's cable
    sweep(1500ms);
    pulled_ = false;
    sweep(3s);
    if (keep_midway_) {
      recorder_->keep([](std::optional<KeptWindow>, std::string) {});
      recorder_->flush();  // the writer closes the segment there: the next has `state none`
    }
    cmd("left_grip cable_break 2 on");
    sweep(500ms);
    cmd("left_grip cable_break 2 off");
    sweep(1s);
    host_alive_ = false;
    sweep(600ms);
    host_alive_ = true;
    sweep(1s);
    cmd("right_grip reboot");
    sweep(4s);
    if (store_then_reset_) {
      rig_->host().nmt().reset_node(kGw);  // the stored TPDO 1 comes back...
      sweep(1s);
      rig_->host().nmt().start(kGw);  // ...and sends
      sweep(1s);
    }
    gw_->set_tap(nullptr);
    recording_ = false;
    recorder_->flush();
  }

  // One run, replayed exactly to its end: no divergence (else both sides shown), nothing stopped.
  static void expect_exact(const std::vector<RunReport>& reports) {
    ASSERT_EQ(reports.size(), 1u);
    EXPECT_EQ(reports[0].mode, ReplayMode::Exact);
    EXPECT_FALSE(reports[0].divergence) << reports[0].divergence->when << "\nafter " << reports[0].divergence->after
                                        << "\nrecorded " << reports[0].divergence->recorded << "\nreplayed "
                                        << reports[0].divergence->replayed;
    EXPECT_EQ(reports[0].stopped, "");
  }

  std::vector<RunReport> replay_all(std::ostream* timeline = nullptr, PlotData* plot = nullptr,
                                    const fs::path& where = {}) {
    std::string error;
    const auto runs = find_runs(where.empty() ? dir_ / "record" : where, error);
    EXPECT_TRUE(runs) << error;
    if (!runs) return {};
    ReplayOptions o;
    o.timeline = timeline;
    o.plot = plot;
    o.gateway.sdo_bus_share = 0.85;  // the recording's meta line must win over this
    return replay(*runs, config_, o);
  }

  fs::path dir_;
  mapping::Config config_;
  canopen::io::SimulatedClock clock_;
  canopen::io::EventLoop loop_{clock_};
  std::unique_ptr<Recorder> recorder_;
  std::unique_ptr<rig::CabRig> rig_;
  std::unique_ptr<GatewayRecorder> tap_;
  std::unique_ptr<StateGiver> states_;
  bool recording_ = true;
  bool keep_midway_ = false;       // a window kept in the middle of the incident
  bool store_then_reset_ = false;  // the host stores the parameters early, resets the gateway late
  Gateway* gw_ = nullptr;
  bool pulled_ = false, host_alive_ = true;
  bool timed_ = false;  // the timed virtual buses (frames take their time on the wire)
};

// The same cab on the timed buses: the frames of the recording take their real time on the
// wire, as a candump of a real bus shows them.
class BlackboxTimed : public Blackbox {
 protected:
  BlackboxTimed() { timed_ = true; }
};

TEST_F(Blackbox, TheReplayOfAnIncidentMakesTheSameFramesAndDecisions) {
  incident();
  std::ostringstream timeline;
  const auto reports = replay_all(&timeline);
  ASSERT_EQ(reports.size(), 1u);
  const RunReport& r = reports[0];
  EXPECT_EQ(r.mode, ReplayMode::Exact);
  EXPECT_FALSE(r.divergence) << r.divergence->when << "\nafter " << r.divergence->after << "\nrecorded "
                             << r.divergence->recorded << "\nreplayed " << r.divergence->replayed;
  EXPECT_EQ(r.stopped, "");
  EXPECT_TRUE(r.notes.empty()) << r.notes.front();
  EXPECT_GT(r.frames_in, 2000u);
  EXPECT_GT(r.compared, 2000u);
  EXPECT_GT(recorder_->status().segments, 2u) << "the incident spans several segments";
  // Each segment after the first begins with the gateway's state, and the replayed gateway was in
  // each (Gateway::export_state, compared key by key).
  EXPECT_EQ(r.states, recorder_->status().segments - 1);
  // The incident is on the timeline: the cable pull, the EMCY, the host's heartbeat, the reboot.
  const std::string t = timeline.str();
  for (const char* expected :
       {"fault right_grip raised", "fault right_grip cleared", "emcy left_grip 3120", "emcy_sent 8130",
        "node right_grip missing", "fe joystick.1 offline", "fe joystick.1 offline buttons[1]=0[offline] buttons[2]=0",
        "fe pedal.1 valid position=-", "indicators 2 0000000000000005 dds\n", "indicators 2 000000000000000A lcm\n",
        "outcome refused", "subdevice_command seat_knob position_error_reset", "nmt 30 80", "node pedal missing"})
    EXPECT_NE(t.find(expected), std::string::npos) << expected << " not on the timeline";
}

// Control-socket requests: `status` changes nothing and the comparison goes on past it; a
// session that reaches into the gateway (an `oegw ctl` remote SDO) is recorded, not replayed:
// the comparison ends there, with the reason.
TEST_F(Blackbox, AStatusRequestIsComparedPastAControlSessionEndsTheComparison) {
  rig_->power_on();
  rig_->run_for(3s);
  gw_->control_request(R"({"protocol": 1, "command": "status"})", loop_.now());
  rig_->run_for(1s);
  (void)gw_->remote_sdo(loop_.now());
  rig_->run_for(1s);
  gw_->set_tap(nullptr);
  recorder_->flush();
  const auto reports = replay_all();
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_FALSE(reports[0].divergence);
  EXPECT_NE(reports[0].stopped.find("a control-socket session reached into the gateway (remote_sdo)"),
            std::string::npos)
      << reports[0].stopped;
  EXPECT_GT(reports[0].compared, 100u) << "compared up to the session, past the status request";
}

// A window kept in the middle (oegw record keep) closes the segment there; the next begins with
// `state none` and the loop gives a state soon after. The whole recording still replays
// exactly, every state checked, and so does the kept window on its own.
TEST_F(Blackbox, AWindowKeptMidwayLeavesTheReplayExact) {
  keep_midway_ = true;
  incident();
  const auto reports = replay_all();
  expect_exact(reports);
  EXPECT_GT(reports[0].states, 1u);
  std::string all;
  for (const auto& e : fs::directory_iterator(dir_ / "record")) {
    if (e.path().extension() != ".events") continue;
    std::ifstream in(e.path());
    all += std::string(std::istreambuf_iterator<char>(in), {});
  }
  EXPECT_NE(all.find("state none (a window was kept: the segment before it closed there)"), std::string::npos);
  const auto kept = fs::directory_iterator(dir_ / "record" / "kept")->path();
  const auto window = replay_all(nullptr, nullptr, kept);
  ASSERT_EQ(window.size(), 1u);
  EXPECT_EQ(window[0].mode, ReplayMode::Exact);
  EXPECT_FALSE(window[0].divergence);
}

// A segment's state the replayed gateway is not in is a divergence, named by its first key
// that differs; a state line damaged on the disk is no state (noted, not compared).
TEST_F(Blackbox, AStateTheReplayedGatewayIsNotInDivergesThere) {
  incident();
  const fs::path events = dir_ / "record" / "20261205T140312Z-000002.events";
  std::ifstream in(events);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  in.close();
  const auto line = std::find_if(lines.begin(), lines.end(),
                                 [](const std::string& l) { return l.find(" state crc32=") != std::string::npos; });
  ASSERT_NE(line, lines.end());
  const auto text_at = line->find("state crc32=");
  std::string error;
  auto state = parse_state_event(line->substr(text_at), error);
  ASSERT_TRUE(state) << error;
  const auto key = state->find("\ncommands_refused ");
  ASSERT_NE(key, std::string::npos);
  const auto end = state->find('\n', key + 1);
  const std::string was = state->substr(key + 1, end - key - 1);
  state->replace(key + 1, end - key - 1, "commands_refused 77");
  const std::string original = *line;
  *line = line->substr(0, text_at) + state_event(*state);
  const auto write = [&] {
    std::ofstream out(events, std::ios::trunc);
    for (const auto& l : lines) out << l << '\n';
  };
  write();
  auto reports = replay_all();
  ASSERT_EQ(reports.size(), 1u);
  ASSERT_TRUE(reports[0].divergence);
  EXPECT_EQ(reports[0].divergence->recorded, "state commands_refused 77 (" + events.string() + ":4)");
  EXPECT_EQ(reports[0].divergence->replayed, "state " + was);
  // The same line with a byte damaged: not a state, noted; the replay is exact.
  *line = original;
  (*line)[line->size() - 3] = (*line)[line->size() - 3] == '0' ? '1' : '0';
  write();
  reports = replay_all();
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_FALSE(reports[0].divergence);
  ASSERT_EQ(reports[0].notes.size(), 1u);
  EXPECT_EQ(reports[0].notes[0],
            events.string() + ":4: state not read: the state's CRC-32 differs from its line's: the line is damaged");
}

TEST_F(Blackbox, AnEditedFrameDivergesAtThatFrame) {
  incident();
  // The 500th TPDO of the right grip, its x changed.
  std::string error;
  const auto runs = find_runs(dir_ / "record", error);
  ASSERT_TRUE(runs) << error;
  int seen = 0;
  std::string edited_where;
  for (const auto& seg : runs->front().segments) {
    std::ifstream in(seg.log);
    std::vector<std::string> lines;
    for (std::string l; std::getline(in, l);) lines.push_back(l);
    for (std::size_t i = 0; i < lines.size() && edited_where.empty(); ++i) {
      if (lines[i].find(" can1 191#") == std::string::npos || ++seen < 500) continue;
      const auto hash = lines[i].find('#');
      lines[i][hash + 2] = lines[i][hash + 2] == '7' ? '1' : '7';  // x's high nibble of its first byte
      edited_where = fmt::format("{}:{}", seg.log.string(), i + 1);
    }
    if (edited_where.empty()) continue;
    std::ofstream out(seg.log, std::ios::trunc);
    for (const auto& l : lines) out << l << '\n';
    break;
  }
  ASSERT_FALSE(edited_where.empty());
  const auto reports = replay_all();
  ASSERT_EQ(reports.size(), 1u);
  ASSERT_TRUE(reports[0].divergence) << "the edited frame went unnoticed";
  EXPECT_NE(reports[0].divergence->after.find(edited_where), std::string::npos)
      << "diverged after " << reports[0].divergence->after << ", edited " << edited_where;
  EXPECT_NE(reports[0].divergence->replayed, reports[0].divergence->recorded);
}

// The first state line of `events` replaced by `text` (the line's time and place kept), or with
// `text` before it when `before`.
void edit_first_state(const fs::path& events, const std::string& text, bool before = false) {
  std::vector<std::string> lines;
  {
    std::ifstream in(events);
    for (std::string l; std::getline(in, l);) lines.push_back(l);
  }
  const auto line = std::find_if(lines.begin(), lines.end(),
                                 [](const std::string& l) { return l.find(" state ") != std::string::npos; });
  ASSERT_NE(line, lines.end()) << events;
  const std::string edited = line->substr(0, line->find(" state ") + 1) + text;
  if (before) lines.insert(line, edited);
  else *line = edited;
  std::ofstream out(events, std::ios::trunc);
  for (const auto& l : lines) out << l << '\n';
}

// A window whose start has left the ring (a kept window of a gateway that ran longer than the
// ring holds) is replayed from its first segment's state: the same frames and decisions, every
// later state checked; an edited frame inside it still diverges there.
TEST_F(Blackbox, AWindowWithoutItsStartReplaysExactlyFromItsFirstState) {
  incident();
  fs::remove(dir_ / "record" / "20261205T140312Z-000000.log");
  fs::remove(dir_ / "record" / "20261205T140312Z-000000.events");
  auto reports = replay_all();
  expect_exact(reports);
  const fs::path second = dir_ / "record" / "20261205T140312Z-000001.events";
  EXPECT_NE(reports[0].from_state.find("(" + second.string() + ":"), std::string::npos) << reports[0].from_state;
  EXPECT_TRUE(reports[0].notes.empty()) << reports[0].notes.front();
  EXPECT_GT(reports[0].compared, 1000u);
  EXPECT_EQ(reports[0].states, recorder_->status().segments - 2) << "each state after the one it began in";
  // Records lost before the state (the writer tells them by a `gap` line before it) are none of
  // the replay's: it begins in the state all the same.
  edit_first_state(dir_ / "record" / "20261205T140312Z-000001.events", "gap frames=3 events=0 (a failed write)", true);
  reports = replay_all();
  expect_exact(reports);
  EXPECT_NE(reports[0].from_state, "");
  // The 100th TPDO of the right grip in the third segment, its x changed.
  const fs::path log = dir_ / "record" / "20261205T140312Z-000002.log";
  std::vector<std::string> lines;
  {
    std::ifstream in(log);
    for (std::string l; std::getline(in, l);) lines.push_back(l);
  }
  int seen = 0;
  std::string edited_where;
  for (std::size_t i = 0; i < lines.size() && edited_where.empty(); ++i) {
    if (lines[i].find(" can1 191#") == std::string::npos || ++seen < 100) continue;
    const auto hash = lines[i].find('#');
    lines[i][hash + 2] = lines[i][hash + 2] == '7' ? '1' : '7';
    edited_where = fmt::format("{}:{}", log.string(), i + 1);
  }
  ASSERT_FALSE(edited_where.empty());
  {
    std::ofstream out(log, std::ios::trunc);
    for (const auto& l : lines) out << l << '\n';
  }
  reports = replay_all();
  ASSERT_EQ(reports.size(), 1u);
  ASSERT_TRUE(reports[0].divergence) << "the edited frame went unnoticed";
  EXPECT_NE(reports[0].divergence->after.find(edited_where), std::string::npos)
      << "diverged after " << reports[0].divergence->after << ", edited " << edited_where;
}

// The segment of `run` whose frames hold `frame` ("can0 000#8120"); -1: none.
int segment_with(const Run& run, const std::string& frame) {
  for (std::size_t i = 0; i < run.segments.size(); ++i) {
    std::ifstream in(run.segments[i].log);
    const std::string all(std::istreambuf_iterator<char>(in), {});
    if (all.find(frame) != std::string::npos) return static_cast<int>(i);
  }
  return -1;
}

// The host stores the parameters before the window and resets the gateway inside it: the replay
// begun in the window's first state is given the store the run had then, not the run's first
// one (none here): the stored TPDO 1 comes back with the reset in both.
TEST_F(Blackbox, AWindowReplayedFromItsStateHasTheStoreOfThatMoment) {
  store_then_reset_ = true;
  incident();
  std::string error;
  const auto runs = find_runs(dir_ / "record", error);
  ASSERT_TRUE(runs) << error;
  ASSERT_EQ(segment_with(runs->front(), "can0 620#2310100173617665"), 0) << "the save before the window";
  const int reset = segment_with(runs->front(), "can0 000#8120");
  ASSERT_GE(reset, 2) << "the reset inside the window, past its first state";
  fs::remove(dir_ / "record" / "20261205T140312Z-000000.log");
  fs::remove(dir_ / "record" / "20261205T140312Z-000000.events");
  const auto reports = replay_all();
  expect_exact(reports);
  EXPECT_NE(reports[0].from_state, "");
  EXPECT_GT(reports[0].states, 1u);
}

// A state of another mapping file is not taken: shown as recorded, and why.
TEST_F(Blackbox, AStateOfAnotherMappingFileIsNotBegunIn) {
  incident();
  fs::remove(dir_ / "record" / "20261205T140312Z-000000.log");
  fs::remove(dir_ / "record" / "20261205T140312Z-000000.events");
  ASSERT_GT(config_.functional_elements.size(), 1u);
  config_.functional_elements.pop_back();
  const auto reports = replay_all();
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].mode, ReplayMode::Recorded);
  EXPECT_EQ(reports[0].from_state, "");
  ASSERT_FALSE(reports[0].notes.empty());
  EXPECT_NE(reports[0].notes.back().find("its first segment's state ("), std::string::npos) << reports[0].notes.back();
  EXPECT_NE(reports[0].notes.back().find(") cannot be taken: "), std::string::npos) << reports[0].notes.back();
}

// A window whose start has left the ring and whose first segment begins with no state: the
// timeline is what the gateway decided then, line for line as recorded, not what a new gateway
// would make of the window's frames (it would first boot the cab).
TEST_F(Blackbox, AWindowWithoutItsStartOrAStateIsShownAsRecordedAndSaysSo) {
  incident();
  fs::remove(dir_ / "record" / "20261205T140312Z-000000.log");
  fs::remove(dir_ / "record" / "20261205T140312Z-000000.events");
  edit_first_state(dir_ / "record" / "20261205T140312Z-000001.events",
                   no_state_event("the recorder is given no states"));
  std::ostringstream timeline;
  const auto reports = replay_all(&timeline);
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].mode, ReplayMode::Recorded);
  EXPECT_FALSE(reports[0].divergence);
  ASSERT_FALSE(reports[0].notes.empty());
  EXPECT_EQ(reports[0].notes.front(),
            "the recording does not reach back to the gateway's start (its first segments left the ring) and its "
            "first segment begins with no state (the recorder is given no states): shown as recorded, nothing "
            "re-run or compared; --fresh re-runs the recorded inputs on a new gateway");
  // The recording's own events, but ticks, segment heads and log lines (not on the timeline).
  std::string error;
  const auto runs = find_runs(dir_ / "record", error);
  ASSERT_TRUE(runs) << error;
  std::vector<std::string> expected;
  std::uint64_t decisions = 0, frames_in = 0, frames_out = 0;
  for (const auto& seg : runs->front().segments) {
    SegmentReader r(seg);
    r.each([&](const Entry& e) {
      if (e.kind == Entry::Kind::Frame) {
        ++(e.direction == Direction::Tx ? frames_out : frames_in);
        return;
      }
      const std::string kind = e.text.substr(0, e.text.find(' '));
      // What the gateway did (its log lines too), not what it was given.
      static const std::set<std::string>
          not_decided{"start", "tick",    "bus",  "indicators", "display",          "nmt", "control", "reload",
                      "gap",   "segment", "meta", "state",      "subdevice_command"};
      if (not_decided.count(kind) == 0) ++decisions;
      if (kind == "tick" || kind == "segment" || kind == "meta" || kind == "state" || kind == "log") return;
      expected.push_back(time_of_day(e.wall_us) + " " + e.text);
    });
  }
  std::vector<std::string> shown;
  std::istringstream in(timeline.str());
  for (std::string l; std::getline(in, l);) {
    // "14:03:12.123456    +12.345678 TEXT": the time of day and the text.
    const auto rel_end = l.find(' ', l.find_first_not_of(' ', l.find(' ')));
    ASSERT_NE(rel_end, std::string::npos) << l;
    shown.push_back(l.substr(0, l.find(' ')) + " " + l.substr(rel_end + 1));
  }
  ASSERT_GT(expected.size(), 100u);
  EXPECT_EQ(shown, expected);
  EXPECT_EQ(reports[0].decisions, decisions);
  EXPECT_EQ(reports[0].frames_in, frames_in);
  EXPECT_EQ(reports[0].frames_out, frames_out);
  EXPECT_NE(timeline.str().find("fault right_grip raised"), std::string::npos);
}

// --fresh: the same window's frames re-run on a new gateway, which boots the cab first: its
// decisions are printed, nothing is compared; with the run's start too.
TEST_F(Blackbox, FreshReRunsTheRecordedFramesOnANewGateway) {
  incident();
  std::string error;
  auto runs = find_runs(dir_ / "record", error);
  ASSERT_TRUE(runs) << error;
  ReplayOptions o;
  o.fresh = true;
  std::ostringstream timeline;
  o.timeline = &timeline;
  auto reports = replay(*runs, config_, o);
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].mode, ReplayMode::Fresh);
  EXPECT_EQ(reports[0].compared, 0u);
  EXPECT_FALSE(reports[0].divergence);
  EXPECT_GT(reports[0].decisions, 0u);
  EXPECT_GT(reports[0].frames_in, 1000u);
  ASSERT_FALSE(reports[0].notes.empty());
  EXPECT_EQ(reports[0].notes.front().rfind("--fresh:", 0), 0u) << reports[0].notes.front();
  EXPECT_NE(timeline.str().find("fault right_grip raised"), std::string::npos);

  fs::remove(dir_ / "record" / "20261205T140312Z-000000.log");
  fs::remove(dir_ / "record" / "20261205T140312Z-000000.events");
  runs = find_runs(dir_ / "record", error);
  ASSERT_TRUE(runs) << error;
  std::ostringstream mid;
  o.timeline = &mid;
  reports = replay(*runs, config_, o);
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].mode, ReplayMode::Fresh);
  // A new gateway asks for the cab's boot-up first: a decision the recorded window never made.
  EXPECT_NE(mid.str().find("waiting-for-boot-up"), std::string::npos) << mid.str().substr(0, 3000);
}

TEST_F(BlackboxTimed, TheReplayOnTimedBusesIsExactToo) {
  incident();
  const auto reports = replay_all();
  expect_exact(reports);
  EXPECT_GT(reports[0].states, 0u);
}

TEST_F(BlackboxTimed, APlainCandumpLogOfTheDownstreamBusShowsWhatTheMappingFileMakesOfIt) {
  incident();
  // candump -l of can1: the recording's downstream lines without their direction marks.
  std::string error;
  const auto runs = find_runs(dir_ / "record", error);
  ASSERT_TRUE(runs) << error;
  const fs::path plain = dir_ / "candump-can1.log";
  {
    std::ofstream out(plain);
    for (const auto& seg : runs->front().segments) {
      std::ifstream in(seg.log);
      for (std::string l; std::getline(in, l);)
        if (l.find(" can1 ") != std::string::npos) out << l.substr(0, l.size() - 2) << '\n';
    }
  }
  std::ostringstream timeline;
  const auto reports = replay_all(&timeline, nullptr, plain);
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].mode, ReplayMode::Fresh);
  EXPECT_GT(reports[0].frames_in, 1000u);
  const std::string t = timeline.str();
  // The gateway's own requests are not fed back (the predefined connection set), the devices'
  // answers and PDOs are: the cab boots and the cable pull is seen.
  EXPECT_NE(t.find("node right_grip operational"), std::string::npos) << t.substr(0, 3000);
  EXPECT_NE(t.find("fault right_grip raised"), std::string::npos);
}

TEST_F(Blackbox, ThePlotHoldsEachFieldTheBandsAndTheMarkers) {
  incident();
  PlotData plot;
  const auto reports = replay_all(nullptr, &plot);
  ASSERT_EQ(reports.size(), 1u);
  const auto names = plot.series_names();
  for (const char* expected : {"joystick.1.x", "joystick.1.y", "joystick.2.x", "node right_grip", "node left_grip"})
    EXPECT_NE(std::find(names.begin(), names.end(), expected), names.end()) << expected;
  EXPECT_GT(plot.bands(), 1u);
  EXPECT_GT(plot.markers(), 5u);
  // The SVG: every series a titled polyline, the fault bands and the EMCY markers drawn.
  std::string svg_error;
  ASSERT_TRUE(plot.write_svg(dir_ / "plot.svg", "incident <&>", svg_error)) << svg_error;
  std::ifstream svg_in(dir_ / "plot.svg");
  std::stringstream svg;
  svg << svg_in.rdbuf();
  const std::string text = svg.str();
  EXPECT_EQ(text.rfind("<?xml", 0), 0u);
  EXPECT_NE(text.find("<title>incident &lt;&amp;&gt;</title>"), std::string::npos) << "the title escaped";
  for (const char* expected : {"<title>joystick.1.x (", "<title>joystick.2.x (", "<title>right_grip (",
                               "<title>sub-devices (node state)</title>"})
    EXPECT_NE(text.find(expected), std::string::npos) << expected;
  const auto count = [&](std::string_view what) {
    std::size_t n = 0;
    for (std::size_t at = 0; (at = text.find(what, at)) != std::string::npos; at += what.size()) ++n;
    return n;
  };
  EXPECT_EQ(count("<polyline class=\"series\""), names.size()) << "one line per series";
  EXPECT_GE(count("<rect class=\"band\""), plot.bands());
  EXPECT_GT(count("<line class=\"marker\" "), 0u);
  EXPECT_EQ(text.find("(0 points)"), std::string::npos);
  if (!fs::exists(std::string(kChartJs))) GTEST_SKIP() << kChartJs << " missing (libjs-chart.js)";
  std::string error;
  ASSERT_TRUE(plot.write_html(dir_ / "plot.html", "incident", error)) << error;
  std::ifstream in(dir_ / "plot.html");
  std::stringstream html;
  html << in.rdbuf();
  EXPECT_NE(html.str().find("Chart.js v3.9.1"), std::string::npos) << "the library is inside the page";
  EXPECT_EQ(html.str().find("<script src="), std::string::npos) << "nothing is fetched";
  EXPECT_NE(html.str().find("\"joystick.1.x\""), std::string::npos);
}

}  // namespace
}  // namespace oegw::gateway::record
