// The downstream network manager: the gateway as NMT master of the cab's sub-devices (CiA 302
// concepts, bus.yml vocabulary). For each configured node it
//   1. resets communication and waits for the boot-up (or finds the node already there): a
//      boot-up that does not come (lost on the bus, a device that sends none) is not waited
//      out: 1000h is read from NetworkTiming::boot_probe_first on, at doubling gaps (CiA
//      302-2's boot-slave process reads the device type of a node whatever it has seen of
//      it), and the node's answer — SDO is served in pre-operational and operational only,
//      never during its reset (CiA 301 §7.3.2.2.1) — starts the configuration at once,
//   2. sends NMT enter pre-operational to the node: a node that starts itself (Novotechnik
//      1F80h bit 3, elobau 5000h) is operational right after its boot-up, or already when the
//      gateway first sees it, and refuses remapping and store while operational,
//   3. reads 1000h and 1018h:01..04 and checks them against the configuration (the revision by
//      its major part, the upper 16 bits, unless NodeSettings::exact_revision; CiA 301
//      §7.5.2.13); then the diagnostics 1008h/1009h/100Ah and 1001h (NodeDiagnostics: an
//      abort of these, or of a 1018h sub-index nothing is expected of, means "not present"),
//      reported once per boot (on_diagnostics),
//   4. runs the driver's boot reads (e.g. a generic node's actual PDO mapping),
//   5. writes the producer heartbeat (1017h), the driver's configuration and the configured
//      `sdo` list, in that order (each request held while another node's heartbeat is late:
//      late_heartbeat()); a driver that must have the node restarted then
//      (Driver::restart_after_configuration: the elobau grip after saving its parameters) gets
//      NMT reset node and the boot starts over,
//   6. refuses the node when a TPDO it uses is synchronous (transmission type 0..240) and the
//      master produces no SYNC (MasterConfig::sync_period 0): those PDOs would never come;
//      with SYNC, a type n TPDO's freshness deadline is kMissedPeriods × n × the SYNC period,
//   7. starts heartbeat monitoring and sends NMT start (state `starting`) — once no other node
//      is being configured or waits for its boot-up (or after NetworkTiming::start_hold_max),
//      so the whole boot's configurations come first and the starts together: their SDO frames (580h/600h
//      + node-ID) win arbitration over every heartbeat (700h + node-ID), so a boot that keeps
//      the bus busy with configurations (many nodes, a slow bus) would delay the heartbeats of
//      the nodes already started past their consumer time, and each node lost would be booted
//      again: a cascade. Held, the node stays `configuring` (its reason says so),
//   8. waits for proof of life: the first heartbeat reporting operational after the NMT start
//      (with heartbeat_ms 0: the first PDO), within the consumer time counted from the NMT
//      start; only then is the node operational and its driver told it is online. CiA 301's
//      consumer starts watching at the first heartbeat, so a node that never sends one would
//      never time out: this deadline is the network manager's own. A heartbeat in another
//      state meanwhile does not count against the node: it may have been sent before the node
//      received the start (the frames crossed on the bus).
// Then it watches: a heartbeat timeout, a node leaving operational, or no proof of life in
// time marks its inputs offline and starts the boot again; a boot-up seen at any time (the
// device rebooted) reconfigures and restarts it; a missing node is retried with back-off (1 s
// doubling to 30 s). Inputs whose PDOs are overdue become Stale (Driver::advance); an object
// whose read-back is a fault's only clear evidence is read while the fault lasts
// (Driver::fault_poll). A node
// marked mandatory keeps fault() true until it is operational. Sans I/O: frames and time in.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "canopen/305/lss_fastscan.hpp"
#include "canopen/305/lss_master.hpp"
#include "canopen/305/lss_slowscan.hpp"
#include "canopen/master.hpp"
#include "subdevices/driver.hpp"
#include "subdevices/node_boot.hpp"

