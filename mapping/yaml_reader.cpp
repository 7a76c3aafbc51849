#include "mapping/yaml_reader.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <set>
#include <utility>

namespace oegw::mapping {

std::string hex(std::int64_t v, int width) {
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

namespace {

// The text of 1-based line `line`, or nullopt past the end.
std::optional<std::string_view> line_of(std::string_view text, int line) {
  std::size_t start = 0;
  for (int i = 1; i < line && start != std::string_view::npos; ++i) {
    start = text.find('\n', start);
    if (start != std::string_view::npos) ++start;
  }
  if (start == std::string_view::npos) return std::nullopt;
  return text.substr(start, text.find('\n', start) - start);
}

// Plain scalars cannot hold [ ] inside a { } flow map: the commonest slip in this format.
std::string flow_map_hint(std::string_view text, int line) {
  const auto l = line_of(text, line);
  if (l && l->find('{') != std::string_view::npos && l->find('[') != std::string_view::npos)
    return " (inside { }, quote names with [ ], e.g. \"buttons[1..8]\", or use block style)";
  return "";
}

}  // namespace

ParsedYaml parse_yaml(std::string_view text, const std::string& file) {
  ParsedYaml out;
  try {
    out.root = YAML::Load(std::string(text));
  } catch (const YAML::Exception& e) {
    Location l{file, e.mark.line + 1, e.mark.column + 1};
    if (e.mark.is_null()) l.line = l.column = 1;
    out.error =
        Diagnostic{l, "YAML syntax error: " + e.msg + "; expected well-formed YAML" + flow_map_hint(text, l.line)};
  }
  return out;
}

Location YamlReader::loc(const YAML::Node& n) const {
  const auto m = n.Mark();
  if (m.is_null()) return {file_, 1, 1};
  return {file_, m.line + 1, m.column + 1};
}

std::vector<Diagnostic> YamlReader::take_errors() {
  std::stable_sort(errors_.begin(), errors_.end(), [](const Diagnostic& a, const Diagnostic& b) {
    return std::pair(a.where.line, a.where.column) < std::pair(b.where.line, b.where.column);
  });
  return std::move(errors_);
}

std::vector<MapEntry> YamlReader::entries(const YAML::Node& map, std::string_view what,
                                          const std::vector<std::string_view>& allowed,
                                          const std::string& expected_map) {
  std::vector<MapEntry> out;
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

const MapEntry* YamlReader::find(const std::vector<MapEntry>& es, std::string_view name) {
  for (const auto& e : es)
    if (e.name == name) return &e;
  return nullptr;
}

void YamlReader::missing(const YAML::Node& map, std::string_view key, std::string_view what,
                         std::string_view expected) {
  error(map, "no '" + std::string(key) + "' in " + std::string(what) + "; expected " + std::string(expected));
}

std::optional<std::int64_t> YamlReader::integer(const MapEntry& e, std::string_view what, std::int64_t lo,
                                                std::int64_t hi, bool show_hex) {
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

std::optional<std::string> YamlReader::string(const MapEntry& e, std::string_view what) {
  if (!e.value.IsScalar() || e.value.Scalar().empty()) {
    error(e.value, "found " + node_kind(e.value) + " for " + std::string(what) + "; expected a text");
    return std::nullopt;
  }
  return e.value.Scalar();
}

std::optional<bool> YamlReader::boolean(const MapEntry& e, std::string_view what) {
  if (e.value.IsScalar()) {
    const auto& s = e.value.Scalar();
    if (s == "true" || s == "yes" || s == "on") return true;
    if (s == "false" || s == "no" || s == "off") return false;
  }
  error(e.value, "found " + node_kind(e.value) + " for " + std::string(what) + "; expected true or false");
  return std::nullopt;
}

std::optional<double> YamlReader::real(const MapEntry& e, std::string_view what) {
  if (e.value.IsScalar()) {
    const auto& s = e.value.Scalar();
    char* end = nullptr;
    const double d = std::strtod(s.c_str(), &end);
    if (!s.empty() && end == s.c_str() + s.size() && std::isfinite(d) && d != 0.0) return d;
  }
  error(e.value, "found " + node_kind(e.value) + " for " + std::string(what) + "; expected a non-zero number");
  return std::nullopt;
}

namespace {
// The bit rates CiA 301 defines for CANopen.
constexpr std::array<std::uint32_t, 8> kBitrates = {10000, 20000, 50000, 125000, 250000, 500000, 800000, 1000000};
}  // namespace

void YamlReader::bitrate(const std::vector<MapEntry>& es, std::string_view what, std::uint32_t& out) {
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

}  // namespace oegw::mapping
