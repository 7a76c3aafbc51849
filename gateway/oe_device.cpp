#include "gateway/oe_device.hpp"

#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>

#include "profiles/cia401/objects.hpp"

namespace oegw::gateway {

using canopen::Access;
using canopen::DataType;
using canopen::NmtState;
using canopen::ObjectDictionary;
using canopen::Origin;
using canopen::SdoAbortCode;
using canopen::TimePoint;
using mapping::FeId;
using mapping::FeKind;

namespace {

// An integer entry's value in its own signedness.
std::int64_t entry_value(const canopen::SubObject& s) {
  if (canopen::is_signed_integer(s.type)) return canopen::decode_signed(s.value);
  return static_cast<std::int64_t>(canopen::decode_unsigned(s.value));
}

}  // namespace

OeDevice::OeDevice(OeDeviceConfig cfg, canopen::FrameSink sink) : cfg_(std::move(cfg)), sink_(std::move(sink)) {
  // A FE listed twice counts once; an instance outside §9.1's ranges is dropped.
  std::erase_if(cfg_.fes, [](const FeId& f) { return f.instance < 1 || f.instance > mapping::max_instances(f.kind); });
  std::sort(cfg_.fes.begin(), cfg_.fes.end());
  cfg_.fes.erase(std::unique(cfg_.fes.begin(), cfg_.fes.end()), cfg_.fes.end());
  const canopen::NodeConfig nc = cia852::build_dictionary(cfg_, od_);
  for (const FeId& fe : cfg_.fes) {
    if (mapping::is_input(fe.kind)) continue;
    for (const auto& f : mapping::fe_fields(fe))
      outputs_[static_cast<std::uint32_t>(f.index) << 8 | f.sub].push_back({fe, *field_ref(fe, f.name), f.bit});
  }
  if (!outputs_.empty()) {
    // Annex A: 1028h mandatory with outputs; sub n = 80h + n, the device's own EMCY not consumed.
    canopen::Object& o = od_.add_array(0x1028, "Emergency consumer object", DataType::Unsigned32, Access::ReadWrite,
                                       127, canopen::encode<std::uint32_t>(0));
    for (auto& [si, so] : o.subs()) {
      if (si == 0) continue;
      std::uint32_t v = 0x80u + si;
      if (si == cfg_.node_id.value()) v |= 0x80000000u;
      so.default_value = canopen::encode<std::uint32_t>(v);
      so.value = so.default_value;
    }
    emcy_consumer_ = std::make_unique<canopen::EmcyConsumer>(od_, [this](const canopen::EmcyMessage& m, TimePoint t) {
      if (on_emcy_) on_emcy_(m, t);
    });
  }
  node_ = std::make_unique<canopen::Node>(od_, nc, [this](const canopen::CanFrame& f) {
    if (sent_) sent_(f);
    sink_(f);
  });
  for (const auto& [key, refs] : outputs_) {
    const canopen::SubObject* s = od_.find(static_cast<std::uint16_t>(key >> 8), static_cast<std::uint8_t>(key));
    output_shadow_[key] = s ? entry_value(*s) : 0;
  }
  watch_host_commands();
  index_inputs();
  node_->on_state_change = [this](NmtState s) { handle_state(s); };
  // CiA 401 6206h/6207h on a host heartbeat loss, in the call that notices it: the timer, an
  // upstream frame (also a late heartbeat, which reports the time-out it overran), or the TPDOs
  // a downstream frame sends.
  node_->on_heartbeat_timeout = [this](canopen::NodeId) { host_heartbeat_lost(now_); };
  node_->on_bit_timing_switch = [this](std::uint8_t index) {
    const auto kbit = canopen::lss::standard_bit_rate_kbit(index);
    if (kbit && on_bit_rate_switch_) on_bit_rate_switch_(std::uint32_t{*kbit} * 1000u);
  };
  subs_ += od_.add_observer([this](std::uint16_t index, std::uint8_t sub, Origin) { handle_od_change(index, sub); });
}

void OeDevice::watch_host_commands() {
  if (outputs_.empty()) return;
  for (const std::uint16_t index :
       {std::uint16_t{cia401::kWriteOutput8}, std::uint16_t{cia401::kWriteAnalogueOutput16}}) {
    canopen::Object* o = od_.find(index);
    if (o == nullptr) continue;
    subs_ +=
        o->add_write_hook([this](canopen::Object& obj, std::uint8_t sub, std::span<const std::uint8_t>, Origin origin) {
          if (origin == Origin::Local) return SdoAbortCode::None;
          // outputs_: index << 8 | sub of every configured output entry -> its FE's fields. Any
          // other entry belongs to an instance that is not configured (its default PDOs map it,
          // profiles/cia852/dictionary.hpp): it keeps its neutral value, the write is refused
          // (SDO abort 0800 0020h, the RPDO's byte ignored).
          const auto it = outputs_.find(static_cast<std::uint32_t>(obj.index()) << 8 | sub);
          if (it == outputs_.end() || it->second.empty())
            return sub == 0 ? SdoAbortCode::None : SdoAbortCode::CannotTransfer;
          const FeId fe = it->second.front().fe;
          const bool take =
              on_host_write_ ? on_host_write_(fe, origin, now_) : cfg_.host_may_not_command.count(fe) == 0;
          return take ? SdoAbortCode::None : SdoAbortCode::CannotTransferLocalControl;
        });
  }
}

canopen::ParameterStore::LoadResult OeDevice::start(TimePoint now) {
  now_ = now;
  // Stored output values (1010h) are reported through on_output by the state change to
  // pre-operational that start() makes (resync_outputs).
  return node_->start(now);
}

bool OeDevice::on_frame(const canopen::CanFrame& frame, TimePoint now) {
  now_ = now;
  bool mine = node_->on_frame(frame, now);
  if (!mine && emcy_consumer_) mine = emcy_consumer_->on_frame(frame, now);
  advance(now);
  return mine;
}

void OeDevice::advance(TimePoint now) {
  now_ = now;
  step_node(now);
}

void OeDevice::step_node(TimePoint now) {
  now_ = now;
  node_->advance(now);  // a heartbeat time-out it notices applies the error values (see above)
}

std::optional<TimePoint> OeDevice::next_deadline() const { return node_->next_deadline(); }

std::optional<bool> OeDevice::analog_interrupts_enabled() {
  const canopen::SubObject* s = od_.resolve(interrupt_enable_);
  if (s == nullptr) return std::nullopt;
  return !s->value.empty() && s->value[0] != 0;
}

bool OeDevice::set_input(FeId fe, std::string_view field, std::int64_t value, TimePoint now) {
  now_ = now;
  const auto f = mapping::find_fe_field(fe, field);
  if (!f) return false;
  return set_input(fe, *f, value, now);
}

bool OeDevice::set_input(FeId fe, const mapping::FeField& field, std::int64_t value, TimePoint now) {
  now_ = now;
  if (!mapping::is_input(fe.kind)) return false;
  if (std::find(cfg_.fes.begin(), cfg_.fes.end(), fe) == cfg_.fes.end()) return false;
  const mapping::FeField* const f = &field;
  canopen::SubObject* s = od_.find(f->index, f->sub);
  if (s == nullptr) return false;
  std::int64_t raw = value;
  if (f->bit != 0xFF) {
    if (value != 0 && value != 1) return false;
    auto byte = static_cast<std::uint8_t>(s->value.at(0));
    byte = static_cast<std::uint8_t>(value ? (byte | (1u << f->bit)) : (byte & ~(1u << f->bit)));
    raw = byte;
  } else {
    const std::size_t w = canopen::fixed_size(f->type);
    const bool is_unsigned =
        f->type == DataType::Unsigned8 || f->type == DataType::Unsigned16 || f->type == DataType::Unsigned32;
    const std::int64_t lo = is_unsigned ? 0 : -(std::int64_t{1} << (8 * w - 1));
    const std::int64_t hi = is_unsigned ? (std::int64_t{1} << (8 * w)) - 1 : (std::int64_t{1} << (8 * w - 1)) - 1;
    if (value < lo || value > hi) return false;
  }
  InputEntry once{{f->index, f->sub}};
  const bool ok = write_input_entry(once, raw);
  if (batch_depth_ == 0) step_node(now);  // event-driven TPDOs go out now (see begin_batch)
  return ok;
}

bool OeDevice::write_input_entry(InputEntry& e, std::int64_t raw) {
  canopen::SubObject* s = od_.resolve(e.slot);
  if (s == nullptr) return false;
  // CiA 401 6423h FALSE: analogue inputs raise no event; the value is stored without telling
  // the PDO service (see the header), so only TPDOs sent for another reason carry it.
  if (e.slot.index == cia401::kReadAnalogueInput16 && analog_interrupts_enabled() == false) {
    // In place (no allocation: this runs for every axis change).
    canopen::put_little_endian(static_cast<std::uint64_t>(raw), s->value);
    shadow_of(e) = s->value;  // same size: no reallocation
    return true;
  }
  if (od_.set_local(e.slot, raw) != SdoAbortCode::None) return false;
  // Looked up again: an observer of the write may have replaced the object.
  if (const canopen::SubObject* now = od_.resolve(e.slot); now != nullptr) shadow_of(e) = now->value;
  return true;
}

std::vector<std::uint8_t>& OeDevice::shadow_of(InputEntry& e) {
  if (e.shadow == nullptr) e.shadow = &input_shadow_[std::uint32_t{e.slot.index} << 8 | e.slot.sub];
  return *e.shadow;
}

void OeDevice::index_inputs() {
  // Each input slot's entries, in the order of fe_fields (profiles/cia852/fe_table.hpp): a
  // bit field's k-th byte holds its bits 8k..8k+7.
  for (const FeId& fe : cfg_.fes) {
    if (!mapping::is_input(fe.kind)) continue;
    for (const auto& f : mapping::fe_fields(fe)) {
      const auto ref = field_ref(fe, f.name);
      if (!ref) continue;
      const bool bits = ref->bit != 0xFF;
      const InputEntry e{{f.index, f.sub}, static_cast<std::uint8_t>(bits ? (ref->bit / 8) * 8 : 0), bits};
      Span& span = input_index_[static_cast<std::size_t>(fe.kind)][fe.instance][static_cast<std::size_t>(ref->slot)];
      const bool known =
          std::any_of(input_entries_.begin() + span.first, input_entries_.begin() + span.first + span.count,
                      [&](const InputEntry& x) { return x.slot.index == e.slot.index && x.slot.sub == e.slot.sub; });
      if (known) continue;
      if (span.count == 0) span.first = static_cast<std::uint16_t>(input_entries_.size());
      // fe_fields lists a slot's fields together, so its entries stay contiguous.
      input_entries_.push_back(e);
      ++span.count;
    }
  }
}

void OeDevice::mirror_input(FeId fe, FeSlot slot, std::int64_t value, TimePoint now) {
  now_ = now;
  const auto k = static_cast<std::size_t>(fe.kind);
  if (k >= input_index_.size() || fe.instance >= input_index_[k].size()) return;
  const Span span = input_index_[k][fe.instance][static_cast<std::size_t>(slot)];
  bool wrote = false;
  for (std::uint16_t i = span.first; i < span.first + span.count; ++i) {
    InputEntry& e = input_entries_[i];
    std::int64_t raw = value;
    if (e.bits) {
      raw = static_cast<std::int64_t>((static_cast<std::uint64_t>(value) >> e.shift) & 0xFFu);
      const canopen::SubObject* s = od_.resolve(e.slot);
      if (s == nullptr || (!s->value.empty() && s->value[0] == raw)) continue;
    }
    // Cannot fail: the entries were looked up from the same FE table at construction and the
    // model's types are the entries' types (a bit field's byte, INTEGER16, INTEGER32), so the
    // value fits; no write hook sits on the input objects.
    wrote = write_input_entry(e, raw) || wrote;
  }
  if (wrote && batch_depth_ == 0) step_node(now);
}

void OeDevice::write_indicators(FeId fe, std::uint64_t bits, TimePoint now) {
  now_ = now;
  for (const auto& [key, refs] : outputs_) {
    if (refs.empty() || !(refs.front().fe == fe) || (key >> 8) != cia401::kWriteOutput8) continue;
    // The entry's eight indicators: bits 8k..8k+7 of the command (k = the first one's bit / 8).
    const auto sub = static_cast<std::uint8_t>(key);
    const auto byte = static_cast<std::uint8_t>(bits >> ((refs.front().ref.bit / 8) * 8));
    if (od_.get<std::uint8_t>(cia401::kWriteOutput8, sub) != byte)
      (void)od_.set<std::uint8_t>(cia401::kWriteOutput8, sub, byte, Origin::Local);
  }
}

void OeDevice::write_display(FeId fe, const std::array<std::int16_t, 12>& parameters, TimePoint now) {
  now_ = now;
  for (const auto& [key, refs] : outputs_) {
    if (refs.empty() || !(refs.front().fe == fe) || (key >> 8) != cia401::kWriteAnalogueOutput16) continue;
    const auto sub = static_cast<std::uint8_t>(key);
    const std::uint8_t p = refs.front().ref.bit;
    if (p < parameters.size() && od_.get<std::int16_t>(cia401::kWriteAnalogueOutput16, sub) != parameters[p])
      (void)od_.set<std::int16_t>(cia401::kWriteAnalogueOutput16, sub, parameters[p], Origin::Local);
  }
}

std::optional<std::int64_t> OeDevice::get(FeId fe, std::string_view field) const {
  const auto f = mapping::find_fe_field(fe, field);
  if (!f) return std::nullopt;
  return get(fe, *f);
}

std::optional<std::int64_t> OeDevice::get(FeId fe, const mapping::FeField& f) const {
  if (std::find(cfg_.fes.begin(), cfg_.fes.end(), fe) == cfg_.fes.end()) return std::nullopt;
  const canopen::SubObject* s = od_.find(f.index, f.sub);
  if (s == nullptr) return std::nullopt;
  if (f.bit != 0xFF) return (s->value.at(0) >> f.bit) & 1;
  return entry_value(*s);
}

// NMT reset node/communication and 1011h restore assign defaults without observers: report the
// outputs that moved.
void OeDevice::resync_outputs() {
  for (auto& [key, v] : output_shadow_) {
    const auto index = static_cast<std::uint16_t>(key >> 8);
    const auto sub = static_cast<std::uint8_t>(key);
    const canopen::SubObject* so = od_.find(index, sub);
    if (so == nullptr) continue;
    const std::int64_t cur = entry_value(*so);
    if (cur == v) continue;
    const std::int64_t old = v;
    v = cur;
    report_outputs(index, sub, old);
  }
}

void OeDevice::handle_state(NmtState s) {
  const bool booted_again = last_state_ == NmtState::Initialisation && s == NmtState::PreOperational;
  last_state_ = s;
  if (booted_again) after_reset();
  resync_outputs();
  // CiA 852 §8.6: entering operational with 6423h FALSE sends EMCY 0080h; no state change.
  auto& emcy = node_->emcy();
  if (s == NmtState::Operational) {
    if (analog_interrupts_enabled() == false) emcy.raise(kEmcyAnalogInputsDisabled, 0x00, now_);
  } else if (emcy.active(kEmcyAnalogInputsDisabled)) {
    emcy.clear(kEmcyAnalogInputsDisabled, now_);
  }
}

namespace {
canopen::EmcyManufacturerField subdevice_msef(canopen::NodeId node, std::string_view name) {
  canopen::EmcyManufacturerField m{};
  m[0] = node.value();
  for (std::size_t i = 0; i < 4 && i < name.size(); ++i) m[1 + i] = static_cast<std::uint8_t>(name[i]);
  return m;
}
}  // namespace

// After every boot-up (an NMT reset node or communication from the host): the inputs get their
// current values back — the reset restored 6000h/6401h/6120h to their defaults although the
// operator still holds the stick — without a TPDO (pre-operational), and each sub-device still
// faulty is reported again with EMCY 7000h, so a host that reset us after its own restart learns
// of it. A reset communication left 7000h active (each fault is an event EMCY again); a reset
// node restarted the EMCY producer (Node: no error active, 1001h 0), and a fault the gateway
// still holds is its evidence now — its inputs stay at their fault values until their own
// evidence clears it — so 7000h is raised anew (1001h bit 0, 1003h), then one EMCY per further
// faulty sub-device.
void OeDevice::after_reset() {
  for (const auto& [key, bytes] : input_shadow_) {
    canopen::SubObject* so = od_.find(static_cast<std::uint16_t>(key >> 8), static_cast<std::uint8_t>(key));
    if (so != nullptr && so->value.size() == bytes.size()) so->value = bytes;
  }
  auto& emcy = node_->emcy();
  for (const auto& [node, name] : faults_) {
    const auto msef = subdevice_msef(canopen::NodeId{node}, name);
    if (!emcy.active(kEmcyAdditionalModules)) {
      emcy.raise(kEmcyAdditionalModules, 0x00, msef, now_, node);
    } else {
      (void)emcy.report(kEmcyAdditionalModules, msef, node, now_);
    }
  }
}

void OeDevice::handle_od_change(std::uint16_t index, std::uint8_t sub) {
  if (index == cia401::kAnalogueInputGlobalInterruptEnable && analog_interrupts_enabled() == true) {
    if (node_->emcy().active(kEmcyAnalogInputsDisabled)) node_->emcy().clear(kEmcyAnalogInputsDisabled, now_);
    return;
  }
  if (index != cia401::kWriteOutput8 && index != cia401::kWriteAnalogueOutput16) return;
  const std::uint32_t key = static_cast<std::uint32_t>(index) << 8 | sub;
  auto it = output_shadow_.find(key);
  if (it == output_shadow_.end()) return;
  const std::int64_t old = it->second;
  const canopen::SubObject* s = od_.find(index, sub);
  it->second = entry_value(*s);
  report_outputs(index, sub, old);
}

void OeDevice::report_outputs(std::uint16_t index, std::uint8_t sub, std::int64_t old_value) {
  if (!on_output_) return;
  const std::uint32_t key = static_cast<std::uint32_t>(index) << 8 | sub;
  const std::int64_t now_value = output_shadow_[key];
  for (const OutputRef& r : outputs_[key]) {
    if (r.bit == 0xFF) {
      if (now_value != old_value) on_output_(r.fe, r.ref, now_value, now_);
    } else {
      const auto b = (now_value >> r.bit) & 1;
      if (b != ((old_value >> r.bit) & 1)) on_output_(r.fe, r.ref, b, now_);
    }
  }
}

void OeDevice::announce_outputs(TimePoint now) {
  now_ = now;
  if (!on_output_) return;
  for (const auto& [key, refs] : outputs_) {
    const std::int64_t v = output_shadow_[key];
    for (const OutputRef& r : refs) on_output_(r.fe, r.ref, r.bit == 0xFF ? v : (v >> r.bit) & 1, now);
  }
}

void OeDevice::host_heartbeat_lost(TimePoint now) { apply_error_values(std::nullopt, now); }

void OeDevice::apply_error_values(std::optional<FeId> only, TimePoint now) {
  now_ = now;
  // outputs_ holds exactly the configured output entries (6200h and 6411h sub-indices), each
  // belonging to one FE: walk them, no search per entry (the gateway calls this per upstream frame
  // while a command watchdog has expired).
  for (const auto& [key, refs] : outputs_) {
    if (refs.empty() || (only && !(refs.front().fe == *only))) continue;
    const auto index = static_cast<std::uint16_t>(key >> 8);
    const auto s = static_cast<std::uint8_t>(key);
    if (index == cia401::kWriteOutput8) {
      // CiA 401 6206h/6207h: per bit, mode 1 = take the error value.
      const auto cur = od_.get<std::uint8_t>(cia401::kWriteOutput8, s);
      const auto mode = od_.get<std::uint8_t>(cia401::kErrorModeOutput8, s);
      const auto val = od_.get<std::uint8_t>(cia401::kErrorValueOutput8, s);
      const auto next = static_cast<std::uint8_t>((cur & ~mode) | (val & mode));
      if (next != cur) (void)od_.set<std::uint8_t>(cia401::kWriteOutput8, s, next, Origin::Local);
    } else if (index == cia401::kWriteAnalogueOutput16 &&
               od_.get<std::uint8_t>(cia401::kAnalogueOutputErrorMode, s) == 1) {
      // 6443h/6444h per channel.
      const std::int32_t ev = od_.get<std::int32_t>(cia401::kAnalogueOutputErrorValueInteger, s);
      const auto clamped = static_cast<std::int16_t>(std::clamp<std::int32_t>(ev, -32768, 32767));
      if (clamped != od_.get<std::int16_t>(cia401::kWriteAnalogueOutput16, s))
        (void)od_.set<std::int16_t>(cia401::kWriteAnalogueOutput16, s, clamped, Origin::Local);
    }
  }
}

void OeDevice::raise_subdevice_fault(std::string_view name, canopen::NodeId node, TimePoint now) {
  now_ = now;
  if (faults_.count(node.value()) != 0) return;
  faults_[node.value()] = std::string(name);
  const auto msef = subdevice_msef(node, name);
  auto& emcy = node_->emcy();
  if (!emcy.active(kEmcyAdditionalModules)) {
    emcy.raise(kEmcyAdditionalModules, 0x00, msef, now, node.value());
  } else {
    (void)emcy.report(kEmcyAdditionalModules, msef, node.value(), now);
  }
}

void OeDevice::clear_subdevice_fault(canopen::NodeId node, TimePoint now) {
  now_ = now;
  auto it = faults_.find(node.value());
  if (it == faults_.end()) return;
  const auto msef = subdevice_msef(node, it->second);
  faults_.erase(it);
  if (faults_.empty()) {
    // The last faulty sub-device recovered: the error reset names it as every other recovery does.
    node_->emcy().clear(kEmcyAdditionalModules, now, msef);
    // With another error still active (EMCY 8130h: the host's heartbeat lost) the producer stays
    // silent (CiA 301 §7.2.7.2 allows it): the recovery is reported as for a sub-device among
    // others, EMCY 0000h naming it with the remaining error register.
    if (node_->emcy().active_count() != 0)
      (void)node_->emcy().report(canopen::EmcyProducer::kErrorReset, msef, node.value(), now);
  } else {
    (void)node_->emcy().report(canopen::EmcyProducer::kErrorReset, msef, node.value(), now);
  }
}

canopen::EmcyManufacturerField OeDevice::forwarded_msef(const canopen::EmcyMessage& emcy) {
  return {emcy.node.value(), emcy.error_register, emcy.msef[0], emcy.msef[1], emcy.msef[2]};
}

bool OeDevice::forward_subdevice_emcy(const canopen::EmcyMessage& emcy, TimePoint now) {
  now_ = now;
  return node_->emcy().report(emcy.code, forwarded_msef(emcy), emcy.node.value(), now, /*relayed=*/true);
}

}  // namespace oegw::gateway

