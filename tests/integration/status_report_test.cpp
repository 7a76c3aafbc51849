// The control socket's `status` report (gateway/control/status_report.hpp) and `oegw status`'s
// table on the simulated cab (rig/cab_rig.hpp: tests/fixtures/demo_cab.yaml's devices as
// simulators on the virtual bus, a simulated clock): every sub-device operational with the
// identity and firmware its simulator's dictionary holds, counters that move with the frames,
// an MCB-402 cable break as its last EMCY, the device gone silent shown missing with that EMCY.
#include "gateway/control/status_report.hpp"

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <memory>
#include <optional>
#include <sstream>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "cli/status_command.hpp"
#include "gateway/control/gateway_control.hpp"
#include "rig/cab_rig.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "tests/fixtures/fixtures.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
namespace gw = oegw::gateway;
using nlohmann::json;

namespace {

const oegw::mapping::FeId kLeds1{oegw::mapping::FeKind::IndicatorCluster, 1};

class StatusReport : public ::testing::Test {
 protected:
  StatusReport() : loop_(clock_) {
    auto loaded = oegw::mapping::load_config_text(oegw::fixtures::mapping_file("demo_cab.yaml"), "demo_cab.yaml",
                                                  gw::driver_catalogue());
    EXPECT_TRUE(loaded.ok()) << loaded.error_text();
    config_ = std::move(*loaded.config);
    // indicators.1 takes DDS only here: LCM and the host are refused (CommandsRefused...).
    for (auto& fe : config_.functional_elements)
      if (fe.id == kLeds1) fe.sources = static_cast<oegw::mapping::CommandSources>(oegw::mapping::CommandSource::Dds);
    store_ = std::filesystem::path(::testing::TempDir()) / ("status_report_" + std::to_string(::getpid()) + ".store");
    std::filesystem::remove(store_);
    rig_ = std::make_unique<oegw::rig::CabRig>(config_, loop_, oegw::rig::CabRigOptions{.store = store_});
    rig_->build();
    started_ = loop_.now();
    rig_->power_on();
    rig_->run_for(5s);
  }
  ~StatusReport() override { std::filesystem::remove(store_); }

  json report() const { return gw::control::status_report(rig_->gw(), config_, {loop_.now(), started_}); }
  static const json& sub(const json& r, const std::string& name) {
    for (const auto& s : r["subdevices"])
      if (s["name"] == name) return s;
    throw std::runtime_error("no sub-device " + name);
  }
  static const json& fe(const json& r, const std::string& name) {
    for (const auto& f : r["functional_elements"])
      if (f["name"] == name) return f;
    throw std::runtime_error("no FE " + name);
  }
  // An SDO download of the host to the gateway; its abort code.
  SdoAbortCode host_write(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data) {
    std::optional<SdoAbortCode> got;
    rig_->host()
        .sdo(NodeId{0x20})
        .download(index, sub, std::move(data), [&](SdoAbortCode c, std::vector<std::uint8_t>) { got = c; });
    rig_->rearm();
    for (int i = 0; i < 2000 && !got; ++i) rig_->run_for(1ms);
    return got.value_or(SdoAbortCode::Timeout);
  }
  std::uint32_t sim_u32(const std::string& name, std::uint16_t index, std::uint8_t subindex) {
    return rig_->devices().device(name)->od().get<std::uint32_t>(index, subindex);
  }

