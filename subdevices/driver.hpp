// A sub-device driver: one node of one device family. It turns that node's PDOs and EMCYs into
// named signals (signal.hpp) and output commands into its RPDOs, and says how the node must be
// configured at boot. Sans I/O like the protocol core: frames and time in, frames out.
//
// The downstream network manager (network_manager.hpp) owns the boot sequence, heartbeat and
// SDO client; it calls the driver's hooks. The mapping layer reads signals and sets outputs.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "canopen/301/emcy.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/state.hpp"
#include "canopen/types.hpp"
#include "subdevices/signal.hpp"

namespace oegw::subdevices {

using canopen::CanFrame;
using canopen::EmcyMessage;
using canopen::FrameSink;
using canopen::NodeId;

// One SDO download of the boot configuration (CiA 301 / the bus.yml "sdo" list).
struct SdoWrite {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::vector<std::uint8_t> data;  // little endian, the object's size
  std::string what;                // for logs: "TPDO1 event timer 50 ms"
};

// 1000h / 1018h values to check at boot; unset fields are not checked.
struct ExpectedIdentity {
  std::optional<std::uint32_t> device_type;
  std::optional<std::uint32_t> vendor_id;
  std::optional<std::uint32_t> product_code;
  std::optional<std::uint32_t> revision;
  std::optional<std::uint32_t> serial;
};

// A decoded EMCY, for logs and for the gateway's status message.
struct DecodedEmcy {
  std::uint16_t code = 0;
  std::string text;  // "elobau 4001h 0x0021: X axis signal 1 out of range"
  // The EMCY reports an error (forwarded upstream under emcy_forwarding: faults). false for a
  // clear code (0000h, Novotechnik 5051h "valid position"), a warning (81xxh CAN communication)
  // and an undecodable code.
  bool error = true;
  // The signals this EMCY puts in Error: as a rule faulted (Driver::faulted) until the driver's
  // clear evidence; the driver's header says where not (a Novotechnik position warning, which
  // its PDOs end). Empty: it faults nothing (a warning, a clear code, an unknown code ignored).
  std::vector<std::size_t> affected;
};

class Driver {
 public:
  Driver() = default;
  Driver(const Driver&) = delete;
  Driver& operator=(const Driver&) = delete;
  virtual ~Driver() = default;

  [[nodiscard]] virtual std::string_view family() const = 0;  // "elobau-mfg", "mcb402", ...
  [[nodiscard]] NodeId node() const { return node_; }

  // The signals, in a fixed order; a signal's index is its position here.
  [[nodiscard]] virtual const std::vector<SignalInfo>& signals() const = 0;
  [[nodiscard]] std::optional<std::size_t> find_signal(std::string_view name) const;
  [[nodiscard]] const SignalValue& value(std::size_t index) const { return values_.at(index); }

  // Boot: what the master checks and writes before NMT start (driver defaults; the network
  // manager appends the configuration file's own writes after these).
  [[nodiscard]] virtual ExpectedIdentity expected_identity() const { return {}; }
  [[nodiscard]] virtual std::vector<SdoWrite> configuration() const { return {}; }
  // Objects besides configuration() that a remote SDO write from the host must not change while
  // the node's signals are in use (gateway/remote_sdo.hpp): e.g. a manufacturer object that sets
  // the node-ID or bit rate. The communication objects the gateway configures are protected
  // for every driver.
  [[nodiscard]] virtual bool protects(std::uint16_t /*index*/, std::uint8_t /*sub*/) const { return false; }
  // Objects the driver must read from the node at boot, before configuration() is written
  // (e.g. a generic node's actual PDO mapping). The network manager calls begin_boot(), then
  // asks boot_reads() in rounds until it returns nothing (an answer may tell what to read
  // next), handing each answer to on_boot_read() and each refused read to
  // on_boot_read_abort(). Returning false from either refuses the node (with `error`).
  // The 1001h error register the manager reads for its diagnostics is handed to on_boot_read()
  // before the first round, so a driver that needs it (and stops listing it once answered) is
  // not asked for it twice.
  virtual void begin_boot() {}
  [[nodiscard]] virtual std::vector<std::pair<std::uint16_t, std::uint8_t>> boot_reads() const { return {}; }
  virtual bool on_boot_read(std::uint16_t /*index*/, std::uint8_t /*sub*/, std::span<const std::uint8_t> /*data*/,
                            std::string& /*error*/) {
    return true;
  }
  virtual bool on_boot_read_abort(std::uint16_t /*index*/, std::uint8_t /*sub*/, canopen::SdoAbortCode /*code*/) {
    return false;
  }

