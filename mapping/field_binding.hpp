// Binding a functional element's fields to the sub-devices' signals: one entry of an FE in the
// mapping file, "field: signal" or "field: { signal: ..., options }", becomes one FieldBinding per
// FE field (config.hpp). A key names one field ("x", "buttons[3]"), a range ("indicator[1..4]")
// or a group ("buttons" = buttons[1..n]); a signal is "subdevice.signal", a range of them
// ("right_grip.buttons[1..8]"), or one bit of a bit-packed signal ("cluster.in[1].bit3"). A
// bit-packed signal (a CiA 401 byte, translate.hpp bit_width) feeding one-bit fields is expanded
// bit by bit. Every mismatch (unknown field or signal, a signal kind that does not fit the field,
// ranges of unequal length, a field fed twice, an output driven twice, options that do not apply)
// is reported through the YamlReader.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "mapping/config.hpp"
#include "mapping/yaml_reader.hpp"

namespace oegw::mapping {

// "base", "base[i]" or "base[a..b]" (1-based, a <= b), as field keys and signal names write it.
struct NameRange {
  std::string base;
  bool indexed = false;
  long first = 0, last = 0;
  [[nodiscard]] long count() const { return indexed ? last - first + 1 : 1; }
  [[nodiscard]] std::string element(long i) const {
    return indexed ? base + "[" + std::to_string(first + i) + "]" : base;
  }
  [[nodiscard]] bool range() const { return indexed && last != first; }
};
[[nodiscard]] std::optional<NameRange> parse_name_range(std::string_view s);

// Binds the field entries of the FEs of one mapping file; remembers what is fed and driven so
// far, so that a field fed twice or an output driven twice is found across entries and FEs.
class FieldBinder {
 public:
  // `subdevices_read`: false when the subdevices section is missing or no map (reported there);
  // then a signal's sub-device is not reported unknown, once per field.
  FieldBinder(YamlReader& r, const std::vector<SubdeviceConfig>& subdevices, bool subdevices_read = true)
      : r_(r), subdevices_(subdevices), subdevices_read_(subdevices_read) {}

  // Appends to fe.fields the bindings of entry `e` (not "sources" / "command_timeout_ms").
  void bind(const MapEntry& e, FunctionalElementConfig& fe);

 private:
  YamlReader& r_;
  const std::vector<SubdeviceConfig>& subdevices_;
  bool subdevices_read_;
  std::map<std::string, Location> fed_;                                  // "fe\nfield" -> where
  std::map<std::pair<std::string, std::string>, Location> outputs_fed_;  // (subdevice, signal)
};

}  // namespace oegw::mapping
