#include "subdevices/cia401.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "canopen/306/eds_check.hpp"
#include "canopen/state.hpp"
#include "profiles/cia401/objects.hpp"
#include "subdevices/driver_options.hpp"
#include "subdevices/families.hpp"

namespace oegw::subdevices {

using canopen::CobId;
using canopen::DataType;
using canopen::SdoAbortCode;

namespace {

constexpr std::uint16_t kPdosPerDirection = 4;  // 1400h–1403h, 1800h–1803h (CiA 401 pre-defined set)

DataType expected_type(std::uint16_t index) {
  switch (index) {
    case cia401::kReadInput8:
    case cia401::kWriteOutput8: return DataType::Unsigned8;
    case cia401::kReadInput32: return DataType::Unsigned32;
    default: return DataType::Integer16;
  }
}

std::uint32_t u32(std::span<const std::uint8_t> d) { return static_cast<std::uint32_t>(canopen::decode_unsigned(d)); }

std::int64_t limit_as_signed(const std::optional<canopen::eds::Value>& v, DataType t, std::int64_t fallback) {
  if (!v || !v->numeric || v->node_relative) return fallback;
  if (canopen::is_signed_integer(t)) {
    const std::size_t n = canopen::fixed_size(t);
    return canopen::decode_signed(canopen::encode_width(v->number, n));
  }
  return static_cast<std::int64_t>(v->number);
}

// CiA 301 §7.2.7.1, Table 26: the error code classes it defines.
const char* emcy_class(std::uint16_t code) {
  const unsigned hi = code >> 12;
  const unsigned hi8 = code >> 8;
  if (hi8 == 0x10) return "generic error";
  if (hi == 0x2) return "current";
  if (hi == 0x3) return "voltage";
  if (hi == 0x4) return "temperature";
  if (hi8 == 0x50) return "device hardware";
  if (hi == 0x6) return "device software";
  if (hi8 == 0x70) return "additional modules";
  if (hi == 0x8) return "monitoring / communication";
  if (hi8 == 0x90) return "external error";
  if (hi8 == 0xF0) return "additional functions";
  if (hi8 == 0xFF) return "device specific";
  return nullptr;
}

std::string hex4(std::uint32_t v) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string s(4, '0');
  for (int i = 3; i >= 0; --i) {
    s[static_cast<std::size_t>(i)] = kHex[v & 0xF];
    v >>= 4;
  }
  return s;
}

}  // namespace

bool Cia401Driver::Pdo::complete() const {
  if (failed) return true;
  if (!cob_id || !transmission_type) return false;
  if ((*cob_id & CobId::kInvalidBit) != 0) return true;  // not used: its mapping does not matter
  if (!count) return false;
  if (transmit && !event_timer_done) return false;  // 18xxh:05 read (or refused) after the mapping
  return std::all_of(entries.begin(), entries.end(), [](const auto& e) { return e.has_value(); });
}

bool Cia401Driver::Pdo::usable() const {
  return !failed && complete() && (*cob_id & CobId::kInvalidBit) == 0 && !decoded.empty() && bits > 0 && bits <= 64;
}

Cia401Driver::Cia401Driver(NodeId node, FrameSink sink, canopen::eds::File file) : eds_(std::move(file)) {
  add_signals(cia401::kReadInput8, "in", SignalKind::Digital, 0, 255, "bits");
  add_signals(cia401::kReadInput32, "in32", SignalKind::Digital, 0, 0xFFFFFFFFll, "bits");
  add_signals(cia401::kReadAnalogueInput16, "analog", SignalKind::Analog, -32768, 32767, "raw16");
  add_signals(cia401::kWriteOutput8, "out", SignalKind::Output, 0, 255, "bits");
  add_signals(cia401::kWriteAnalogueOutput16, "aout", SignalKind::Output, -32768, 32767, "raw16");
  init(node, std::move(sink), signals_.size());
  for (std::uint16_t n = 1; n <= kPdosPerDirection; ++n) {
    for (bool transmit : {false, true}) {
      Pdo p;
      p.transmit = transmit;
      p.number = n;
      if (eds_.find(p.comm_index()) != nullptr && eds_.find(p.map_index()) != nullptr) pdos_.push_back(std::move(p));
    }
  }
}

