// The `functional_elements` section: the CiA 852 FEs the gateway offers, "kind.instance" ->
// { field: signal, ... } (field_binding.hpp), and for output FEs who may command them
// (`sources`) and their command watchdog (`command_timeout_ms`).
#include <algorithm>
#include <map>
#include <tuple>

#include "mapping/field_binding.hpp"
#include "mapping/sections/sections.hpp"

namespace oegw::mapping::sections {

namespace {

std::vector<std::string_view> kind_names() {
  std::vector<std::string_view> kinds;
  for (auto k : {FeKind::Joystick, FeKind::FootPedal, FeKind::Encoder, FeKind::Wheel, FeKind::ButtonCluster,
                 FeKind::IndicatorCluster, FeKind::Display})
    kinds.push_back(to_string(k));
  return kinds;
}

// "joystick.1" -> its FeId: a known kind and an instance in range (CiA 852 clause 9).
std::optional<FeId> read_fe_id(YamlReader& r, const MapEntry& e) {
  const auto dot = e.name.find('.');
  const std::string kind_name = e.name.substr(0, dot);
  const auto kind = fe_kind_from_string(kind_name);
  if (!kind) {
    const auto kinds = kind_names();
    r.error(e.key, "unknown functional element kind '" + kind_name + "' in '" + e.name + "'; expected one of " +
                       join(kinds) + did_you_mean(kind_name, kinds));
    return std::nullopt;
  }
  const auto range = "1.." + std::to_string(max_instances(*kind));
  const auto inst = dot == std::string::npos ? std::nullopt : parse_integer(std::string_view(e.name).substr(dot + 1));
  if (!inst || e.name.substr(dot + 1).find_first_not_of("0123456789") != std::string::npos) {
    r.error(e.key,
            "functional element '" + e.name + "' has no instance number; expected " + kind_name + ".N with N " + range);
    return std::nullopt;
  }
  if (*inst < 1 || *inst > max_instances(*kind)) {
    r.error(e.key, "instance " + std::to_string(*inst) + " of '" + e.name + "' is out of range; expected " + kind_name +
                       "." + range + " (CiA 852 clause 9)");
    return std::nullopt;
  }
  return FeId{*kind, static_cast<std::uint8_t>(*inst)};
}

// `sources: [canopen, dds, lcm]` or one name: who may command an output FE (config.hpp).
void read_command_sources(YamlReader& r, const MapEntry& e, FunctionalElementConfig& fe, const std::string& fe_name) {
  static const std::vector<std::string_view> names = {"canopen", "dds", "lcm"};
  const std::string expected = "a list of canopen, dds, lcm, e.g. sources: [canopen, dds]";
  if (fe.input()) {
    r.error(e.key, fe_name + " is an input; 'sources' applies to indicators and display (commands in)");
    return;
  }
  std::vector<YAML::Node> items;
  if (e.value.IsScalar() && !e.value.Scalar().empty()) {
    items.push_back(e.value);
  } else if (e.value.IsSequence() && e.value.size() > 0) {
    for (const auto& n : e.value) items.push_back(n);
  } else {
    r.error(e.value, "found " + node_kind(e.value) + " for " + fe_name + " sources; expected " + expected);
    return;
  }
  CommandSources set = 0;
  bool ok = true;
  for (const auto& n : items) {
    const std::string name = n.IsScalar() ? n.Scalar() : std::string();
    const auto it = std::find(names.begin(), names.end(), name);
    if (it == names.end()) {
      r.error(n, "found " + (n.IsScalar() ? "'" + name + "'" : node_kind(n)) + " in " + fe_name +
                     " sources; expected one of canopen, dds, lcm" + did_you_mean(name, names));
      ok = false;
      continue;
    }
    const auto bit = static_cast<CommandSources>(1u << (it - names.begin()));
    if ((set & bit) != 0) {
      r.error(n, "'" + name + "' appears twice in " + fe_name + " sources; expected each source once");
      ok = false;
    }
    set = static_cast<CommandSources>(set | bit);
  }
  if (!ok) return;
  fe.sources = set;
  fe.sources_where = r.loc(e.value);
}

void read_command_timeout(YamlReader& r, const MapEntry& e, FunctionalElementConfig& fe, const std::string& fe_name) {
  if (fe.input())
    r.error(e.key, fe_name + " is an input; 'command_timeout_ms' applies to indicators and display (commands in)");
  else if (auto v = r.integer(e, fe_name + " command_timeout_ms", 0, 600000))
    fe.command_timeout_ms = static_cast<std::uint32_t>(*v);
}

// An FE needs at least one field; `sources` and `command_timeout_ms` alone are not enough.
void check_has_fields(YamlReader& r, const MapEntry& fe_entry, const std::vector<MapEntry>& es,
                      const std::string& fe_name) {
  if (fe_entry.value.IsMap() && es.empty() && fe_entry.value.size() == 0)
    r.error(fe_entry.value, fe_name + " has no fields; expected at least one field fed by a signal");
  if (!es.empty() && std::all_of(es.begin(), es.end(), [](const MapEntry& x) {
        return x.name == "sources" || x.name == "command_timeout_ms";
      })) {
    std::string keys;
    for (const auto& x : es) keys += (keys.empty() ? "'" : " and '") + x.name + "'";
    r.error(fe_entry.value,
            fe_name + " has only " + keys + " and no fields; expected at least one field fed by a signal");
  }
}

// The entries of one FE: its settings and its fields.
void read_fe_entries(YamlReader& r, const MapEntry& fe_entry, FieldBinder& binder, FunctionalElementConfig& fe) {
  const std::string fe_name = mapping::fe_name(fe.id);
  const auto es = r.entries(fe_entry.value, fe_name, {}, "a map of field -> signal, e.g. { x: right_grip.x }");
  check_has_fields(r, fe_entry, es, fe_name);
  for (const auto& e : es) {
    if (e.name == "sources") read_command_sources(r, e, fe, fe_name);
    else if (e.name == "command_timeout_ms") read_command_timeout(r, e, fe, fe_name);
    else binder.bind(e, fe);
  }
}

// The FE's bindings in its dictionary order (fe_fields), whatever order the file wrote them in.
void sort_fields(FunctionalElementConfig& fe) {
  const auto order = fe_fields(fe.id);
  auto rank = [&](const FieldBinding& b) {
    for (std::size_t i = 0; i < order.size(); ++i)
      if (order[i].name == b.field.name) return i;
    return order.size();
  };
  std::stable_sort(fe.fields.begin(), fe.fields.end(),
                   [&](const FieldBinding& a, const FieldBinding& b) { return rank(a) < rank(b); });
}

}  // namespace

void read_functional_elements(YamlReader& r, const MapEntry& sec, Config& cfg, bool subdevices_read) {
  const auto es = r.entries(sec.value, "functional_elements", {}, "a map of kind.instance -> {field: signal, ...}");
  FieldBinder binder(r, cfg.subdevices, subdevices_read);
  std::map<std::string, Location> seen;  // canonical name: "joystick.01" is "joystick.1"
  for (const auto& e : es) {
    const auto id = read_fe_id(r, e);
    if (!id) continue;
    FunctionalElementConfig fe;
    fe.id = *id;
    fe.where = r.loc(e.key);
    auto [first, fresh] = seen.emplace(fe_name(fe.id), fe.where);
    if (!fresh) {
      r.error(e.key, "functional element '" + e.name + "' appears twice (first at " + first->second.line_column() +
                         "); expected each functional element once");
      continue;
    }
    read_fe_entries(r, e, binder, fe);
    if (!fe.fields.empty()) {
      sort_fields(fe);
      cfg.functional_elements.push_back(std::move(fe));
    }
  }
  std::sort(cfg.functional_elements.begin(), cfg.functional_elements.end(),
            [](const auto& a, const auto& b) { return a.id < b.id; });
}

// A source the FE lists whose transport the publish section leaves off can never deliver a
// command: refused here rather than found out in the cab. When no listed source can, that is
// the one error; otherwise each dead source is, naming the setting that would bring it alive.
void check_command_sources_reachable(YamlReader& r, const Config& cfg) {
  const auto& p = cfg.publish;
  // Why a transport is off: a section written with `enabled: false`, or no section at all.
  const auto off = [](std::string_view name, bool written) {
    return written ? "publish." + std::string(name) + ".enabled is false"
                   : "the file has no publish." + std::string(name) + " section (publish." + std::string(name) +
                         ".enabled is false)";
  };
  for (const auto& fe : cfg.functional_elements) {
    if (fe.input()) continue;
    const bool dds_dead = fe.accepts(CommandSource::Dds) && !p.dds.enabled;
    const bool lcm_dead = fe.accepts(CommandSource::Lcm) && !p.lcm.enabled;
    const bool dds = fe.accepts(CommandSource::Dds) && p.dds.enabled;
    const bool lcm = fe.accepts(CommandSource::Lcm) && p.lcm.enabled;
    if (!fe.accepts(CommandSource::Canopen) && !dds && !lcm) {
      const char* expected = fe.accepts(CommandSource::Dds) && fe.accepts(CommandSource::Lcm)
                                 ? "publish.dds.enabled or publish.lcm.enabled true"
                             : fe.accepts(CommandSource::Dds) ? "publish.dds.enabled true"
                                                              : "publish.lcm.enabled true";
      r.error(fe.sources_where, fe_name(fe.id) + " takes commands only from " + describe_sources(fe.sources) +
                                    ", which the publish section does not enable; expected " + expected +
                                    ", or canopen among the sources");
      continue;
    }
    // Sources not written are the default (canopen, dds), not the file's choice: DDS among them
    // serves when it is enabled, and a file without DDS is not told about it.
    if (fe.sources_where.line == 0) continue;
    for (const auto& [dead, name, transport, written] : {std::tuple{dds_dead, "dds", "DDS", p.dds.where.line != 0},
                                                         std::tuple{lcm_dead, "lcm", "LCM", p.lcm.where.line != 0}})
      if (dead)
        r.error(fe.sources_where, fe_name(fe.id) + " sources list " + name + ", but " + off(name, written) + ": no " +
                                      transport + " command can reach it; expected publish." + name +
                                      ".enabled true, or " + name + " off the sources");
  }
}

}  // namespace oegw::mapping::sections
