// `oegw sim FILE` (gateway_sim.hpp): the user's mapping file on a simulated cab.
#include "programs/gateway_sim.hpp"

#include <sys/epoll.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>

#include <fmt/format.h>

#include "canopen/io/event_loop.hpp"
#include "canopen/io/socketcan_transport.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "gateway/control/gateway_control.hpp"
#include "gateway/gateway.hpp"
#include "gateway/programs.hpp"
#include "gateway/publishing.hpp"
#include "profiles/cia852/pdo_defaults.hpp"
#include "programs/live_view.hpp"
#include "programs/private_folder.hpp"
#include "programs/sim_story.hpp"
#include "publish/dds_publisher.hpp"
#include "rig/cab_rig.hpp"
#include "subdevices/sim/sim_bench.hpp"

namespace oegw::programs {

using namespace gateway;  // the programs compose the daemon's library

using namespace canopen;
using namespace canopen::io;
using namespace std::chrono_literals;
namespace sd = oegw::subdevices;

namespace {

// One line of the script: when, what, and where it was written (for the errors of a command the
// simulators refuse when it runs).
struct SimStep {
  Duration at{};
  std::string command;
  std::size_t line = 0;
  std::size_t column = 0;
};

// The FE status words of the table (live_view.cpp fe_line), which `expect` takes.
constexpr std::pair<std::string_view, gateway::FeStatus> kStatusWords[] = {{"valid", FeStatus::Valid},
                                                                           {"error", FeStatus::Error},
                                                                           {"n/a", FeStatus::NotAvailable},
                                                                           {"stale", FeStatus::Stale},
                                                                           {"offline", FeStatus::Offline}};

std::vector<std::string> words_of(const std::string& s) {
  std::istringstream in(s);
  std::vector<std::string> w;
  for (std::string x; in >> x;) w.push_back(x);
  return w;
}

// "6200:01" or "0x6200:0x01" (hex either way, as oegw ctl's objects are written): index, sub.
std::optional<std::pair<std::uint16_t, std::uint8_t>> parse_object(const std::string& s) {
  const auto colon = s.find(':');
  if (colon == std::string::npos) return std::nullopt;
  char* end = nullptr;
  const std::string i = s.substr(0, colon), k = s.substr(colon + 1);
  const unsigned long index = std::strtoul(i.c_str(), &end, 16);
  if (i.empty() || *end != '\0' || index == 0 || index > 0xFFFF) return std::nullopt;
  const unsigned long sub = std::strtoul(k.c_str(), &end, 16);
  if (k.empty() || *end != '\0' || sub > 0xFF) return std::nullopt;
  return std::pair{static_cast<std::uint16_t>(index), static_cast<std::uint8_t>(sub)};
}

// "FF 01" or "FF01": 1..8 bytes, as candump writes them.
std::optional<std::vector<std::uint8_t>> parse_bytes(const std::vector<std::string>& w, std::size_t from) {
  std::string hex;
  for (std::size_t i = from; i < w.size(); ++i) hex += w[i];
  if (hex.empty() || hex.size() % 2 != 0 || hex.size() > 16) return std::nullopt;
  std::vector<std::uint8_t> out;
  for (std::size_t i = 0; i < hex.size(); i += 2) {
    char* end = nullptr;
    const std::string b = hex.substr(i, 2);
    const unsigned long v = std::strtoul(b.c_str(), &end, 16);
    if (*end != '\0') return std::nullopt;
    out.push_back(static_cast<std::uint8_t>(v));
  }
  return out;
}

// The words the script and standard input take beside the simulators' own
// (subdevices/sim/sim_bench.hpp SimBench::command); "" when `w` is one of them and well formed,
// else what was expected. `fes`: the FE names of the file.
std::string check_own_command(const std::vector<std::string>& w, const std::vector<std::string>& fes,
                              const std::map<std::uint16_t, std::uint32_t>& rpdos) {
  if (w[0] == "motion") return w.size() == 2 && (w[1] == "on" || w[1] == "off") ? "" : "motion on|off";
  if (w[0] == "say" || w[0] == "stop") return w[0] == "stop" && w.size() != 1 ? "stop, alone" : "";
  if (w[0] == "expect") {
    if (w.size() != 3) return "expect <FE> valid|held|error|n/a|stale|offline";
    if (std::find(fes.begin(), fes.end(), w[1]) == fes.end()) {
      std::string known;
      for (const auto& f : fes) known += (known.empty() ? "" : ", ") + f;
      return "an FE of the file (" + known + ")";
    }
    const bool word = w[2] == "held" || std::any_of(std::begin(kStatusWords), std::end(kStatusWords),
                                                    [&](const auto& s) { return s.first == w[2]; });
    return word ? "" : "a status: valid, held, error, n/a, stale or offline";
  }
  if (w[0] == "host") {
    static const char* const kUsage =
        "host nmt start|stop|preop|reset|reset_comm, host read IDX:SUB, host write IDX:SUB BYTES or host rpdo N BYTES";
    if (w.size() == 3 && w[1] == "nmt") {
      for (const char* v : {"start", "stop", "preop", "reset", "reset_comm"})
        if (w[2] == v) return "";
      return kUsage;
    }
    if (w.size() == 3 && w[1] == "read") return parse_object(w[2]) ? "" : "host read IDX:SUB (hex, e.g. 6401:01)";
    if (w.size() >= 4 && w[1] == "write")
      return parse_object(w[2]) && parse_bytes(w, 3) ? "" : "host write IDX:SUB BYTES (hex, e.g. 6200:01 FF)";
    if (w.size() >= 4 && w[1] == "rpdo") {
      char* end = nullptr;
      const unsigned long n = std::strtoul(w[2].c_str(), &end, 10);
      if (*end != '\0' || !rpdos.contains(static_cast<std::uint16_t>(n))) {
        std::string known;
        for (const auto& [k, v] : rpdos) known += (known.empty() ? "" : ", ") + std::to_string(k);
        return "host rpdo N BYTES with an RPDO of this gateway (" + (known.empty() ? std::string("none") : known) + ")";
      }
      return parse_bytes(w, 3) ? "" : "host rpdo N BYTES (1..8 hex bytes)";
    }
    return kUsage;
  }
  return "?";  // not one of ours: the simulators'
}

// The COB-IDs the built-in host gives the gateway's PDOs (CiA 852 §12.1: all disabled but TPDO 1's
// mapping; the host assigns them): TPDO 1 keeps 180h + node-ID, every other one the next free
// identifier from 190h on, skipping the gateway's predefined connection set and its SDO servers'.
std::map<std::pair<bool, std::uint16_t>, std::uint32_t> assign_pdo_cob_ids(const mapping::Config& cfg,
                                                                           const std::vector<mapping::FeId>& fes) {
  const std::uint32_t node = cfg.upstream.node_id;
  std::vector<std::uint32_t> taken{0x80 + node, 0x580 + node, 0x600 + node, 0x700 + node};
  for (std::uint32_t base : {0x180u, 0x200u, 0x280u, 0x300u, 0x380u, 0x400u, 0x480u, 0x500u})
    taken.push_back(base + node);
  for (const auto& s : cfg.upstream.sdo_servers) {
    if (s.request) taken.push_back(*s.request);
    if (s.response) taken.push_back(*s.response);
  }
  std::map<std::pair<bool, std::uint16_t>, std::uint32_t> out;
  std::uint32_t next = 0x190;
  for (const auto& p : cia852::default_pdos(fes, NodeId{cfg.upstream.node_id})) {
    if (p.transmit && p.number == 1) {
      out[{true, 1}] = 0x180 + node;
      continue;
    }
    while (std::find(taken.begin(), taken.end(), next) != taken.end()) ++next;
    if (next > 0x57F) break;  // 1000 identifiers: more PDOs than clause 12 has
    out[{p.transmit, p.number}] = next++;
  }
  return out;
}

// Reads the script: "SECONDS COMMAND" per line, `#` starts a comment. Errors as the mapping
// file's: "FILE:LINE:COLUMN: found ...; expected ...", every one.
std::vector<SimStep> read_script(const std::string& path, std::vector<std::pair<std::size_t, std::string>>& errors) {
  std::ifstream in(path);
  if (!in) {
    errors.emplace_back(0, fmt::format("{}: cannot be read ({})", path, std::strerror(errno)));
    return {};
  }
  std::vector<SimStep> steps;
  std::string text;
  for (std::size_t n = 1; std::getline(in, text); ++n) {
    if (const auto hash = text.find('#'); hash != std::string::npos) text.resize(hash);
    const auto first = text.find_first_not_of(" \t\r");
    if (first == std::string::npos) continue;
    const auto time_end = text.find_first_of(" \t", first);
    std::string time = text.substr(first, time_end == std::string::npos ? std::string::npos : time_end - first);
    if (!time.empty() && time.back() == 's') time.pop_back();
    char* end = nullptr;
    const double s = std::strtod(time.c_str(), &end);
    if (time.empty() || *end != '\0' || !std::isfinite(s) || s < 0 || s > 86400) {
      errors.emplace_back(
          n, fmt::format("{}:{}:{}: found '{}'; expected the time in seconds from the start (0..86400, e.g. 2.5)", path,
                         n, first + 1, text.substr(first, time_end - first)));
      continue;
    }
    const auto cmd = time_end == std::string::npos ? std::string::npos : text.find_first_not_of(" \t", time_end);
    if (cmd == std::string::npos) {
      errors.emplace_back(n, fmt::format("{}:{}:{}: found nothing after the time; expected a command", path, n,
                                         text.size() + 1));
      continue;
    }
    std::string command = text.substr(cmd);
    while (!command.empty() && (command.back() == ' ' || command.back() == '\t' || command.back() == '\r'))
      command.pop_back();
    steps.push_back({std::chrono::duration_cast<Duration>(std::chrono::duration<double>(s)), command, n, cmd + 1});
  }
  // Steps at one time run in the order written.
  std::stable_sort(steps.begin(), steps.end(), [](const SimStep& a, const SimStep& b) { return a.at < b.at; });
  return steps;
}

// A SocketCAN interface joined to one of the in-process buses: every frame on the bus goes out on
// the interface, every frame received there comes onto the bus (the kernel does not echo a
// socket's own frames back to it).
struct VcanBridge {
  std::unique_ptr<SocketCanTransport> can;
  std::unique_ptr<VirtualPort> port;
  EventLoop::WatchId watch = 0;
};

// "6200h:01: abort 06020000h (...)": an SDO the host's write or read got refused.
std::string sdo_text(std::uint16_t index, std::uint8_t sub, SdoAbortCode c) {
  return fmt::format("{:04X}h:{:02X}: abort {:08X}h ({})", index, sub, static_cast<std::uint32_t>(c), to_string(c));
}

// One SDO write of the host's configuration (SimSession::configure).
struct HostWrite {
  std::uint16_t index;
  std::uint8_t sub;
  std::vector<std::uint8_t> data;
  bool optional;  // an object the gateway may not have
};

// What the file and the script give the run, all checked before anything starts.
struct SimPlan {
  std::vector<std::string> fe_names;
  std::map<std::pair<bool, std::uint16_t>, std::uint32_t> cob_ids;  // assign_pdo_cob_ids
  std::map<std::uint16_t, std::uint32_t> rpdos;                     // RPDO number: COB-ID
  std::vector<SimStep> steps;
};

// The script, every line checked before anything starts: our own words here, the simulators'
// on a bench of their own (SimBench::command on simulators nobody listens to). An exit code when
// the script has errors (each printed).
std::optional<int> plan_script(const GatewaySimOptions& options, const mapping::Config& cfg,
                               const rig::CabRigOptions& rig_options, SimPlan& plan) {
  std::vector<mapping::FeId> fe_ids;
  for (const auto& fe : cfg.functional_elements) {
    fe_ids.push_back(fe.id);
    plan.fe_names.push_back(mapping::fe_name(fe.id));
  }
  plan.cob_ids = assign_pdo_cob_ids(cfg, fe_ids);
  for (const auto& [key, cob] : plan.cob_ids)
    if (!key.first) plan.rpdos[key.second] = cob;
  if (options.script.empty()) return std::nullopt;
  std::vector<std::pair<std::size_t, std::string>> errors;  // by line
  plan.steps = read_script(options.script, errors);
  sd::sim::SimBench dry([](const CanFrame&) {});
  rig::add_cab_simulators(dry, cfg, rig_options.simulator_options);
  for (const auto& s : plan.steps) {
    const auto w = words_of(s.command);
    const std::string own = check_own_command(w, plan.fe_names, plan.rpdos);
    if (own.empty()) continue;
    if (own != "?") {
      errors.emplace_back(s.line, fmt::format("{}:{}:{}: found '{}'; expected {}", options.script, s.line, s.column,
                                              s.command, own));
      continue;
    }
    const std::string answer = dry.command(s.command, TimePoint{});
    if (answer.rfind("error: ", 0) == 0)
      errors.emplace_back(s.line, fmt::format("{}:{}:{}: found '{}'; {}", options.script, s.line, s.column, s.command,
                                              answer.substr(7)));
  }
  if (errors.empty()) return std::nullopt;
  std::stable_sort(errors.begin(), errors.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [line, e] : errors) std::fprintf(stderr, "%s\n", e.c_str());
  std::fprintf(stderr, "oegw sim: %zu error(s) in %s; nothing started\n", errors.size(), options.script.c_str());
  return exit_code::kBadFile;
}

// --vcan: both buses on SocketCAN as well. An exit code when it cannot be.
std::optional<int> open_vcan(const std::string& vcan, rig::CabRig& rig, std::vector<VcanBridge>& bridges) {
  if (vcan.empty()) return std::nullopt;
  const auto comma = vcan.find(',');
  const std::string names[2] = {vcan.substr(0, comma),
                                comma == std::string::npos ? std::string() : vcan.substr(comma + 1)};
  if (names[0].empty() || names[1].empty() || names[0] == names[1]) {
    std::fprintf(stderr, "oegw sim: --vcan %s: expected two interfaces UP,DOWN (e.g. vcan0,vcan1)\n", vcan.c_str());
    return exit_code::kUsage;
  }
  VirtualBus* buses[2] = {&rig.up(), &rig.down()};
  for (int i = 0; i < 2; ++i) {
    VcanBridge b;
    try {
      b.can = SocketCanTransport::open(names[i]);
    } catch (const CanOpenError& e) {
      std::fprintf(stderr, "oegw sim: --vcan %s: %s\n", i == 0 ? "UP" : "DOWN", e.what());
      return exit_code::kCannotStart;
    }
    b.port = buses[i]->attach(names[i]);
    bridges.push_back(std::move(b));
  }
  for (auto& b : bridges) {
    b.port->set_receiver([can = b.can.get()](const CanFrame& f, TimePoint) { (void)can->send(f); });
    b.can->set_receiver([port = b.port.get(), &rig](const CanFrame& f, TimePoint) {
      (void)port->send(f);
      rig.rearm();
    });
  }
  return std::nullopt;
}

// The sim from the gateway's connection on: the state its steps share, one method per step in
// the order run() takes them. Members in the order they are made, so they go in reverse.
class SimSession {
 public:
  SimSession(const GatewaySimOptions& o, const mapping::Config& c, const std::filesystem::path& d, EventLoop& l,
             rig::CabRig& r, const SimPlan& p, std::vector<VcanBridge>& b, SimStory* s)
      : options(o),
        cfg(c),
        dir(d),
        loop(l),
        rig(r),
        plan(p),
        bridges(b),
        gw(r.gw()),
        host(r.host()),
        bench(r.devices()),
        gateway_node(c.upstream.node_id),
        t0(l.now()),
        story(s) {
    if (options.frames) print_frames_of(rig, t0);
    tty = ::isatty(STDOUT_FILENO) != 0 && !options.frames && !options.fast;
    screen = LiveScreen(tty);
    gw.on_log = [this](const std::string& line) {
      if (story == nullptr || story->shows(line)) say("gateway: " + line);
    };
  }

