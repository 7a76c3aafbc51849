// The downstream bus scan of `oegw scan`, sans I/O like every service of the
// protocol core: frames and time in, frames out (docs/design/protocol-core.md), so that a test
// drives it on a simulated clock and `oegw scan` on a SocketCAN interface.
//
// What it does, from start():
//  * listens the whole time for boot-ups and heartbeats (700h + node-ID, CiA 301 §7.2.8.3.2):
//    a node in NMT stopped answers no SDO but is still heard;
//  * reads 1000h, 1018h:01..04 and 1017h of every node-ID first..last by SDO (expedited upload,
//    CiA 301 §7.2.4.3.6), at most `parallel` node-IDs at a time, each with its own time-out. A
//    node-ID whose 1000h read times out is absent (unless it was heard); an abort or a time-out
//    of a later object (the MCB-402 has no 1018h:04) leaves that value unknown and goes on;
//  * then asks "identify non-configured remote slave" (CiA 305 §8.4.3.7) and, if a node without
//    node-ID answers, runs LSS fastscan (CiA 305 §8.4.4) to read the LSS address of one of them.
//    Fastscan cannot skip a node already found without configuring it, so one address is read
//    per scan; `ScanResult::unconfigured` says whether nodes without node-ID are present at all.
//    The node found is sent back to LSS waiting mode, its node-ID still unconfigured;
//  * ends when all that is done and `listen` has passed since start() (heartbeats of nodes that
//    answer no SDO come at their producer period).
// Nothing is written to any node: the scan changes nothing on the bus.
//
// Beside a running gateway (`oegw scan` through its control socket, gateway/control/
// scan_service.hpp) two things differ: the node-IDs of its sub-devices are not probed (their SDO
// channels are the gateway's own clients': CiA 301 §7.2.4.1, one client per server channel at a
// time), and the LSS master is the gateway's (SharedLss), which it feeds with the bus's frames
// and whose own commissioning comes first.
#pragma once

#include <cstddef>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "canopen/301/sdo_client.hpp"
#include "canopen/305/lss.hpp"
#include "canopen/305/lss_fastscan.hpp"
#include "canopen/305/lss_master.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"
#include "subdevices/family_identity.hpp"

namespace oegw::subdevices {

using canopen::CanFrame;
using canopen::Duration;
using canopen::FrameSink;
using canopen::NodeId;
using canopen::TimePoint;

struct ScanConfig {
  Duration sdo_timeout = std::chrono::milliseconds(100);  // per SDO read
  std::size_t parallel = 8;  // node-IDs probed at once (1..127); a real interface's TX queue is short
  Duration listen = std::chrono::milliseconds(1000);     // the scan lasts at least this long
  bool lss = true;                                       // identify non-configured + fastscan
  Duration lss_timeout = std::chrono::milliseconds(25);  // per LSS step (fastscan has up to 132)
  std::uint8_t first = 1;                                // node-IDs probed: first..last (1..127)
  std::uint8_t last = 127;
  // Node-IDs not probed by SDO (a running gateway's sub-devices, see above); still heard.
  std::set<std::uint8_t> skip;
};

// Another owner's LSS master and fastscan, which that owner feeds with the frames and advances
// (the running gateway's network manager). Both null: LSS is not possible now (`why_not`).
struct SharedLss {
  canopen::LssMaster* master = nullptr;
  canopen::LssFastscan* fastscan = nullptr;
  std::string why_not;  // set: LSS is not possible now (e.g. another client's scan runs)
};

struct ScannedNode {
  NodeId node;
  bool answered_sdo = false;               // at least one SDO answer (data or abort)
  bool heard = false;                      // a boot-up or heartbeat seen
  bool booted = false;                     // a boot-up seen during the scan
  std::optional<canopen::NmtState> state;  // the last heartbeat's state
  NodeIdentity identity;
  std::optional<std::uint16_t> producer_heartbeat_ms;  // 1017h as read
  std::optional<Duration> heartbeat_period;            // the shortest gap between two heartbeats heard
  FamilyMatch family;
  // Through a running gateway: the sub-device of the mapping file at this node-ID (its name,
  // which the draft keeps) and the state the gateway holds it in ("operational", "missing").
  std::string configured_as;
  std::string gateway_state;
};

struct ScanResult {
  std::vector<ScannedNode> nodes;  // by node-ID
  // "identify non-configured remote slave" was answered: at least one node without node-ID.
  bool unconfigured = false;
  // The LSS address fastscan read (of one of them); absent when fastscan failed or was not run.
  std::optional<canopen::lss::Address> unconfigured_address;
  std::string lss_note;  // why fastscan gave no address, for the report
};

struct ScanProgress {
  std::size_t probed = 0;  // node-IDs whose probing ended
  std::size_t total = 0;
  std::size_t found = 0;  // nodes found so far (answered or heard)
  bool lss = false;       // the LSS part has started
};

class BusScanner {
 public:
  BusScanner(FrameSink sink, ScanConfig config);
  // LSS on another owner's master (asked when the LSS part starts, see above).
  BusScanner(FrameSink sink, ScanConfig config, std::function<SharedLss()> shared_lss);
  ~BusScanner();  // cancels a fastscan of its own on a shared master
  BusScanner(const BusScanner&) = delete;
  BusScanner& operator=(const BusScanner&) = delete;

