// "family:node[:key=value,...]" — how the bench programs (oegw-sim, oegw master) name a device
// on their command line, e.g. "elobau-mfg:0x11", "cia401:0x30:eds=subdevices/eds/generic_pedal.eds".
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "subdevices/driver.hpp"

namespace oegw::subdevices {

struct DeviceSpec {
  std::string family;
  NodeId node{};
  DriverOptions options;
  [[nodiscard]] std::string name() const;  // "elobau-mfg@11h"
};

// nullopt with `error` saying what is wrong and what was expected.
std::optional<DeviceSpec> parse_device_spec(std::string_view text, std::string& error);

}  // namespace oegw::subdevices
