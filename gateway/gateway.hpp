// The OE interface module at run time: one CiA 852 device upstream (OeDevice), the network
// manager and drivers downstream, and between them the mapping file's bindings with their
// translators and the fault policy. Sans I/O: frames and time come in on two sides.
//
// Data path (docs/design/architecture.md#the-data-path-one-direction): driver → translator (a
// binding's FieldTranslator) → FeModel → CiA 852 device (mirrored into the dictionary at once) |
// DDS | LCM (on_fe_change, once per FE at the end of each entry point); commands → CommandArbiter →
// outputs (the output bindings).
//
// Fault policy (docs/design/fault-policy.md: a lost input never keeps the machine moving):
//  * a sub-device that is lost (heartbeat timeout, no heartbeat in operational after NMT start,
//    refused at boot, never seen), reports an error EMCY, sends error / not-available codes for a
//    bound signal, or whose PDOs are overdue (Stale, Driver::advance): every FE field it feeds
//    takes its fault value at once (the translators see the non-Valid status), and EMCY 7000h
//    ("additional modules", CiA 852 Table 37) goes upstream naming it; when evidence shows the
//    cause gone (the network manager's proof of life, a fresh PDO, the error reset) the
//    error-reset EMCY follows and the log names the evidence (docs/design/fault-policy.md);
//  * outputs: every entry point (upstream frame, timer, DDS/LCM command, a node coming back)
//    runs in an output batch, so one command reaches each sub-device as one frame per RPDO;
//  * neutral interlock: after that, each axis stays at neutral until it has been seen inside
//    its deadband (mapping/translate.hpp).
//  * EMCY faults are the drivers' (Driver::faulted,
//    docs/design/device-documents.md#faults-what-sets-them-what-clears-them): each driver says
//    which signals an EMCY faults and what clears them (its clear code, its error state read back
//    at every start); a warning faults nothing and ends nothing. A faulted bound input is at its
//    fault value before the EMCY goes up; while the driver holds any fault the node is faulty
//    (7000h) and every input of it is held at its fault value. The gateway keeps no EMCY state of
//    its own.
//
// EMCYs (docs/design/fault-policy.md, gateway/oe_device.hpp for the frames):
//  * every EMCY a configured sub-device sends is counted and kept (subdevice_emcy) and, as the
//    mapping file's downstream.emcy_forwarding says (all, faults, none), passed upstream as an
//    EMCY of the gateway (remote EMCY, OeDevice::forward_subdevice_emcy), before the EMCY 7000h
//    the fault policy may send for the same EMCY;
//  * the EMCYs of other upstream nodes the CiA 852 device consumes (1028h, present when the
//    mapping file has output FEs) are logged and kept per node (upstream_emcys).
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "canopen/master.hpp"
#include "gateway/command_arbiter.hpp"
#include "gateway/fe_model.hpp"
#include "gateway/fe_samples.hpp"
#include "gateway/gateway_tap.hpp"
#include "gateway/oe_device.hpp"
#include "gateway/remote_sdo.hpp"
#include "mapping/config.hpp"
#include "mapping/translate.hpp"
#include "subdevices/network_manager.hpp"

