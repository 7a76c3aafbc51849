// make_driver: the family name used in configuration files -> the family's factory.
#include "subdevices/driver.hpp"
#include "subdevices/families.hpp"

namespace oegw::subdevices {

std::unique_ptr<Driver> make_driver(std::string_view family, NodeId node, FrameSink sink,
                                    const DriverOptions& options, std::string& error) {
  if (family == "elobau-mfg") return make_elobau_mfg_driver(node, std::move(sink), options, error);
  if (family == "mcb402") return make_mcb402_driver(node, std::move(sink), options, error);
  if (family == "novotechnik-406") return make_novotechnik_406_driver(node, std::move(sink), options, error);
  if (family == "cia401") return make_cia401_driver(node, std::move(sink), options, error);
  error = "unknown driver '" + std::string(family) +
          "' (expected one of: elobau-mfg, mcb402, novotechnik-406, cia401)";
  return nullptr;
}

}  // namespace oegw::subdevices