  SimulatedClock clock_;
  EventLoop loop_;
  oegw::mapping::Config config_;
  std::filesystem::path store_;
  std::unique_ptr<oegw::rig::CabRig> rig_;
  TimePoint started_{};
};

TEST_F(StatusReport, EverySubdeviceOperationalWithTheIdentityItsDeviceHolds) {
  const json r = report();
  EXPECT_EQ(r["mapping_file"], "demo_cab.yaml");
  EXPECT_EQ(r["uptime_ms"], 5000);
  EXPECT_EQ(r["upstream"]["node_id"], 0x20);
  EXPECT_EQ(r["upstream"]["interface"], "virtual");
  EXPECT_EQ(r["upstream"]["nmt_state"], std::string(to_string(rig_->gw().upstream().node().state())));
  EXPECT_EQ(r["upstream"]["active_emcys"], json::array());
  ASSERT_EQ(r["subdevices"].size(), 5u);
  for (const auto& s : r["subdevices"]) {
    const std::string name = s["name"];
    SCOPED_TRACE(name);
    EXPECT_EQ(s["state"], "operational");
    EXPECT_EQ(s["fault"], nullptr);
    EXPECT_EQ(s["identity"]["vendor_id"], sim_u32(name, 0x1018, 1));
    EXPECT_EQ(s["identity"]["product_code"], sim_u32(name, 0x1018, 2));
    EXPECT_EQ(s["identity"]["revision"], sim_u32(name, 0x1018, 3));
    if (name != "left_grip") {
      EXPECT_EQ(s["last_emcy"], nullptr);
    }
    EXPECT_GT(s["counters"]["frames"].get<std::uint64_t>(), 20u) << "5 s of heartbeats, SDO answers, PDOs";
    EXPECT_EQ(s["counters"]["bad_frames"], 0);
    EXPECT_EQ(s["counters"]["reboots_seen"], 0);
  }
  // The MCB-402's power-on warning (MCB §4: 083 00 81 11 ...) is its last EMCY, no fault.
  const json& mcb = sub(r, "left_grip");
  ASSERT_TRUE(mcb["last_emcy"].is_object()) << mcb.dump();
  EXPECT_EQ(mcb["last_emcy"]["code"], 0x8100);
  EXPECT_EQ(mcb["last_emcy"]["error_register"], 0x11);
  EXPECT_EQ(mcb["last_emcy"]["count"], 1);
  EXPECT_EQ(sub(r, "right_grip")["node_id"], 0x11);
  EXPECT_EQ(sub(r, "right_grip")["driver"], "elobau-mfg");
  EXPECT_EQ(sub(r, "right_grip")["mandatory"], true);
  const json& enc = sub(r, "seat_knob");  // Novotechnik: a 1008h the report carries as text
  EXPECT_TRUE(enc["device_name"].is_string()) << enc.dump();
  // The FEs in FE order, each bound field with its value and status.
  ASSERT_FALSE(r["functional_elements"].empty());
  const json& joy = r["functional_elements"][0];
  EXPECT_EQ(joy["name"], "joystick.1");
  EXPECT_EQ(joy["status"], "valid");
  bool x = false;
  for (const auto& f : joy["fields"])
    if (f["name"] == "x") {
      x = true;
      EXPECT_EQ(f["status"], "valid");
      EXPECT_EQ(f["value"], 0) << "the grip at rest";
    }
  EXPECT_TRUE(x) << joy.dump();
  EXPECT_EQ(r["commands"]["refused"], 0);
}

TEST_F(StatusReport, CountersFollowTheFramesAndTheReboots) {
  const auto before = sub(report(), "right_grip")["counters"]["frames"].get<std::uint64_t>();
  rig_->run_for(1s);  // 100 ms heartbeats at least
  const auto after = sub(report(), "right_grip")["counters"]["frames"].get<std::uint64_t>();
  EXPECT_GE(after - before, 10u);
  EXPECT_EQ(rig_->command("right_grip reboot").rfind("ok", 0), 0u);
  rig_->run_for(5s);
  const json s = sub(report(), "right_grip");
  EXPECT_EQ(s["counters"]["reboots_seen"], 1);
  EXPECT_EQ(s["counters"]["gateway_resets"], 1)
      << "its first boot answered the gateway's reset; the reboot was its own";
  EXPECT_EQ(s["state"], "operational");
  EXPECT_EQ(report()["downstream"]["counters"]["reboots_seen"], 1);
  EXPECT_EQ(sub(report(), "left_grip")["counters"]["reboots_seen"], 0);
  EXPECT_EQ(sub(report(), "left_grip")["counters"]["gateway_resets"], 1);
}

// The interfaces' socket counters, when the caller has them (`oegw run`): every field, and the
// table's line for frames the kernel dropped only when there are any.
TEST_F(StatusReport, BusCountersOfBothInterfacesAndTheKernelsDropsInTheTable) {
  EXPECT_FALSE(report()["upstream"].contains("bus")) << "no transports given: no bus object";
  const TransportCounters up{.rx_frames = 7,
                             .tx_frames = 9,
                             .tx_dropped = 1,
                             .rx_dropped = 0,
                             .error_frames = 2,
                             .errors = 3};
  TransportCounters down{.rx_frames = 1200,
                         .tx_frames = 40,
                         .tx_dropped = 0,
                         .rx_dropped = 0,
                         .error_frames = 0,
                         .errors = 0};
  gw::control::StatusContext at{loop_.now(), started_, &up, &down};
  json r = gw::control::status_report(rig_->gw(), config_, at);
  EXPECT_EQ(r["upstream"]["bus"], (json{{"rx_frames", 7},
                                        {"tx_frames", 9},
                                        {"rx_dropped", 0},
                                        {"tx_dropped", 1},
                                        {"error_frames", 2},
                                        {"errors", 3}}));
  EXPECT_EQ(r["downstream"]["bus"]["rx_frames"], 1200);
  EXPECT_EQ(oegw::cli::status_table(r).find("dropped by the kernel"), std::string::npos) << "nothing dropped: no line";
  down.rx_dropped = 345;
  r = gw::control::status_report(rig_->gw(), config_, at);
  EXPECT_EQ(r["downstream"]["bus"]["rx_dropped"], 345);
  EXPECT_NE(oegw::cli::status_table(r).find(
                "\ndownstream: 1200 frames read, 345 dropped by the kernel before the gateway read them\n"),
            std::string::npos)
      << oegw::cli::status_table(r);
}

// The publishing transports as `oegw run` has them: each up, or down with why and when it is
// tried again, in the report and as the table's `publishing:` line.
TEST_F(StatusReport, PublishingTransportsUpOrDownWithTheReason) {
  EXPECT_FALSE(report().contains("publishing")) << "`oegw run` adds it (GatewayControl::add_status_field)";
  json r = report();
  r["publishing"] = gw::control::publishing_status({});
  EXPECT_NE(oegw::cli::status_table(r).find("\npublishing: off\n"), std::string::npos);
  r["publishing"] = gw::control::publishing_status(
      {{"dds", true, "", 0, {}, {}}, {"lcm", false, "no route to 224.0.0.1 (Network is unreachable)", 3, 7s, 4s}});
  EXPECT_EQ(r["publishing"][0], (json{{"transport", "dds"}, {"state", "up"}}));
  EXPECT_EQ(r["publishing"][1], (json{{"transport", "lcm"},
                                      {"state", "down"},
                                      {"reason", "no route to 224.0.0.1 (Network is unreachable)"},
                                      {"failed_attempts", 3},
                                      {"down_ms", 7000},
                                      {"next_attempt_ms", 4000}}));
  EXPECT_NE(oegw::cli::status_table(r).find(
                "\npublishing: dds up; lcm down: no route to 224.0.0.1 (Network is unreachable) (3 failed attempts,\n"
                "    next in 4.0 s)\n"),
            std::string::npos)
      << "wrapped at 100 columns, as every line of the table: " << oegw::cli::status_table(r);
  // The reason as `oegw run` gives it (publish.lcm.url, the command that adds a route) is long.
  r["publishing"] = gw::control::publishing_status(
      {{"lcm", false,
        "publish.lcm.url: \"udpm://224.0.0.1:7667?ttl=0\": no route to 224.0.0.1 (Network is unreachable) — add "
        "one: ip route add 224.0.0.0/4 dev lo",
        6, 30s, 7500ms}});
  std::istringstream table(oegw::cli::status_table(r));
  for (std::string l; std::getline(table, l);) EXPECT_LE(l.size(), 100u) << l;
}

// Refused commands per output FE (LCM, the host's SDO) and per sub-device (3000h): in the
// report, in the sub-device's row and in the table's last line; the totals count also what
// names no FE or sub-device of the file.
TEST_F(StatusReport, RefusedCommandsAreCountedPerFeAndPerSubdevice) {
  gw::Gateway& g = rig_->gw();
  EXPECT_FALSE(g.command_indicators(1, 0x01, loop_.now(), oegw::mapping::CommandSource::Lcm));
  EXPECT_EQ(host_write(0x6200, 0x01, {0xFF}), SdoAbortCode::CannotTransferLocalControl) << "indicators.1: DDS only";
  EXPECT_FALSE(g.command_indicators(7, 0x01, loop_.now(), oegw::mapping::CommandSource::Dds)) << "no indicators.7";
  EXPECT_TRUE(g.command_indicators(1, 0x01, loop_.now(), oegw::mapping::CommandSource::Dds));
  // 3000h: the elobau grip (11h) has no position error reset; node 55h is no sub-device.
  EXPECT_EQ(host_write(0x3000, 0, {0x11, 0x01, 0, 0}), SdoAbortCode::InvalidValue);
  EXPECT_EQ(host_write(0x3000, 0, {0x55, 0x01, 0, 0}), SdoAbortCode::SubIndexDoesNotExist);
  EXPECT_FALSE(g.subdevice_command("left_grip", "position_error_reset", loop_.now())) << "the MCB-402 has none";
  const json r = report();
  EXPECT_EQ(fe(r, "indicators.1")["refused_commands"], 2);
  EXPECT_EQ(fe(r, "indicators.2")["refused_commands"], 0);
  EXPECT_EQ(fe(r, "joystick.1")["refused_commands"], 0) << "an input FE: nothing commands it";
  EXPECT_EQ(r["commands"]["refused"], 3);
  EXPECT_EQ(sub(r, "right_grip")["counters"]["refused_commands"], 1);
  EXPECT_EQ(sub(r, "left_grip")["counters"]["refused_commands"], 1);
  EXPECT_EQ(sub(r, "seat_knob")["counters"]["refused_commands"], 0);
  EXPECT_EQ(r["commands"]["subdevice_refused"], 3);
  const std::string table = oegw::cli::status_table(r);
  EXPECT_NE(table.find("\ncommands refused: 3 to FEs (indicators.1 2), 3 to sub-devices (right_grip 1, left_grip 1)\n"),
            std::string::npos)
      << table;
  EXPECT_NE(table.find("\nsub-device     node driver           state           frames   bad reboots resets refused\n"),
            std::string::npos)
      << table;
  const auto row = table.find("\nright_grip ");
  ASSERT_NE(row, std::string::npos) << table;
  const std::string line = table.substr(row + 1, table.find('\n', row + 1) - row - 1);
  EXPECT_TRUE(line.ends_with("       0      1       1")) << "reboots 0, resets 1, refused 1: " << line;
}

TEST_F(StatusReport, ALostDeviceIsMissingWithItsLastEmcy) {
  EXPECT_EQ(rig_->command("left_grip cable_break 1 on").rfind("ok", 0), 0u);
  rig_->run_for(200ms);
  json s = sub(report(), "left_grip");
  ASSERT_TRUE(s["last_emcy"].is_object()) << s.dump();
  EXPECT_EQ(s["last_emcy"]["code"], 0x3120);
  EXPECT_LE(s["last_emcy"]["age_ms"].get<std::int64_t>(), 200);
  EXPECT_EQ(s["state"], "faulty") << "operational, its inputs held at their fault values";
  EXPECT_TRUE(s["fault"].is_string());
  EXPECT_EQ(report()["upstream"]["active_emcys"], json::array({0x7000}));
  EXPECT_EQ(rig_->command("left_grip silent on").rfind("ok", 0), 0u);
  rig_->run_for(500ms);  // heartbeat lost after 150 ms; the first retry comes 1 s later
  const json r = report();
  s = sub(r, "left_grip");
  EXPECT_EQ(s["state"], "missing");
  EXPECT_EQ(s["last_emcy"]["code"], 0x3120) << "kept after the device went";
  EXPECT_GE(s["last_emcy"]["age_ms"].get<std::int64_t>(), 500);

  // `oegw status`'s table of the same report: 100 columns at most, the grip's row says it.
  const std::string table = oegw::cli::status_table(r);
  std::istringstream lines(table);
  std::vector<std::string> rows;
  for (std::string line; std::getline(lines, line);) {
    EXPECT_LE(line.size(), 100u) << line;
    rows.push_back(line);
  }
  const auto row =
      std::find_if(rows.begin(), rows.end(), [](const std::string& l) { return l.rfind("left_grip ", 0) == 0; });
  ASSERT_NE(row, rows.end()) << table;
  EXPECT_NE(row->find(" 03h mcb402 "), std::string::npos) << *row;
  EXPECT_NE(row->find(" missing "), std::string::npos) << *row;
  ASSERT_LT(row + 4, rows.end());
  EXPECT_EQ(row[1], "    vendor 00000058h product 01040131h revision 00000001h serial -")
      << "MCB §1018h, as read at boot";
  EXPECT_EQ(row[2].rfind("    name \"CO4013A\" hardware ", 0), 0u) << row[2];
  EXPECT_EQ(row[3].rfind("    last EMCY 3120h reg 81h data ", 0), 0u) << row[3];
  EXPECT_EQ(row[4], "    fault: missing (heartbeat lost)");
  EXPECT_NE(table.find("\njoystick.2      offline        buttons[1]=0(offline) "), std::string::npos) << table;
}

// `status` over the daemon's socket (gateway/control/gateway_control.hpp): many clients asking
// at once share one render (it costs milliseconds on a slow controller for a full cab, and 200
// clients queued in front of an operator's `oegw status` would make it wait for all of theirs),
// and the answer is never older than the reuse window (GatewayControl::kStatusReuse, or 20 times
// the render's own time) nor than another request.
class StatusOverTheSocket : public StatusReport {
 protected:
  StatusOverTheSocket() {
    dir_ = std::filesystem::path(::testing::TempDir()) / ("status_socket_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    config_.control.enabled = true;
    config_.control.socket = (dir_ / "oegw.sock").string();
    config_.control.group.clear();
    control_ = std::make_unique<gw::control::GatewayControl>(loop_, rig_->gw(), config_, "demo_cab.yaml",
                                                             [this] { rig_->rearm(); });
  }
  ~StatusOverTheSocket() override {
    for (const int fd : fds_) ::close(fd);
    control_.reset();
    std::filesystem::remove_all(dir_);
  }
  // A client that connects and sends `line`; its answer comes with answers().
  int ask(const std::string& line) {
    const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::strncpy(a.sun_path, config_.control.socket.c_str(), sizeof a.sun_path - 1);
    EXPECT_EQ(::connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a), 0) << std::strerror(errno);
    EXPECT_EQ(::send(fd, line.data(), line.size(), MSG_NOSIGNAL), static_cast<ssize_t>(line.size()));
    fds_.push_back(fd);
    return fd;
  }
  // Serves the socket (the clock stands still) until each client has its answer line; each
  // closes once it has it, as `oegw status` does (8 connections are served at once, the rest
  // wait in the listen queue).
  std::vector<std::string> answers(const std::vector<int>& fds) {
    std::vector<std::string> got(fds.size());
    std::vector<bool> done(fds.size(), false);
    for (int round = 0; round < 20000; ++round) {
      bool all = true;
      for (std::size_t i = 0; i < fds.size(); ++i) {
        if (done[i]) continue;
        char buf[65536];
        const ssize_t n = ::recv(fds[i], buf, sizeof buf, MSG_DONTWAIT);
        if (n > 0) got[i].append(buf, static_cast<std::size_t>(n));
        done[i] = !got[i].empty() && got[i].back() == '\n';
        if (done[i]) {
          ::close(fds[i]);
          std::erase(fds_, fds[i]);
        }
        all = all && done[i];
      }
      if (all) break;
      loop_.run_once(0ms);
    }
    return got;
  }

