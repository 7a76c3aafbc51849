// The functional-element (FE) model: the typed state of every configured FE (CiA 852 §9,
// Tables 1–7), between the translators and the three sinks.
//
//   driver → translator → FeModel → CiA 852 device (OeDevice::mirror_input, per changed slot)
//                                 → DDS | LCM (GatewayPublishing, per changed FE)
//   commands → CommandArbiter → FeModel (output FEs) and the sub-devices' outputs
//
// Each state carries its status (the worst of the signals feeding it) and its source time: the
// reception time of the frame that carried the value last written (or, for a status change the
// gateway decided itself — a time-out, a lost node — the time it decided). DDS and LCM samples
// carry that time as `timestamp_us`.
//
// No strings on the per-frame path: a mapping-file field name is resolved to a FieldRef once,
// at load (field_ref()).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "canopen/state.hpp"
#include "canopen/types.hpp"
#include "gateway/fe_samples.hpp"
#include "mapping/fe_names.hpp"

namespace oegw::gateway {

// The parts of an FE state one field writes. Bit fields (buttons, memory, switches,
// indicators) hold one bit per field; Parameters holds the 12 display parameters.
enum class FeSlot : std::uint8_t { X, Y, Z, Buttons, Memory, Position, Switches, Indicators, Parameters };
inline constexpr std::size_t kFeSlots = 9;
using SlotMask = std::uint16_t;  // bit = static_cast<unsigned>(FeSlot)
[[nodiscard]] constexpr SlotMask slot_bit(FeSlot s) { return static_cast<SlotMask>(1u << static_cast<unsigned>(s)); }

// One FE field as the model addresses it: its slot and, for a bit field, the bit (0-based:
// buttons[k] = bit k−1, memory_x/y/z = bits 0/1/2, switch[k], indicator[k]); for a display
// parameter[p], p−1. 0xFF for a whole-value slot (x, y, z, position).
struct FieldRef {
  FeSlot slot = FeSlot::X;
  std::uint8_t bit = 0xFF;
  friend bool operator==(const FieldRef&, const FieldRef&) = default;
};

// The FieldRef of the field of `fe` that the mapping file names `name` ("x", "buttons[3]",
// "switch[17]", "parameter[2]"); nullopt when `fe` has no such field (profiles/cia852/fe_table.hpp).
[[nodiscard]] std::optional<FieldRef> field_ref(mapping::FeId fe, std::string_view name);
// The mapping-file name of a field (diagnostics, logs, tests).
[[nodiscard]] std::string field_name(mapping::FeId fe, FieldRef ref);

// An FE's name in a run-time state (canopen/state.hpp): its kind and instance. A list of FEs
// follows the mapping file's order, so the reader checks each against the FE at its place
// (`what` names the list's FEs: "FEs", "outputs").
void put_fe_id(canopen::StateWriter& w, mapping::FeId fe);
[[nodiscard]] mapping::FeId get_fe_id(const canopen::StateReader& r);
void expect_fe_id(const canopen::StateReader& r, mapping::FeId here, std::string_view what);

struct FeHeader {
  FeStatus status = FeStatus::Offline;
  canopen::TimePoint source_time{};
};
struct JoystickState {
  FeHeader h;
  std::int16_t x = 0, y = 0, z = 0;  // CiA 401 INTEGER16 full scale (6401h)
  std::uint8_t buttons = 0;          // bit i = button i+1 (6000h sub 2n)
  std::uint8_t memory = 0;           // bits m-x, m-y, m-z (6000h sub 2n−1)
};
struct PedalState {
  FeHeader h;
  std::int16_t position = 0;
  std::uint8_t memory = 0;  // bit 0: m-x
};
struct WheelState {
  FeHeader h;
  std::int16_t position = 0;
};
struct EncoderState {
  FeHeader h;
  std::uint32_t position = 0;  // 6120h UNSIGNED32
};
struct ButtonClusterState {
  FeHeader h;
  std::uint64_t switches = 0;  // bit i = switch i+1
};
struct IndicatorState {
  FeHeader h;
  std::uint64_t indicators = 0;  // bit i = indicator i+1, as the outputs are driven
};
struct DisplayState {
  FeHeader h;
  std::array<std::int16_t, 12> parameters{};
};
using FeState =
    std::variant<JoystickState, PedalState, WheelState, EncoderState, ButtonClusterState, IndicatorState, DisplayState>;

class FeModel {
 public:
  // The configured FEs (duplicates and instances outside CiA 852 §9.1's ranges are dropped).
  explicit FeModel(std::vector<mapping::FeId> fes);