namespace oegw::subdevices {

enum class NodeState : std::uint8_t {
  Idle,           // not started yet
  WaitingBootUp,  // reset communication sent, waiting for the boot-up
  Configuring,    // identity check, boot reads, configuration writes
  Starting,       // NMT start sent, waiting for proof of life (heartbeat in operational)
  Operational,    // started and alive, inputs flowing
  Missing,        // no answer / heartbeat lost: retried with back-off
  Refused,        // wrong identity or a configuration the node refused: retried with back-off
};
[[nodiscard]] std::string_view to_string(NodeState s);

struct NetworkCounters {
  std::uint64_t unknown_pdo = 0;     // a PDO-range frame no configured node's driver consumes
  std::uint64_t unknown_emcy = 0;    // an EMCY from a node not in the configuration
  std::uint64_t reboots_seen = 0;    // reboots of configured nodes the gateway did not cause (NodeCounters)
  std::uint64_t gateway_resets = 0;  // boot-ups answering the gateway's NMT resets (NodeCounters)
};

// What the network manager counted of one configured node since the gateway started.
struct NodeCounters {
  // Frames received from it: its PDOs (the COB-IDs its driver consumes), heartbeats and
  // boot-ups (700h + node-ID), EMCYs (080h + node-ID), SDO answers (580h + node-ID).
  std::uint64_t frames = 0;
  // Its boot-ups after its first start that the gateway did not cause: a power cycle, its own
  // reset, another master's NMT reset — any boot-up while the gateway was not waiting for the
  // answer to a reset of its own. NetworkCounters sums them.
  std::uint64_t reboots_seen = 0;
  // Its boot-ups answering the gateway's own NMT reset communication / reset node (the first
  // boot, every retry of a lost or refused node): the gateway's doing, not the device's.
  std::uint64_t gateway_resets = 0;
};

struct NetworkTiming {
  Duration boot_wait = std::chrono::seconds(2);  // boot-up wait after reset communication
  // The boot-up probe (header, step 1): the first read of 1000h this long after the reset,
  // each awaited boot_probe_timeout (at most the SDO client's own time-out), the next after
  // twice the previous gap, while boot_wait runs, each when no other node is being configured
  // (NetworkManager::configuring_any()). A device that boots in time never sees one.
  // 0: no probes (boot_wait is waited out).
  Duration boot_probe_first = std::chrono::milliseconds(100);
  Duration boot_probe_timeout = std::chrono::milliseconds(100);
  // The longest a configured node's NMT start is held while other nodes are being configured
  // (header, step 7): one node that keeps rebooting does not hold the others for ever.
  Duration start_hold_max = std::chrono::seconds(2);
  Duration retry_first = std::chrono::seconds(1);  // back-off starts here ...
  Duration retry_max = std::chrono::seconds(30);   // ... doubles up to here
};

class NetworkManager {
 public:
  using Timing = NetworkTiming;

  // `master` is the downstream CANopen master (its NMT, SDO clients, heartbeat and EMCY
  // consumers); the network manager installs itself on its callbacks.
  explicit NetworkManager(canopen::Master& master, Timing timing = {});
  NetworkManager(const NetworkManager&) = delete;
  NetworkManager& operator=(const NetworkManager&) = delete;

  // Adds a node; the driver must be for settings.node. Returns false (adding nothing) for a
  // node-ID or name already present.
  bool add(NodeSettings settings, std::unique_ptr<Driver> driver);

  // Boots every node.
  void start(TimePoint now);

