#include "gateway/fe_model.hpp"

#include <algorithm>
#include <charconv>
#include <stdexcept>

#include <fmt/format.h>

namespace oegw::gateway {

using mapping::FeId;
using mapping::FeKind;

namespace {

// "buttons[3]" with base "buttons" → 3; 0 when `name` is not base[k].
unsigned indexed(std::string_view name, std::string_view base) {
  if (name.size() < base.size() + 3 || name.substr(0, base.size()) != base || name[base.size()] != '[' ||
      name.back() != ']')
    return 0;
  unsigned k = 0;
  const auto digits = name.substr(base.size() + 1, name.size() - base.size() - 2);
  const auto [p, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), k);
  return ec == std::errc{} && p == digits.data() + digits.size() ? k : 0;
}

std::optional<FieldRef> bit_of(std::string_view name, std::string_view base, FeSlot slot, unsigned count) {
  const unsigned k = indexed(name, base);
  if (k < 1 || k > count) return std::nullopt;
  return FieldRef{slot, static_cast<std::uint8_t>(k - 1)};
}

template <class T>
bool assign(T& dst, std::int64_t v) {
  const auto n = static_cast<T>(v);
  if (dst == n) return false;
  dst = n;
  return true;
}

template <class T>
bool assign_bit(T& dst, std::uint8_t bit, std::int64_t v) {
  const T mask = static_cast<T>(T{1} << bit);
  const T n = static_cast<T>(v != 0 ? (dst | mask) : (dst & static_cast<T>(~mask)));
  if (dst == n) return false;
  dst = n;
  return true;
}

// Writes `ref` of one typed state; false when the value is unchanged or the state has no such slot.
bool write_slot(JoystickState& s, FieldRef r, std::int64_t v) {
  switch (r.slot) {
    case FeSlot::X: return assign(s.x, v);
    case FeSlot::Y: return assign(s.y, v);
    case FeSlot::Z: return assign(s.z, v);
    case FeSlot::Buttons: return r.bit < 8 && assign_bit(s.buttons, r.bit, v);
    case FeSlot::Memory: return r.bit < 3 && assign_bit(s.memory, r.bit, v);
    default: return false;
  }
}
bool write_slot(PedalState& s, FieldRef r, std::int64_t v) {
  if (r.slot == FeSlot::Position) return assign(s.position, v);
  return r.slot == FeSlot::Memory && r.bit == 0 && assign_bit(s.memory, 0, v);
}
bool write_slot(WheelState& s, FieldRef r, std::int64_t v) {
  return r.slot == FeSlot::Position && assign(s.position, v);
}
bool write_slot(EncoderState& s, FieldRef r, std::int64_t v) {
  return r.slot == FeSlot::Position && assign(s.position, v);
}
bool write_slot(ButtonClusterState& s, FieldRef r, std::int64_t v) {
  return r.slot == FeSlot::Switches && r.bit < 64 && assign_bit(s.switches, r.bit, v);
}
bool write_slot(IndicatorState& s, FieldRef r, std::int64_t v) {
  return r.slot == FeSlot::Indicators && r.bit < 64 && assign_bit(s.indicators, r.bit, v);
}
bool write_slot(DisplayState& s, FieldRef r, std::int64_t v) {
  return r.slot == FeSlot::Parameters && r.bit < 12 && assign(s.parameters[r.bit], v);
}

std::int64_t slot_of(const JoystickState& s, FeSlot slot) {
  switch (slot) {
    case FeSlot::X: return s.x;
    case FeSlot::Y: return s.y;
    case FeSlot::Z: return s.z;
    case FeSlot::Buttons: return s.buttons;
    case FeSlot::Memory: return s.memory;
    default: return 0;
  }
}
std::int64_t slot_of(const PedalState& s, FeSlot slot) {
  return slot == FeSlot::Position ? s.position : slot == FeSlot::Memory ? s.memory : 0;
}
std::int64_t slot_of(const WheelState& s, FeSlot slot) { return slot == FeSlot::Position ? s.position : 0; }
std::int64_t slot_of(const EncoderState& s, FeSlot slot) { return slot == FeSlot::Position ? s.position : 0; }
std::int64_t slot_of(const ButtonClusterState& s, FeSlot slot) {
  return slot == FeSlot::Switches ? static_cast<std::int64_t>(s.switches) : 0;
}
std::int64_t slot_of(const IndicatorState& s, FeSlot slot) {
  return slot == FeSlot::Indicators ? static_cast<std::int64_t>(s.indicators) : 0;
}
std::int64_t slot_of(const DisplayState&, FeSlot) { return 0; }  // per parameter: read()

FeState initial_state(FeKind k) {
  switch (k) {
    case FeKind::Joystick: return JoystickState{};
    case FeKind::FootPedal: return PedalState{};
    case FeKind::Wheel: return WheelState{};
    case FeKind::Encoder: return EncoderState{};
    case FeKind::ButtonCluster: return ButtonClusterState{};
    case FeKind::IndicatorCluster: return IndicatorState{};
    case FeKind::Display: return DisplayState{};
  }
  return JoystickState{};
}

FeHeader& header(FeState& s) {
  return std::visit([](auto& st) -> FeHeader& { return st.h; }, s);
}
const FeHeader& header(const FeState& s) {
  return std::visit([](const auto& st) -> const FeHeader& { return st.h; }, s);
}

// Each kind's values under their slots' names, and back (a value outside its type refused).
void put_values(canopen::StateWriter& w, const JoystickState& s) {
  w.put("x", s.x);
  w.put("y", s.y);
  w.put("z", s.z);
  w.put("buttons", s.buttons);
  w.put("memory", s.memory);
}
void put_values(canopen::StateWriter& w, const PedalState& s) {
  w.put("position", s.position);
  w.put("memory", s.memory);
}
void put_values(canopen::StateWriter& w, const WheelState& s) { w.put("position", s.position); }
void put_values(canopen::StateWriter& w, const EncoderState& s) { w.put("position", s.position); }
void put_values(canopen::StateWriter& w, const ButtonClusterState& s) { w.put("switches", s.switches); }
void put_values(canopen::StateWriter& w, const IndicatorState& s) { w.put("indicators", s.indicators); }
void put_values(canopen::StateWriter& w, const DisplayState& s) {
  w.put_list("parameters", s.parameters.size(), [&](std::size_t p) { w.put("value", s.parameters[p]); });
}

// A bit field's value with no bit above `bits` (memory_x/y/z, a pedal's memory_x).
std::uint8_t bits(const canopen::StateReader& r, std::string_view key, unsigned count) {
  const auto v = r.get<std::uint8_t>(key);
  if ((v >> count) != 0) r.fail(key, "sets a bit the FE has no field for");
  return v;
}
void get_values(const canopen::StateReader& r, JoystickState& s) {
  s.x = r.get<std::int16_t>("x");
  s.y = r.get<std::int16_t>("y");
  s.z = r.get<std::int16_t>("z");
  s.buttons = r.get<std::uint8_t>("buttons");
  s.memory = bits(r, "memory", 3);
}
void get_values(const canopen::StateReader& r, PedalState& s) {
  s.position = r.get<std::int16_t>("position");
  s.memory = bits(r, "memory", 1);
}
void get_values(const canopen::StateReader& r, WheelState& s) { s.position = r.get<std::int16_t>("position"); }
void get_values(const canopen::StateReader& r, EncoderState& s) { s.position = r.get<std::uint32_t>("position"); }
void get_values(const canopen::StateReader& r, ButtonClusterState& s) { s.switches = r.get<std::uint64_t>("switches"); }
void get_values(const canopen::StateReader& r, IndicatorState& s) { s.indicators = r.get<std::uint64_t>("indicators"); }
void get_values(const canopen::StateReader& r, DisplayState& s) {
  std::size_t p = 0;
  r.read_list("parameters", s.parameters.size(),
              [&](const canopen::StateReader& item) { s.parameters[p++] = item.get<std::int16_t>("value"); });
  if (p != s.parameters.size()) r.fail("parameters.count", "is not 12 (CiA 852 §9.8)");
}

}  // namespace

