// `oegw scan` through the running gateway: the control socket's `scan` command
// runs the bus scan (subdevices/bus_scan.hpp) on the downstream bus beside the gateway, so a cab
// in service can be scanned without stopping it (a node added, a node-ID forgotten).
//
//  * What it may touch: node-IDs that are no sub-device of the mapping file are probed by SDO as
//    `oegw scan -i IF` probes them; the sub-devices' node-IDs are not (their SDO channels are the
//    gateway's own clients', CiA 301 §7.2.4.1) — they are reported from what the gateway read at
//    their boot (1000h, 1018h, NodeDiagnostics), the heartbeat it asks of them, the state it holds
//    them in, and their mapping-file name, which the draft keeps. LSS runs on the network
//    manager's master (NetworkManager::client_lss), the one `oegw ctl` uses: the gateway's own
//    commissioning comes first (then LSS is skipped, and said so), and a fastscan it interrupts
//    ends without an address.
//  * Requests (docs/reference/control-protocol.md#scan): {"command": "scan", "action": "start",
//    settings...} answers {"scan": {"id": N}} at once, or refuses (CiA 309-3 error 102) while a
//    scan runs; {"command": "scan", "action": "status", "id": N} answers its progress and, once
//    done, its result with the gateway's interfaces for the draft. The last result is kept until
//    the next start; a status of another id is refused, naming the current one.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "canopen/io/event_loop.hpp"
#include "gateway/control/control_protocol.hpp"
#include "gateway/gateway.hpp"
#include "mapping/config.hpp"
#include "subdevices/bus_scan.hpp"

namespace oegw::gateway::control {

// A scan's result as the protocol carries it, and back (the client writes the draft from it).
// from: nullopt and `error` for an answer that is not one.
[[nodiscard]] nlohmann::json scan_result_json(const subdevices::ScanResult& r);
[[nodiscard]] std::optional<subdevices::ScanResult> scan_result_from_json(const nlohmann::json& j, std::string& error);

class ScanService {
 public:
  // Adds `scan` to `protocol`. `gw` and `config` outlive it. `rearm`: called after the scan
  // acted (its LSS requests on the network manager's master move the gateway's next deadline).
  ScanService(canopen::io::EventLoop& loop, Gateway& gw, const mapping::Config& config, ControlProtocol& protocol,
              std::function<void()> rearm);
  ~ScanService();  // a scan still running ends (its fastscan on the shared master is cancelled)
  ScanService(const ScanService&) = delete;
  ScanService& operator=(const ScanService&) = delete;

  // A reload (gateway/reload.hpp), while the old gateway still runs: a scan still running ends
  // (its status then says so, 102). attach(): serves the new gateway.
  void detach();
  void attach(Gateway& gw, const mapping::Config& config);

 private:
  void hook();
  nlohmann::json start(const nlohmann::json& request);
  nlohmann::json status(const nlohmann::json& request) const;
  // After the scanner acted: its result once done, the timers re-armed.
  void settle();
  [[nodiscard]] subdevices::ScanResult with_subdevices(subdevices::ScanResult r) const;

  canopen::io::EventLoop& loop_;
  Gateway* gw_;
  const mapping::Config* config_;
  std::function<void()> rearm_;
  std::unique_ptr<subdevices::BusScanner> scanner_;
  std::unique_ptr<canopen::io::ServiceDriver> driver_;
  std::uint64_t id_ = 0;                  // the current (or last) scan; 0: none yet
  std::uint64_t ended_ = 0;               // a scan a reload ended (detach)
  std::optional<nlohmann::json> result_;  // the last scan's, once done
};

}  // namespace oegw::gateway::control