  // A write of configuration() the node refused (`code`): the driver may give another write in
  // its stead (a device without the object the document's default names: the Novotechnik's
  // 6020h, mapped as 6004h instead), which the network manager makes in its place; nullopt refuses
  // the node, as any refused write does.
  [[nodiscard]] virtual std::optional<SdoWrite> instead_of_refused(const SdoWrite& /*write*/,
                                                                   canopen::SdoAbortCode /*code*/) {
    return std::nullopt;
  }
  // A driver that needs the node restarted once its configuration is written (the elobau grip
  // after saving its parameters, "Restart the joystick after saving procedure") says so here,
  // asked after the writes: the network manager then sends NMT reset node and boots it again.
  [[nodiscard]] virtual bool restart_after_configuration() const { return false; }

  // An object whose read-back is a fault's only clear evidence while the node runs (the
  // MCB-402's 1001h after a cable break its board never resets by EMCY): while fault_poll()
  // names one, the network manager reads it every `period` while the node is operational and
  // hands the answer (or nothing, on an abort) to on_fault_poll(). on_fault_poll_sent() is called
  // as the request goes out: a driver ignores an answer to a request sent before a fault it
  // latched since (the EMCY may overtake the answer on the bus).
  struct FaultPoll {
    std::uint16_t index = 0;
    std::uint8_t sub = 0;
    Duration period{0};
  };
  [[nodiscard]] virtual std::optional<FaultPoll> fault_poll() const { return std::nullopt; }
  virtual void on_fault_poll_sent() {}
  // Returns what the answer showed, for the log ("" = nothing to report).
  virtual std::string on_fault_poll(std::span<const std::uint8_t> /*data*/, TimePoint /*now*/) { return {}; }

  // Device commands an integrator may give (Gateway::subdevice_command), by name: the SDO
  // writes each one is (empty: no such command). E.g. the Novotechnik "position_error_reset".
  [[nodiscard]] virtual std::vector<std::string> commands() const { return {}; }
  [[nodiscard]] virtual std::vector<SdoWrite> command(std::string_view /*name*/) const { return {}; }

  // Runtime. on_frame() gets every frame whose COB-ID belongs to this node's PDOs (the network
  // manager routes by COB-ID); it returns false for a frame it does not use (counted).
  virtual bool on_frame(const CanFrame& frame, TimePoint now) = 0;
  virtual DecodedEmcy on_emcy(const EmcyMessage& emcy, TimePoint now) = 0;
  // The COB-IDs of the node's TPDOs the driver consumes (for routing and receive filters).
  [[nodiscard]] virtual std::vector<std::uint32_t> consumed_cob_ids() const = 0;

  // The network manager reports the node's life: operational (configured, started) or not.
  // Going offline marks every input Offline; coming back leaves them Offline until a PDO
  // arrives (the neutral interlock is the mapping layer's job).
  virtual void on_online(TimePoint now);
  virtual void on_offline(TimePoint now);

  // Outputs: sets output signal `index` to `value` and sends what the device needs (RPDO).
  // Returns false (sending nothing) for a non-output signal or a value out of range.
  // Between begin_outputs() and end_outputs() nothing is sent: end_outputs() sends each RPDO
  // whose content changed once, so that one command changing several outputs reaches the
  // device as one frame per RPDO and never as the intermediate states (an LED byte 00h -> 05h
  // is one frame 05h, not 01h then 05h). Nests; the outermost end_outputs() sends.
  virtual bool set_output(std::size_t index, std::int64_t value, TimePoint now) = 0;
  void begin_outputs() { ++output_batch_; }
  void end_outputs(TimePoint now);

