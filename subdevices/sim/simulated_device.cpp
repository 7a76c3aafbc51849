#include "subdevices/sim/simulated_device.hpp"

namespace oegw::subdevices::sim {

void SimulatedDevice::build(std::unique_ptr<canopen::ObjectDictionary> od, const canopen::NodeConfig& config) {
  od_ = std::move(od);
  node_ = std::make_unique<canopen::Node>(*od_, config, out());
}

void SimulatedDevice::start(TimePoint now) { (void)node_->start(now); }

void SimulatedDevice::reboot(TimePoint now) {
  on_power_cycle(now);
  node_->nmt().reset(false, now);  // reset application: defaults, stored values, boot-up
}

void SimulatedDevice::send(const CanFrame& frame) {
  if (silent_) return;
  // CiA 301 §7.2.8.3.2: heartbeat 700h + node-ID; the boot-up (state 00h) still goes out.
  if (heartbeat_stopped_ && frame.id == canopen::cob::kHeartbeat + node_->node_id().value() && frame.dlc == 1 &&
      frame.data[0] != 0)
    return;
  if (pdo_stopped_ && is_tpdo(frame)) return;
  if (sink_) sink_(frame);
}

bool SimulatedDevice::is_tpdo(const CanFrame& frame) const {
  // CiA 301 §7.5.2.35: TPDO communication parameters at 1800h..19FFh, COB-ID in sub-index 01h
  // (bit 31 set: the PDO does not exist / is not valid; bit 29: 29-bit identifier).
  const auto& objects = od_->objects();
  for (auto it = objects.lower_bound(0x1800); it != objects.end() && it->first <= 0x19FF; ++it) {
    const canopen::SubObject* s = od_->find(it->first, 1);
    if (s == nullptr || s->value.size() < 4) continue;
    const canopen::CobId cob{od_->get<std::uint32_t>(it->first, 1)};
    if (cob.valid() && cob.extended() == frame.extended && cob.can_id() == frame.id) return true;
  }
  return false;
}

bool SimulatedDevice::on_frame(const CanFrame& frame, TimePoint now) {
  if (silent_) return false;
  return node_->on_frame(frame, now);
}

void SimulatedDevice::advance(TimePoint now) { node_->advance(now); }

std::optional<TimePoint> SimulatedDevice::next_deadline() const { return node_->next_deadline(); }

}  // namespace oegw::subdevices::sim