namespace oegw::gateway {

// The catalogue of driver signals the mapping file is checked against (built on make_driver).
mapping::SignalCatalogue driver_catalogue();

struct GatewayOptions {
  std::optional<std::filesystem::path> store_path;  // overrides upstream.store (demo, tests)
  // Overrides downstream.sdo_timeout_ms (tests).
  std::optional<canopen::Duration> sdo_timeout;
  subdevices::NetworkTiming timing{};
  // The share of the downstream bus the gateway's own SDO traffic (configuration, remote SDO;
  // a scan's probes are bounded by BusScanner's `parallel` instead) may take, its requests paced
  // accordingly at the mapping file's downstream.bitrate (canopen/301/sdo_pacer.hpp); 0: not
  // paced (the instant virtual buses of tests, which have no time on the wire to share).
  double sdo_bus_share = kDefaultSdoBusShare;
  static constexpr double kDefaultSdoBusShare = 0.85;
  // The black box (gateway/gateway_tap.hpp), told everything from the construction on; it must
  // outlive the gateway.
  GatewayTap* tap = nullptr;
};

class Gateway {
 public:
  Gateway(const mapping::Config& config, canopen::FrameSink upstream, canopen::FrameSink downstream,
          GatewayOptions options = {});
  // A reload (gateway/reload.hpp): a gateway for `config` around the upstream device another
  // gateway handed over (release_upstream()), with the same FE set; resume() starts it.
  // `drivers`, when not empty, are its sub-devices' drivers, one per sub-device of `config` in
  // its order, built beforehand (gateway/reload.hpp build_reload_drivers); else it builds them.
  struct HandedOver {
    explicit HandedOver(std::unique_ptr<OeDevice> d, std::vector<std::unique_ptr<subdevices::Driver>> built = {})
        : device(std::move(d)), drivers(std::move(built)) {}
    std::unique_ptr<OeDevice> device;
    std::vector<std::unique_ptr<subdevices::Driver>> drivers;
  };
  Gateway(const mapping::Config& config, HandedOver upstream, canopen::FrameSink downstream,
          GatewayOptions options = {});
  Gateway(const Gateway&) = delete;
  Gateway& operator=(const Gateway&) = delete;

  // Powers the upstream device on (boot-up) and starts booting the sub-devices.
  canopen::ParameterStore::LoadResult start(canopen::TimePoint now);

  // The reload's handover (gateway/reload.hpp has the rules). hand_over(), on the gateway being
  // replaced: every output at its CiA 401 error value (6206h/6207h, 6443h/6444h), reaching its
  // sub-device while that is still operational, and NMT enter pre-operational to each
  // sub-device `next` no longer configures (its PDOs stop: nothing consumes them). Then
  // release_upstream() detaches the upstream device (its SDO servers' remote target dropped, a
  // host's remote transfer in flight with it); only destruction may follow.
  void hand_over(const mapping::Config& next, canopen::TimePoint now);
  [[nodiscard]] std::unique_ptr<OeDevice> release_upstream();
  // Instead of start(), on a gateway built around a handed-over device, whose NMT state,
  // heartbeat and dictionary go on: every input at its fault value (one TPDO per PDO when
  // operational), the outputs as the device holds them (their error values until the next
  // command), then EMCY kEmcyReload, then the sub-devices are booted again, all of them. A
  // sub-device faulty before (7000h active for its node) stays faulty until its own evidence
  // when this file keeps it (same name and node-ID); else its fault ends, logged.
  void resume(canopen::TimePoint now);
  // CiA 301 Table 21 "data set" (a 6xxx device software code, allowed beside CiA 852 Table 37 by
  // its clause 14): the configuration is being replaced. Held from resume() until every
  // sub-device of the new file is operational or faulty (then its own 7000h tells), register
  // bit 0 (generic: CiA 301 §7.5.2.2 has no bit for software).
  static constexpr std::uint16_t kEmcyReload = 0x6300;
  [[nodiscard]] bool reloading() const { return reloading_; }

  // Why no run-time state can be taken now, or "" when it can: the state holds no request on the
  // wire, whose answer would call back into a gateway that is not there ("right_grip:
  // configuring (an SDO request on the wire or held)", a remote SDO transfer, a host's SDO
  // transfer). Not from inside a call of this gateway (std::logic_error).
  [[nodiscard]] std::string busy() const;
  // Run-time state (canopen/state.hpp) of everything the run decided: the downstream master and
  // network manager with each driver, remote SDO, the upstream device, the FE model, the command
  // arbiter, each field's translator and each sub-device's fault and outputs. Only when busy()
  // is "" (else std::logic_error). import_state() is for a gateway built from the same mapping
  // file and options and not started: it takes the place of start(), sends nothing and calls
  // no callback nor the tap; it throws canopen::StateError on a state of another file or
  // version, and the gateway must then be thrown away.
  void export_state(canopen::StateWriter& w) const;
  void import_state(const canopen::StateReader& r);

