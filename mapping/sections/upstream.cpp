// The `upstream` section: the gateway as a CiA 852 device on the host's bus.
#include <algorithm>
#include <cstdio>
#include <tuple>

#include "canopen/types.hpp"
#include "mapping/sections/sections.hpp"

namespace oegw::mapping::sections {

namespace {

namespace cob = canopen::cob;

constexpr std::size_t kMaxSdoServers = 127;  // 1201h..127Fh

// "1201h".
std::string sdo_server_index(std::size_t k) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%04Xh", static_cast<unsigned>(0x1200 + k));
  return buf;
}

// "601h..67Fh (the default SDO client->server identifiers)": the restricted range (CiA 301
// §7.3.5, cob::restricted) that holds `id`.
std::string restricted_range(std::uint32_t id) {
  struct Range {
    std::uint32_t lo, hi;
    const char* what;
  };
  static constexpr Range kRanges[] = {
      {0x000, 0x000, "000h (NMT)"},
      {0x001, 0x07F, "001h..07Fh (reserved)"},
      {0x101, 0x180, "101h..180h (reserved)"},
      {0x581, 0x5FF, "581h..5FFh (the default SDO server->client identifiers)"},
      {0x601, 0x67F, "601h..67Fh (the default SDO client->server identifiers)"},
      {0x6E0, 0x6FF, "6E0h..6FFh (reserved)"},
      {0x701, 0x77F, "701h..77Fh (NMT error control)"},
      {0x780, 0x7FF, "780h..7FFh (reserved, LSS)"},
  };
  for (const auto& r : kRanges)
    if (id >= r.lo && id <= r.hi) return r.what;
  return "?";
}

// One `{ subdevice, request, response }` entry; what could be read is kept.
void read_sdo_server(YamlReader& r, const YAML::Node& item, std::size_t k, SdoServerConfig& s) {
  s.where = r.loc(item);
  const std::string what = "upstream sdo_servers entry " + std::to_string(k) + " (" + sdo_server_index(k) + ")";
  const auto ks =
      r.entries(item, what, {"subdevice", "request", "response"}, "a map with subdevice, request, response");
  if (!item.IsMap()) return;
  if (const auto* e = r.find(ks, "subdevice")) {
    s.subdevice_where = r.loc(e->value);
    if (auto v = r.string(*e, "subdevice")) s.subdevice = *v;
  }
  if (const auto* e = r.find(ks, "request")) {
    s.request_where = r.loc(e->value);
    if (auto v = r.integer(*e, "request", 0, 0x7FF, true)) s.request = static_cast<std::uint32_t>(*v);
  }
  if (const auto* e = r.find(ks, "response")) {
    s.response_where = r.loc(e->value);
    if (auto v = r.integer(*e, "response", 0, 0x7FF, true)) s.response = static_cast<std::uint32_t>(*v);
  }
  const bool req = r.find(ks, "request") != nullptr;
  const bool rsp = r.find(ks, "response") != nullptr;
  if (req != rsp)
    r.error(req ? s.request_where : s.response_where,
            std::string(req ? "request" : "response") + " of SDO server " + sdo_server_index(k) + " without " +
                (req ? "response" : "request") +
                "; expected both COB-IDs, or neither (the channel is then disabled until the host writes " +
                sdo_server_index(k) + ":01/02)");
}

void read_sdo_servers(YamlReader& r, const MapEntry& l, std::vector<SdoServerConfig>& out) {
  if (!l.value.IsSequence()) {
    r.error(l.value,
            "found " + node_kind(l.value) + " for sdo_servers; expected a list of {subdevice, request, response}");
    return;
  }
  std::size_t k = 0;
  for (const auto& item : l.value) {
    if (++k > kMaxSdoServers) {
      r.error(item, "sdo_servers entry " + std::to_string(k) +
                        " is beyond 127Fh; expected at most 127 additional SDO "
                        "server channels (1201h..127Fh)");
      return;
    }
    out.emplace_back();
    read_sdo_server(r, item, k, out.back());
  }
}

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
      r.entries(sec.value, "upstream",
                {"interface", "node_id", "bitrate", "identity", "heartbeat_ms", "store", "network_id", "sdo_servers"},
                "a map with interface, node_id, bitrate, identity, heartbeat_ms, store, network_id, sdo_servers");
  if (!sec.value.IsMap()) return;
  if (const auto* e = r.find(es, "interface")) {
    u.interface_where = r.loc(e->value);
    if (auto s = r.string(*e, "interface")) u.interface = *s;
  }
  if (r.find(es, "node_id")) r.set_int(es, "node_id", "node_id", 1, 127, u.node_id);
  else r.missing(sec.value, "node_id", "upstream", "the gateway's node-ID 1..127");
  r.bitrate(es, "bitrate", u.bitrate);
  r.set_int(es, "heartbeat_ms", "heartbeat_ms", 0, 65535, u.heartbeat_ms);
  if (const auto* e = r.find(es, "network_id")) u.network_id_where = r.loc(e->value);
  r.set_int(es, "network_id", "network_id", 1, 127, u.network_id);
  if (const auto* e = r.find(es, "store")) {
    u.store_where = r.loc(e->value);
    if (auto s = r.string(*e, "store")) u.store = r.path(*s);  // from the file's folder
  }
  if (const auto* e = r.find(es, "identity")) read_identity(r, *e, u.identity);
  if (const auto* e = r.find(es, "sdo_servers")) read_sdo_servers(r, *e, u.sdo_servers);
}