  // Frames: give every downstream frame here (it feeds the master first, then routes PDOs).
  bool on_frame(const CanFrame& frame, TimePoint now);
  void advance(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const;

  // CiA 305 commissioning of a device found at a default node-ID (e.g. an elobau grip at 11h):
  // switch it to LSS configuration — selectively by its LSS address (1018h values) when given,
  // else globally, so only one unconfigured device may be on the bus — configure the node-ID
  // (and the bit timing, CiA 305 table 0 index), store, switch back to waiting. The new
  // node-ID takes effect at the device's next reset communication. `done(ok, why)`.
  void commission(std::optional<canopen::lss::Address> address, NodeId new_id, std::optional<std::uint8_t> bit_timing,
                  TimePoint now, std::function<void(bool ok, const std::string& why)> done);

  // LSS for `oegw ctl`'s CiA 309-3 lss_* commands (gateway/control/ctl_service.hpp), on the same
  // LSS master. The gateway's own LSS work (commission()) comes first: while it runs, client_lss()
  // is nullptr and the command is refused; when it starts, a client's fastscan still running ends
  // (LssFastscan::Outcome::Cancelled, a slowscan likewise) and sends no further step. A single client request already
  // queued or on the wire ends first (it lasts at most the LSS time-out); commission() follows it.
  [[nodiscard]] canopen::LssMaster* client_lss() { return own_lss_ != 0 ? nullptr : &lss_; }
  [[nodiscard]] canopen::LssFastscan* client_fastscan() { return own_lss_ != 0 ? nullptr : &fastscan_; }
  [[nodiscard]] canopen::LssSlowscan* client_slowscan() { return own_lss_ != 0 ? nullptr : &slowscan_; }
  // A client's fastscan or slowscan runs: each ends with a slave selected, so only one at a time
  // (two selected slaves would take the same node-ID).
  [[nodiscard]] bool client_scan_running() const { return fastscan_.running() || slowscan_.running(); }
  // True while commission() runs.
  [[nodiscard]] bool own_lss_busy() const { return own_lss_ != 0; }

  // Why no run-time state can be taken now, or "" when it can: the state holds no request on
  // the wire (an SDO transfer's callback, an LSS exchange), so none may be under way: "grip:
  // configuring (an SDO request on the wire or held)".
  [[nodiscard]] std::string busy() const;
  // Run-time state (canopen/state.hpp): each node's boot state and its timers, what its last
  // boot read (diagnostics), the counters, the PDOs held for its proof of life, and its
  // driver's state; which node each PDO COB-ID is routed to; the counters. The Master's state
  // is its own (Master::export_state). Only when busy() is "" (else std::logic_error). The
  // import is for a manager given the same nodes by add(), in the same order, before start():
  // nothing is sent, no callback is called. Throws StateError; a manager whose import threw is
  // thrown away.
  void export_state(canopen::StateWriter& w) const;
  void import_state(const canopen::StateReader& r);

  [[nodiscard]] NodeState state(std::string_view name) const;
  [[nodiscard]] Driver* driver(std::string_view name);
  [[nodiscard]] const Driver* driver(std::string_view name) const;
  [[nodiscard]] std::vector<std::string> names() const;
  // True while any mandatory node is not operational.
  [[nodiscard]] bool fault() const;
  [[nodiscard]] const NetworkCounters& counters() const { return counters_; }
  // One node's counters (zeros for an unknown name).
  [[nodiscard]] NodeCounters node_counters(std::string_view name) const;
  // The diagnostics read at the node's last boot (empty before the first); nullptr for an
  // unknown name.
  [[nodiscard]] const NodeDiagnostics* diagnostics(std::string_view name) const;
  // Once per boot of a node, when its diagnostics have been read (before the configuration
  // writes): for the log.
  std::function<void(const std::string& name, const NodeDiagnostics&)> on_diagnostics;

  // Every state change of a node, with a human-readable reason ("1018h:01 is 00000001h, the
  // configuration expects 0000015Ah").
  std::function<void(const std::string& name, NodeState state, const std::string& why)> on_node_state;
  // Bad input, once per kind and source (CiA 301 frames the gateway ignores): "grip: 3 frames of
  // the wrong length", "unknown PDO 1A5h". For the log; the counters keep counting.
  std::function<void(const std::string& what)> on_bad_input;
  // A boot-up after a reset of the device's application: one the gateway did not ask for (a
  // power cycle, the device's own reset) or the answer to its NMT reset node. Whatever the node
  // reported before (EMCYs) is void. A boot-up answering the gateway's reset communication is
  // not reported here: that reset leaves the device's errors as they were.
  std::function<void(const std::string& name)> on_application_reset;
  // The next (re)boot of the node sends NMT reset node instead of reset communication: the
  // gateway holds an error the device reported and wants it reset, or reported again.
  void reset_application_next(std::string_view name);
  // EMCYs of configured nodes, decoded by their driver.
  std::function<void(const std::string& name, const EmcyMessage&, const DecodedEmcy&)> on_emcy;
  // A driver's fault poll (Driver::fault_poll) answered with evidence it took (`what`, e.g.
  // "1001h read 00h: no device error, the cable break is over"): its faults may have ended.
  std::function<void(const std::string& name, const std::string& what)> on_fault_evidence;

 private:
  struct Managed {
    NodeSettings settings;
    std::unique_ptr<Driver> driver;
    NodeState state = NodeState::Idle;
    std::uint64_t generation = 0;       // bumps on every (re)boot: stale SDO callbacks are ignored
    std::optional<TimePoint> deadline;  // boot-up wait end, or the next retry
    Duration backoff{0};
    bool started_once = false;
    bool reset_node_next = false;  // reset_application_next(): begin_boot() sends reset node
    bool reset_node_sent = false;  // the boot-up awaited answers a reset node
    // The boot-up answering the gateway's last reset is still owed: set by begin_boot(),
    // cleared by a boot-up and by proof of life. A node that answered the boot-up probe (or
    // the read after boot_wait) is configured while it is owed: the device may have queued
    // its boot-up behind its SDO answer, which wins arbitration with its lower CAN-ID. Such a
    // boot-up is counted as the reset's answer — and the configuration still starts over, since
    // a reboot during it would look no different on the bus.
    bool boot_up_owed = false;
    std::optional<TimePoint> probe_at;                 // WaitingBootUp: the next boot-up probe
    Duration probe_gap{0};                             // ... and the gap after it
    std::optional<TimePoint> held_since;               // Configuring: configured, its NMT start held (step 7)
    NodeBoot boot;                                     // steps 3 to 5 of the header
    InputCounters reported;                            // what on_bad_input has already said
    std::vector<std::pair<CanFrame, TimePoint>> held;  // Starting: last PDO per COB-ID, for go_live
    NodeCounters counted;
    // Operational: the next read of the driver's fault poll (Driver::fault_poll), and whether
    // one is on the wire.
    std::optional<TimePoint> poll_at;
    bool poll_pending = false;
    // Its last heartbeat (any state), for the heartbeat guard (late_heartbeat()).
    std::optional<TimePoint> last_heartbeat;
    // Configuring: its next step waits for a late heartbeat of another node (late_heartbeat()).
    bool step_held = false;
  };

  Managed* find(NodeId node);
  const Managed* find(NodeId node) const;
  const Managed* find(std::string_view name) const;
  void set_state(Managed& m, NodeState s, const std::string& why, TimePoint now);
  void begin_boot(Managed& m, TimePoint now);  // reset communication, wait for boot-up
  void probe(Managed& m);                      // WaitingBootUp: read 1000h (header, step 1)
  // A node is being configured. The boot-up probe waits meanwhile: the configuration's SDO
  // frames (600h/580h + node-ID) win arbitration over every boot-up (700h + node-ID), so on a
  // busy bus a boot-up is late, not lost, and a probe answered before it would cost the node a
  // second configuration (Managed::boot_up_owed).
  [[nodiscard]] bool configuring_any() const;
  // configuring_any(), or a node waits for its boot-up (its configuration is next) and has
  // left no boot-up probe unanswered (else it is likely absent): a configured node's NMT start
  // is held meanwhile (header, step 7).
  [[nodiscard]] bool booting_any() const;
  // The nodes the two count: configuring (not held), and waiting for a boot-up that may come
  // (with probes_on()).
  [[nodiscard]] static bool is_configuring(const Managed& m) {
    return m.state == NodeState::Configuring && !m.held_since;
  }
  [[nodiscard]] bool awaiting_boot_up(const Managed& m) const {
    return m.state == NodeState::WaitingBootUp && m.probe_gap <= timing_.boot_probe_first;
  }
  [[nodiscard]] bool probes_on() const {
    return timing_.boot_probe_first.count() > 0 && timing_.boot_probe_first < timing_.boot_wait;
  }
  // Identity, boot reads, writes, start; `why` is the Configuring state's reason.
  void configure(Managed& m, TimePoint now, const std::string& why = "boot-up seen: checking identity and configuring");
  [[nodiscard]] std::string sync_refusal(const Managed& m) const;  // step 6; empty when fine
  // A PDO COB-ID the node's driver consumes that another node's already does; empty when none.
  [[nodiscard]] std::string cob_refusal(const Managed& m) const;
  void run_step(Managed& m);
  void route(Managed& m);
  void count_frame(const CanFrame& frame);  // NodeCounters::frames of its sender
  void report_bad_input(Managed& m);
  void report_once(std::uint64_t& seen, std::uint64_t now_count, const std::string& name,
                   const char* what);          // (re)builds the COB-ID routing of a node's TPDOs
  void finish(Managed& m, TimePoint now);      // configured: start, or hold the start
  void start_node(Managed& m, TimePoint now);  // NMT start: Starting
  void go_live(Managed& m, const std::string& evidence, TimePoint now);  // proof of life seen
  [[nodiscard]] Duration proof_deadline(const Managed& m) const;
  void fail(Managed& m, NodeState s, const std::string& why, TimePoint now);
  void poll_faults(Managed& m, TimePoint now);  // Operational: the driver's fault poll when due
  // The heartbeat guard (header, step 5): an operational node whose heartbeat is later than its
  // period plus a third of its consumer margin (consumer time − period) holds every
  // configuration's next SDO request until that heartbeat arrives or the node's consumer time has
  // run out. Returns when the hold ends at the latest (the earliest such consumer deadline), or
  // nullopt when no heartbeat is late. The configurations' SDO frames (580h/600h + node) win
  // arbitration over every heartbeat, and the periodic PDOs take what the pacing leaves: a long
  // configuration (a sub-device rebooted while the rest of a loaded cab runs) would otherwise
  // keep the lowest-priority heartbeat off the bus past its consumer time.
  [[nodiscard]] std::optional<TimePoint> late_heartbeat() const;
  void release_held_steps();  // the guard let go: the held configurations go on
  void lost(Managed& m, const std::string& why, TimePoint now);
  [[nodiscard]] std::uint16_t consumer_ms(const Managed& m) const;

  canopen::Master& master_;
  Timing timing_;
  canopen::LssMaster lss_;
  canopen::LssFastscan fastscan_{lss_};  // `_lss_fastscan` of oegw ctl
  canopen::LssSlowscan slowscan_{lss_};  // `_lss_slowscan` of oegw ctl
  unsigned own_lss_ = 0;                 // commission() operations running
  std::vector<std::unique_ptr<Managed>> nodes_;
  std::map<std::uint32_t, Managed*> by_cob_;  // consumed TPDO COB-ID -> node
  NetworkCounters counters_;
  TimePoint now_{};
};

}  // namespace oegw::subdevices
