#include "canopen/master.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "canopen/state.hpp"

namespace oegw::canopen {

namespace {
ObjectDictionary& with_consumer_objects(ObjectDictionary& od, std::uint8_t entries) {
  if (od.find(0x1016) == nullptr) install_heartbeat_consumer_objects(od, entries);
  return od;
}
}  // namespace

Master::Master(ObjectDictionary& od, FrameSink sink, MasterConfig config)
    : od_(with_consumer_objects(od, config.heartbeat_entries)),
      sink_(std::move(sink)),
      cfg_(config),
      nmt_([this](const CanFrame& f) { sink_(f); }),
      hb_(od_),
      emcy_(od_, [this](const EmcyMessage& m, TimePoint t) {
        if (on_emcy) on_emcy(m, t);
      }) {
  sdo_pacer_ = SdoPacer(cfg_.sdo_request_gap);
  if (cfg_.sync_period.count() > 0) {
    const auto us = std::chrono::duration_cast<std::chrono::microseconds>(cfg_.sync_period).count();
    sync_ = std::make_unique<SyncService>(
        od_, [this](const CanFrame& f) { sink_(f); },
        SyncConfig{.cob_id = cob::kSync | CobId::kBit30, .period_us = static_cast<std::uint32_t>(us)});
  }
  hb_.on_timeout([this](NodeId n) {
    if (on_heartbeat_timeout) on_heartbeat_timeout(n);
  });
  hb_.on_state([this](NodeId n, NmtState s) {
    if (on_state) on_state(n, s);
  });
  hb_.on_heartbeat([this](NodeId n, NmtState s) {
    if (on_heartbeat) on_heartbeat(n, s);
  });
}

SdoClient& Master::sdo(NodeId server) {
  auto& slot = sdo_[server.value()];
  if (!slot) {
    SdoClientConfig c = SdoClientConfig::for_node(server);
    c.timeout = cfg_.sdo_timeout;
    slot = std::make_unique<SdoClient>([this](const CanFrame& f) { sink_(f); }, c);
    if (sdo_pacer_.paced()) slot->set_pacer(&sdo_pacer_);
    slot->set_cob_change_counter(&cob_changes_);
    slot->set_work_list(&working_);
    ++cob_changes_;
    clients_.clear();
    for (const auto& [id, client] : sdo_) clients_.push_back(client.get());
  }
  return *slot;
}

SdoAbortCode Master::monitor_heartbeat(NodeId node, std::uint16_t ms) {
  Object* obj = od_.find(0x1016);
  // Reuse the node's entry if it has one, else the first unused entry.
  std::optional<std::uint8_t> target;
  for (const auto& [sub, s] : obj->subs()) {
    if (sub == 0 || s.value.size() != 4) continue;
    const std::uint32_t v = get_u32(s.value.data());
    const auto entry_node = static_cast<std::uint8_t>(v >> 16);
    if (entry_node == node.value()) {
      target = sub;
      break;
    }
    if (!target && (v & 0xFFFFu) == 0) target = sub;
  }
  if (!target) return SdoAbortCode::ResourceNotAvailable;
  return od_.set<std::uint32_t>(0x1016, *target, heartbeat_consumer_entry(node, ms), Origin::Sdo);
}

bool Master::on_frame(const CanFrame& frame, TimePoint now) {
  // CiA 301 §7.2.8.3.2.1: the boot-up message (700h + node-ID, one byte 00h) is reported for
  // every node, watched by 1016h or not: a node that rebooted must be reconfigured.
  if (!frame.rtr && frame.dlc == 1 && frame.data[0] == 0 && frame.id > cob::kHeartbeat &&
      frame.id <= cob::kHeartbeat + 127 && on_boot) {
    on_boot(NodeId{static_cast<std::uint8_t>(frame.id - cob::kHeartbeat)});
  }
  if (hb_.on_frame(frame, now)) return true;
  if (emcy_.on_frame(frame, now)) return true;
  if (some_client_answers_on(frame)) {
    for (SdoClient* client : clients_) {
      if (client->answers_on(frame)) return client->on_frame(frame, now);
    }
  }
  if (on_other_frame) on_other_frame(frame, now);
  return false;
}

bool Master::some_client_answers_on(const CanFrame& frame) {
  if (answer_ids_built_ != cob_changes_) {
    answer_ids_.assign(kStandardIds, false);
    answer_extended_ = false;
    for (const SdoClient* client : clients_) {
      const CobId cob = client->config().response_cob;
      if (!cob.valid()) continue;
      if (cob.extended()) {
        answer_extended_ = true;
      } else {
        answer_ids_[cob.can_id()] = true;
      }
    }
    answer_ids_built_ = cob_changes_;
  }
  // CanFrame's fields are public: a frame built field by field may carry an identifier past 7FFh
  // without `extended`: no index into answer_ids_, it goes the way of an extended frame.
  if (frame.extended || frame.id >= kStandardIds) return answer_extended_;
  return answer_ids_[frame.id];
}

void Master::advance(TimePoint now) {
  hb_.advance(now);
  // A callback may add a client (sdo()), which rebuilds clients_: the walk goes on after the
  // client it advanced, wherever that now is, so that none is skipped or advanced twice (as a
  // walk over the map: a client added after it is advanced in this pass, one before it not).
  for (std::size_t i = 0; i < clients_.size(); ++i) {
    SdoClient* const client = clients_[i];
    client->advance(now);
    if (clients_[i] != client)
      i = static_cast<std::size_t>(std::find(clients_.begin(), clients_.end(), client) - clients_.begin());
  }
  working_.prune();
  if (sync_) sync_->advance(now);
}

std::optional<TimePoint> Master::next_deadline() const {
  std::optional<TimePoint> best = hb_.next_deadline();
  if (sync_)
    if (const auto t = sync_->next_deadline(); t && (!best || *t < *best)) best = t;
  // Only the clients that may have work: an idle one has no deadline (SdoWorkList).
  for (const SdoClient* client : working_.clients()) {
    const auto t = client->next_deadline();
    if (t && (!best || *t < *best)) best = t;
  }
  return best;
}

std::optional<NodeId> Master::busy_sdo_server() const {
  for (const auto& [id, client] : sdo_)
    if (!client->idle()) return NodeId{id};
  return std::nullopt;
}

void Master::export_state(StateWriter& w) const {
  if (const auto busy = busy_sdo_server()) {
    throw std::logic_error("Master::export_state: the SDO client of node " + std::to_string(busy->value()) +
                           " has a transfer under way");
  }
  {
    const StateWriter::Scope scope(w, "od");
    od_.export_values(w);
  }
  w.put_state("heartbeat", hb_);
  w.put_state("pacer", sdo_pacer_);
  w.put("produces_sync", sync_ != nullptr);
  if (sync_) w.put_state("sync", *sync_);
  std::vector<std::pair<std::uint8_t, const SdoClient*>> clients;
  for (const auto& [id, client] : sdo_) clients.emplace_back(id, client.get());
  w.put_list("sdo", clients.size(), [&](std::size_t i) {
    w.put("server", clients[i].first);
    clients[i].second->export_state(w);
  });
}

void Master::import_state(const StateReader& r) {
  if (r.get<bool>("produces_sync") != (sync_ != nullptr)) {
    r.fail("produces_sync", sync_ ? "differs: this master produces SYNC" : "differs: this master produces no SYNC");
  }
  od_.import_values(r.in("od"));
  hb_.reload();
  emcy_.reload();
  if (sync_) sync_->reload();
  hb_.import_state(r.in("heartbeat"));
  sdo_pacer_.import_state(r.in("pacer"));
  if (sync_) sync_->import_state(r.in("sync"));
  r.read_list("sdo", 127, [&](const StateReader& item) {
    const NodeId server = item.node_id("server");
    if (!server.valid()) item.fail("server", "is no node-ID (1..127)");
    sdo(server).import_state(item);
  });
}

}  // namespace oegw::canopen