  bool on_upstream_frame(const canopen::CanFrame& frame, canopen::TimePoint now);
  bool on_downstream_frame(const canopen::CanFrame& frame, canopen::TimePoint now);
  void on_upstream_bus_event(canopen::BusEvent event, canopen::TimePoint now);
  // What the downstream controller reports. The interface going down (BusEvent::InterfaceDown)
  // takes every sub-device away with the gateway's own hardware: EMCY 5000h "generic CANopen
  // device hardware error" (CiA 852 Table 37) upstream, held until a downstream frame is received
  // again. The sub-devices' own losses follow as 7000h from their heartbeats, as usual.
  void on_downstream_bus_event(canopen::BusEvent event, canopen::TimePoint now);
  static constexpr std::uint16_t kEmcyHardware = 0x5000;
  void advance(canopen::TimePoint now);
  [[nodiscard]] std::optional<canopen::TimePoint> next_deadline() const;

  // The bound fields of one FE as the FE model holds them, with the status of the signal feeding
  // each (diagnostics, the demo, tests: the publishers read the typed model()).
  struct FieldState {
    std::string name;
    std::int64_t value = 0;
    subdevices::SignalStatus status = subdevices::SignalStatus::Offline;
    bool interlocked = false;
  };
  [[nodiscard]] std::vector<FieldState> fields(mapping::FeId fe) const;
  // The same without the names, in the same order, into `out` (the black box reads them at
  // every change of the FE: no allocation once `out` has grown).
  struct FieldSample {
    std::int64_t value = 0;
    subdevices::SignalStatus status = subdevices::SignalStatus::Offline;
    bool interlocked = false;
    friend bool operator==(const FieldSample&, const FieldSample&) = default;
  };
  void field_samples(mapping::FeId fe, std::vector<FieldSample>& out) const;
  [[nodiscard]] FeStatus status(mapping::FeId fe) const;
  [[nodiscard]] const std::vector<mapping::FeId>& fes() const { return model_.fes(); }  // in FE order

  // Commands from the machine application (DDS/LCM), through the command arbiter
  // (gateway/command_arbiter.hpp): only the sources the FE lists in the mapping file are taken;
  // among those the last writer wins. Returns false, changing nothing, for a source the FE does
  // not take or an FE the mapping file does not configure (logged once per FE and source).
  bool command_indicators(std::uint8_t instance, std::uint64_t bits, canopen::TimePoint now,
                          mapping::CommandSource source);
  bool command_display(std::uint8_t instance, const std::array<std::int16_t, 12>& parameters, canopen::TimePoint now,
                       mapping::CommandSource source);
  // A device command of a sub-device's driver (Driver::commands(), e.g. the Novotechnik
  // "position_error_reset", 2100h): sent as SDO downloads while the node is operational, each
  // answer logged. False (logged) for an unknown sub-device or command, or a node not
  // operational. What it changes comes from the device's own evidence (a clear EMCY).
  bool subdevice_command(const std::string& name, std::string_view command, canopen::TimePoint now);
  // The host's way to the same commands: an SDO download of 3000h "Sub-device command"
  // (cia852::kSubdeviceCommand) = command code << 8 | node-ID; the codes are kSubdeviceCommands.
  // Refused, changing nothing: a node not configured 0609 0011h, an unknown code (or one the
  // node's driver has not, or bits 16..31 set) 0609 0030h, a node not operational 0800 0022h.
  static constexpr std::pair<std::uint8_t, std::string_view> kSubdeviceCommands[] = {{1, "position_error_reset"}};
  // Commands refused so far: a source the FE does not take (each refused SDO download and each
  // refused RPDO entry of the host counts), an FE not configured.
  [[nodiscard]] std::uint64_t refused_commands() const { return arbiter_->refused(); }
  // Those of one configured output FE (zero for an input FE: nothing commands it).
  [[nodiscard]] std::uint64_t refused_commands(mapping::FeId fe) const { return arbiter_->refused(fe); }
  // Commands aimed at sub-devices that the gateway refused: remote SDO transfers (RemoteSdo:
  // the node's state, the write policy, a network indication naming no sub-device), 3000h
  // sub-device commands of the host and subdevice_command() (an unknown node or command, a node
  // not operational). A sub-device's own SDO aborts are not refusals of the gateway.
  [[nodiscard]] std::uint64_t subdevice_refused_commands() const;
  // Those aimed at one configured sub-device (zeros for an unknown name).
  [[nodiscard]] std::uint64_t subdevice_refused_commands(const std::string& name) const;