  int run() {
    watch_host();
    open_control();
    for (auto& b : bridges) b.watch = watch_transport(loop, *b.can);
    if (story != nullptr) story->banner(control ? control_cfg.control.socket : std::string());
    else print_banner();
    if (auto refused = start_publishing()) return *refused;
    let_the_operator_move();
    plan_host_writes();
    schedule();
    take_typed_commands();
    return run_loop_and_report();
  }

 private:
  void say(const std::string& s) { screen.log(stamped(loop.now() - t0, s)); }

  std::uint64_t tpdo_count() const {
    std::uint64_t n = 0;
    for (const auto& [cob, count] : tpdos) n += count;
    return n;
  }

  // The host's view: TPDOs per COB-ID, EMCYs, the gateway's heartbeat.
  void watch_host() {
    for (const auto& [key, cob] : plan.cob_ids)
      if (key.first) tpdo_number[cob] = key.second;
    host.on_other_frame = [this](const CanFrame& f, TimePoint) {
      if (tpdo_number.contains(f.id)) ++tpdos[f.id];
      if (story != nullptr) story->host_frame(f);
    };
    host.on_emcy = [this](const EmcyMessage& m, TimePoint) {
      if (story != nullptr) story->host_emcy(m);
      ++emcys;
      last_emcy = m.code;
      say(fmt::format("host: EMCY {:04X}h from the gateway{}", m.code,
                      m.code == 0x7000 ? fmt::format(" (sub-device {:02X}h failed)", m.msef[0])
                      : m.code == 0    ? " (error reset)"
                                       : ""));
    };
    host.on_heartbeat_timeout = [this](NodeId) { say("host: the gateway's heartbeat timed out"); };
  }