namespace oegw::gateway {

void OeDevice::begin_batch() { ++batch_depth_; }

void OeDevice::end_batch(canopen::TimePoint now) {
  if (batch_depth_ > 0 && --batch_depth_ == 0) step_node(now);
}

std::string OeDevice::busy() const {
  for (std::size_t k = 0; k < node_->sdo_server_count(); ++k) {
    if (node_->sdo_server(k).busy()) return fmt::format("the host's SDO transfer on server {:04X}h", 0x1200 + k);
  }
  return {};
}

void OeDevice::export_state(canopen::StateWriter& w) const {
  if (batch_depth_ != 0) throw std::logic_error("OeDevice::export_state inside an input batch");
  w.put_state("node", *node_);
  w.put("now", now_);
  w.put("last_state", last_state_);
  w.put_list("faults", faults_.size(), [&, it = faults_.begin()](std::size_t) mutable {
    w.put("node", it->first);
    w.put_text("name", it->second);
    ++it;
  });
  w.put_list("outputs", output_shadow_.size(), [&, it = output_shadow_.begin()](std::size_t) mutable {
    w.put("key", it->first);
    w.put("value", it->second);
    ++it;
  });
  w.put_list("inputs", input_shadow_.size(), [&, it = input_shadow_.begin()](std::size_t) mutable {
    w.put("key", it->first);
    w.put_bytes("bytes", it->second);
    ++it;
  });
}

void OeDevice::import_state(const canopen::StateReader& r) {
  if (batch_depth_ != 0) throw std::logic_error("OeDevice::import_state inside an input batch");
  // Read and checked first: the Node's import changes the dictionary.
  std::map<std::uint8_t, std::string> faults;
  r.read_list("faults", 127, [&](const canopen::StateReader& item) {
    const canopen::NodeId node = item.node_id("node");
    if (!node.valid()) item.fail("node", "is no sub-device's node-ID");
    faults[node.value()] = item.text("name", kMaxStateText);
  });
  std::map<std::uint32_t, std::int64_t> outputs = output_shadow_;
  std::size_t n = 0;
  r.read_list("outputs", outputs.size(), [&](const canopen::StateReader& item) {
    const auto it = outputs.find(item.get<std::uint32_t>("key"));
    if (it == outputs.end()) item.fail("key", "is no output entry of this device");
    it->second = item.integer("value");
    ++n;
  });
  if (n != outputs.size()) r.fail("outputs.count", "differs from this device's output entries");
  std::map<std::uint32_t, std::vector<std::uint8_t>> inputs;
  r.read_list("inputs", input_entries_.size(), [&](const canopen::StateReader& item) {
    const auto key = item.get<std::uint32_t>("key");
    const bool known = std::any_of(input_entries_.begin(), input_entries_.end(), [&](const InputEntry& e) {
      return (std::uint32_t{e.slot.index} << 8 | e.slot.sub) == key;
    });
    if (!known) item.fail("key", "is no input entry of this device");
    inputs[key] = item.bytes("bytes");
  });
  const canopen::NmtState last = r.nmt_state("last_state");
  const TimePoint now = r.time("now");
  node_->import_state(r.in("node"));
  // handle_state() follows every NMT state change.
  if (last != node_->nmt().state()) r.fail("last_state", "differs from the NMT state");
  for (const auto& [key, bytes] : inputs) {
    const canopen::SubObject* so = od_.find(static_cast<std::uint16_t>(key >> 8), static_cast<std::uint8_t>(key));
    if (so == nullptr || so->value.size() != bytes.size()) r.fail("inputs", "holds an entry of another size");
  }
  if (emcy_consumer_) emcy_consumer_->reload();
  for (InputEntry& e : input_entries_) e.shadow = nullptr;  // into input_shadow_, replaced
  input_shadow_ = std::move(inputs);
  output_shadow_ = std::move(outputs);
  faults_ = std::move(faults);
  last_state_ = last;
  now_ = now;
}

}  // namespace oegw::gateway
