#include "cli/status_command.hpp"

#include "gateway/record/recording_service.hpp"

#include <cstdio>
#include <sstream>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "cli/control_client.hpp"
#include "gateway/control/control_protocol.hpp"
#include "gateway/gateway.hpp"

namespace oegw::cli {

using nlohmann::json;

namespace {

constexpr std::size_t kWidth = 100;

// A number as hex with `digits` digits and an h, "-" for null (a value the node does not have).
std::string hex(const json& v, int digits) {
  if (!v.is_number_unsigned() && !v.is_number_integer()) return "-";
  return fmt::format("{:0{}X}h", v.get<std::uint64_t>(), digits);
}
std::string text(const json& v) { return v.is_string() ? "\"" + v.get<std::string>() + "\"" : "-"; }
// A counter, "-" when the answer lacks it (a daemon of the same protocol before it was added).
std::string count(const json& o, const char* key) {
  return o.contains(key) && o[key].is_number_unsigned() ? std::to_string(o[key].get<std::uint64_t>()) : "-";
}
std::string seconds(std::int64_t ms) { return fmt::format("{:.1f} s", static_cast<double>(ms) / 1000.0); }

std::string emcy_text(const json& e) {
  if (e.is_null()) return "-";
  std::string data;
  for (const auto& b : e["data"]) data += fmt::format("{:02X}", b.get<unsigned>());
  return fmt::format("{} reg {} data {}, {} ago ({} in all)", hex(e["code"], 4), hex(e["error_register"], 2), data,
                     seconds(e["age_ms"].get<std::int64_t>()), e["count"].get<std::uint64_t>());
}

// Words after `indent`, wrapped to kWidth.
void wrap(std::string& out, const std::string& first, const std::vector<std::string>& words, std::size_t indent) {
  std::string line = first;
  for (const auto& w : words) {
    if (line.size() > indent && line.size() + 1 + w.size() > kWidth) {
      out += line + "\n";
      line = std::string(indent, ' ');
    } else if (line.size() > indent) {
      line += ' ';
    }
    line += w;
  }
  out += line + "\n";
}

// A line's words (split at its spaces), for wrap().
std::vector<std::string> split_words(const std::string& line) {
  std::vector<std::string> out;
  std::istringstream in(line);
  for (std::string w; in >> w;) out.push_back(w);
  return out;
}

// name, node, driver, state, frames, bad, reboots, resets, refused (88 columns).
constexpr const char* kSubdeviceRow = "{:<14} {:>4} {:<16} {:<12} {:>9} {:>5} {:>7} {:>6} {:>7}\n";

// "commands refused: 3 to FEs (indicators.1 2, display.1 1), 1 to sub-devices (right_grip 1)":
// the totals, then who had any (the FEs in FE order, the sub-devices in file order).
std::string refused_line(const json& st) {
  const auto who = [](const json& list, auto&& counter) {
    std::vector<std::string> out;
    for (const auto& e : list)
      if (const std::string n = counter(e); n != "0" && n != "-") out.push_back(e["name"].get<std::string>() + " " + n);
    return out;
  };
  const auto group = [](const std::string& total, const char* to, const std::vector<std::string>& names) {
    std::string g = total + " to " + to;
    if (!names.empty()) g += " (" + fmt::format("{}", fmt::join(names, ", ")) + ")";
    return g;
  };
  const json& c = st["commands"];
  return "commands refused: " +
         group(count(c, "refused"), "FEs",
               who(st["functional_elements"], [](const json& fe) { return count(fe, "refused_commands"); })) +
         ", " +
         group(count(c, "subdevice_refused"), "sub-devices",
               who(st["subdevices"], [](const json& d) { return count(d["counters"], "refused_commands"); }));
}

// One row per sub-device, then its last EMCY, identity and firmware, and why it is faulty.
void subdevice_rows(std::string& out, const json& s) {
  const json& c = s["counters"];
  out +=
      fmt::format(kSubdeviceRow, s["name"].get<std::string>(), hex(s["node_id"], 2), s["driver"].get<std::string>(),
                  s["state"].get<std::string>(), c["frames"].get<std::uint64_t>(), c["bad_frames"].get<std::uint64_t>(),
                  c["reboots_seen"].get<std::uint64_t>(), count(c, "gateway_resets"), count(c, "refused_commands"));
  const json& id = s["identity"];
  wrap(out, "    ",
       {"vendor " + hex(id["vendor_id"], 8), "product " + hex(id["product_code"], 8),
        "revision " + hex(id["revision"], 8), "serial " + hex(id["serial"], 8)},
       6);
  wrap(out, "    ",
       {"name " + text(s["device_name"]), "hardware " + text(s["hardware_version"]),
        "software " + text(s["software_version"])},
       6);
  if (!s["last_emcy"].is_null()) wrap(out, "    ", {"last EMCY " + emcy_text(s["last_emcy"])}, 6);
  if (s["state"] != "operational" && s["network_state"] != s["state"])
    wrap(out, "    ", {"network manager: " + s["network_state"].get<std::string>()}, 6);
  if (s["fault"].is_string()) wrap(out, "    ", {"fault: " + s["fault"].get<std::string>()}, 6);
}

void fe_rows(std::string& out, const json& fe) {
  std::vector<std::string> words;
  for (const auto& f : fe["fields"]) {
    std::string w = f["name"].get<std::string>() + "=" + std::to_string(f["value"].get<std::int64_t>());
    if (f["status"] != "valid") w += "(" + f["status"].get<std::string>() + ")";
    if (f["interlocked"].get<bool>()) w += "(held)";
    words.push_back(w);
  }
  const std::string head =
      fmt::format("{:<15} {:<14} ", fe["name"].get<std::string>(), fe["status"].get<std::string>());
  wrap(out, head, words, head.size());
}

}  // namespace

std::string status_table(const json& st) {
  std::string out;
  const json& up = st["upstream"];
  const json& down = st["downstream"];
  std::string active;
  for (const auto& e : up["active_emcys"]) active += (active.empty() ? "" : ", ") + hex(e, 4);
  out += fmt::format("gateway: up {}, mapping file {}\n", seconds(st["uptime_ms"].get<std::int64_t>()),
                     st["mapping_file"].get<std::string>());
  out += fmt::format("upstream:   {}, network {}, node-ID {}, {}, active EMCYs: {}\n",
                     up["interface"].get<std::string>(), up["network_id"].get<int>(), hex(up["node_id"], 2),
                     up["nmt_state"].get<std::string>(), active.empty() ? "none" : active);
  // Each SDO server channel a network indication redirected (absent from an older daemon).
  for (const auto& r : up.value("sdo_redirects", json::array())) {
    std::string request;
    for (const auto& b : r["indication"]) request += fmt::format("{:02X} ", b.get<unsigned>());
    const std::string sub = r["subdevice"].get<std::string>();
    wrap(out, "",
         split_words(fmt::format("remote SDO: SDO server {} ({}/{}) redirected to {} (network {}, node {}) for {} by "
                                 "the network indication {}: a client on {} reaches {}, not the gateway",
                                 hex(r["sdo_server"], 4), hex(r["request_cob_id"], 3), hex(r["response_cob_id"], 3),
                                 sub, r["network_id"].get<int>(), hex(r["node_id"], 2),
                                 seconds(r["age_ms"].get<std::int64_t>()), request.substr(0, request.size() - 1),
                                 hex(r["request_cob_id"], 3), sub)),
         4);
  }
  const json& dc = down["counters"];
  out += fmt::format("downstream: {}, network {}, PDOs of unknown nodes {}, EMCYs of unknown nodes {}\n",
                     down["interface"].get<std::string>(), down["network_id"].get<int>(),
                     dc["unknown_pdo"].get<std::uint64_t>(), dc["unknown_emcy"].get<std::uint64_t>());
  // Publishing (`oegw run` only): each transport up, or down with why
  // (docs/guides/dds-lcm.md#publishing-degrades-the-gateway-runs).
  if (st.contains("publishing")) {
    std::string line;
    for (const auto& t : st["publishing"]) {
      line += (line.empty() ? "" : "; ") + t["transport"].get<std::string>() + " " + t["state"].get<std::string>();
      if (t["state"] == "up") continue;
      line += ": " + t["reason"].get<std::string>();
      const auto failed = t["failed_attempts"].get<std::uint64_t>();
      line +=
          fmt::format(" ({} failed attempt{}, {})", failed, failed == 1 ? "" : "s",
                      t["next_attempt_ms"].is_null() ? std::string("one running")
                                                     : "next in " + seconds(t["next_attempt_ms"].get<std::int64_t>()));
    }
    wrap(out, "", split_words("publishing: " + (line.empty() ? std::string("off") : line)), 4);
  }
  // The control socket's clients and what its bounds did to them
  // (docs/reference/limits.md#the-control-socket).
  if (st.contains("control") && st["control"].is_object()) {
    const json& c = st["control"];
    const auto n = [&c](const char* key) { return c.value(key, std::uint64_t{0}); };
    wrap(out, "",
         split_words(fmt::format("control: {} of {} connections; {} answers, {} status renders", n("clients"),
                                 n("max_clients"), n("answered"), n("status_renders"))),
         4);
    wrap(out, "    ",
         split_words(fmt::format("{} peers refused; {} connections closed by a bound ({} to make room)", n("refused"),
                                 n("dropped"), n("evicted"))),
         4);
  }
  // Frames the kernel dropped before the gateway read them: shown only when there are any.
  for (const auto& [side, j] : {std::pair<const char*, const json*>{"upstream", &up}, {"downstream", &down}})
    if (j->contains("bus") && (*j)["bus"].value("rx_dropped", std::uint64_t{0}) != 0)
      out += fmt::format("{}: {} frames read, {} dropped by the kernel before the gateway read them\n", side,
                         (*j)["bus"]["rx_frames"].get<std::uint64_t>(), (*j)["bus"]["rx_dropped"].get<std::uint64_t>());
  if (st.contains("record")) out += gateway::record::record_status_line(st["record"]);
  out += "\n" + fmt::format(kSubdeviceRow, "sub-device", "node", "driver", "state", "frames", "bad", "reboots",
                            "resets", "refused");
  for (const auto& s : st["subdevices"]) subdevice_rows(out, s);
  out += fmt::format("\n{:<15} {:<14} {}\n", "FE", "status", "fields (value, status if not valid)");
  for (const auto& fe : st["functional_elements"]) fe_rows(out, fe);
  out += "\n";
  wrap(out, "", split_words(refused_line(st)), 4);
  return out;
}

std::string control_socket_of(const std::string& socket, const std::string& config, const char* program, bool& ok) {
  ok = true;
  if (!socket.empty()) return socket;
  if (config.empty()) return std::string(mapping::kDefaultControlSocket);
  auto r = mapping::load_config(config, gateway::driver_catalogue());
  if (!r.ok()) {
    std::fprintf(stderr, "%s\n%s: %s unreadable; give --socket instead\n", r.error_text().c_str(), program,
                 config.c_str());
    ok = false;
    return {};
  }
  return r.config->control.socket;
}

int ask_exit_code(AskStatus s) {
  switch (s) {
    case AskStatus::Ok: return kStatusOk;
    case AskStatus::NoDaemon: return kStatusNoDaemon;
    case AskStatus::PermissionDenied: return kStatusPermission;
    case AskStatus::Timeout: return kStatusTimeout;
    case AskStatus::Failed: return kStatusFailed;
  }
  return kStatusFailed;
}

int run_status(const StatusOptions& o) {
  bool ok = false;
  const std::string path = control_socket_of(o.socket, o.config, "oegw status", ok);
  if (!ok) return kStatusFailed;
  const auto timeout = std::chrono::milliseconds(static_cast<std::int64_t>(o.timeout_s * 1000.0));
  const AskResult r = ask_daemon(path,
                                 gateway::control::json_line(
                                     json{{"protocol", gateway::control::kControlProtocol}, {"command", "status"}}),
                                 timeout);
  if (r.status != AskStatus::Ok) {
    std::fprintf(stderr, "oegw status: %s\n", r.text.c_str());
    return ask_exit_code(r.status);
  }
  const json answer = json::parse(r.text, nullptr, false);
  const bool good = answer.is_object() && answer.value("ok", false) && answer.contains("status");
  // The daemon's own refusal of this user (control_server.hpp, SO_PEERCRED): the same exit code
  // as the socket file's mode keeping it out.
  const bool denied = !good && answer.is_object() && answer.contains("error") && answer["error"].is_object() &&
                      answer["error"].value("code", "") == "permission_denied";
  if (o.json) {
    std::printf("%s\n", r.text.c_str());
    return good ? kStatusOk : denied ? kStatusPermission : kStatusFailed;
  }
  if (!good) {
    const std::string why = answer.is_object() && answer.contains("error") && answer["error"].is_object()
                                ? answer["error"].value("message", r.text)
                                : r.text;
    std::fprintf(stderr, "oegw status: the gateway answered: %s\n", why.c_str());
    return denied ? kStatusPermission : kStatusFailed;
  }
  try {
    std::printf("%s", status_table(answer["status"]).c_str());
  } catch (const json::exception& e) {
    std::fprintf(stderr, "oegw status: an answer this oegw cannot read (%s); --json shows it\n", e.what());
    return kStatusFailed;
  }
  return kStatusOk;
}

}  // namespace oegw::cli