std::vector<Driver::TpdoTraffic> Cia401Driver::expected_tpdos(const std::vector<SdoWrite>& writes) const {
  const bool booted = std::any_of(pdos_.begin(), pdos_.end(), [](const Pdo& p) { return p.transmit && p.usable(); });
  if (booted) return Driver::expected_tpdos(writes);
  std::vector<TpdoTraffic> out;
  for (std::uint16_t n = 1; n <= kPdosPerDirection; ++n) {
    const auto d = canopen::eds::pdo_defaults(eds_, true, n, node());
    if (!d || !CobId{d->cob_id}.valid()) continue;
    unsigned bits = 0;
    for (const std::uint32_t e : d->mapping) bits += e & 0xFF;
    TpdoTraffic t{CobId{d->cob_id}.can_id(), static_cast<std::uint8_t>(std::min(8u, (bits + 7) / 8)), d->event_timer,
                  d->transmission_type, d->inhibit_time};
    apply_tpdo_writes(t, static_cast<std::uint16_t>(0x1800 + n - 1), writes);
    out.push_back(t);
  }
  return out;
}

void Cia401Driver::refresh_carriers() {
  std::vector<Carrier> carriers;
  for (const Pdo& p : pdos_) {
    if (!p.transmit || !p.usable()) continue;
    Carrier c;
    c.cob_id = CobId{*p.cob_id}.can_id();
    c.comm_index = p.comm_index();
    c.event_timer_ms = p.event_timer.value_or(0);  // as read from the node at boot
    c.transmission_type = p.transmission_type.value_or(0xFF);
    c.length = static_cast<std::uint8_t>(std::min(8u, (p.bits + 7) / 8));
    for (const Entry& e : p.decoded)
      if (e.signal >= 0) c.signals.push_back(static_cast<std::size_t>(e.signal));
    carriers.push_back(std::move(c));
  }
  set_carriers(std::move(carriers));
}

void Cia401Driver::add_signals(std::uint16_t index, const char* prefix, SignalKind kind, std::int64_t min,
                               std::int64_t max, const char* unit) {
  const canopen::eds::ObjectEntry* o = eds_.find(index);
  if (o == nullptr || o->code == canopen::ObjectCode::Var) return;
  const DataType t = expected_type(index);
  for (const auto& [sub, e] : o->subs) {
    if (sub == 0 || e.type != t) continue;  // another type is not CiA 401's object: not decoded
    SignalInfo s;
    s.name = std::string(prefix) + "[" + std::to_string(sub) + "]";
    s.kind = kind;
    s.min = min;
    s.max = max;
    s.unit = unit;
    if (kind == SignalKind::Output) {
      s.min = std::max(min, limit_as_signed(e.low, t, min));
      s.max = std::min(max, limit_as_signed(e.high, t, max));
    }
    s.neutral = std::clamp<std::int64_t>(0, s.min, s.max);
    std::int64_t initial = 0;
    if (e.default_value && e.default_value->numeric && !e.default_value->node_relative)
      initial = limit_as_signed(e.default_value, t, 0);
    by_object_[std::uint32_t{index} << 8 | sub] = signals_.size();
    width_.push_back(static_cast<std::uint8_t>(canopen::fixed_size(t) * 8));
    outputs_.push_back(std::clamp(initial, s.min, s.max));
    signals_.push_back(std::move(s));
  }
}

ExpectedIdentity Cia401Driver::expected_identity() const {
  ExpectedIdentity id;
  if (auto dt = eds_.default_number(0x1000, 0, node())) id.device_type = static_cast<std::uint32_t>(*dt);
  auto pick = [&](std::string_view key, std::uint8_t sub) -> std::optional<std::uint32_t> {
    if (auto v = eds_.device_number(key)) return v;
    if (auto v = eds_.default_number(0x1018, sub, node())) return static_cast<std::uint32_t>(*v);
    return std::nullopt;
  };
  id.vendor_id = pick("VendorNumber", 1);
  id.product_code = pick("ProductNumber", 2);
  id.revision = pick("RevisionNumber", 3);
  return id;
}

// ---- boot-time mapping read -----------------------------------------------------------------

void Cia401Driver::reset_mapping() {
  pending_.clear();
  for (Pdo& p : pdos_) {
    Pdo fresh;
    fresh.transmit = p.transmit;
    fresh.number = p.number;
    p = std::move(fresh);
  }
}

