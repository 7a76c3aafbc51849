#include "mapping/yaml_reader.hpp"

#include <yaml-cpp/eventhandler.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <set>
#include <sstream>
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

std::string lower_case(std::string_view s) {
  std::string out(s);
  for (char& c : out)
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  return out;
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

namespace {
// What a message quotes of a value: a long one (up to YamlLimits::kScalarBytes, or a list of
// many, repeated by aliases) is cut, so that no error message grows with the file.
constexpr std::size_t kQuoted = 80;
std::string quoted(const std::string& s) { return s.size() <= kQuoted ? s : s.substr(0, kQuoted) + "..."; }
}  // namespace

std::string node_kind(const YAML::Node& n) {
  switch (n.Type()) {
    case YAML::NodeType::Map: return "a map";
    case YAML::NodeType::Sequence: {
      std::string out = "[";
      for (const auto& item : n) {
        if (!item.IsScalar()) return "a list";
        if (out.size() > kQuoted) return out + ", ...]";
        out += (out.size() > 1 ? ", " : "") + quoted(item.Scalar());
      }
      return out + "]";
    }
    case YAML::NodeType::Scalar: return "'" + quoted(n.Scalar()) + "'";
    default: return "nothing";
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

bool looks_like_integer(std::string_view s) {
  if (!s.empty() && (s.front() == '-' || s.front() == '+')) s.remove_prefix(1);
  const bool hexa = s.size() > 2 && s[0] == '0' && (s[1] == 'x' || s[1] == 'X');
  if (hexa) s.remove_prefix(2);
  if (s.empty()) return false;
  return std::all_of(s.begin(), s.end(), [hexa](char c) {
    return (c >= '0' && c <= '9') || (hexa && ((c >= 'a' && c <= 'f') || (c >= 'A' && c <= 'F')));
  });
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

// The first line up to `last` whose indentation holds a tab, and the tab's column (1-based).
std::optional<std::pair<int, int>> tab_indent(std::string_view text, int last) {
  // One pass over the text (a line_of() per line would rescan it from the start each time).
  std::size_t start = 0;
  for (int line = 1; line <= last && start <= text.size(); ++line) {
    for (std::size_t i = start; i < text.size() && (text[i] == ' ' || text[i] == '\t'); ++i)
      if (text[i] == '\t') return std::pair(line, static_cast<int>(i - start) + 1);
    const auto end = text.find('\n', start);
    if (end == std::string_view::npos) break;
    start = end + 1;
  }
  return std::nullopt;
}

Location at(const std::string& file, std::string_view text, std::size_t offset) {
  Location l{file, 1, 1};
  for (std::size_t i = 0; i < offset && i < text.size(); ++i) {
    if (text[i] == '\n') {
      ++l.line;
      l.column = 1;
    } else {
      ++l.column;
    }
  }
  return l;
}

std::string byte_hex(unsigned char b) {
  static constexpr char kDigits[] = "0123456789ABCDEF";
  return std::string("0x") + kDigits[b >> 4] + kDigits[b & 0xF];
}

std::string limit_text(std::size_t limit) {
  return std::to_string(limit) + " (docs/reference/mapping-file.md#the-file-itself-limits-text-one-document)";
}

// YAML is UTF-8 text (YAML 1.2 §5.1, §5.2): no NUL or other C0 control character besides tab,
// line feed and carriage return, no DEL, no broken or overlong sequence.
std::optional<Diagnostic> check_text(std::string_view text, const std::string& file) {
  std::size_t i = 0;
  if (text.substr(0, 3) == "\xEF\xBB\xBF") i = 3;  // a byte-order mark is allowed
  while (i < text.size()) {
    const auto b = static_cast<unsigned char>(text[i]);
    if (b < 0x80) {
      if ((b < 0x20 && b != '\t' && b != '\n' && b != '\r') || b == 0x7F)
        return Diagnostic{at(file, text, i), "byte " + byte_hex(b) + (b == 0 ? " (NUL)" : " (a control character)") +
                                                 " is not text; expected a UTF-8 text file"};
      ++i;
      continue;
    }
    const std::size_t n = b >= 0xF0 && b <= 0xF4 ? 4 : b >= 0xE0 && b <= 0xEF ? 3 : b >= 0xC2 && b <= 0xDF ? 2 : 0;
    bool ok = n != 0 && i + n <= text.size();
    std::uint32_t cp = n == 2 ? b & 0x1Fu : n == 3 ? b & 0x0Fu : b & 0x07u;
    for (std::size_t k = 1; ok && k < n; ++k) {
      const auto c = static_cast<unsigned char>(text[i + k]);
      ok = (c & 0xC0) == 0x80;
      cp = (cp << 6) | (c & 0x3Fu);
    }
    if (ok && n == 3) ok = cp >= 0x800 && (cp < 0xD800 || cp > 0xDFFF);
    if (ok && n == 4) ok = cp >= 0x10000 && cp <= 0x10FFFF;
    if (!ok) return Diagnostic{at(file, text, i), "byte " + byte_hex(b) + " is not UTF-8; expected a UTF-8 text file"};
    i += n;
  }
  return std::nullopt;
}

// Indentation (with the "- " markers of lists nested on one line) and flow nesting, counted on
// the text, so that yaml-cpp's recursive parser never sees a file nested deeper than YamlLimits
// allows. Quoted scalars and comments are skipped; a quote opens a scalar only where a scalar
// can start (so the ' of "don't" in a plain scalar is text).
std::optional<Diagnostic> check_layout(std::string_view text, const std::string& file) {
  int depth = 0;
  char quote = 0;  // ', " or # (a comment) while inside one
  bool line_start = true;
  char prev = ' ';
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (line_start && !quote) {
      line_start = false;
      std::size_t j = i;
      const auto marker = [&](std::size_t k) {
        return (text[k] == '-' || text[k] == '?' || text[k] == ':') && k + 1 < text.size() &&
               (text[k + 1] == ' ' || text[k + 1] == '\t');
      };
      while (j < text.size() && (text[j] == ' ' || text[j] == '\t' || marker(j))) ++j;
      const bool content = j < text.size() && text[j] != '\n' && text[j] != '\r' && text[j] != '#';
      if (content && j - i > static_cast<std::size_t>(YamlLimits::kIndent))
        return Diagnostic{at(file, text, i), "indentation of " + std::to_string(j - i) + " columns; expected at most " +
                                                 limit_text(YamlLimits::kIndent)};
    }
    if (c == '\n') {
      line_start = true;
      prev = ' ';
      if (quote == '#') quote = 0;
      continue;
    }
    if (quote == '#') continue;
    if (quote != 0) {
      if (quote == '"' && c == '\\') {
        ++i;  // an escaped character
      } else if (c == quote) {
        if (quote == '\'' && i + 1 < text.size() && text[i + 1] == '\'') ++i;  // '' inside '...'
        else quote = 0;
      }
      prev = c;
      continue;
    }
    const bool can_start = prev == ' ' || prev == '\t' || prev == '[' || prev == '{' || prev == ',';
    if ((c == '"' || c == '\'') && can_start) {
      quote = c;
    } else if (c == '#' && (prev == ' ' || prev == '\t')) {
      quote = '#';
    } else if (c == '[' || c == '{') {
      if (++depth > YamlLimits::kFlowNesting)
        return Diagnostic{at(file, text, i), "[ ] and { } nested deeper than " +
                                                 std::to_string(YamlLimits::kFlowNesting) +
                                                 " levels; expected at most " + limit_text(YamlLimits::kFlowNesting)};
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
    prev = c;
  }
  return std::nullopt;
}

// The parsed tree against YamlLimits: depth, the length of each scalar, and the number of nodes
// (an alias counts its whole target each time it is used, so a "billion laughs" file stops here
// instead of in whatever walks the tree next).
class TreeCheck {
 public:
  explicit TreeCheck(const std::string& file) : file_(file) {}
  std::optional<Diagnostic> run(const YAML::Node& n) {
    walk(n, 1);
    return std::move(error_);
  }

 private:
  [[nodiscard]] Location loc(const YAML::Node& n) const {
    const auto m = n.Mark();
    return m.is_null() ? Location{file_, 1, 1} : Location{file_, m.line + 1, m.column + 1};
  }
  void walk(const YAML::Node& n, int depth) {
    if (error_) return;
    if (++nodes_ > YamlLimits::kNodes) {
      error_ = Diagnostic{loc(n), "more than " + std::to_string(YamlLimits::kNodes) +
                                      " values (an alias counted each time it is used); expected at most " +
                                      limit_text(YamlLimits::kNodes)};
      return;
    }
    if (n.IsScalar()) {
      if (n.Scalar().size() > YamlLimits::kScalarBytes)
        error_ = Diagnostic{loc(n), "a value of " + std::to_string(n.Scalar().size()) + " bytes; expected at most " +
                                        limit_text(YamlLimits::kScalarBytes)};
      return;
    }
    if (!n.IsMap() && !n.IsSequence()) return;
    if (depth > YamlLimits::kDepth) {
      error_ = Diagnostic{loc(n), "maps and lists nested deeper than " + std::to_string(YamlLimits::kDepth) +
                                      " levels; expected at most " + limit_text(YamlLimits::kDepth)};
      return;
    }
    for (auto it = n.begin(); it != n.end() && !error_; ++it) {
      if (n.IsMap()) {
        walk(it->first, depth + 1);
        walk(it->second, depth + 1);
      } else {
        walk(*it, depth + 1);
      }
    }
  }
  const std::string& file_;
  std::size_t nodes_ = 0;
  std::optional<Diagnostic> error_;
};

// Where the second document of `text` starts: the document marker ("---", or "..." ending the
// first) on or before `mark_line` (the parser's mark of that document, 0: unknown).
Location second_document(std::string_view text, const std::string& file, int mark_line) {
  if (mark_line <= 0) mark_line = std::numeric_limits<int>::max();
  Location l{file, 1, 1};
  int line = 1;
  for (std::size_t start = 0; start < text.size() && line <= mark_line; ++line) {
    const auto end = text.find('\n', start);
    const auto t = text.substr(start, end == std::string_view::npos ? std::string_view::npos : end - start);
    const auto marker = t.substr(0, 3);
    if ((marker == "---" || marker == "...") && (t.size() == 3 || t[3] == ' ' || t[3] == '\t' || t[3] == '\r'))
      l.line = line;
    if (end == std::string_view::npos) break;
    start = end + 1;
  }
  return l;
}

// Counts nothing but where a document starts: the parser's events are not kept. yaml-cpp's
// LoadAll is not used: on some inputs it yields documents without end (a 636-byte file filled
// memory in mapping_fuzz); asking the parser for two documents at most is bounded.
class DocumentStart final : public YAML::EventHandler {
 public:
  std::optional<YAML::Mark> mark;
  void OnDocumentStart(const YAML::Mark& m) override { mark = m; }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t, const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}
};

}  // namespace

ParsedYaml parse_yaml(std::string_view text, const std::string& file) {
  ParsedYaml out;
  if (text.size() > YamlLimits::kFileBytes) {
    out.error = Diagnostic{{file, 1, 1},
                           "a text of " + std::to_string(text.size()) + " bytes; expected at most " +
                               limit_text(YamlLimits::kFileBytes)};
    return out;
  }
  if ((out.error = check_text(text, file)) || (out.error = check_layout(text, file))) return out;
  std::optional<YAML::Mark> second;
  try {
    const std::string owned(text);
    out.root = YAML::Load(owned);  // the first document
    std::istringstream in(owned);
    YAML::Parser parser(in);
    DocumentStart first, next;
    if (parser.HandleNextDocument(first) && parser.HandleNextDocument(next)) second = next.mark.value_or(YAML::Mark());
  } catch (const YAML::Exception& e) {
    Location l{file, e.mark.line + 1, e.mark.column + 1};
    if (e.mark.is_null()) l.line = l.column = 1;
    std::string hint = flow_map_hint(text, l.line);
    if (const auto tab = tab_indent(text, l.line)) {
      l.line = tab->first;
      l.column = tab->second;
      hint = " (line " + std::to_string(tab->first) + " is indented with a tab: YAML indents with spaces only)";
    }
    out.error = Diagnostic{l, "YAML syntax error: " + e.msg + "; expected well-formed YAML" + hint};
    return out;
  }
  if (second) {
    out.root = YAML::Node();
    out.error = Diagnostic{second_document(text, file, second->is_null() ? 0 : second->line + 1),
                           "a second YAML document starts here; expected one document per mapping file "
                           "(the second would be ignored)"};
    return out;
  }
  out.error = TreeCheck(file).run(out.root);
  return out;
}

namespace {
constexpr std::string_view kMergeKey = "<<";  // YAML 1.1 merge key (yaml.org/type/merge.html)
}  // namespace

std::string YamlReader::path(const std::string& written) const {
  const std::filesystem::path p(written);
  if (!base_ || p.is_absolute()) return written;
  return (*base_ / p).lexically_normal().string();
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
  // The map's own keys first: they win over merged ones wherever "<<" stands.
  std::set<std::string> own;
  for (auto it = map.begin(); it != map.end(); ++it)
    if (it->first.IsScalar() && it->first.Scalar() != kMergeKey) own.insert(it->first.Scalar());
  std::set<std::string> seen;
  const auto add = [&](const YAML::Node& key, const YAML::Node& value, bool merged) {
    const std::string name = key.Scalar();
    if (merged && (own.count(name) != 0 || seen.count(name) != 0)) return;  // set here, or by an earlier merge
    if (!seen.insert(name).second) {
      error(key, "duplicate key '" + name + "' in " + std::string(what) + "; expected each key once");
      return;
    }
    if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), name) == allowed.end()) {
      error(key, "unknown key '" + name + "' in " + std::string(what) + "; expected one of " + join(allowed) +
                     did_you_mean(name, allowed));
      return;
    }
    out.push_back({name, key, value});
  };
  for (auto it = map.begin(); it != map.end(); ++it) {
    const YAML::Node key = it->first;
    if (!key.IsScalar()) {
      error(key, "found " + node_kind(key) + " as a key in " + std::string(what) + "; expected a name");
      continue;
    }
    if (key.Scalar() != kMergeKey) {
      add(key, it->second, false);
      continue;
    }
    std::vector<YAML::Node> sources;
    if (it->second.IsSequence())
      for (const auto& s : it->second) sources.push_back(s);
    else sources.push_back(it->second);
    for (const auto& src : sources) {
      if (!src.IsMap()) {
        error(src, "found " + node_kind(src) + " for the merge key '<<' in " + std::string(what) +
                       "; expected an alias of a map (<<: *name) or a list of them");
        continue;
      }
      // A merged map may merge others itself: its entries as it sees them, then ours win.
      for (const auto& e : entries(src, what, {}, expected_map)) add(e.key, e.value, true);
    }
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
  if (!v && looks_like_integer(e.value.Scalar())) {  // beyond 64 bits
    error(e.value, std::string(what) + " " + e.value.Scalar() + " is out of range; expected " + range);
    return std::nullopt;
  }
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