std::optional<FieldRef> field_ref(FeId fe, std::string_view name) {
  switch (fe.kind) {
    case FeKind::Joystick:
      if (name == "x") return FieldRef{FeSlot::X};
      if (name == "y") return FieldRef{FeSlot::Y};
      if (name == "z") return FieldRef{FeSlot::Z};
      if (name == "memory_x") return FieldRef{FeSlot::Memory, 0};
      if (name == "memory_y") return FieldRef{FeSlot::Memory, 1};
      if (name == "memory_z") return FieldRef{FeSlot::Memory, 2};
      return bit_of(name, "buttons", FeSlot::Buttons, 8);
    case FeKind::FootPedal:
      if (name == "position") return FieldRef{FeSlot::Position};
      if (name == "memory_x") return FieldRef{FeSlot::Memory, 0};
      return std::nullopt;
    case FeKind::Encoder:
    case FeKind::Wheel:
      if (name == "position") return FieldRef{FeSlot::Position};
      return std::nullopt;
    case FeKind::ButtonCluster: return bit_of(name, "switch", FeSlot::Switches, 64);
    case FeKind::IndicatorCluster: return bit_of(name, "indicator", FeSlot::Indicators, 64);
    case FeKind::Display: return bit_of(name, "parameter", FeSlot::Parameters, 12);
  }
  return std::nullopt;
}

