#include "cli/signals_command.hpp"

#include <algorithm>
#include <cstdio>

#include "gateway/programs.hpp"
#include "mapping/draft.hpp"
#include "mapping/yaml_reader.hpp"
#include "subdevices/driver.hpp"
#include "subdevices/driver_options.hpp"

namespace oegw::cli {

namespace {

namespace sd = subdevices;

// One row of the signal table: consecutive signals base[i]..base[j] that differ only by their
// index are one row "base[i..j]".
struct Row {
  std::string name, dir, kind, range, unit, neutral;
};

std::string base_of(const std::string& name, long& index) {
  const auto lb = name.find('[');
  index = -1;
  if (lb == std::string::npos || name.back() != ']') return name;
  try {
    index = std::stol(name.substr(lb + 1, name.size() - lb - 2));
  } catch (...) {
    index = -1;
    return name;
  }
  return name.substr(0, lb);
}

std::vector<Row> rows(const std::vector<sd::SignalInfo>& signals) {
  std::vector<Row> out;
  std::size_t i = 0;
  while (i < signals.size()) {
    const sd::SignalInfo& s = signals[i];
    long first = 0;
    const std::string base = base_of(s.name, first);
    std::size_t j = i + 1;
    long last = first;
    while (first >= 0 && j < signals.size()) {
      const sd::SignalInfo& t = signals[j];
      long k = 0;
      if (base_of(t.name, k) != base || k != last + 1 || t.kind != s.kind || t.min != s.min || t.max != s.max ||
          t.neutral != s.neutral || t.unit != s.unit)
        break;
      last = k;
      ++j;
    }
    Row r;
    r.name =
        first >= 0 && last > first ? base + "[" + std::to_string(first) + ".." + std::to_string(last) + "]" : s.name;
    r.dir = s.output() ? "out" : "in";
    r.kind = std::string(sd::to_string(s.kind));
    r.range = std::to_string(s.min) + ".." + std::to_string(s.max);
    r.unit = s.unit.empty() ? "-" : s.unit;
    r.neutral = std::to_string(s.neutral);
    out.push_back(std::move(r));
    i = j;
  }
  return out;
}

std::string default_text(const sd::OptionSpec& o) {
  if (!o.default_value.empty()) return std::string(o.default_value);
  return o.required ? "required" : "unset";
}

std::string type_column(const sd::OptionSpec& o) {
  if (o.type == sd::OptionSpec::Type::Choice) {
    std::string out;
    for (const auto c : o.choices) out += (out.empty() ? "" : " or ") + std::string(c);
    return out;
  }
  return o.type_text();
}

std::string what_it_does(const sd::OptionSpec& o) {
  return (o.safety ? std::string("SAFETY-RELEVANT: ") : std::string()) + std::string(o.description) + ".";
}

// `text` in lines of at most 80 columns, the first indented `indent` spaces, the others `rest`.
std::string wrap(const std::string& text, std::size_t indent, std::size_t rest) {
  return mapping::wrap_words(text, 80, std::string(indent, ' '), std::string(rest, ' '));
}

std::string pad(const std::string& s, std::size_t n) { return s.size() >= n ? s : s + std::string(n - s.size(), ' '); }

std::string text_table(const std::vector<Row>& rs) {
  std::vector<Row> all{{"signal", "dir", "kind", "range", "unit", "neutral"}};
  all.insert(all.end(), rs.begin(), rs.end());
  std::size_t w[5] = {};
  for (const Row& r : all) {
    w[0] = std::max(w[0], r.name.size());
    w[1] = std::max(w[1], r.dir.size());
    w[2] = std::max(w[2], r.kind.size());
    w[3] = std::max(w[3], r.range.size());
    w[4] = std::max(w[4], r.unit.size());
  }
  std::string out;
  for (const Row& r : all)
    out += "  " + pad(r.name, w[0]) + "  " + pad(r.dir, w[1]) + "  " + pad(r.kind, w[2]) + "  " + pad(r.range, w[3]) +
           "  " + pad(r.unit, w[4]) + "  " + r.neutral + "\n";
  return out;
}

std::string md_cell(std::string s) {
  for (std::size_t p = 0; (p = s.find('|', p)) != std::string::npos; p += 2) s.replace(p, 1, "\\|");
  return s;
}

// One driver: its signals (from a driver built with `given`, nullopt when it cannot be built
// without an option the user did not give) and options.
std::string describe(const sd::DriverInfo& info, const std::optional<std::vector<sd::SignalInfo>>& signals,
                     bool markdown) {
  std::string out;
  if (markdown) {
    out += "#### `" + std::string(info.family) + "`\n\n" + std::string(info.device) + ".\n\n";
    if (signals) {
      out += "| signal | direction | kind | range | unit | neutral |\n| --- | --- | --- | --- | --- | --- |\n";
      for (const Row& r : rows(*signals))
        out += "| `" + r.name + "` | " + r.dir + " | " + r.kind + " | " + r.range + " | " + md_cell(r.unit) + " | " +
               r.neutral + " |\n";
      out += "\n";
    }
    if (!info.signals_note.empty()) out += "Signals: " + std::string(info.signals_note) + ".\n\n";
    out += "| option | type | default | what it does |\n| --- | --- | --- | --- |\n";
    for (const sd::OptionSpec& o : info.options) {
      std::string does = std::string(o.description) + ".";
      if (o.safety) does = "**Safety-relevant:** " + does;
      out += "| `" + std::string(o.name) + "` | " + md_cell(type_column(o)) + " | " + md_cell(default_text(o)) + " | " +
             md_cell(does) + " |\n";
    }
    return out;
  }
  out += wrap(std::string(info.family) + ": " + std::string(info.device), 0, 2);
  if (signals) out += text_table(rows(*signals));
  if (!info.signals_note.empty()) out += wrap("signals: " + std::string(info.signals_note) + ".", 2, 4);
  out += "  options:\n";
  for (const sd::OptionSpec& o : info.options) {
    out += wrap("- " + std::string(o.name) + ": " + type_column(o) + ", default " + default_text(o), 2, 6);
    out += wrap(what_it_does(o), 6, 6);
  }
  return out;
}

}  // namespace

std::string signals_listing(const SignalsOptions& o, std::string& error) {
  sd::DriverOptions given;
  for (const std::string& kv : o.options) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos || eq == 0) {
      error = "option '" + kv + "' is not key=value";
      return {};
    }
    given.values.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
  }
  if (!o.eds.empty()) given.values.emplace_back("eds", o.eds);
  std::string out;
  for (const sd::DriverInfo& info : sd::drivers()) {
    if (!o.driver.empty() && info.family != o.driver) continue;
    const auto signals = sd::listing_signals(info, given, error);
    if (!error.empty()) return {};
    if (!out.empty()) out += "\n";
    out += describe(info, signals, o.markdown);
  }
  return out;
}