  // Publishing as the file says (--no-publish: none); a setting that cannot work leaves the
  // sim without it (oegw run refuses to start instead), but a DDS Security set asked for and
  // refused stops it: it would publish in the clear. An exit code when it stops.
  std::optional<int> start_publishing() {
    publish_config = cfg.publish;
    if (!options.dds_security.empty()) {
      // The set's file names (scripts/make-dds-security.sh), the gateway's identity.
      auto& sec = publish_config.dds.security.emplace();
      const std::filesystem::path set = std::filesystem::absolute(options.dds_security);
      sec.path = {(set / "ca.pem").string(), (set / "gateway.pem").string(),    (set / "gateway.key").string(),
                  (set / "ca.pem").string(), (set / "governance.p7s").string(), (set / "permissions.p7s").string()};
    }
    const mapping::PublishConfig& publish = publish_config;
    if (!options.dds_security.empty() && !(options.publish && publish.dds.enabled))
      say("--dds-security " + options.dds_security +
          " not used: " + (options.publish ? "the file's publish.dds is off" : "--no-publish"));
    if (!options.publish || !(publish.dds.enabled || publish.lcm.enabled)) return std::nullopt;
    try {
      publishing = std::make_unique<gateway::GatewayPublishing>(gw, publish, [this] { return loop.now(); });
    } catch (const publish::PublishConfigError& e) {
      if (publish.dds.security) {
        // What refused it names the setting (publish.dds.security.<file>); the option when it gave the set.
        std::fprintf(stderr, "oegw %s: %s%s\n", story ? "demo" : "sim",
                     options.dds_security.empty() ? "" : ("--dds-security " + options.dds_security + ": ").c_str(),
                     e.what());
        return exit_code::kCannotStart;
      }
      say(std::string("not publishing: ") + e.what());
      return std::nullopt;
    }
    std::string on;
    if (publish.dds.enabled)
      on = fmt::format("DDS (topics oegw/*, domain {}, partition {}, network {}{})", publish.dds.domain,
                       publish.dds.partition, publish.dds.network,
                       publish.dds.security ? ", DDS Security with " + options.dds_security : std::string());
    if (publish.lcm.enabled)
      on += fmt::format("{}LCM (channels {}*, {})", on.empty() ? "" : " and ", publish.lcm.channel_prefix,
                        publish.lcm.url);
    std::string commanded;
    std::size_t n_commanded = 0;
    for (const auto& fe : cfg.functional_elements)
      if (!fe.input() && (fe.accepts(mapping::CommandSource::Dds) || fe.accepts(mapping::CommandSource::Lcm)))
        commanded += (n_commanded++ == 0 ? "" : ", ") + mapping::fe_name(fe.id);
    say("publishing every FE on " + on +
        (commanded.empty() ? "" : "; " + commanded + (n_commanded == 1 ? " takes" : " take") + " commands from there"));
    // The machine cannot carry one now (an offline computer has no multicast route for LCM): the
    // sim runs without it and it is opened again as `oegw run` does.
    for (const auto& t : publishing->transports())
      if (!t.up) say(t.name + " not publishing yet: " + t.reason + "; opened again until it works");
    publishing->run_on(loop, [this] { rig.rearm(); });
    return std::nullopt;
  }

