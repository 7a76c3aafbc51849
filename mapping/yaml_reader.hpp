// Reading the mapping file's YAML (yaml-cpp) and reporting what is wrong with it. Every value
// is read through a YamlReader, which type- and range-checks it and collects one Diagnostic per
// error, "file:line:column: what was found; expected what" (config.hpp), so that a file with
// several mistakes gets them all at once. Nothing here knows the sections of the file.
#pragma once

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mapping/config.hpp"

namespace oegw::mapping {

// ---- Wording of the diagnostics --------------------------------------------------------------

// "0x7F", or zero-padded to `width` hex digits: "0x181".
[[nodiscard]] std::string hex(std::int64_t v, int width = 0);

// Levenshtein distance (insertions, deletions, substitutions of one character each).
[[nodiscard]] std::size_t edit_distance(std::string_view a, std::string_view b);

// `s` in lower case (ASCII): names compared whatever case they were typed in.
[[nodiscard]] std::string lower_case(std::string_view s);

// The candidate `found` is a near miss of, or nullopt (also when `found` is one of them). The one
// helper for every name the user types (keys, driver families, FE kinds, signals, `oegw signals
// DRIVER`): compared without regard to case ("MCB402", "Elobau-MFG"), by edit distance (at most 2
// edits, or a third of the name), and a name written without its suffix after '-' or '_' counts
// as one edit ("novotechnik" for novotechnik-406, "elobau" for elobau-mfg).
template <typename Range>
[[nodiscard]] std::optional<std::string> near_miss(std::string_view found, const Range& candidates) {
  const std::string f = lower_case(found);
  std::size_t best = std::numeric_limits<std::size_t>::max();
  std::string best_name;
  for (const auto& c : candidates) {
    const std::string_view cv(c);
    if (cv == found) return std::nullopt;
    const std::string lc = lower_case(cv);
    std::size_t d = edit_distance(f, lc);
    if (f.size() >= 3 && lc.size() > f.size() && lc.compare(0, f.size(), f) == 0 &&
        (lc[f.size()] == '-' || lc[f.size()] == '_'))
      d = std::min<std::size_t>(d, 1);
    if (d < best) {
      best = d;
      best_name = std::string(cv);
    }
  }
  if (best_name.empty()) return std::nullopt;
  if (best == 0 || (best <= 2 && best < found.size()) || best * 3 <= found.size()) return best_name;
  return std::nullopt;
}

// " (did you mean 'x'?)" for a near miss among `candidates`, else "".
template <typename Range>
[[nodiscard]] std::string did_you_mean(std::string_view found, const Range& candidates) {
  const auto m = near_miss(found, candidates);
  return m ? " (did you mean '" + *m + "'?)" : std::string();
}

// "a, b, c".
template <typename Range>
[[nodiscard]] std::string join(const Range& names, std::string_view sep = ", ") {
  std::string out;
  for (const auto& n : names) {
    if (!out.empty()) out += sep;
    out += std::string_view(n);
  }
  return out;
}

// "buttons[1]", "buttons[2]", ... -> "buttons[1..16]"; other names unchanged; joined by ", ".
[[nodiscard]] std::string compress_names(const std::vector<std::string>& names);

// What a node is, for "found ...": "a map", "[a, b]" (a list of scalars), "a list", "'text'",
// "nothing".
[[nodiscard]] std::string node_kind(const YAML::Node& n);

// A decimal or 0x-hex integer with an optional sign; nullopt for anything else or beyond int64.
[[nodiscard]] std::optional<std::int64_t> parse_integer(std::string_view s);
// True when `s` is written as such an integer, whatever its size (to tell "out of range" from
// "not a number").
[[nodiscard]] bool looks_like_integer(std::string_view s);

// ---- Parsing the text ------------------------------------------------------------------------

// The limits of a mapping file
// (docs/reference/mapping-file.md#the-file-itself-limits-text-one-document). A mapping file for the
// largest cab CANopen allows (127 sub-devices, every FE) is far inside each; beyond them the file
// is refused before yaml-cpp reads it (nesting, text) or before anything else reads it (the tree),
// so a hostile or broken file costs neither memory nor stack.
struct YamlLimits {
  static constexpr std::size_t kFileBytes = 1024 * 1024;  // the whole file
  static constexpr int kFlowNesting = 32;                 // [ ] and { } inside each other
  static constexpr int kIndent = 128;                     // columns of indentation and "- " markers
  static constexpr int kDepth = 32;                       // maps and lists inside each other
  static constexpr std::size_t kScalarBytes = 4096;       // one value or key
  static constexpr std::size_t kNodes = 200000;           // nodes, aliases counted where used
};

struct ParsedYaml {
  YAML::Node root;
  std::optional<Diagnostic> error;  // a syntax error: nothing else can be checked
};

// The one YAML document of `text`, or the first error: a byte that is not UTF-8 text (a NUL, a
// control character, a broken sequence), a limit of YamlLimits passed, a syntax error at the
// parser's mark (with a hint for the commonest slips of this format: "[ ]" unquoted inside a
// "{ }" flow map, a tab in the indentation), or a second document ("---") after the first, which
// yaml-cpp's Load would silently drop.
[[nodiscard]] ParsedYaml parse_yaml(std::string_view text, const std::string& file);

// ---- Reading values, collecting the errors ---------------------------------------------------

// One key of a map, with its key node (for the key's position) and its value.
struct MapEntry {
  std::string name;
  YAML::Node key;
  YAML::Node value;
};

class YamlReader {
 public:
  // `base`: the folder a relative path in the file is taken from (the mapping file's own folder,
  // docs/reference/mapping-file.md#paths); none: paths stay as written (text that is in no folder).
  explicit YamlReader(std::string file, std::optional<std::filesystem::path> base = std::nullopt)
      : file_(std::move(file)), base_(std::move(base)) {}

