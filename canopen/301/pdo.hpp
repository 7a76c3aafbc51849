// Process data objects (CiA 301 §7.2.2, objects 1400h..1BFFh), "sans I/O".
//
// Two steps:
//   1. install_rpdo()/install_tpdo() put a PDO's communication (1400h+n-1 / 1800h+n-1) and mapping
//      (1600h+n-1 / 1A00h+n-1) parameter objects into the OD, with the caller's defaults (CiA 852
//      clause 12 gives 41 TPDOs and 34 RPDOs, disabled, type FFh, arbitrary COB-IDs). PDO numbers
//      are 1-based: TPDO 1 = 1800h/1A00h, up to 512.
//   2. PdoService scans the OD for those objects and runs every PDO of the node: one service per
//      node, holding Rpdo and Tpdo objects (reach them with rpdo(n)/tpdo(n)). It installs write
//      hooks that enforce the CiA 301 rules (COB-ID, transmission type, mapping procedure) and an
//      OD observer that applies each committed change and detects changes of mapped TPDO data.
//      A COB-ID (sub 1) is refused with 0609 0030h when bits 0..29 change while the PDO exists,
//      when it is an 11-bit COB-ID with any of bits 11..28 set (§7.5.2.35/37: they are 0 with
//      bit 29 = 0; CobId::well_formed) or a valid one on a restricted CAN-ID (cob::restricted).
//
// Transmission types (CiA 301 §7.5.2.35/37; MCB-402 "Description of transmission type"):
//   0        TPDO: sent at the next SYNC if its data changed or request() was called.
//   1..240   TPDO: sent at every n-th SYNC (from the SYNC whose counter equals the SYNC start value
//            6h when that is non-zero and the SYNC carries a counter).
//   252      TPDO: data sampled at SYNC, sent only on RTR.   253: sampled and sent on RTR.
//   254/255  TPDO: sent on request() or a change of mapped data, and when the event timer (5h, ms)
//            elapses; never sooner than the inhibit time (3h, 100 µs) after the previous one.
//   RPDO 0..240: received data are written to the OD at the next SYNC; 254/255: at once.
//   RPDO event timer: deadline monitoring — on_rpdo_timeout when no RPDO arrived for 5h ms after
//   the previous one (armed by the first reception).
// "Changed" means the packed PDO payload differs from the last one sent: an application that
// rewrites an input with the same value does not load the bus.
//
// Mapped entries are resolved to SubObject pointers when a mapping becomes valid; the per-frame
// path does no map look-ups. Those pointers stay valid as long as the mapped objects are not
// removed or replaced in the OD; after such a change, or after ObjectDictionary::reset_to_defaults
// (which runs no observers), call PdoService::reload().
//
// Wiring (one node): SyncService::set_handler -> PdoService::on_sync; PdoService::on_length_error
// -> EmcyProducer::raise; NMT state changes -> PdoService::set_operational. The service installs
// hooks and an observer holding `this` in the OD and removes them in its destructor (their
// Subscriptions), so the OD may outlive it.
// Install every PDO before constructing the service: it does not see PDOs installed later.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <unordered_map>
#include <vector>

#include "canopen/301/object_dictionary.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

class StateWriter;  // canopen/state.hpp
class StateReader;

// One mapping entry, CiA 301 §7.5.2.36: index << 16 | sub-index << 8 | length in bits.
constexpr std::uint32_t pdo_map(std::uint16_t index, std::uint8_t sub, std::uint8_t bits) {
  return static_cast<std::uint32_t>(index) << 16 | static_cast<std::uint32_t>(sub) << 8 | bits;
}

struct PdoParameters {
  std::uint32_t cob_id = CobId::kInvalidBit;
  std::uint8_t transmission_type = 0xFF;
  std::uint16_t inhibit_time = 0;      // TPDO, 100 µs units
  std::uint16_t event_timer = 0;       // ms
  std::uint8_t sync_start = 0;         // TPDO
  std::vector<std::uint32_t> mapping;  // sub-index 0 = mapping.size()
  std::uint8_t mapping_capacity = 8;   // mapping entries 1..capacity exist (1..64)
};

// Installs (replacing any previous) 1400h+n-1 and 1600h+n-1; n is 1..512.
void install_rpdo(ObjectDictionary& od, std::uint16_t n, const PdoParameters& p);
// Installs (replacing any previous) 1800h+n-1 and 1A00h+n-1; n is 1..512.
void install_tpdo(ObjectDictionary& od, std::uint16_t n, const PdoParameters& p);

