#include "gateway/oe_device.hpp"

#include <algorithm>

#include "canopen/301/heartbeat.hpp"

namespace oegw::gateway {

using canopen::Access;
using canopen::DataType;
using canopen::NmtState;
using canopen::ObjectDictionary;
using canopen::Origin;
using canopen::PdoParameters;
using canopen::pdo_map;
using canopen::SdoAbortCode;
using canopen::TimePoint;
using mapping::FeId;
using mapping::FeKind;

namespace {

std::uint8_t u8(unsigned v) { return static_cast<std::uint8_t>(v); }

// An integer entry's value in its own signedness.
std::int64_t entry_value(const canopen::SubObject& s) {
  if (canopen::is_signed_integer(s.type)) return canopen::decode_signed(s.value);
  return static_cast<std::int64_t>(canopen::decode_unsigned(s.value));
}

bool has(const std::vector<FeId>& fes, FeKind k, unsigned n) {
  return std::find(fes.begin(), fes.end(), FeId{k, u8(n)}) != fes.end();
}
bool has_kind(const std::vector<FeId>& fes, FeKind k) {
  return std::any_of(fes.begin(), fes.end(), [k](const FeId& f) { return f.kind == k; });
}

// An ARRAY holding only the given sub-indexes; sub 0 = the highest one (CiA 301 §7.4.3).
void add_sparse_array(ObjectDictionary& od, std::uint16_t index, std::string name, DataType type, Access access,
                      const std::set<std::uint8_t>& subs, std::vector<std::uint8_t> dflt, bool mappable,
                      const std::function<std::string(std::uint8_t)>& sub_name) {
  if (subs.empty()) return;
  const std::uint8_t highest = *subs.rbegin();
  canopen::Object& obj = od.add_array(index, std::move(name), type, access, highest, std::move(dflt), mappable);
  for (std::uint8_t s = 1; s <= highest; ++s) {
    if (subs.count(s) == 0) {
      obj.subs().erase(s);
    } else {
      obj.find(s)->name = sub_name(s);
    }
    if (s == 255) break;
  }
}

// The name of an entry after the FE field(s) it holds: "joystick 1 x", "joystick 1 memory",
// "joystick 1 buttons 1-8", "buttons 2 switch 9-16", "display 1 parameter 3".
std::string entry_name(const std::vector<FeId>& fes, std::uint16_t index, std::uint8_t sub) {
  for (const FeId& fe : fes) {
    std::vector<std::string> names;
    for (const auto& f : mapping::fe_fields(fe))
      if (f.index == index && f.sub == sub) names.push_back(f.name);
    if (names.empty()) continue;
    std::string n = std::string(mapping::to_string(fe.kind)) + " " + std::to_string(fe.instance) + " ";
    const std::string& first = names.front();
    const auto br = first.find('[');
    if (names.size() == 1) {
      if (br == std::string::npos) return n + first;
      return n + first.substr(0, br) + " " + first.substr(br + 1, first.size() - br - 2);
    }
    if (first.rfind("memory", 0) == 0) return n + "memory";
    const std::string& last = names.back();
    const auto lbr = last.find('[');
    if (br == std::string::npos || lbr == std::string::npos) return n + first;
    return n + first.substr(0, br) + " " + first.substr(br + 1, first.size() - br - 2) + "-" +
           last.substr(lbr + 1, last.size() - lbr - 2);
  }
  return "entry " + std::to_string(sub);
}

}  // namespace

std::uint32_t device_type_for(const std::vector<FeId>& fes, const std::set<FeId>& joysticks_without_buttons) {
  // CiA 852 Table 8: every row sets bit 7 of the specific functionality and M.
  std::uint32_t specific = 0x80;
  std::uint32_t io = 0;
  for (const FeId& fe : fes) {
    switch (fe.kind) {
      case FeKind::Joystick:
        specific |= 0x01;
        io |= 0x4;
        if (joysticks_without_buttons.count(fe) == 0) io |= 0x1;
        break;
      case FeKind::FootPedal: specific |= 0x02; io |= 0x4; break;
      case FeKind::Encoder: specific |= 0x04; io |= 0x4; break;
      case FeKind::Wheel: specific |= 0x08; io |= 0x4; break;
      case FeKind::ButtonCluster: specific |= 0x10; io |= 0x1; break;
      case FeKind::IndicatorCluster: specific |= 0x20; io |= 0x2; break;
      case FeKind::Display: specific |= 0x40; io |= 0xA; break;
    }
  }
  return specific << 24 | 1u << 23 | io << 16 | kProfile401;
}

std::vector<OePdo> oe_pdos(const std::vector<FeId>& fes, canopen::NodeId node_id) {
  std::vector<OePdo> out;
  auto add = [&](bool transmit, unsigned number, std::vector<std::uint32_t> mapping, std::uint32_t cob) {
    if (mapping.empty()) return;
    PdoParameters p;
    p.cob_id = cob;
    p.transmission_type = 0xFF;  // §12.1
    p.mapping = std::move(mapping);
    p.mapping_capacity = 8;
    out.push_back({transmit, static_cast<std::uint16_t>(number), std::move(p)});
  };
  constexpr std::uint32_t kDisabled = 0x80000000u;
  // §12.2.1/§12.2.2: TPDO 1 joystick 1, TPDO 5..19 joysticks 2..16 (Table 12 layout).
  for (unsigned n = 1; n <= 16; ++n) {
    if (!has(fes, FeKind::Joystick, n)) continue;
    std::vector<std::uint32_t> m = {pdo_map(0x6401, u8(3 * n - 2), 16), pdo_map(0x6401, u8(3 * n - 1), 16),
                                    pdo_map(0x6401, u8(3 * n), 16), pdo_map(0x6000, u8(2 * n - 1), 8),
                                    pdo_map(0x6000, u8(2 * n), 8)};
    // Table 10: (8000 0180h or C000 0180h) + node-ID for TPDO 1; 8000 0000h for TPDO 5..19.
    add(true, n == 1 ? 1 : 3 + n, std::move(m), n == 1 ? kDisabled + 0x180 + node_id.value() : kDisabled);
  }
  // §12.2.3/§12.2.4, Table 16: TPDO 20 + k carries pedals 2k+1 and 2k+2.
  for (unsigned k = 0; k < 8; ++k) {
    std::vector<std::uint32_t> m;
    for (unsigned p = 2 * k + 1; p <= 2 * k + 2; ++p) {
      if (!has(fes, FeKind::FootPedal, p)) continue;
      m.push_back(pdo_map(0x6000, u8(0x20 + p), 8));
      m.push_back(pdo_map(0x6401, u8(0x30 + p), 16));
    }
    add(true, 20 + k, std::move(m), kDisabled);
  }
  // §12.2.5/§12.2.6, Table 20: TPDO 28 + k carries encoders 2k+1, 2k+2.
  for (unsigned k = 0; k < 4; ++k) {
    std::vector<std::uint32_t> m;
    for (unsigned e = 2 * k + 1; e <= 2 * k + 2; ++e)
      if (has(fes, FeKind::Encoder, e)) m.push_back(pdo_map(0x6120, u8(0x80 + e), 32));
    add(true, 28 + k, std::move(m), kDisabled);
  }
  // §12.2.7/§12.2.8, Table 24: TPDO 32 wheels 1..4, TPDO 33 wheels 5..8.
  for (unsigned k = 0; k < 2; ++k) {
    std::vector<std::uint32_t> m;
    for (unsigned w = 4 * k + 1; w <= 4 * k + 4; ++w)
      if (has(fes, FeKind::Wheel, w)) m.push_back(pdo_map(0x6401, u8(0x40 + w), 16));
    add(true, 32 + k, std::move(m), kDisabled);
  }
  // §12.2.9/§12.2.10, Table 28: TPDO 34 + (n−1) push-button cluster n, eight bytes.
  for (unsigned n = 1; n <= 8; ++n) {
    if (!has(fes, FeKind::ButtonCluster, n)) continue;
    std::vector<std::uint32_t> m;
    for (unsigned b = 0; b < 8; ++b) m.push_back(pdo_map(0x6000, u8(0x31 + 8 * (n - 1) + b), 8));
    add(true, 33 + n, std::move(m), kDisabled);
  }
  // §12.2.11/§12.2.12, Table 32: RPDO 1 indicator cluster 1, RPDO 5..11 clusters 2..8.
  for (unsigned n = 1; n <= 8; ++n) {
    if (!has(fes, FeKind::IndicatorCluster, n)) continue;
    std::vector<std::uint32_t> m;
    for (unsigned b = 0; b < 8; ++b) m.push_back(pdo_map(0x6200, u8(0x01 + 8 * (n - 1) + b), 8));
    add(false, n == 1 ? 1 : 3 + n, std::move(m), kDisabled);
  }
  // §12.2.13/§12.2.14, Table 36: display 1 on RPDO 2, 4, 12; display d on RPDO 13+3(d−2)...
  for (unsigned d = 1; d <= 8; ++d) {
    if (!has(fes, FeKind::Display, d)) continue;
    const unsigned numbers[3] = {d == 1 ? 2u : 13 + 3 * (d - 2), d == 1 ? 4u : 14 + 3 * (d - 2),
                                 d == 1 ? 12u : 15 + 3 * (d - 2)};
    for (unsigned r = 0; r < 3; ++r) {
      std::vector<std::uint32_t> m;
      for (unsigned p = 4 * r + 1; p <= 4 * r + 4; ++p) m.push_back(pdo_map(0x6411, u8(12 * (d - 1) + p), 16));
      add(false, numbers[r], std::move(m), kDisabled);
    }
  }
  return out;
}

canopen::NodeConfig build_oe_dictionary(const OeDeviceConfig& cfg, ObjectDictionary& od) {
  const auto& fes = cfg.fes;
  std::map<std::uint16_t, std::set<std::uint8_t>> subs;
  for (const FeId& fe : fes)
    for (const auto& f : mapping::fe_fields(fe)) subs[f.index].insert(f.sub);
  auto namer = [&](std::uint16_t index) {
    return [&fes, index](std::uint8_t s) { return entry_name(fes, index, s); };
  };
  auto subs_of = [&](std::uint16_t index) { return subs.count(index) ? subs[index] : std::set<std::uint8_t>{}; };

  add_sparse_array(od, 0x6000, "Read input 8-bit", DataType::Unsigned8, Access::ReadOnly, subs_of(0x6000), {0}, true,
                   namer(0x6000));
  add_sparse_array(od, 0x6120, "Read input 32-bit", DataType::Integer32, Access::ReadOnly, subs_of(0x6120),
                   canopen::encode<std::int32_t>(0), true, namer(0x6120));
  add_sparse_array(od, 0x6401, "Read analogue input 16-bit", DataType::Integer16, Access::ReadOnly, subs_of(0x6401),
                   canopen::encode<std::int16_t>(0), true, namer(0x6401));
  if (has_kind(fes, FeKind::Joystick) || has_kind(fes, FeKind::FootPedal) || has_kind(fes, FeKind::Wheel))
    od.add_var(0x6423, "Analogue input global interrupt enable", DataType::Boolean, Access::ReadWrite, {0});
  const auto ind = subs_of(0x6200);
  add_sparse_array(od, 0x6200, "Write output 8-bit", DataType::Unsigned8, Access::ReadWrite, ind, {0}, true,
                   namer(0x6200));
  add_sparse_array(od, 0x6206, "Error mode output 8-bit", DataType::Unsigned8, Access::ReadWrite, ind, {0x01}, false,
                   namer(0x6200));
  add_sparse_array(od, 0x6207, "Error value output 8-bit", DataType::Unsigned8, Access::ReadWrite, ind, {0x00}, false,
                   namer(0x6200));
  const auto disp = subs_of(0x6411);
  add_sparse_array(od, 0x6411, "Write analogue output 16-bit", DataType::Integer16, Access::ReadWrite, disp,
                   canopen::encode<std::int16_t>(0), true, namer(0x6411));
  add_sparse_array(od, 0x6443, "Analogue output error mode", DataType::Unsigned8, Access::ReadWrite, disp, {0x01},
                   false, namer(0x6411));
  add_sparse_array(od, 0x6444, "Analogue output error value integer", DataType::Integer32, Access::ReadWrite, disp,
                   canopen::encode<std::int32_t>(0), false, namer(0x6411));
  // 6206h/6443h: CiA 401 error modes are 0 or 1 per bit/channel; 6443h channels hold 0 or 1.
  if (auto* o = od.find(0x6443))
    for (auto& [s, sub] : o->subs())
      if (s != 0) sub.high = std::uint64_t{1};

  for (const OePdo& p : oe_pdos(fes, cfg.node_id)) {
    if (p.transmit) {
      canopen::install_tpdo(od, p.number, p.params);
    } else {
      canopen::install_rpdo(od, p.number, p.params);
    }
    // Tables 10, 14, 18, 22, 26, 30, 34: "highest sub-index supported" is const.
    const auto comm = static_cast<std::uint16_t>((p.transmit ? 0x1800 : 0x1400) + p.number - 1);
    od.find(comm, 0)->access = Access::Const;
  }

  canopen::NodeConfig nc;
  nc.node_id = cfg.node_id;
  nc.device_type = device_type_for(fes, cfg.joysticks_without_buttons);
  nc.device_name = cfg.device_name;
  nc.hardware_version = cfg.hardware_version;
  nc.software_version = cfg.software_version;
  nc.identity.vendor = cfg.identity.vendor;
  nc.identity.product = cfg.identity.product;
  nc.identity.revision = cfg.identity.revision;
  nc.identity.serial = cfg.identity.serial;
  nc.heartbeat_ms = cfg.heartbeat_ms;
  nc.store_path = cfg.store_path;
  const bool outputs = has_kind(fes, FeKind::IndicatorCluster) || has_kind(fes, FeKind::Display);
  if (outputs) {
    // §8.3 / Annex A: heartbeat consumer mandatory with outputs; one entry, the host's.
    nc.heartbeat_consumers = 1;
    canopen::Object& hb = canopen::install_heartbeat_consumer_objects(od, 1);
    const auto v = canopen::encode<std::uint32_t>(
        canopen::heartbeat_consumer_entry(canopen::NodeId{static_cast<std::uint8_t>(cfg.host_node)}, cfg.host_heartbeat_ms));
    hb.find(1)->default_value = v;
    hb.find(1)->value = v;
  }
  return nc;
}

// ---------------------------------------------------------------------------------------------

OeDevice::OeDevice(OeDeviceConfig cfg, canopen::FrameSink sink) : cfg_(std::move(cfg)), sink_(std::move(sink)) {
  // A FE listed twice counts once; an instance outside §9.1's ranges is dropped.
  std::erase_if(cfg_.fes, [](const FeId& f) { return f.instance < 1 || f.instance > mapping::max_instances(f.kind); });
  std::sort(cfg_.fes.begin(), cfg_.fes.end());
  cfg_.fes.erase(std::unique(cfg_.fes.begin(), cfg_.fes.end()), cfg_.fes.end());
  const canopen::NodeConfig nc = build_oe_dictionary(cfg_, od_);
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
    emcy_consumer_ = std::make_unique<canopen::EmcyConsumer>(
        od_, [this](const canopen::EmcyMessage& m, TimePoint t) {
          if (on_emcy_) on_emcy_(m, t);
        });
  }
  node_ = std::make_unique<canopen::Node>(od_, nc, sink_);
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
  subs_ += od_.add_observer([this](std::uint16_t index, std::uint8_t sub, Origin) { handle_od_change(index, sub); });
}