  [[nodiscard]] const std::string& file() const { return file_; }
  // `written` taken from the base folder when it is relative; an absolute path unchanged; `~` is
  // not expanded (no shell reads the file): "~/x" is the folder "~" under the base.
  [[nodiscard]] std::string path(const std::string& written) const;
  [[nodiscard]] Location loc(const YAML::Node& n) const;  // 1:1 for a node without a mark
  void error(const Location& l, std::string msg) { errors_.push_back({l, std::move(msg)}); }
  void error(const YAML::Node& n, std::string msg) { error(loc(n), std::move(msg)); }
  // The errors so far, sorted by position (stable: one position keeps the order found).
  [[nodiscard]] std::vector<Diagnostic> take_errors();
  [[nodiscard]] bool has_errors() const { return !errors_.empty(); }

  // The entries of `map` (described as `what`); a non-map, a non-scalar key, a duplicate key and
  // (when `allowed` is not empty) an unknown key are errors, and such entries are left out.
  // A merge key (YAML 1.1 "<<: *grip", or "<<: [*a, *b]") adds the entries of the maps it names
  // that the map does not set itself, at its place; of several merged maps the first that sets a
  // key wins (the YAML merge-key rule). yaml-cpp 0.7 reads "<<" as a plain key.
  std::vector<MapEntry> entries(const YAML::Node& map, std::string_view what,
                                const std::vector<std::string_view>& allowed, const std::string& expected_map);
  // The entry named `name`, or nullptr.
  [[nodiscard]] static const MapEntry* find(const std::vector<MapEntry>& es, std::string_view name);
  // "no 'key' in what; expected ...", at `map`.
  void missing(const YAML::Node& map, std::string_view key, std::string_view what, std::string_view expected);

  // Typed values; each reports its own error and returns nullopt.
  std::optional<std::int64_t> integer(const MapEntry& e, std::string_view what, std::int64_t lo, std::int64_t hi,
                                      bool show_hex = false);
  std::optional<std::string> string(const MapEntry& e, std::string_view what);  // a non-empty scalar
  std::optional<bool> boolean(const MapEntry& e, std::string_view what);        // true/yes/on, false/no/off
  std::optional<double> real(const MapEntry& e, std::string_view what);         // finite and non-zero

  // `out` = the integer at `key` in lo..hi, when the key is there and its value fits.
  template <typename T>
  void set_int(const std::vector<MapEntry>& es, std::string_view key, std::string_view what, std::int64_t lo,
               std::int64_t hi, T& out, bool show_hex = false) {
    if (const auto* e = find(es, key))
      if (auto v = integer(*e, what, lo, hi, show_hex)) out = static_cast<T>(*v);
  }
  // `out` = the "bitrate" entry when it is one of the CiA 301 bit rates (10 kbit/s .. 1 Mbit/s).
  void bitrate(const std::vector<MapEntry>& es, std::string_view what, std::uint32_t& out);

 private:
  std::string file_;
  std::optional<std::filesystem::path> base_;
  std::vector<Diagnostic> errors_;
};

}  // namespace oegw::mapping
