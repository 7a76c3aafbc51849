#include "canopen/301/sync.hpp"

#include "canopen/state.hpp"

namespace oegw::canopen {

SyncService::SyncService(ObjectDictionary& od, FrameSink sink, SyncConfig config) : od_(od), sink_(std::move(sink)) {
  if (od_.find(0x1005) == nullptr)
    od_.add_var(0x1005, "COB-ID SYNC", DataType::Unsigned32, Access::ReadWrite, encode<std::uint32_t>(config.cob_id));
  if (od_.find(0x1006) == nullptr)
    od_.add_var(0x1006, "Communication cycle period", DataType::Unsigned32, Access::ReadWrite,
                encode<std::uint32_t>(config.period_us));
  if (config.window && od_.find(0x1007) == nullptr)
    od_.add_var(0x1007, "Synchronous window length", DataType::Unsigned32, Access::ReadWrite,
                encode<std::uint32_t>(config.window_us));
  if (od_.find(0x1019) == nullptr)
    od_.add_var(0x1019, "Synchronous counter overflow value", DataType::Unsigned8, Access::ReadWrite,
                {config.counter_overflow});

  // CiA 301 §7.5.2.5: the CAN-ID may not change while this node produces SYNC (bit 30 = 1).
  subs_ += od_.find(0x1005)->add_write_hook([this](Object&, std::uint8_t, std::span<const std::uint8_t> b, Origin o) {
    if (o == Origin::Local || b.size() != 4) return SdoAbortCode::None;
    const CobId cur{od_.get<std::uint32_t>(0x1005, 0)};
    const CobId next{get_u32(b.data())};
    if (cur.bit30() && next.bit30() && (cur.raw() & 0x3FFFFFFFu) != (next.raw() & 0x3FFFFFFFu))
      return SdoAbortCode::InvalidValue;
    if (!next.well_formed()) return SdoAbortCode::InvalidValue;  // bits 11..28 of an 11-bit COB-ID
    return SdoAbortCode::None;
  });
  // CiA 301 §7.5.2.41: 1019h is 0 or 2..240, and may only be written while 1006h is 0
  // (0800 0022h: not in the present state).
  subs_ += od_.find(0x1019)->add_write_hook([this](Object&, std::uint8_t, std::span<const std::uint8_t> b, Origin o) {
    if (o == Origin::Local || b.size() != 1) return SdoAbortCode::None;
    if (b[0] == 1 || b[0] > 240) return SdoAbortCode::InvalidValue;
    if (od_.get<std::uint32_t>(0x1006, 0) != 0) return SdoAbortCode::CannotTransferDeviceState;
    return SdoAbortCode::None;
  });
  subs_ += od_.add_observer([this](std::uint16_t index, std::uint8_t, Origin) {
    if (index == 0x1005 || index == 0x1006 || index == 0x1019) reconfigure();
  });
}

void SyncService::reconfigure() {
  restart_pending_ = true;
  next_sync_.reset();
  counter_ = 0;
}

bool SyncService::producer() const {
  return CobId{od_.get<std::uint32_t>(cob_slot_)}.bit30() && od_.get<std::uint32_t>(period_slot_) != 0;
}

bool SyncService::in_window(TimePoint now) const {
  const std::uint32_t w = od_.get<std::uint32_t>(0x1007, 0);
  if (w == 0) return true;
  return last_sync_ && now - *last_sync_ <= Duration{w};
}

void SyncService::deliver(std::uint8_t counter, TimePoint now) {
  last_sync_ = now;
  if (handler_) handler_(counter, now);
}

bool SyncService::on_frame(const CanFrame& frame, TimePoint now) {
  if (now > last_now_) last_now_ = now;
  const CobId cob{od_.get<std::uint32_t>(cob_slot_)};
  if (frame.rtr || frame.id != cob.can_id() || frame.extended != cob.extended()) return false;
  if (cob.bit30()) return false;  // we are the producer: a foreign SYNC on our ID is not ours to consume
  const bool counter_expected = od_.get<std::uint8_t>(overflow_slot_) != 0;
  if (frame.dlc != (counter_expected ? 1 : 0)) {
    if (on_length_error) on_length_error(kEmcyUnexpectedSyncLength);
  } else if (on_length_ok) {
    on_length_ok();
  }
  deliver(frame.dlc >= 1 ? frame.data[0] : 0, now);
  return true;
}

void SyncService::advance(TimePoint now) {
  if (now > last_now_) last_now_ = now;
  if (!producer()) {
    restart_pending_ = false;
    next_sync_.reset();
    return;
  }
  const Duration period{od_.get<std::uint32_t>(period_slot_)};
  if (restart_pending_) {
    restart_pending_ = false;
    counter_ = 0;
    next_sync_ = now + period;  // the first SYNC one period after production starts
  }
  const CobId cob{od_.get<std::uint32_t>(cob_slot_)};
  const std::uint8_t overflow = od_.get<std::uint8_t>(overflow_slot_);
  // One SYNC per call even if several periods were missed: a late loop does not burst.
  if (next_sync_ && now >= *next_sync_) {
    CanFrame f;
    f.id = cob.can_id();
    f.extended = cob.extended();
    std::uint8_t counter = 0;
    if (overflow >= 2) {
      counter_ = counter_ >= overflow ? 1 : static_cast<std::uint8_t>(counter_ + 1);
      counter = counter_;
      f.dlc = 1;
      f.data[0] = counter;
    }
    sink_(f);
    *next_sync_ += period;
    if (*next_sync_ <= now) next_sync_ = now + period;
    deliver(counter, now);
  }
}

std::optional<TimePoint> SyncService::next_deadline() const {
  if (!producer()) return std::nullopt;
  if (restart_pending_) return last_now_;
  return next_sync_;
}

void SyncService::export_state(StateWriter& w) const {
  w.put("restart_pending", restart_pending_);
  w.put("next_sync", next_sync_);
  w.put("last_sync", last_sync_);
  w.put("last_now", last_now_);
  w.put("counter", counter_);
}

void SyncService::import_state(const StateReader& r) {
  const bool restart_pending = r.get<bool>("restart_pending");
  const std::optional<TimePoint> next_sync = r.optional_time("next_sync");
  const std::optional<TimePoint> last_sync = r.optional_time("last_sync");
  const TimePoint last_now = r.time("last_now");
  const auto counter = r.get<std::uint8_t>("counter");
  restart_pending_ = restart_pending;
  next_sync_ = next_sync;
  last_sync_ = last_sync;
  last_now_ = last_now;
  counter_ = counter;
}

}  // namespace oegw::canopen