  [[nodiscard]] bool has(mapping::FeId fe) const { return find(fe) >= 0; }
  [[nodiscard]] const std::vector<mapping::FeId>& fes() const { return ids_; }

  // Writes one field; true if its value changed. A change stamps the FE with `source_time`,
  // hands the slot's new value to the slot observer at once (the CiA 852 device: the dictionary
  // is current in the same call) and marks the FE for the publishers (for_each_changed).
  // One-bit fields take 0/1 (any non-zero value sets the bit). Unknown FE: false.
  bool write(mapping::FeId fe, FieldRef ref, std::int64_t value, canopen::TimePoint source_time);
  // Sets the FE's status; true if it changed (the FE is then marked changed, stamped `when`).
  bool set_status(mapping::FeId fe, FeStatus status, canopen::TimePoint when);

  [[nodiscard]] std::int64_t read(mapping::FeId fe, FieldRef ref) const;
  // The whole value of a slot (a bit field as its bits, a whole value sign-extended).
  [[nodiscard]] std::int64_t slot_value(mapping::FeId fe, FeSlot slot) const;
  [[nodiscard]] FeStatus status(mapping::FeId fe) const;
  [[nodiscard]] canopen::TimePoint source_time(mapping::FeId fe) const;
  // The typed state; nullptr when `fe` is not configured or not of that kind.
  template <class S>
  [[nodiscard]] const S* get(mapping::FeId fe) const {
    const int i = find(fe);
    return i < 0 ? nullptr : std::get_if<S>(&entries_[static_cast<std::size_t>(i)].state);
  }

  // The FEs changed since the last call, in FE order, each once; clears the marks. No
  // allocation (both lists' capacity is the FE count). `f` may change the model (a consumer
  // that commands an output): those changes are reported in a further round of this call.
  template <class F>
  void for_each_changed(F&& f) {
    if (reporting_) return;  // a call from inside f: the outer call reports it
    reporting_ = true;
    while (!changed_.empty()) {
      sort_changed();
      round_.swap(changed_);  // changed_ is now empty (and keeps its capacity)
      for (const std::uint16_t i : round_) entries_[i].published_mark = false;
      for (const std::uint16_t i : round_) f(entries_[i].id);
      round_.clear();
    }
    reporting_ = false;
  }
  // Stamps the FE's source time without a change of value or status (start: the time the
  // gateway set every input to its fault value) and marks it changed.
  void stamp(mapping::FeId fe, canopen::TimePoint when);
  [[nodiscard]] bool any_changed() const { return !changed_.empty(); }

  // Called by write() for every slot whose value changed: (FE, slot, slot_value()).
  using SlotObserver = std::function<void(mapping::FeId, FeSlot, std::int64_t)>;
  void on_slot_change(SlotObserver cb) { on_slot_ = std::move(cb); }

  // Run-time state (canopen/state.hpp): each FE's values, status and source time, and whether
  // the publishers are still owed it. Not while for_each_changed reports. The import calls no
  // observer: the dictionary the slots mirror carries its own state.
  void export_state(canopen::StateWriter& w) const;
  void import_state(const canopen::StateReader& r);

 private:
  struct Entry {
    mapping::FeId id;
    FeState state;
    bool published_mark = false;
  };
  [[nodiscard]] int find(mapping::FeId fe) const;
  void mark(std::size_t i);
  void sort_changed();

  std::vector<mapping::FeId> ids_;
  std::vector<Entry> entries_;
  std::vector<std::uint16_t> changed_;
  std::vector<std::uint16_t> round_;  // the round for_each_changed is reporting
  bool reporting_ = false;
  SlotObserver on_slot_;
  // kind × instance (1..16) → index in entries_, or −1.
  std::array<std::array<std::int16_t, 17>, 7> index_{};
};

}  // namespace oegw::gateway
