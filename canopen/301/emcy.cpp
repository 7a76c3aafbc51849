#include "canopen/301/emcy.hpp"

#include <algorithm>
#include <string>

#include "canopen/state.hpp"

namespace oegw::canopen {

namespace {
constexpr std::uint16_t kErrorRegister = 0x1001;
constexpr std::uint16_t kErrorField = 0x1003;
constexpr std::uint16_t kCobIdEmcy = 0x1014;
constexpr std::uint16_t kInhibitEmcy = 0x1015;
constexpr std::uint16_t kEmcyConsumer = 0x1028;
}  // namespace

EmcyProducer::EmcyProducer(ObjectDictionary& od, FrameSink sink, NodeId node, EmcyConfig config)
    : od_(od), sink_(std::move(sink)), queue_limit_(config.queue_limit) {
  if (od_.find(kErrorRegister) == nullptr)
    od_.add_var(kErrorRegister, "Error register", DataType::Unsigned8, Access::ReadOnly, {0});
  if (od_.find(kErrorField) == nullptr) {
    const std::uint8_t n = std::clamp<std::uint8_t>(config.history_size, 1, 254);
    od_.add_array(kErrorField, "Pre-defined error field", DataType::Unsigned32, Access::ReadOnly, n, {0, 0, 0, 0});
    SubObject* s0 = od_.find(kErrorField, 0);
    s0->name = "Number of errors";
    s0->access = Access::ReadWrite;
    s0->default_value = {0};
    s0->value = {0};
  }
  if (od_.find(kCobIdEmcy) == nullptr)
    od_.add_var(kCobIdEmcy, "COB-ID EMCY", DataType::Unsigned32, Access::ReadWrite,
                encode<std::uint32_t>(config.cob_id.value_or(cob::kEmcy + node.value())));
  if (od_.find(kInhibitEmcy) == nullptr)
    od_.add_var(kInhibitEmcy, "Inhibit time EMCY", DataType::Unsigned16, Access::ReadWrite,
                encode<std::uint16_t>(config.inhibit_time));

  // CiA 301 §7.5.2.13: only 0 may be written to 1003h:00 (clears the history), 0609 0030h
  // otherwise. The entries themselves are read-only to SDO.
  subs_ +=
      od_.find(kErrorField)->add_write_hook([](Object&, std::uint8_t sub, std::span<const std::uint8_t> b, Origin o) {
        if (o == Origin::Local || sub != 0) return SdoAbortCode::None;
        return (b.size() == 1 && b[0] == 0) ? SdoAbortCode::None : SdoAbortCode::InvalidValue;
      });
  // CiA 301 §7.5.2.17: bits 0..29 of 1014h may not change while the EMCY is valid (bit 31 = 0).
  subs_ +=
      od_.find(kCobIdEmcy)->add_write_hook([this](Object&, std::uint8_t, std::span<const std::uint8_t> b, Origin o) {
        if (o == Origin::Local || b.size() != 4) return SdoAbortCode::None;
        const CobId cur{od_.get<std::uint32_t>(kCobIdEmcy, 0)};
        const CobId next{get_u32(b.data())};
        if (cur.valid() && next.valid() && (cur.raw() & 0x3FFFFFFFu) != (next.raw() & 0x3FFFFFFFu))
          return SdoAbortCode::InvalidValue;
        if (!next.well_formed()) return SdoAbortCode::InvalidValue;  // bits 11..28 of an 11-bit COB-ID
        return SdoAbortCode::None;
      });
  subs_ += od_.add_observer([this](std::uint16_t index, std::uint8_t sub, Origin) {
    if (index != kErrorField || sub != 0 || od_.get<std::uint8_t>(kErrorField, 0) != 0) return;
    Object* obj = od_.find(kErrorField);
    for (auto& [si, s] : obj->subs())
      if (si != 0) std::fill(s.value.begin(), s.value.end(), std::uint8_t{0});
  });
}

Duration EmcyProducer::inhibit() const { return Duration{std::int64_t{od_.get<std::uint16_t>(kInhibitEmcy, 0)} * 100}; }

bool EmcyProducer::active(std::uint16_t code) const {
  return std::any_of(active_.begin(), active_.end(), [code](const ActiveError& e) { return e.code == code; });
}

std::uint8_t EmcyProducer::error_register() const { return od_.get<std::uint8_t>(kErrorRegister, 0); }

void EmcyProducer::update_register() {
  std::uint8_t reg = 0;
  for (const auto& e : active_) reg = static_cast<std::uint8_t>(reg | e.bits | 0x01);
  (void)od_.set<std::uint8_t>(kErrorRegister, 0, reg, Origin::Local);
}

void EmcyProducer::push_history(std::uint32_t entry) {
  Object* obj = od_.find(kErrorField);
  const std::uint8_t capacity = obj->subs().rbegin()->first;
  const std::uint8_t count = od_.get<std::uint8_t>(kErrorField, 0);
  // Newest at sub-index 1; older ones move up, the oldest falls off the end.
  for (std::uint8_t i = capacity; i >= 2; --i)
    (void)od_.set<std::uint32_t>(kErrorField, i, od_.get<std::uint32_t>(kErrorField, static_cast<std::uint8_t>(i - 1)));
  (void)od_.set<std::uint32_t>(kErrorField, 1, entry);
  (void)od_.set<std::uint8_t>(kErrorField, 0, std::min<std::uint8_t>(static_cast<std::uint8_t>(count + 1), capacity));
}

bool EmcyProducer::emit(std::uint16_t code, const EmcyManufacturerField& msef, TimePoint now, bool relayed) {
  const CobId cob{od_.get<std::uint32_t>(kCobIdEmcy, 0)};
  if (!cob.valid()) return false;
  CanFrame f;
  f.id = cob.can_id();
  f.extended = cob.extended();
  f.dlc = 8;
  put_u16(f.data.data(), code);
  f.data[2] = error_register();
  std::copy(msef.begin(), msef.end(), f.data.begin() + 3);
  const Duration inh = inhibit();
  const bool inhibited = inh.count() > 0 && last_sent_ && now < *last_sent_ + inh;
  if (inhibited || !queue_.empty()) {
    if (queue_.size() >= queue_limit_) {
      // Full: a relayed EMCY is dropped; an own one takes the place of the oldest relayed one
      // queued, and is dropped only when the queue holds nothing but own EMCYs.
      auto relayed_one = std::find_if(queue_.begin(), queue_.end(), [](const Queued& q) { return q.relayed; });
      ++dropped_;
      if (relayed || relayed_one == queue_.end()) return false;
      queue_.erase(relayed_one);
    }
    queue_.push_back({f, relayed});
    return true;
  }
  sink_(f);
  last_sent_ = now;
  return true;
}

bool EmcyProducer::raise(std::uint16_t code, std::uint8_t register_bits, const EmcyManufacturerField& msef,
                         TimePoint now, std::uint16_t info) {
  if (active(code)) return false;
  active_.push_back({code, register_bits});
  update_register();
  push_history(std::uint32_t{code} | std::uint32_t{info} << 16);
  (void)emit(code, msef, now);
  return true;
}

bool EmcyProducer::report(std::uint16_t code, const EmcyManufacturerField& msef, std::uint16_t info, TimePoint now,
                          bool relayed) {
  // CiA 301 §7.5.2.13: 1003h lists the errors that occurred; an error reset is none.
  if (code != kErrorReset) push_history(std::uint32_t{code} | std::uint32_t{info} << 16);
  return emit(code, msef, now, relayed);
}

void EmcyProducer::restart() {
  active_.clear();
  queue_.clear();
  last_sent_.reset();
  update_register();
}

bool EmcyProducer::clear(std::uint16_t code, TimePoint now, const EmcyManufacturerField& reset_msef) {
  auto it = std::find_if(active_.begin(), active_.end(), [code](const ActiveError& e) { return e.code == code; });
  if (it == active_.end()) return false;
  active_.erase(it);
  update_register();
  // CiA 301 §7.2.7.2: when the last error is gone the producer sends "error reset" (0000h). With
  // errors remaining it may stay silent, which it does.
  if (active_.empty()) (void)emit(kErrorReset, reset_msef, now);
  return true;
}

void EmcyProducer::advance(TimePoint now) {
  if (queue_.empty()) return;  // the usual case: no dictionary read
  const Duration inh = inhibit();
  while (!queue_.empty() && (inh.count() == 0 || !last_sent_ || now >= *last_sent_ + inh)) {
    sink_(queue_.front().frame);
    queue_.pop_front();
    last_sent_ = now;
  }
}

std::optional<TimePoint> EmcyProducer::next_deadline() const {
  if (queue_.empty()) return std::nullopt;
  if (!last_sent_) return TimePoint{};
  return *last_sent_ + inhibit();
}

// ---------------------------------------------------------------------------------------------

EmcyConsumer::EmcyConsumer(ObjectDictionary& od, EmcyHandler handler, std::uint8_t nodes)
    : od_(od), handler_(std::move(handler)) {
  if (od_.find(kEmcyConsumer) == nullptr) {
    od_.add_array(kEmcyConsumer, "Emergency consumer object", DataType::Unsigned32, Access::ReadWrite,
                  std::min<std::uint8_t>(nodes, 127), {0, 0, 0, 0});
    for (auto& [si, s] : od_.find(kEmcyConsumer)->subs()) {
      if (si == 0) continue;
      s.default_value = encode<std::uint32_t>(cob::kEmcy + si);
      s.value = s.default_value;
    }
  }
  // The consumed COB-IDs: an 11-bit one with bits 11..28 set is refused (CobId::well_formed).
  subs_ +=
      od_.find(kEmcyConsumer)->add_write_hook([](Object&, std::uint8_t sub, std::span<const std::uint8_t> b, Origin o) {
        if (o == Origin::Local || sub == 0 || b.size() != 4) return SdoAbortCode::None;
        return CobId{get_u32(b.data())}.well_formed() ? SdoAbortCode::None : SdoAbortCode::InvalidValue;
      });
  subs_ += od_.add_observer([this](std::uint16_t index, std::uint8_t, Origin) {
    if (index == kEmcyConsumer) rebuild();
  });
  rebuild();
}

void EmcyConsumer::rebuild() {
  by_id_.clear();
  const Object* obj = od_.find(kEmcyConsumer);
  if (obj == nullptr) return;
  for (const auto& [si, s] : obj->subs()) {
    if (si == 0 || si > 127 || s.value.size() != 4) continue;
    const CobId cob{get_u32(s.value.data())};
    // Two entries on one COB-ID is a configuration error; the lower node-ID keeps it.
    if (cob.valid()) by_id_.emplace(cob.can_id() | (cob.extended() ? 0x80000000u : 0u), si);
  }
}

bool EmcyConsumer::on_frame(const CanFrame& frame, TimePoint now) {
  if (frame.rtr) return false;
  auto it = by_id_.find(frame.id | (frame.extended ? 0x80000000u : 0u));
  if (it == by_id_.end()) return false;
  // An EMCY is 8 bytes; a shorter one (seen from some devices) is read with zeros for the
  // missing bytes rather than lost.
  EmcyMessage m;
  m.node = NodeId{it->second};
  std::array<std::uint8_t, 8> d{};
  std::copy_n(frame.data.begin(), frame.dlc, d.begin());
  m.code = get_u16(d.data());
  m.error_register = d[2];
  std::copy_n(d.begin() + 3, 5, m.msef.begin());
  if (handler_) handler_(m, now);
  return true;
}

void EmcyProducer::export_state(StateWriter& w) const {
  w.put_list("active", active_.size(), [&](std::size_t i) {
    w.put("code", active_[i].code);
    w.put("bits", active_[i].bits);
  });
  // Held back by the 1015h inhibit time (CiA 301 §7.2.7.3.3), in order.
  w.put_list("queue", queue_.size(), [&](std::size_t i) {
    w.put("frame", queue_[i].frame);
    w.put("relayed", queue_[i].relayed);
  });
  w.put("last_sent", last_sent_);
  w.put("dropped", dropped_);
}

void EmcyProducer::import_state(const StateReader& r) {
  std::vector<ActiveError> active;
  r.read_list("active", 0xFFFF, [&](const StateReader& item) {
    active.push_back(ActiveError{item.get<std::uint16_t>("code"), item.get<std::uint8_t>("bits")});
  });
  std::deque<Queued> queue;
  r.read_list("queue", queue_limit_, [&](const StateReader& item) {
    queue.push_back(Queued{item.frame("frame"), item.get<bool>("relayed")});
  });
  const std::optional<TimePoint> last_sent = r.optional_time("last_sent");
  const auto dropped = r.get<std::uint64_t>("dropped");
  active_ = std::move(active);
  queue_ = std::move(queue);
  last_sent_ = last_sent;
  dropped_ = static_cast<std::size_t>(dropped);
}

}  // namespace oegw::canopen
