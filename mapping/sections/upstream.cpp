// The `upstream` section: the gateway as a CiA 852 device on the host's bus.
#include "mapping/sections/sections.hpp"

namespace oegw::mapping::sections {

namespace {

// 1018h sub-indices 1..4, as `identity: { vendor_id, product_code, revision, serial }`.
void read_identity(YamlReader& r, const MapEntry& e, UpstreamIdentity& id) {
  const auto ids = r.entries(e.value, "upstream identity", {"vendor_id", "product_code", "revision", "serial"},
                             "a map with vendor_id, product_code, revision, serial");
  r.set_int(ids, "vendor_id", "vendor_id", 0, 0xFFFFFFFF, id.vendor_id, true);
  r.set_int(ids, "product_code", "product_code", 0, 0xFFFFFFFF, id.product_code, true);
  r.set_int(ids, "revision", "revision", 0, 0xFFFFFFFF, id.revision, true);
  r.set_int(ids, "serial", "serial", 0, 0xFFFFFFFF, id.serial, true);
}

}  // namespace

void read_upstream(YamlReader& r, const MapEntry& sec, UpstreamConfig& u) {
  u.where = r.loc(sec.key);
  const auto es =
      r.entries(sec.value, "upstream", {"interface", "node_id", "bitrate", "identity", "heartbeat_ms", "store", "network_id"},
                "a map with interface, node_id, bitrate, identity, heartbeat_ms, store, network_id");
  if (!sec.value.IsMap()) return;
  if (const auto* e = r.find(es, "interface"))
    if (auto s = r.string(*e, "interface")) u.interface = *s;
  if (r.find(es, "node_id"))
    r.set_int(es, "node_id", "node_id", 1, 127, u.node_id);
  else
    r.missing(sec.value, "node_id", "upstream", "the gateway's node-ID 1..127");
  r.bitrate(es, "bitrate", u.bitrate);
  r.set_int(es, "heartbeat_ms", "heartbeat_ms", 0, 65535, u.heartbeat_ms);
  if (const auto* e = r.find(es, "network_id")) u.network_id_where = r.loc(e->value);
  r.set_int(es, "network_id", "network_id", 1, 127, u.network_id);
  if (const auto* e = r.find(es, "store"))
    if (auto s = r.string(*e, "store")) u.store = *s;
  if (const auto* e = r.find(es, "identity")) read_identity(r, *e, u.identity);
}

}  // namespace oegw::mapping::sections
