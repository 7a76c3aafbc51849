// The options of each driver as one table per family: the factory parses the mapping file's
// `options` against it (names, ranges, choices, defaults) and `oegw signals` lists it, so the
// listing cannot say other than what parsing does.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "subdevices/driver.hpp"

namespace oegw::subdevices {

struct OptionSpec {
  enum class Type : std::uint8_t {
    Integer,  // a decimal (or 0x.. hexadecimal) integer inside one of `ranges`
    Choice,   // one of `choices`, as written
    Text,     // any text the driver judges itself (a path, a list of bit numbers)
  };
  std::string_view name;
  Type type = Type::Integer;
  std::vector<std::pair<std::int64_t, std::int64_t>> ranges;  // Integer: accepted [lo, hi] ranges
  std::vector<std::string_view> choices;                      // Choice
  std::string_view unit;                                      // "ms", "percent"; "" none
  std::string_view syntax;  // Text: what it takes ("path of an EDS file"); others: derived
  // The value the parser applies before the written ones ("" = none: required, or unset).
  std::string_view default_value;
  bool required = false;
  // What the parser says when a required option is missing ("" = "option 'x' is required").
  std::string_view missing;
  // For `oegw signals` when a required option is missing: a value that builds a driver whose
  // signals are those of any valid value ("" = none: the signals depend on it, e.g. an EDS).
  std::string_view listing_value;
  std::string_view note;  // appended to a refusal: "(the document's 5 ms coding cycle)"
  std::string_view description;
  // A wrong value weakens a check the gateway makes on the operator's inputs (`oegw signals`
  // says so): the elobau channel cross-check, detent and channel-2 deadline.
  bool safety = false;

  // "integer 0..100 percent", "pass | clamp", "path of the node's EDS file".
  [[nodiscard]] std::string type_text() const;
  // "1..240, 254 or 255"
  [[nodiscard]] std::string ranges_text() const;
};

// An Integer option's text: decimal (a leading '-' allowed) or 0x.. hexadecimal, the whole text.
[[nodiscard]] std::optional<std::int64_t> parse_option_integer(const std::string& text);

// The value of one option, checked against its spec: the text as written and, for an Integer,
// its number.
struct OptionValue {
  const OptionSpec* spec;
  const std::string& text;
  std::int64_t number;
};

// One refusal of a driver's options: the option it is about (as the options name it; "" when it
// is about no single written option: the family, the node-ID, two options that disagree) and
// what is wrong, "<family>: ...".
struct OptionRefusal {
  std::string option;
  std::string message;
};
using OptionRefusals = std::vector<OptionRefusal>;
// The messages, one a line: what a factory's `std::string& error` holds.
[[nodiscard]] std::string refusal_text(const OptionRefusals& refusals);

// Checks `given` against `table` (every name known, an Integer in range, a Choice one of its
// choices, every required one present) and hands each value to `apply`: the
// table's defaults first, then the written values in order. `apply` stores it in the driver's
// options, or returns false with `error` set for a value only the driver can judge (a Text).
// Every refusal is collected, not only the first (a mapping file with two wrong options gets
// both at once, as every other mistake of the file); false when there is any. Refusals are
// "<family>: ..." and name the option.
bool parse_options(std::string_view family, const std::vector<OptionSpec>& table, const DriverOptions& given,
                   const std::function<bool(const OptionValue&, std::string& error)>& apply, OptionRefusals& refusals);

// make_driver() with every refusal of the options apart (the `std::string& error` form has their
// messages, one a line): the mapping file reports each at its option's value.
std::unique_ptr<Driver> make_driver(std::string_view family, NodeId node, FrameSink sink, const DriverOptions& options,
                                    OptionRefusals& refusals);
// A factory's `std::string& error` form from its OptionRefusals form: `make(refusals)`, and on
// refusal the messages, one a line.
template <typename Make>
std::unique_ptr<Driver> with_error_text(std::string& error, Make&& make) {
  OptionRefusals refusals;
  auto driver = make(refusals);
  if (!driver) error = refusal_text(refusals);
  return driver;
}

// What `oegw signals` shows of one family (registry.cpp): its option table and how to build a
// driver to read its signals from.
struct DriverInfo {
  std::string_view family;  // "elobau-mfg"
  std::string_view device;  // "elobau MFG 34xG / 36xG joystick grip (elobau CANopen protocol v01.21)"
  const std::vector<OptionSpec>& options;
  // How the signals depend on the options ("" = they do not), e.g. the elobau detent range.
  std::string_view signals_note;
};
[[nodiscard]] std::span<const DriverInfo> drivers();
[[nodiscard]] const DriverInfo* find_driver_info(std::string_view family);

// The signals of `info`'s driver built with `given`, each required option not given taking the
// value its table names for listings (mcb402 button_bits); nullopt (no error) when one has none
// (cia401 without an EDS), nullopt with `error` when the driver refuses `given`. `oegw signals`
// lists these, and `oegw scan`'s draft takes its FE lines from them.
[[nodiscard]] std::optional<std::vector<SignalInfo>> listing_signals(const DriverInfo& info, DriverOptions given,
                                                                     std::string& error);
// "elobau-mfg, mcb402, novotechnik-406, cia401"
[[nodiscard]] std::string driver_names();

// The option every family lists for Driver::set_freshness_floor (docs/design/fault-policy.md: the
// floor of the derived freshness deadlines), `default_ms` the family's default. Each factory
// applies it with apply_freshness_floor().
[[nodiscard]] OptionSpec freshness_floor_option(std::string_view default_ms);
inline constexpr std::string_view kFreshnessFloorOption = "freshness_floor_ms";
void apply_freshness_floor(Driver& driver, std::int64_t ms);

// The draft's placeholder for a required option (`oegw scan`): parse_options refuses it with the
// option's `missing` text, which says how to find the value.
inline constexpr std::string_view kPlaceholder = "TODO";

// The tables (in each family's file).
const std::vector<OptionSpec>& elobau_mfg_options();
const std::vector<OptionSpec>& mcb402_options();
const std::vector<OptionSpec>& novotechnik_406_options();
const std::vector<OptionSpec>& cia401_options();

}  // namespace oegw::subdevices