  [[nodiscard]] OeDevice& upstream() { return *oe_; }
  [[nodiscard]] const OeDevice& upstream() const { return *oe_; }
  [[nodiscard]] const FeModel& model() const { return model_; }
  [[nodiscard]] subdevices::NetworkManager& downstream() { return network_; }
  [[nodiscard]] const subdevices::NetworkManager& downstream() const { return network_; }
  // The downstream master (its SDO pacing: status).
  [[nodiscard]] const canopen::Master& master() const { return master_; }
  // Remote SDO: the host's transfers to sub-devices (gateway/remote_sdo.hpp).
  [[nodiscard]] const RemoteSdo& remote_sdo() const { return *remote_sdo_; }
  // An SDO server channel a network indication has redirected to a sub-device
  // (docs/guides/remote-sdo.md): every client of that channel reaches the sub-device,
  // not the gateway, until it ends. Logged when it begins and ends; `oegw status` lists them.
  struct SdoRedirect {
    std::uint16_t server = 0;          // the channel's object, 1200h + channel
    canopen::CobId request, response;  // its COB-IDs (client -> server, server -> client)
    canopen::SdoServer::Redirect redirect;
    std::string subdevice;  // the configured sub-device named
  };
  [[nodiscard]] std::vector<SdoRedirect> sdo_redirects() const;
  // The same RemoteSdo for the control socket's transfers (`oegw ctl`, gateway/control/
  // ctl_service.hpp): one mechanism, one policy for the host's and the commissioning tool's SDO.
  // `now` is the entry point's time (the gateway's clock of the call, as for a frame).
  [[nodiscard]] RemoteSdo& remote_sdo(canopen::TimePoint now);
  // NMT node control of a downstream node from the control socket (`oegw ctl`). Empty when
  // sent; else why not, sending nothing: a sub-device the gateway is booting (its boot comes
  // first), or NMT start of a sub-device the gateway holds as missing or refused (only its own
  // boot starts a node). A node the mapping file does not configure is commanded as asked
  // (commissioning a new device). What follows is the network manager's as for any NMT state
  // change it did not cause (a stopped node in use is lost: its FEs take their fault values).
  [[nodiscard]] std::string downstream_nmt(canopen::NodeId node, canopen::NmtCommand cs, canopen::TimePoint now);
  // Every boot-up and EMCY on the downstream bus, configured node or not, after the gateway has
  // handled it (the control socket's event lines, `oegw ctl`).
  // A line for the log from the control socket's commands ("control: " + line).
  void log_control(const std::string& line) { log("control: " + line); }
  std::function<void(canopen::NodeId)> on_downstream_boot_up;
  std::function<void(const canopen::EmcyMessage&)> on_downstream_emcy;
  // The downstream bus for a commissioning tool's own traffic (`oegw scan` through the daemon,
  // gateway/control/scan_service.hpp): a frame sent as the gateway sends its own, and every
  // frame received, after the gateway has handled it. Only for node-IDs that are no sub-device
  // and for LSS on the network manager's master (their SDO channels are the gateway's clients').
  void send_downstream(const canopen::CanFrame& frame);
  std::function<void(const canopen::CanFrame&, canopen::TimePoint)> on_downstream_frame_seen;
  [[nodiscard]] const std::map<std::string, std::string>& faults() const { return faults_; }

  // The EMCYs received from one node: the last one, when it arrived (the gateway's clock), how
  // many so far; all zeros before the first.
  struct EmcyRecord {
    canopen::EmcyMessage last{};
    canopen::TimePoint time{};
    std::uint64_t count = 0;
  };
  // A sub-device's EMCYs, by its mapping-file name (zeros for an unknown name).
  [[nodiscard]] EmcyRecord subdevice_emcy(const std::string& name) const;
  // The EMCYs of other upstream nodes the CiA 852 device consumed (1028h), by node-ID.
  [[nodiscard]] const std::map<std::uint8_t, EmcyRecord>& upstream_emcys() const { return upstream_emcys_; }