  void start(TimePoint now);
  bool on_frame(const CanFrame& frame, TimePoint now);
  void advance(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const;
  [[nodiscard]] bool done() const { return phase_ == Phase::Done; }
  // The nodes found (complete once done()).
  [[nodiscard]] ScanResult result() const;

  // How far it is (total: the node-IDs to probe, known from start()).
  [[nodiscard]] ScanProgress progress() const;
  // progress() after every node-ID probed, and when the LSS part starts.
  std::function<void(const ScanProgress&)> on_progress;
  // When the LSS part ended inside a shared master's callback (its owner's call, not this
  // scanner's): next_deadline() and done() may have changed.
  std::function<void()> on_wake;

 private:
  enum class Phase : std::uint8_t { Idle, Probing, Lss, Listening, Done };
  struct Probe {
    std::unique_ptr<canopen::SdoClient> sdo;
    std::size_t step = 0;
  };
  void launch(std::uint8_t node, TimePoint now);
  void read_next(std::uint8_t node);
  void probe_ended(std::uint8_t node);
  void after_probing(TimePoint now);
  void lss_ended(TimePoint now);
  void report();
  ScannedNode& node(std::uint8_t id);

  FrameSink sink_;
  ScanConfig cfg_;
  Phase phase_ = Phase::Idle;
  TimePoint start_{}, now_{};
  std::deque<std::uint8_t> pending_;
  std::map<std::uint8_t, Probe> active_;
  std::map<std::uint8_t, ScannedNode> nodes_;
  std::map<std::uint8_t, TimePoint> last_heartbeat_;
  std::size_t probed_ = 0, total_ = 0;
  bool lss_began_ = false;  // the LSS part started (it stays so in progress())
  bool ended_ = false;      // a probe ended inside a callback: refill after it returns
  canopen::LssMaster own_lss_;
  canopen::LssFastscan own_fastscan_{own_lss_};
  std::function<SharedLss()> shared_lss_;
  canopen::LssMaster* lss_ = &own_lss_;  // the shared master's once the LSS part runs on it
  canopen::LssFastscan* fastscan_ = &own_fastscan_;
  bool lss_shared_ = false;
  bool fastscan_mine_ = false;  // a fastscan of this scan runs on the shared master
  // A shared master may answer after this scanner is gone: its callbacks check this first.
  std::shared_ptr<bool> alive_ = std::make_shared<bool>(true);
  ScanResult lss_result_;
};

}  // namespace oegw::subdevices
