#include "cli/scan_command.hpp"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <thread>

#include "canopen/io/event_loop.hpp"
#include "canopen/io/socketcan_transport.hpp"
#include "cli/control_client.hpp"
#include "cli/signals_command.hpp"
#include "cli/status_command.hpp"
#include "gateway/control/control_protocol.hpp"
#include "gateway/control/scan_service.hpp"
#include "gateway/programs.hpp"
#include "gateway/run_on_bus.hpp"
#include "subdevices/driver_options.hpp"

namespace oegw::cli {

namespace {

namespace sd = subdevices;
using canopen::NmtState;

std::string hex(std::uint32_t v, int digits) {
  char b[16];
  std::snprintf(b, sizeof b, "%0*X", digits, v);
  return b;
}

// "elobau_mfg_11": the family and the node-ID in hex, a name the mapping file takes as a key.
// A sub-device of the running gateway keeps its mapping-file name.
std::string entry_name(const sd::ScannedNode& n) {
  if (!n.configured_as.empty()) return n.configured_as;
  std::string family = n.family.family.empty() ? "node" : n.family.family;
  std::replace(family.begin(), family.end(), '-', '_');
  std::string id = hex(n.node.value(), 2);
  std::transform(id.begin(), id.end(), id.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return family + "_" + id;
}

std::string state_text(const sd::ScannedNode& n) {
  if (!n.state) return n.booted ? "booted" : "";
  switch (*n.state) {
    case NmtState::Operational: return "operational";
    case NmtState::PreOperational: return "pre-operational";
    case NmtState::Stopped: return "stopped";
    default: return "";
  }
}

// The heartbeat the draft asks of the node: its own 1017h when it produces one, else what was
// heard, else the mapping file's default 100 ms.
struct HeartbeatChoice {
  std::uint16_t ms = 100;
  std::string why;
};
HeartbeatChoice heartbeat_choice(const sd::ScannedNode& n) {
  if (n.producer_heartbeat_ms && *n.producer_heartbeat_ms > 0)
    return {*n.producer_heartbeat_ms, n.configured_as.empty() ? "the node's 1017h" : "the running gateway's"};
  if (n.heartbeat_period) {
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(*n.heartbeat_period).count();
    if (ms > 0 && ms <= 65535) return {static_cast<std::uint16_t>(ms), "the period heard"};
  }
  return {100, "the node produces none yet; the gateway writes it to 1017h at boot"};
}

// One line about the node: what it is and why, for the draft and the summary.
std::string describe(const sd::ScannedNode& n) {
  std::string out = "node " + hex(n.node.value(), 2) + "h: " + (n.family.family.empty() ? "unknown" : n.family.family);
  out += " (" + n.family.reason + ")";
  const auto& id = n.identity;
  std::string ident;
  if (id.device_type) ident += "device type " + hex(*id.device_type, 8) + "h";
  if (id.vendor_id) ident += std::string(ident.empty() ? "" : ", ") + "vendor " + hex(*id.vendor_id, 8) + "h";
  if (id.product_code) ident += std::string(ident.empty() ? "" : ", ") + "product " + hex(*id.product_code, 8) + "h";
  if (id.revision) ident += std::string(ident.empty() ? "" : ", ") + "revision " + hex(*id.revision, 8) + "h";
  if (id.serial) ident += std::string(ident.empty() ? "" : ", ") + "serial " + hex(*id.serial, 8) + "h";
  if (!ident.empty()) out += "; " + ident;
  if (!n.configured_as.empty()) {
    out += "; the gateway's sub-device " + n.configured_as + ", " + n.gateway_state;
    if (const auto s = state_text(n); !s.empty()) out += " (heartbeat: " + s + ")";
    return out;
  }
  if (!n.answered_sdo) out += "; heard but answered no SDO";
  if (const auto s = state_text(n); !s.empty()) out += "; " + s;
  return out;
}

// Text wrapped into comment lines of at most 100 columns, each starting with `prefix`.
std::string comment(const std::string& prefix, const std::string& text) {
  return wrap_words(text, 100, prefix, prefix);
}

// FE instances handed out so far, per kind, so that uncommenting every suggestion of every node
// gives each FE once.
struct FeCounters {
  std::map<std::string, int> next;
  std::optional<int> take(const std::string& kind) {
    static const std::map<std::string, int> limit = {{"joystick", 16}, {"pedal", 16},     {"encoder", 8}, {"wheel", 8},
                                                     {"buttons", 8},   {"indicators", 8}, {"display", 8}};
    int& n = next[kind];
    if (n >= limit.at(kind)) return std::nullopt;
    return ++n;
  }
};

std::optional<int> bit_count(const sd::SignalInfo& s) {
  if (s.min != 0 || s.max < 1 || s.unit != "bits") return std::nullopt;
  int n = 0;
  for (std::int64_t v = s.max; v & 1; v >>= 1) ++n;
  if ((std::int64_t{1} << n) - 1 != s.max) return std::nullopt;
  return n;
}

// The suggested FE lines of one node (without the comment mark): its joystick axes and buttons,
// other axes as wheels, analogue values as pedals, positions as encoders, the rest of the
// one-bit and bit-packed inputs as a button cluster, one-bit outputs as indicators and other
// outputs as display parameters (the field table of
// docs/reference/mapping-file.md#functional_elements-kindinstance-field-signal-required-may-be-empty).
std::vector<std::string> fe_lines(const std::string& name, const std::vector<sd::SignalInfo>& signals, FeCounters& fe) {
  using K = sd::SignalKind;
  std::vector<std::string> out;
  std::set<std::string> used;
  auto find = [&](const std::string& n, K kind) -> const sd::SignalInfo* {
    for (const auto& s : signals)
      if (s.name == n && s.kind == kind) return &s;
    return nullptr;
  };
  const auto sig = [&](const std::string& s) { return name + "." + s; };
  // A joystick: x and y axes (z when there is one), buttons[1..k] up to 8.
  if (find("x", K::Axis) && find("y", K::Axis)) {
    if (const auto j = fe.take("joystick")) {
      out.push_back("joystick." + std::to_string(*j) + ":");
      for (const char* axis : {"x", "y", "z"})
        if (find(axis, K::Axis)) {
          out.push_back(std::string("  ") + axis + ": " + sig(axis));
          used.insert(axis);
        }
      int k = 0;
      while (k < 8 && find("buttons[" + std::to_string(k + 1) + "]", K::Button)) ++k;
      if (k > 0) {
        out.push_back("  buttons[1.." + std::to_string(k) + "]: " + sig("buttons[1.." + std::to_string(k) + "]"));
        for (int i = 1; i <= k; ++i) used.insert("buttons[" + std::to_string(i) + "]");
      }
    }
  }
  std::vector<std::string> switches, indicators, parameters;
  int sw = 0, ind = 0, par = 0;
  for (const auto& s : signals) {
    if (used.count(s.name)) continue;
    const auto one = [&](const std::string& kind, const std::string& field) {
      if (const auto i = fe.take(kind)) {
        out.push_back(kind + "." + std::to_string(*i) + ":");
        out.push_back("  " + field + ": " + sig(s.name));
      } else {
        out.push_back("# " + sig(s.name) + ": every " + kind + " FE taken");
      }
    };
    switch (s.kind) {
      case K::Axis: one("wheel", "position"); break;
      case K::Analog: one("pedal", "position"); break;
      case K::Position: one("encoder", "position"); break;
      case K::Speed: out.push_back("# " + sig(s.name) + ": a Speed signal, no FE field takes it"); break;
      case K::Button:
      case K::Digital: {
        const int n = s.kind == K::Button ? 1 : bit_count(s).value_or(0);
        if (n == 0 || sw + n > 64) {
          out.push_back("# " + sig(s.name) + ": " + std::string(sd::to_string(s.kind)) + " " + std::to_string(s.min) +
                        ".." + std::to_string(s.max) + ", no switch field fits it here");
          break;
        }
        const std::string range =
            n == 1 ? std::to_string(sw + 1) : std::to_string(sw + 1) + ".." + std::to_string(sw + n);
        switches.push_back("  switch[" + range + "]: " + sig(s.name));
        sw += n;
        break;
      }
      case K::Output: {
        const auto n = s.min == 0 && s.max == 1 ? std::optional<int>(1) : bit_count(s);
        if (n && ind + *n <= 64) {
          const std::string range =
              *n == 1 ? std::to_string(ind + 1) : std::to_string(ind + 1) + ".." + std::to_string(ind + *n);
          indicators.push_back("  indicator[" + range + "]: " + sig(s.name));
          ind += *n;
        } else if (par < 12) {
          parameters.push_back("  parameter[" + std::to_string(++par) + "]: " + sig(s.name));
        } else {
          out.push_back("# " + sig(s.name) + ": every display parameter taken");
        }
        break;
      }
    }
  }
  const auto block = [&](const std::string& kind, const std::vector<std::string>& lines) {
    if (lines.empty()) return;
    const auto i = fe.take(kind);
    if (!i) {
      out.push_back("# " + name + ": every " + kind + " FE taken");
      return;
    }
    out.push_back(kind + "." + std::to_string(*i) + ":");
    out.insert(out.end(), lines.begin(), lines.end());
  };
  block("buttons", switches);
  block("indicators", indicators);
  block("display", parameters);
  return out;
}

}  // namespace

std::string draft_mapping(const sd::ScanResult& scan, const DraftSettings& settings) {
  std::string subs, fes;
  FeCounters counters;
  std::size_t named = 0;
  for (const sd::ScannedNode& n : scan.nodes) {
    const std::string name = entry_name(n);
    const sd::DriverInfo* info = sd::find_driver_info(n.family.family);
    subs += "\n" + comment("  # ", describe(n));
    const HeartbeatChoice hb = heartbeat_choice(n);
    std::vector<std::string> entry = {name + ":", "  driver: " + n.family.family,
                                      "  node_id: 0x" + hex(n.node.value(), 2),
                                      "  heartbeat_ms: " + std::to_string(hb.ms) + "  # " + hb.why};
    std::string identity;
    if (n.identity.vendor_id) identity += "vendor_id: 0x" + hex(*n.identity.vendor_id, 8);
    if (n.identity.product_code)
      identity += std::string(identity.empty() ? "" : ", ") + "product_code: 0x" + hex(*n.identity.product_code, 8);
    if (!identity.empty())
      entry.push_back("  identity: { " + identity + " }  # checked at boot; revision and serial may be added");
    // Required options: a commissioning choice (a listing value exists: the driver's signals do
    // not depend on it) is the placeholder TODO, which `oegw check` refuses with how to find the
    // value (subdevices/driver_options.hpp kPlaceholder); a required option the signals depend on
    // (cia401's EDS) leaves the entry commented out.
    std::vector<std::string> options;
    std::string missing;
    if (info) {
      for (const sd::OptionSpec& o : info->options) {
        if (!o.required) continue;
        if (o.listing_value.empty()) {
          missing += (missing.empty() ? "" : ", ") + std::string(o.name);
          options.push_back("    " + std::string(o.name) + ": TODO");
          continue;
        }
        options.push_back("    # TODO required, a commissioning choice: " + std::string(o.description) + ".");
        options.push_back("    " + std::string(o.name) + ": " + std::string(sd::kPlaceholder) +
                          "  # `oegw check` refuses this until a value is written, and says how to find it");
      }
    }
    if (!options.empty()) {
      entry.push_back("  options:");
      entry.insert(entry.end(), options.begin(), options.end());
    }
    const bool active = info && missing.empty();
    if (!info) {
      subs += comment("  # ",
                      "TODO no driver fits this node; the entry below is left for reference (`oegw "
                      "signals` lists the drivers; a CiA 401 node may be driven by cia401 with its EDS).");
      entry[1] = "  driver: TODO";
    } else if (!active) {
      subs +=
          comment("  # ", "TODO " + n.family.family + " needs " + missing + ": uncomment the entry and fill it in " +
                              "(`oegw signals " + n.family.family + " --eds FILE` lists the signals an EDS gives).");
    }
    for (const auto& line : entry) subs += (active ? "  " : "  # ") + line + "\n";
    if (!active) continue;
    ++named;
    std::string error;
    const auto signals = listing_signals(*info, {}, error);
    // "  # " marks a line to uncomment, "  ## " a note.
    fes += "\n  ## " + name + " (" + n.family.family + ", node " + hex(n.node.value(), 2) + "h)\n";
    if (!signals) {
      fes += "  ## (its signals depend on options: `oegw signals " + n.family.family + "`)\n";
      continue;
    }
    for (const auto& line : fe_lines(name, *signals, counters))
      fes += (line.rfind("# ", 0) == 0 ? "  #" : "  # ") + line + "\n";
  }

  std::string out;
  if (settings.through_gateway)
    out += "# DRAFT mapping file written by `oegw scan` through the gateway running on " + settings.downstream +
           "\n# (its sub-devices keep their names; their options are in its mapping file; format: "
           "docs/reference/mapping-file.md).\n";
  else
    out += "# DRAFT mapping file written by `oegw scan -i " + settings.downstream +
           "` (format: docs/reference/mapping-file.md).\n";
  out += "# Found " + std::to_string(scan.nodes.size()) + " node(s), " + std::to_string(named) +
         " with a driver entry. Review every TODO, then `oegw check FILE`.\n";
  out += "# Each driver's signals and options: `oegw signals DRIVER`.\n";
  if (scan.unconfigured) {
    out += "#\n";
    std::string text = "TODO a node without node-ID answered LSS (CiA 305 identify non-configured remote slave)";
    if (scan.unconfigured_address) {
      const auto& a = *scan.unconfigured_address;
      text += "; LSS fastscan read its address: vendor 0x" + hex(a.vendor, 8) + ", product 0x" + hex(a.product, 8) +
              ", revision 0x" + hex(a.revision, 8) + ", serial 0x" + hex(a.serial, 8);
      sd::NodeIdentity id{.vendor_id = a.vendor, .product_code = a.product};
      if (const auto f = sd::name_family(id); !f.family.empty()) text += " (" + f.family + ")";
    } else if (!scan.lss_note.empty()) {
      text += "; " + scan.lss_note;
    }
    text +=
        ". Give it a free node-ID with an LSS master (switch state selective to that address, configure node-ID, "
        "store configuration, switch state global waiting) and scan again; further nodes without node-ID "
        "show up only once this one has one.";
    out += comment("# ", text);
  }
  out += "\nupstream:                    # the gateway as a CiA 852 device on the host's bus\n";
  out += "  interface: " + settings.upstream + "  # TODO the host's bus (oegw scan --upstream)\n";
  out += "  node_id: 0x20              # TODO the gateway's node-ID on the host's bus\n";
  out += "  bitrate: " + std::to_string(settings.bitrate) + "\n";
  if (!settings.store.empty()) out += "  store: " + settings.store + "  # 1010h \"save\" (oegw scan --store)\n";
  out += "\ndownstream:                  # the bus scanned, the gateway is its master\n";
  out += "  interface: " + settings.downstream + "\n";
  out += "  bitrate: " + std::to_string(settings.bitrate) + "  # the scan does not measure it (oegw scan --bitrate)\n";
  out += "\nsubdevices:" + std::string(named == 0 ? " {}" : "") + "\n" + subs;
  out += "\n# Suggested functional elements for the signals of each node (uncomment what the cab uses;\n";
  out +=
      "# the FE kinds and fields: "
      "docs/reference/mapping-file.md#functional_elements-kindinstance-field-signal-required-may-be-empty).\n";
  out += "functional_elements: {}  # TODO remove the {} when you uncomment FE lines below\n" + fes;
  return out;
}

std::string scan_summary(const sd::ScanResult& scan) {
  std::string out;
  for (const sd::ScannedNode& n : scan.nodes) out += describe(n) + "\n";
  if (scan.unconfigured) {
    out += "a node without node-ID answered LSS";
    if (scan.unconfigured_address) {
      const auto& a = *scan.unconfigured_address;
      out += ": LSS address vendor " + hex(a.vendor, 8) + "h, product " + hex(a.product, 8) + "h, revision " +
             hex(a.revision, 8) + "h, serial " + hex(a.serial, 8) + "h; give it a node-ID by LSS and scan again";
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
int report(const sd::ScanResult& result, const DraftSettings& settings, const std::string& output) {
  std::fputs(scan_summary(result).c_str(), stderr);
  const std::string draft = draft_mapping(result, settings);
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
  DraftSettings d{.downstream = down.value("interface", downstream),
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