  // The control socket on a private path (oegw status, oegw ctl), in real time only.
  void open_control() {
    control_cfg = cfg;
    if (options.fast) return;
    control_cfg.control.enabled = true;
    control_cfg.control.socket = (dir / "control.sock").string();
    control_cfg.control.group.clear();
    try {
      control = std::make_unique<control::GatewayControl>(loop, gw, control_cfg, options.file, [this] { rig.rearm(); });
    } catch (const std::exception& e) {
      say(std::string("no control socket: ") + e.what());
    }
  }

  void print_banner() const {
    std::printf("oegw sim: %s on a simulated cab, gateway node %02Xh\n", options.file.c_str(), cfg.upstream.node_id);
    std::string devices;
    for (const auto& s : cfg.subdevices) devices += fmt::format(" {} ({} {:02X}h)", s.name, s.driver, s.node().value());
    std::printf("  downstream:%s\n", devices.empty() ? " no sub-devices" : devices.c_str());
    std::printf("  upstream:   the built-in host enables the gateway's PDOs (TPDO 1 on %03Xh) and starts it\n",
                0x180 + cfg.upstream.node_id);
    if (!bridges.empty())
      std::printf("  on SocketCAN too: upstream %s, downstream %s (candump -L %s,%s ...)\n",
                  bridges[0].can->interface().c_str(), bridges[1].can->interface().c_str(),
                  bridges[0].can->interface().c_str(), bridges[1].can->interface().c_str());
    if (control)
      std::printf("  control:    oegw status --socket %s (oegw ctl alike)\n", control_cfg.control.socket.c_str());
    std::printf("\n");
    std::fflush(stdout);
  }

