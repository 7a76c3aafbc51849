#include "mapping/translate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

namespace oegw::mapping {

using canopen::DataType;
using subdevices::SignalInfo;
using subdevices::SignalKind;
using subdevices::SignalStatus;

namespace {

constexpr std::int64_t kI16Min = std::numeric_limits<std::int16_t>::min();
constexpr std::int64_t kI16Max = std::numeric_limits<std::int16_t>::max();
constexpr std::int64_t kI32Min = std::numeric_limits<std::int32_t>::min();
constexpr std::int64_t kI32Max = std::numeric_limits<std::int32_t>::max();
constexpr std::int64_t kU32Max = std::numeric_limits<std::uint32_t>::max();

bool one_bit(const FeField& f) { return f.bit != 0xFF; }

// The low 32 bits as UNSIGNED32 (two's complement of a negative value).
std::int64_t wrap32(std::int64_t v) { return v & 0xFFFFFFFF; }

}  // namespace

double default_scale(const SignalInfo& signal, const FeField& field) {
  if (one_bit(field) || field.type != DataType::Integer16) return 1.0;
  if (signal.unit == "percent") return static_cast<double>(kI16Max) / 100.0;
  if (signal.min >= kI16Min && signal.max <= kI16Max) return 1.0;
  const auto span = std::max(std::llabs(signal.min), std::llabs(signal.max));
  return static_cast<double>(kI16Max) / static_cast<double>(span);
}

unsigned bit_width(const SignalInfo& signal) {
  const bool packable =
      signal.kind == SignalKind::Digital || (signal.kind == SignalKind::Output && signal.unit == "bits");
  if (!packable || signal.min != 0 || signal.max < 3 || signal.max > 0xFFFFFFFFLL) return 0;
  const auto m = static_cast<std::uint64_t>(signal.max);
  if ((m & (m + 1)) != 0) return 0;  // not 2^n - 1
  unsigned n = 0;
  for (auto v = m; v != 0; v >>= 1) ++n;
  return n;
}

InputParams resolve_input(const SignalInfo& signal, const FeField& field, const FieldOptions& o,
                          std::uint8_t signal_bit) {
  InputParams p;
  p.signal_bit = signal_bit;
  p.signal_neutral = signal.neutral;
  p.offset = o.offset;
  p.deadband = o.deadband < 0 ? 0 : o.deadband;
  p.invert = o.invert;
  if (one_bit(field)) {
    p.mode = InputParams::Mode::Bit;
    p.clamp_min = 0;
    p.clamp_max = 1;
    p.neutral = 0;
    p.fault = o.fault.value_or(0);
    p.interlock = o.interlock.value_or(false);
    return p;
  }
  const double def = default_scale(signal, field);
  p.scale = o.scale.value_or(def);
  if (field.type == DataType::Integer16) {
    const bool scaled = p.scale != 1.0;
    p.clamp_min = scaled ? -kI16Max : kI16Min;
    p.clamp_max = kI16Max;
  } else if (field.type == DataType::Unsigned32) {
    p.clamp_min = 0;
    p.clamp_max = kU32Max;
    // A signal outside 0..FFFFFFFFh (a signed INTEGER32 position, a wider counter) keeps its
    // 32-bit pattern unless scale or clamp says otherwise.
    if (!o.scale && !o.clamp && (signal.min < 0 || signal.max > kU32Max)) p.mode = InputParams::Mode::Wrap32;
  } else {
    p.clamp_min = kI32Min;
    p.clamp_max = kI32Max;
  }
  if (o.clamp) {
    p.clamp_min = o.clamp->first;
    p.clamp_max = o.clamp->second;
  }
  p.interlock = o.interlock.value_or(field.type == DataType::Integer16 &&
                                     (signal.kind == SignalKind::Axis || signal.kind == SignalKind::Analog));
  // The neutral in FE units: the signal's neutral through the same pipeline (no deadband needed).
  p.neutral = translate_input(p, signal.neutral);
  p.fault = o.fault.value_or(p.neutral);
  return p;
}

bool in_zero_position(const InputParams& p, std::int64_t raw) {
  if (p.mode == InputParams::Mode::Bit && p.signal_bit != 0xFF) return ((raw >> p.signal_bit) & 1) == 0;
  const auto d = raw - p.signal_neutral;
  return (d < 0 ? -d : d) <= p.deadband;
}

std::int64_t translate_input(const InputParams& p, std::int64_t raw) {
  std::int64_t v = raw;
  if (p.mode == InputParams::Mode::Bit) {
    bool on = p.signal_bit == 0xFF ? v != 0 : ((v >> p.signal_bit) & 1) != 0;
    if (p.invert) on = !on;
    return on ? 1 : 0;
  }
  if (p.invert) v = 2 * p.signal_neutral - v;
  if (in_zero_position(p, v)) v = p.signal_neutral;
  if (p.mode == InputParams::Mode::Wrap32) return wrap32(v + p.offset);
  std::int64_t out = p.scale == 1.0 ? v : std::llround(static_cast<double>(v) * p.scale);
  out += p.offset;
  return std::clamp(out, p.clamp_min, std::max(p.clamp_min, p.clamp_max));
}

std::int64_t FieldTranslator::update(const subdevices::SignalValue& v) {
  if (v.status != SignalStatus::Valid) {
    locked_ = p_.interlock;
    value_ = p_.fault;
    return value_;
  }
  if (locked_) {
    if (!p_.interlock || in_zero_position(p_, v.value)) {
      locked_ = false;
    } else {
      value_ = p_.neutral;
      return value_;
    }
  }
  value_ = translate_input(p_, v.value);
  return value_;
}

void FieldTranslator::export_state(canopen::StateWriter& w) const {
  w.put("value", value_);
  w.put("locked", locked_);
}

void FieldTranslator::import_state(const canopen::StateReader& r) {
  const std::int64_t value = r.integer("value");
  const bool locked = r.get<bool>("locked");
  // update(): only an interlocked field locks, and a locked one holds its fault value or neutral.
  if (locked && !p_.interlock) r.fail("locked", "is set on a field without the neutral interlock");
  bool possible = value == p_.fault || value == p_.neutral;
  if (!possible && !locked) {
    switch (p_.mode) {
      case InputParams::Mode::Bit: possible = value == 0 || value == 1; break;
      case InputParams::Mode::Wrap32: possible = value >= 0 && value <= 0xFFFFFFFF; break;
      case InputParams::Mode::Value:
        possible = value >= p_.clamp_min && value <= std::max(p_.clamp_min, p_.clamp_max);
        break;
    }
  }
  if (!possible) r.fail("value", "is no value this field's translation gives");
  value_ = value;
  locked_ = locked;
}

OutputParams resolve_output(const SignalInfo& signal, const FeField& field, const FieldOptions& o,
                            std::uint8_t signal_bit) {
  OutputParams p;
  p.signal_bit = signal_bit;
  p.bit = one_bit(field);
  p.scale = o.scale.value_or(1.0);
  p.offset = o.offset;
  p.invert = o.invert;
  p.clamp_min = o.clamp ? o.clamp->first : signal.min;
  p.clamp_max = o.clamp ? o.clamp->second : signal.max;
  return p;
}

std::int64_t translate_output(const OutputParams& p, std::int64_t fe_value) {
  std::int64_t v = fe_value;
  if (p.bit) {
    v = v != 0 ? 1 : 0;
    if (p.invert) v = 1 - v;
  } else if (p.invert) {
    v = -v;
  }
  std::int64_t out = p.scale == 1.0 ? v : std::llround(static_cast<double>(v) * p.scale);
  out += p.offset;
  return std::clamp(out, p.clamp_min, std::max(p.clamp_min, p.clamp_max));
}

std::int64_t apply_output(const OutputParams& p, std::int64_t fe_value, std::int64_t current) {
  if (p.signal_bit == 0xFF) return translate_output(p, fe_value);
  bool on = fe_value != 0;
  if (p.invert) on = !on;
  const auto mask = std::int64_t{1} << p.signal_bit;
  return on ? (current | mask) : (current & ~mask);
}

}  // namespace oegw::mapping