class PdoService;

namespace pdo_detail {
// A mapped entry resolved to its storage. `obj`/`sub` are null for an RPDO dummy entry.
struct Mapped {
  Object* obj = nullptr;
  SubObject* sub = nullptr;
  std::uint16_t bit_offset = 0;
  std::uint8_t bits = 0;
};
}  // namespace pdo_detail

class Tpdo {
 public:
  [[nodiscard]] std::uint16_t number() const { return number_; }
  [[nodiscard]] CobId cob_id() const { return cob_; }
  [[nodiscard]] std::uint8_t transmission_type() const { return type_; }
  // A valid COB-ID and a non-empty mapping: what it takes to run in NMT Operational.
  [[nodiscard]] bool configured() const { return cob_.valid() && !entries_.empty(); }
  // Configured and the service in NMT Operational.
  [[nodiscard]] bool active() const;
  // Application event: types 254/255 are sent at the next advance() (subject to the inhibit
  // time); type 0 at the next SYNC. Ignored for the other types.
  void request() { requested_ = true; }
  // As request(), then transmits at once if nothing (inhibit time) prevents it.
  void request(TimePoint now);
  [[nodiscard]] std::uint8_t dlc() const { return dlc_; }

 private:
  friend class PdoService;
  Tpdo(PdoService& svc, std::uint16_t number) : svc_(svc), number_(number) {}
  void reload();
  void reset_runtime();
  void export_state(StateWriter& w) const;
  void import_state(const StateReader& r);
  [[nodiscard]] std::array<std::uint8_t, 8> pack() const;
  void send(const std::array<std::uint8_t, 8>& payload, TimePoint now);
  void service(TimePoint now);  // event-driven types
  void on_sync(std::uint8_t counter, TimePoint now);
  void on_rtr(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline(TimePoint last_now) const;
  [[nodiscard]] bool event_driven() const { return type_ >= 254; }

  PdoService& svc_;
  std::uint16_t number_;
  CobId cob_;
  std::uint8_t type_ = 0xFF;
  Duration inhibit_{0};
  Duration event_{0};
  std::uint8_t sync_start_ = 0;
  std::vector<pdo_detail::Mapped> entries_;
  std::uint8_t dlc_ = 0;

  bool requested_ = false;
  bool changed_ = false;
  bool restart_ = true;
  bool have_sent_ = false;
  std::array<std::uint8_t, 8> last_{};
  std::optional<TimePoint> inhibit_until_;
  std::optional<TimePoint> event_deadline_;
  unsigned sync_count_ = 0;
  bool waiting_start_ = false;
  bool have_buffer_ = false;
  std::array<std::uint8_t, 8> buffer_{};
};

class Rpdo {
 public:
  [[nodiscard]] std::uint16_t number() const { return number_; }
  [[nodiscard]] CobId cob_id() const { return cob_; }
  [[nodiscard]] std::uint8_t transmission_type() const { return type_; }
  // A valid COB-ID and a non-empty mapping: what it takes to run in NMT Operational.
  [[nodiscard]] bool configured() const { return cob_.valid() && !entries_.empty(); }
  // Configured and the service in NMT Operational.
  [[nodiscard]] bool active() const;
  [[nodiscard]] std::uint8_t dlc() const { return dlc_; }
  // Deadline monitoring (event timer) has fired since the last reception.
  [[nodiscard]] bool timed_out() const { return timed_out_; }

 private:
  friend class PdoService;
  Rpdo(PdoService& svc, std::uint16_t number) : svc_(svc), number_(number) {}
  void reload();
  void reset_runtime();
  void export_state(StateWriter& w) const;
  void import_state(const StateReader& r);
  void receive(const CanFrame& frame, TimePoint now);
  void apply(const std::uint8_t* data);
  void on_sync();
  void service(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const { return active() ? deadline_ : std::nullopt; }

  PdoService& svc_;
  std::uint16_t number_;
  CobId cob_;
  std::uint8_t type_ = 0xFF;
  Duration event_{0};
  std::vector<pdo_detail::Mapped> entries_;
  std::uint8_t dlc_ = 0;

  bool pending_ = false;  // synchronous: received, to be applied at the next SYNC
  std::array<std::uint8_t, 8> buffer_{};
  std::optional<TimePoint> deadline_;
  bool timed_out_ = false;
};

class PdoService {
 public:
  // EMCY codes reported through on_length_error (CiA 301 §7.2.7.1, Table 26).
  static constexpr std::uint16_t kEmcyPdoLengthError = 0x8210;     // PDO not processed: too short
  static constexpr std::uint16_t kEmcyPdoLengthExceeded = 0x8220;  // longer than mapped