std::vector<SdoRead> Cia401Driver::mapping_reads() const {
  std::vector<SdoRead> reads;
  for (const Pdo& p : pdos_) {
    if (p.complete()) continue;
    const std::string name = std::string(p.transmit ? "TPDO" : "RPDO") + std::to_string(p.number);
    if (!p.cob_id) reads.push_back({p.comm_index(), 1, name + " COB-ID"});
    if (!p.transmission_type) reads.push_back({p.comm_index(), 2, name + " transmission type"});
    if (p.cob_id && (*p.cob_id & CobId::kInvalidBit) != 0) continue;
    if (!p.count) {
      reads.push_back({p.map_index(), 0, name + " number of mapped objects"});
      continue;
    }
    for (std::size_t i = 0; i < p.entries.size(); ++i)
      if (!p.entries[i])
        reads.push_back(
            {p.map_index(), static_cast<std::uint8_t>(i + 1), name + " mapping entry " + std::to_string(i + 1)});
    // The event timer the node actually uses (its stored value may not be the EDS's): the
    // freshness deadline of the inputs this TPDO carries (Driver::kMissedPeriods).
    if (p.transmit && !p.event_timer_done) reads.push_back({p.comm_index(), 5, name + " event timer"});
  }
  return reads;
}

Cia401Driver::Pdo* Cia401Driver::find_pdo(std::uint16_t index) {
  for (Pdo& p : pdos_)
    if (p.comm_index() == index || p.map_index() == index) return &p;
  return nullptr;
}

SdoAbortCode Cia401Driver::apply_mapping_read(std::uint16_t index, std::uint8_t sub,
                                              std::span<const std::uint8_t> data) {
  Pdo* p = find_pdo(index);
  if (p == nullptr) return SdoAbortCode::ObjectDoesNotExist;
  auto refuse = [p](SdoAbortCode c) {
    p->failed = true;
    p->decoded.clear();
    return c;
  };
  if (index == p->comm_index()) {
    if (sub == 1) {
      if (data.size() != 4) return refuse(SdoAbortCode::LengthMismatch);
      // CiA 301 §7.3.5: no PDO may use a restricted CAN-ID. A node that reports one (an
      // unconfigured device's 0, say) would have the gateway send its outputs as NMT commands,
      // or read its heartbeats or SDO answers as inputs.
      const CobId c{u32(data)};
      if (c.valid() && !c.extended() && canopen::cob::restricted(c.can_id())) return refuse(SdoAbortCode::InvalidValue);
      p->cob_id = u32(data);
    } else if (sub == 2) {
      if (data.size() != 1) return refuse(SdoAbortCode::LengthMismatch);
      p->transmission_type = data[0];
    } else if (sub == 5 && p->transmit) {
      if (data.size() != 2) return refuse(SdoAbortCode::LengthMismatch);
      p->event_timer = static_cast<std::uint16_t>(data[0] | (data[1] << 8));
      p->event_timer_done = true;
    } else {
      return SdoAbortCode::SubIndexDoesNotExist;
    }
  } else if (sub == 0) {
    if (data.size() != 1) return refuse(SdoAbortCode::LengthMismatch);
    if (data[0] > 64) return refuse(SdoAbortCode::ValueTooHigh);
    p->count = data[0];
    p->entries.assign(data[0], std::nullopt);
  } else {
    if (!p->count || sub > *p->count) return SdoAbortCode::SubIndexDoesNotExist;
    if (data.size() != 4) return refuse(SdoAbortCode::LengthMismatch);
    p->entries[sub - 1] = u32(data);
  }
  if (p->complete() && !p->failed) build(*p);
  return SdoAbortCode::None;
}

void Cia401Driver::apply_mapping_abort(std::uint16_t index, std::uint8_t sub, SdoAbortCode /*code*/) {
  Pdo* p = find_pdo(index);
  if (p == nullptr) return;
  if (p->transmit && index == p->comm_index() && sub == 5) {
    // 18xxh:05 is optional (CiA 301 §7.5.2.35): without it the TPDO has no event timer.
    p->event_timer_done = true;
    if (p->complete() && !p->failed) build(*p);
    return;
  }
  p->failed = true;
  p->decoded.clear();
}

