// make_driver: the family name used in configuration files -> the family's factory; and what
// `oegw signals` shows of each family (driver_options.hpp).
#include "subdevices/driver.hpp"
#include "subdevices/driver_options.hpp"
#include "subdevices/families.hpp"

namespace oegw::subdevices {

std::span<const DriverInfo> drivers() {
  static const DriverInfo table[] = {
      {"elobau-mfg", "elobau MFG 34xG / 36xG multifunction joystick grip (elobau CANopen protocol v01.21)",
       elobau_mfg_options(), "the axes are -110..110 with detent: pass (the default), -100..100 with detent: clamp"},
      {"mcb402", "MCB-402 joystick base board (CO4013A4): 4 axes, 7 push buttons, 4 LED outputs", mcb402_options(), ""},
      {"novotechnik-406", "Novotechnik MZ1-2200 / MC1-2800 / MB1-3600 sensor, CiA 406 encoder profile",
       novotechnik_406_options(),
       "an absolute encoder has no \"not operated\" position: position's neutral 0 is the value it reports "
       "while Error or Offline, not a safe state (act on the status); cams and work_area are 6300h:01 and "
       "6400h:01, mapped into TPDO1 at boot"},
      {"cia401", "Generic CiA 401 I/O node (pedals, button clusters, indicator panels) described by its EDS",
       cia401_options(),
       "they come from the node's EDS file (option eds): in[k] per 6000h sub-index (Digital 0..255), "
       "in32[k] per 6120h (Digital, 32 lines), analog[k] per 6401h (Analog -32768..32767), out[k] per 6200h "
       "(Output 0..255), aout[k] per 6411h (Output -32768..32767), the outputs narrowed by the EDS's "
       "LowLimit/HighLimit; "
       "`oegw signals cia401 --eds FILE` lists those of one EDS"},
  };
  return table;
}

const DriverInfo* find_driver_info(std::string_view family) {
  for (const DriverInfo& d : drivers())
    if (d.family == family) return &d;
  return nullptr;
}

std::string driver_names() {
  std::string out;
  for (const DriverInfo& d : drivers()) out += (out.empty() ? "" : ", ") + std::string(d.family);
  return out;
}

std::unique_ptr<Driver> make_driver(std::string_view family, NodeId node, FrameSink sink, const DriverOptions& options,
                                    OptionRefusals& refusals) {
  if (family == "elobau-mfg") return make_elobau_mfg_driver(node, std::move(sink), options, refusals);
  if (family == "mcb402") return make_mcb402_driver(node, std::move(sink), options, refusals);
  if (family == "novotechnik-406") return make_novotechnik_406_driver(node, std::move(sink), options, refusals);
  if (family == "cia401") return make_cia401_driver(node, std::move(sink), options, refusals);
  refusals.push_back({"", "unknown driver '" + std::string(family) + "' (expected one of: " + driver_names() + ")"});
  return nullptr;
}

std::unique_ptr<Driver> make_driver(std::string_view family, NodeId node, FrameSink sink, const DriverOptions& options,
                                    std::string& error) {
  return with_error_text(error, [&](OptionRefusals& refusals) {
    return make_driver(family, node, std::move(sink), options, refusals);
  });
}

std::optional<std::vector<SignalInfo>> listing_signals(const DriverInfo& info, DriverOptions given,
                                                       std::string& error) {
  for (const OptionSpec& o : info.options) {
    if (!o.required || given.get(o.name)) continue;
    if (o.listing_value.empty()) return std::nullopt;
    given.values.emplace_back(std::string(o.name), std::string(o.listing_value));
  }
  auto driver = make_driver(info.family, NodeId{1}, {}, given, error);
  if (!driver) return std::nullopt;
  return driver->signals();
}

}  // namespace oegw::subdevices