  void view(bool keep) {
    auto rows = gateway_rows(gw, screen.size().first - 1);
    const std::string own = story != nullptr ? story->host_row() : std::string();
    rows.push_back(!own.empty()
                       ? own
                       : fmt::format("  host: {} TPDOs on {} COB-IDs, {} EMCYs{}", tpdo_count(), tpdos.size(), emcys,
                                     emcys ? fmt::format(" (last {:04X}h)", last_emcy) : std::string()));
    screen.draw(std::move(rows), keep);
  }

  // The operator's hands rest until every sub-device is operational (at most 3 s): a gateway
  // holds an axis at neutral until it has seen it there (the zero-position rule), so a cab
  // that boots with its sticks deflected shows `held`, which is right but not the first thing to see.
  void let_the_operator_move() {
    if (options.motion)
      hands_timer = loop.call_every(t0 + 10ms, 10ms, [this] {
        bool all = true;
        for (const auto& n : gw.downstream().names())
          all = all && gw.downstream().state(n) == sd::NodeState::Operational;
        if (!all && loop.now() - t0 < 3s) return;
        loop.cancel(hands_timer);
        moving = true;
        say("the operator moves every input");
      });
    loop.call_every(loop.now(), 20ms, [this] {
      if (!moving) return;
      bench.move(loop.now());
      rig.rearm();
    });
  }

