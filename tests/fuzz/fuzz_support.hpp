// What the stack fuzz targets share: the trap on a broken invariant, and the drivers' signal
// catalogue as gateway::driver_catalogue gives it (without the gateway library's DDS/LCM).
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "subdevices/driver.hpp"
#include "subdevices/driver_options.hpp"

namespace oegw::fuzz {

inline void check(bool ok) {
  if (!ok) __builtin_trap();
}

inline std::optional<std::vector<subdevices::SignalInfo>> catalogue(std::string_view family,
                                                                    const subdevices::DriverOptions& options,
                                                                    subdevices::OptionRefusals& refusals) {
  auto driver = subdevices::make_driver(family, canopen::NodeId{1}, {}, options, refusals);
  if (!driver) return std::nullopt;
  return driver->signals();
}

}  // namespace oegw::fuzz
