#include "canopen/301/heartbeat.hpp"

#include "canopen/state.hpp"

namespace oegw::canopen {

namespace {
constexpr std::uint16_t kConsumerIndex = 0x1016;
constexpr std::uint16_t kProducerIndex = 0x1017;

struct Decoded {
  NodeId node;
  Duration time;
  bool used;
};
Decoded decode_entry(std::uint32_t v) {
  const NodeId node{static_cast<std::uint8_t>((v >> 16) & 0xFF)};
  const Duration time = std::chrono::milliseconds(v & 0xFFFF);
  return {node, time, node.valid() && time.count() != 0};
}
}  // namespace

Object& install_heartbeat_producer_objects(ObjectDictionary& od, std::uint16_t default_ms) {
  if (Object* o = od.find(kProducerIndex)) return *o;
  return od.add_var(kProducerIndex, "Producer heartbeat time", DataType::Unsigned16, Access::ReadWrite,
                    encode<std::uint16_t>(default_ms));
}

Object& install_heartbeat_consumer_objects(ObjectDictionary& od, std::uint8_t entries) {
  if (Object* o = od.find(kConsumerIndex)) return *o;
  return od.add_array(kConsumerIndex, "Consumer heartbeat time", DataType::Unsigned32, Access::ReadWrite, entries,
                      encode<std::uint32_t>(0));
}

// ---------------------------------------------------------------- producer

HeartbeatProducer::HeartbeatProducer(ObjectDictionary& od, NodeId node_id, FrameSink sink)
    : od_(od), node_id_(node_id), sink_(std::move(sink)) {
  reload();
  subs_ += od_.add_observer([this](std::uint16_t index, std::uint8_t sub, Origin) {
    if (index == kProducerIndex && sub == 0) reload();
  });
}

void HeartbeatProducer::set_period_ms(std::uint16_t ms) { period_ = std::chrono::milliseconds(ms); }

void HeartbeatProducer::reload() { set_period_ms(od_.get<std::uint16_t>(kProducerIndex, 0)); }

void HeartbeatProducer::start(NmtState state, NodeId node_id, TimePoint now) {
  state_ = state;
  node_id_ = node_id;
  running_ = node_id.valid();
  reference_ = now;
}

void HeartbeatProducer::stop() { running_ = false; }

std::optional<TimePoint> HeartbeatProducer::next_deadline() const {
  if (!running_ || period_.count() == 0) return std::nullopt;
  return reference_ + period_;
}

void HeartbeatProducer::advance(TimePoint now) {
  const auto due = next_deadline();
  if (!due || now < *due) return;
  if (sink_) sink_(CanFrame(cob::kHeartbeat + node_id_.value(), {static_cast<std::uint8_t>(state_)}));
  // Keep the cadence when called on time; after a late call (or a shortened period whose
  // moment had passed) count from now rather than sending a burst.
  reference_ = (now - *due < period_) ? *due : now;
}

// ---------------------------------------------------------------- consumer

HeartbeatConsumer::HeartbeatConsumer(ObjectDictionary& od) : od_(od) {
  Object* obj = od_.find(kConsumerIndex);
  std::uint8_t count = 0;
  if (obj != nullptr) {
    for (const auto& [sub, s] : obj->subs()) count = std::max(count, sub);
    subs_ += obj->add_write_hook([](Object& o, std::uint8_t sub, std::span<const std::uint8_t> bytes, Origin) {
      if (sub == 0 || bytes.size() != 4) return SdoAbortCode::None;
      const Decoded d = decode_entry(get_u32(bytes.data()));
      if (!d.used) return SdoAbortCode::None;
      for (const auto& [other, s] : o.subs()) {
        if (other == 0 || other == sub || s.value.size() != 4) continue;
        const Decoded e = decode_entry(get_u32(s.value.data()));
        if (e.used && e.node == d.node) return SdoAbortCode::ParameterIncompatibility;
      }
      return SdoAbortCode::None;
    });
    subs_ += od_.add_observer([this](std::uint16_t index, std::uint8_t sub, Origin) {
      if (index == kConsumerIndex && sub != 0) load_entry(sub);
    });
  }
  entries_.resize(count);
  reload();
}

void HeartbeatConsumer::load_entry(std::uint8_t sub) {
  if (sub == 0 || sub > entries_.size()) return;
  Entry& e = entries_[sub - 1u];
  const Decoded d = decode_entry(od_.get<std::uint32_t>(kConsumerIndex, sub));
  e = Entry{};
  forget_deadline();
  // A duplicate can only come from values set without hooks (a stored-parameter load): the
  // first entry for a node wins, so a node is never reported twice.
  for (const Entry& other : entries_)
    if (&other != &e && other.status != Status::Unused && other.node == d.node) return;
  if (d.used) {
    e.node = d.node;
    e.time = d.time;
    e.status = Status::Waiting;
  }
}

void HeartbeatConsumer::reload() {
  for (Entry& e : entries_) e = Entry{};  // so that stale entries do not count as duplicates
  for (std::size_t i = 0; i < entries_.size(); ++i) load_entry(static_cast<std::uint8_t>(i + 1));
  forget_deadline();
}

bool HeartbeatConsumer::on_frame(const CanFrame& frame, TimePoint now) {
  if (frame.extended || frame.rtr || frame.id <= cob::kHeartbeat || frame.id > cob::kHeartbeat + 127) return false;
  const NodeId node{static_cast<std::uint8_t>(frame.id - cob::kHeartbeat)};
  bool mine = false;
  for (Entry& e : entries_) {
    if (e.status == Status::Unused || e.node != node) continue;
    mine = true;
    if (frame.dlc != 1 || !is_nmt_state(frame.data[0])) {
      ++invalid_frames_;
      continue;
    }
    // A heartbeat that arrives after the consumer time (the caller reached its timers late, or
    // a frame was read before them) first ends the monitoring period it overran: the time-out
    // is reported, then the heartbeat resumes monitoring as any returning one does.
    if (e.status == Status::Active && now >= e.last + e.time) {
      e.status = Status::TimedOut;
      forget_deadline();  // before each callback: one may ask next_deadline()
      if (on_timeout_) on_timeout_(e.node);
    }
    const auto state = static_cast<NmtState>(frame.data[0]);
    const bool changed = e.state != state;
    e.state = state;
    if (state == NmtState::Initialisation) {
      e.status = Status::Waiting;
      forget_deadline();
      if (on_boot_) on_boot_(node);
      continue;
    }
    e.status = Status::Active;
    e.last = now;
    forget_deadline();
    if (changed && on_state_) on_state_(node, state);
    if (on_heartbeat_) on_heartbeat_(node, state);
  }
  return mine;
}

void HeartbeatConsumer::advance(TimePoint now) {
  if (deadline_known_ && (!deadline_ || now < *deadline_)) return;  // no entry is due
  for (Entry& e : entries_) {
    if (e.status != Status::Active || now < e.last + e.time) continue;
    e.status = Status::TimedOut;
    forget_deadline();
    if (on_timeout_) on_timeout_(e.node);
  }
}

std::optional<TimePoint> HeartbeatConsumer::next_deadline() const {
  if (deadline_known_) return deadline_;
  std::optional<TimePoint> next;
  for (const Entry& e : entries_) {
    if (e.status != Status::Active) continue;
    const TimePoint t = e.last + e.time;
    if (!next || t < *next) next = t;
  }
  deadline_ = next;
  deadline_known_ = true;
  return next;
}

const HeartbeatConsumer::Entry* HeartbeatConsumer::find(NodeId node) const {
  for (const Entry& e : entries_)
    if (e.status != Status::Unused && e.node == node) return &e;
  return nullptr;
}

HeartbeatConsumer::Status HeartbeatConsumer::status(NodeId node) const {
  const Entry* e = find(node);
  return e == nullptr ? Status::Unused : e->status;
}

std::optional<NmtState> HeartbeatConsumer::last_state(NodeId node) const {
  const Entry* e = find(node);
  return e == nullptr ? std::nullopt : e->state;
}

void HeartbeatProducer::export_state(StateWriter& w) const {
  w.put("node_id", node_id_.value());  // start()'s: LSS may have changed it (CiA 305)
  w.put("state", state_);
  w.put("running", running_);
  w.put("reference", reference_);
}

void HeartbeatProducer::import_state(const StateReader& r) {
  const NodeId node_id = r.node_id("node_id");
  const NmtState state = r.nmt_state("state");
  const bool running = r.get<bool>("running");
  reference_ = r.time("reference");
  node_id_ = node_id;
  state_ = state;
  running_ = running;
}

void HeartbeatConsumer::export_state(StateWriter& w) const {
  w.put("invalid_frames", invalid_frames_);
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    const Entry& e = entries_[i];
    if (e.status == Status::Unused) continue;
    const StateWriter::Scope scope(w, std::to_string(i + 1));
    w.put("node", e.node.value());
    w.put("status", e.status);
    w.put("last", e.last);
    if (e.state) w.put("state", *e.state);
  }
}

