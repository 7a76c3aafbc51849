// The control socket's protocol (docs/reference/control-protocol.md): one request per line, a JSON
// object {"command": "status"} (optionally "protocol": 1), one JSON line in answer, in order, on
// a connection that may carry several. Every answer has "protocol" and "ok"; a refusal has
// "error": {"code", "message"}. New commands (`oegw ctl`'s) are added by name; a
// command grows by new fields, never by changing the meaning of one (then "protocol" goes up).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace oegw::gateway::control {

inline constexpr int kControlProtocol = 1;

class ControlProtocol {
 public:
  // A command's answer: the fields of the answer besides protocol/ok/command, from the request
  // (the whole object, for the command's own arguments).
  using Command = std::function<nlohmann::json(const nlohmann::json& request)>;
  void add(std::string name, Command command);
  // A command that answers later (an SDO transfer of `oegw ctl`): it calls `done` exactly once
  // with the answer's fields, at once or from a later turn of the event loop.
  using Done = std::function<void(nlohmann::json fields)>;
  using AsyncCommand = std::function<void(const nlohmann::json& request, Done done)>;
  void add_async(std::string name, AsyncCommand command) { commands_[std::move(name)] = std::move(command); }

  // The answer line (no newline) to one request line, through `reply` (exactly once; at once,
  // or later for an async command). Never throws: malformed input, an unknown command or a
  // failing command each give an error answer.
  using Reply = std::function<void(std::string line)>;
  void answer(std::string_view line, Reply reply) const;
  // The same for a caller that needs the line now: an async command that has not answered
  // by the time it returns gives a `failed` answer.
  [[nodiscard]] std::string answer(std::string_view line) const;

 private:
  std::map<std::string, AsyncCommand, std::less<>> commands_;
};

// A request's unsigned integer field in [lo, hi]; std::invalid_argument naming the field (the
// protocol answers it as `failed`) when absent or out of range. request_field_or: `fallback`
// when absent.
[[nodiscard]] std::uint64_t request_field(const nlohmann::json& request, const char* key, std::uint64_t lo,
                                          std::uint64_t hi);
[[nodiscard]] std::uint64_t request_field_or(const nlohmann::json& request, const char* key, std::uint64_t lo,
                                             std::uint64_t hi, std::uint64_t fallback);

// {"protocol": 1, "ok": false, "error": {"code": code, "message": message}} as a line.
[[nodiscard]] std::string control_error(std::string_view code, const std::string& message);
// A value's bytes as the protocol carries them (`oegw ctl`'s sdo_read/sdo_write "data"):
// lower-case hex, two digits a byte. bytes_from_hex: nullopt and `error` for text that is not.
[[nodiscard]] std::string bytes_to_hex(const std::vector<std::uint8_t>& bytes);
[[nodiscard]] std::optional<std::vector<std::uint8_t>> bytes_from_hex(std::string_view text, std::string& error);
// A JSON text that never fails to serialise: bytes that are not UTF-8 (a device's 1008h, say)
// become U+FFFD.
[[nodiscard]] std::string json_line(const nlohmann::json& j);

}  // namespace oegw::gateway::control