int Cia401Driver::signal_for(std::uint32_t entry) const {
  auto it = by_object_.find(entry >> 8);
  if (it == by_object_.end()) return -1;
  if ((entry & 0xFF) != width_[it->second]) return -1;  // a partial or oversized mapping: not decoded
  return static_cast<int>(it->second);
}

void Cia401Driver::build(Pdo& p) {
  p.decoded.clear();
  p.bits = 0;
  if ((*p.cob_id & CobId::kInvalidBit) != 0) return;
  for (const auto& e : p.entries) {
    const std::uint32_t raw = *e;
    const unsigned bits = raw & 0xFF;
    int sig = signal_for(raw);
    // A TPDO carries inputs only; an RPDO outputs only (a misdirected entry is skipped).
    if (sig >= 0 && signals_[static_cast<std::size_t>(sig)].output() != !p.transmit) sig = -1;
    p.decoded.push_back(Entry{raw, sig});
    p.bits += bits;
    if (bits == 0) p.bits = 65;  // CiA 301 §7.5.2.36: a zero-length entry is invalid
  }
}

bool Cia401Driver::needs_sync() const {
  return std::any_of(pdos_.begin(), pdos_.end(),
                     [](const Pdo& p) { return p.usable() && p.transmission_type && *p.transmission_type <= 240; });
}

std::vector<SdoWrite> Cia401Driver::configuration() const {
  const canopen::eds::SubEntry* enable = eds_.find(0x6423, 0);
  if (enable == nullptr || !canopen::writable(enable->access)) return {};
  for (const Pdo& p : pdos_) {
    if (!p.transmit || !p.usable() || !p.transmission_type) continue;
    const std::uint8_t t = *p.transmission_type;
    if (t != 0 && t < 254) continue;  // cyclic synchronous: sent at the SYNC, changed or not
    for (const Entry& e : p.decoded)
      if ((e.raw >> 16) == 0x6401 && e.signal >= 0)
        return {SdoWrite{0x6423,
                         0,
                         {1},
                         "analogue input global interrupt enable (6423h) TRUE: TPDO" + std::to_string(p.number) +
                             " maps an analogue input and is sent on change"}};
  }
  return {};
}

// ---- runtime --------------------------------------------------------------------------------

std::vector<std::uint32_t> Cia401Driver::consumed_cob_ids() const {
  std::vector<std::uint32_t> ids;
  for (const Pdo& p : pdos_) {
    if (!p.transmit || !p.usable()) continue;
    const CobId c{*p.cob_id};
    ids.push_back(c.extended() ? (c.can_id() | CobId::kExtendedBit) : c.can_id());
  }
  return ids;
}

bool Cia401Driver::on_frame(const CanFrame& frame, TimePoint now) {
  for (const Pdo& p : pdos_) {
    if (!p.transmit || !p.usable()) continue;
    const CobId c{*p.cob_id};
    if (c.can_id() != frame.id || c.extended() != frame.extended) continue;
    if (frame.rtr || frame.dlc != (p.bits + 7) / 8) {
      ++counters_.wrong_length;
      return false;
    }
    std::uint64_t payload = 0;
    for (std::size_t i = 0; i < frame.dlc; ++i) payload |= std::uint64_t{frame.data[i]} << (8 * i);
    unsigned offset = 0;
    for (const Entry& e : p.decoded) {
      const unsigned bits = e.raw & 0xFF;
      if (e.signal >= 0) {
        const auto idx = static_cast<std::size_t>(e.signal);
        const std::uint64_t mask = bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1;
        const std::uint64_t raw = (payload >> offset) & mask;
        std::int64_t v = static_cast<std::int64_t>(raw);
        if (signals_[idx].min < 0 && bits < 64 && (raw >> (bits - 1)) != 0)
          v = static_cast<std::int64_t>(raw | ~mask);  // INTEGER16: sign-extend
        update(idx, v, SignalStatus::Valid, now);
      }
      offset += bits;
    }
    return true;
  }
  ++counters_.unknown_cob;
  return false;
}