  // An FE's value or status changed (for the publishers): once per FE, in FE order, at the end
  // of the call that changed it (the model is then complete for that frame).
  std::function<void(mapping::FeId)> on_fe_change;
  // Log lines ("right_grip: missing (heartbeat lost)"), for journald.
  std::function<void(const std::string&)> on_log;

  // The observer of every input, output and decision (gateway/gateway_tap.hpp: the black box);
  // nullptr: none. It must outlive the gateway or be removed first.
  void set_tap(GatewayTap* tap) { tap_ = tap; }
  // A control-socket request line reaching the running gateway (told to the tap only).
  void control_request(std::string_view line, canopen::TimePoint now) {
    if (tap_ != nullptr) tap_->control(line, now);
  }

 private:
  struct Sub;
  struct Binding {
    mapping::FeId fe;
    const mapping::FieldBinding* field;
    FieldRef ref;                                        // the FE model's field
    std::optional<mapping::FieldTranslator> translator;  // inputs
    mapping::OutputParams output;                        // outputs
    std::size_t signal = 0;                              // index in the driver's signals
    std::size_t group = 0;                               // inputs: index in groups_ (its FE)
    subdevices::SignalStatus status = subdevices::SignalStatus::Offline;
    Sub* sub = nullptr;  // its sub-device (no look-up by name on the way to an output)
  };
  // The input bindings of one FE (its status is the worst of theirs).
  struct FeGroup {
    mapping::FeId fe;
    std::vector<std::size_t> inputs;
  };
  // The output bindings of one output FE, per field (indicator k−1, parameter p−1).
  struct OutputGroup {
    mapping::FeId fe;
    std::vector<std::vector<std::size_t>> by_field;
  };
  // What keeps a sub-device faulty (update_fault): its state, an error EMCY, or one bound input.
  struct Cause {
    enum class Kind : std::uint8_t { None, State, Emcy, Input };
    Kind kind = Kind::None;
    std::size_t binding = 0;  // Input: the index in bindings_
    subdevices::SignalStatus status = subdevices::SignalStatus::Valid;
    friend bool operator==(const Cause&, const Cause&) = default;
  };
  struct Sub {
    const mapping::SubdeviceConfig* config = nullptr;
    subdevices::Driver* driver = nullptr;
    bool operational = false;
    bool failed = false;  // missing, refused or rebooted since it was last operational (a fault)
    std::string why;
    std::vector<std::vector<std::size_t>> by_signal;  // driver signal index -> bindings_
    std::vector<std::size_t> inputs;                  // its input bindings, in bindings_ order
    std::vector<std::size_t> outputs;                 // its output bindings
    std::vector<std::int64_t> output_values;          // per driver signal: the value last set
    // The driver holds a fault (Driver::any_fault) while operational: every input of this node
    // is held at its fault value, also those the driver leaves Valid.
    bool forced = false;
    Cause cause;                         // the fault's cause (Kind::None: not faulty)
    EmcyRecord emcy;                     // the EMCYs it sent
    std::uint64_t refused_commands = 0;  // 3000h / subdevice_command() for it, refused
  };

