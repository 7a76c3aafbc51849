// The kernel's rule for a network interface name (net/core/dev.c dev_valid_name): 1..15 bytes
// (IFNAMSIZ counts the terminating NUL), not "." or "..", no '/', ':' or white space. One rule for
// the transport that opens the interface and for `oegw check`, which refuses the name first.
#pragma once

#include <cctype>
#include <cstddef>
#include <string>
#include <string_view>

namespace oegw::canopen::io {

inline constexpr std::size_t kMaxInterfaceName = 15;  // IFNAMSIZ - 1

// Why the kernel refuses `name` as an interface name, or "" when it takes it.
[[nodiscard]] inline std::string interface_name_problem(std::string_view name) {
  if (name.empty()) return "is empty";
  if (name.size() > kMaxInterfaceName)
    return "is " + std::to_string(name.size()) + " bytes long, longer than the kernel's 15 (IFNAMSIZ - 1)";
  if (name == "." || name == "..") return "is '" + std::string(name) + "', which the kernel refuses";
  for (const char c : name) {
    if (c == '/' || c == ':') return std::string("contains '") + c + "'";
    if (std::isspace(static_cast<unsigned char>(c)) != 0) return "contains white space";
  }
  return "";
}

}  // namespace oegw::canopen::io
