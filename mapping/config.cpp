// The mapping file as a whole: the Config types' helpers and load_config(). Reading the YAML
// and its diagnostics are yaml_reader.*, each section's parser is in sections/, the fields'
// binding to signals field_binding.*.
#include "mapping/config.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdio>

#include "canopen/text_file.hpp"
#include "mapping/sections/sections.hpp"
#include "mapping/yaml_reader.hpp"

namespace oegw::mapping {

bool valid_subdevice_name(std::string_view name) {
  return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
  });
}

using canopen::DataType;
using subdevices::SignalInfo;

std::string Location::str() const { return file + ":" + std::to_string(line) + ":" + std::to_string(column); }
std::string Location::line_column() const {
  return "line " + std::to_string(line) + ", column " + std::to_string(column);
}
std::string Diagnostic::str() const { return where.str() + ": " + message; }

std::string LoadResult::error_text() const {
  std::string out;
  for (const auto& e : errors) out += e.str() + "\n";
  return out;
}

const SignalInfo* SubdeviceConfig::find_signal(std::string_view n) const {
  for (const auto& s : signals)
    if (s.name == n) return &s;
  return nullptr;
}

subdevices::NodeSettings SubdeviceConfig::node_settings() const {
  subdevices::NodeSettings n;
  n.name = name;
  n.node = node();
  n.heartbeat_ms = heartbeat_ms;
  n.heartbeat_timeout_ms = heartbeat_timeout_ms;
  n.pdo_timeout_ms = pdo_timeout_ms;
  n.mandatory = mandatory;
  n.identity = identity;
  n.exact_revision = exact_revision;
  for (const auto& w : sdo) n.sdo.push_back(w.to_sdo_write());
  return n;
}

const SubdeviceConfig* Config::find_subdevice(std::string_view n) const {
  for (const auto& s : subdevices)
    if (s.name == n) return &s;
  return nullptr;
}

const FunctionalElementConfig* Config::find_fe(FeId id) const {
  for (const auto& f : functional_elements)
    if (f.id == id) return &f;
  return nullptr;
}

std::string_view to_string(CommandSource s) {
  switch (s) {
    case CommandSource::Canopen: return "canopen";
    case CommandSource::Dds: return "dds";
    case CommandSource::Lcm: return "lcm";
  }
  return "?";
}

std::string describe_sources(CommandSources sources) {
  std::string out;
  for (auto s : {CommandSource::Canopen, CommandSource::Dds, CommandSource::Lcm})
    if ((sources & static_cast<CommandSources>(s)) != 0) out += (out.empty() ? "" : ", ") + std::string(to_string(s));
  return out.empty() ? "none" : out;
}

namespace {

std::size_t type_size(DataType t) {
  switch (t) {
    case DataType::Integer8:
    case DataType::Unsigned8: return 1;
    case DataType::Integer16:
    case DataType::Unsigned16: return 2;
    default: return 4;
  }
}

}  // namespace

subdevices::SdoWrite SdoWriteConfig::to_sdo_write() const {
  subdevices::SdoWrite w;
  w.index = index;
  w.sub = sub_index;
  const auto u = static_cast<std::uint64_t>(value);
  for (std::size_t i = 0; i < type_size(type); ++i) w.data.push_back(static_cast<std::uint8_t>(u >> (8 * i)));
  char buf[64];
  std::snprintf(buf, sizeof buf, "mapping file %04Xh:%02X = %lld", static_cast<unsigned>(index),
                static_cast<unsigned>(sub_index), static_cast<long long>(value));
  w.what = buf;
  return w;
}

