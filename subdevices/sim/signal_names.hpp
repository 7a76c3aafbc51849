// Parsing the driver signal names simulators accept in set_input()/output().
#pragma once

#include <charconv>
#include <optional>
#include <string_view>

namespace oegw::subdevices::sim {

// "buttons[3]" with base "buttons" -> 3; anything else -> nullopt.
inline std::optional<std::size_t> indexed_signal(std::string_view name, std::string_view base) {
  if (name.size() < base.size() + 3 || name.substr(0, base.size()) != base || name[base.size()] != '[' ||
      name.back() != ']')
    return std::nullopt;
  const std::string_view digits = name.substr(base.size() + 1, name.size() - base.size() - 2);
  std::size_t v = 0;
  const auto [ptr, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
  if (ec != std::errc{} || ptr != digits.data() + digits.size()) return std::nullopt;
  return v;
}

}  // namespace oegw::subdevices::sim
