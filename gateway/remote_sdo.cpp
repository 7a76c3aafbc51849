#include "gateway/remote_sdo.hpp"

#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>

namespace oegw::gateway {

using canopen::SdoAbortCode;
using canopen::SdoTarget;
using canopen::TimePoint;
namespace sd = oegw::subdevices;

namespace {

std::string abort_text(SdoAbortCode code) {
  const auto v = static_cast<std::uint32_t>(code);
  return fmt::format("{:04X} {:04X}h ({})", v >> 16, v & 0xFFFF, canopen::to_string(code));
}

// What re-wires or re-flashes a sub-device, or changes what the gateway configured on it and
// relies on (CiA 301 §7.5.2, CiA 302-3):
//  * every COB-ID object: SYNC 1005h, TIME 1012h, EMCY 1014h (the fault policy and remote EMCY
//    listen on 80h + node-ID), the EMCY consumer's COB-IDs 1028h, the SDO server and client
//    parameters 1200h–12FFh (an SDO answer moved onto another device's TPDO COB-ID would be taken
//    for that device's inputs), the PDO communication and mapping parameters 1400h–1BFFh, and
//    100Eh "COB-ID guard" of DS 301 v3 devices (the MCB-402 document lists it rw: its heartbeat
//    and boot-up COB-ID);
//  * the heartbeat consumer/producer 1016h/1017h, the error behaviour 1029h (what the node does
//    on an error decides its proof of life), store and restore 1010h/1011h;
//  * program download and control 1F50h–1F57h (CiA 302-3: a new firmware, the application
//    stopped or started behind the gateway's back) and NMT startup 1F80h.
bool communication_protected(std::uint16_t index) {
  return index == 0x1005 || index == 0x100E || index == 0x1010 || index == 0x1011 || index == 0x1012 ||
         index == 0x1014 || index == 0x1016 || index == 0x1017 || index == 0x1028 || index == 0x1029 ||
         (index >= 0x1200 && index <= 0x12FF) || (index >= 0x1400 && index <= 0x1BFF) ||
         (index >= 0x1F50 && index <= 0x1F57) || index == 0x1F80;
}

}  // namespace

RemoteSdo::RemoteSdo(const mapping::Config& config, canopen::Master& master, sd::NetworkManager& network,
                     std::function<canopen::NodeId()> self)
    : config_(config), master_(master), network_(network), self_(std::move(self)) {
  for (const auto& fe : config_.functional_elements)
    for (const auto& f : fe.fields) in_use_.insert(f.subdevice);
}

void RemoteSdo::log(const std::string& line) {
  if (on_log) on_log(line);
}

const mapping::SubdeviceConfig* RemoteSdo::find(const SdoTarget& target) const {
  if (target.network != config_.downstream.network_id) return nullptr;
  for (const auto& s : config_.subdevices)
    if (s.node_id == target.node) return &s;
  return nullptr;
}

SdoTarget RemoteSdo::target_of(const std::string& name) const {
  for (const auto& s : config_.subdevices)
    if (s.name == name) return {config_.downstream.network_id, s.node_id};
  return {};
}

std::string RemoteSdo::subdevice_at(const SdoTarget& target) const {
  const mapping::SubdeviceConfig* s = find(target);
  return s == nullptr ? std::string() : s->name;
}

std::string RemoteSdo::describe(const SdoTarget& target) const {
  const std::string name = subdevice_at(target);
  return fmt::format("{}(network {}, node {:02X}h)", name.empty() ? "" : name + " ", target.network, target.node);
}

SdoAbortCode RemoteSdo::select(const SdoTarget& target, Selection& selection) {
  const bool own_network = target.network == config_.upstream.network_id;
  if ((target.network == 0 && target.node == 0) || (own_network && target.node == self_().value())) {
    selection = Selection::Local;
    return SdoAbortCode::None;
  }
  if (!own_network && target.network != config_.downstream.network_id) {
    ++counters_.refused;
    log(
        fmt::format("remote SDO: network indication refused: network {} is neither the upstream ({}) nor the "
                    "downstream ({}) network",
                    target.network, config_.upstream.network_id, config_.downstream.network_id));
    return SdoAbortCode::ObjectDoesNotExist;
  }
  if (find(target) == nullptr) {
    ++counters_.refused;
    log(fmt::format("remote SDO: network indication refused: node {:02X}h on network {} is no {}", target.node,
                    target.network, own_network ? "node the gateway reaches (only itself)" : "configured sub-device"));
    return SdoAbortCode::SubIndexDoesNotExist;
  }
  selection = Selection::Remote;
  return SdoAbortCode::None;
}

SdoAbortCode RemoteSdo::check(const SdoTarget& target, const mapping::SubdeviceConfig*& sub) const {
  sub = find(target);
  if (sub == nullptr) return SdoAbortCode::SubIndexDoesNotExist;
  switch (network_.state(sub->name)) {
    case sd::NodeState::Missing: return SdoAbortCode::HardwareError;
    case sd::NodeState::Idle:
    case sd::NodeState::WaitingBootUp:
    case sd::NodeState::Configuring: return SdoAbortCode::CannotTransferDeviceState;
    case sd::NodeState::Starting:
    case sd::NodeState::Operational:
    case sd::NodeState::Refused: break;
  }
  return SdoAbortCode::None;
}

bool RemoteSdo::write_refused(const mapping::SubdeviceConfig& sub, std::uint16_t index, std::uint8_t sub_index) {
  if (!in_use_.contains(sub.name)) return false;
  if (communication_protected(index)) return true;
  for (const auto& w : sub.sdo)
    if (w.index == index) return true;
  if (sd::Driver* d = network_.driver(sub.name)) {
    if (d->protects(index, sub_index)) return true;
    for (const auto& w : d->configuration())
      if (w.index == index) return true;
  }
  return false;
}

std::uint64_t RemoteSdo::refused(const std::string& subdevice) const {
  const auto it = refused_by_subdevice_.find(subdevice);
  return it == refused_by_subdevice_.end() ? 0 : it->second;
}

RemoteSdo::Ticket RemoteSdo::refuse(SdoAbortCode code, const std::string& what, const mapping::SubdeviceConfig* sub,
                                    Done& done) {
  ++counters_.refused;
  if (sub != nullptr) ++refused_by_subdevice_[sub->name];
  log("remote SDO: " + what + " refused: " + abort_text(code));
  const Ticket t = next_++;
  done(code, {});
  return t;
}

RemoteSdo::Ticket RemoteSdo::track(std::uint8_t node, Done done) {
  ++counters_.transfers;
  const Ticket t = next_++;
  pending_.push_back({t, node, 0, std::move(done)});
  return t;
}

void RemoteSdo::finish(Ticket ticket, SdoAbortCode code, std::vector<std::uint8_t> data) {
  auto it = std::find_if(pending_.begin(), pending_.end(), [&](const Pending& p) { return p.ticket == ticket; });
  if (it == pending_.end()) return;  // cancelled meanwhile
  Done done = std::move(it->done);
  pending_.erase(it);
  if (code != SdoAbortCode::None) ++counters_.remote_aborts;
  done(code, std::move(data));
}

RemoteSdo::Ticket RemoteSdo::upload(const SdoTarget& target, std::uint16_t index, std::uint8_t sub, TimePoint now,
                                    Done done) {
  const mapping::SubdeviceConfig* sc = nullptr;
  if (const SdoAbortCode c = check(target, sc); c != SdoAbortCode::None)
    return refuse(c, fmt::format("read of node {:02X}h {:04X}h:{:02X}", target.node, index, sub), sc, done);
  const Ticket t = track(target.node, std::move(done));
  canopen::SdoClient& client = master_.sdo(sc->node());
  pending_.back().client_ticket =
      client.upload(index, sub,
                    [this, t](SdoAbortCode code, std::vector<std::uint8_t> data) { finish(t, code, std::move(data)); });
  client.advance(now);  // starts it now, not at the next turn of the event loop
  return t;
}

RemoteSdo::Ticket RemoteSdo::download(const SdoTarget& target, std::uint16_t index, std::uint8_t sub,
                                      std::span<const std::uint8_t> data, bool size_indicated, TimePoint now,
                                      Done done) {
  const mapping::SubdeviceConfig* sc = nullptr;
  const std::string what = fmt::format("write of node {:02X}h {:04X}h:{:02X}", target.node, index, sub);
  if (const SdoAbortCode c = check(target, sc); c != SdoAbortCode::None) return refuse(c, what, sc, done);
  if (write_refused(*sc, index, sub))
    return refuse(SdoAbortCode::CannotTransferLocalControl,
                  what + " (" + sc->name + ": the gateway configures this object and its FEs are in use)", sc, done);
  const Ticket t = track(target.node, std::move(done));
  canopen::SdoClient& client = master_.sdo(sc->node());
  pending_.back().client_ticket = client.download(
      index, sub, std::vector<std::uint8_t>(data.begin(), data.end()),
      [this, t](SdoAbortCode code, std::vector<std::uint8_t> out) { finish(t, code, std::move(out)); },
      size_indicated ? canopen::SdoTransfer::Auto : canopen::SdoTransfer::ExpeditedUnsized);
  client.advance(now);
  return t;
}

void RemoteSdo::cancel(Ticket ticket, SdoAbortCode why) {
  auto it = std::find_if(pending_.begin(), pending_.end(), [&](const Pending& p) { return p.ticket == ticket; });
  if (it == pending_.end()) return;
  const Pending p = std::move(*it);
  pending_.erase(it);  // before the client's callback: it must find nothing
  master_.sdo(canopen::NodeId{p.node}).cancel(p.client_ticket, why);
}

void RemoteSdo::export_state(canopen::StateWriter& w) const {
  if (!pending_.empty()) throw std::logic_error("RemoteSdo::export_state while a transfer is in flight");
  w.put("next", next_);
  w.put("counters.transfers", counters_.transfers);
  w.put("counters.refused", counters_.refused);
  w.put("counters.remote_aborts", counters_.remote_aborts);
  // By the sub-devices' order in the mapping file: their names are no state keys.
  w.put_list("refused_by", config_.subdevices.size(),
             [&](std::size_t i) { w.put("count", refused(config_.subdevices[i].name)); });
}

void RemoteSdo::import_state(const canopen::StateReader& r) {
  if (!pending_.empty()) throw std::logic_error("RemoteSdo::import_state while a transfer is in flight");
  const auto next = r.get<Ticket>("next");
  if (next == 0) r.fail("next", "is 0: tickets start at 1");
  const canopen::StateReader c = r.in("counters");
  const RemoteSdoCounters counters{c.get<std::uint64_t>("transfers"), c.get<std::uint64_t>("refused"),
                                   c.get<std::uint64_t>("remote_aborts")};
  std::map<std::string, std::uint64_t> by;
  std::size_t i = 0;
  std::uint64_t sum = 0;
  r.read_list("refused_by", config_.subdevices.size(), [&](const canopen::StateReader& item) {
    const auto n = item.get<std::uint64_t>("count");
    if (n != 0) by[config_.subdevices[i].name] = n;
    sum += n;
    ++i;
  });
  if (i != config_.subdevices.size()) r.fail("refused_by.count", "differs from the mapping file's sub-devices");
  // Each is also in the total (refuse()).
  if (sum > counters.refused) r.fail("counters.refused", "is below the sub-devices' refusals");
  next_ = next;
  counters_ = counters;
  refused_by_subdevice_ = std::move(by);
}

}  // namespace oegw::gateway