void OeDevice::watch_host_commands() {
  if (outputs_.empty()) return;
  for (const std::uint16_t index : {std::uint16_t{0x6200}, std::uint16_t{0x6411}}) {
    canopen::Object* o = od_.find(index);
    if (o == nullptr) continue;
    subs_ += o->add_write_hook([this](canopen::Object& obj, std::uint8_t sub, std::span<const std::uint8_t>,
                                      Origin origin) {
      if (origin == Origin::Local) return SdoAbortCode::None;
      // outputs_: index << 8 | sub of every configured output entry -> its FE's fields.
      const auto it = outputs_.find(static_cast<std::uint32_t>(obj.index()) << 8 | sub);
      if (it == outputs_.end() || it->second.empty()) return SdoAbortCode::None;
      const FeId fe = it->second.front().fe;
      const bool take = on_host_write_ ? on_host_write_(fe, origin) : cfg_.host_may_not_command.count(fe) == 0;
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

bool OeDevice::analog_interrupt_enabled() const {
  const canopen::SubObject* s = od_.find(0x6423, 0);
  return s != nullptr && !s->value.empty() && s->value[0] != 0;
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
    const std::int64_t lo = -(std::int64_t{1} << (8 * w - 1));
    const std::int64_t hi = (std::int64_t{1} << (8 * w - 1)) - 1;
    if (value < lo || value > hi) return false;
  }
  const bool ok = write_input_entry(InputEntry{f->index, f->sub, 0, false}, raw);
  if (batch_depth_ == 0) step_node(now);  // event-driven TPDOs go out now (see begin_batch)
  return ok;
}

bool OeDevice::write_input_entry(const InputEntry& e, std::int64_t raw) {
  canopen::SubObject* s = od_.find(e.index, e.sub);
  if (s == nullptr) return false;
  // CiA 401 6423h FALSE: analogue inputs raise no event; the value is stored without telling
  // the PDO service (see the header), so only TPDOs sent for another reason carry it.
  if (e.index == 0x6401 && od_.find(0x6423) != nullptr && !analog_interrupt_enabled()) {
    // In place, little endian as encode_width() (no allocation: this runs for every axis change).
    const auto u = static_cast<std::uint64_t>(raw);
    for (std::size_t i = 0; i < s->value.size(); ++i) s->value[i] = static_cast<std::uint8_t>(i < 8 ? u >> (8 * i) : 0);
    input_shadow_[std::uint32_t{e.index} << 8 | e.sub] = s->value;  // same size: no reallocation
    return true;
  }
  const SdoAbortCode rc = od_.set<std::int64_t>(e.index, e.sub, raw, Origin::Local);
  if (rc == SdoAbortCode::None) input_shadow_[std::uint32_t{e.index} << 8 | e.sub] = s->value;
  return rc == SdoAbortCode::None;
}

void OeDevice::index_inputs() {
  // Each input slot's entries, in the order of fe_fields (mapping/functional_elements.hpp): a
  // bit field's k-th byte holds its bits 8k..8k+7.
  for (const FeId& fe : cfg_.fes) {
    if (!mapping::is_input(fe.kind)) continue;
    for (const auto& f : mapping::fe_fields(fe)) {
      const auto ref = field_ref(fe, f.name);
      if (!ref) continue;
      const bool bits = ref->bit != 0xFF;
      const InputEntry e{f.index, f.sub, static_cast<std::uint8_t>(bits ? (ref->bit / 8) * 8 : 0), bits};
      Span& span = input_index_[static_cast<std::size_t>(fe.kind)][fe.instance][static_cast<std::size_t>(ref->slot)];
      const bool known = std::any_of(input_entries_.begin() + span.first, input_entries_.begin() + span.first + span.count,
                                     [&](const InputEntry& x) { return x.index == e.index && x.sub == e.sub; });
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
    const InputEntry& e = input_entries_[i];
    std::int64_t raw = value;
    if (e.bits) {
      raw = static_cast<std::int64_t>((static_cast<std::uint64_t>(value) >> e.shift) & 0xFFu);
      const canopen::SubObject* s = od_.find(e.index, e.sub);
      if (s == nullptr || (!s->value.empty() && s->value[0] == raw)) continue;
    }
    wrote = write_input_entry(e, raw) || wrote;
  }
  if (wrote && batch_depth_ == 0) step_node(now);
}

void OeDevice::write_indicators(FeId fe, std::uint64_t bits) {
  for (const auto& [key, refs] : outputs_) {
    if (refs.empty() || !(refs.front().fe == fe) || (key >> 8) != 0x6200) continue;
    // The entry's eight indicators: bits 8k..8k+7 of the command (k = the first one's bit / 8).
    const auto sub = static_cast<std::uint8_t>(key);
    const auto byte = static_cast<std::uint8_t>(bits >> ((refs.front().ref.bit / 8) * 8));
    if (od_.get<std::uint8_t>(0x6200, sub) != byte) (void)od_.set<std::uint8_t>(0x6200, sub, byte, Origin::Local);
  }
}

void OeDevice::write_display(FeId fe, const std::array<std::int16_t, 12>& parameters) {
  for (const auto& [key, refs] : outputs_) {
    if (refs.empty() || !(refs.front().fe == fe) || (key >> 8) != 0x6411) continue;
    const auto sub = static_cast<std::uint8_t>(key);
    const std::uint8_t p = refs.front().ref.bit;
    if (p < parameters.size() && od_.get<std::int16_t>(0x6411, sub) != parameters[p])
      (void)od_.set<std::int16_t>(0x6411, sub, parameters[p], Origin::Local);
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
    if (od_.find(0x6423) != nullptr && !analog_interrupt_enabled())
      emcy.raise(kEmcyAnalogInputsDisabled, 0x00, now_);
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
// faulty is reported again with EMCY 7000h (the producer kept the error active across the
// reset), so a host that reset us after its own restart learns of it.
void OeDevice::after_reset() {
  for (const auto& [key, bytes] : input_shadow_) {
    canopen::SubObject* so = od_.find(static_cast<std::uint16_t>(key >> 8), static_cast<std::uint8_t>(key));
    if (so != nullptr && so->value.size() == bytes.size()) so->value = bytes;
  }
  for (const auto& [node, name] : faults_) send_emcy_frame(kEmcyAdditionalModules, subdevice_msef(canopen::NodeId{node}, name));
}

void OeDevice::handle_od_change(std::uint16_t index, std::uint8_t sub) {
  if (index == 0x6423 && analog_interrupt_enabled()) {
    if (node_->emcy().active(kEmcyAnalogInputsDisabled)) node_->emcy().clear(kEmcyAnalogInputsDisabled, now_);
    return;
  }
  if (index != 0x6200 && index != 0x6411) return;
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
      if (now_value != old_value) on_output_(r.fe, r.ref, now_value);
    } else {
      const auto b = (now_value >> r.bit) & 1;
      if (b != ((old_value >> r.bit) & 1)) on_output_(r.fe, r.ref, b);
    }
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
    if (index == 0x6200) {
      // CiA 401 6206h/6207h: per bit, mode 1 = take the error value.
      const auto cur = od_.get<std::uint8_t>(0x6200, s);
      const auto mode = od_.get<std::uint8_t>(0x6206, s);
      const auto val = od_.get<std::uint8_t>(0x6207, s);
      const auto next = static_cast<std::uint8_t>((cur & ~mode) | (val & mode));
      if (next != cur) (void)od_.set<std::uint8_t>(0x6200, s, next, Origin::Local);
    } else if (index == 0x6411 && od_.get<std::uint8_t>(0x6443, s) == 1) {
      // 6443h/6444h per channel.
      const std::int32_t ev = od_.get<std::int32_t>(0x6444, s);
      const auto clamped = static_cast<std::int16_t>(std::clamp<std::int32_t>(ev, -32768, 32767));
      if (clamped != od_.get<std::int16_t>(0x6411, s)) (void)od_.set<std::int16_t>(0x6411, s, clamped, Origin::Local);
    }
  }
}

void OeDevice::send_emcy_frame(std::uint16_t code, const canopen::EmcyManufacturerField& msef) {
  const NmtState st = node_->state();
  if (st != NmtState::PreOperational && st != NmtState::Operational) return;
  const canopen::CobId cob{od_.get<std::uint32_t>(0x1014, 0)};
  if (!cob.valid()) return;
  canopen::CanFrame f;
  f.id = cob.can_id();
  f.extended = cob.extended();
  f.dlc = 8;
  f.data[0] = static_cast<std::uint8_t>(code);
  f.data[1] = static_cast<std::uint8_t>(code >> 8);
  f.data[2] = node_->emcy().error_register();
  std::copy(msef.begin(), msef.end(), f.data.begin() + 3);
  sink_(f);
}


void OeDevice::raise_subdevice_fault(std::string_view name, canopen::NodeId node, TimePoint now) {
  now_ = now;
  if (faults_.count(node.value()) != 0) return;
  faults_[node.value()] = std::string(name);
  const auto msef = subdevice_msef(node, name);
  auto& emcy = node_->emcy();
  if (!emcy.active(kEmcyAdditionalModules)) {
    emcy.raise(kEmcyAdditionalModules, 0x00, msef, now);
  } else {
    send_emcy_frame(kEmcyAdditionalModules, msef);
  }
}

void OeDevice::clear_subdevice_fault(canopen::NodeId node, TimePoint now) {
  now_ = now;
  auto it = faults_.find(node.value());
  if (it == faults_.end()) return;
  const auto msef = subdevice_msef(node, it->second);
  faults_.erase(it);
  if (faults_.empty()) {
    node_->emcy().clear(kEmcyAdditionalModules, now);
    // With another error still active (EMCY 8130h: the host's heartbeat lost) the producer stays
    // silent (CiA 301 §7.2.7.2 allows it): the recovery is reported as for a sub-device among
    // others, EMCY 0000h naming it with the remaining error register.
    if (node_->emcy().active_count() != 0) send_emcy_frame(canopen::EmcyProducer::kErrorReset, msef);
  } else {
    send_emcy_frame(canopen::EmcyProducer::kErrorReset, msef);
  }
}

}  // namespace oegw::gateway

namespace oegw::gateway {

void OeDevice::begin_batch() { ++batch_depth_; }

void OeDevice::end_batch(canopen::TimePoint now) {
  if (batch_depth_ > 0 && --batch_depth_ == 0) step_node(now);
}

}  // namespace oegw::gateway
