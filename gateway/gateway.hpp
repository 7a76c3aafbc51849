// The OE interface module at run time: one CiA 852 device upstream (OeDevice), the network
// manager and drivers downstream, and between them the mapping file's bindings with their
// translators and the fault policy. Sans I/O: frames and time come in on two sides.
//
// Fault policy (DESIGN.md "A lost input never keeps the machine moving"):
//  * a sub-device that is lost (heartbeat timeout, no heartbeat in operational after NMT start,
//    refused at boot, never seen), reports an error EMCY, sends error / not-available codes for a
//    bound signal, or whose PDOs are overdue (Stale, Driver::advance): every FE field it feeds
//    takes its fault value at once (the translators see the non-Valid status), and EMCY 7000h
//    ("additional modules", CiA 852 Table 37) goes upstream naming it; when evidence shows the
//    cause gone (the network manager's proof of life, a fresh PDO, the error reset) the
//    error-reset EMCY follows and the log names the evidence (README "Fault policy");
//  * outputs: every entry point (upstream frame, timer, DDS/LCM command, a node coming back)
//    runs in an output batch, so one command reaches each sub-device as one frame per RPDO;
//  * neutral interlock: after that, each axis stays at neutral until it has been seen inside
//    its deadband (mapping/translate.hpp).
//  * an error EMCY lasts until the sub-device's error reset (0000h): a warning EMCY (decoded
//    error = false) does not end it, and while it lasts every input of that node is held at its
//    fault value, also when the driver maps the EMCY to no signal (tests/integration/
//    gateway_e2e_test.cpp).
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "canopen/master.hpp"
#include "gateway/fe_samples.hpp"
#include "gateway/oe_device.hpp"
#include "mapping/config.hpp"
#include "mapping/translate.hpp"
#include "subdevices/network_manager.hpp"

namespace oegw::gateway {

// The catalogue of driver signals the mapping file is checked against (built on make_driver).
mapping::SignalCatalogue driver_catalogue();

struct GatewayOptions {
  std::optional<std::filesystem::path> store_path;  // overrides upstream.store (demo, tests)
  canopen::Duration sdo_timeout = std::chrono::seconds(1);
  subdevices::NetworkTiming timing{};
};

class Gateway {
 public:
  Gateway(const mapping::Config& config, canopen::FrameSink upstream, canopen::FrameSink downstream,
          GatewayOptions options = {});
  Gateway(const Gateway&) = delete;
  Gateway& operator=(const Gateway&) = delete;

  // Powers the upstream device on (boot-up) and starts booting the sub-devices.
  canopen::ParameterStore::LoadResult start(canopen::TimePoint now);

  bool on_upstream_frame(const canopen::CanFrame& frame, canopen::TimePoint now);
  bool on_downstream_frame(const canopen::CanFrame& frame, canopen::TimePoint now);
  void on_upstream_bus_event(canopen::BusEvent event, canopen::TimePoint now);
  void advance(canopen::TimePoint now);
  [[nodiscard]] std::optional<canopen::TimePoint> next_deadline() const;

  // The state of one FE: its fields' current values (as in the upstream dictionary) and the
  // worst status of the signals feeding it.
  struct FieldState {
    std::string name;
    std::int64_t value = 0;
    subdevices::SignalStatus status = subdevices::SignalStatus::Offline;
    bool interlocked = false;
  };
  [[nodiscard]] std::vector<FieldState> fields(mapping::FeId fe) const;
  [[nodiscard]] FeStatus status(mapping::FeId fe) const;
  [[nodiscard]] std::vector<mapping::FeId> fes() const;

  // Commands from the machine application (DDS/LCM): written into the upstream dictionary as
  // the host would, then driven to the outputs. Only the sources the FE lists in the mapping
  // file are taken (mapping::CommandSource; the host's own writes are checked by OeDevice);
  // among those the last writer wins. Returns false, changing nothing, for a source the FE does
  // not take or an FE the mapping file does not configure (logged once per FE and source).
  bool command_indicators(std::uint8_t instance, std::uint64_t bits, canopen::TimePoint now,
                          mapping::CommandSource source);
  bool command_display(std::uint8_t instance, const std::array<std::int16_t, 12>& parameters, canopen::TimePoint now,
                       mapping::CommandSource source);
  // Commands refused so far: a source the FE does not take (each refused SDO download and each
  // refused RPDO entry of the host counts), an FE not configured.
  [[nodiscard]] std::uint64_t refused_commands() const { return refused_commands_; }