  // Freshness of the values (docs/design/fault-policy.md). A signal carried by a TPDO the device
  // sends periodically (event timer T, transmission type 254/255, CiA 301 §7.5.2.35) is Stale
  // once kMissedPeriods × T pass without that PDO: the node may still send its heartbeat, but
  // the value is no longer evidence. The mapping file's pdo_timeout_ms replaces the derived
  // deadline for every PDO-carried signal (also PDOs sent on change only, which have none), or
  // for every input signal of a driver that declares no carriers.
  static constexpr int kMissedPeriods = 3;
  // The boot writes that were made (the driver's configuration() and the mapping file's `sdo`
  // list, in that order): event timers (18xxh:05) and transmission types (18xxh:02) written
  // there replace the driver's defaults.
  void apply_boot_writes(const std::vector<SdoWrite>& writes);
  void set_pdo_timeout(Duration timeout);  // 0: the deadlines derived from the event timers
  // The floor of a derived deadline (docs/design/fault-policy.md): kMissedPeriods × T, or the SYNC
  // product, is raised to at least this, so that a controller whose scheduling stalls for less
  // than the floor minus one period (a loaded cab controller, a TCG guest: ~130 ms seen) raises
  // no stale fault, while a device whose PDOs stop is still caught within the floor. Each family
  // has its default (the option freshness_floor_ms, freshness_floor_option()); 0: no floor.
  // pdo_timeout_ms, written by the user, is taken as it is.
  void set_freshness_floor(Duration floor);
  [[nodiscard]] Duration freshness_floor() const { return freshness_floor_; }
  // SYNC: a TPDO of transmission type n = 1..240 is sent after every n-th SYNC (CiA 301
  // §7.5.2.35), so with the SYNC period P it is Stale once kMissedPeriods × n × P pass without
  // it. 0: no SYNC is produced (such a TPDO then has no derived deadline).
  void set_sync_period(Duration period);
  // The communication index (18xxh) of the first carrier whose transmission type is synchronous
  // (0..240: sent only at a SYNC), after apply_boot_writes(); nullopt when none is.
  [[nodiscard]] std::optional<std::uint16_t> synchronous_carrier() const;
  // The deadline of one signal (0: none), and the largest of all (0: none).
  [[nodiscard]] Duration freshness(std::size_t index) const;
  [[nodiscard]] Duration longest_freshness() const;
  // Since when the node is proven alive (the network manager; nullopt while it is not): a
  // signal with a deadline that has had no PDO since then, nor since it went offline, is Stale
  // once the deadline passes (a node that starts but never sends its PDOs).
  void set_alive_since(std::optional<TimePoint> since);
  // The network manager calls this for every PDO it routes here, before on_frame(): the signals
  // its carrier holds are fresh from `now` on. Only this makes a value fresh: a driver that
  // republishes a value from an older frame (the elobau's channel-2 TPDO, an EMCY) cannot
  // revive an overdue signal (update() keeps it Stale). A PDO that arrives after its deadline
  // first marks its signals Stale (the deadline passed before anyone looked).
  void pdo_received(std::uint32_t can_id, TimePoint now);
  // Marks signals whose PDO is overdue Stale (on_change reports them).
  void advance(TimePoint now);
  // True when the driver has freshness deadlines and every signal that has one is Stale: for a
  // node without heartbeat, the sign that it is gone (or stopped by someone else).
  [[nodiscard]] bool all_stale() const;
  // Inline: the network manager asks every operational driver after each frame; the answer is
  // kept until a PDO, the proof of life or a signal's status changes it.
  [[nodiscard]] std::optional<TimePoint> next_deadline() const {
    return next_due_known_ ? next_due_ : find_next_deadline();
  }

  // Faults (docs/design/device-documents.md#faults-what-sets-them-what-clears-them). The device's
  // own reports of an error (an EMCY, or its error state read back at boot) fault signals: a
  // faulted input is Error with its neutral value whatever its PDOs carry (an output keeps its
  // value, status Error), until the driver clears the fault on the device's evidence — its
  // documented clear code, or its error state read back at every (re)start (boot_reads()). Going
  // offline and coming back change nothing (Offline shows meanwhile): only evidence does. The
  // gateway holds no fault state of its own besides this (gateway/gateway.hpp).
  [[nodiscard]] bool faulted(std::size_t index) const { return index < faults_.size() && faults_[index]; }
  [[nodiscard]] bool any_fault() const { return fault_count_ != 0; }
  // The node booted on its own or answered NMT reset node (its error state is that of a fresh
  // start). A driver whose boot_reads() read the error state back keeps its faults for that
  // read-back to decide; the default drops them (the device reports again what persists).
  virtual void on_application_reset(TimePoint now);

  // One TPDO the device sends, as the boot configures it: what `oegw check` counts for the
  // bus load (gateway/bus_load.hpp).
  struct TpdoTraffic {
    std::uint32_t cob_id = 0;
    std::uint8_t length = 8;           // data bytes
    std::uint16_t event_timer_ms = 0;  // 0: none
    std::uint8_t transmission_type = 0xFF;
    std::uint16_t inhibit_100us = 0;  // 0: none
  };
  // The TPDOs the device sends once `writes` (its configuration() and the mapping file's `sdo`
  // list, in that order) are made: its carriers, with the event timers (18xxh:05), transmission
  // types (:02) and inhibit times (:03) written there. Without a boot (the generic node reads
  // its PDOs at boot) a driver answers from its device description.
  [[nodiscard]] virtual std::vector<TpdoTraffic> expected_tpdos(const std::vector<SdoWrite>& writes) const;

