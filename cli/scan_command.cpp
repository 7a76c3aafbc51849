#include "cli/scan_command.hpp"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <thread>

#include "canopen/io/event_loop.hpp"
#include "canopen/io/socketcan_transport.hpp"
#include "cli/control_client.hpp"
#include "cli/status_command.hpp"
#include "gateway/control/control_protocol.hpp"
#include "gateway/control/scan_service.hpp"
#include "gateway/programs.hpp"
#include "gateway/run_on_bus.hpp"
#include "mapping/draft.hpp"
#include "subdevices/driver_options.hpp"

namespace oegw::cli {

namespace sd = subdevices;

std::string scan_summary(const sd::ScanResult& scan) {
  std::string out;
  for (const sd::ScannedNode& n : scan.nodes) out += mapping::describe_node(n) + "\n";
  if (scan.unconfigured) {
    out += "a node without node-ID answered LSS";
    if (scan.unconfigured_address) {
      const auto& a = *scan.unconfigured_address;
      out += fmt::format(
          ": LSS address vendor {:08X}h, product {:08X}h, revision {:08X}h, serial {:08X}h; give it a "
          "node-ID by LSS and scan again",
          a.vendor, a.product, a.revision, a.serial);
    } else if (!scan.lss_note.empty()) {
      out += " (" + scan.lss_note + ")";
    }
    out += "\n";
  }
  return out;
}

namespace {

// Progress on standard error: on a terminal one line redrawn for each node-ID, in a log every
// 16th and the last.
class ProgressLines {
 public:
  explicit ProgressLines(bool on) : on_(on), tty_(isatty(STDERR_FILENO) != 0) {}
  void operator()(const sd::ScanProgress& p) {
    if (!on_) return;
    // (through the gateway the polls may see the LSS part start before the last node-ID's line)
    if (!(p.probed == last_ && drawn_) && (tty_ || p.probed == p.total || p.probed - last_ >= 16)) {
      last_ = p.probed;
      drawn_ = true;
      std::fprintf(stderr, "%sprobing node %zu/%zu, found %zu%s", tty_ ? "\r" : "", p.probed, p.total, p.found,
                   tty_ ? "" : "\n");
    }
    if (p.lss && !lss_told_) {
      std::fprintf(stderr, "%sLSS: asking for nodes without node-ID\n", tty_ ? "\n" : "");
      lss_told_ = true;
    }
  }
  void end() const {
    if (on_ && tty_ && drawn_) std::fputs("\n", stderr);
  }

