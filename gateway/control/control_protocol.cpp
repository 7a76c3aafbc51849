#include "gateway/control/control_protocol.hpp"

namespace oegw::gateway {

using nlohmann::json;

std::string json_line(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

std::string control_error(std::string_view code, const std::string& message) {
  return json_line(
      json{{"protocol", kControlProtocol}, {"ok", false}, {"error", json{{"code", code}, {"message", message}}}});
}

std::string ControlProtocol::answer(std::string_view line) const {
  const json request = json::parse(line.begin(), line.end(), nullptr, /*allow_exceptions=*/false);
  if (request.is_discarded() || !request.is_object())
    return control_error("bad_request", "a request is one line of JSON, an object such as {\"command\": \"status\"}");
  if (const auto p = request.find("protocol"); p != request.end()) {
    if (!p->is_number_integer() || p->get<std::int64_t>() < 1)
      return control_error("bad_request", "\"protocol\" is a version number, e.g. 1");
    if (p->get<std::int64_t>() > kControlProtocol)
      return control_error("unsupported_protocol", "this gateway speaks protocol " + std::to_string(kControlProtocol) +
                                                       "; the request asks for " + std::to_string(p->get<std::int64_t>()));
  }
  const auto c = request.find("command");
  if (c == request.end() || !c->is_string())
    return control_error("bad_request", "no \"command\" in the request; expected e.g. {\"command\": \"status\"}");
  const std::string name = c->get<std::string>();
  const auto it = commands_.find(name);
  if (it == commands_.end()) {
    std::string known;
    for (const auto& [n, fn] : commands_) known += (known.empty() ? "" : ", ") + n;
    return control_error("unknown_command", "no command '" + name + "'; this gateway has: " + known);
  }
  try {
    json out = it->second(request);
    out["protocol"] = kControlProtocol;
    out["ok"] = true;
    out["command"] = name;
    return json_line(out);
  } catch (const std::exception& e) {  // a command's own failure answers; it never ends the gateway
    return control_error("failed", name + ": " + e.what());
  }
}

}  // namespace oegw::gateway
