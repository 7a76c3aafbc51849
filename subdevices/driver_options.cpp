#include "subdevices/driver_options.hpp"

#include <charconv>

namespace oegw::subdevices {

std::optional<std::int64_t> parse_option_integer(const std::string& s) {
  const char* b = s.data();
  const char* e = s.data() + s.size();
  int base = 10;
  if (s.size() > 2 && s[0] == '0' && (s[1] == 'x' || s[1] == 'X')) {
    b += 2;
    base = 16;
  }
  if (b == e) return std::nullopt;
  std::int64_t v = 0;
  const auto [p, ec] = std::from_chars(b, e, v, base);
  if (ec != std::errc{} || p != e) return std::nullopt;
  return v;
}

namespace {

std::string quoted_choices(const std::vector<std::string_view>& choices) {
  std::string out;
  for (std::size_t i = 0; i < choices.size(); ++i) {
    if (i > 0) out += i + 1 == choices.size() ? " or " : ", ";
    out += "'" + std::string(choices[i]) + "'";
  }
  return out;
}

std::string names(const std::vector<OptionSpec>& table) {
  std::string out;
  for (const OptionSpec& s : table) out += (out.empty() ? "" : ", ") + std::string(s.name);
  return out;
}

}  // namespace

std::string OptionSpec::ranges_text() const {
  std::string out;
  for (std::size_t i = 0; i < ranges.size(); ++i) {
    if (i > 0) out += i + 1 == ranges.size() ? " or " : ", ";
    const auto [lo, hi] = ranges[i];
    out += lo == hi ? std::to_string(lo) : std::to_string(lo) + ".." + std::to_string(hi);
  }
  return out;
}

std::string OptionSpec::type_text() const {
  switch (type) {
    case Type::Integer: return "integer " + ranges_text() + (unit.empty() ? "" : " (" + std::string(unit) + ")");
    case Type::Choice: return quoted_choices(choices);
    case Type::Text: return std::string(syntax);
  }
  return {};
}

std::string refusal_text(const OptionRefusals& refusals) {
  std::string out;
  for (const OptionRefusal& r : refusals) out += (out.empty() ? "" : "\n") + r.message;
  return out;
}

bool parse_options(std::string_view family, const std::vector<OptionSpec>& table, const DriverOptions& given,
                   const std::function<bool(const OptionValue&, std::string& error)>& apply, OptionRefusals& refusals) {
  const std::string f(family);
  const std::size_t before = refusals.size();
  auto refuse = [&](std::string_view option, std::string message) {
    refusals.push_back({std::string(option), std::move(message)});
  };
  // One value against its spec, then to `apply`; a refusal is recorded against `option` ("" for
  // a default, which no one wrote).
  auto one = [&](const OptionSpec& spec, const std::string& text, std::string_view option) {
    std::int64_t number = 0;
    if (spec.type == OptionSpec::Type::Integer) {
      const auto v = parse_option_integer(text);
      bool in = false;
      for (const auto& [lo, hi] : spec.ranges) in = in || (v && *v >= lo && *v <= hi);
      if (!in) {
        refuse(option, f + ": " + std::string(spec.name) + " '" + text + "' is not an " + spec.type_text() +
                           (spec.note.empty() ? "" : " " + std::string(spec.note)));
        return;
      }
      number = *v;
    } else if (spec.type == OptionSpec::Type::Choice) {
      bool in = false;
      for (const auto c : spec.choices) in = in || c == text;
      if (!in) {
        refuse(option, f + ": " + std::string(spec.name) + " '" + text + "' must be " + spec.type_text() +
                           (spec.note.empty() ? "" : " " + std::string(spec.note)));
        return;
      }
    }
    std::string error;
    if (!apply(OptionValue{&spec, text, number}, error)) refuse(option, error);
  };
  for (const auto& [key, text] : given.values) {
    bool known = false;
    for (const OptionSpec& s : table) known = known || s.name == key;
    if (!known) refuse(key, f + ": unknown option '" + key + "' (expected " + names(table) + ")");
  }
  for (const OptionSpec& s : table) {
    if (s.default_value.empty()) continue;
    one(s, std::string(s.default_value), "");
  }
  for (const OptionSpec& s : table) {
    bool present = false;
    for (const auto& [key, text] : given.values) present = present || key == s.name;
    if (present || !s.required) continue;
    refuse("", s.missing.empty()
                   ? f + ": option '" + std::string(s.name) + "' (" + std::string(s.description) + ") is required"
                   : std::string(s.missing));
  }
  for (const auto& [key, text] : given.values)
    for (const OptionSpec& s : table) {
      if (s.name != key) continue;
      if (s.required && text == kPlaceholder) {
        refuse(key, f + ": option " + std::string(s.name) + " is still the draft's placeholder " +
                        std::string(kPlaceholder) + "; " +
                        (s.missing.empty() ? std::string(s.description) : std::string(s.missing)));
        continue;
      }
      one(s, text, key);
    }
  return refusals.size() == before;
}

OptionSpec freshness_floor_option(std::string_view default_ms) {
  return OptionSpec{.name = kFreshnessFloorOption,
                    .type = OptionSpec::Type::Integer,
                    .ranges = {{0, 600000}},
                    .unit = "ms",
                    .default_value = default_ms,
                    .description =
                        "floor of the PDO freshness deadlines derived from the event timers (3 periods): a deadline "
                        "is at least this, so a controller stall shorter than the floor less one period is no "
                        "stale fault; 0: no floor; pdo_timeout_ms replaces both ("
                        "docs/reference/drivers.md#freshness-floors)"};
}

void apply_freshness_floor(Driver& driver, std::int64_t ms) {
  driver.set_freshness_floor(std::chrono::milliseconds(ms));
}

}  // namespace oegw::subdevices
