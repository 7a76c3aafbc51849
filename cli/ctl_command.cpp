#include "cli/ctl_command.hpp"

#include <poll.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <deque>
#include <iostream>

#include <fmt/format.h>

#include "canopen/305/lss_fastscan.hpp"
#include "canopen/305/lss_slowscan.hpp"
#include "cli/status_command.hpp"
#include "gateway/control/control_protocol.hpp"

namespace oegw::cli {

using nlohmann::json;
namespace ascii = canopen::ascii;
using ascii::Command;
using ascii::GatewayError;

namespace {

const char* nmt_service(Command c) {
  switch (c) {
    case Command::Start: return "start";
    case Command::Stop: return "stop";
    case Command::PreOperational: return "preop";
    case Command::ResetNode: return "reset_node";
    case Command::ResetCommunication: return "reset_comm";
    default: return "";
  }
}

// The control request of a CiA 309-3 LSS command
// (docs/reference/control-protocol.md#oegw-ctls-commands: lss).
json lss_request(const ascii::Request& r) {
  json j{{"command", "lss"}, {"network", r.network}};
  switch (r.command) {
    case Command::LssSwitchGlobal:
      j["service"] = "switch_global";
      j["mode"] = r.value;
      break;
    case Command::LssSwitchSelective:
      j["service"] = "switch_selective";
      j["address"] = r.address;
      break;
    case Command::LssSetNode:
      j["service"] = "set_node";
      j["node"] = r.value;
      break;
    case Command::LssConfBitrate:
      j["service"] = "conf_bitrate";
      j["table_index"] = r.value;
      break;
    case Command::LssActivateBitrate:
      j["service"] = "activate_bitrate";
      j["delay_ms"] = r.value;
      break;
    case Command::LssStore: j["service"] = "store"; break;
    case Command::LssInquireAddress:
      j["service"] = "inquire_address";
      if (r.lss_part) j["part"] = *r.lss_part;
      break;
    case Command::LssGetNode: j["service"] = "inquire_node"; break;
    case Command::LssIdentNonConfigured: j["service"] = "identify_non_configured"; break;
    case Command::LssFastscan:
      j["service"] = "fastscan";
      if (r.value != 0) j["timeout_ms"] = r.value;
      if (r.known_mask) {
        j["known"] = r.address;
        j["mask"] = *r.known_mask;
      }
      break;
    case Command::LssIdentity:
    case Command::LssSlowscan:
      j["service"] = r.command == Command::LssIdentity ? "identify_remote" : "slowscan";
      j["range"] = r.range;
      break;
    default: break;
  }
  return j;
}

// "0.1.0" -> "0.1" (the implementation version of the `info version` answer).
std::string major_minor(const std::string& v) {
  const auto a = v.find('.');
  if (a == std::string::npos) return v + ".0";
  const auto b = v.find_first_not_of("0123456789", a + 1);
  return v.substr(0, b == std::string::npos ? v.size() : b);
}

}  // namespace

CtlSession::CtlSession(Ask ask, std::string version, std::chrono::milliseconds answer_timeout)
    : ask_(std::move(ask)), version_(std::move(version)), answer_timeout_(answer_timeout) {}

CtlSession::Outcome CtlSession::ask(const json& request, std::chrono::milliseconds timeout, json& answer) {
  Outcome o;
  json r = request;
  r["protocol"] = gateway::control::kControlProtocol;
  const AskResult a = ask_(gateway::control::json_line(r), timeout);
  if (a.status != AskStatus::Ok) {
    o.fatal = ask_exit_code(a.status);
    o.why = a.text;
    return o;
  }
  answer = json::parse(a.text, nullptr, false);
  if (!answer.is_object()) {
    o.fatal = kCtlError;
    o.why = "an answer this oegw cannot read: " + a.text;
    return o;
  }
  if (!answer.value("ok", false)) {
    const json e = answer.value("error", json::object());
    const std::string code = e.is_object() ? e.value("code", "") : "";
    // Refused as a user (the daemon's peer check), or a daemon without `oegw ctl`'s commands.
    if (code == "permission_denied" || code == "unknown_command") {
      o.fatal = code == "permission_denied" ? kStatusPermission : kCtlError;
      o.why = "the gateway answered: " + (e.is_object() ? e.value("message", a.text) : a.text);
    }
  }
  return o;
}

std::string CtlSession::answer_of(std::uint32_t seq, const ascii::Request& r, const json& a, bool& error) const {
  error = true;
  if (!a.value("ok", false)) {
    const json e = a.value("error", json::object());
    return ascii::answer_error(seq, GatewayError::InternalState, e.is_object() ? e.value("message", "") : a.dump());
  }
  if (a.contains("gateway_error"))
    return ascii::answer_error(seq, static_cast<GatewayError>(a["gateway_error"].get<int>()), a.value("message", ""));
  if (a.contains("abort") && a["abort"].get<std::uint32_t>() != 0)
    return ascii::answer_abort(seq, static_cast<canopen::SdoAbortCode>(a["abort"].get<std::uint32_t>()));
  if (r.command == Command::Read) {
    std::string why;
    const auto bytes = gateway::control::bytes_from_hex(a.value("data", ""), why);
    const auto text = bytes ? ascii::format(r.type, *bytes) : std::nullopt;
    // A value whose length does not fit the type: lely's gateway answers the same code.
    if (!text) return ascii::answer_abort(seq, canopen::SdoAbortCode::LengthMismatch);
    error = false;
    return ascii::answer_value(seq, *text);
  }
  if (ascii::is_lss(r.command)) {
    error = false;
    // lely's gw_txt.c: an LSS address as four 32-bit numbers, one part as one, the node-ID in
    // decimal (hex digits upper-case, as this gateway prints every unsigned value).
    if (const auto it = a.find("address"); it != a.end() && it->is_array() && it->size() == 4)
      return fmt::format("[{}] 0x{:08X} 0x{:08X} 0x{:08X} 0x{:08X}", seq, (*it)[0].get<std::uint32_t>(),
                         (*it)[1].get<std::uint32_t>(), (*it)[2].get<std::uint32_t>(), (*it)[3].get<std::uint32_t>());
    if (a.contains("value")) return fmt::format("[{}] 0x{:08X}", seq, a["value"].get<std::uint32_t>());
    if (a.contains("node")) return fmt::format("[{}] {}", seq, a["node"].get<unsigned>());
    return ascii::answer_ok(seq);
  }
  if (r.command == Command::InfoVersion) {
    error = false;
    // lely gw_txt.c's order: vendor, product, revision, serial, gateway class, protocol hi.lo
    // (CiA 309-3 3.0, as CANopenNode names the version it implements), implementation hi.lo
    // (oegw's). The four 1018h values as `r 0x1018 N u32` prints them (ascii::format: 0x and
    // eight upper-case hex digits), so the two answers compare as text.
    const auto u32 = [&a](const char* key) { return fmt::format("0x{:08X}", a.value(key, 0u)); };
    return fmt::format("[{}] {} {} {} {} {} 3.0 {}", seq, u32("vendor_id"), u32("product_code"), u32("revision"),
                       u32("serial"), a.value("gateway_class", 3), major_minor(version_));
  }
  error = false;
  return ascii::answer_ok(seq);
}

CtlSession::Outcome CtlSession::execute(std::string_view line) {
  Outcome o;
  const ascii::Parsed p = ascii::parse(line, defaults_);
  if (p.kind == ascii::Parsed::Kind::Empty) return o;
  const std::uint32_t seq = p.request.sequence.value_or(next_seq_);
  next_seq_ = seq + 1;
  if (p.kind == ascii::Parsed::Kind::Error) {
    o.error = true;
    o.lines.push_back(ascii::answer_error(seq, p.error, p.message));
    return o;
  }
  const ascii::Request& r = p.request;
  json request;
  std::chrono::milliseconds timeout = answer_timeout_;
  switch (r.command) {
    case Command::SetNetwork:
      defaults_.network = static_cast<std::uint16_t>(r.value);
      o.lines.push_back(ascii::answer_ok(seq));
      return o;
    case Command::SetNode:
      defaults_.node = static_cast<std::uint8_t>(r.value);
      o.lines.push_back(ascii::answer_ok(seq));
      return o;
    case Command::SetSdoTimeout:
      sdo_timeout_ms_[r.network] = r.value;
      o.lines.push_back(ascii::answer_ok(seq));
      return o;
    case Command::InfoVersion: request = {{"command", "info"}}; break;
    case Command::Read:
    case Command::Write: {
      request = {{"command", r.command == Command::Read ? "sdo_read" : "sdo_write"},
                 {"network", r.network},
                 {"node", r.node},
                 {"index", r.index},
                 {"sub", r.sub}};
      if (r.command == Command::Write) request["data"] = gateway::control::bytes_to_hex(r.data);
      if (const auto it = sdo_timeout_ms_.find(r.network); it != sdo_timeout_ms_.end()) {
        request["timeout_ms"] = it->second;
        timeout = std::max(timeout, std::chrono::milliseconds(it->second + 2000));
      }
      break;
    }
    default:
      if (ascii::is_lss(r.command)) {
        request = lss_request(r);
        if (r.command == Command::LssFastscan) {
          // A fastscan is up to LssFastscan::kMaxSteps steps of the step time-out each.
          const std::uint32_t step_ms = r.value != 0 ? r.value : kDefaultLssStepMs;
          timeout = std::max(timeout, std::chrono::milliseconds(canopen::LssFastscan::kMaxSteps * step_ms + 2000));
        } else if (r.command == Command::LssSlowscan) {
          timeout =
              std::max(timeout, std::chrono::milliseconds(canopen::LssSlowscan::kMaxSteps * kDefaultLssStepMs + 2000));
        }
        break;
      }
      request = {{"command", "nmt"}, {"network", r.network}, {"node", r.node}, {"service", nmt_service(r.command)}};
      break;
  }
  json a;
  Outcome asked = ask(request, timeout, a);
  if (asked.fatal != 0) return asked;
  o.lines.push_back(answer_of(seq, r, a, o.error));
  return o;
}

CtlSession::Outcome CtlSession::poll_events() {
  Outcome o;
  json request{{"command", "events"}};
  if (last_event_) request["after"] = *last_event_;
  json a;
  Outcome asked = ask(request, answer_timeout_, a);
  if (asked.fatal != 0) return asked;
  if (!a.value("ok", false) || !a.contains("last")) return o;
  if (last_event_) {
    if (const auto lost = a.value("lost", std::uint64_t{0}); lost != 0)
      o.lines.push_back(fmt::format("# {} events lost (the gateway keeps the last {})", lost, 256));
    for (const auto& e : a["events"]) {
      const auto net = e.value("network", 0);
      const auto node = e.value("node", 0);
      if (e.value("kind", "") == "boot_up") {
        o.lines.push_back(ascii::boot_up_event(static_cast<std::uint16_t>(net), static_cast<std::uint8_t>(node)));
      } else if (e.value("kind", "") == "emcy") {
        std::array<std::uint8_t, 5> m{};
        const auto d = e.value("data", std::vector<unsigned>{});
        for (std::size_t i = 0; i < m.size() && i < d.size(); ++i) m[i] = static_cast<std::uint8_t>(d[i]);
        o.lines.push_back(ascii::emcy_event(static_cast<std::uint16_t>(net), static_cast<std::uint8_t>(node),
                                            e.value("code", std::uint16_t{0}),
                                            e.value("error_register", std::uint8_t{0}), m));
      }
    }
  }
  last_event_ = a["last"].get<std::uint64_t>();
  return o;
}

namespace {

// The minimal history of an interactive session: `history` lists it, `!!` runs the last line
// again, `!N` line N. Not GNU readline (GPL-3, while oegw is Apache-2.0) and not libedit (its
// development package is no build dependency of oegw):
// docs/guides/commission.md#commissioning-oegw-ctl says so.
class History {
 public:
  // The line to run for `in` (itself, or the line a `!` names); false with `error` set when a
  // `!` names nothing. `history` gives an empty line and prints the list to `out`.
  bool expand(const std::string& in, std::string& line, std::string& error, std::string& out) {
    line = in;
    if (in == "history") {
      for (std::size_t i = 0; i < lines_.size(); ++i) out += fmt::format("{:5}  {}\n", first_ + i, lines_[i]);
      line.clear();
      return true;
    }
    if (in.size() >= 2 && in[0] == '!') {
      std::size_t n = 0;
      if (in == "!!") {
        if (lines_.empty()) return (error = "no history yet", false);
        n = first_ + lines_.size() - 1;
      } else {
        try {
          n = std::stoul(in.substr(1));
        } catch (const std::exception&) {
          return (error = "'" + in + "': !! or !N (a number `history` lists)", false);
        }
      }
      if (n < first_ || n >= first_ + lines_.size())
        return (error = "no line " + std::to_string(n) + " in the history", false);
      line = lines_[n - first_];
      out += line + "\n";
    }
    if (!line.empty()) add(line);
    return true;
  }

