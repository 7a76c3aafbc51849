// SYNC (CiA 301 §7.2.5): producer and consumer in one service, "sans I/O".
//
// Objects (installed by the constructor when absent, with the defaults in SyncConfig):
//   1005h COB-ID SYNC     UNSIGNED32 rw  bit 30 = this node produces SYNC, bits 0..28 the CAN-ID
//   1006h cycle period    UNSIGNED32 rw  µs, 0 = producer disabled
//   1007h window length   UNSIGNED32 rw  µs, 0 = no window (optional, SyncConfig::window)
//   1019h counter overflow UNSIGNED8 rw   0 = SYNC without counter (DLC 0); 2..240 = DLC 1 with a
//                                         counter running 1..overflow (§7.5.2.41)
//
// The consumer accepts frames on the 1005h CAN-ID and calls the SyncHandler (normally
// PdoService::on_sync) with the counter (0 when the SYNC carries none). A producing node sends
// SYNC from advance() and also delivers it to its own handler, as its PDOs are synchronised by
// the SYNC it produces.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>

#include "canopen/301/object_dictionary.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

class StateWriter;  // canopen/state.hpp
class StateReader;

struct SyncConfig {
  std::uint32_t cob_id = cob::kSync;  // | CobId::kBit30 to make this node the SYNC producer
  std::uint32_t period_us = 0;
  std::uint8_t counter_overflow = 0;
  bool window = false;  // install 1007h
  std::uint32_t window_us = 0;
};

// counter: 1..240 from the SYNC's data byte, 0 when the SYNC has no counter.
using SyncHandler = std::function<void(std::uint8_t counter, TimePoint now)>;

class SyncService {
 public:
  SyncService(ObjectDictionary& od, FrameSink sink, SyncConfig config = {});
  SyncService(const SyncService&) = delete;
  SyncService& operator=(const SyncService&) = delete;

  void set_handler(SyncHandler handler) { handler_ = std::move(handler); }
  // CiA 301 §7.2.5.2 / Table 26: a received SYNC whose length does not match 1019h (DLC 0 when
  // 1019h = 0, DLC 1 otherwise) is reported with EMCY code 8240h "unexpected SYNC data length".
  // The SYNC is still delivered, with the counter byte when there is one (0 otherwise).
  static constexpr std::uint16_t kEmcyUnexpectedSyncLength = 0x8240;
  std::function<void(std::uint16_t emcy_code)> on_length_error;
  // A consumed SYNC whose length does match 1019h (the Node clears 8240h with it).
  std::function<void()> on_length_ok;

  // Re-reads 1005h/1006h/1019h (after reset_to_defaults or a parameter load, which bypass the
  // OD observers).
  void reload() { reconfigure(); }

  bool on_frame(const CanFrame& frame, TimePoint now);
  void advance(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const;

  [[nodiscard]] bool producer() const;
  // The last SYNC seen (consumed or produced), for the synchronous window (1007h).
  [[nodiscard]] std::optional<TimePoint> last_sync() const { return last_sync_; }
  // True when synchronous PDOs may still be sent: no window configured, or `now` is within
  // 1007h µs of the last SYNC.
  [[nodiscard]] bool in_window(TimePoint now) const;

  // Run-time state (canopen/state.hpp), for an object of the same configuration whose
  // dictionary values have been imported and reloaded first. Throws StateError.
  void export_state(StateWriter& w) const;
  void import_state(const StateReader& r);

 private:
  void reconfigure();
  void deliver(std::uint8_t counter, TimePoint now);

  ObjectDictionary& od_;
  FrameSink sink_;
  SyncHandler handler_;
  bool restart_pending_ = true;
  std::optional<TimePoint> next_sync_;
  std::optional<TimePoint> last_sync_;
  TimePoint last_now_{};
  std::uint8_t counter_ = 0;  // last counter sent by the producer
  // 1005h, 1006h and 1019h, read by advance() and next_deadline() after every frame the node
  // handles: through slots, without a look-up each time (their values are read live).
  mutable ObjectDictionary::Slot cob_slot_{.index = 0x1005};
  mutable ObjectDictionary::Slot period_slot_{.index = 0x1006};
  mutable ObjectDictionary::Slot overflow_slot_{.index = 0x1019};
  Subscriptions subs_;  // declared last: unregisters the OD callbacks first on destruction
};

}  // namespace oegw::canopen