void HeartbeatConsumer::import_state(const StateReader& r) {
  std::vector<Entry> entries = entries_;
  for (std::size_t i = 0; i < entries.size(); ++i) {
    Entry& e = entries[i];
    const StateReader er = r.in(std::to_string(i + 1));
    if (e.status == Status::Unused) {
      if (er.has("node")) er.fail("node", "is set, and 1016h:" + std::to_string(i + 1) + " is not in use here");
      continue;
    }
    if (er.get<std::uint8_t>("node") != e.node.value()) {
      er.fail("node", "differs: 1016h:" + std::to_string(i + 1) + " watches node " + std::to_string(e.node.value()));
    }
    const auto status = er.get<std::uint8_t>("status");
    if (status == static_cast<std::uint8_t>(Status::Unused) || status > static_cast<std::uint8_t>(Status::TimedOut)) {
      er.fail("status", "= " + std::to_string(status) + " is no consumer status");
    }
    e.status = static_cast<Status>(status);
    e.last = er.time("last");
    e.state = er.has("state") ? std::optional<NmtState>(er.nmt_state("state")) : std::nullopt;
  }
  invalid_frames_ = r.get<std::uint64_t>("invalid_frames");
  entries_ = std::move(entries);
  forget_deadline();
}

}  // namespace oegw::canopen