  // Called with a signal's index whenever its value or status changed.
  std::function<void(std::size_t index, const SignalValue& value)> on_change;

  // Run-time state (canopen/state.hpp), for a fresh driver of the same family and options: what
  // the last boot learned from the node and wrote to it (import applies them as
  // apply_boot_writes does: they shape the watches), each signal's value, status, time and fault,
  // when each watched PDO last came, the proof of life, the counters, then the family's own
  // latches (export_family_state). Outside an output batch only. on_change is not called. Throws
  // canopen::StateError; a driver whose import threw is thrown away. The owner imports after it
  // has set the deadlines' options (set_pdo_timeout, set_sync_period, set_freshness_floor: they
  // clear the watches) and routes frames by consumed_cob_ids() afterwards (a CiA 401 node's come
  // with its PDOs).
  void export_state(canopen::StateWriter& w) const;
  void import_state(const canopen::StateReader& r);

  [[nodiscard]] const InputCounters& counters() const { return counters_; }

  // Where its RPDOs go from now on: a driver built before its gateway (a reload's, in the thread
  // that reads the file: gateway/reload.hpp build_reload_drivers) gets the gateway's sink here.
  void bind_sink(FrameSink sink) { sink_ = std::move(sink); }

 protected:
  // Drivers are built by their factory with their node and the sink for RPDOs.
  void init(NodeId node, FrameSink sink, std::size_t signal_count);
  // Updates a signal; calls on_change if value or status differ. Inline, the common case of a
  // PDO that repeats most of its values (a grip's TPDO carries every button with each axis
  // change): with no signal faulted and no watch due yet nothing can override the status, so an
  // equal value and status only move the signal's time; all else is update_checked().
  void update(std::size_t index, std::int64_t value, SignalStatus status, TimePoint now) {
    if (fault_count_ == 0 && (!earliest_due_ || now < *earliest_due_) && index < values_.size()) {
      SignalValue& v = values_[index];
      if (v.value == value && v.status == status) {
        v.timestamp = now;
        return;
      }
    }
    update_checked(index, value, status, now);
  }
  // Faults a signal, Error at once when `now` is given; without it the status is left (at boot,
  // while the signals are Offline anyway; a state import). A cleared input keeps its neutral
  // value in Error until its next PDO brings a value (that frame is the evidence it is good
  // again).
  void set_fault(std::size_t index, std::optional<TimePoint> now = std::nullopt);
  void clear_fault(std::size_t index);
  void clear_all_faults();
  void send(const CanFrame& frame) {
    if (sink_) sink_(frame);
  }
  // Inside begin_outputs()/end_outputs(): set_output() records what changed and leaves the
  // sending to flush_outputs(), which end_outputs() calls once.
  [[nodiscard]] bool outputs_deferred() const { return output_batch_ > 0; }
  virtual void flush_outputs(TimePoint /*now*/) {}

  // One TPDO of the device and the input signals it carries (for freshness).
  struct Carrier {
    std::uint32_t cob_id = 0;  // the CAN-ID it arrives on (pdo_received)
    // false: a PDO the device may not send at all (the elobau's channel-2 TPDO #1, which a grip
    // may have disabled): watched only once it has been seen since the proof of life.
    bool required = true;
    std::uint16_t comm_index = 0x1800;     // 1800h + TPDO number - 1
    std::uint16_t event_timer_ms = 0;      // 0: sent on change (or SYNC) only
    std::uint8_t transmission_type = 254;  // the event timer counts for 254/255 only
    std::vector<std::size_t> signals;
    std::uint8_t length = 8;          // data bytes of the PDO (its mapping), for the bus load
    std::uint16_t inhibit_100us = 0;  // 18xxh:03 as the device has it by default
  };
  // Applies the writes to 18xxh:02/:03/:05 of `comm_index` (expected_tpdos()).
  static void apply_tpdo_writes(TpdoTraffic& t, std::uint16_t comm_index, const std::vector<SdoWrite>& writes);
  // Declares the carriers (in the constructor, or from refresh_carriers()).
  void set_carriers(std::vector<Carrier> carriers);
  // Called by apply_boot_writes() first: a driver that learns its PDO layout at boot (the
  // generic CiA 401 node) declares its carriers here.
  virtual void refresh_carriers() {}
  // Called by apply_boot_writes() with every write made (its configuration() and the mapping
  // file's `sdo` list): a driver whose boot reads a write may override takes the written value
  // (the elobau's fitted buttons 2100h:01h/02h).
  virtual void boot_writes_made(const std::vector<SdoWrite>& /*writes*/) {}
  // The family's run-time state, under "family." (export_state). What the family learned from the
  // node at boot and its carriers depend on (a CiA 401 node's PDOs) is imported first, before the
  // boot writes are applied again; the rest after.
  virtual void export_family_state(canopen::StateWriter& /*w*/) const {}
  virtual void import_boot_learned(const canopen::StateReader& /*family*/) {}
  virtual void import_family_state(const canopen::StateReader& /*family*/) {}