  Gateway(const mapping::Config& config, std::unique_ptr<OeDevice> handed_over, canopen::FrameSink upstream,
          canopen::FrameSink downstream, const GatewayOptions& options,
          std::vector<std::unique_ptr<subdevices::Driver>> drivers = {});
  // The constructor's steps, in this order.
  void connect_upstream_device();
  void add_subdevices(std::vector<std::unique_ptr<subdevices::Driver>> built);
  void bind_functional_elements();
  void hook_network();
  void hook_master();
  void hook_upstream_device();
  // The network manager's and the upstream device's reports.
  void on_node_state(const std::string& name, subdevices::NodeState st, const std::string& why);
  void on_subdevice_emcy(const std::string& name, const canopen::EmcyMessage& e, const subdevices::DecodedEmcy& d);
  void on_fault_evidence(const std::string& name, const std::string& what);
  void on_upstream_emcy(const canopen::EmcyMessage& m, canopen::TimePoint t);
  // resume(): ends kEmcyReload once every sub-device is operational or faulty.
  void settle_reload();
  void on_signal(Sub& s, std::size_t index, const subdevices::SignalValue& v);
  void on_output(mapping::FeId fe, FieldRef ref, std::int64_t value);
  void drive(Binding& b, Sub& s, std::int64_t value);
  // Raises or clears the node's fault; `evidence` names what cleared it, for the log.
  void update_fault(Sub& s, std::string_view evidence);
  // The fault policy's EMCY for a node (7000h, or the 0000h of its recovery); while a
  // sub-device's EMCY is being decoded, held until that EMCY has been forwarded.
  void fault_emcy(Sub& s, bool raise);
  // An output batch (nests): the drivers on_output() reaches meanwhile send once, at the end
  // (Driver::begin_outputs), one frame per RPDO however many outputs changed.
  void begin_outputs();
  void end_outputs(canopen::TimePoint now);
  // Feeds one input binding (the EMCY hold of its node applied) into the FE model.
  // `decided_now`: the value is the gateway's decision of now, not a frame's (source time).
  void feed(Binding& b, const Sub& s, const subdevices::SignalValue& v, bool decided_now = false);
  // The FEs the call changed, to the publishers (on_fe_change).
  void publish_changes();
  void log(const std::string& line);
  // The log line of a change of SDO server channel `channel`'s redirect.
  void log_redirect(std::size_t channel, const std::optional<canopen::SdoServer::Redirect>& before,
                    const std::optional<canopen::SdoServer::Redirect>& after, canopen::SdoServer::RedirectChange why);

  GatewayTap* tap_;
  // The downstream sink the gateway was given, behind the tap (every frame it sends downstream
  // passes here; the upstream device's frames reach the tap through OeDevice::on_sent).
  canopen::FrameSink tapped(Bus bus, canopen::FrameSink sink);
  canopen::FrameSink downstream_out_;
  mapping::Config config_;
  canopen::ObjectDictionary master_od_;
  canopen::Master master_;
  subdevices::NetworkManager network_;
  std::unique_ptr<RemoteSdo> remote_sdo_;  // before oe_: its SDO servers point to it
  std::unique_ptr<OeDevice> oe_;
  canopen::Subscription command_hook_;  // 3000h's write hook (after oe_: removed before it)
  canopen::SdoAbortCode host_subdevice_command(std::uint32_t value);
  // subdevice_command() and downstream_nmt() without telling the tap (the host's 3000h path is
  // told as its upstream frame).
  bool run_subdevice_command(const std::string& name, std::string_view command, canopen::TimePoint now);
  std::string run_downstream_nmt(canopen::NodeId node, canopen::NmtCommand cs, canopen::TimePoint now);
  // Counts a refused 3000h / subdevice_command() (`s`: the sub-device it was for, or nullptr).
  void count_refused(Sub* s);
  std::uint64_t subdevice_commands_refused_ = 0;  // 3000h / subdevice_command() refusals, all
  FeModel model_;
  canopen::TimePoint now_{};
  bool downstream_down_ = false;  // BusEvent::InterfaceDown, no downstream frame since (EMCY 5000h)
  std::unique_ptr<CommandArbiter> arbiter_;
  std::map<std::string, Sub> subs_;
  unsigned output_depth_ = 0;
  std::vector<subdevices::Driver*> batched_;  // drivers in the current output batch
  std::vector<Binding> bindings_;
  // FE -> its bindings, [first, end) in bindings_: bound one FE after the other, each FE's are
  // contiguous (the black box reads them at every change of the FE).
  std::map<mapping::FeId, std::pair<std::size_t, std::size_t>> fe_bindings_;
  [[nodiscard]] std::span<const Binding> bindings_of(mapping::FeId fe) const;
  std::vector<FeGroup> groups_;
  std::vector<OutputGroup> output_groups_;
  std::map<std::string, std::string> faults_;            // sub-device -> reason
  std::map<std::uint8_t, EmcyRecord> upstream_emcys_;    // upstream node-ID -> its EMCYs (1028h)
  bool reloading_ = false;                               // kEmcyReload held (resume())
  bool decoding_emcy_ = false;                           // inside a sub-device's EMCY
  std::vector<std::pair<Sub*, bool>> held_fault_emcys_;  // fault_emcy calls meanwhile
};

}  // namespace oegw::gateway
