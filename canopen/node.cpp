#include "canopen/node.hpp"

#include <stdexcept>

#include "canopen/305/lss_store.hpp"
#include "canopen/state.hpp"

namespace oegw::canopen {

namespace {

constexpr std::uint16_t kDeviceType = 0x1000;
constexpr std::uint16_t kDeviceName = 0x1008;
constexpr std::uint16_t kHardwareVersion = 0x1009;
constexpr std::uint16_t kSoftwareVersion = 0x100A;
constexpr std::uint16_t kIdentity = 0x1018;
constexpr std::uint16_t kSdoServer = 0x1200;
constexpr std::size_t kMaxExtraSdoServers = 127;  // 1201h..127Fh
// A state's store file (or the reason it was refused): a whole dictionary stored is tens of kB.
constexpr std::size_t kMaxStoreText = std::size_t{4} << 20;
constexpr std::uint16_t kEmcySoftware = 0x6000;  // CiA 301 / CiA 852 Table 37: generic software error

std::vector<std::uint8_t> text(const std::string& s) { return {s.begin(), s.end()}; }

// The COB-ID entries whose CiA 301 default is "function code + node-ID" (§7.3.5, Table 36).
bool is_node_relative_cob(std::uint16_t index, std::uint8_t sub) {
  if (index == 0x1014 && sub == 0) return true;
  if (index == kSdoServer && (sub == 1 || sub == 2)) return true;
  if (index >= 0x1400 && index <= 0x15FF && sub == 1) return true;
  if (index >= 0x1800 && index <= 0x19FF && sub == 1) return true;
  return false;
}

bool is_function_code(std::uint32_t base) {
  switch (base) {
    case cob::kEmcy:
    case cob::kTpdo1:
    case cob::kRpdo1:
    case cob::kTpdo2:
    case cob::kRpdo2:
    case cob::kTpdo3:
    case cob::kRpdo3:
    case cob::kTpdo4:
    case cob::kRpdo4:
    case cob::kSdoTx:
    case cob::kSdoRx: return true;
    default: return false;
  }
}

}  // namespace

Node::Node(ObjectDictionary& od, NodeConfig config, FrameSink sink)
    : od_(od),
      cfg_(std::move(config)),
      sink_(std::move(sink)),
      bit_timing_(cfg_.bit_timing_index),
      cob_base_(cfg_.node_id),
      installed_((install_communication_objects(), true)),
      store_(cfg_.store_path.empty() ? nullptr : std::make_unique<ParameterStore>(od_, cfg_.store_path)),
      nmt_(cfg_.node_id, [this](const CanFrame& f) { emit(f); }),
      hb_producer_(od_, cfg_.node_id, [this](const CanFrame& f) { emit(f); }),
      hb_consumer_(od_),
      emcy_(
          od_, [this](const CanFrame& f) { send(f); }, cfg_.node_id, cfg_.emcy),
      sync_(
          od_, [this](const CanFrame& f) { send(f); }, cfg_.sync),
      pdo_(od_, [this](const CanFrame& f) { send(f); }),
      sdo_(
          od_, [this](const CanFrame& f) { send(f); }, cfg_.node_id, cfg_.sdo_timeout),
      lss_(
          cfg_.identity, cfg_.node_id, cfg_.bit_timing_index, [this](const CanFrame& f) { emit(f); },
          LssSlave::Callbacks{
              .on_pending_node_id = [this](NodeId id) { nmt_.set_pending_node_id(id); },
              .on_pending_bit_timing = {},
              .on_activate_bit_timing = [this](std::uint8_t index,
                                               Duration delay) { begin_bit_timing_switch(index, delay); },
              .on_store = cfg_.store_path.empty() ? std::function<std::uint8_t(NodeId, std::uint8_t)>{}
                                                  : [this](NodeId id, std::uint8_t bt) { return store_lss(id, bt); },
              .on_start_nmt = [this]() { nmt_.reset(true, now_); },
          },
          cfg_.supported_bit_timings) {
  (void)installed_;
  install_sdo_channels();
  nmt_.on_reset([this](bool communication_only) { handle_reset(communication_only, now_); });
  nmt_.on_state_change([this](NmtState s) { handle_state(s); });
  sync_.set_handler([this](std::uint8_t counter, TimePoint now) { pdo_.on_sync(counter, now); });
  sync_.on_length_error = [this](std::uint16_t code) { emcy_.raise(code, 0x10, now_); };
  // 8240h is over with the next SYNC of the length 1019h asks (CiA 301 §7.2.5, §7.5.2.41): the
  // error was that SYNC's length, and this one has the right one.
  sync_.on_length_ok = [this] {
    if (emcy_.active(SyncService::kEmcyUnexpectedSyncLength)) emcy_.clear(SyncService::kEmcyUnexpectedSyncLength, now_);
  };
  // CiA 301 §7.2.7.1: an RPDO of the wrong length is reported with EMCY 8210h (or 8220h).
  pdo_.on_length_error = [this](std::uint16_t, std::uint16_t code) { emcy_.raise(code, 0x10, now_); };
  // The length error is over once an RPDO of the right length has been processed.
  pdo_.on_rpdo = [this](std::uint16_t) {
    for (const std::uint16_t code : {PdoService::kEmcyPdoLengthError, PdoService::kEmcyPdoLengthExceeded})
      if (emcy_.active(code)) emcy_.clear(code, now_);
  };
  // CiA 301 Table 26: 8130h "life guard error or heartbeat error"; a consumer timeout is a
  // communication error for 1029h.
  hb_consumer_.on_timeout([this](NodeId n) {
    emcy_.raise(0x8130, 0x10, now_);
    communication_error(now_);
    if (on_heartbeat_timeout) on_heartbeat_timeout(n);
  });
  // The error is over with the next heartbeat of the producer, whatever state it reports: a
  // producer that comes back in the state it had (the usual case) changes no state, so a
  // state-change callback would leave 8130h active for good, and a later loss unreported.
  hb_consumer_.on_heartbeat([this](NodeId, NmtState) {
    if (emcy_.active(0x8130)) emcy_.clear(0x8130, now_);
  });
}

void Node::communication_error(TimePoint now) {
  switch (od_.get<std::uint8_t>(0x1029, 1)) {
    case 0:
      if (nmt_.state() == NmtState::Operational) nmt_.enter(NmtState::PreOperational, now);
      break;
    case 2: nmt_.enter(NmtState::Stopped, now); break;
    default: break;  // 1: no state change
  }
}

void Node::on_bus_event(BusEvent event, TimePoint now) {
  now_ = now;
  switch (event) {
    case BusEvent::ErrorPassive:
      error_passive_ = true;
      emcy_.raise(0x8120, 0x10, now);
      break;
    case BusEvent::ErrorActive:
      error_passive_ = false;
      if (emcy_.active(0x8120)) emcy_.clear(0x8120, now);
      break;
    case BusEvent::BusOff:
      bus_off_ = true;
      communication_error(now);
      break;
    case BusEvent::Restarted:
      if (bus_off_) {
        bus_off_ = false;
        error_passive_ = false;
        if (emcy_.active(0x8120)) emcy_.clear(0x8120, now);
        emcy_.raise(0x8140, 0x10, now);  // "recovered from bus off": an event, reported once
        emcy_.clear(0x8140, now);
      }
      break;
    case BusEvent::ControllerOverflow:
      emcy_.raise(0x8110, 0x10, now);  // "CAN overrun (objects lost)"
      emcy_.clear(0x8110, now);
      break;
    default: break;
  }
}

void Node::install_communication_objects() {
  od_.add_var(kDeviceType, "Device type", DataType::Unsigned32, Access::Const, encode<std::uint32_t>(cfg_.device_type));
  od_.add_var(kDeviceName, "Manufacturer device name", DataType::VisibleString, Access::Const, text(cfg_.device_name));
  od_.add_var(kHardwareVersion, "Manufacturer hardware version", DataType::VisibleString, Access::Const,
              text(cfg_.hardware_version));
  od_.add_var(kSoftwareVersion, "Manufacturer software version", DataType::VisibleString, Access::Const,
              text(cfg_.software_version));
  od_.add_record(kIdentity, "Identity object");
  od_.add_record_member(kIdentity, 1, "Vendor-ID", DataType::Unsigned32, Access::ReadOnly,
                        encode<std::uint32_t>(cfg_.identity.vendor));
  od_.add_record_member(kIdentity, 2, "Product code", DataType::Unsigned32, Access::ReadOnly,
                        encode<std::uint32_t>(cfg_.identity.product));
  od_.add_record_member(kIdentity, 3, "Revision number", DataType::Unsigned32, Access::ReadOnly,
                        encode<std::uint32_t>(cfg_.identity.revision));
  od_.add_record_member(kIdentity, 4, "Serial number", DataType::Unsigned32, Access::ReadOnly,
                        encode<std::uint32_t>(cfg_.identity.serial));
  // CiA 301 §7.5.2.33: the default SDO server's COB-IDs are read-only.
  od_.add_record(kSdoServer, "SDO server parameter");
  od_.add_record_member(kSdoServer, 1, "COB-ID client to server (rx)", DataType::Unsigned32, Access::ReadOnly,
                        encode<std::uint32_t>(cob::kSdoRx + cfg_.node_id.value()));
  od_.add_record_member(kSdoServer, 2, "COB-ID server to client (tx)", DataType::Unsigned32, Access::ReadOnly,
                        encode<std::uint32_t>(cob::kSdoTx + cfg_.node_id.value()));
  // CiA 301 §7.5.2.32: error behaviour; sub 1 = communication error, default 0 (enter
  // pre-operational when operational).
  od_.add_array(0x1029, "Error behaviour", DataType::Unsigned8, Access::ReadWrite, 1, {0});
  od_.find(0x1029, 1)->name = "Communication error";
  od_.find(0x1029, 1)->high = std::uint64_t{2};
  install_heartbeat_producer_objects(od_, cfg_.heartbeat_ms);
  if (cfg_.heartbeat_consumers > 0) install_heartbeat_consumer_objects(od_, cfg_.heartbeat_consumers);
  install_sdo_channel_objects();
}

// CiA 301 §7.5.2.33: 1201h..127Fh "SDO server parameter", sub 0 = 3, sub 1/2 the COB-IDs (rw
// for the additional channels), sub 3 the node-ID of the SDO client.
void Node::install_sdo_channel_objects() {
  if (cfg_.sdo_servers.size() > kMaxExtraSdoServers)
    throw std::invalid_argument("NodeConfig::sdo_servers: at most 127 additional SDO server channels (1201h..127Fh)");
  for (std::size_t k = 1; k <= cfg_.sdo_servers.size(); ++k) {
    const auto index = static_cast<std::uint16_t>(kSdoServer + k);
    const SdoServerChannel& c = cfg_.sdo_servers[k - 1];
    od_.add_record(index, "SDO server parameter");
    od_.add_record_member(index, 1, "COB-ID client to server (rx)", DataType::Unsigned32, Access::ReadWrite,
                          encode<std::uint32_t>(c.request));
    od_.add_record_member(index, 2, "COB-ID server to client (tx)", DataType::Unsigned32, Access::ReadWrite,
                          encode<std::uint32_t>(c.response));
    SubObject& client =
        od_.add_record_member(index, 3, "Node-ID of the SDO client", DataType::Unsigned8, Access::ReadWrite, {0});
    client.high = std::uint64_t{127};
  }
}

void Node::install_sdo_channels() {
  for (std::size_t k = 1; k <= cfg_.sdo_servers.size(); ++k) {
    const auto index = static_cast<std::uint16_t>(kSdoServer + k);
    extra_sdo_.push_back(std::make_unique<SdoServer>(
        od_, [this](const CanFrame& f) { send(f); }, CobId{CobId::kInvalidBit}, CobId{CobId::kInvalidBit},
        cfg_.sdo_timeout));
    subs_ += od_.find(index)->add_write_hook(
        [this, index](Object&, std::uint8_t sub, std::span<const std::uint8_t> b, Origin origin) {
          if (origin == Origin::Local) return SdoAbortCode::None;
          return check_sdo_channel_write(index, sub, b);
        });
  }
  pending_.assign(extra_sdo_.size(), false);
  if (extra_sdo_.empty()) return;
  subs_ += od_.add_observer([this](std::uint16_t index, std::uint8_t sub, Origin) {
    if (index <= kSdoServer || index > kSdoServer + extra_sdo_.size() || (sub != 1 && sub != 2)) return;
    const std::size_t k = index - kSdoServer;
    if (dispatching_) {
      pending_[k - 1] = true;
    } else {
      apply_sdo_channel(k);
    }
  });
  reload_sdo_channels();
}

SdoAbortCode Node::check_sdo_channel_write(std::uint16_t index, std::uint8_t sub,
                                           std::span<const std::uint8_t> b) const {
  if ((sub != 1 && sub != 2) || b.size() != 4) return SdoAbortCode::None;  // the OD checks length and range
  const CobId cur{od_.get<std::uint32_t>(index, sub)};
  const CobId next{get_u32(b.data())};
  // CiA 301 §7.5.2.33: the identifier may change only while the COB-ID is not valid (bit 31 = 1).
  if (cur.valid() && next.valid() && (cur.raw() & 0x3FFFFFFFu) != (next.raw() & 0x3FFFFFFFu))
    return SdoAbortCode::InvalidValue;
  if (!next.well_formed()) return SdoAbortCode::InvalidValue;
  if (!next.valid()) return SdoAbortCode::None;
  // CiA 301 §7.3.5: a restricted CAN-ID is not for a configurable COB-ID.
  if (!next.extended() && cob::restricted(next.can_id())) return SdoAbortCode::InvalidValue;
  if (cob_in_use(next, index, sub)) return SdoAbortCode::InvalidValue;
  return SdoAbortCode::None;
}

bool Node::cob_in_use(CobId cob, std::uint16_t except_index, std::uint8_t except_sub) const {
  auto same = [&cob](std::uint32_t raw) {
    const CobId other{raw};
    return other.extended() == cob.extended() && other.can_id() == cob.can_id();
  };
  for (const auto& [index, obj] : od_.objects()) {
    if (index < 0x1005) continue;
    if (index > 0x19FF) break;  // the COB-ID entries are all below 1A00h
    for (const auto& [sub, s] : obj.subs()) {
      if ((index == except_index && sub == except_sub) || s.value.size() != 4) continue;
      const std::uint32_t raw = get_u32(s.value.data());
      bool used = false;
      if (index == 0x1005 && sub == 0) {
        used = true;  // SYNC: consumed or produced, bit 31 is "don't care" (CiA 301 §7.5.2.5)
      } else if (index == 0x1012 && sub == 0) {
        used = (raw & (CobId::kInvalidBit | CobId::kBit30)) != 0;  // TIME: consumed (bit 31) or produced (bit 30)
      } else if ((index == 0x1014 && sub == 0) || (index == 0x1028 && sub != 0) ||
                 (index >= 0x1200 && index <= 0x12FF && (sub == 1 || sub == 2)) ||
                 (index >= 0x1400 && index <= 0x15FF && sub == 1) || (index >= 0x1800 && index <= 0x19FF && sub == 1)) {
        used = CobId{raw}.valid();
      }
      if (used && same(raw)) return true;
    }
  }
  return false;
}

void Node::apply_sdo_channel(std::size_t k) {
  const auto index = static_cast<std::uint16_t>(kSdoServer + k);
  const CobId rx{od_.get<std::uint32_t>(index, 1)};
  const CobId tx{od_.get<std::uint32_t>(index, 2)};
  // The channel serves only with both COB-IDs valid (see the header).
  const std::uint32_t off = (rx.valid() && tx.valid()) ? 0 : CobId::kInvalidBit;
  const CobId eff_rx{rx.raw() | off};
  const CobId eff_tx{tx.raw() | off};
  SdoServer& s = *extra_sdo_[k - 1];
  if (s.rx_cob_id() != eff_rx || s.tx_cob_id() != eff_tx) s.set_cob_ids(eff_rx, eff_tx);
}

void Node::reload_sdo_channels() {
  for (std::size_t k = 1; k <= extra_sdo_.size(); ++k) {
    pending_[k - 1] = false;
    apply_sdo_channel(k);
    extra_sdo_[k - 1]->reset();
  }
}

SdoServer& Node::sdo_server(std::size_t channel) {
  if (channel == 0) return sdo_;
  if (channel > extra_sdo_.size()) throw std::out_of_range("Node::sdo_server: no such SDO server channel");
  return *extra_sdo_[channel - 1];
}

ParameterStore::LoadResult Node::start(TimePoint now) {
  now_ = now;
  load_lss_file();
  ParameterStore::LoadResult result{.ok = true, .file_present = false, .applied = 0, .skipped = 0, .error = {}};
  if (store_) result = store_->load();
  hb_producer_.reload();
  hb_consumer_.reload();
  sync_.reload();
  pdo_.reload();
  reload_sdo_channels();
  store_refused_ = !result.ok;
  nmt_.start(now);
  return result;
}

void Node::load_lss_file() {
  // A half-written or foreign file is ignored: the configured defaults stay.
  const std::optional<LssStored> stored = read_lss_store(cfg_.store_path);
  if (!stored) return;
  const NodeId id = stored->node_id;
  if (id != cfg_.node_id) rebase_node_id(cfg_.node_id, id);
  cob_base_ = id;
  nmt_.set_pending_node_id(id);
  lss_.set_active_node_id(id);
  sdo_.set_cob_ids(CobId{cob::kSdoRx + id.value()}, CobId{cob::kSdoTx + id.value()});
  bit_timing_ = stored->bit_timing;
  lss_.set_bit_timing(stored->bit_timing);
}

std::uint8_t Node::store_lss(NodeId id, std::uint8_t bit_timing) {
  std::string error;
  // CiA 305 §8.3.5: error code 2 = storage media access error.
  return write_lss_store(cfg_.store_path, LssStored{id, bit_timing}, error) ? 0 : 2;
}

void Node::begin_bit_timing_switch(std::uint8_t index, Duration delay) {
  bt_next_ = index;
  bt_switch_at_ = now_ + delay;
  bt_resume_at_ = now_ + 2 * delay;
  advance_bit_timing(now_);  // a switch delay of 0 switches at once
}

void Node::advance_bit_timing(TimePoint now) {
  if (bt_switch_at_ && now >= *bt_switch_at_) {
    bt_switch_at_.reset();
    bit_timing_ = bt_next_;
    if (on_bit_timing_switch) on_bit_timing_switch(bt_next_);
  }
  if (!bt_switch_at_ && bt_resume_at_ && now >= *bt_resume_at_) bt_resume_at_.reset();
}

void Node::rebase_node_id(NodeId from, NodeId to) {
  std::vector<std::uint16_t> indices;
  for (const auto& [index, obj] : od_.objects()) indices.push_back(index);
  for (const std::uint16_t index : indices) {
    for (auto& [sub, s] : od_.find(index)->subs()) {
      if (!is_node_relative_cob(index, sub) || s.default_value.size() != 4) continue;
      const std::uint32_t def = get_u32(s.default_value.data());
      const CobId cob{def};
      if (cob.extended()) continue;
      const std::uint32_t id = cob.can_id();
      if (id < from.value() || !is_function_code(id - from.value())) continue;
      const std::uint32_t moved = (def & ~0x7FFu) | (id - from.value() + to.value());
      put_u32(s.default_value.data(), moved);
      // CiA 305 §4 / CiA 301 §7.3.5: at power-on with an LSS-stored node-ID no reset_to_defaults
      // follows, so an entry still holding the old default moves as well (else TPDOs, EMCY and
      // 1200h would stay on the old node-ID while the node boots with the new one). A value the
      // application changed is left alone; a stored value is applied afterwards.
      if (s.value.size() == 4 && get_u32(s.value.data()) == def) s.value = s.default_value;
    }
  }
}

void Node::handle_reset(bool communication_only, TimePoint now) {
  now_ = now;
  const NodeId new_id = nmt_.pending_node_id();
  if (new_id.valid() && new_id != cob_base_ && cob_base_.valid()) {
    rebase_node_id(cob_base_, new_id);
    cob_base_ = new_id;
  }
  if (communication_only) {
    od_.reset_to_defaults(0x1000, 0x1FFF);
  } else {
    // Reset node restarts the application (CiA 301 §7.3.2.2.1): its errors with it. What still
    // holds is raised again once pre-operational (handle_state: the store, the controller's
    // error-passive state; the application's own, e.g. the gateway's sub-device faults).
    emcy_.restart();
    od_.reset_to_defaults(0x0000, 0xFFFF);
  }
  if (store_) {
    const ParameterStore::LoadResult r = communication_only ? store_->load(0x1000, 0x1FFF) : store_->load();
    store_refused_ = !r.ok;  // EMCY in initialisation would be held back: applied in handle_state
    if (on_store_reload) on_store_reload(r, communication_only);
  }
  // A reset communication leaves the application's active errors (CiA 301 §7.3.2.2.1: only the
  // communication parameters restart), while it has just put 1001h back to 0: 1001h follows the
  // producer again, so the error register never says "no error" while errors are active
  // (§7.5.2.2).
  emcy_.reapply_register();
  // CiA 305: the pending node-ID becomes the active one, FFh included (the node stays in
  // initialisation then, see NmtSlave, and answers "identify non-configured remote slave").
  lss_.set_active_node_id(new_id);
  if (new_id.valid()) {
    sdo_.set_cob_ids(CobId{cob::kSdoRx + new_id.value()}, CobId{cob::kSdoTx + new_id.value()});
  }
  sdo_.reset();
  reload_sdo_channels();
  hb_producer_.reload();
  hb_consumer_.reload();
  sync_.reload();
  pdo_.reload();
}

void Node::apply_store_result(bool refused) {
  if (refused && !emcy_.active(kEmcySoftware)) {
    emcy_.raise(kEmcySoftware, 0x00, now_);
  } else if (!refused && emcy_.active(kEmcySoftware)) {
    emcy_.clear(kEmcySoftware, now_);
  }
}

void Node::handle_state(NmtState s) {
  gate_ = s;
  if (s == NmtState::PreOperational && store_refused_) {
    apply_store_result(*store_refused_);
    store_refused_.reset();
  }
  // After a reset node the controller is still error passive: 8120h again (the EMCY restarted).
  if (s == NmtState::PreOperational && error_passive_ && !emcy_.active(0x8120)) emcy_.raise(0x8120, 0x10, now_);
  if (s == NmtState::Initialisation) {
    hb_producer_.stop();
  } else if (!hb_producer_.running()) {
    hb_producer_.start(s, nmt_.node_id(), nmt_.last_transition());
  } else {
    hb_producer_.set_state(s);
  }
  // CiA 301 §7.3.2.2.1: PDOs only in operational; leaving a state drops SDO transfers only
  // through reset (the server keeps running in pre-operational and operational).
  pdo_.set_operational(s == NmtState::Operational, nmt_.last_transition());
  if (s == NmtState::Stopped) {
    sdo_.reset();
    for (auto& extra : extra_sdo_) extra->reset();
  }
  if (on_state_change) on_state_change(s);
}

void Node::emit(const CanFrame& frame) {
  if (bt_resume_at_) return;  // CiA 305 activate bit timing: no frame until both delays passed
  sink_(frame);
}

void Node::send(const CanFrame& frame) {
  // CiA 301 §7.3.2.2.1, Table 47: in Stopped (and during initialisation) only NMT, heartbeat and
  // LSS are served; SDO, EMCY, SYNC and PDO frames are held back.
  if (gate_ != NmtState::PreOperational && gate_ != NmtState::Operational) return;
  emit(frame);
}

bool Node::on_frame(const CanFrame& frame, TimePoint now) {
  now_ = now;
  if (nmt_.on_frame(frame, now)) return true;
  if (lss_.on_frame(frame, now)) return true;
  if (hb_consumer_.on_frame(frame, now)) return true;
  const bool serving = gate_ == NmtState::PreOperational || gate_ == NmtState::Operational;
  if (!serving) return false;
  if (sync_.on_frame(frame, now)) return true;
  if (sdo_.on_frame(frame, now)) return true;
  if (!extra_sdo_.empty()) {
    // A channel's COB-IDs written through an SDO channel change after the answer is out.
    const bool outer = dispatching_;  // a client wired straight back to the node nests calls
    dispatching_ = true;
    bool taken = false;
    for (auto& extra : extra_sdo_)
      if (extra->on_frame(frame, now)) {
        taken = true;
        break;
      }
    dispatching_ = outer;
    if (!outer)
      for (std::size_t k = 1; k <= pending_.size(); ++k)
        if (pending_[k - 1]) {
          pending_[k - 1] = false;
          apply_sdo_channel(k);
        }
    if (taken) return true;
  }
  return pdo_.on_frame(frame, now);
}

void Node::advance(TimePoint now) {
  now_ = now;
  advance_bit_timing(now);
  hb_producer_.advance(now);
  hb_consumer_.advance(now);
  sdo_.advance(now);
  for (auto& extra : extra_sdo_) extra->advance(now);
  emcy_.advance(now);
  sync_.advance(now);
  pdo_.advance(now);
}

std::optional<TimePoint> Node::next_deadline() const {
  std::optional<TimePoint> best;
  auto take = [&best](std::optional<TimePoint> t) {
    if (t && (!best || *t < *best)) best = t;
  };
  take(bt_switch_at_);
  take(bt_resume_at_);
  take(hb_producer_.next_deadline());
  take(hb_consumer_.next_deadline());
  take(sdo_.next_deadline());
  for (const auto& extra : extra_sdo_) take(extra->next_deadline());
  take(emcy_.next_deadline());
  take(sync_.next_deadline());
  take(pdo_.next_deadline());
  return best;
}

void Node::export_state(StateWriter& w) const {
  w.put("now", now_);
  w.put("gate", gate_);
  w.put("cob_base", cob_base_.value());
  w.put("bit_timing", bit_timing_);
  w.put("bt_switch_at", bt_switch_at_);
  w.put("bt_resume_at", bt_resume_at_);
  w.put("bt_next", bt_next_);
  w.put("bus_off", bus_off_);
  w.put("error_passive", error_passive_);
  w.put("store_refused", store_refused_);
  if (store_) {
    // The store file as the node last read or wrote it: the next reset applies it.
    const StateWriter::Scope scope(w, "store");
    const PlainFile& seen = store_->seen();
    w.put("file", seen.state);
    if (seen.state == PlainFile::State::Read) w.put_text("text", seen.text);
    if (seen.state == PlainFile::State::Refused) w.put_text("error", seen.error);
  }
  {
    const StateWriter::Scope scope(w, "od");
    od_.export_values(w);
  }
  w.put_state("nmt", nmt_);
  w.put_state("heartbeat_producer", hb_producer_);
  w.put_state("heartbeat_consumer", hb_consumer_);
  w.put_state("emcy", emcy_);
  w.put_state("sync", sync_);
  w.put_state("pdo", pdo_);
  w.put_state("lss", lss_);
  w.put_list("sdo", sdo_server_count(), [&](std::size_t k) { sdo_server(k).export_state(w); });
}

void Node::import_state(const StateReader& r) {
  // CiA 305 table 0: a supported index (LSS configure bit timing) or any a store can give
  // (load_lss_file takes it as stored).
  const auto bit_timing_index = [&](std::string_view key) {
    const auto i = r.get<std::uint8_t>(key);
    if (!lss::has_bit_timing(cfg_.supported_bit_timings | lss::kStorableBitTimings, i)) {
      r.fail(key, "is no bit timing this node supports or a store gives");
    }
    return i;
  };
  const TimePoint now = r.time("now");
  const NmtState gate = r.nmt_state("gate");
  const NodeId cob_base = r.node_id("cob_base");
  if (!cob_base.valid()) r.fail("cob_base", "is no node-ID (1..127): the COB-IDs follow a valid one");
  const std::uint8_t bit_timing = bit_timing_index("bit_timing");
  const std::uint8_t bt_next = bit_timing_index("bt_next");
  const std::optional<TimePoint> bt_switch_at = r.optional_time("bt_switch_at");
  const std::optional<TimePoint> bt_resume_at = r.optional_time("bt_resume_at");
  if (bt_switch_at && !bt_resume_at) r.fail("bt_resume_at", "is missing: a switch under way ends silence later");
  const bool bus_off = r.get<bool>("bus_off");
  const bool error_passive = r.get<bool>("error_passive");
  const std::optional<bool> store_refused = r.optional<bool>("store_refused");
  PlainFile store_seen;
  if (store_) {
    const StateReader st = r.in("store");
    store_seen.state = st.get<PlainFile::State>("file");
    if (store_seen.state > PlainFile::State::Refused) st.fail("file", "is none of 0 (absent), 1 (read), 2 (refused)");
    if (store_seen.state == PlainFile::State::Read) store_seen.text = st.text("text", kMaxStoreText);
    if (store_seen.state == PlainFile::State::Refused) store_seen.error = st.text("error", kMaxStoreText);
  }

  // As handle_reset: the defaults of the form "function code + node-ID" first, so that the
  // dictionary's layout (its defaults included) is the state's. The SDO servers' COB-IDs come
  // with their own state.
  if (cob_base != cob_base_) {
    rebase_node_id(cob_base_, cob_base);
    cob_base_ = cob_base;
  }
  od_.import_values(r.in("od"));
  hb_producer_.reload();
  hb_consumer_.reload();
  sync_.reload();
  pdo_.reload();
  nmt_.import_state(r.in("nmt"));
  hb_producer_.import_state(r.in("heartbeat_producer"));
  hb_consumer_.import_state(r.in("heartbeat_consumer"));
  emcy_.import_state(r.in("emcy"));
  sync_.import_state(r.in("sync"));
  pdo_.import_state(r.in("pdo"));
  lss_.import_state(r.in("lss"));
  std::size_t channels = 0;
  r.read_list("sdo", sdo_server_count(), [&](const StateReader& item) { sdo_server(channels++).import_state(item); });
  if (channels != sdo_server_count()) r.fail("sdo.count", "differs from this node's SDO server channels");
  // What a run keeps in step (handle_state, handle_reset, load_lss_file): a state where they
  // differ is of no run, and would serve PDOs in a state the host stopped, or answer SDO on
  // another node's COB-IDs.
  if (gate != nmt_.state()) r.fail("gate", "differs from the NMT state");
  if (lss_.active_node_id() != nmt_.node_id()) r.fail("lss.active_node_id", "differs from the NMT node-ID");
  if (nmt_.node_id().valid() && nmt_.node_id() != cob_base) r.fail("cob_base", "differs from the NMT node-ID");
  if (sdo_.rx_cob_id().raw() != cob::kSdoRx + cob_base.value() ||
      sdo_.tx_cob_id().raw() != cob::kSdoTx + cob_base.value()) {
    r.fail("sdo.0", "is not on 600h/580h + the node-ID (CiA 301 §7.3.5)");
  }
  now_ = now;
  gate_ = gate;
  bit_timing_ = bit_timing;
  bt_next_ = bt_next;
  bt_switch_at_ = bt_switch_at;
  bt_resume_at_ = bt_resume_at;
  bus_off_ = bus_off;
  error_passive_ = error_passive;
  store_refused_ = store_refused;
  if (store_) store_->set_seen(std::move(store_seen));
}

}  // namespace oegw::canopen
