#include "mapping/config.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

namespace oegw::mapping {

using canopen::DataType;
using subdevices::SignalInfo;
using subdevices::SignalKind;

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
    case CommandSource::Canopen:
      return "canopen";
    case CommandSource::Dds:
      return "dds";
    case CommandSource::Lcm:
      return "lcm";
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
    case DataType::Unsigned8:
      return 1;
    case DataType::Integer16:
    case DataType::Unsigned16:
      return 2;
    default:
      return 4;
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

constexpr std::array<std::string_view, 4> kFamilies = {"elobau-mfg", "mcb402", "novotechnik-406", "cia401"};

std::string hex(std::int64_t v, int width = 0) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "0x%0*llX", width, static_cast<unsigned long long>(v));
  return buf;
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

// " — did you mean 'x'?" for a near miss among `candidates`, else "".
template <typename Range>
std::string did_you_mean(std::string_view found, const Range& candidates) {
  std::size_t best = std::numeric_limits<std::size_t>::max();
  std::string best_name;
  for (const auto& c : candidates) {
    const std::string_view cv(c);
    const auto d = edit_distance(found, cv);
    if (d < best) {
      best = d;
      best_name = std::string(cv);
    }
  }
  if (best_name.empty() || best == 0) return "";
  if ((best <= 2 && best < found.size()) || best * 3 <= found.size()) return " (did you mean '" + best_name + "'?)";
  return "";
}

template <typename Range>
std::string join(const Range& names, std::string_view sep = ", ") {
  std::string out;
  for (const auto& n : names) {
    if (!out.empty()) out += sep;
    out += std::string_view(n);
  }
  return out;
}

// "buttons[1]", "buttons[2]", ... -> "buttons[1..16]"; other names unchanged.
std::string compress_names(const std::vector<std::string>& names) {
  std::vector<std::string> out;
  std::size_t i = 0;
  while (i < names.size()) {
    const auto& n = names[i];
    const auto lb = n.find('[');
    if (lb == std::string::npos || n.back() != ']') {
      out.push_back(n);
      ++i;
      continue;
    }
    const std::string base = n.substr(0, lb);
    const long first = std::strtol(n.c_str() + lb + 1, nullptr, 10);
    long last = first;
    std::size_t j = i + 1;
    while (j < names.size() && names[j] == base + "[" + std::to_string(last + 1) + "]") {
      ++last;
      ++j;
    }
    out.push_back(first == last ? n : base + "[" + std::to_string(first) + ".." + std::to_string(last) + "]");
    i = j;
  }
  return join(out);
}

std::string node_kind(const YAML::Node& n) {
  switch (n.Type()) {
    case YAML::NodeType::Map:
      return "a map";
    case YAML::NodeType::Sequence: {
      std::string out = "[";
      for (const auto& item : n) {
        if (!item.IsScalar()) return "a list";
        out += (out.size() > 1 ? ", " : "") + item.Scalar();
      }
      return out + "]";
    }
    case YAML::NodeType::Scalar:
      return "'" + n.Scalar() + "'";
    default:
      return "nothing";
  }
}

std::optional<std::int64_t> parse_integer(std::string_view s) {
  if (s.empty()) return std::nullopt;
  bool neg = false;
  if (s.front() == '-' || s.front() == '+') {
    neg = s.front() == '-';
    s.remove_prefix(1);
  }
  int base = 10;
  if (s.size() > 2 && s[0] == '0' && (s[1] == 'x' || s[1] == 'X')) {
    base = 16;
    s.remove_prefix(2);
  }
  if (s.empty()) return std::nullopt;
  std::uint64_t v = 0;
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v, base);
  if (ec != std::errc() || p != s.data() + s.size()) return std::nullopt;
  if (v > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) return std::nullopt;
  const auto sv = static_cast<std::int64_t>(v);
  return neg ? -sv : sv;
}

struct Entry {
  std::string name;
  YAML::Node key;
  YAML::Node value;
};

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

constexpr std::array<std::uint32_t, 9> kBitrates = {10000, 20000, 50000, 125000, 250000, 500000, 800000, 1000000};

// A COB-ID in use on the downstream bus.
struct CobUse {
  std::uint32_t cob = 0;
  std::string owner;  // "right_grip TPDO1"
  bool explicit_ = false;
  Location where;
};

struct FieldRef {  // a parsed "base", "base[i]" or "base[a..b]"
  std::string base;
  bool indexed = false;
  long first = 0, last = 0;
  [[nodiscard]] long count() const { return indexed ? last - first + 1 : 1; }
  [[nodiscard]] std::string element(long i) const {
    return indexed ? base + "[" + std::to_string(first + i) + "]" : base;
  }
  [[nodiscard]] bool range() const { return indexed && last != first; }
};

std::optional<FieldRef> parse_ref(std::string_view s) {
  FieldRef r;
  const auto lb = s.find('[');
  if (lb == std::string_view::npos) {
    if (s.empty() || s.find(']') != std::string_view::npos) return std::nullopt;
    r.base = std::string(s);
    return r;
  }
  if (s.back() != ']' || lb == 0) return std::nullopt;
  r.base = std::string(s.substr(0, lb));
  const auto inner = s.substr(lb + 1, s.size() - lb - 2);
  const auto dots = inner.find("..");
  auto num = [](std::string_view t) -> std::optional<long> {
    long v = 0;
    auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || p != t.data() + t.size() || v < 1) return std::nullopt;
    return v;
  };
  const auto a = num(dots == std::string_view::npos ? inner : inner.substr(0, dots));
  const auto b = dots == std::string_view::npos ? a : num(inner.substr(dots + 2));
  if (!a || !b || *b < *a) return std::nullopt;
  r.indexed = true;
  r.first = *a;
  r.last = *b;
  return r;
}

class Loader {
 public:
  Loader(std::string file, const SignalCatalogue& catalogue) : file_(std::move(file)), catalogue_(catalogue) {}