  std::filesystem::path dir_;
  std::unique_ptr<gw::control::GatewayControl> control_;
  std::vector<int> fds_;
};

TEST_F(StatusOverTheSocket, TwoHundredClientsAtOnceShareOneRender) {
  const std::string request = "{\"command\": \"status\"}\n";
  std::vector<int> fds;
  for (int i = 0; i < 200; ++i) fds.push_back(ask(request));
  const auto got = answers(fds);
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_FALSE(got[i].empty()) << "client " << i << " not answered";
    EXPECT_EQ(got[i], got[0]) << "client " << i;
  }
  EXPECT_EQ(json::parse(got[0])["status"]["upstream"]["node_id"], 0x20);
  EXPECT_EQ(control_->status_renders(), 1u) << "one render for all of them (the clock stood still)";
}

// The socket's own counters in the answer and as the table's `control:` line: the clients it
// serves now, the answers and renders so far (the answer being rendered not yet counted).
TEST_F(StatusOverTheSocket, TheAnswerCountsTheSocketsClientsAnswersAndRenders) {
  const std::string request = "{\"command\": \"status\"}\n";
  std::vector<int> fds;
  for (int i = 0; i < 20; ++i) fds.push_back(ask(request));
  const auto first = answers(fds);
  EXPECT_EQ(json::parse(first[0])["status"]["control"], (json{{"clients", 8},
                                                              {"max_clients", 8},
                                                              {"handled", 1},
                                                              {"answered", 0},
                                                              {"status_renders", 1},
                                                              {"refused", 0},
                                                              {"dropped", 0},
                                                              {"evicted", 0}}))
      << "rendered for the first of them, the 8 a slot was free for accepted in one wake-up";
  rig_->run_for(gw::control::GatewayControl::kStatusReuse);
  const int idle = ask("");  // holds a slot without asking
  const auto later = answers({ask(request)});
  const json c = json::parse(later[0])["status"]["control"];
  EXPECT_EQ(c["clients"], 2) << c;
  EXPECT_EQ(c["handled"], 21) << c;
  EXPECT_EQ(c["answered"], 20) << c;
  EXPECT_EQ(c["status_renders"], 2) << c;
  EXPECT_NE(oegw::cli::status_table(json::parse(later[0])["status"])
                .find("\ncontrol: 2 of 8 connections; 20 answers, 2 status renders\n    0 peers refused; 0 connections "
                      "closed by a bound (0 to make room)\n"),
            std::string::npos)
      << oegw::cli::status_table(json::parse(later[0])["status"]);
  std::istringstream table(oegw::cli::status_table(json::parse(later[0])["status"]));
  for (std::string line; std::getline(table, line);) EXPECT_LE(line.size(), 100u) << line;
  ::close(idle);
  std::erase(fds_, idle);
}