 private:
  bool on_, tty_;
  bool drawn_ = false, lss_told_ = false;
  std::size_t last_ = 0;
};

// The summary on standard error, the draft where asked; the exit code.
int report(const sd::ScanResult& result, const mapping::DraftSettings& settings, const std::string& output) {
  std::fputs(scan_summary(result).c_str(), stderr);
  const std::string draft = mapping::draft_mapping(result, settings);
  if (output == "-") {
    std::fputs(draft.c_str(), stdout);
  } else {
    std::ofstream f(output, std::ios::trunc);
    f << draft;
    f.close();
    if (!f) {
      spdlog::error("cannot write {}", output);
      return exit_code::kCannotStart;
    }
    std::fprintf(stderr, "draft written to %s: review its TODOs, then oegw check %s\n", output.c_str(), output.c_str());
  }
  if (result.nodes.empty()) {
    spdlog::error("no node found on {}", settings.downstream);
    return exit_code::kBadFile;
  }
  return exit_code::kOk;
}

int scan_direct(const ScanOptions& o) {
  using namespace canopen;
  using namespace canopen::io;
  auto port = gateway::open_tool_interface(o.interface);
  if (!port) return exit_code::kCannotStart;
  const auto ms = [](double v) {
    return std::chrono::duration_cast<Duration>(std::chrono::duration<double, std::milli>(v));
  };
  sd::ScanConfig cfg;
  cfg.sdo_timeout = ms(o.timeout_ms);
  cfg.listen = ms(o.listen_ms);
  cfg.lss_timeout = ms(o.lss_timeout_ms);
  cfg.parallel = o.parallel;
  cfg.lss = o.lss;
  SocketCanTransport* bus = port.get();
  sd::BusScanner scanner([bus](const CanFrame& f) { (void)bus->send(f); }, cfg);
  ProgressLines progress(o.progress);
  scanner.on_progress = [&progress](const sd::ScanProgress& p) { progress(p); };
  // Until the scan is done (after a timer or a frame) or a signal.
  gateway::run_on_bus(*port, scanner);
  progress.end();
  if (!scanner.done()) {
    spdlog::error("scan interrupted: no draft written");
    return exit_code::kCannotStart;
  }
  if (port->counters().tx_dropped > 0)
    spdlog::warn("{} frame(s) dropped by a full TX queue: nodes may be missing; scan again with a smaller --parallel",
                 port->counters().tx_dropped);
  return report(scanner.result(),
                {.downstream = o.interface, .upstream = o.upstream, .bitrate = o.bitrate, .store = o.store}, o.output);
}

// One request to the gateway: its answer, or nullopt after an error on standard error (`code`
// the exit code). A refusal of the control protocol or a CiA 309-3 error of the command count.
std::optional<nlohmann::json> ask(const std::string& socket, const nlohmann::json& request, int& code) {
  const AskResult a = ask_daemon(socket, gateway::control::json_line(request), std::chrono::seconds(5));
  if (a.status != AskStatus::Ok) {
    spdlog::error("{}", a.text);
    code = ask_exit_code(a.status);
    return std::nullopt;
  }
  auto j = nlohmann::json::parse(a.text, nullptr, false);
  if (!j.is_object()) {
    spdlog::error("an answer this oegw cannot read: {}", a.text);
    code = kStatusFailed;
    return std::nullopt;
  }
  if (!j.value("ok", false)) {
    const auto e = j.value("error", nlohmann::json::object());
    const std::string why = e.is_object() ? e.value("code", "") : "";
    spdlog::error("the gateway answered: {}", e.is_object() ? e.value("message", a.text) : a.text);
    code = why == "permission_denied" ? kStatusPermission : kStatusFailed;
    return std::nullopt;
  }
  if (j.contains("gateway_error")) {
    spdlog::error("the gateway refused the scan: {}", j.value("message", a.text));
    code = kStatusFailed;
    return std::nullopt;
  }
  return j;
}

std::uint64_t whole_ms(double v) { return static_cast<std::uint64_t>(std::max(1.0, std::ceil(v))); }

int scan_through_gateway(const ScanOptions& o, const std::string& socket, const std::string& downstream) {
  using nlohmann::json;
  int code = exit_code::kOk;
  std::fprintf(
      stderr,
      "scanning %s through the running gateway (%s): its sub-devices as it knows them, the other node-IDs probed\n",
      downstream.c_str(), socket.c_str());
  const json start{{"command", "scan"},
                   {"action", "start"},
                   {"timeout_ms", whole_ms(o.timeout_ms)},
                   {"listen_ms", static_cast<std::uint64_t>(std::ceil(o.listen_ms))},
                   {"lss_timeout_ms", whole_ms(o.lss_timeout_ms)},
                   {"parallel", o.parallel},
                   {"lss", o.lss}};
  const auto started = ask(socket, start, code);
  if (!started) return code;
  const auto id = started->value("scan", nlohmann::json::object()).value("id", std::uint64_t{0});
  ProgressLines progress(o.progress);
  // The gateway's scan always ends (each step has its time-out); this bounds a gateway that
  // stopped answering its status.
  const double bound_ms = 127.0 / o.parallel * 7 * o.timeout_ms + o.listen_ms + 200 * o.lss_timeout_ms + 60000;
  const auto give_up =
      std::chrono::steady_clock::now() + std::chrono::milliseconds(static_cast<std::int64_t>(bound_ms));
  json scan;
  while (true) {
    // (polling a process over its socket for what it shows on screen: no timing logic)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    const auto s = ask(socket, json{{"command", "scan"}, {"action", "status"}, {"id", id}}, code);
    if (!s) return code;
    scan = s->value("scan", json::object());
    const json p = scan.value("progress", json::object());
    progress(sd::ScanProgress{.probed = p.value("probed", std::size_t{0}),
                              .total = p.value("total", std::size_t{0}),
                              .found = p.value("found", std::size_t{0}),
                              .lss = p.value("lss", false)});
    if (!scan.value("running", true)) break;
    if (std::chrono::steady_clock::now() > give_up) {
      progress.end();
      spdlog::error("the gateway's scan {} has not ended in {:.0f} s: no draft written", id, bound_ms / 1000);
      return kStatusTimeout;
    }
  }
  progress.end();
  std::string why;
  const auto result = gateway::control::scan_result_from_json(scan.value("result", json::object()), why);
  if (!result) {
    spdlog::error("the gateway's scan result cannot be read: {}", why);
    return kStatusFailed;
  }
  const json up = scan.value("upstream", json::object());
  const json down = scan.value("downstream", json::object());
  mapping::DraftSettings d{.downstream = down.value("interface", downstream),
                           .upstream = o.upstream_given ? o.upstream : up.value("interface", o.upstream),
                           .bitrate = o.bitrate_given ? o.bitrate : down.value("bitrate", o.bitrate),
                           .store = !o.store.empty() ? o.store : up.value("store", std::string()),
                           .through_gateway = true};
  return report(*result, d, o.output);
}

}  // namespace

int run_scan(const ScanOptions& o) {
  if (o.via == ScanOptions::Via::Direct) return scan_direct(o);
  bool ok = true;
  const std::string socket = control_socket_of(o.socket, o.config, "oegw scan", ok);
  if (!ok) return exit_code::kBadFile;
  const AskResult a = ask_daemon(socket, R"({"command": "info"})", std::chrono::seconds(5));
  if (a.status == AskStatus::NoDaemon && o.via == ScanOptions::Via::Auto) {
    if (o.interface.empty()) {
      spdlog::error("no gateway runs ({}): name the bus to scan with -i", a.text);
      return exit_code::kCannotStart;
    }
    return scan_direct(o);
  }
  if (a.status == AskStatus::PermissionDenied && o.via == ScanOptions::Via::Auto) {
    spdlog::error(
        "{}. A gateway runs here and may be the master of {}: a scan beside it would collide with its SDO "
        "clients. Ask as root or a member of its control group, or give --direct if it drives another bus.",
        a.text, o.interface.empty() ? "the bus" : o.interface);
    return exit_code::kCannotStart;
  }
  if (a.status != AskStatus::Ok) {
    spdlog::error("{}", a.text);
    return ask_exit_code(a.status);
  }
  const auto info = nlohmann::json::parse(a.text, nullptr, false);
  const auto it = info.is_object() ? info.find("downstream_interface") : info.end();
  const std::string downstream = it != info.end() && it->is_string() ? it->get<std::string>() : "";
  if (downstream.empty()) {
    spdlog::error("the gateway at {} does not answer `scan` (an older oegw?): {}", socket, a.text);
    return kStatusFailed;
  }
  if (!o.interface.empty() && o.interface != downstream) {
    if (o.via == ScanOptions::Via::Daemon) {
      spdlog::error("the gateway at {} drives {}, not {}", socket, downstream, o.interface);
      return exit_code::kCannotStart;
    }
    std::fprintf(stderr, "the gateway at %s drives %s: scanning %s directly\n", socket.c_str(), downstream.c_str(),
                 o.interface.c_str());
    return scan_direct(o);
  }
  try {
    return scan_through_gateway(o, socket, downstream);
  } catch (const nlohmann::json::exception& e) {  // a field of an unexpected type in an answer
    spdlog::error("an answer of the gateway at {} this oegw cannot read: {}", socket, e.what());
    return kStatusFailed;
  }
}

}  // namespace oegw::cli