DecodedEmcy Cia401Driver::on_emcy(const EmcyMessage& emcy, TimePoint now) {
  DecodedEmcy d;
  d.code = emcy.code;
  if (emcy.code == canopen::EmcyProducer::kErrorReset) {
    d.error = false;
    d.text = "cia401 EMCY 0000h: error reset";
    // No longer Error, but no value either until the next PDO: Offline, as before the first
    // one (Stale means a PDO is overdue, which a node sending on change only never is).
    clear_all_faults();
    for (std::size_t i = 0; i < signals_.size(); ++i)
      if (!signals_[i].output() && value(i).status == SignalStatus::Error)
        update(i, signals_[i].neutral, SignalStatus::Offline, now);
    return d;
  }
  const char* cls = emcy_class(emcy.code);
  if (cls == nullptr) {
    ++counters_.unknown_emcy;
    d.text = "cia401 EMCY " + hex4(emcy.code) + "h: unknown error code (ignored)";
    d.error = false;
    return d;
  }
  d.text = "cia401 EMCY " + hex4(emcy.code) + "h: " + cls;
  if ((emcy.code & 0xFF00) == 0x8100) {
    // CiA 301 Table 26 81xxh "communication" (CAN overrun, error passive, life guard / heartbeat
    // error, recovered from bus off): a warning about the bus, not about the values.
    d.error = false;
    d.text += " (warning)";
    return d;
  }
  for (std::size_t i = 0; i < signals_.size(); ++i) {
    if (signals_[i].output()) continue;
    set_fault(i, now);
    d.affected.push_back(i);
  }
  return d;
}

bool Cia401Driver::set_output(std::size_t index, std::int64_t v, TimePoint now) {
  if (index >= signals_.size() || !signals_[index].output()) return false;
  if (v < signals_[index].min || v > signals_[index].max) return false;
  const auto sig = static_cast<int>(index);
  bool mapped = false;
  for (std::size_t k = 0; k < pdos_.size(); ++k) {
    const Pdo& p = pdos_[k];
    if (p.transmit || !p.usable()) continue;
    if (std::none_of(p.decoded.begin(), p.decoded.end(), [sig](const Entry& e) { return e.signal == sig; })) continue;
    mapped = true;
    if (std::find(pending_.begin(), pending_.end(), k) == pending_.end()) pending_.push_back(k);
  }
  if (!mapped) return false;
  outputs_[index] = v;
  if (!outputs_deferred()) flush_outputs(now);
  update(index, v, SignalStatus::Valid, now);
  return true;
}

void Cia401Driver::flush_outputs(TimePoint /*now*/) {
  for (const std::size_t k : pending_) {
    const Pdo& p = pdos_[k];
    std::uint64_t payload = 0;
    unsigned offset = 0;
    for (const Entry& e : p.decoded) {
      const unsigned bits = e.raw & 0xFF;
      if (e.signal >= 0) {
        const std::uint64_t mask = bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1;
        payload |= (static_cast<std::uint64_t>(outputs_[static_cast<std::size_t>(e.signal)]) & mask) << offset;
      }
      offset += bits;
    }
    const CobId c{*p.cob_id};
    CanFrame f;
    f.id = c.can_id();
    f.extended = c.extended();
    f.dlc = static_cast<std::uint8_t>((p.bits + 7) / 8);
    for (std::size_t i = 0; i < f.dlc; ++i) f.data[i] = static_cast<std::uint8_t>(payload >> (8 * i));
    send(f);
  }
  pending_.clear();
}

const std::vector<OptionSpec>& cia401_options() {
  static const std::vector<OptionSpec> table = {
      {.name = "eds",
       .type = OptionSpec::Type::Text,
       .syntax = "path of the node's EDS file",
       .required = true,
       .missing = "cia401: option 'eds' (path of the node's EDS file) is required",
       .description = "the node's EDS (CiA 306): its 6000h, 6120h, 6401h, 6200h, 6411h sub-indices are the "
                      "signals; a relative path is taken from the mapping file's folder"},
      freshness_floor_option("200"),
  };
  return table;
}