std::string field_name(FeId fe, FieldRef r) {
  const unsigned k = static_cast<unsigned>(r.bit) + 1;
  switch (r.slot) {
    case FeSlot::X: return "x";
    case FeSlot::Y: return "y";
    case FeSlot::Z: return "z";
    case FeSlot::Position: return "position";
    case FeSlot::Memory: return r.bit == 0 ? "memory_x" : r.bit == 1 ? "memory_y" : "memory_z";
    case FeSlot::Buttons: return fmt::format("buttons[{}]", k);
    case FeSlot::Switches: return fmt::format("switch[{}]", k);
    case FeSlot::Indicators: return fmt::format("indicator[{}]", k);
    case FeSlot::Parameters: return fmt::format("parameter[{}]", k);
  }
  (void)fe;
  return "?";
}

void put_fe_id(canopen::StateWriter& w, FeId fe) {
  w.put("kind", fe.kind);
  w.put("instance", fe.instance);
}

FeId get_fe_id(const canopen::StateReader& r) { return FeId{r.get<FeKind>("kind"), r.get<std::uint8_t>("instance")}; }

void expect_fe_id(const canopen::StateReader& r, FeId here, std::string_view what) {
  if (get_fe_id(r) != here) {
    r.fail("kind",
           fmt::format("differs: the state is of another mapping file's {} (here {})", what, mapping::fe_name(here)));
  }
}

FeModel::FeModel(std::vector<FeId> fes) {
  for (auto& row : index_) row.fill(-1);
  std::erase_if(fes, [](const FeId& f) { return f.instance < 1 || f.instance > mapping::max_instances(f.kind); });
  std::sort(fes.begin(), fes.end());
  fes.erase(std::unique(fes.begin(), fes.end()), fes.end());
  ids_ = fes;
  for (const FeId& f : ids_) {
    index_[static_cast<std::size_t>(f.kind)][f.instance] = static_cast<std::int16_t>(entries_.size());
    entries_.push_back({f, initial_state(f.kind)});
  }
  changed_.reserve(entries_.size());
  round_.reserve(entries_.size());
}

void FeModel::stamp(FeId fe, canopen::TimePoint when) {
  const int i = find(fe);
  if (i < 0) return;
  header(entries_[static_cast<std::size_t>(i)].state).source_time = when;
  mark(static_cast<std::size_t>(i));
}

void FeModel::export_state(canopen::StateWriter& w) const {
  if (reporting_) throw std::logic_error("FeModel::export_state while the changes are reported");
  w.put_list("fe", entries_.size(), [&](std::size_t i) {
    const Entry& e = entries_[i];
    put_fe_id(w, e.id);
    w.put("status", header(e.state).status);
    w.put("at", header(e.state).source_time);
    if (e.published_mark) w.put("owed", true);
    std::visit([&](const auto& s) { put_values(w, s); }, e.state);
  });
}

