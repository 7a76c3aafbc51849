#include "canopen/305/lss_master.hpp"

namespace oegw::canopen {

using namespace lss::cs;

LssMaster::LssMaster(FrameSink sink, Duration timeout) : sink_(std::move(sink)), timeout_(timeout) {}

CanFrame LssMaster::frame(std::uint8_t cs, std::uint32_t value) {
  CanFrame f(cob::kLssMaster, {cs, 0, 0, 0, 0, 0, 0, 0});
  put_u32(&f.data[1], value);
  return f;
}

void LssMaster::enqueue(Request r, TimePoint now) {
  if (now > now_) now_ = now;
  queue_.push_back(std::move(r));
  pump(now);
}

// Starts queued requests while the line is free. Requests without an answer finish at once.
void LssMaster::pump(TimePoint now) {
  while (!active_ && !queue_.empty()) {
    Request r = std::move(queue_.front());
    queue_.pop_front();
    for (const CanFrame& f : r.frames)
      if (sink_) sink_(f);
    if (r.answer == 0) {
      if (r.cb) r.cb(Result{});
      continue;
    }
    deadline_ = now + r.timeout.value_or(timeout_);
    active_ = std::move(r);
  }
}

void LssMaster::finish(const Result& result, TimePoint now) {
  Callback cb = std::move(active_->cb);
  active_.reset();
  if (cb) cb(result);
  pump(now);
}

void LssMaster::switch_state_global(lss::Mode mode, TimePoint now, Callback cb) {
  enqueue({{frame(kSwitchStateGlobal, static_cast<std::uint8_t>(mode))}, 0, false, false, std::move(cb)}, now);
}

void LssMaster::switch_state_selective(const lss::Address& a, TimePoint now, Callback cb) {
  enqueue({{frame(kSwitchSelectiveVendor, a.vendor), frame(kSwitchSelectiveProduct, a.product),
            frame(kSwitchSelectiveRevision, a.revision), frame(kSwitchSelectiveSerial, a.serial)},
           kSwitchSelectiveResponse,
           false,
           false,
           std::move(cb)},
          now);
}

void LssMaster::configure_node_id(NodeId id, TimePoint now, Callback cb) {
  enqueue({{frame(kConfigureNodeId, id.value())}, kConfigureNodeId, true, false, std::move(cb)}, now);
}

void LssMaster::configure_bit_timing(std::uint8_t table_index, TimePoint now, Callback cb) {
  // Byte 1: table selector 0 (CiA standard table), byte 2: table index.
  enqueue({{frame(kConfigureBitTiming, static_cast<std::uint32_t>(table_index) << 8)},
           kConfigureBitTiming,
           true,
           false,
           std::move(cb)},
          now);
}

void LssMaster::activate_bit_timing(std::uint16_t switch_delay_ms, TimePoint now, Callback cb) {
  enqueue({{frame(kActivateBitTiming, switch_delay_ms)}, 0, false, false, std::move(cb)}, now);
}

void LssMaster::store_configuration(TimePoint now, Callback cb) {
  enqueue({{frame(kStoreConfiguration)}, kStoreConfiguration, true, false, std::move(cb)}, now);
}

void LssMaster::inquire(Inquiry what, TimePoint now, Callback cb) {
  const auto c = static_cast<std::uint8_t>(what);
  enqueue({{frame(c)}, c, false, false, std::move(cb)}, now);
}

void LssMaster::identify_remote_slave(const lss::AddressRange& r, TimePoint now, Callback cb,
                                      std::optional<Duration> whole_window) {
  enqueue({{frame(kIdentifyVendor, r.vendor), frame(kIdentifyProduct, r.product),
            frame(kIdentifyRevisionLow, r.revision_low), frame(kIdentifyRevisionHigh, r.revision_high),
            frame(kIdentifySerialLow, r.serial_low), frame(kIdentifySerialHigh, r.serial_high)},
           kIdentifySlaveResponse,
           false,
           true,
           std::move(cb),
           whole_window.has_value(),
           false,
           whole_window},
          now);
}

void LssMaster::identify_non_configured(TimePoint now, Callback cb) {
  enqueue({{frame(kIdentifyNonConfigured)}, kIdentifyNonConfiguredResponse, false, true, std::move(cb)}, now);
}

void LssMaster::fastscan(std::uint32_t id_number, std::uint8_t bit_checked, std::uint8_t sub, std::uint8_t next,
                         TimePoint now, Callback cb, std::optional<Duration> timeout) {
  CanFrame f = frame(kFastscan, id_number);
  f.data[5] = bit_checked;
  f.data[6] = sub;
  f.data[7] = next;
  enqueue({{f}, kIdentifySlaveResponse, false, true, std::move(cb), true, false, timeout}, now);
}

bool LssMaster::on_frame(const CanFrame& f, TimePoint now) {
  if (f.id != cob::kLssSlave || f.extended) return false;
  if (now > now_) now_ = now;
  if (f.rtr || f.dlc != 8 || !active_ || f.data[0] != active_->answer) return true;
  if (active_->whole_window) {
    active_->answered = true;
    return true;
  }
  Result r;
  if (active_->has_error_code) {
    r.error = f.data[1];
    r.specific_error = f.data[2];
    r.status = r.error == 0 ? Status::Ok : Status::Refused;
  } else {
    r.value = get_u32(&f.data[1]);
    if (active_->answer == kInquireNodeId) r.value &= 0xFF;
  }
  finish(r, now);
  return true;
}

void LssMaster::advance(TimePoint now) {
  if (now > now_) now_ = now;
  if (!active_ || now < deadline_) return;
  Result r;
  r.status = active_->answered ? Status::Ok : active_->silence_is_answer ? Status::NoAnswer : Status::Timeout;
  finish(r, now);
}

std::optional<TimePoint> LssMaster::next_deadline() const {
  if (!active_) return std::nullopt;
  return deadline_;
}

}  // namespace oegw::canopen
