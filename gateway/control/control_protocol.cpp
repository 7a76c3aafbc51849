#include "gateway/control/control_protocol.hpp"

#include <memory>
#include <stdexcept>

#include <fmt/format.h>

namespace oegw::gateway::control {

using nlohmann::json;

std::string json_line(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

std::string bytes_to_hex(const std::vector<std::uint8_t>& bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string s;
  for (const std::uint8_t b : bytes) {
    s += kDigits[b >> 4];
    s += kDigits[b & 0xF];
  }
  return s;
}

std::optional<std::vector<std::uint8_t>> bytes_from_hex(std::string_view text, std::string& error) {
  if (text.size() % 2 != 0) {
    error = "an even number of hex digits";
    return std::nullopt;
  }
  const auto digit = [](char c) {
    return c >= '0' && c <= '9'   ? c - '0'
           : c >= 'a' && c <= 'f' ? c - 'a' + 10
           : c >= 'A' && c <= 'F' ? c - 'A' + 10
                                  : -1;
  };
  std::vector<std::uint8_t> out;
  for (std::size_t i = 0; i < text.size(); i += 2) {
    const int hi = digit(text[i]), lo = digit(text[i + 1]);
    if (hi < 0 || lo < 0) {
      error = "'" + std::string(text.substr(i, 2)) + "' is no hex byte";
      return std::nullopt;
    }
    out.push_back(static_cast<std::uint8_t>(hi * 16 + lo));
  }
  return out;
}

std::string control_error(std::string_view code, const std::string& message) {
  return json_line(
      json{{"protocol", kControlProtocol}, {"ok", false}, {"error", json{{"code", code}, {"message", message}}}});
}

void ControlProtocol::add(std::string name, Command command) {
  commands_[std::move(name)] = [command = std::move(command)](const json& request, Done done) {
    done(command(request));
  };
}

std::string ControlProtocol::answer(std::string_view line) const {
  // Shared: an async command answering after this returned writes into it, not into a dead frame.
  auto out = std::make_shared<std::string>();
  answer(line, [out](std::string a) { *out = std::move(a); });
  return out->empty() ? control_error("failed", "the command answers later; ask over the socket") : *out;
}

void ControlProtocol::answer(std::string_view line, Reply reply) const {
  const json request = json::parse(line.begin(), line.end(), nullptr, /*allow_exceptions=*/false);
  if (request.is_discarded() || !request.is_object())
    return reply(
        control_error("bad_request", "a request is one line of JSON, an object such as {\"command\": \"status\"}"));
  if (const auto p = request.find("protocol"); p != request.end()) {
    if (!p->is_number_integer() || p->get<std::int64_t>() < 1)
      return reply(control_error("bad_request", "\"protocol\" is a version number, e.g. 1"));
    if (p->get<std::int64_t>() > kControlProtocol)
      return reply(control_error("unsupported_protocol",
                                 "this gateway speaks protocol " + std::to_string(kControlProtocol) +
                                     "; the request asks for " + std::to_string(p->get<std::int64_t>())));
  }
  const auto c = request.find("command");
  if (c == request.end() || !c->is_string())
    return reply(
        control_error("bad_request", "no \"command\" in the request; expected e.g. {\"command\": \"status\"}"));
  const std::string name = c->get<std::string>();
  const auto it = commands_.find(name);
  if (it == commands_.end()) {
    std::string known;
    for (const auto& [n, fn] : commands_) known += (known.empty() ? "" : ", ") + n;
    return reply(control_error("unknown_command", "no command '" + name + "'; this gateway has: " + known));
  }
  // `reply` once: a command that throws after answering does not answer twice.
  auto replied = std::make_shared<bool>(false);
  try {
    it->second(request, [reply, replied, name](json out) {
      if (*replied) return;
      *replied = true;
      out["protocol"] = kControlProtocol;
      out["ok"] = true;
      out["command"] = name;
      reply(json_line(out));
    });
  } catch (const std::exception& e) {  // a command's own failure answers; it never ends the gateway
    if (!*replied) {
      *replied = true;
      reply(control_error("failed", name + ": " + e.what()));
    }
  }
}

std::uint64_t request_field(const nlohmann::json& r, const char* key, std::uint64_t lo, std::uint64_t hi) {
  const auto it = r.find(key);
  if (it == r.end() || !it->is_number_unsigned() || it->get<std::uint64_t>() < lo || it->get<std::uint64_t>() > hi)
    throw std::invalid_argument(fmt::format("\"{}\": expected an integer {}..{}", key, lo, hi));
  return it->get<std::uint64_t>();
}

std::uint64_t request_field_or(const nlohmann::json& r, const char* key, std::uint64_t lo, std::uint64_t hi,
                               std::uint64_t fallback) {
  return r.contains(key) ? request_field(r, key, lo, hi) : fallback;
}

}  // namespace oegw::gateway::control