std::unique_ptr<Driver> make_cia401_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                           OptionRefusals& refusals) {
  std::optional<std::string> path;
  std::int64_t floor_ms = 0;
  if (!parse_options(
          "cia401", cia401_options(), options,
          [&path, &floor_ms](const OptionValue& v, std::string& /*error*/) {
            if (v.spec->name == kFreshnessFloorOption) {
              floor_ms = v.number;
            } else {
              path = v.text;
            }
            return true;
          },
          refusals))
    return nullptr;
  if (!node.valid()) {
    refusals.push_back({"", "cia401: node-ID " + std::to_string(node.value()) + " is not 1..127"});
    return nullptr;
  }
  if (!path || path->empty()) {
    refusals.push_back({"eds", "cia401: option 'eds' (path of the node's EDS file) is required"});
    return nullptr;
  }
  // A path to nothing is the commonest slip (a typo, a folder not copied to the cab): said as
  // that, with the path as the driver was given it.
  std::error_code ec;
  if (!std::filesystem::exists(*path, ec) && !ec) {
    refusals.push_back({"eds", "cia401: EDS file " + *path + " does not exist"});
    return nullptr;
  }
  std::string why;
  auto file = canopen::eds::load(*path, why);
  if (!file) {
    refusals.push_back({"eds", "cia401: " + why});
    return nullptr;
  }
  if (const auto problems = canopen::eds::check_pdo_mappings(*file); !problems.empty()) {
    refusals.push_back(
        {"eds", "cia401: " + problems.front() +
                    (problems.size() > 1 ? " (and " + std::to_string(problems.size() - 1) + " more)" : "")});
    return nullptr;
  }
  auto d = std::make_unique<Cia401Driver>(node, std::move(sink), std::move(*file));
  apply_freshness_floor(*d, floor_ms);
  return d;
}

std::unique_ptr<Driver> make_cia401_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                           std::string& error) {
  return with_error_text(error, [&](OptionRefusals& refusals) {
    return make_cia401_driver(node, std::move(sink), options, refusals);
  });
}

}  // namespace oegw::subdevices

