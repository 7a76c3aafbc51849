// Downstream signal -> functional-element (FE) value, and FE value -> sub-device output.
// Pure functions plus one small stateful FieldTranslator per FE field (the neutral interlock).
// No I/O, no clock: the caller feeds SignalValues as the drivers report them.
//
// Conventions (docs/reference/mapping-file.md#translation-translatehpp):
//  * Input pipeline, in this order: invert (mirror about the signal's neutral) -> deadband (in
//    signal units: |v - neutral| <= deadband gives neutral) -> scale (round to nearest) ->
//    offset -> clamp (in FE units).
//  * Default scale for an INTEGER16 FE field: a "percent" signal (elobau S8) has 100 % = full
//    scale = 32767, so the ±110 % detent becomes ±36044 and is clamped to ±32767; any other
//    signal whose range fits INTEGER16 (MCB-402 raw16, generic 6401h) passes unscaled; a wider
//    signal is scaled so that max(|min|, |max|) becomes 32767.
//  * Default clamp for an INTEGER16 field: ±32767 when the value is scaled (symmetric full
//    scale), the INTEGER16 range -32768..32767 when it passes unscaled. UNSIGNED32 (encoder
//    6120h) passes unscaled; a signal outside 0..FFFFFFFFh (a signed INTEGER32 position) keeps
//    its 32-bit pattern (two's complement), so a wrapping counter keeps wrapping.
//  * One-bit fields (buttons, memory bits, switches): 1 when the (inverted) signal is non-zero.
//    A bit-packed signal (a CiA 401 input byte: Digital, 0..2^n−1, n ≥ 2; see bit_width()) feeds
//    one-bit fields bit by bit: field k takes bit `signal_bit` of the value.
//  * Fault value: what the field holds while its signal is not Valid; the FE neutral (the
//    signal's neutral translated) unless the file says otherwise.
//  * Neutral interlock (axes: Axis/Analog signals into INTEGER16 fields): after any non-Valid
//    status (and at start), the field stays at neutral until the input has been seen inside its
//    deadband around neutral; then it follows again. Set `interlock: false` to disable.
//  * Outputs (indicator bits, display parameters -> output signals): value * scale + offset,
//    a bit inverted when `invert`, then clamped to the output signal's range (or `clamp`). An
//    indicator bit driving one bit of a bit-packed output (a CiA 401 output byte) sets or clears
//    that bit of the output's current value (apply_output()).
#pragma once

#include <cstdint>
#include <optional>
#include <utility>

#include "canopen/state.hpp"
#include "mapping/fe_names.hpp"
#include "subdevices/signal.hpp"

namespace oegw::mapping {

// Per-field options as written in the mapping file (unset = default, see above).
struct FieldOptions {
  std::optional<double> scale;
  std::int64_t offset = 0;
  std::int64_t deadband = 0;  // signal units
  bool invert = false;
  std::optional<std::pair<std::int64_t, std::int64_t>> clamp;  // FE units (outputs: signal units)
  std::optional<std::int64_t> fault;                           // FE units
  std::optional<bool> interlock;
};

// The resolved parameters of one input field: everything FieldTranslator needs.
struct InputParams {
  enum class Mode : std::uint8_t { Value, Bit, Wrap32 };  // Wrap32: the low 32 bits, UNSIGNED32
  Mode mode = Mode::Value;
  double scale = 1.0;
  std::int64_t offset = 0;
  std::int64_t deadband = 0;
  bool invert = false;
  std::int64_t signal_neutral = 0;
  std::int64_t clamp_min = -32768;
  std::int64_t clamp_max = 32767;
  std::int64_t neutral = 0;  // the FE value of the signal's neutral
  std::int64_t fault = 0;    // while not Valid
  bool interlock = false;
  std::uint8_t signal_bit = 0xFF;  // Bit mode on a bit-packed signal: the bit taken; 0xFF = value != 0
};

// The number of bits of a bit-packed signal (Digital, or an Output in "bits", with range
// 0..2^n−1, n ≥ 2: a CiA 401 input/output byte), else 0. Such a signal feeds n one-bit fields.
[[nodiscard]] unsigned bit_width(const subdevices::SignalInfo& signal);

// Defaults for `signal` feeding `field`, overridden by `options`.
[[nodiscard]] InputParams resolve_input(const subdevices::SignalInfo& signal, const FeField& field,
                                        const FieldOptions& options, std::uint8_t signal_bit = 0xFF);
// The default scale alone (1.0 when the value passes unscaled).
[[nodiscard]] double default_scale(const subdevices::SignalInfo& signal, const FeField& field);

// A Valid raw signal value -> the FE value (pure; no interlock, no fault).
[[nodiscard]] std::int64_t translate_input(const InputParams& p, std::int64_t raw);
// True when `raw` is inside the deadband around the signal's neutral (the interlock's release).
[[nodiscard]] bool in_zero_position(const InputParams& p, std::int64_t raw);

// One FE input field fed by one signal: fault value and neutral interlock.
class FieldTranslator {
 public:
  explicit FieldTranslator(InputParams p) : p_(p), value_(p.fault), locked_(p.interlock) {}
  // Feeds the signal's latest value/status; returns the FE value.
  std::int64_t update(const subdevices::SignalValue& v);
  [[nodiscard]] std::int64_t value() const { return value_; }
  // True while the interlock holds the field at neutral (or, not Valid, at its fault value).
  [[nodiscard]] bool interlocked() const { return locked_; }
  [[nodiscard]] const InputParams& params() const { return p_; }
  // Run-time state (canopen/state.hpp): the value and the interlock. The import refuses a value
  // update() could not have given these parameters.
  void export_state(canopen::StateWriter& w) const;
  void import_state(const canopen::StateReader& r);

 private:
  InputParams p_;
  std::int64_t value_;
  bool locked_;  // an interlocked field starts locked: the signal starts Offline
};

// The resolved parameters of one output field (FE -> sub-device output signal).
struct OutputParams {
  bool bit = false;
  double scale = 1.0;
  std::int64_t offset = 0;
  bool invert = false;
  std::int64_t clamp_min = 0;
  std::int64_t clamp_max = 0;
  std::uint8_t signal_bit = 0xFF;  // the bit of a bit-packed output this field drives; 0xFF = whole value
};
[[nodiscard]] OutputParams resolve_output(const subdevices::SignalInfo& signal, const FeField& field,
                                          const FieldOptions& options, std::uint8_t signal_bit = 0xFF);
// The FE value (an indicator bit 0/1, a display parameter) -> the output signal's value.
[[nodiscard]] std::int64_t translate_output(const OutputParams& p, std::int64_t fe_value);
// The output signal's new value given its `current` one: translate_output() for a whole-value
// field; for a field driving one bit of a bit-packed output, `current` with that bit set to the
// (inverted) FE bit.
[[nodiscard]] std::int64_t apply_output(const OutputParams& p, std::int64_t fe_value, std::int64_t current);

}  // namespace oegw::mapping