  // The host: the PDOs' COB-IDs (CiA 852 §12.1), 6423h TRUE where the gateway has analogue
  // inputs (CiA 401: else they raise no event), then NMT start. Each write after the last's answer.
  void plan_host_writes() {
    for (const auto& [key, cob] : plan.cob_ids)
      writes.push_back({static_cast<std::uint16_t>((key.first ? 0x1800 : 0x1400) + key.second - 1), 1,
                        encode<std::uint32_t>(cob), false});
    writes.push_back({0x6423, 0, {1}, true});
  }

  void configure(std::size_t i) {
    if (i == writes.size()) {
      host.nmt().start(gateway_node);
      say(fmt::format("host: {} PDOs enabled, NMT start to node {:02X}h", plan.cob_ids.size(), cfg.upstream.node_id));
      rig.rearm();
      return;
    }
    const HostWrite& w = writes[i];
    host.sdo(gateway_node).download(w.index, w.sub, w.data, [this, i](SdoAbortCode c, std::vector<std::uint8_t>) {
      const HostWrite& done = writes[i];
      if (c != SdoAbortCode::None && !(done.optional && c == SdoAbortCode::ObjectDoesNotExist)) {
        ++host_refusals;
        say("host: SDO write " + sdo_text(done.index, done.sub, c));
      }
      configure(i + 1);
    });
    rig.rearm();
  }

  // What a command does, from the script or typed on standard input; false when it failed.
  bool run_command(const std::string& command) {
    const auto w = words_of(command);
    if (w.empty()) return true;
    const std::string own = check_own_command(w, plan.fe_names, plan.rpdos);
    if (own != "?" && !own.empty()) {
      say("error: '" + command + "': expected " + own);
      return false;
    }
    if (own == "?") {
      const std::string answer = bench.command(command, loop.now());
      rig.rearm();
      say(answer);
      return answer.rfind("error: ", 0) != 0;
    }
    if (w[0] == "motion") {
      if (hands_timer != 0) loop.cancel(hands_timer);
      moving = w[1] == "on";
      say(std::string("the operator ") + (moving ? "moves the inputs" : "lets go of the inputs"));
    } else if (w[0] == "say") {
      say(command.substr(command.find("say") + 4));
    } else if (w[0] == "stop") {
      loop.stop();
    } else if (w[0] == "expect") {
      return expect(w);
    } else if (w[0] == "host") {
      host_command(w);
    }
    return true;
  }

  // `expect FE STATUS`: whether the gateway shows the FE so.
  bool expect(const std::vector<std::string>& w) {
    const auto fe =
        std::find_if(gw.fes().begin(), gw.fes().end(), [&](const auto& id) { return mapping::fe_name(id) == w[1]; });
    if (fe == gw.fes().end()) {
      say("FAILED: expect " + w[1] + ": the gateway has no such FE");
      return false;
    }
    const auto fields = gw.fields(*fe);
    const FeStatus status = gw.status(*fe);
    const bool held = status == FeStatus::Valid &&
                      std::any_of(fields.begin(), fields.end(), [](const auto& f) { return f.interlocked; });
    std::string is = held ? "held" : "";
    if (is.empty())
      for (const auto& [name, s] : kStatusWords)
        if (s == status) is = name;
    const bool ok = is == w[2] || (w[2] == "valid" && is == "held");
    say(ok ? fmt::format("ok: {} {}", w[1], is) : fmt::format("FAILED: expected {} {}, it is {}", w[1], w[2], is));
    return ok;
  }