namespace {

// A COB-ID the gateway uses on the host's bus, or an SDO channel's.
struct UpstreamCob {
  std::uint32_t id;
  std::string owner;  // "the gateway's TPDO1 (180h + node-ID 20h)", "SDO server 1201h request"
  Location where;     // set for an SDO channel's
};

// "180h", "20h".
std::string hex_h(std::uint32_t v, int width) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%0*Xh", width, static_cast<unsigned>(v));
  return buf;
}

// The gateway's own COB-IDs on the host's bus: its predefined connection set (EMCY, TPDO1..4,
// RPDO1..4, default SDO, heartbeat; the CiA 852 PDOs start there or are assigned by the host),
// SYNC 080h (1005h), TIME 100h, and, with output FEs (1028h, CiA 852 Annex A), the EMCYs of the
// other nodes it consumes.
std::vector<UpstreamCob> gateway_cobs(const Config& c) {
  std::vector<UpstreamCob> out;
  const canopen::NodeId node{c.upstream.node_id};
  if (!node.valid()) return out;  // node_id is reported as such
  for (const auto& d : cob::predefined_connection_set(node))
    out.push_back({d.cob_id,
                   "the gateway's " + std::string(d.service) + " (" + hex_h(d.cob_id - node.value(), 3) +
                       " + node-ID " + hex_h(node.value(), 2) + ")",
                   {}});
  out.push_back({cob::kSync, "the gateway's SYNC (1005h)", {}});
  out.push_back({cob::kTime, "TIME (100h, CiA 301 predefined connection set)", {}});
  const bool outputs = std::any_of(c.functional_elements.begin(), c.functional_elements.end(),
                                   [](const FunctionalElementConfig& f) { return !f.input(); });
  if (outputs)
    for (std::uint32_t n = 1; n <= 127; ++n)
      if (n != node.value())
        out.push_back({cob::kEmcy + n, "the EMCY of node " + hex_h(n, 2) + ", which the gateway consumes (1028h)", {}});
  return out;
}

}  // namespace

void check_sdo_servers(YamlReader& r, const Config& c, bool subdevices_read) {
  std::vector<std::string> names;
  for (const auto& d : c.subdevices) names.push_back(d.name);
  std::vector<UpstreamCob> used = gateway_cobs(c);
  const std::size_t gateway_count = used.size();
  for (std::size_t k = 1; k <= c.upstream.sdo_servers.size(); ++k) {
    const SdoServerConfig& s = c.upstream.sdo_servers[k - 1];
    const std::string server = "SDO server " + sdo_server_index(k);
    if (subdevices_read && !s.subdevice.empty() && c.find_subdevice(s.subdevice) == nullptr)
      r.error(s.subdevice_where, "unknown sub-device '" + s.subdevice + "' for " + server + "; expected one of " +
                                     (names.empty() ? std::string("the sub-devices section's names") : join(names)) +
                                     did_you_mean(s.subdevice, names));
    if (!s.enabled()) continue;
    for (const auto& [which, id, where] :
         {std::tuple{"request", *s.request, s.request_where}, std::tuple{"response", *s.response, s.response_where}}) {
      const std::string what = std::string(which) + " COB-ID " + hex(id, 3) + " of " + server;
      if (cob::restricted(id)) {
        r.error(where, what + " is a CAN-ID CiA 301 restricts: " + restricted_range(id) +
                           "; expected an 11-bit COB-ID outside 000h..07Fh, 101h..180h, 581h..5FFh, 601h..67Fh, "
                           "6E0h..6FFh, 701h..7FFh");
        continue;
      }
      const auto clash = std::find_if(used.begin(), used.end(), [id = id](const UpstreamCob& u) { return u.id == id; });
      if (clash == used.end()) {
        used.push_back({id, server + " " + which, where});
        continue;
      }
      const bool channel = static_cast<std::size_t>(clash - used.begin()) >= gateway_count;
      r.error(where, what +
                         (channel ? " is already used by " + clash->owner + " (" + clash->where.line_column() + ")"
                                  : " clashes with " + clash->owner) +
                         "; expected a COB-ID no other object of the gateway uses");
    }
  }
}

}  // namespace oegw::mapping::sections