void FeModel::import_state(const canopen::StateReader& r) {
  if (reporting_) throw std::logic_error("FeModel::import_state while the changes are reported");
  std::vector<Entry> entries = entries_;
  std::size_t i = 0;
  r.read_list("fe", entries.size(), [&](const canopen::StateReader& item) {
    Entry& e = entries[i++];
    expect_fe_id(item, e.id, "FEs");
    const auto status = item.get<std::uint8_t>("status");
    if (status > static_cast<std::uint8_t>(FeStatus::Offline)) item.fail("status", "is no FE status");
    header(e.state) = FeHeader{static_cast<FeStatus>(status), item.time("at")};
    e.published_mark = item.get_or("owed", false);
    std::visit([&](auto& s) { get_values(item, s); }, e.state);
  });
  if (i != entries.size())
    r.fail("fe.count", "differs from the mapping file's " + std::to_string(entries.size()) + " FEs");
  entries_ = std::move(entries);
  changed_.clear();
  for (std::size_t k = 0; k < entries_.size(); ++k)
    if (entries_[k].published_mark) changed_.push_back(static_cast<std::uint16_t>(k));
}

int FeModel::find(FeId fe) const {
  const auto k = static_cast<std::size_t>(fe.kind);
  if (k >= index_.size() || fe.instance >= index_[k].size()) return -1;
  return index_[k][fe.instance];
}

void FeModel::mark(std::size_t i) {
  if (entries_[i].published_mark) return;
  entries_[i].published_mark = true;
  changed_.push_back(static_cast<std::uint16_t>(i));  // capacity reserved: no allocation
}

void FeModel::sort_changed() { std::sort(changed_.begin(), changed_.end()); }  // entries_ is in FE order

bool FeModel::write(FeId fe, FieldRef ref, std::int64_t value, canopen::TimePoint source_time) {
  const int i = find(fe);
  if (i < 0) return false;
  Entry& e = entries_[static_cast<std::size_t>(i)];
  const bool changed = std::visit([&](auto& s) { return write_slot(s, ref, value); }, e.state);
  if (!changed) return false;
  header(e.state).source_time = source_time;
  mark(static_cast<std::size_t>(i));
  if (on_slot_) on_slot_(fe, ref.slot, ref.slot == FeSlot::Parameters ? read(fe, ref) : slot_value(fe, ref.slot));
  return true;
}

bool FeModel::set_status(FeId fe, FeStatus status, canopen::TimePoint when) {
  const int i = find(fe);
  if (i < 0) return false;
  FeHeader& h = header(entries_[static_cast<std::size_t>(i)].state);
  if (h.status == status) return false;
  h.status = status;
  h.source_time = when;
  mark(static_cast<std::size_t>(i));
  return true;
}

std::int64_t FeModel::slot_value(FeId fe, FeSlot slot) const {
  const int i = find(fe);
  if (i < 0) return 0;
  return std::visit([slot](const auto& s) { return slot_of(s, slot); }, entries_[static_cast<std::size_t>(i)].state);
}

std::int64_t FeModel::read(FeId fe, FieldRef ref) const {
  if (ref.slot == FeSlot::Parameters) {
    const auto* d = get<DisplayState>(fe);
    return d != nullptr && ref.bit < d->parameters.size() ? d->parameters[ref.bit] : 0;
  }
  const std::int64_t v = slot_value(fe, ref.slot);
  if (ref.bit == 0xFF) return v;
  return (static_cast<std::uint64_t>(v) >> ref.bit) & 1u;
}

FeStatus FeModel::status(FeId fe) const {
  const int i = find(fe);
  return i < 0 ? FeStatus::Offline : header(entries_[static_cast<std::size_t>(i)].state).status;
}

canopen::TimePoint FeModel::source_time(FeId fe) const {
  const int i = find(fe);
  return i < 0 ? canopen::TimePoint{} : header(entries_[static_cast<std::size_t>(i)].state).source_time;
}

}  // namespace oegw::gateway