  [[nodiscard]] OeDevice& upstream() { return *oe_; }
  [[nodiscard]] subdevices::NetworkManager& downstream() { return network_; }
  [[nodiscard]] const std::map<std::string, std::string>& faults() const { return faults_; }

  // An FE's value or status changed (for the publishers).
  std::function<void(mapping::FeId)> on_fe_change;
  // Log lines ("right_grip: missing (heartbeat lost)"), for journald.
  std::function<void(const std::string&)> on_log;

 private:
  struct Binding {
    mapping::FeId fe;
    const mapping::FieldBinding* field;
    std::optional<mapping::FieldTranslator> translator;  // inputs
    std::optional<mapping::FeField> target;              // inputs: the field, looked up once
    mapping::OutputParams output;                         // outputs
    std::size_t signal = 0;                               // index in the driver's signals
    subdevices::SignalStatus status = subdevices::SignalStatus::Offline;
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
    bool emcy_error = false;
    std::string why;
    std::vector<std::vector<std::size_t>> by_signal;  // driver signal index -> bindings_
    std::vector<std::size_t> inputs;                   // its input bindings, in bindings_ order
    // An error EMCY holds every input of this node at its fault value, also when the driver
    // leaves its signals Valid (an EMCY code it cannot map to a signal).
    bool forced = false;
    Cause cause;  // the fault's cause (Kind::None: not faulty)
  };

  void on_signal(const std::string& sub, std::size_t index, const subdevices::SignalValue& v);
  void on_output(mapping::FeId fe, const std::string& field, std::int64_t value);
  // Raises or clears the node's fault; `evidence` names what cleared it, for the log.
  void update_fault(Sub& s, std::string_view evidence);
  // An output batch (nests): the drivers on_output() reaches meanwhile send once, at the end
  // (Driver::begin_outputs), one frame per RPDO however many outputs changed.
  void begin_outputs();
  void end_outputs(canopen::TimePoint now);
  // Feeds one input binding (the EMCY hold of its node applied); returns true if it changed.
  bool feed(Binding& b, const Sub& s, const subdevices::SignalValue& v);
  void log(const std::string& line);
  // A command from `source` for `fe`: true if the FE takes it (its watchdog restarts), else
  // refused() and false.
  bool take_command(mapping::FeId fe, mapping::CommandSource source, canopen::TimePoint now);
  // Counts a refused command and logs it once per FE and way ("dds", "lcm", "SDO", "RPDO").
  void refused(mapping::FeId fe, std::string_view way, const std::string& why);
  void command_seen(mapping::FeId fe);  // an accepted command: restarts the FE's watchdog
  void hold_error_values(canopen::TimePoint now);

  mapping::Config config_;
  canopen::ObjectDictionary master_od_;
  canopen::Master master_;
  subdevices::NetworkManager network_;
  std::unique_ptr<OeDevice> oe_;
  std::map<std::string, Sub> subs_;
  unsigned output_depth_ = 0;
  std::vector<subdevices::Driver*> batched_;  // drivers in the current output batch
  std::vector<Binding> bindings_;
  std::map<std::pair<std::string, std::size_t>, std::int64_t> output_values_;        // last sent
  std::map<std::string, std::string> faults_;  // sub-device -> reason
  canopen::TimePoint now_{};
  std::uint64_t refused_commands_ = 0;
  struct CommandWatch {  // mapping-file command_timeout_ms of one output FE
    mapping::FeId fe;
    canopen::Duration timeout;
    canopen::TimePoint last;
    bool expired = false;
  };
  std::vector<CommandWatch> watches_;
  bool started_ = false;  // start() called: the watchdogs run from then
  std::set<std::pair<mapping::FeId, std::string>> refused_logged_;  // (FE, way) already logged
};

}  // namespace oegw::gateway