  // `host nmt|read|write|rpdo ...`: the built-in host does it.
  void host_command(const std::vector<std::string>& w) {
    if (w[1] == "nmt") {
      const NmtCommand cs = w[2] == "start"   ? NmtCommand::Start
                            : w[2] == "stop"  ? NmtCommand::Stop
                            : w[2] == "preop" ? NmtCommand::EnterPreOperational
                            : w[2] == "reset" ? NmtCommand::ResetNode
                                              : NmtCommand::ResetCommunication;
      host.nmt().send(cs, gateway_node);
      say("host: NMT " + w[2] + " to the gateway");
    } else if (w[1] == "read" || w[1] == "write") {
      const auto [index, sub] = *parse_object(w[2]);
      auto done = [this, index, sub, what = w[1]](SdoAbortCode c, std::vector<std::uint8_t> data) {
        if (c != SdoAbortCode::None) return say("host: SDO " + what + " " + sdo_text(index, sub, c));
        std::string hex;
        for (auto b : data) hex += fmt::format(" {:02X}", b);
        say(fmt::format("host: SDO {} {:04X}h:{:02X}: ok{}", what, index, sub, hex));
      };
      if (w[1] == "read") host.sdo(gateway_node).upload(index, sub, done);
      else host.sdo(gateway_node).download(index, sub, *parse_bytes(w, 3), done);
    } else {
      const auto bytes = *parse_bytes(w, 3);
      CanFrame f(plan.rpdos.at(static_cast<std::uint16_t>(std::stoul(w[2]))), bytes);
      (void)rig.host_port().send(f);
      say("host: RPDO " + w[2] + " " + f.to_string());
    }
    rig.rearm();
  }

  // Power on, the script's steps, the table, the end. The script's times count from here, once
  // the set-up is done: publishing with DDS Security authenticates its participant first (3 s on
  // an emulated arm64, a slow cab controller alike), which counted from t0 would fire the first
  // steps at once. The log's times stay since t0.
  void schedule() {
    const TimePoint start = loop.now();
    const auto& steps = plan.steps;
    const auto last_step = steps.empty() ? Duration{0} : steps.back().at;
    if (options.seconds > 0)
      end_at = start + std::chrono::duration_cast<Duration>(std::chrono::duration<double>(options.seconds));
    else if (options.fast && story == nullptr)
      end_at = start + last_step + (steps.empty() ? Duration{10s} : Duration{1s});

    loop.call_at(start, [this] {
      if (story != nullptr) story->begin(stage);
      rig.power_on();
      if (cfg.upstream.heartbeat_ms > 0)
        (void)host.monitor_heartbeat(gateway_node,
                                     static_cast<std::uint16_t>(std::min(3 * cfg.upstream.heartbeat_ms, 65535)));
      if (story == nullptr || !story->host_waits()) configure(0);
    });
    for (const auto& s : steps)
      loop.call_at(start + s.at, [this, s] {
        if (!run_command(s.command)) ++failures;
      });
    if (!options.fast) view_timer = loop.call_every(start + 1s, tty ? 100ms : 1s, [this] { view(false); });
    if (end_at != TimePoint::max()) loop.call_at(end_at, [this] { loop.stop(); });
  }

  // Commands typed on standard input (real time): one a line, as the script's without the time.
  void take_typed_commands() {
    struct stat in_stat {};
    // epoll takes a terminal, a pipe or a socket; a regular file or /dev/null it refuses (EPERM):
    // nothing is typed there.
    const bool typed_input = ::isatty(STDIN_FILENO) != 0 || (::fstat(STDIN_FILENO, &in_stat) == 0 &&
                                                             (S_ISFIFO(in_stat.st_mode) || S_ISSOCK(in_stat.st_mode)));
    if (options.fast || !typed_input) return;
    stdin_watch = loop.watch(STDIN_FILENO, EPOLLIN, [this](std::uint32_t) {
      char buf[512];
      const ssize_t n = ::read(STDIN_FILENO, buf, sizeof buf);
      if (n <= 0) {
        loop.unwatch(stdin_watch);
        stdin_watch = 0;
        return;
      }
      typed.append(buf, static_cast<std::size_t>(n));
      for (auto nl = typed.find('\n'); nl != std::string::npos; nl = typed.find('\n')) {
        const std::string line = typed.substr(0, nl);
        typed.erase(0, nl + 1);
        if (!run_command(line)) ++failures;
      }
    });
  }

