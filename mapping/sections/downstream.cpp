// The `downstream` section: the sub-devices' bus, of which the gateway is the master.
#include "mapping/sections/sections.hpp"

namespace oegw::mapping::sections {

void read_downstream(YamlReader& r, const MapEntry& sec, DownstreamConfig& d) {
  d.where = r.loc(sec.key);
  const auto es =
      r.entries(sec.value, "downstream", {"interface", "bitrate", "network_id", "emcy_forwarding", "sdo_timeout_ms"},
                "a map with interface, bitrate, network_id, emcy_forwarding, sdo_timeout_ms");
  if (const auto* e = r.find(es, "interface"))
    if (auto s = r.string(*e, "interface")) d.interface = *s;
  r.bitrate(es, "bitrate", d.bitrate);
  if (const auto* e = r.find(es, "network_id")) d.network_id_where = r.loc(e->value);
  r.set_int(es, "network_id", "network_id", 1, 127, d.network_id);
  r.set_int(es, "sdo_timeout_ms", "sdo_timeout_ms", 10, 60000, d.sdo_timeout_ms);
  if (const auto* e = r.find(es, "emcy_forwarding")) {
    if (auto s = r.string(*e, "emcy_forwarding")) {
      bool known = false;
      for (const EmcyForwarding f : {EmcyForwarding::All, EmcyForwarding::Faults, EmcyForwarding::None})
        if (*s == to_string(f)) {
          d.emcy_forwarding = f;
          known = true;
        }
      if (!known) r.error(e->value, "found '" + *s + "' for emcy_forwarding; expected one of all, faults, none");
    }
  }
}

}  // namespace oegw::mapping::sections