 private:
  void add(const std::string& l) {
    lines_.push_back(l);
    if (lines_.size() > 500) {
      lines_.pop_front();
      ++first_;
    }
  }
  std::deque<std::string> lines_;
  std::size_t first_ = 1;
};

void print(const CtlSession::Outcome& o) {
  for (const auto& l : o.lines) std::printf("%s\n", l.c_str());
  std::fflush(stdout);
}

}  // namespace

int run_ctl(const CtlOptions& o) {
  bool ok = false;
  const std::string path = control_socket_of(o.socket, o.config, "oegw ctl", ok);
  if (!ok) return kCtlError;
  const auto timeout = std::chrono::milliseconds(static_cast<std::int64_t>(o.timeout_s * 1000.0));
  CtlSession session([path](const std::string& line, std::chrono::milliseconds t) { return ask_daemon(path, line, t); },
                     o.version, timeout);
  const auto fatal = [](const CtlSession::Outcome& r) {
    std::fprintf(stderr, "oegw ctl: %s\n", r.why.c_str());
    return r.fatal;
  };
  if (const auto first = session.poll_events(); first.fatal != 0) return fatal(first);
  const bool interactive = ::isatty(STDIN_FILENO) != 0;
  History history;
  std::string pending;  // bytes of a line not yet complete (interactive: read as they come)
  int rc = kCtlOk;
  while (true) {
    if (interactive) {
      std::printf("> ");
      std::fflush(stdout);
      // Wait for a line, showing the gateway's events meanwhile (every 0.5 s).
      bool have_line = false;
      bool eof = false;
      while (!have_line && !eof) {
        pollfd p{STDIN_FILENO, POLLIN, 0};
        if (::poll(&p, 1, 500) > 0) {
          char buf[512];
          const ssize_t n = ::read(STDIN_FILENO, buf, sizeof buf);
          if (n <= 0) eof = true;
          else pending.append(buf, static_cast<std::size_t>(n));
          have_line = pending.find('\n') != std::string::npos;
        } else {
          const auto ev = session.poll_events();
          if (ev.fatal != 0) return fatal(ev);
          if (!ev.lines.empty()) {
            std::printf("\r");
            print(ev);
            std::printf("> %s", pending.c_str());
            std::fflush(stdout);
          }
        }
      }
      if (!have_line && pending.empty()) {
        std::printf("\n");
        return rc;
      }
    } else {
      std::string l;
      if (!std::getline(std::cin, l)) return rc;
      pending = l + "\n";
    }
    const auto nl = pending.find('\n');
    std::string line = pending.substr(0, nl == std::string::npos ? pending.size() : nl);
    pending.erase(0, nl == std::string::npos ? pending.size() : nl + 1);
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (interactive) {
      std::string run, error, out;
      if (!history.expand(line, run, error, out)) {
        std::fprintf(stderr, "oegw ctl: %s\n", error.c_str());
        continue;
      }
      std::printf("%s", out.c_str());
      line = run;
    }
    const auto r = session.execute(line);
    if (r.fatal != 0) return fatal(r);
    print(r);
    const auto ev = session.poll_events();
    if (ev.fatal != 0) return fatal(ev);
    print(ev);
    if (r.error && o.exit_on_error) return kCtlError;
  }
}

}  // namespace oegw::cli