  int run_loop_and_report() {
    if (options.fast) {
      while (!loop.stop_requested() && loop.now() < end_at) loop.advance_by(5ms);
    } else {
      loop.handle_signals({SIGINT, SIGTERM});
      loop.run();
    }
    if (view_timer != 0) loop.cancel(view_timer);
    if (stdin_watch != 0) loop.unwatch(stdin_watch);
    for (auto& b : bridges)
      if (b.watch != 0) loop.unwatch(b.watch);
    // The last table stays on the screen, below the log. Drawn here, once the loop has returned:
    // frames handled in the same wake-up as the last step still log, and would land below it.
    view(true);
    if (story != nullptr) return story->end(stage);
    const std::uint64_t n = tpdo_count();
    std::printf("\noegw sim: %.1f s%s, %llu TPDOs and %llu EMCYs at the host; %s\n",
                std::chrono::duration<double>(loop.now() - t0).count(), options.fast ? " simulated" : "",
                static_cast<unsigned long long>(n), static_cast<unsigned long long>(emcys),
                failures == 0 ? "every command and expectation as written"
                              : fmt::format("{} command(s) or expectation(s) FAILED", failures).c_str());
    return failures == 0 ? exit_code::kOk : exit_code::kBadFile;
  }

  const GatewaySimOptions& options;
  const mapping::Config& cfg;
  const std::filesystem::path& dir;
  EventLoop& loop;
  rig::CabRig& rig;
  const SimPlan& plan;
  std::vector<VcanBridge>& bridges;
  Gateway& gw;
  Master& host;
  sd::sim::SimBench& bench;
  const NodeId gateway_node;
  const TimePoint t0;
  SimStory* story;
  SimStage stage{.loop = loop,
                 .rig = rig,
                 .cob_ids = plan.cob_ids,
                 .say = [this](const std::string& line) { say(line); },
                 .motion = [this](bool on) { moving = on; },
                 .configure_host = [this] { configure(0); },
                 .view = [this](bool keep) { view(keep); },
                 .steps_only =
                     [this] {
                       // In a pipe or a file the table every second would repeat itself from here.
                       if (tty || view_timer == 0) return;
                       loop.cancel(view_timer);
                       view_timer = 0;
                     },
                 .host_refusals = [this] { return host_refusals; },
                 .published =
                     [this] {
                       return publishing ? std::optional<std::uint64_t>(publishing->published()) : std::nullopt;
                     }};
  int host_refusals = 0;  // the host's set-up writes the gateway refused
  bool tty = false;
  LiveScreen screen{false};
  int failures = 0;
  std::map<std::uint32_t, std::uint64_t> tpdos;  // the host's TPDOs per COB-ID
  std::uint64_t emcys = 0;
  std::uint16_t last_emcy = 0;
  std::map<std::uint32_t, std::uint16_t> tpdo_number;
  mapping::PublishConfig publish_config;
  std::unique_ptr<gateway::GatewayPublishing> publishing;
  std::unique_ptr<gateway::control::GatewayControl> control;
  mapping::Config control_cfg;
  bool moving = false;
  EventLoop::TimerId hands_timer = 0;
  std::vector<HostWrite> writes;
  TimePoint end_at = TimePoint::max();
  EventLoop::TimerId view_timer = 0;
  std::string typed;
  EventLoop::WatchId stdin_watch = 0;
};

}  // namespace

int run_gateway_sim(const GatewaySimOptions& options, SimStory* story) {
  auto loaded = mapping::load_config(options.file, gateway::driver_catalogue());
  if (!loaded.ok()) {
    std::fprintf(stderr, "%s", loaded.error_text().c_str());
    return exit_code::kBadFile;
  }
  mapping::Config cfg = *loaded.config;

  // The sim's own files (the 1010h store, the control socket): the file's upstream.store and
  // control.socket are the cab controller's, never touched here.
  const auto folder = PrivateFolder::make("sim");
  if (!folder) return exit_code::kCannotStart;
  const std::filesystem::path& dir = folder->path();

  SimulatedClock sim_clock;
  auto loop_ptr = options.fast ? std::make_unique<EventLoop>(sim_clock) : std::make_unique<EventLoop>();
  EventLoop& loop = *loop_ptr;
  rig::CabRigOptions rig_options{.store = dir / "upstream.store"};
  rig_options.simulator_options = rig::simulators_as_wired(cfg);
  rig::CabRig rig(cfg, loop, rig_options);
  try {
    rig.build_devices();
  } catch (const std::runtime_error& e) {
    std::fprintf(stderr, "oegw sim: %s\n", e.what());
    return exit_code::kBadFile;
  }

  SimPlan plan;
  if (auto refused = plan_script(options, cfg, rig_options, plan)) return *refused;
  std::vector<VcanBridge> bridges;
  if (auto refused = open_vcan(options.vcan, rig, bridges)) return *refused;

  rig.connect_gateway();
  SimSession session(options, cfg, dir, loop, rig, plan, bridges, story);
  return session.run();
}

}  // namespace oegw::programs