namespace oegw::subdevices {

std::vector<std::pair<std::uint16_t, std::uint8_t>> Cia401Driver::boot_reads() const {
  std::vector<std::pair<std::uint16_t, std::uint8_t>> out;
  if (!error_register_read_) out.emplace_back(0x1001, 0);
  for (const SdoRead& r : mapping_reads()) out.emplace_back(r.index, r.sub);
  return out;
}

void Cia401Driver::on_error_register(std::span<const std::uint8_t> data) {
  error_register_read_ = true;
  if (data.size() != 1) return;  // UNSIGNED8: another length is no evidence, the faults stay
  // CiA 301 §7.5.2.2: bit 0 generic (set at any error), 1 current, 2 voltage, 3 temperature,
  // 4 communication, 5 device profile, 7 manufacturer. A communication error alone is the
  // warning an 81xxh EMCY is (it faults nothing).
  constexpr std::uint8_t kGeneric = 0x01;
  constexpr std::uint8_t kCommunication = 0x10;
  const std::uint8_t reg = data[0];
  const bool error = (reg & ~(kGeneric | kCommunication)) != 0 || reg == kGeneric;
  if (!error) {
    clear_all_faults();
    return;
  }
  for (std::size_t i = 0; i < signals_.size(); ++i)
    if (!signals_[i].output()) set_fault(i);
}

bool Cia401Driver::on_boot_read(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                                std::string& error) {
  if (index == 0x1001 && sub == 0) {
    on_error_register(data);
    return true;
  }
  const canopen::SdoAbortCode code = apply_mapping_read(index, sub, data);
  if (code == canopen::SdoAbortCode::None) return true;
  error = std::string(canopen::to_string(code));
  if (code == canopen::SdoAbortCode::InvalidValue) {  // only a COB-ID on a restricted CAN-ID (header)
    char b[160];
    std::snprintf(b, sizeof b,
                  "the PDO's COB-ID %03Xh is a restricted CAN-ID (CiA 301 §7.3.5: NMT, SYNC/EMCY, SDO, heartbeat "
                  "and LSS identifiers)",
                  static_cast<unsigned>(CobId{u32(data)}.can_id()));
    error = b;
  }
  return false;
}

bool Cia401Driver::on_boot_read_abort(std::uint16_t index, std::uint8_t sub, canopen::SdoAbortCode code) {
  if (index == 0x1001 && sub == 0) {
    error_register_read_ = true;  // no evidence either way: the faults stay
    return true;
  }
  apply_mapping_abort(index, sub, code);  // that PDO is simply not used
  return true;
}

// The PDOs as read back from the node at boot (its carriers follow from them), whether this boot
// read 1001h, and the outputs as last commanded.
void Cia401Driver::export_family_state(canopen::StateWriter& w) const {
  w.put_list("pdos", pdos_.size(), [&](std::size_t k) {
    const Pdo& p = pdos_[k];
    w.put("transmit", p.transmit);
    w.put("number", p.number);
    w.put("cob_id", p.cob_id);
    w.put("transmission_type", p.transmission_type);
    w.put("event_timer", p.event_timer);
    w.put("event_timer_done", p.event_timer_done);
    w.put("count", p.count);
    w.put_list("entries", p.entries.size(), [&](std::size_t e) { w.put("raw", p.entries[e]); });
    w.put("failed", p.failed);
  });
  w.put("error_register_read", error_register_read_);
  w.put_list("outputs", outputs_.size(), [&](std::size_t i) { w.put("value", outputs_[i]); });
}

void Cia401Driver::import_boot_learned(const canopen::StateReader& r) {
  std::vector<Pdo> pdos = pdos_;
  std::size_t k = 0;
  r.read_list("pdos", pdos.size(), [&](const canopen::StateReader& item) {
    Pdo& p = pdos[k++];
    if (item.get<bool>("transmit") != p.transmit) item.fail("transmit", "differs: the state is of another EDS's PDOs");
    if (item.get<std::uint16_t>("number") != p.number)
      item.fail("number", "differs: the state is of another EDS's PDOs");
    p.cob_id = item.optional<std::uint32_t>("cob_id");
    // As apply_mapping_read: a boot never keeps a PDO on a restricted CAN-ID (CiA 301 §7.3.5).
    if (const CobId c{p.cob_id.value_or(0)};
        p.cob_id && c.valid() && !c.extended() && canopen::cob::restricted(c.can_id())) {
      item.fail("cob_id", "is on a restricted CAN-ID (CiA 301 §7.3.5)");
    }
    p.transmission_type = item.optional<std::uint8_t>("transmission_type");
    p.event_timer = item.optional<std::uint16_t>("event_timer");
    p.event_timer_done = item.get<bool>("event_timer_done");
    p.count = item.optional<std::uint8_t>("count");
    // CiA 301 §7.5.2.36: at most 64 entries; the boot reads as many as the count says.
    if (p.count && *p.count > 64) item.fail("count", "is above 64 mapping entries");
    p.failed = item.get<bool>("failed");
    p.entries.clear();
    item.read_list("entries", 64,
                   [&](const canopen::StateReader& e) { p.entries.push_back(e.optional<std::uint32_t>("raw")); });
    // A read count makes room for as many entries (apply_mapping_read); none before it.
    if (p.entries.size() != p.count.value_or(0)) item.fail("entries.count", "differs from the count");
    p.decoded.clear();
    p.bits = 0;
    if (p.complete() && !p.failed) build(p);
  });
  if (k != pdos.size()) r.fail("pdos.count", "differs: the state is of another EDS's PDOs");
  pdos_ = std::move(pdos);
}

void Cia401Driver::import_family_state(const canopen::StateReader& r) {
  error_register_read_ = r.get<bool>("error_register_read");
  std::vector<std::int64_t> outputs;
  r.read_list("outputs", outputs_.size(), [&](const canopen::StateReader& item) {
    // set_output() keeps each within its signal's range; an RPDO would carry it as it is.
    const SignalInfo& s = signals_[outputs.size()];
    const std::int64_t v = item.integer("value");
    if (v < s.min || v > s.max) item.fail("value", "is outside " + s.name + "'s range");
    outputs.push_back(v);
  });
  if (outputs.size() != outputs_.size()) r.fail("outputs.count", "differs from this node's signals");
  outputs_ = std::move(outputs);
  // The error register faults every input at once (on_boot_read, on_emcy), an output never.
  std::optional<bool> inputs;
  for (std::size_t i = 0; i < signals_.size(); ++i) {
    const bool f = faulted(i);
    if (signals_[i].output() ? f : inputs.value_or(f) != f) {
      r.fail("error_register_read", "cannot explain signal " + std::to_string(i) + "'s fault: the error register " +
                                        "faults every input or none, and no output");
    }
    if (!signals_[i].output()) inputs = f;
  }
}

}  // namespace oegw::subdevices