TEST_F(StatusOverTheSocket, AStatusAfterAnotherRequestOrOlderThanTheReuseIsRenderedAgain) {
  const std::string request = "{\"command\": \"status\"}\n";
  const auto first = answers({ask(request)});
  EXPECT_EQ(control_->status_renders(), 1u);
  (void)answers({ask(request)});
  EXPECT_EQ(control_->status_renders(), 1u) << "the same instant: the same answer";
  // Another command (here one the gateway does not have) may change what status shows.
  const auto other = answers({ask("{\"command\": \"nope\"}\n")});
  ASSERT_FALSE(other[0].empty());
  (void)answers({ask(request)});
  EXPECT_EQ(control_->status_renders(), 2u) << "rendered afresh after another request";
  // Older than the reuse: rendered afresh, with its time.
  rig_->run_for(gw::control::GatewayControl::kStatusReuse);
  const auto later = answers({ask(request)});
  EXPECT_EQ(control_->status_renders(), 3u);
  EXPECT_GT(json::parse(later[0])["status"]["uptime_ms"].get<std::int64_t>(),
            json::parse(first[0])["status"]["uptime_ms"].get<std::int64_t>());
  // A different request line (the protocol field) is its own.
  (void)answers({ask("{\"protocol\": 1, \"command\": \"status\"}\n")});
  EXPECT_EQ(control_->status_renders(), 4u);
}