  // Scans `od` for the PDO objects installed by install_rpdo/install_tpdo. Starts outside NMT
  // Operational: nothing is sent or applied until set_operational(true).
  PdoService(ObjectDictionary& od, FrameSink sink);
  PdoService(const PdoService&) = delete;
  PdoService& operator=(const PdoService&) = delete;

  // Re-reads every PDO's parameters from the OD (after reset_to_defaults, or after mapped
  // objects were replaced).
  void reload();

  // NMT: PDOs run only in Operational. Entering it sends every event-driven TPDO once (CiA 852
  // §12.1) and restarts timers and SYNC counting.
  void set_operational(bool operational, TimePoint now);
  [[nodiscard]] bool operational() const { return operational_; }

  bool on_frame(const CanFrame& frame, TimePoint now);
  void on_sync(std::uint8_t counter, TimePoint now);
  void advance(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const;

  [[nodiscard]] Tpdo* tpdo(std::uint16_t n);
  [[nodiscard]] Rpdo* rpdo(std::uint16_t n);

  // Run-time state (canopen/state.hpp), for a service of the same configuration whose dictionary
  // values have been imported and reload()ed first: NMT operational, and each PDO's timers,
  // pending requests and data held (a PDO left as a reload makes it writes nothing). Throws
  // StateError.
  void export_state(StateWriter& w) const;
  void import_state(const StateReader& r);

  // Application callbacks. on_length_error(rpdo number, EMCY code 8210h/8220h): hand it to the
  // EMCY producer. on_rpdo_timeout(n): the RPDO's event timer elapsed without a reception.
  // on_rpdo(n): an RPDO's data were written to the OD.
  std::function<void(std::uint16_t, std::uint16_t)> on_length_error;
  std::function<void(std::uint16_t)> on_rpdo_timeout;
  std::function<void(std::uint16_t)> on_rpdo;

 private:
  friend class Tpdo;
  friend class Rpdo;

  void install_hooks(bool transmit, std::uint16_t n);
  void on_od_change(std::uint16_t index, std::uint8_t sub);
  void rebuild_tables();
  [[nodiscard]] SdoAbortCode check_mapping(bool transmit, std::uint32_t entry, unsigned& bits) const;
  [[nodiscard]] SdoAbortCode check_comm_write(bool transmit, std::uint16_t n, std::uint8_t sub,
                                              std::span<const std::uint8_t> bytes) const;
  [[nodiscard]] SdoAbortCode check_map_write(bool transmit, std::uint16_t n, std::uint8_t sub,
                                             std::span<const std::uint8_t> bytes) const;
  [[nodiscard]] std::vector<pdo_detail::Mapped> resolve(bool transmit, std::uint16_t n, unsigned& total_bits);
  static std::uint32_t key(CobId c) { return c.can_id() | (c.extended() ? 0x80000000u : 0u); }

  ObjectDictionary& od_;
  FrameSink sink_;
  bool operational_ = false;
  TimePoint last_now_{};
  std::vector<std::unique_ptr<Tpdo>> tpdos_;
  std::vector<std::unique_ptr<Rpdo>> rpdos_;
  std::unordered_map<std::uint32_t, Rpdo*> rx_by_id_;
  std::unordered_map<std::uint32_t, Tpdo*> rtr_by_id_;
  std::unordered_map<std::uint32_t, std::vector<Tpdo*>> watch_;  // index << 8 | sub -> TPDOs mapping it
  // The PDOs advance() and next_deadline() can act on, in number order: those with a valid COB-ID
  // and a mapping, TPDOs also event-driven (types FEh/FFh; CiA 301 §7.5.2.37: the others run on
  // SYNC or RTR only). The device's dictionary holds up to 512 of each, most of them unused, and
  // both walks run after every frame; rebuild_tables() keeps the lists with the parameters.
  std::vector<Tpdo*> timed_tpdos_;
  std::vector<Rpdo*> timed_rpdos_;
  Subscriptions subs_;  // declared last: unregisters the OD callbacks first on destruction
};

}  // namespace oegw::canopen
