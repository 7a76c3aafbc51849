// The `downstream` section: the sub-devices' bus, of which the gateway is the master.
#include "mapping/sections/sections.hpp"

#include <cstdio>
#include <cstdlib>

namespace oegw::mapping::sections {

void read_downstream(YamlReader& r, const MapEntry& sec, DownstreamConfig& d) {
  d.where = r.loc(sec.key);
  const auto es =
      r.entries(sec.value, "downstream",
                {"interface", "bitrate", "network_id", "emcy_forwarding", "sdo_timeout_ms", "sync_period_ms"},
                "a map with interface, bitrate, network_id, emcy_forwarding, sdo_timeout_ms, sync_period_ms");
  if (const auto* e = r.find(es, "interface")) {
    d.interface_where = r.loc(e->value);
    if (auto s = r.string(*e, "interface")) d.interface = *s;
  }
  r.bitrate(es, "bitrate", d.bitrate);
  if (const auto* e = r.find(es, "network_id")) d.network_id_where = r.loc(e->value);
  r.set_int(es, "network_id", "network_id", 1, 127, d.network_id);
  r.set_int(es, "sdo_timeout_ms", "sdo_timeout_ms", 10, 60000, d.sdo_timeout_ms);
  if (const auto* e = r.find(es, "sync_period_ms")) d.sync_period_where = r.loc(e->value);
  r.set_int(es, "sync_period_ms", "sync_period_ms", 0, 10000, d.sync_period_ms);
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

void check_sync(YamlReader& r, const Config& cfg) {
  if (cfg.downstream.sync_period_ms != 0) return;
  auto refuse = [&r](const Location& at, const std::string& what, std::int64_t type) {
    r.error(at, what + " " + std::to_string(type) +
                    " is a synchronous transmission type (the PDO is sent only at a SYNC, CiA 301 §7.5.2.35) and "
                    "downstream.sync_period_ms is 0, so no SYNC is produced; expected downstream.sync_period_ms "
                    "1..10000, or an asynchronous type (254, 255)");
  };
  for (const SubdeviceConfig& s : cfg.subdevices) {
    for (const auto& [key, at] : s.option_where) {
      if (key != "transmission_type") continue;
      const auto v = s.options.get(key);
      char* end = nullptr;
      const long long t = v ? std::strtoll(v->c_str(), &end, 0) : -1;
      if (v && end != v->c_str() && *end == '\0' && t >= 0 && t <= 240)
        refuse(at, "sub-device '" + s.name + "' option transmission_type", t);
    }
    for (const SdoWriteConfig& w : s.sdo)
      if (w.index >= 0x1800 && w.index <= 0x19FF && w.sub_index == 2 && w.value >= 0 && w.value <= 240) {
        char b[96];
        std::snprintf(b, sizeof b, "sub-device '%s' sdo write %04Xh:02 (TPDO transmission type)", s.name.c_str(),
                      static_cast<unsigned>(w.index));
        refuse(w.where, b, w.value);
      }
  }
}

}  // namespace oegw::mapping::sections
