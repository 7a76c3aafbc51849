// The `subdevices` section: the nodes on the downstream bus, their drivers, supervision times,
// identity checks, SDO writes at boot and driver options; their signals from the catalogue.
#include <algorithm>
#include <array>
#include <cctype>
#include <filesystem>
#include <map>
#include <span>
#include <utility>

#include "mapping/sections/cob_ids.hpp"
#include "mapping/sections/sections.hpp"
#include "subdevices/driver_options.hpp"

namespace oegw::mapping::sections {

namespace {

using canopen::DataType;

const std::vector<std::string_view> kSubdeviceKeys = {"driver",         "node_id",
                                                      "heartbeat_ms",   "heartbeat_timeout_ms",
                                                      "pdo_timeout_ms", "mandatory",
                                                      "identity",       "sdo",
                                                      "options"};

// The types an `sdo` write may name, with their value ranges.
struct DataTypeName {
  std::string_view name;
  DataType type;
  std::int64_t min, max;
};
constexpr std::array<DataTypeName, 6> kSdoTypes = {{
    {"u8", DataType::Unsigned8, 0, 0xFF},
    {"u16", DataType::Unsigned16, 0, 0xFFFF},
    {"u32", DataType::Unsigned32, 0, 0xFFFFFFFF},
    {"i8", DataType::Integer8, -128, 127},
    {"i16", DataType::Integer16, -32768, 32767},
    {"i32", DataType::Integer32, std::numeric_limits<std::int32_t>::min(), std::numeric_limits<std::int32_t>::max()},
}};

// heartbeat_ms, heartbeat_timeout_ms (longer than the heartbeat), pdo_timeout_ms, and proof of
// life: without a heartbeat only fresh PDOs show the node is there.
void read_supervision(YamlReader& r, const std::vector<MapEntry>& ks, const std::string& what, SubdeviceConfig& s) {
  r.set_int(ks, "heartbeat_ms", "heartbeat_ms", 0, 65535, s.heartbeat_ms);
  r.set_int(ks, "heartbeat_timeout_ms", "heartbeat_timeout_ms", 0, 65535, s.heartbeat_timeout_ms);
  if (const auto* t = r.find(ks, "heartbeat_timeout_ms");
      t && s.heartbeat_timeout_ms != 0 && s.heartbeat_ms != 0 && s.heartbeat_timeout_ms <= s.heartbeat_ms)
    r.error(t->value, "heartbeat_timeout_ms " + t->value.Scalar() + " is not longer than heartbeat_ms " +
                          std::to_string(s.heartbeat_ms) + "; expected more than " + std::to_string(s.heartbeat_ms) +
                          " (or 0 for 1.5 x heartbeat_ms)");
  r.set_int(ks, "pdo_timeout_ms", "pdo_timeout_ms", 0, 65535, s.pdo_timeout_ms);
  if (const auto* h = r.find(ks, "heartbeat_ms"); h && s.heartbeat_ms == 0 && s.pdo_timeout_ms == 0)
    r.error(h->value, "heartbeat_ms 0 leaves " + what +
                          " without proof of life; expected a heartbeat (heartbeat_ms > 0) or pdo_timeout_ms > 0");
}

// The 1000h/1018h values checked at boot; each one optional.
void read_identity(YamlReader& r, const MapEntry& e, const std::string& what, SubdeviceConfig& s) {
  subdevices::ExpectedIdentity& id = s.identity;
  const auto ids = r.entries(e.value, what + " identity",
                             {"device_type", "vendor_id", "product_code", "revision", "revision_match", "serial"},
                             "a map with device_type, vendor_id, product_code, revision, revision_match, serial");
  if (const auto* x = r.find(ids, "revision_match"))
    if (auto m = r.string(*x, "revision_match")) {
      if (*m == "exact" || *m == "major") {
        s.exact_revision = *m == "exact";
      } else {
        r.error(x->value, "found '" + *m +
                              "' for revision_match; expected major (the upper 16 bits of 1018h:03, "
                              "the default) or exact");
      }
    }
  auto opt = [&](std::string_view k, std::optional<std::uint32_t>& out) {
    if (const auto* x = r.find(ids, k))
      if (auto v = r.integer(*x, k, 0, 0xFFFFFFFF, true)) out = static_cast<std::uint32_t>(*v);
  };
  opt("device_type", id.device_type);
  opt("vendor_id", id.vendor_id);
  opt("product_code", id.product_code);
  opt("revision", id.revision);
  opt("serial", id.serial);
}

// The driver's options, name -> one scalar each, or a list of scalars passed on as their values
// joined by ',' (e.g. the MCB-402's button_bits: [1, 2, 3, 4, 5, 7, 6]); the driver judges them
// (read_signals).
void read_options(YamlReader& r, const MapEntry& e, const std::string& what, SubdeviceConfig& s) {
  for (const auto& x : r.entries(e.value, what + " options", {}, "a map of the driver's options")) {
    std::string value;
    bool scalars = x.value.IsScalar() || x.value.IsSequence();
    if (x.value.IsScalar()) value = x.value.Scalar();
    if (x.value.IsSequence())
      for (const auto& item : x.value) {
        scalars = scalars && item.IsScalar();
        if (item.IsScalar()) value += (value.empty() ? "" : ",") + item.Scalar();
      }
    if (!scalars) {
      r.error(x.value, "found " + node_kind(x.value) + " for option '" + x.name +
                           "'; expected a single value or a list of single values");
      continue;
    }
    // A file the driver opens is taken from the mapping file's folder
    // (docs/reference/mapping-file.md#paths).
    s.options.values.emplace_back(x.name, subdevices::is_file_option(x.name) ? r.path(value) : value);
    s.option_where.emplace_back(x.name, r.loc(x.value));
  }
}

const DataTypeName* sdo_type(YamlReader& r, const MapEntry& te) {
  const std::string t = te.value.IsScalar() ? te.value.Scalar() : "";
  const DataTypeName* type = nullptr;
  for (const auto& d : kSdoTypes)
    if (d.name == t) type = &d;
  if (!type) {
    std::vector<std::string_view> names;
    for (const auto& d : kSdoTypes) names.push_back(d.name);
    r.error(te.value,
            "found " + node_kind(te.value) + " for type; expected one of " + join(names) + did_you_mean(t, names));
  }
  return type;
}

// One `{ index, sub_index, value, type }` write; nullopt (errors reported) unless all four fit.
std::optional<SdoWriteConfig> read_sdo_write(YamlReader& r, const YAML::Node& item) {
  SdoWriteConfig w;
  w.where = r.loc(item);
  const auto ks = r.entries(item, "an sdo write", {"index", "sub_index", "value", "type"},
                            "a map with index, sub_index, value, type");
  if (!item.IsMap()) return std::nullopt;
  bool good = true;
  auto need = [&](std::string_view k, std::string_view expected) -> const MapEntry* {
    const auto* e = r.find(ks, k);
    if (!e) {
      r.missing(item, k, "an sdo write", expected);
      good = false;
    }
    return e;
  };
  const auto* ie = need("index", "an object index 0x1000..0xFFFF");
  const auto* se = need("sub_index", "a sub-index 0..255");
  const auto* ve = need("value", "the value to write");
  const auto* te = need("type", "one of u8, u16, u32, i8, i16, i32");
  if (ie) {
    if (auto v = r.integer(*ie, "index", 0x1000, 0xFFFF, true)) w.index = static_cast<std::uint16_t>(*v);
    else good = false;
  }
  if (se) {
    if (auto v = r.integer(*se, "sub_index", 0, 255, true)) w.sub_index = static_cast<std::uint8_t>(*v);
    else good = false;
  }
  const DataTypeName* type = te ? sdo_type(r, *te) : nullptr;
  if (te && !type) good = false;
  if (type) w.type = type->type;
  if (ve && type) {
    if (auto v = r.integer(*ve, std::string("value of type ") + std::string(type->name), type->min, type->max,
                           type->min == 0))
      w.value = *v;
    else good = false;
  }
  if (!good) return std::nullopt;
  return w;
}

void read_sdo_list(YamlReader& r, const MapEntry& l, SubdeviceConfig& s) {
  if (!l.value.IsSequence()) {
    r.error(l.value, "found " + node_kind(l.value) + " for sdo; expected a list of {index, sub_index, value, type}");
    return;
  }
  for (const auto& item : l.value)
    if (auto w = read_sdo_write(r, item)) s.sdo.push_back(*w);
}

// The families' names, as the driver registry has them (subdevices/registry.cpp).
std::vector<std::string_view> family_names() {
  std::vector<std::string_view> names;
  for (const auto& d : subdevices::drivers()) names.push_back(d.family);
  return names;
}

// One refusal of the driver's options, at the option's value when it is about one that is written
// (else at `options`, or at the driver without them), with the expected clause the driver's
// message lacks. A file option (an `eds:`) naming no file gets how a path is taken instead
// (docs/reference/mapping-file.md#paths), and, written with a leading '~', that no shell expands it.
void report_refusal(YamlReader& r, const MapEntry& drv, const std::vector<MapEntry>& ks, const std::string& what,
                    const SubdeviceConfig& s, const subdevices::OptionRefusal& refusal) {
  const auto* o = r.find(ks, "options");
  Location at = o ? r.loc(o->key) : r.loc(drv.value);
  std::string written;
  for (const auto& [name, where] : s.option_where)
    if (!refusal.option.empty() && name == refusal.option) at = where;
  if (o && o->value.IsMap() && !refusal.option.empty())
    if (const auto v = o->value[refusal.option]; v && v.IsScalar()) written = v.Scalar();
  const std::string opened =
      subdevices::is_file_option(refusal.option) ? s.options.get(refusal.option).value_or("") : "";
  std::error_code ec;
  const bool absent = !opened.empty() && !std::filesystem::exists(opened, ec) && !ec;
  std::string msg = "driver " + s.driver + " refused " + what + ": " + refusal.message;
  if (absent && !written.empty() && written.front() == '~')
    msg += " ('" + written + "' was written: '~' is not expanded, no shell reads the mapping file)";
  if (refusal.message.find("; expected") == std::string::npos)
    msg += absent ? "; expected the path of an existing file, absolute or relative to the mapping file's folder"
                  : "; expected options the " + s.driver + " driver accepts";
  r.error(at, msg);
}

// The driver's signals from the catalogue; an unknown driver or options it refuses are errors,
// every refused option its own (at its value).
void read_signals(YamlReader& r, const SignalCatalogue& catalogue, const MapEntry& drv, const std::vector<MapEntry>& ks,
                  const std::string& what, SubdeviceConfig& s) {
  subdevices::OptionRefusals refusals;
  if (!catalogue) refusals.push_back({"", "no signal catalogue"});
  auto sig = catalogue ? catalogue(s.driver, s.options, refusals) : std::nullopt;
  const auto families = family_names();
  if (sig) {
    s.signals = std::move(*sig);
  } else if (std::find(families.begin(), families.end(), s.driver) == families.end()) {
    r.error(drv.value,
            "unknown driver '" + s.driver + "'; expected one of " + join(families) + did_you_mean(s.driver, families));
  } else {
    if (refusals.empty()) refusals.push_back({"", "no reason given"});
    for (const auto& refusal : refusals) report_refusal(r, drv, ks, what, s, refusal);
  }
}

// Node-IDs name each node's default COB-IDs: two sub-devices on one node-ID are reported as that,
// once, not as 13 clashes.
using NodesInUse = std::map<int, std::pair<std::string, Location>>;
void check_node_id_unique(YamlReader& r, const MapEntry& nid, const SubdeviceConfig& s, NodesInUse& by_node) {
  auto [it, fresh] = by_node.emplace(s.node_id, std::pair(s.name, r.loc(nid.value)));
  if (!fresh)
    r.error(nid.value, "node_id " + nid.value.Scalar() + " of '" + s.name + "' is already used by sub-device '" +
                           it->second.first + "' (" + it->second.second.line_column() +
                           "), so all their default COB-IDs clash; expected a node-ID of its own");
}

// The map of one sub-device; its errors are reported, `s` keeps what could be read.
void read_subdevice(YamlReader& r, const MapEntry& e, const std::vector<MapEntry>& ks, const SignalCatalogue& catalogue,
                    NodesInUse& by_node, SubdeviceConfig& s) {
  const auto what = "sub-device '" + e.name + "'";
  const auto* drv = r.find(ks, "driver");
  if (drv) {
    if (auto d = r.string(*drv, "driver")) s.driver = *d;
  } else {
    r.missing(e.value, "driver", what, "one of " + join(family_names()));
  }
  if (r.find(ks, "node_id")) r.set_int(ks, "node_id", "node_id", 1, 127, s.node_id, false);
  else r.missing(e.value, "node_id", what, "its node-ID 1..127");
  read_supervision(r, ks, what, s);
  if (const auto* m = r.find(ks, "mandatory"))
    if (auto b = r.boolean(*m, "mandatory")) s.mandatory = *b;
  if (const auto* id = r.find(ks, "identity")) read_identity(r, *id, what, s);
  if (const auto* o = r.find(ks, "options")) read_options(r, *o, what, s);
  if (const auto* l = r.find(ks, "sdo")) read_sdo_list(r, *l, s);
  if (s.node_id != 0) check_node_id_unique(r, *r.find(ks, "node_id"), s, by_node);
  if (drv && !s.driver.empty()) read_signals(r, catalogue, *drv, ks, what, s);
}

}  // namespace

void read_subdevices(YamlReader& r, const MapEntry& sec, const SignalCatalogue& catalogue,
                     std::vector<SubdeviceConfig>& out) {
  const auto es = r.entries(sec.value, "subdevices", {}, "a map of sub-device name -> {driver, node_id, ...}");
  NodesInUse by_node;
  std::vector<CobUse> cobs;
  // Beyond 127 the rest is not read (a file of 100 000 sub-devices costs nothing more than one
  // of 128); the first 127 are, so that references to them are no further errors.
  if (es.size() > kMaxSubdevices)
    r.error(es[kMaxSubdevices].key, "sub-device " + std::to_string(kMaxSubdevices + 1) + " ('" +
                                        es[kMaxSubdevices].name + "'); expected at most " +
                                        std::to_string(kMaxSubdevices) + " (one per CANopen node-ID)");
  for (const auto& e : std::span(es).first(std::min(es.size(), kMaxSubdevices))) {
    SubdeviceConfig s;
    s.name = e.name;
    s.where = r.loc(e.key);
    if (!valid_subdevice_name(e.name))
      r.error(e.key, "sub-device name '" + e.name +
                         "' has characters other than a-z, 0-9 and _; expected a name like right_grip");
    const auto ks = r.entries(e.value, "sub-device '" + e.name + "'", kSubdeviceKeys,
                              "a map with driver, node_id, heartbeat_ms, heartbeat_timeout_ms, pdo_timeout_ms, "
                              "mandatory, identity, sdo, options");
    if (e.value.IsMap()) {
      read_subdevice(r, e, ks, catalogue, by_node, s);
      if (s.node_id != 0) add_cob_uses(r, s, cobs);
    }
    out.push_back(std::move(s));
  }
  check_cob_clashes(r, cobs);
}

}  // namespace oegw::mapping::sections