// A render that takes long (a slow controller) is shared for 20 times its own time, not only
// for kStatusReuse, and for kStatusReuseMost at most: however many ask with the same line, their
// renders take at most a twentieth of the loop.
TEST_F(StatusOverTheSocket, ASlowRenderIsSharedForTwentyTimesItsOwnTime) {
  TimePoint cost_now{};
  Duration render_takes = 5ms;
  control_->set_cost_clock([&cost_now] { return cost_now; });
  control_->add_status_field("slow", [&cost_now, &render_takes] {
    cost_now += render_takes;
    return json(nullptr);
  });
  const std::string request = "{\"command\": \"status\"}\n";
  (void)answers({ask(request)});
  EXPECT_EQ(control_->status_renders(), 1u);
  rig_->run_for(gw::control::GatewayControl::kStatusReuse);
  (void)answers({ask(request)});
  EXPECT_EQ(control_->status_renders(), 1u) << "a 5 ms render is given again for 100 ms";
  rig_->run_for(79ms);
  (void)answers({ask(request)});
  EXPECT_EQ(control_->status_renders(), 1u) << "99 ms after it";
  rig_->run_for(1ms);
  render_takes = 200ms;  // 20 times that would be 4 s
  (void)answers({ask(request)});
  EXPECT_EQ(control_->status_renders(), 2u) << "100 ms after it: rendered afresh";
  rig_->run_for(gw::control::GatewayControl::kStatusReuseMost - 1ms);
  (void)answers({ask(request)});
  EXPECT_EQ(control_->status_renders(), 2u);
  rig_->run_for(1ms);
  (void)answers({ask(request)});
  EXPECT_EQ(control_->status_renders(), 3u) << "an answer is never given again after kStatusReuseMost";
}

// A command that answers later (an SDO transfer of `oegw ctl`) ends the reuse when it answers,
// not only when it is asked: a status rendered while it ran shows the state before it.
TEST_F(StatusOverTheSocket, ACommandAnsweringLaterEndsTheReuseWhenItAnswers) {
  gw::control::ControlProtocol::Done later;
  control_->add_command("later",
                        [&later](const json&, gw::control::ControlProtocol::Done done) { later = std::move(done); });
  const std::string request = "{\"command\": \"status\"}\n";
  const int waiting = ask("{\"command\": \"later\"}\n");
  for (int i = 0; i < 5 && !later; ++i) loop_.run_once(0ms);
  ASSERT_TRUE(later) << "the command runs";
  (void)answers({ask(request)});
  EXPECT_EQ(control_->status_renders(), 1u);
  later(json{{"done", true}});
  const auto got = answers({waiting});
  EXPECT_NE(got[0].find("\"done\":true"), std::string::npos) << got[0];
  (void)answers({ask(request)});
  EXPECT_EQ(control_->status_renders(), 2u) << "rendered afresh: the command has answered since";
}

}  // namespace