namespace {

// The file's top level: every section, each parsed by its own reader (sections/), then the
// checks across sections.
void read_file(YamlReader& r, const YAML::Node& root, const SignalCatalogue& catalogue, Config& cfg) {
  const std::string top = "a map with upstream, downstream, publish, control, record, subdevices, functional_elements";
  if (!root.IsMap()) {
    r.error(root.IsNull() ? Location{r.file(), 1, 1} : r.loc(root),
            "found " + node_kind(root) + " at the top; expected " + top);
    return;
  }
  const std::vector<std::string_view> names = {"upstream",   "downstream",         "publish", "control", "record",
                                               "subdevices", "functional_elements"};
  const auto es = r.entries(root, "the file", names, top);
  // A section written under a misspelt name ("subdevice:", "sub_devices:") is reported at that
  // key, with the name (entries() above); it is not reported missing as well.
  auto missing = [&](std::string_view key, std::string_view expected) {
    for (auto it = root.begin(); it != root.end(); ++it)
      if (it->first.IsScalar() && std::find(names.begin(), names.end(), it->first.Scalar()) == names.end() &&
          near_miss(it->first.Scalar(), names) == std::string(key))
        return;
    r.missing(root, key, "the file", expected);
  };
  if (const auto* e = r.find(es, "upstream")) sections::read_upstream(r, *e, cfg.upstream);
  else missing("upstream", "an upstream section with at least node_id");
  if (const auto* e = r.find(es, "downstream")) sections::read_downstream(r, *e, cfg.downstream);
  else missing("downstream", "a downstream section");
  if (const auto* e = r.find(es, "publish")) sections::read_publish(r, *e, cfg.publish);
  if (const auto* e = r.find(es, "control")) sections::read_control(r, *e, cfg.control);
  if (const auto* e = r.find(es, "record")) sections::read_record(r, *e, cfg.record);
  // Without a readable subdevices section every sub-device an FE names would be "unknown": that
  // one mistake is reported once, where it is, and the names are not checked.
  const auto* subdevices = r.find(es, "subdevices");
  const bool subdevices_read = subdevices != nullptr && subdevices->value.IsMap();
  if (subdevices) sections::read_subdevices(r, *subdevices, catalogue, cfg.subdevices);
  else missing("subdevices", "a subdevices section");
  if (const auto* e = r.find(es, "functional_elements"))
    sections::read_functional_elements(r, *e, cfg, subdevices_read);
  else missing("functional_elements", "a functional_elements section");
  sections::check_command_sources_reachable(r, cfg);
  sections::check_sdo_servers(r, cfg, subdevices_read);
  sections::check_sync(r, cfg);
  // CiA 302-7: a network ID names one network; the two buses need two.
  if (cfg.upstream.network_id == cfg.downstream.network_id) {
    const bool down_written = cfg.downstream.network_id_where.line != 0;
    const Location at = down_written                              ? cfg.downstream.network_id_where
                        : cfg.upstream.network_id_where.line != 0 ? cfg.upstream.network_id_where
                                                                  : cfg.downstream.where;
    r.error(at, std::string(down_written ? "downstream" : "upstream") + " network_id " +
                    std::to_string(cfg.upstream.network_id) +
                    " names both buses; expected two distinct network IDs 1..127 (defaults: upstream 1, downstream 2)");
  }
}

}  // namespace

LoadResult load_config_text(std::string_view text, std::string_view file, const SignalCatalogue& catalogue,
                            std::optional<std::filesystem::path> base) {
  LoadResult result;
  auto parsed = parse_yaml(text, std::string(file));
  if (parsed.error) {
    result.errors.push_back(std::move(*parsed.error));
    return result;
  }
  YamlReader r{std::string(file), std::move(base)};
  Config cfg;
  cfg.file = std::string(file);
  try {
    read_file(r, parsed.root, catalogue, cfg);
  } catch (const YAML::Exception& e) {  // not expected: every access is type-checked first
    r.error(Location{r.file(), e.mark.is_null() ? 1 : e.mark.line + 1, e.mark.is_null() ? 1 : e.mark.column + 1},
            "unreadable YAML: " + e.msg + "; expected the layout docs/reference/mapping-file.md describes");
  }
  if (r.has_errors()) result.errors = r.take_errors();
  else result.config = std::move(cfg);
  return result;
}

LoadResult load_config(const std::string& path, const SignalCatalogue& catalogue) {
  const auto file = canopen::read_text_file(path, YamlLimits::kFileBytes);
  if (!file.text) {
    LoadResult r;
    r.errors.push_back({{path, 1, 1}, file.error});
    return r;
  }
  return load_config_text(*file.text, path, catalogue, std::filesystem::path(path).parent_path());
}

}  // namespace oegw::mapping