  LoadResult run(std::string_view text) {
    LoadResult result;
    YAML::Node root;
    try {
      root = YAML::Load(std::string(text));
    } catch (const YAML::Exception& e) {
      Location l{file_, e.mark.line + 1, e.mark.column + 1};
      if (e.mark.is_null()) l.line = l.column = 1;
      // Plain scalars cannot hold [ ] inside a { } flow map: the commonest slip in this format.
      std::string hint;
      std::size_t start = 0;
      for (int i = 1; i < l.line && start != std::string_view::npos; ++i) {
        start = text.find('\n', start);
        if (start != std::string_view::npos) ++start;
      }
      if (start != std::string_view::npos) {
        const auto line = text.substr(start, text.find('\n', start) - start);
        if (line.find('{') != std::string_view::npos && line.find('[') != std::string_view::npos)
          hint = " (inside { }, quote names with [ ], e.g. \"buttons[1..8]\", or use block style)";
      }
      result.errors.push_back({l, "YAML syntax error: " + e.msg + "; expected well-formed YAML" + hint});
      return result;
    }
    cfg_.file = file_;
    try {
      check(root);
    } catch (const YAML::Exception& e) {  // not expected: every access is type-checked first
      error(Location{file_, e.mark.is_null() ? 1 : e.mark.line + 1, e.mark.is_null() ? 1 : e.mark.column + 1},
            "unreadable YAML: " + e.msg + "; expected the layout mapping/README.md describes");
    }
    std::stable_sort(errors_.begin(), errors_.end(), [](const Diagnostic& a, const Diagnostic& b) {
      return std::pair(a.where.line, a.where.column) < std::pair(b.where.line, b.where.column);
    });
    if (errors_.empty()) {
      result.config = std::move(cfg_);
    } else {
      result.errors = std::move(errors_);
    }
    return result;
  }

 private:
  Location loc(const YAML::Node& n) const {
    const auto m = n.Mark();
    if (m.is_null()) return {file_, 1, 1};
    return {file_, m.line + 1, m.column + 1};
  }
  void error(const Location& l, std::string msg) { errors_.push_back({l, std::move(msg)}); }
  void error(const YAML::Node& n, std::string msg) { error(loc(n), std::move(msg)); }