  InputCounters counters_;

 private:
  // One watched PDO: its deadline, the signals it carries, when it last came. A signal is as
  // fresh as the stalest PDO that carries it (an elobau axis needs TPDO #0, and TPDO #1 once
  // seen: one of them alone does not keep it live).
  static constexpr std::uint32_t kAnyCob = 0xFFFFFFFF;  // a driver without carriers: any PDO
  struct Watch {
    std::uint32_t cob;
    Duration deadline;
    bool required;
    std::vector<std::size_t> signals;
    std::optional<TimePoint> last;
    std::optional<TimePoint> due;  // compute_due(), kept current: nullopt while not watched
  };
  void update_checked(std::size_t index, std::int64_t value, SignalStatus status, TimePoint now);
  void rebuild_deadlines();
  [[nodiscard]] std::optional<TimePoint> compute_due(const Watch& w) const;  // nullopt: not watched yet
  [[nodiscard]] bool overdue(std::size_t index, TimePoint now) const;
  [[nodiscard]] bool watched(std::size_t index) const;  // Valid, or Offline while alive
  void mark_stale(const Watch& w, TimePoint now);
  void refresh_earliest_due();  // after any Watch::due changed

  NodeId node_{};
  FrameSink sink_;
  std::vector<SignalValue> values_;
  std::vector<bool> faults_;  // by signal: faulted (set_fault)
  std::size_t fault_count_ = 0;
  unsigned output_batch_ = 0;
  std::vector<Carrier> carriers_;
  std::vector<SdoWrite> boot_writes_;  // the last apply_boot_writes(), for export_state
  Duration pdo_timeout_{0};
  Duration freshness_floor_{0};
  Duration sync_period_{0};
  std::optional<TimePoint> alive_since_;
  std::vector<Duration> deadline_;  // by signal: the shortest of its PDOs'; 0 = none
  std::vector<Watch> watches_;
  std::vector<std::uint32_t> watch_mask_;  // by signal: bit k = watches_[k] carries it
  std::optional<TimePoint> earliest_due_;  // the soonest Watch::due: before it nothing is overdue
  [[nodiscard]] std::optional<TimePoint> find_next_deadline() const;
  // next_deadline()'s answer, kept while nothing it depends on changed: the event loop asks for
  // it after every frame, and the network manager asks every driver. It depends on the watches'
  // dues (each change ends in refresh_earliest_due()) and on the signals' statuses (update()),
  // the only two places that clear next_due_known_. find_next_deadline() computes it afresh.
  mutable std::optional<TimePoint> next_due_;
  mutable bool next_due_known_ = false;
  std::vector<std::size_t> with_deadline_;  // the signals that have one
};

// Creates a driver by family name ("elobau-mfg", "mcb402", "novotechnik-406", "cia401").
// `options` are the family's settings from the configuration (e.g. the elobau channel
// tolerance, the generic node's EDS path), parsed by the family's option table
// (driver_options.hpp, also what `oegw signals` lists); unknown options are an error. Returns
// nullptr and sets `error` for an unknown family or bad options.
struct DriverOptions {
  std::vector<std::pair<std::string, std::string>> values;  // key -> value, as written
  [[nodiscard]] std::optional<std::string> get(std::string_view key) const;
};
// The options that name a file (cia401 `eds`): the mapping loader takes a relative one from the
// mapping file's folder (docs/reference/mapping-file.md#paths), so a driver always sees the path to
// open.
[[nodiscard]] constexpr bool is_file_option(std::string_view key) { return key == "eds"; }
std::unique_ptr<Driver> make_driver(std::string_view family, NodeId node, FrameSink sink, const DriverOptions& options,
                                    std::string& error);

}  // namespace oegw::subdevices
