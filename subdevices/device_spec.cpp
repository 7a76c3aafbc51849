#include "subdevices/device_spec.hpp"

#include <cstdio>
#include <cstdlib>

namespace oegw::subdevices {

std::string DeviceSpec::name() const {
  char b[8];
  std::snprintf(b, sizeof b, "@%02Xh", node.value());
  return family + b;
}

std::optional<DeviceSpec> parse_device_spec(std::string_view text, std::string& error) {
  const std::string where = "device '" + std::string(text) + "': ";
  const auto c1 = text.find(':');
  if (c1 == std::string_view::npos || c1 == 0) {
    error = where + "expected family:node[:key=value,...], e.g. elobau-mfg:0x11";
    return std::nullopt;
  }
  DeviceSpec spec;
  spec.family = std::string(text.substr(0, c1));
  const auto rest = text.substr(c1 + 1);
  const auto c2 = rest.find(':');
  const std::string node_text(rest.substr(0, c2));
  char* end = nullptr;
  const long node = std::strtol(node_text.c_str(), &end, 0);
  if (node_text.empty() || *end != '\0' || node < 1 || node > 127) {
    error = where + "node-ID '" + node_text + "' is not 1..127 (decimal or 0x..)";
    return std::nullopt;
  }
  spec.node = NodeId{static_cast<std::uint8_t>(node)};
  if (c2 != std::string_view::npos) {
    std::string_view opts = rest.substr(c2 + 1);
    while (!opts.empty()) {
      const auto comma = opts.find(',');
      const std::string_view kv = opts.substr(0, comma);
      const auto eq = kv.find('=');
      if (eq == std::string_view::npos || eq == 0) {
        error = where + "option '" + std::string(kv) + "' is not key=value";
        return std::nullopt;
      }
      spec.options.values.emplace_back(std::string(kv.substr(0, eq)), std::string(kv.substr(eq + 1)));
      if (comma == std::string_view::npos) break;
      opts = opts.substr(comma + 1);
    }
  }
  return spec;
}

}  // namespace oegw::subdevices