  // The entries of a map; unknown keys (when `allowed` is not empty) and duplicates reported.
  std::vector<Entry> entries(const YAML::Node& map, std::string_view what, const std::vector<std::string_view>& allowed,
                             const std::string& expected_map) {
    std::vector<Entry> out;
    if (!map.IsMap()) {
      error(map, "found " + node_kind(map) + " for " + std::string(what) + "; expected " + expected_map);
      return out;
    }
    std::set<std::string> seen;
    for (auto it = map.begin(); it != map.end(); ++it) {
      const YAML::Node key = it->first;
      if (!key.IsScalar()) {
        error(key, "found " + node_kind(key) + " as a key in " + std::string(what) + "; expected a name");
        continue;
      }
      const std::string name = key.Scalar();
      if (!seen.insert(name).second) {
        error(key, "duplicate key '" + name + "' in " + std::string(what) + "; expected each key once");
        continue;
      }
      if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), name) == allowed.end()) {
        error(key, "unknown key '" + name + "' in " + std::string(what) + "; expected one of " + join(allowed) +
                       did_you_mean(name, allowed));
        continue;
      }
      out.push_back({name, key, it->second});
    }
    return out;
  }

  static const Entry* find(const std::vector<Entry>& es, std::string_view name) {
    for (const auto& e : es)
      if (e.name == name) return &e;
    return nullptr;
  }

  void missing(const YAML::Node& map, std::string_view key, std::string_view what, std::string_view expected) {
    error(map, "no '" + std::string(key) + "' in " + std::string(what) + "; expected " + std::string(expected));
  }

  std::optional<std::int64_t> integer(const Entry& e, std::string_view what, std::int64_t lo, std::int64_t hi,
                                      bool show_hex = false) {
    const auto range = show_hex ? hex(lo) + ".." + hex(hi) : std::to_string(lo) + ".." + std::to_string(hi);
    if (!e.value.IsScalar()) {
      error(e.value, "found " + node_kind(e.value) + " for " + std::string(what) + "; expected an integer " + range);
      return std::nullopt;
    }
    const auto v = parse_integer(e.value.Scalar());
    if (!v) {
      error(e.value, std::string(what) + " '" + e.value.Scalar() + "' is not a number; expected an integer " + range +
                         " (decimal or 0x hex)");
      return std::nullopt;
    }
    if (*v < lo || *v > hi) {
      error(e.value, std::string(what) + " " + e.value.Scalar() + " is out of range; expected " + range);
      return std::nullopt;
    }
    return v;
  }

  std::optional<std::string> string(const Entry& e, std::string_view what) {
    if (!e.value.IsScalar() || e.value.Scalar().empty()) {
      error(e.value, "found " + node_kind(e.value) + " for " + std::string(what) + "; expected a text");
      return std::nullopt;
    }
    return e.value.Scalar();
  }

  std::optional<bool> boolean(const Entry& e, std::string_view what) {
    if (e.value.IsScalar()) {
      const auto& s = e.value.Scalar();
      if (s == "true" || s == "yes" || s == "on") return true;
      if (s == "false" || s == "no" || s == "off") return false;
    }
    error(e.value, "found " + node_kind(e.value) + " for " + std::string(what) + "; expected true or false");
    return std::nullopt;
  }

  std::optional<double> real(const Entry& e, std::string_view what) {
    if (e.value.IsScalar()) {
      const auto& s = e.value.Scalar();
      char* end = nullptr;
      const double d = std::strtod(s.c_str(), &end);
      if (!s.empty() && end == s.c_str() + s.size() && std::isfinite(d) && d != 0.0) return d;
    }
    error(e.value, "found " + node_kind(e.value) + " for " + std::string(what) + "; expected a non-zero number");
    return std::nullopt;
  }

  template <typename T>
  void set_int(const std::vector<Entry>& es, std::string_view key, std::string_view what, std::int64_t lo,
               std::int64_t hi, T& out, bool show_hex = false) {
    if (const auto* e = find(es, key))
      if (auto v = integer(*e, what, lo, hi, show_hex)) out = static_cast<T>(*v);
  }

  void bitrate(const std::vector<Entry>& es, std::string_view what, std::uint32_t& out) {
    const auto* e = find(es, "bitrate");
    if (!e) return;
    const auto v = integer(*e, what, 10000, 1000000);
    if (!v) return;
    if (std::find(kBitrates.begin(), kBitrates.end(), static_cast<std::uint32_t>(*v)) == kBitrates.end()) {
      error(e->value, std::string(what) + " " + e->value.Scalar() +
                          " is not a CiA 301 bit rate; expected one of 10000, 20000, 50000, 125000, 250000, 500000, "
                          "800000, 1000000");
      return;
    }
    out = static_cast<std::uint32_t>(*v);
  }

  // ---------------------------------------------------------------------------------------------
  void check(const YAML::Node& root) {
    const std::string top = "a map with upstream, downstream, publish, subdevices, functional_elements";
    if (!root.IsMap()) {
      error(root.IsNull() ? Location{file_, 1, 1} : loc(root),
            "found " + node_kind(root) + " at the top; expected " + top);
      return;
    }
    const auto es =
        entries(root, "the file", {"upstream", "downstream", "publish", "subdevices", "functional_elements"}, top);
    if (const auto* e = find(es, "upstream"))
      upstream(*e);
    else
      missing(root, "upstream", "the file", "an upstream section with at least node_id");
    if (const auto* e = find(es, "downstream"))
      downstream(*e);
    else
      missing(root, "downstream", "the file", "a downstream section");
    if (const auto* e = find(es, "publish")) publish(*e);
    if (const auto* e = find(es, "subdevices"))
      subdevices(*e);
    else
      missing(root, "subdevices", "the file", "a subdevices section");
    if (const auto* e = find(es, "functional_elements"))
      functional_elements(*e);
    else
      missing(root, "functional_elements", "the file", "a functional_elements section");
    command_sources_reachable();
  }

  // An output FE whose only sources are transports the publish section leaves off could never
  // be commanded: refused here rather than found out in the cab.
  void command_sources_reachable() {
    const auto& p = cfg_.publish;
    for (const auto& fe : cfg_.functional_elements) {
      if (fe.input() || fe.sources == kAllCommandSources || fe.accepts(CommandSource::Canopen)) continue;
      const bool dds = fe.accepts(CommandSource::Dds) && p.dds.enabled;
      const bool lcm = fe.accepts(CommandSource::Lcm) && p.lcm.enabled;
      if (dds || lcm) continue;
      error(fe.sources_where, fe_name(fe.id) +
                                  " takes commands only from " + describe_sources(fe.sources) +
                                  ", which the publish section does not enable; expected " +
                                  (fe.accepts(CommandSource::Dds) && fe.accepts(CommandSource::Lcm)
                                       ? "publish.dds or publish.lcm"
                                       : fe.accepts(CommandSource::Dds) ? "publish.dds" : "publish.lcm") +
                                  " enabled, or canopen among the sources");
    }
  }

  // `sources: [canopen, dds, lcm]` or one name: who may command an output FE (config.hpp).
  void command_sources(const Entry& e, FunctionalElementConfig& fe, const std::string& fe_name) {
    static const std::vector<std::string_view> names = {"canopen", "dds", "lcm"};
    const std::string expected = "a list of canopen, dds, lcm, e.g. sources: [canopen, dds]";
    if (fe.input()) {
      error(e.key, fe_name + " is an input; 'sources' applies to indicators and display (commands in)");
      return;
    }
    std::vector<YAML::Node> items;
    if (e.value.IsScalar() && !e.value.Scalar().empty()) {
      items.push_back(e.value);
    } else if (e.value.IsSequence() && e.value.size() > 0) {
      for (const auto& n : e.value) items.push_back(n);
    } else {
      error(e.value, "found " + node_kind(e.value) + " for " + fe_name + " sources; expected " + expected);
      return;
    }
    CommandSources set = 0;
    bool ok = true;
    for (const auto& n : items) {
      const std::string name = n.IsScalar() ? n.Scalar() : std::string();
      const auto it = std::find(names.begin(), names.end(), name);
      if (it == names.end()) {
        error(n, "found " + (n.IsScalar() ? "'" + name + "'" : node_kind(n)) + " in " + fe_name +
                     " sources; expected one of canopen, dds, lcm" + did_you_mean(name, names));
        ok = false;
        continue;
      }
      const auto bit = static_cast<CommandSources>(1u << (it - names.begin()));
      if ((set & bit) != 0) {
        error(n, "'" + name + "' appears twice in " + fe_name + " sources; expected each source once");
        ok = false;
      }
      set = static_cast<CommandSources>(set | bit);
    }
    if (!ok) return;
    fe.sources = set;
    fe.sources_where = loc(e.value);
  }

  void upstream(const Entry& sec) {
    auto& u = cfg_.upstream;
    u.where = loc(sec.key);
    const auto es =
        entries(sec.value, "upstream", {"interface", "node_id", "bitrate", "identity", "heartbeat_ms", "store"},
                "a map with interface, node_id, bitrate, identity, heartbeat_ms, store");
    if (!sec.value.IsMap()) return;
    if (const auto* e = find(es, "interface"))
      if (auto s = string(*e, "interface")) u.interface = *s;
    if (find(es, "node_id"))
      set_int(es, "node_id", "node_id", 1, 127, u.node_id);
    else
      missing(sec.value, "node_id", "upstream", "the gateway's node-ID 1..127");
    bitrate(es, "bitrate", u.bitrate);
    set_int(es, "heartbeat_ms", "heartbeat_ms", 0, 65535, u.heartbeat_ms);
    if (const auto* e = find(es, "store"))
      if (auto s = string(*e, "store")) u.store = *s;
    if (const auto* e = find(es, "identity")) {
      const auto ids = entries(e->value, "upstream identity", {"vendor_id", "product_code", "revision", "serial"},
                               "a map with vendor_id, product_code, revision, serial");
      set_int(ids, "vendor_id", "vendor_id", 0, 0xFFFFFFFF, u.identity.vendor_id, true);
      set_int(ids, "product_code", "product_code", 0, 0xFFFFFFFF, u.identity.product_code, true);
      set_int(ids, "revision", "revision", 0, 0xFFFFFFFF, u.identity.revision, true);
      set_int(ids, "serial", "serial", 0, 0xFFFFFFFF, u.identity.serial, true);
    }
  }

  void downstream(const Entry& sec) {
    auto& d = cfg_.downstream;
    d.where = loc(sec.key);
    const auto es = entries(sec.value, "downstream", {"interface", "bitrate"}, "a map with interface, bitrate");
    if (const auto* e = find(es, "interface"))
      if (auto s = string(*e, "interface")) d.interface = *s;
    bitrate(es, "bitrate", d.bitrate);
  }

  void publish(const Entry& sec) {
    const auto es = entries(sec.value, "publish", {"period_ms", "dds", "lcm"}, "a map with period_ms, dds, lcm");
    set_int(es, "period_ms", "period_ms", 1, 60000, cfg_.publish.period_ms);
    if (const auto* e = find(es, "dds")) {
      auto& d = cfg_.publish.dds;
      d.enabled = true;
      const auto ds =
          entries(e->value, "publish dds", {"enabled", "domain", "partition", "network"},
                  "a map with enabled, domain, partition, network");
      if (const auto* x = find(ds, "enabled"))
        if (auto b = boolean(*x, "enabled")) d.enabled = *b;
      set_int(ds, "domain", "domain", 0, 232, d.domain);
      if (const auto* x = find(ds, "partition"))
        if (auto s = string(*x, "partition")) d.partition = *s;
      if (const auto* x = find(ds, "network"))
        if (auto s = string(*x, "network")) d.network = *s;
    }
    if (const auto* e = find(es, "lcm")) {
      auto& l = cfg_.publish.lcm;
      l.enabled = true;
      const auto ls = entries(e->value, "publish lcm", {"enabled", "url", "channel_prefix"},
                              "a map with enabled, url, channel_prefix");
      if (const auto* x = find(ls, "enabled"))
        if (auto b = boolean(*x, "enabled")) l.enabled = *b;
      if (const auto* x = find(ls, "url"))
        if (auto s = string(*x, "url")) {
          l.url = *s;
          link_local_lcm_group(*x);
        }
      if (const auto* x = find(ls, "channel_prefix"))
        if (auto s = string(*x, "channel_prefix")) l.channel_prefix = *s;
    }
  }

  // ---------------------------------------------------------------------------------------------
  void subdevices(const Entry& sec) {
    const auto es = entries(sec.value, "subdevices", {}, "a map of sub-device name -> {driver, node_id, ...}");
    std::map<int, std::pair<std::string, Location>> by_node;
    std::vector<CobUse> cobs;
    for (const auto& e : es) {
      SubdeviceConfig s;
      s.name = e.name;
      s.where = loc(e.key);
      const bool good_name = !e.name.empty() && std::all_of(e.name.begin(), e.name.end(), [](char c) {
        return std::islower(static_cast<unsigned char>(c)) || std::isdigit(static_cast<unsigned char>(c)) || c == '_';
      });
      if (!good_name)
        error(e.key, "sub-device name '" + e.name +
                         "' has characters other than a-z, 0-9 and _; expected a name like right_grip");
      const auto what = "sub-device '" + e.name + "'";
      const auto ks = entries(
          e.value, what,
          {"driver", "node_id", "heartbeat_ms", "heartbeat_timeout_ms", "pdo_timeout_ms", "mandatory", "identity", "sdo",
           "options"},
          "a map with driver, node_id, heartbeat_ms, heartbeat_timeout_ms, pdo_timeout_ms, mandatory, identity, sdo, "
          "options");
      if (!e.value.IsMap()) {
        cfg_.subdevices.push_back(std::move(s));
        continue;
      }
      const auto* drv = find(ks, "driver");
      if (drv) {
        if (auto d = string(*drv, "driver")) s.driver = *d;
      } else {
        missing(e.value, "driver", what, "one of " + join(kFamilies));
      }
      if (find(ks, "node_id")) {
        set_int(ks, "node_id", "node_id", 1, 127, s.node_id, false);
      } else {
        missing(e.value, "node_id", what, "its node-ID 1..127");
      }
      set_int(ks, "heartbeat_ms", "heartbeat_ms", 0, 65535, s.heartbeat_ms);
      set_int(ks, "heartbeat_timeout_ms", "heartbeat_timeout_ms", 0, 65535, s.heartbeat_timeout_ms);
      if (const auto* t = find(ks, "heartbeat_timeout_ms");
          t && s.heartbeat_timeout_ms != 0 && s.heartbeat_ms != 0 && s.heartbeat_timeout_ms <= s.heartbeat_ms)
        error(t->value, "heartbeat_timeout_ms " + t->value.Scalar() + " is not longer than heartbeat_ms " +
                            std::to_string(s.heartbeat_ms) + "; expected more than " + std::to_string(s.heartbeat_ms) +
                            " (or 0 for 1.5 x heartbeat_ms)");
      set_int(ks, "pdo_timeout_ms", "pdo_timeout_ms", 0, 65535, s.pdo_timeout_ms);
      // Proof of life (DESIGN.md): without a heartbeat only fresh PDOs show the node is there.
      if (const auto* h = find(ks, "heartbeat_ms"); h && s.heartbeat_ms == 0 && s.pdo_timeout_ms == 0)
        error(h->value, "heartbeat_ms 0 leaves " + what +
                            " without proof of life; expected a heartbeat (heartbeat_ms > 0) or pdo_timeout_ms > 0");
      if (const auto* m = find(ks, "mandatory"))
        if (auto b = boolean(*m, "mandatory")) s.mandatory = *b;
      if (const auto* id = find(ks, "identity")) {
        const auto ids =
            entries(id->value, what + " identity", {"device_type", "vendor_id", "product_code", "revision", "serial"},
                    "a map with device_type, vendor_id, product_code, revision, serial");
        auto opt = [&](std::string_view k, std::optional<std::uint32_t>& out) {
          if (const auto* x = find(ids, k))
            if (auto v = integer(*x, k, 0, 0xFFFFFFFF, true)) out = static_cast<std::uint32_t>(*v);
        };
        opt("device_type", s.identity.device_type);
        opt("vendor_id", s.identity.vendor_id);
        opt("product_code", s.identity.product_code);
        opt("revision", s.identity.revision);
        opt("serial", s.identity.serial);
      }
      if (const auto* o = find(ks, "options")) {
        for (const auto& x : entries(o->value, what + " options", {}, "a map of the driver's options")) {
          if (!x.value.IsScalar()) {
            error(x.value, "found " + node_kind(x.value) + " for option '" + x.name + "'; expected a single value");
            continue;
          }
          s.options.values.emplace_back(x.name, x.value.Scalar());
        }
      }
      if (const auto* l = find(ks, "sdo")) sdo_list(*l, s);
      // Node-ID uniqueness.
      if (s.node_id != 0) {
        const auto* nid = find(ks, "node_id");
        auto [it, fresh] = by_node.emplace(s.node_id, std::pair(s.name, loc(nid->value)));
        if (!fresh)
          error(nid->value, "node_id " + nid->value.Scalar() + " of '" + s.name + "' is already used by sub-device '" +
                                it->second.first + "' (" + it->second.second.line_column() +
                                "), so all their default COB-IDs clash; expected a node-ID of its own");
      }
      // Signals from the catalogue.
      if (drv && !s.driver.empty()) {
        std::string err;
        if (!catalogue_) err = "no signal catalogue";
        auto sig = catalogue_ ? catalogue_(s.driver, s.options, err) : std::nullopt;
        if (sig) {
          s.signals = std::move(*sig);
        } else if (std::find(kFamilies.begin(), kFamilies.end(), s.driver) == kFamilies.end()) {
          error(drv->value, "unknown driver '" + s.driver + "'" + (err.empty() ? "" : " (" + err + ")") +
                                "; expected one of " + join(kFamilies) + did_you_mean(s.driver, kFamilies));
        } else {
          const auto* o = find(ks, "options");
          error(o ? o->key : drv->value, "driver " + s.driver + " refused " + what + ": " + err +
                                             "; expected options the " + s.driver + " driver accepts");
        }
      }
      if (s.node_id != 0) default_cobs(s, cobs);
      cfg_.subdevices.push_back(std::move(s));
    }
    cob_clashes(cobs);
  }

  void sdo_list(const Entry& l, SubdeviceConfig& s) {
    if (!l.value.IsSequence()) {
      error(l.value, "found " + node_kind(l.value) + " for sdo; expected a list of {index, sub_index, value, type}");
      return;
    }
    for (const auto& item : l.value) {
      SdoWriteConfig w;
      w.where = loc(item);
      const auto ks = entries(item, "an sdo write", {"index", "sub_index", "value", "type"},
                              "a map with index, sub_index, value, type");
      if (!item.IsMap()) continue;
      bool good = true;
      auto need = [&](std::string_view k, std::string_view expected) -> const Entry* {
        const auto* e = find(ks, k);
        if (!e) {
          missing(item, k, "an sdo write", expected);
          good = false;
        }
        return e;
      };
      const auto* ie = need("index", "an object index 0x1000..0xFFFF");
      const auto* se = need("sub_index", "a sub-index 0..255");
      const auto* ve = need("value", "the value to write");
      const auto* te = need("type", "one of u8, u16, u32, i8, i16, i32");
      if (ie) {
        if (auto v = integer(*ie, "index", 0x1000, 0xFFFF, true))
          w.index = static_cast<std::uint16_t>(*v);
        else
          good = false;
      }
      if (se) {
        if (auto v = integer(*se, "sub_index", 0, 255, true))
          w.sub_index = static_cast<std::uint8_t>(*v);
        else
          good = false;
      }
      const DataTypeName* type = nullptr;
      if (te) {
        const std::string t = te->value.IsScalar() ? te->value.Scalar() : "";
        for (const auto& d : kSdoTypes)
          if (d.name == t) type = &d;
        if (!type) {
          std::vector<std::string_view> names;
          for (const auto& d : kSdoTypes) names.push_back(d.name);
          error(te->value,
                "found " + node_kind(te->value) + " for type; expected one of " + join(names) + did_you_mean(t, names));
          good = false;
        } else {
          w.type = type->type;
        }
      }
      if (ve && type) {
        if (auto v = integer(*ve, std::string("value of type ") + std::string(type->name), type->min, type->max,
                             type->min == 0))
          w.value = *v;
        else
          good = false;
      }
      if (good) s.sdo.push_back(w);
    }
  }

  // The CiA 301 predefined connection set of `s`, minus what its sdo list re-assigns, plus that.
  void default_cobs(const SubdeviceConfig& s, std::vector<CobUse>& cobs) {
    const std::uint32_t n = s.node_id;
    std::map<std::pair<int, int>, const SdoWriteConfig*> explicit_cobs;  // (index, sub)
    for (const auto& w : s.sdo) {
      const bool pdo = (w.index >= 0x1400 && w.index <= 0x15FF) || (w.index >= 0x1800 && w.index <= 0x19FF);
      if ((pdo && w.sub_index == 1) || (w.index == 0x1014 && w.sub_index == 0))
        explicit_cobs[{w.index, w.sub_index}] = &w;
    }
    auto add_default = [&](std::uint32_t cob, std::string what, int index, int sub) {
      if (explicit_cobs.count({index, sub})) return;
      cobs.push_back({cob, s.name + " " + what + " (default)", false, s.where});
    };
    add_default(0x80 + n, "EMCY", 0x1014, 0);
    for (std::uint32_t k = 0; k < 4; ++k) {
      add_default(0x180 + 0x100 * k + n, "TPDO" + std::to_string(k + 1), 0x1800 + static_cast<int>(k), 1);
      add_default(0x200 + 0x100 * k + n, "RPDO" + std::to_string(k + 1), 0x1400 + static_cast<int>(k), 1);
    }
    cobs.push_back({0x580 + n, s.name + " SDO server->client (default)", false, s.where});
    cobs.push_back({0x600 + n, s.name + " SDO client->server (default)", false, s.where});
    cobs.push_back({0x700 + n, s.name + " heartbeat (default)", false, s.where});
    for (const auto& [key, w] : explicit_cobs) {
      const auto v = static_cast<std::uint32_t>(w->value);
      if (v & 0x80000000u) continue;  // not valid: the PDO/EMCY is off
      const std::uint32_t cob = v & 0x1FFFFFFFu;
      char what[64];
      std::snprintf(what, sizeof what, "%s %04Xh:%02X",
                    key.first == 0x1014  ? "EMCY"
                    : key.first < 0x1800 ? "RPDO"
                                         : "TPDO",
                    static_cast<unsigned>(key.first), static_cast<unsigned>(key.second));
      const bool extended = (v & 0x20000000u) != 0;
      const bool restricted =
          !extended && (cob <= 0x7F || (cob >= 0x101 && cob <= 0x180) || (cob >= 0x581 && cob <= 0x5FF) ||
                        (cob >= 0x601 && cob <= 0x67F) || (cob >= 0x6E0 && cob <= 0x6FF) || cob >= 0x701 ||
                        cob == 0x80 || cob == 0x100);
      if (restricted) {
        error(w->where,
              "COB-ID " + hex(cob, 3) + " of " + s.name + " " + what +
                  " is reserved by CiA 301 (NMT, SYNC, TIME, SDO, heartbeat or LSS); expected a PDO/EMCY COB-ID");
        continue;
      }
      cobs.push_back({cob | (extended ? 0x20000000u : 0u), s.name + " " + what, true, w->where});
    }
  }

  void cob_clashes(const std::vector<CobUse>& cobs) {
    for (std::size_t i = 0; i < cobs.size(); ++i) {
      if (!cobs[i].explicit_) continue;
      for (std::size_t j = 0; j < cobs.size(); ++j) {
        if (i == j || cobs[i].cob != cobs[j].cob) continue;
        if (cobs[j].explicit_ && j > i) continue;  // report a pair of explicit ones once, at the later
        error(cobs[i].where, "COB-ID " + hex(cobs[i].cob, 3) + " of " + cobs[i].owner + " clashes with " +
                                 cobs[j].owner + "; expected a COB-ID no other node uses");
        break;
      }
    }
  }

  // The groups 224.0.0.0/24 reach every host of the link: the gateway's host-local default
  // udpm://224.0.0.1:7667?ttl=0 uses 224.0.0.1 because the kernel never sends an IGMP report for
  // it (so nothing at all leaves the host), but with a ttl above 0 every device on the cab
  // network would receive each sample. A network deployment uses an administratively scoped
  // group (239.x.x.x) instead.
  void link_local_lcm_group(const Entry& e) {
    const std::string url = e.value.Scalar();
    const std::string scheme = "udpm://";
    if (url.rfind(scheme, 0) != 0) return;
    const auto q = url.find('?');
    const std::string host_port = url.substr(scheme.size(), q == std::string::npos ? std::string::npos : q - scheme.size());
    const std::string host = host_port.substr(0, host_port.find(':'));
    // The address as liblcm reads it (inet_aton: "224.0.1" and hex forms are addresses too).
    in_addr a{};
    if (::inet_aton(host.c_str(), &a) == 0 || (ntohl(a.s_addr) & 0xFFFFFF00u) != 0xE0000000u) return;
    // Every ttl option (the last one counts for liblcm) must read exactly "0"; absent means 0.
    std::string ttl = "0";
    if (q != std::string::npos) {
      std::stringstream opts(url.substr(q + 1));
      for (std::string kv; std::getline(opts, kv, '&');)
        if (kv.rfind("ttl=", 0) == 0) ttl = kv.substr(4);
    }
    if (ttl == "0") return;
    error(e.value, "publish lcm url '" + url + "' sends to the link-local group " + ::inet_ntoa(a) + " with ttl '" +
                       ttl + "', so every host on the network would receive it; expected ttl=0 (this host only) or "
                       "a 239.x.x.x group for a network, e.g. udpm://239.255.76.67:7667?ttl=1");
  }

  // ---------------------------------------------------------------------------------------------
  void functional_elements(const Entry& sec) {
    const auto es = entries(sec.value, "functional_elements", {}, "a map of kind.instance -> {field: signal, ...}");
    std::vector<std::string_view> kinds;
    for (auto k : {FeKind::Joystick, FeKind::FootPedal, FeKind::Encoder, FeKind::Wheel, FeKind::ButtonCluster,
                   FeKind::IndicatorCluster, FeKind::Display})
      kinds.push_back(to_string(k));
    std::map<std::pair<std::string, std::string>, Location> outputs_fed;  // (subdevice, signal)
    for (const auto& e : es) {
      const auto dot = e.name.find('.');
      const std::string kind_name = e.name.substr(0, dot);
      const auto kind = fe_kind_from_string(kind_name);
      if (!kind) {
        error(e.key, "unknown functional element kind '" + kind_name + "' in '" + e.name + "'; expected one of " +
                         join(kinds) + did_you_mean(kind_name, kinds));
        continue;
      }
      const auto range = "1.." + std::to_string(max_instances(*kind));
      const auto inst =
          dot == std::string::npos ? std::nullopt : parse_integer(std::string_view(e.name).substr(dot + 1));
      if (!inst || e.name.substr(dot + 1).find_first_not_of("0123456789") != std::string::npos) {
        error(e.key, "functional element '" + e.name + "' has no instance number; expected " + kind_name +
                         ".N with N " + range);
        continue;
      }
      if (*inst < 1 || *inst > max_instances(*kind)) {
        error(e.key, "instance " + std::to_string(*inst) + " of '" + e.name + "' is out of range; expected " +
                         kind_name + "." + range + " (CiA 852 clause 9)");
        continue;
      }
      FunctionalElementConfig fe;
      fe.id = FeId{*kind, static_cast<std::uint8_t>(*inst)};
      fe.where = loc(e.key);
      const auto canonical = kind_name + "." + std::to_string(*inst);
      auto [seen, fresh] = fe_seen_.emplace(canonical, fe.where);
      if (!fresh) {
        error(e.key, "functional element '" + e.name + "' appears twice (first at " + seen->second.line_column() +
                         "); expected each functional element once");
        continue;
      }
      fields(e, fe, outputs_fed);
      if (!fe.fields.empty()) {
        const auto order = fe_fields(fe.id);
        auto rank = [&](const FieldBinding& b) {
          for (std::size_t i = 0; i < order.size(); ++i)
            if (order[i].name == b.field.name) return i;
          return order.size();
        };
        std::stable_sort(fe.fields.begin(), fe.fields.end(),
                         [&](const FieldBinding& a, const FieldBinding& b) { return rank(a) < rank(b); });
        cfg_.functional_elements.push_back(std::move(fe));
      }
    }
    std::sort(cfg_.functional_elements.begin(), cfg_.functional_elements.end(),
              [](const auto& a, const auto& b) { return a.id < b.id; });
  }

  static std::string accepted_kinds(const FeField& f, bool input) {
    if (!input) return "an Output signal";
    if (f.bit != 0xFF) return "a Button or Digital signal";
    if (f.type == DataType::Integer16) return "an Axis or Analog signal";
    return "a Position or Analog signal";
  }
  static bool fits(const SignalInfo& s, const FeField& f, bool input) {
    if (!input) return s.kind == SignalKind::Output;
    if (f.bit != 0xFF) return s.kind == SignalKind::Button || s.kind == SignalKind::Digital;
    if (f.type == DataType::Integer16) return s.kind == SignalKind::Axis || s.kind == SignalKind::Analog;
    return s.kind == SignalKind::Position || s.kind == SignalKind::Analog;
  }
  static std::string kind_name(SignalKind k) {
    switch (k) {
      case SignalKind::Axis:
        return "an Axis";
      case SignalKind::Button:
        return "a Button";
      case SignalKind::Position:
        return "a Position";
      case SignalKind::Speed:
        return "a Speed";
      case SignalKind::Digital:
        return "a Digital";
      case SignalKind::Analog:
        return "an Analog";
      case SignalKind::Output:
        return "an Output";
    }
    return "an unknown";
  }

  void fields(const Entry& fe_entry, FunctionalElementConfig& fe,
              std::map<std::pair<std::string, std::string>, Location>& outputs_fed) {
    const bool input = is_input(fe.id.kind);
    const auto all = fe_fields(fe.id);
    std::vector<std::string> field_names;
    for (const auto& f : all) field_names.push_back(f.name);
    const std::string fe_name = mapping::fe_name(fe.id);
    const auto es = entries(fe_entry.value, fe_name, {}, "a map of field -> signal, e.g. { x: right_grip.x }");
    if (fe_entry.value.IsMap() && es.empty() && fe_entry.value.size() == 0)
      error(fe_entry.value, fe_name + " has no fields; expected at least one field fed by a signal");
    if (!es.empty() && std::all_of(es.begin(), es.end(), [](const Entry& x) {
          return x.name == "sources" || x.name == "command_timeout_ms";
        }))
    {
      std::string keys;
      for (const auto& x : es) keys += (keys.empty() ? "'" : " and '") + x.name + "'";
      error(fe_entry.value, fe_name + " has only " + keys + " and no fields; expected at least one field fed by a signal");
    }
    for (const auto& e : es) {
      if (e.name == "sources") {
        command_sources(e, fe, fe_name);
        continue;
      }
      if (e.name == "command_timeout_ms") {
        if (input)
          error(e.key, fe_name + " is an input; 'command_timeout_ms' applies to indicators and display (commands in)");
        else if (auto v = integer(e, fe_name + " command_timeout_ms", 0, 600000))
          fe.command_timeout_ms = static_cast<std::uint32_t>(*v);
        continue;
      }
      // The field key: "x", "buttons" (a group: buttons[1..n]), "buttons[3]", "indicator[1..4]".
      auto key = parse_ref(e.name);
      const bool group =
          key && !key->indexed && !find_fe_field(fe.id, key->base) && find_fe_field(fe.id, key->base + "[1]");
      if (!key || (!group && !find_fe_field(fe.id, key->element(0))) ||
          (key->indexed && !find_fe_field(fe.id, key->element(key->count() - 1)))) {
        std::vector<std::string> bases;
        for (const auto& n : field_names) bases.push_back(n.substr(0, n.find('[')));
        error(e.key, fe_name + " has no field '" + e.name + "'; expected one of " + compress_names(field_names) +
                         did_you_mean(key ? key->base : e.name, bases));
        continue;
      }
      // The value: "dev.signal" or { signal: dev.signal, options... }.
      YAML::Node sig_node = e.value;
      FieldOptions opts;
      bool opts_ok = true;
      if (e.value.IsMap()) {
        // What applies depends on the field: a one-bit input has no scale; outputs no fault.
        const auto first = *find_fe_field(fe.id, group ? key->base + "[1]" : key->element(0));
        const bool bit = first.bit != 0xFF;
        std::vector<std::string_view> allowed;
        if (!input)
          allowed = {"signal", "scale", "offset", "invert", "clamp"};
        else if (bit)
          allowed = {"signal", "invert", "fault", "interlock"};
        else
          allowed = {"signal", "scale", "offset", "deadband", "invert", "clamp", "fault", "interlock"};
        std::int64_t lo = std::numeric_limits<std::int64_t>::min() / 2,
                     hi = std::numeric_limits<std::int64_t>::max() / 2;
        if (input && bit) {
          lo = 0;
          hi = 1;
        } else if (input && first.type == DataType::Integer16) {
          lo = -32768;
          hi = 32767;
        } else if (input) {
          lo = std::numeric_limits<std::int32_t>::min();
          hi = std::numeric_limits<std::int32_t>::max();
        }
        range_lo_ = lo;
        range_hi_ = hi;
        const auto os = entries(e.value, fe_name + " " + e.name, allowed, "a map with " + join(allowed));
        const auto* s = find(os, "signal");
        if (!s) {
          missing(e.value, "signal", fe_name + " " + e.name, "the feeding signal, e.g. right_grip.x");
          continue;
        }
        sig_node = s->value;
        opts_ok = options(os, opts);
      }
      if (!sig_node.IsScalar()) {
        error(sig_node, "found " + node_kind(sig_node) + " for " + fe_name + " " + e.name +
                            "; expected a signal like right_grip.x or { signal: right_grip.x, ... }");
        continue;
      }
      const std::string text = sig_node.Scalar();
      const auto dot = text.find('.');
      std::string sig_text = dot == std::string::npos ? std::string() : text.substr(dot + 1);
      // An explicit bit of a bit-packed signal: "cluster.in[1].bit3".
      std::optional<unsigned> pick;
      if (const auto b = sig_text.rfind(".bit"); b != std::string::npos) {
        const auto digits = sig_text.substr(b + 4);
        const auto v = parse_integer(digits);
        if (!digits.empty() && digits.find_first_not_of("0123456789") == std::string::npos && v && *v < 64) {
          pick = static_cast<unsigned>(*v);
          sig_text.resize(b);
        }
      }
      const auto sref = sig_text.empty() ? std::nullopt : parse_ref(sig_text);
      if (!sref || (pick && sref->range())) {
        error(sig_node, "found '" + text + "' for " + fe_name + " " + e.name +
                            "; expected a signal as subdevice.signal, subdevice.signal[a..b] or subdevice.signal.bitN");
        continue;
      }
      const std::string dev_name = text.substr(0, dot);
      const SubdeviceConfig* dev = cfg_.find_subdevice(dev_name);
      if (!dev) {
        std::vector<std::string> names;
        for (const auto& d : cfg_.subdevices) names.push_back(d.name);
        error(sig_node, "unknown sub-device '" + dev_name + "' in signal '" + text + "'; expected one of " +
                            (names.empty() ? std::string("the sub-devices section's names") : join(names)) +
                            did_you_mean(dev_name, names));
        continue;
      }
      if (dev->signals.empty()) continue;  // its driver was already refused
      const FeField first = *find_fe_field(fe.id, group ? key->base + "[1]" : key->element(0));
      const bool bit_field = first.bit != 0xFF;
      // The signal's elements; a bit-packed one (a CiA 401 byte) feeds one-bit fields bit by bit.
      struct Source {
        const SignalInfo* info;
        std::string name;
        std::uint8_t bit;
      };
      std::vector<Source> sources;
      bool bad = false, expanded = false;
      std::vector<std::string> sig_names;
      for (const auto& si : dev->signals) sig_names.push_back(si.name);
      for (long i = 0; i < sref->count() && !bad; ++i) {
        const auto sname = sref->element(i);
        const SignalInfo* info = dev->find_signal(sname);
        if (!info) {
          const bool base_known = std::any_of(sig_names.begin(), sig_names.end(), [&](const std::string& n) {
            return sref->indexed && n.rfind(sref->base + "[", 0) == 0;
          });
          error(sig_node, "sub-device '" + dev_name + "' (" + dev->driver + ") has no signal '" + sname +
                              "'; expected one of " + compress_names(sig_names) +
                              (base_known ? "" : did_you_mean(sname, sig_names)));
          bad = true;
          break;
        }
        const unsigned width = bit_width(*info);
        if (pick) {
          if (width == 0 || *pick >= width) {
            error(sig_node,
                  "found bit " + std::to_string(*pick) + " of '" + dev_name + "." + sname + "'" +
                      (width == 0 ? ", which is not bit-packed" : "") + "; expected " +
                      (width == 0 ? std::string("the signal without .bitN") : "a bit 0.." + std::to_string(width - 1)));
            bad = true;
            break;
          }
          sources.push_back({info, sname, static_cast<std::uint8_t>(*pick)});
        } else if (bit_field && width > 0) {
          expanded = true;
          for (unsigned bit = 0; bit < width; ++bit) sources.push_back({info, sname, static_cast<std::uint8_t>(bit)});
        } else {
          sources.push_back({info, sname, 0xFF});
        }
      }
      if (bad) continue;
      // Element counts.
      const long n = static_cast<long>(sources.size());
      FieldRef fkey = *key;
      if (group) {
        if (!sref->indexed && !expanded) {
          error(sig_node, "found the single signal '" + text + "' for the field group " + fe_name + " " + e.name +
                              "; expected a signal range such as " + dev_name +
                              ".buttons[1..8], or a bit-packed signal");
          continue;
        }
        fkey.indexed = true;
        fkey.first = 1;
        fkey.last = n;
        if (!find_fe_field(fe.id, fkey.element(n - 1))) {
          const auto size = std::to_string(count_group(all, e.name));
          error(sig_node, "signal range '" + text + "' has " + std::to_string(n) + (expanded ? " bits" : " elements") +
                              " but " + fe_name + " has " + e.name + "[1.." + size + "]; expected at most " + size +
                              " signals");
          continue;
        }
      } else if (fkey.count() != n) {
        error(sig_node, fe_name + " " + e.name + " has " + std::to_string(fkey.count()) + " element" +
                            (fkey.count() == 1 ? "" : "s") + " but '" + text + "' has " + std::to_string(n) +
                            (expanded ? " bits" : "") + "; expected ranges of equal length");
        continue;
      }
      for (long i = 0; i < n; ++i) {
        const auto fname = fkey.element(i);
        const auto& src = sources[static_cast<std::size_t>(i)];
        const auto field = find_fe_field(fe.id, fname);
        const auto full = dev_name + "." + src.name;
        if (!fits(*src.info, *field, input)) {
          error(sig_node, "signal '" + full + "' is " + kind_name(src.info->kind) + " signal; expected " +
                              accepted_kinds(*field, input) + " for " + fe_name + " " + fname +
                              (input ? "" : " (an output functional element)"));
          break;
        }
        const auto fk = fe_name + "\n" + fname;
        auto [it, fresh] = fed_.emplace(fk, loc(e.key));
        if (!fresh) {
          error(e.key, fe_name + " " + fname + " is fed twice (first at " + it->second.line_column() +
                           "); expected each field fed by one signal");
          break;  // one error per entry
        }
        if (!input) {
          const auto out_name = src.bit == 0xFF ? full : full + " bit " + std::to_string(src.bit);
          auto [ot, ofresh] = outputs_fed.emplace(std::pair(dev_name, out_name), loc(e.key));
          if (!ofresh) {
            error(sig_node, "output signal '" + out_name + "' is driven twice (first at " + ot->second.line_column() +
                                "); expected each output driven by one field");
            break;
          }
        }
        if (!opts_ok) continue;
        FieldBinding b;
        b.field = *field;
        b.subdevice = dev_name;
        b.signal = src.name;
        b.signal_bit = src.bit;
        b.signal_info = *src.info;
        b.options = opts;
        b.where = loc(e.key);
        fe.fields.push_back(std::move(b));
      }
    }
  }

  static long count_group(const std::vector<FeField>& all, const std::string& base) {
    long n = 0;
    for (const auto& f : all)
      if (f.name.rfind(base + "[", 0) == 0) ++n;
    return n;
  }

  bool options(const std::vector<Entry>& os, FieldOptions& o) {
    bool ok = true;
    for (const auto& e : os) {
      if (e.name == "signal") continue;
      if (e.name == "scale") {
        if (auto v = real(e, "scale"))
          o.scale = *v;
        else
          ok = false;
      } else if (e.name == "offset") {
        if (auto v = integer(e, "offset", -2147483648LL, 2147483647LL))
          o.offset = *v;
        else
          ok = false;
      } else if (e.name == "deadband") {
        if (auto v = integer(e, "deadband", 0, 2147483647LL))
          o.deadband = *v;
        else
          ok = false;
      } else if (e.name == "fault") {
        if (auto v = integer(e, "fault", range_lo_, range_hi_))
          o.fault = *v;
        else
          ok = false;
      } else if (e.name == "invert") {
        if (auto v = boolean(e, "invert"))
          o.invert = *v;
        else
          ok = false;
      } else if (e.name == "interlock") {
        if (auto v = boolean(e, "interlock"))
          o.interlock = *v;
        else
          ok = false;
      } else if (e.name == "clamp") {
        std::optional<std::int64_t> lo, hi;
        if (e.value.IsSequence() && e.value.size() == 2) {
          lo = parse_integer(e.value[0].IsScalar() ? e.value[0].Scalar() : "");
          hi = parse_integer(e.value[1].IsScalar() ? e.value[1].Scalar() : "");
        }
        if (!lo || !hi || *lo > *hi || *lo < range_lo_ || *hi > range_hi_) {
          error(e.value, "found " + node_kind(e.value) + " for clamp; expected [min, max] with integers " +
                             std::to_string(range_lo_) + " <= min <= max <= " + std::to_string(range_hi_));
          ok = false;
        } else {
          o.clamp = std::pair(*lo, *hi);
        }
      }
    }
    return ok;
  }

  std::string file_;
  const SignalCatalogue& catalogue_;
  std::vector<Diagnostic> errors_;
  Config cfg_;
  std::map<std::string, Location> fed_;
  std::map<std::string, Location> fe_seen_;
  std::int64_t range_lo_ = 0, range_hi_ = 0;  // of the field whose options are parsed
};

}  // namespace

LoadResult load_config_text(std::string_view text, std::string_view file, const SignalCatalogue& catalogue) {
  return Loader(std::string(file), catalogue).run(text);
}

LoadResult load_config(const std::string& path, const SignalCatalogue& catalogue) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    LoadResult r;
    r.errors.push_back({{path, 1, 1}, "cannot open the file; expected a readable mapping file"});
    return r;
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  return load_config_text(ss.str(), path, catalogue);
}

}  // namespace oegw::mapping
