#include "mapping/field_binding.hpp"

#include <algorithm>
#include <charconv>
#include <limits>

namespace oegw::mapping {

using canopen::DataType;
using subdevices::SignalInfo;
using subdevices::SignalKind;

std::optional<NameRange> parse_name_range(std::string_view s) {
  NameRange r;
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

namespace {

// ---- Which signal kinds fit which field ------------------------------------------------------

// Inputs: a one-bit field takes a Button or Digital signal, an INTEGER16 field an Axis or Analog
// one, a 32-bit field (UNSIGNED32 encoder) a Position or Analog one. Outputs take Output signals.
bool fits(const SignalInfo& s, const FeField& f, bool input) {
  if (!input) return s.kind == SignalKind::Output;
  if (f.bit != 0xFF) return s.kind == SignalKind::Button || s.kind == SignalKind::Digital;
  if (f.type == DataType::Integer16) return s.kind == SignalKind::Axis || s.kind == SignalKind::Analog;
  return s.kind == SignalKind::Position || s.kind == SignalKind::Analog;
}

std::string accepted_kinds(const FeField& f, bool input) {
  if (!input) return "an Output signal";
  if (f.bit != 0xFF) return "a Button or Digital signal";
  if (f.type == DataType::Integer16) return "an Axis or Analog signal";
  return "a Position or Analog signal";
}

// Where a signal of this kind could go instead (`oegw check`'s hint after a kind mismatch):
// every FE kind with a field that fits it, e.g. "a Position signal fits encoder.N
// position". Read from the FE table with fits() itself, so the hint cannot name a field that
// would be refused too.
std::string kind_hint(const SignalInfo& s, std::string_view kind_text) {
  std::vector<std::string> places;
  for (const FeKind k : {FeKind::Joystick, FeKind::FootPedal, FeKind::Encoder, FeKind::Wheel, FeKind::ButtonCluster,
                         FeKind::IndicatorCluster, FeKind::Display}) {
    std::vector<std::string> names;
    for (const auto& f : fe_fields(FeId{k, 1}))
      if (fits(s, f, is_input(k))) names.push_back(f.name);
    if (names.empty()) continue;
    const auto fields = compress_names(names);
    const bool one = fields.find(", ") == std::string::npos;
    places.push_back(std::string(to_string(k)) + ".N " + (one ? fields : "(" + fields + ")"));
  }
  const std::string what = std::string(kind_text) + " signal";
  if (places.empty()) return "; no functional element field takes " + what + " (CiA 852 clause 9)";
  std::string list;
  for (std::size_t i = 0; i < places.size(); ++i)
    list += (i == 0 ? "" : i + 1 == places.size() ? " or " : ", ") + places[i];
  return "; " + what + " fits " + list;
}

std::string kind_name(SignalKind k) {
  switch (k) {
    case SignalKind::Axis: return "an Axis";
    case SignalKind::Button: return "a Button";
    case SignalKind::Position: return "a Position";
    case SignalKind::Speed: return "a Speed";
    case SignalKind::Digital: return "a Digital";
    case SignalKind::Analog: return "an Analog";
    case SignalKind::Output: return "an Output";
  }
  return "an unknown";
}

// ---- Options ---------------------------------------------------------------------------------

struct ValueRange {
  std::int64_t lo = 0, hi = 0;
};

// The options a field takes: a one-bit input has no scale; outputs no fault.
std::vector<std::string_view> allowed_options(const FeField& first, bool input) {
  if (!input) return {"signal", "scale", "offset", "invert", "clamp"};
  if (first.bit != 0xFF) return {"signal", "invert", "fault", "interlock"};
  return {"signal", "scale", "offset", "deadband", "invert", "clamp", "fault", "interlock"};
}

// The range of the FE value, for `fault` and `clamp`: 0..1 for a one-bit input, the OD type's
// for an INTEGER16/UNSIGNED32/INTEGER32 input; outputs (in signal units) only loosely bounded.
ValueRange option_range(const FeField& first, bool input) {
  if (input && first.bit != 0xFF) return {0, 1};
  if (input && first.type == DataType::Integer16) return {-32768, 32767};
  if (input && first.type == DataType::Unsigned32) return {0, std::numeric_limits<std::uint32_t>::max()};
  if (input) return {std::numeric_limits<std::int32_t>::min(), std::numeric_limits<std::int32_t>::max()};
  return {std::numeric_limits<std::int64_t>::min() / 2, std::numeric_limits<std::int64_t>::max() / 2};
}

bool read_clamp(YamlReader& r, const MapEntry& e, ValueRange range, FieldOptions& o) {
  std::optional<std::int64_t> lo, hi;
  if (e.value.IsSequence() && e.value.size() == 2) {
    lo = parse_integer(e.value[0].IsScalar() ? e.value[0].Scalar() : "");
    hi = parse_integer(e.value[1].IsScalar() ? e.value[1].Scalar() : "");
  }
  if (!lo || !hi || *lo > *hi || *lo < range.lo || *hi > range.hi) {
    r.error(e.value, "found " + node_kind(e.value) + " for clamp; expected [min, max] with integers " +
                         std::to_string(range.lo) + " <= min <= max <= " + std::to_string(range.hi));
    return false;
  }
  o.clamp = std::pair(*lo, *hi);
  return true;
}

// `out` = the value when it reads; false (error reported) otherwise.
template <typename T, typename V>
bool assign(const std::optional<V>& v, T& out) {
  if (!v) return false;
  out = *v;
  return true;
}

// The options besides `signal`; false when one of them is wrong (each error reported).
bool read_options(YamlReader& r, const std::vector<MapEntry>& os, ValueRange range, FieldOptions& o) {
  bool ok = true;
  for (const auto& e : os) {
    if (e.name == "scale") ok &= assign(r.real(e, "scale"), o.scale);
    else if (e.name == "offset") ok &= assign(r.integer(e, "offset", -2147483648LL, 2147483647LL), o.offset);
    else if (e.name == "deadband") ok &= assign(r.integer(e, "deadband", 0, 2147483647LL), o.deadband);
    else if (e.name == "fault") ok &= assign(r.integer(e, "fault", range.lo, range.hi), o.fault);
    else if (e.name == "invert") ok &= assign(r.boolean(e, "invert"), o.invert);
    else if (e.name == "interlock") ok &= assign(r.boolean(e, "interlock"), o.interlock);
    else if (e.name == "clamp") ok &= read_clamp(r, e, range, o);
  }
  return ok;
}

// ---- One entry -------------------------------------------------------------------------------

// The field key: one field, a range of them, or a group.
struct FieldKey {
  NameRange fields;
  bool group = false;  // "buttons" for buttons[1..n]: n comes from the signal
  FeField first;       // the first field named
};

// The value: the signal node and the options written with it.
struct SignalValue {
  YAML::Node node;
  FieldOptions options;
  bool options_ok = true;
  YAML::Node scale, offset;  // the values of those options when written, else undefined
};

// The signal named by the value.
struct SignalRef {
  std::string text;             // as written, "cluster.in[1].bit3"
  std::string device;           // "cluster"
  NameRange signals;            // "in[1]"
  std::optional<unsigned> bit;  // 3
};

// One signal element feeding (or fed by) one field: a whole signal or one bit of it.
struct Source {
  const SignalInfo* info;
  std::string name;  // "buttons[3]"
  std::uint8_t bit;  // 0xFF: the whole value
};
struct Sources {
  std::vector<Source> list;
  bool expanded = false;  // a bit-packed signal expanded bit by bit
};

// Splits off an explicit bit of a bit-packed signal: "in[1].bit3" -> "in[1]", 3.
std::optional<unsigned> split_bit(std::string& signal) {
  const auto b = signal.rfind(".bit");
  if (b == std::string::npos) return std::nullopt;
  const auto digits = signal.substr(b + 4);
  const auto v = parse_integer(digits);
  if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos || !v || *v >= 64)
    return std::nullopt;
  signal.resize(b);
  return static_cast<unsigned>(*v);
}

class FieldEntry {
 public:
  FieldEntry(YamlReader& r, const std::vector<SubdeviceConfig>& subdevices, bool subdevices_read, const MapEntry& e,
             FunctionalElementConfig& fe)
      : r_(r),
        subdevices_(subdevices),
        subdevices_read_(subdevices_read),
        e_(e),
        fe_(fe),
        fe_name_(mapping::fe_name(fe.id)),
        input_(fe.input()) {}

  // Binds the entry; `fed` and `outputs_fed` record every field fed and every output driven.
  void bind(std::map<std::string, Location>& fed,
            std::map<std::pair<std::string, std::string>, Location>& outputs_fed) {
    const auto key = field_key();
    if (!key) return;
    const auto value = signal_value(*key);
    if (!value) return;
    const auto sig = signal_ref(value->node);
    if (!sig) return;
    const SubdeviceConfig* dev = subdevice(*sig, value->node);
    if (!dev || dev->signals.empty()) return;  // no signals: its driver was already refused
    const auto sources = expand(*dev, *sig, key->first.bit != 0xFF, value->node);
    if (!sources) return;
    const auto fields = field_range(*key, *sig, *sources, value->node);
    if (!fields) return;
    bind_each(*fields, *sig, *sources, *value, fed, outputs_fed);
  }

 private:
  [[nodiscard]] std::string what() const { return fe_name_ + " " + e_.name; }

  // "x", "buttons" (a group: buttons[1..n]), "buttons[3]", "indicator[1..4]"; an error unless
  // the FE has every field named.
  std::optional<FieldKey> field_key() {
    const FeId id = fe_.id;
    const auto key = parse_name_range(e_.name);
    const bool group = key && !key->indexed && !find_fe_field(id, key->base) && find_fe_field(id, key->base + "[1]");
    if (!key || (!group && !find_fe_field(id, key->element(0))) ||
        (key->indexed && !find_fe_field(id, key->element(key->count() - 1)))) {
      std::vector<std::string> names, bases;
      for (const auto& f : fe_fields(id)) {
        names.push_back(f.name);
        bases.push_back(f.name.substr(0, f.name.find('[')));
      }
      r_.error(e_.key, fe_name_ + " has no field '" + e_.name + "'; expected one of " + compress_names(names) +
                           did_you_mean(key ? key->base : e_.name, bases));
      return std::nullopt;
    }
    return FieldKey{*key, group, *find_fe_field(id, group ? key->base + "[1]" : key->element(0))};
  }

  // "dev.signal" or { signal: dev.signal, options... }; the options that apply depend on the field.
  std::optional<SignalValue> signal_value(const FieldKey& key) {
    SignalValue v{e_.value, {}, true};
    if (e_.value.IsMap()) {
      const auto allowed = allowed_options(key.first, input_);
      const auto os = r_.entries(e_.value, what(), allowed, "a map with " + join(allowed));
      const auto* s = r_.find(os, "signal");
      if (!s) {
        r_.missing(e_.value, "signal", what(), "the feeding signal, e.g. right_grip.x");
        return std::nullopt;
      }
      v.node = s->value;
      v.options_ok = read_options(r_, os, option_range(key.first, input_), v.options);
      if (const auto* x = r_.find(os, "scale")) v.scale = x->value;
      if (const auto* x = r_.find(os, "offset")) v.offset = x->value;
    }
    if (!v.node.IsScalar()) {
      r_.error(v.node, "found " + node_kind(v.node) + " for " + what() +
                           "; expected a signal like right_grip.x or { signal: right_grip.x, ... }");
      return std::nullopt;
    }
    return v;
  }

  // subdevice.signal, subdevice.signal[a..b] or subdevice.signal.bitN.
  std::optional<SignalRef> signal_ref(const YAML::Node& node) {
    SignalRef s;
    s.text = node.Scalar();
    const auto dot = s.text.find('.');
    std::string signal = dot == std::string::npos ? std::string() : s.text.substr(dot + 1);
    s.bit = split_bit(signal);
    const auto range = signal.empty() ? std::nullopt : parse_name_range(signal);
    if (!range || (s.bit && range->range())) {
      r_.error(node, "found '" + s.text + "' for " + what() +
                         "; expected a signal as subdevice.signal, subdevice.signal[a..b] or subdevice.signal.bitN");
      return std::nullopt;
    }
    s.device = s.text.substr(0, dot);
    s.signals = *range;
    return s;
  }

  const SubdeviceConfig* subdevice(const SignalRef& sig, const YAML::Node& node) {
    for (const auto& d : subdevices_)
      if (d.name == sig.device) return &d;
    if (!subdevices_read_) return nullptr;  // the missing or broken section is the one error
    std::vector<std::string> names;         // a refused name (reported where it stands) is no suggestion
    for (const auto& d : subdevices_)
      if (valid_subdevice_name(d.name)) names.push_back(d.name);
    r_.error(node, "unknown sub-device '" + sig.device + "' in signal '" + sig.text + "'; expected one of " +
                       (names.empty() ? std::string("the sub-devices section's names") : join(names)) +
                       did_you_mean(sig.device, names));
    return nullptr;
  }

  void no_such_signal(const SubdeviceConfig& dev, const SignalRef& sig, const std::string& name,
                      const YAML::Node& node) {
    std::vector<std::string> names;
    for (const auto& si : dev.signals) names.push_back(si.name);
    const bool base_known = std::any_of(names.begin(), names.end(), [&](const std::string& n) {
      return sig.signals.indexed && n.rfind(sig.signals.base + "[", 0) == 0;
    });
    r_.error(node, "sub-device '" + sig.device + "' (" + dev.driver + ") has no signal '" + name +
                       "'; expected one of " + compress_names(names) + (base_known ? "" : did_you_mean(name, names)));
  }

  // The signal's elements; a bit-packed one feeds one-bit fields bit by bit.
  std::optional<Sources> expand(const SubdeviceConfig& dev, const SignalRef& sig, bool bit_field,
                                const YAML::Node& node) {
    Sources out;
    for (long i = 0; i < sig.signals.count(); ++i) {
      const auto name = sig.signals.element(i);
      const SignalInfo* info = dev.find_signal(name);
      if (!info) {
        no_such_signal(dev, sig, name, node);
        return std::nullopt;
      }
      const unsigned width = bit_width(*info);
      if (sig.bit) {
        if (width == 0 || *sig.bit >= width) {
          r_.error(node, "found bit " + std::to_string(*sig.bit) + " of '" + sig.device + "." + name + "'" +
                             (width == 0 ? ", which is not bit-packed" : "") + "; expected " +
                             (width == 0 ? std::string("the signal without .bitN")
                                         : "a bit 0.." + std::to_string(width - 1)));
          return std::nullopt;
        }
        out.list.push_back({info, name, static_cast<std::uint8_t>(*sig.bit)});
      } else if (bit_field && width > 0) {
        out.expanded = true;
        for (unsigned bit = 0; bit < width; ++bit) out.list.push_back({info, name, static_cast<std::uint8_t>(bit)});
      } else {
        out.list.push_back({info, name, 0xFF});
      }
    }
    return out;
  }

  // The fields the sources feed: a group takes as many as there are sources (at most the FE's),
  // a field or range exactly as many.
  std::optional<NameRange> field_range(const FieldKey& key, const SignalRef& sig, const Sources& sources,
                                       const YAML::Node& node) {
    const long n = static_cast<long>(sources.list.size());
    NameRange fields = key.fields;
    if (key.group) {
      if (!sig.signals.indexed && !sources.expanded) {
        r_.error(node, "found the single signal '" + sig.text + "' for the field group " + what() +
                           "; expected a signal range such as " + sig.device +
                           ".buttons[1..8], or a bit-packed signal");
        return std::nullopt;
      }
      fields.indexed = true;
      fields.first = 1;
      fields.last = n;
      if (!find_fe_field(fe_.id, fields.element(n - 1))) {
        const auto size = std::to_string(group_size(e_.name));
        r_.error(node, "signal range '" + sig.text + "' has " + std::to_string(n) +
                           (sources.expanded ? " bits" : " elements") + " but " + fe_name_ + " has " + e_.name +
                           "[1.." + size + "]; expected at most " + size + " signals");
        return std::nullopt;
      }
    } else if (fields.count() != n) {
      r_.error(node, what() + " has " + std::to_string(fields.count()) + " element" + (fields.count() == 1 ? "" : "s") +
                         " but '" + sig.text + "' has " + std::to_string(n) + (sources.expanded ? " bits" : "") +
                         "; expected ranges of equal length");
      return std::nullopt;
    }
    return fields;
  }

  // How many fields base[1], base[2], ... the FE has.
  [[nodiscard]] long group_size(const std::string& base) const {
    long n = 0;
    for (const auto& f : fe_fields(fe_.id))
      if (f.name.rfind(base + "[", 0) == 0) ++n;
    return n;
  }

  // An indicator bit driving a whole output signal sends two values, off and on, through
  // value x scale + offset (translate.hpp); one beyond the output's range would be clamped to a
  // value the file never meant (an elobau LED code 3 on a signal of 0..2), so the scale or offset
  // that puts it there is refused. A `clamp` written with them is the file's explicit wish.
  bool output_values_fit(const FeField& field, const Source& src, const SignalValue& value, const std::string& full) {
    const bool scale = value.scale.IsScalar(), offset = value.offset.IsScalar();
    if (input_ || field.bit == 0xFF || src.bit != 0xFF || (!scale && !offset)) return true;
    OutputParams p = resolve_output(*src.info, field, value.options);
    if (!value.options.clamp) {
      p.clamp_min = std::numeric_limits<std::int64_t>::min() / 2;
      p.clamp_max = std::numeric_limits<std::int64_t>::max() / 2;
    }
    const auto range = std::to_string(src.info->min) + ".." + std::to_string(src.info->max);
    for (const std::int64_t bit : {1, 0}) {
      const std::int64_t out = translate_output(p, bit);
      if (out >= src.info->min && out <= src.info->max) continue;
      const YAML::Node& at = scale ? value.scale : value.offset;
      std::string options;
      if (scale) options = "scale " + value.scale.Scalar();
      if (offset) options += (options.empty() ? "" : ", ") + std::string("offset ") + value.offset.Scalar();
      r_.error(at, options + " gives " + fe_name_ + " " + field.name + " " + (bit != 0 ? "on" : "off") + " as " +
                       std::to_string(out) + ", beyond the range " + range + " of output signal '" + full +
                       "'; expected off and on inside " + range);
      return false;
    }
    return true;
  }

  // One binding per field; stops at the first error of the entry.
  void bind_each(const NameRange& fields, const SignalRef& sig, const Sources& sources, const SignalValue& value,
                 std::map<std::string, Location>& fed,
                 std::map<std::pair<std::string, std::string>, Location>& outputs_fed) {
    const YAML::Node& node = value.node;
    for (long i = 0; i < fields.count(); ++i) {
      const auto fname = fields.element(i);
      const auto& src = sources.list[static_cast<std::size_t>(i)];
      const auto field = find_fe_field(fe_.id, fname);
      const auto full = sig.device + "." + src.name;
      if (!fits(*src.info, *field, input_)) {
        r_.error(node, "signal '" + full + "' is " + kind_name(src.info->kind) + " signal; expected " +
                           accepted_kinds(*field, input_) + " for " + fe_name_ + " " + fname +
                           (input_ ? "" : " (an output functional element)") +
                           kind_hint(*src.info, kind_name(src.info->kind)));
        return;
      }
      auto [it, fresh] = fed.emplace(fe_name_ + "\n" + fname, r_.loc(e_.key));
      if (!fresh) {
        r_.error(e_.key, fe_name_ + " " + fname + " is fed twice (first at " + it->second.line_column() +
                             "); expected each field fed by one signal");
        return;
      }
      if (!input_) {
        const auto out_name = src.bit == 0xFF ? full : full + " bit " + std::to_string(src.bit);
        auto [ot, ofresh] = outputs_fed.emplace(std::pair(sig.device, out_name), r_.loc(e_.key));
        if (!ofresh) {
          r_.error(node, "output signal '" + out_name + "' is driven twice (first at " + ot->second.line_column() +
                             "); expected each output driven by one field");
          return;
        }
      }
      if (!value.options_ok) continue;
      if (!output_values_fit(*field, src, value, full)) return;
      FieldBinding b;
      b.field = *field;
      b.subdevice = sig.device;
      b.signal = src.name;
      b.signal_bit = src.bit;
      b.signal_info = *src.info;
      b.options = value.options;
      b.where = r_.loc(e_.key);
      fe_.fields.push_back(std::move(b));
    }
  }

  YamlReader& r_;
  const std::vector<SubdeviceConfig>& subdevices_;
  const bool subdevices_read_;
  const MapEntry& e_;
  FunctionalElementConfig& fe_;
  const std::string fe_name_;
  const bool input_;
};

}  // namespace

void FieldBinder::bind(const MapEntry& e, FunctionalElementConfig& fe) {
  FieldEntry(r_, subdevices_, subdevices_read_, e, fe).bind(fed_, outputs_fed_);
}

}  // namespace oegw::mapping