int run_signals(const SignalsOptions& o) {
  if (!o.driver.empty() && !sd::find_driver_info(o.driver)) {
    std::vector<std::string_view> families;
    for (const sd::DriverInfo& d : sd::drivers()) families.push_back(d.family);
    std::fprintf(stderr, "oegw signals: unknown driver '%s'; expected one of %s%s\n", o.driver.c_str(),
                 sd::driver_names().c_str(), mapping::did_you_mean(o.driver, families).c_str());
    return exit_code::kUsage;
  }
  if (o.driver.empty() && (!o.options.empty() || !o.eds.empty())) {
    std::fprintf(stderr, "oegw signals: --option and --eds need a DRIVER (e.g. oegw signals cia401 --eds FILE)\n");
    return exit_code::kUsage;
  }
  for (const std::string& kv : o.options)
    if (kv.find('=') == std::string::npos || kv.front() == '=') {
      std::fprintf(stderr, "oegw signals: --option '%s' is not key=value (e.g. detent=clamp)\n", kv.c_str());
      return exit_code::kUsage;
    }
  std::string error;
  const std::string out = signals_listing(o, error);
  if (!error.empty()) {
    std::fprintf(stderr, "oegw signals: %s\n", error.c_str());
    return exit_code::kBadFile;
  }
  std::fputs(out.c_str(), stdout);
  return exit_code::kOk;
}

}  // namespace oegw::cli
