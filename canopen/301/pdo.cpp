#include "canopen/301/pdo.hpp"

#include <algorithm>
#include <charconv>
#include <cstring>
#include <string>

#include "canopen/state.hpp"

namespace oegw::canopen {

namespace {

// Services each PDO of `pdos` (ascending by number) once. A PDO's callback may write PDO
// parameters, which rebuilds the list under the walk; the walk then goes on after the PDO it
// serviced, by number, as a walk over every PDO would (none skipped, none serviced twice).
template <class Pdo, class Fn>
void service_in_order(const std::vector<Pdo*>& pdos, Fn&& service) {
  for (std::size_t i = 0; i < pdos.size(); ++i) {
    Pdo* p = pdos[i];
    service(*p);
    if (i < pdos.size() && pdos[i] == p) continue;
    const auto next = std::upper_bound(pdos.begin(), pdos.end(), p->number(),
                                       [](std::uint16_t n, const Pdo* q) { return n < q->number(); });
    i = static_cast<std::size_t>(next - pdos.begin()) - 1;  // ++i: the first after p
  }
}

constexpr std::uint16_t kRpdoComm = 0x1400;
constexpr std::uint16_t kRpdoMap = 0x1600;
constexpr std::uint16_t kTpdoComm = 0x1800;
constexpr std::uint16_t kTpdoMap = 0x1A00;
constexpr std::uint16_t kMaxPdos = 512;

std::uint16_t comm_index(bool transmit, std::uint16_t n) {
  return static_cast<std::uint16_t>((transmit ? kTpdoComm : kRpdoComm) + n - 1);
}
std::uint16_t map_index(bool transmit, std::uint16_t n) {
  return static_cast<std::uint16_t>((transmit ? kTpdoMap : kRpdoMap) + n - 1);
}

// Copies `n` bits from src (starting at bit `so`) to dst (starting at bit `doff`); bit 0 is the
// least significant bit of byte 0, as CANopen packs PDOs (CiA 301 §7.1.2, §7.2.2).
void copy_bits(const std::uint8_t* src, unsigned so, std::uint8_t* dst, unsigned doff, unsigned n) {
  if (so % 8 == 0 && doff % 8 == 0 && n % 8 == 0) {
    std::memcpy(dst + doff / 8, src + so / 8, n / 8);
    return;
  }
  for (unsigned i = 0; i < n; ++i) {
    const unsigned s = so + i;
    const unsigned d = doff + i;
    const auto mask = static_cast<std::uint8_t>(1u << (d % 8));
    if ((src[s / 8] >> (s % 8)) & 1u) {
      dst[d / 8] = static_cast<std::uint8_t>(dst[d / 8] | mask);
    } else {
      dst[d / 8] = static_cast<std::uint8_t>(dst[d / 8] & ~mask);
    }
  }
}

void install_comm(ObjectDictionary& od, bool transmit, std::uint16_t n, const PdoParameters& p) {
  const std::uint16_t idx = comm_index(transmit, n);
  od.remove(idx);
  od.add_record(idx, (transmit ? "TPDO " : "RPDO ") + std::to_string(n) + " communication parameter");
  od.add_record_member(idx, 1, "COB-ID used by PDO", DataType::Unsigned32, Access::ReadWrite,
                       encode<std::uint32_t>(p.cob_id));
  od.add_record_member(idx, 2, "Transmission type", DataType::Unsigned8, Access::ReadWrite, {p.transmission_type});
  if (transmit)
    od.add_record_member(idx, 3, "Inhibit time", DataType::Unsigned16, Access::ReadWrite,
                         encode<std::uint16_t>(p.inhibit_time));
  od.add_record_member(idx, 5, "Event timer", DataType::Unsigned16, Access::ReadWrite,
                       encode<std::uint16_t>(p.event_timer));
  if (transmit)
    od.add_record_member(idx, 6, "SYNC start value", DataType::Unsigned8, Access::ReadWrite, {p.sync_start});
}

void install_map(ObjectDictionary& od, bool transmit, std::uint16_t n, const PdoParameters& p) {
  const std::uint16_t idx = map_index(transmit, n);
  od.remove(idx);
  od.add_record(idx, (transmit ? "TPDO " : "RPDO ") + std::to_string(n) + " mapping parameter");
  const std::size_t cap = std::min<std::size_t>(64, std::max<std::size_t>(p.mapping_capacity, p.mapping.size()));
  for (std::size_t i = 1; i <= cap; ++i) {
    const std::uint32_t v = i <= p.mapping.size() ? p.mapping[i - 1] : 0;
    od.add_record_member(idx, static_cast<std::uint8_t>(i), "Mapped object " + std::to_string(i), DataType::Unsigned32,
                         Access::ReadWrite, encode<std::uint32_t>(v));
  }
  // Sub-index 0 of a mapping record is the number of mapped objects, not the highest sub-index.
  SubObject* s0 = od.find(idx, 0);
  s0->name = "Number of mapped objects";
  s0->access = Access::ReadWrite;
  s0->default_value = {static_cast<std::uint8_t>(std::min<std::size_t>(p.mapping.size(), cap))};
  s0->value = s0->default_value;
}

}  // namespace

void install_rpdo(ObjectDictionary& od, std::uint16_t n, const PdoParameters& p) {
  if (n < 1 || n > kMaxPdos) return;
  install_comm(od, false, n, p);
  install_map(od, false, n, p);
}

void install_tpdo(ObjectDictionary& od, std::uint16_t n, const PdoParameters& p) {
  if (n < 1 || n > kMaxPdos) return;
  install_comm(od, true, n, p);
  install_map(od, true, n, p);
}

// ---------------------------------------------------------------------------------------------
// Tpdo

bool Tpdo::active() const { return svc_.operational_ && configured(); }

void Tpdo::reload() {
  const std::uint16_t ci = comm_index(true, number_);
  const ObjectDictionary& od = svc_.od_;
  cob_ = CobId{od.get<std::uint32_t>(ci, 1)};
  type_ = od.get<std::uint8_t>(ci, 2);
  inhibit_ = Duration{std::int64_t{od.get<std::uint16_t>(ci, 3)} * 100};
  event_ = std::chrono::milliseconds{od.get<std::uint16_t>(ci, 5)};
  sync_start_ = od.get<std::uint8_t>(ci, 6);
  unsigned bits = 0;
  entries_ = svc_.resolve(true, number_, bits);
  dlc_ = static_cast<std::uint8_t>((bits + 7) / 8);
  reset_runtime();
}

// Kept across a reset: the last payload sent (a reconfiguration such as a new event timer is not
// a change of data) and the end of the inhibit time (no frame sooner, whatever happens).
void Tpdo::reset_runtime() {
  requested_ = false;
  changed_ = false;
  restart_ = true;
  event_deadline_.reset();
  sync_count_ = 0;
  waiting_start_ = sync_start_ != 0;
  have_buffer_ = false;
}

std::array<std::uint8_t, 8> Tpdo::pack() const {
  std::array<std::uint8_t, 8> out{};
  for (const auto& e : entries_) copy_bits(e.sub->value.data(), 0, out.data(), e.bit_offset, e.bits);
  return out;
}

void Tpdo::send(const std::array<std::uint8_t, 8>& payload, TimePoint now) {
  CanFrame f;
  f.id = cob_.can_id();
  f.extended = cob_.extended();
  f.dlc = dlc_;
  f.data = payload;
  svc_.sink_(f);
  last_ = payload;
  have_sent_ = true;
  requested_ = false;
  changed_ = false;
  if (inhibit_.count() > 0) {
    inhibit_until_ = now + inhibit_;
  } else {
    inhibit_until_.reset();
  }
  // CiA 301 §7.5.2.37: the event timer restarts with every transmission.
  if (event_driven() && event_.count() > 0) event_deadline_ = now + event_;
}

void Tpdo::request(TimePoint now) {
  requested_ = true;
  if (now > svc_.last_now_) svc_.last_now_ = now;
  if (event_driven()) service(now);
}

void Tpdo::service(TimePoint now) {
  if (!active() || !event_driven()) return;
  if (restart_) {
    restart_ = false;
    if (event_.count() > 0) event_deadline_ = now + event_;
  }
  if (event_deadline_ && now >= *event_deadline_) {
    requested_ = true;  // "the elapsed timer is considered to be an event" (MCB-402, §5)
    event_deadline_.reset();
  }
  if (!requested_ && !changed_) return;
  // CiA 301: no transmission sooner than the inhibit time after the previous one; the event is
  // kept and the data current when the inhibit time ends are sent.
  if (inhibit_until_ && now < *inhibit_until_) return;
  const auto payload = pack();
  if (requested_ || !have_sent_ || payload != last_) {
    send(payload, now);
  } else {
    changed_ = false;  // rewritten with the same value
  }
}

void Tpdo::on_sync(std::uint8_t counter, TimePoint now) {
  if (!active()) return;
  if (type_ == 0) {
    if (!requested_ && !changed_) return;
    const auto payload = pack();
    if (requested_ || !have_sent_ || payload != last_) {
      send(payload, now);
    } else {
      changed_ = false;
    }
  } else if (type_ <= 240) {
    if (waiting_start_) {
      // CiA 301 §7.5.2.37 sub-index 6: the SYNC whose counter equals the start value is the first
      // one; a SYNC without a counter makes the start value meaningless.
      if (counter == 0) {
        waiting_start_ = false;
      } else if (counter == sync_start_) {
        waiting_start_ = false;
        sync_count_ = 0;
        send(pack(), now);
        return;
      } else {
        return;
      }
    }
    if (++sync_count_ >= type_) {
      sync_count_ = 0;
      send(pack(), now);
    }
  } else if (type_ == 252) {
    buffer_ = pack();
    have_buffer_ = true;
  }
}

void Tpdo::on_rtr(TimePoint now) {
  if (!active() || cob_.bit30()) return;  // bit 30 = 1: no RTR allowed on this PDO
  if (type_ == 252) {
    if (have_buffer_) send(buffer_, now);  // the data sampled at the last SYNC
    return;
  }
  send(pack(), now);
}

std::optional<TimePoint> Tpdo::next_deadline(TimePoint last_now) const {
  if (!active() || !event_driven()) return std::nullopt;
  if (restart_) return last_now;
  std::optional<TimePoint> r = event_deadline_;
  if (requested_ || changed_) {
    const TimePoint due = inhibit_until_ ? *inhibit_until_ : last_now;
    if (!r || due < *r) r = due;
  }
  return r;
}

// ---------------------------------------------------------------------------------------------
// Rpdo

bool Rpdo::active() const { return svc_.operational_ && configured(); }

void Rpdo::reload() {
  const std::uint16_t ci = comm_index(false, number_);
  const ObjectDictionary& od = svc_.od_;
  cob_ = CobId{od.get<std::uint32_t>(ci, 1)};
  type_ = od.get<std::uint8_t>(ci, 2);
  event_ = std::chrono::milliseconds{od.get<std::uint16_t>(ci, 5)};
  unsigned bits = 0;
  entries_ = svc_.resolve(false, number_, bits);
  dlc_ = static_cast<std::uint8_t>((bits + 7) / 8);
  reset_runtime();
}

void Rpdo::reset_runtime() {
  pending_ = false;
  deadline_.reset();
  timed_out_ = false;
}

void Rpdo::receive(const CanFrame& frame, TimePoint now) {
  if (!active()) return;
  if (frame.dlc < dlc_) {
    // CiA 301 §7.2.2.1: a PDO shorter than its mapping is not processed; EMCY 8210h
    // "PDO not processed due to length error".
    if (svc_.on_length_error) svc_.on_length_error(number_, PdoService::kEmcyPdoLengthError);
    return;
  }
  if (frame.dlc > dlc_) {
    // CiA 301 §7.2.2.1: a longer PDO is processed with its first bytes, the rest ignored; the
    // device may signal EMCY 8220h "PDO length exceeded". We process it and report 8220h: the
    // application decides whether to raise that EMCY.
    if (svc_.on_length_error) svc_.on_length_error(number_, PdoService::kEmcyPdoLengthExceeded);
  }
  if (event_.count() > 0) deadline_ = now + event_;
  timed_out_ = false;
  if (type_ <= 240) {
    buffer_ = frame.data;  // synchronous: takes effect at the next SYNC
    pending_ = true;
  } else {
    apply(frame.data.data());
  }
}

void Rpdo::apply(const std::uint8_t* data) {
  for (const auto& e : entries_) {
    if (e.sub == nullptr) continue;  // dummy entry
    std::array<std::uint8_t, 8> tmp{};
    const std::size_t size = e.sub->value.size();
    std::memcpy(tmp.data(), e.sub->value.data(), size);
    copy_bits(data, e.bit_offset, tmp.data(), 0, e.bits);
    // A value refused by the object's limits or hooks is dropped; the other entries still apply.
    (void)svc_.od_.write_resolved(*e.obj, *e.sub, std::span<const std::uint8_t>(tmp.data(), size), Origin::Pdo);
  }
  if (svc_.on_rpdo) svc_.on_rpdo(number_);
}

void Rpdo::on_sync() {
  if (!active() || !pending_) return;
  pending_ = false;
  apply(buffer_.data());
}

void Rpdo::service(TimePoint now) {
  if (!active() || !deadline_ || now < *deadline_) return;
  deadline_.reset();
  timed_out_ = true;
  if (svc_.on_rpdo_timeout) svc_.on_rpdo_timeout(number_);
}

// ---------------------------------------------------------------------------------------------
// PdoService

PdoService::PdoService(ObjectDictionary& od, FrameSink sink) : od_(od), sink_(std::move(sink)) {
  for (std::uint16_t n = 1; n <= kMaxPdos; ++n) {
    if (od_.find(comm_index(false, n)) != nullptr && od_.find(map_index(false, n)) != nullptr) {
      rpdos_.push_back(std::unique_ptr<Rpdo>(new Rpdo(*this, n)));
      install_hooks(false, n);
    }
    if (od_.find(comm_index(true, n)) != nullptr && od_.find(map_index(true, n)) != nullptr) {
      tpdos_.push_back(std::unique_ptr<Tpdo>(new Tpdo(*this, n)));
      install_hooks(true, n);
    }
  }
  subs_ += od_.add_observer([this](std::uint16_t index, std::uint8_t sub, Origin) { on_od_change(index, sub); });
  reload();
}

void PdoService::reload() {
  for (auto& r : rpdos_) r->reload();
  for (auto& t : tpdos_) t->reload();
  rebuild_tables();
}

Tpdo* PdoService::tpdo(std::uint16_t n) {
  for (auto& t : tpdos_)
    if (t->number() == n) return t.get();
  return nullptr;
}

Rpdo* PdoService::rpdo(std::uint16_t n) {
  for (auto& r : rpdos_)
    if (r->number() == n) return r.get();
  return nullptr;
}

void PdoService::install_hooks(bool transmit, std::uint16_t n) {
  subs_ += od_.find(comm_index(transmit, n))
               ->add_write_hook([this, transmit, n](Object&, std::uint8_t sub, std::span<const std::uint8_t> b,
                                                    Origin) { return check_comm_write(transmit, n, sub, b); });
  subs_ += od_.find(map_index(transmit, n))
               ->add_write_hook([this, transmit, n](Object&, std::uint8_t sub, std::span<const std::uint8_t> b,
                                                    Origin) { return check_map_write(transmit, n, sub, b); });
}

SdoAbortCode PdoService::check_comm_write(bool transmit, std::uint16_t n, std::uint8_t sub,
                                          std::span<const std::uint8_t> b) const {
  const std::uint16_t ci = comm_index(transmit, n);
  const CobId cur{od_.get<std::uint32_t>(ci, 1)};
  switch (sub) {
    case 1: {
      if (b.size() != 4) return SdoAbortCode::None;  // the OD refuses the length
      const CobId next{get_u32(b.data())};
      // CiA 301 §7.5.2.35/37: bits 0..29 may not change while the PDO exists (bit 31 = 0).
      if (cur.valid() && next.valid() && (cur.raw() & 0x3FFFFFFFu) != (next.raw() & 0x3FFFFFFFu))
        return SdoAbortCode::InvalidValue;
      // An 11-bit COB-ID with bits 11..28 set (CobId::well_formed) or a restricted CAN-ID
      // (cob::restricted) is refused with 0609 0030h.
      if (!next.well_formed()) return SdoAbortCode::InvalidValue;
      if (next.valid() && !next.extended() && cob::restricted(next.can_id())) return SdoAbortCode::InvalidValue;
      return SdoAbortCode::None;
    }
    case 2: {
      if (b.size() != 1) return SdoAbortCode::None;
      const std::uint8_t t = b[0];
      if (t >= 241 && t <= 251) return SdoAbortCode::InvalidValue;                 // reserved
      if (!transmit && (t == 252 || t == 253)) return SdoAbortCode::InvalidValue;  // TPDO only
      return SdoAbortCode::None;
    }
    case 3:
    case 6:
      // CiA 301 §7.5.2.37: inhibit time and SYNC start value may not change while the PDO exists.
      return cur.valid() ? SdoAbortCode::InvalidValue : SdoAbortCode::None;
    default: return SdoAbortCode::None;
  }
}

// CiA 301 §7.3.5 (PDO mapping procedure), §7.5.2.36/38.
//
// Abort codes when the procedure is not followed: CiA 301 asks for the PDO to be destroyed
// (COB-ID bit 31 = 1) before sub-index 0 changes, and for sub-index 0 to be 0 before the entries
// change. Both refusals are about the present state of the PDO, not about the value written, so
// they use 0800 0022h ("cannot be transferred or stored because of the present device state");
// 0604 0043h ("general parameter incompatibility") would blame the value itself.
SdoAbortCode PdoService::check_map_write(bool transmit, std::uint16_t n, std::uint8_t sub,
                                         std::span<const std::uint8_t> b) const {
  const std::uint16_t mi = map_index(transmit, n);
  if (sub == 0) {
    if (b.size() != 1) return SdoAbortCode::None;
    if (CobId{od_.get<std::uint32_t>(comm_index(transmit, n), 1)}.valid())
      return SdoAbortCode::CannotTransferDeviceState;
    const std::uint8_t count = b[0];
    const Object* obj = od_.find(mi);
    const std::uint8_t capacity = obj->subs().rbegin()->first;
    if (count > capacity) return SdoAbortCode::MappingExceedsPdoLength;
    unsigned total = 0;
    for (std::uint8_t i = 1; i <= count; ++i) {
      unsigned bits = 0;
      const SdoAbortCode c = check_mapping(transmit, od_.get<std::uint32_t>(mi, i), bits);
      if (c != SdoAbortCode::None) return c;
      total += bits;
      if (total > 64) return SdoAbortCode::MappingExceedsPdoLength;
    }
    return SdoAbortCode::None;
  }
  if (od_.get<std::uint8_t>(mi, 0) != 0) return SdoAbortCode::CannotTransferDeviceState;
  if (b.size() != 4) return SdoAbortCode::None;
  const std::uint32_t entry = get_u32(b.data());
  if (entry == 0) return SdoAbortCode::None;  // clearing an entry
  unsigned bits = 0;
  return check_mapping(transmit, entry, bits);  // step 3 already checks the object
}

SdoAbortCode PdoService::check_mapping(bool transmit, std::uint32_t entry, unsigned& bits) const {
  const auto index = static_cast<std::uint16_t>(entry >> 16);
  const auto sub = static_cast<std::uint8_t>(entry >> 8);
  bits = entry & 0xFFu;
  if (index == 0) return SdoAbortCode::ObjectDoesNotExist;
  if (index <= 0x0007) {
    // Dummy entries (CiA 301 §7.4.7.1: the static data types BOOLEAN..UNSIGNED32) reserve space
    // in an RPDO; they are allowed whether or not the OD lists the DEFTYPE objects. A TPDO has no
    // use for them.
    if (transmit) return SdoAbortCode::CannotBeMapped;
    const auto type = static_cast<DataType>(index);
    const unsigned expected = static_cast<unsigned>(fixed_size(type) * 8);
    if (bits == expected || (type == DataType::Boolean && bits == 1)) return SdoAbortCode::None;
    return SdoAbortCode::CannotBeMapped;
  }
  // CiA 301 §7.3.5 names 0602 0000h for a mapped object that does not exist, whether the index
  // or only the sub-index is missing.
  const SubObject* s = od_.find(index, sub);
  if (s == nullptr) return SdoAbortCode::ObjectDoesNotExist;
  const SdoAbortCode access =
      transmit ? od_.check_read(index, sub, Origin::Pdo) : od_.check_write(index, sub, Origin::Pdo);
  if (access != SdoAbortCode::None) return SdoAbortCode::CannotBeMapped;
  const std::size_t size = fixed_size(s->type);
  if (size == 0 || size > 8) return SdoAbortCode::CannotBeMapped;
  if (bits == size * 8 || (s->type == DataType::Boolean && bits == 1)) return SdoAbortCode::None;
  return SdoAbortCode::CannotBeMapped;  // the length must be the object's
}

std::vector<pdo_detail::Mapped> PdoService::resolve(bool transmit, std::uint16_t n, unsigned& total_bits) {
  std::vector<pdo_detail::Mapped> out;
  total_bits = 0;
  const std::uint16_t mi = map_index(transmit, n);
  const std::uint8_t count = od_.get<std::uint8_t>(mi, 0);
  for (std::uint8_t i = 1; i <= count; ++i) {
    if (od_.find(mi, i) == nullptr) return {};
    const std::uint32_t entry = od_.get<std::uint32_t>(mi, i);
    unsigned bits = 0;
    // Defaults are checked as a written sub-index 0 would be; an invalid one leaves the PDO
    // without mapping (inactive) rather than sending garbage.
    if (check_mapping(transmit, entry, bits) != SdoAbortCode::None || total_bits + bits > 64) {
      total_bits = 0;
      return {};
    }
    pdo_detail::Mapped m;
    const auto index = static_cast<std::uint16_t>(entry >> 16);
    if (index > 0x0007) {
      m.obj = od_.find(index);
      m.sub = m.obj->find(static_cast<std::uint8_t>(entry >> 8));
    }
    m.bit_offset = static_cast<std::uint16_t>(total_bits);
    m.bits = static_cast<std::uint8_t>(bits);
    out.push_back(m);
    total_bits += bits;
  }
  return out;
}

void PdoService::rebuild_tables() {
  rx_by_id_.clear();
  rtr_by_id_.clear();
  watch_.clear();
  timed_tpdos_.clear();
  timed_rpdos_.clear();
  for (auto& r : rpdos_) {
    if (!r->configured()) continue;
    rx_by_id_[key(r->cob_)] = r.get();
    timed_rpdos_.push_back(r.get());
  }
  for (auto& t : tpdos_) {
    if (!t->configured()) continue;
    if (t->event_driven()) timed_tpdos_.push_back(t.get());
    if (!t->cob_.bit30()) rtr_by_id_[key(t->cob_)] = t.get();
    for (const auto& e : t->entries_) {
      auto& v = watch_[static_cast<std::uint32_t>(e.obj->index()) << 8 | e.sub->sub_index];
      if (std::find(v.begin(), v.end(), t.get()) == v.end()) v.push_back(t.get());
    }
  }
}

void PdoService::on_od_change(std::uint16_t index, std::uint8_t sub) {
  if (index >= kRpdoComm && index < kTpdoMap + kMaxPdos) {
    const bool transmit = index >= kTpdoComm;
    const std::uint16_t base =
        transmit ? (index >= kTpdoMap ? kTpdoMap : kTpdoComm) : (index >= kRpdoMap ? kRpdoMap : kRpdoComm);
    const auto n = static_cast<std::uint16_t>(index - base + 1);
    if (transmit) {
      if (Tpdo* t = tpdo(n)) {
        const bool was = t->active();
        t->reload();
        // A TPDO that becomes active while Operational sends its data once, as on entering
        // Operational (CiA 852 §12.1).
        if (!was && t->active() && t->event_driven()) t->requested_ = true;
      }
    } else if (Rpdo* r = rpdo(n)) {
      r->reload();
    }
    rebuild_tables();
    return;
  }
  auto it = watch_.find(static_cast<std::uint32_t>(index) << 8 | sub);
  if (it == watch_.end()) return;
  for (Tpdo* t : it->second) t->changed_ = true;
}

void PdoService::set_operational(bool operational, TimePoint now) {
  if (now > last_now_) last_now_ = now;
  if (operational == operational_) return;
  operational_ = operational;
  for (auto& r : rpdos_) r->reset_runtime();
  for (auto& t : tpdos_) {
    t->reset_runtime();
    // CiA 852 §12.1: "all TPDOs shall be transmitted after the device transits into NMT
    // Operational state".
    if (operational && t->event_driven()) t->requested_ = true;
  }
}

bool PdoService::on_frame(const CanFrame& frame, TimePoint now) {
  if (now > last_now_) last_now_ = now;
  const std::uint32_t k = frame.id | (frame.extended ? 0x80000000u : 0u);
  if (frame.rtr) {
    auto it = rtr_by_id_.find(k);
    if (it == rtr_by_id_.end()) return false;
    it->second->on_rtr(now);
    return true;
  }
  auto it = rx_by_id_.find(k);
  if (it == rx_by_id_.end()) return false;
  it->second->receive(frame, now);
  return true;
}

void PdoService::on_sync(std::uint8_t counter, TimePoint now) {
  if (now > last_now_) last_now_ = now;
  if (!operational_) return;
  for (auto& r : rpdos_) r->on_sync();              // actuate outputs received before this SYNC
  for (auto& t : tpdos_) t->on_sync(counter, now);  // then sample inputs
}

void PdoService::advance(TimePoint now) {
  if (now > last_now_) last_now_ = now;
  if (!operational_) return;  // no PDO is active()
  service_in_order(timed_tpdos_, [now](Tpdo& t) { t.service(now); });
  service_in_order(timed_rpdos_, [now](Rpdo& r) { r.service(now); });
}

std::optional<TimePoint> PdoService::next_deadline() const {
  if (!operational_) return std::nullopt;
  std::optional<TimePoint> best;
  auto consider = [&](std::optional<TimePoint> d) {
    if (d && (!best || *d < *best)) best = d;
  };
  for (const Tpdo* t : timed_tpdos_) consider(t->next_deadline(last_now_));
  for (const Rpdo* r : timed_rpdos_) consider(r->next_deadline());
  return best;
}

// ---- run-time state ----------------------------------------------------------------------
// A PDO writes only what differs from a PDO just reload()ed; what it leaves out reads back as
// that. The dictionary holds up to 512 of each, most of them never used.

namespace {

using Payload = std::array<std::uint8_t, 8>;

Payload payload_of(const StateReader& r, std::string_view key) {
  const std::vector<std::uint8_t> b = r.bytes(key);
  if (b.size() != 8) r.fail(key, "is not 8 bytes");
  Payload out{};
  std::copy(b.begin(), b.end(), out.begin());
  return out;
}

}  // namespace

void Tpdo::export_state(StateWriter& w) const {
  if (requested_) w.put("requested", true);
  if (changed_) w.put("changed", true);
  if (!restart_) w.put("restart", false);
  // What the next payload is compared with (CiA 301 §7.5.2.37: types FEh/FFh send on a change).
  if (have_sent_) w.put_bytes("last", last_);
  w.put("inhibit_until", inhibit_until_);
  w.put("event_deadline", event_deadline_);
  if (sync_count_ != 0) w.put("sync_count", sync_count_);
  if (waiting_start_ != (sync_start_ != 0)) w.put("waiting_start", waiting_start_);
  if (have_buffer_) w.put_bytes("buffer", buffer_);  // type FCh: sampled at the last SYNC
}

void Tpdo::import_state(const StateReader& r) {
  requested_ = r.get_or("requested", false);
  changed_ = r.get_or("changed", false);
  restart_ = r.get_or("restart", true);
  have_sent_ = r.has("last");
  last_ = have_sent_ ? payload_of(r, "last") : Payload{};
  inhibit_until_ = r.optional_time("inhibit_until");
  event_deadline_ = r.optional_time("event_deadline");
  sync_count_ = r.get_or("sync_count", 0u);
  waiting_start_ = r.get_or("waiting_start", sync_start_ != 0);
  have_buffer_ = r.has("buffer");
  buffer_ = have_buffer_ ? payload_of(r, "buffer") : Payload{};
}

void Rpdo::export_state(StateWriter& w) const {
  if (pending_) w.put_bytes("pending", buffer_);  // synchronous: applied at the next SYNC
  w.put("deadline", deadline_);
  if (timed_out_) w.put("timed_out", true);
}

void Rpdo::import_state(const StateReader& r) {
  pending_ = r.has("pending");
  buffer_ = pending_ ? payload_of(r, "pending") : Payload{};
  deadline_ = r.optional_time("deadline");
  timed_out_ = r.get_or("timed_out", false);
}

void PdoService::export_state(StateWriter& w) const {
  w.put("operational", operational_);
  w.put("last_now", last_now_);
  for (const auto& t : tpdos_) {
    const StateWriter::Scope scope(w, "tpdo." + std::to_string(t->number()));
    t->export_state(w);
  }
  for (const auto& rp : rpdos_) {
    const StateWriter::Scope scope(w, "rpdo." + std::to_string(rp->number()));
    rp->export_state(w);
  }
}

void PdoService::import_state(const StateReader& r) {
  // A PDO this dictionary does not have is another configuration.
  for (const bool transmit : {true, false}) {
    const StateReader pr = r.in(transmit ? "tpdo" : "rpdo");
    for (const std::string& n : pr.children()) {
      std::uint16_t number = 0;
      const auto [end, ec] = std::from_chars(n.data(), n.data() + n.size(), number);
      const auto numbered = [number](const auto& p) { return p->number() == number; };
      const bool known = ec == std::errc{} && end == n.data() + n.size() &&
                         (transmit ? std::ranges::any_of(tpdos_, numbered) : std::ranges::any_of(rpdos_, numbered));
      if (!known) pr.fail(n, "is no PDO of this dictionary");
    }
  }
  const bool operational = r.get<bool>("operational");
  const TimePoint last_now = r.time("last_now");
  for (auto& t : tpdos_) t->import_state(r.in("tpdo." + std::to_string(t->number())));
  for (auto& rp : rpdos_) rp->import_state(r.in("rpdo." + std::to_string(rp->number())));
  operational_ = operational;
  last_now_ = last_now;
}

}  // namespace oegw::canopen
