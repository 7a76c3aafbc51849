#include "subdevices/sim/simulated_device.hpp"

namespace oegw::subdevices::sim {

void SimulatedDevice::build(std::unique_ptr<canopen::ObjectDictionary> od, const canopen::NodeConfig& config) {
  od_ = std::move(od);
  node_ = std::make_unique<canopen::Node>(*od_, config, out());
}

void SimulatedDevice::start(TimePoint now) {
  now_ = now;
  delayed_.clear();
  (void)node_->start(now);
}

void SimulatedDevice::reboot(TimePoint now) {
  now_ = now;
  delayed_.clear();  // the answers it was about to give die with its application
  on_power_cycle(now);
  node_->nmt().reset(false, now);  // reset application: defaults, stored values, boot-up
}

void SimulatedDevice::send(const CanFrame& frame) {
  if (silent_) return;
  // CiA 301 §7.2.8.3.2: heartbeat 700h + node-ID; the boot-up (state 00h) still goes out.
  const bool on_heartbeat_cob = frame.id == canopen::cob::kHeartbeat + node_->node_id().value() && frame.dlc == 1;
  if (heartbeat_stopped_ && on_heartbeat_cob && frame.data[0] != 0) return;
  if (boot_up_lost_ && on_heartbeat_cob && frame.data[0] == 0) return;
  if (pdo_stopped_ && is_tpdo(frame)) return;
  if (sdo_latency_.count() > 0 && is_sdo_answer(frame)) {
    delayed_.emplace_back(now_ + sdo_latency_, frame);
    return;
  }
  if (sink_) sink_(frame);
}

bool SimulatedDevice::is_sdo_answer(const CanFrame& frame) const {
  // CiA 301 §7.5.2.33: the server's answers go out on 1200h:02 (COB-ID server -> client).
  const canopen::SubObject* s = od_->find(0x1200, 2);
  if (s == nullptr || s->value.size() < 4) return false;
  const canopen::CobId tx{od_->get<std::uint32_t>(0x1200, 2)};
  return tx.valid() && tx.extended() == frame.extended && tx.can_id() == frame.id;
}

void SimulatedDevice::release_answers(TimePoint now) {
  while (!delayed_.empty() && delayed_.front().first <= now) {
    const CanFrame f = delayed_.front().second;
    delayed_.pop_front();
    if (!silent_ && sink_) sink_(f);
  }
}

namespace {

// Calls fn(cob) for each valid COB-ID in sub-index 01h of the PDO communication parameters
// first..last (bit 31 set: the PDO does not exist / is not valid; bit 29: 29-bit identifier),
// until fn returns true; returns whether it did. No allocation: is_tpdo() runs per frame sent.
template <class Fn>
bool any_pdo_cob_id(const canopen::ObjectDictionary& od, std::uint16_t first, std::uint16_t last, Fn fn) {
  const auto& objects = od.objects();
  for (auto it = objects.lower_bound(first); it != objects.end() && it->first <= last; ++it) {
    const canopen::SubObject* s = od.find(it->first, 1);
    if (s == nullptr || s->value.size() < 4) continue;
    const canopen::CobId cob{od.get<std::uint32_t>(it->first, 1)};
    if (cob.valid() && fn(cob)) return true;
  }
  return false;
}

}  // namespace

std::vector<canopen::CobId> SimulatedDevice::tpdo_cob_ids() const {
  // CiA 301 §7.5.2.35: TPDO communication parameters at 1800h..19FFh.
  return pdo_cob_ids(0x1800, 0x19FF);
}

std::vector<canopen::CobId> SimulatedDevice::rpdo_cob_ids() const {
  // CiA 301 §7.5.2.33: RPDO communication parameters at 1400h..15FFh.
  return pdo_cob_ids(0x1400, 0x15FF);
}

std::vector<canopen::CobId> SimulatedDevice::pdo_cob_ids(std::uint16_t first, std::uint16_t last) const {
  std::vector<canopen::CobId> ids;
  any_pdo_cob_id(*od_, first, last, [&ids](canopen::CobId cob) {
    ids.push_back(cob);
    return false;
  });
  return ids;
}

bool SimulatedDevice::is_tpdo(const CanFrame& frame) const {
  return any_pdo_cob_id(*od_, 0x1800, 0x19FF, [&frame](canopen::CobId cob) {
    return cob.extended() == frame.extended && cob.can_id() == frame.id;
  });
}

bool SimulatedDevice::on_frame(const CanFrame& frame, TimePoint now) {
  now_ = now;
  if (silent_) return false;
  if (intercepted(frame)) return true;
  return node_->on_frame(frame, now);
}

bool SimulatedDevice::intercepted(const CanFrame& frame) {
  const canopen::NmtState state = node_->state();
  // SDO is served in pre-operational and operational only (CiA 301 §7.3.2.2.1, Table 47).
  if (state != canopen::NmtState::PreOperational && state != canopen::NmtState::Operational) return false;
  if (frame.extended || frame.rtr || frame.dlc != 8) return false;
  const canopen::CobId rx{od_->get<std::uint32_t>(0x1200, 1)};
  if (!rx.valid() || rx.extended() || frame.id != rx.can_id()) return false;
  // CiA 301 §7.2.4.3.3 / §7.2.4.3.9: ccs 1 = initiate download; ccs 6 with bit 0 clear = initiate
  // block download.
  const std::uint8_t ccs = frame.data[0] >> 5;
  if (ccs != 1 && !(ccs == 6 && (frame.data[0] & 0x01) == 0)) return false;
  const auto index = static_cast<std::uint16_t>(frame.data[1] | (frame.data[2] << 8));
  const std::uint8_t sub = frame.data[3];
  canopen::SdoAbortCode code = refuse_download(index, sub, state);
  if (code == canopen::SdoAbortCode::None) {
    // Expedited (e = 1): bytes 4..7, of which 4 - n when the size is indicated (s = 1).
    const bool expedited = ccs == 1 && (frame.data[0] & 0x02) != 0;
    if (!expedited) return false;
    const std::size_t n = (frame.data[0] & 0x01) != 0 ? 4u - ((frame.data[0] >> 2) & 0x03) : 4u;
    const auto handled = handle_download(index, sub, std::span<const std::uint8_t>(&frame.data[4], n));
    if (!handled) return false;
    code = *handled;
  }
  const canopen::CobId tx{od_->get<std::uint32_t>(0x1200, 2)};
  CanFrame answer;
  answer.id = tx.can_id();
  answer.dlc = 8;
  const auto c = static_cast<std::uint32_t>(code);
  // 60h = initiate download response; 80h = abort with the code in bytes 4..7.
  answer.data = {static_cast<std::uint8_t>(code == canopen::SdoAbortCode::None ? 0x60 : 0x80),
                 frame.data[1],
                 frame.data[2],
                 sub,
                 static_cast<std::uint8_t>(c),
                 static_cast<std::uint8_t>(c >> 8),
                 static_cast<std::uint8_t>(c >> 16),
                 static_cast<std::uint8_t>(c >> 24)};
  send(answer);
  return true;
}

void SimulatedDevice::advance(TimePoint now) {
  now_ = now;
  release_answers(now);
  node_->advance(now);
}

std::optional<TimePoint> SimulatedDevice::next_deadline() const {
  std::optional<TimePoint> t = node_->next_deadline();
  if (!delayed_.empty() && (!t || delayed_.front().first < *t)) t = delayed_.front().first;
  return t;
}

}  // namespace oegw::subdevices::sim
