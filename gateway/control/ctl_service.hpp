// The control socket's commands for `oegw ctl`
// (docs/reference/control-protocol.md#oegw-ctls-commands): SDO reads and writes, NMT, the gateway's
// identity and the event lines, on the running Gateway. The CiA 309-3 text is the client's
// (canopen/309/ascii_gateway.hpp); here are its effects.
//
//  * Networks are the mapping file's: upstream.network_id names the gateway's own dictionary
//    (only the gateway's node-ID is reached there), downstream.network_id the sub-devices.
//  * Downstream SDO goes through the Gateway's RemoteSdo, the same object and the same policy as
//    the host's remote SDO (gateway/remote_sdo.hpp): the gateway's own boot and configuration come
//    first (0800 0022h), a write that would break the FE translation is refused (0800 0021h), a
//    missing node 0606 0000h, a node no sub-device 0609 0011h, the sub-device's own aborts passed
//    on. There is no second policy here.
//  * Upstream SDO reads and writes the gateway's own dictionary as its SDO server does
//    (ObjectDictionary::read/write with Origin::Sdo: existence, access, length, limits, hooks).
//  * A request's `timeout_ms` (`set sdo_timeout`) ends a transfer still running after that long
//    with 0504 0000h (the downstream SDO client's own time-out, downstream.sdo_timeout_ms,
//    ends it earlier when shorter).
//  * LSS (CiA 305, `lss`): the downstream network manager's LSS master (NetworkManager::
//    client_lss), the same one its own commissioning uses; that comes first: while it runs, an
//    `lss` request is refused (102), and a client's fastscan it interrupts is answered 102. One
//    fastscan at a time; `set_node` refuses the node-ID of a configured sub-device on the bus.
//  * Events: every boot-up and EMCY on the downstream bus, numbered; a client asks for those
//    after the last number it saw (`events`). The last kMaxEvents are kept.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

#include "canopen/io/event_loop.hpp"
#include "gateway/control/control_protocol.hpp"
#include "gateway/gateway.hpp"
#include "mapping/config.hpp"

namespace oegw::gateway::control {

class CtlService {
 public:
  static constexpr std::size_t kMaxEvents = 256;
  static constexpr std::uint32_t kMaxTimeoutMs = 65535;

  // Adds sdo_read, sdo_write, nmt, info and events to `protocol`. `rearm`: called after a
  // command has acted on the gateway (its next deadline may have changed).
  CtlService(canopen::io::EventLoop& loop, Gateway& gw, const mapping::Config& config, ControlProtocol& protocol,
             std::function<void()> rearm);
  ~CtlService();  // cancels the transfers still running
  CtlService(const CtlService&) = delete;
  CtlService& operator=(const CtlService&) = delete;

  // A reload (gateway/reload.hpp), while the old gateway still runs: a client's SDO transfer in
  // flight is answered 0800 0022h (as RemoteSdo answers a transfer the gateway takes back), its
  // fastscan or slowscan ends (102); an LSS request in flight goes with the old network manager
  // unanswered (the client's time-out ends it). attach(): serves the new gateway; the events
  // and their numbering go on.
  void detach();
  void attach(Gateway& gw, const mapping::Config& config);

 private:
  struct Transfer;
  void sdo(const nlohmann::json& request, bool write, ControlProtocol::Done done);
  nlohmann::json nmt(const nlohmann::json& request);
  void lss(const nlohmann::json& request, ControlProtocol::Done done);
  // A handler per LSS sub-command (CiA 309-3 lss_*, CiA 305 services): true when it asked the
  // LSS master, false when it answered at once.
  struct LssCall;
  bool lss_switch_global(const LssCall& call);
  bool lss_switch_selective(const LssCall& call);
  bool lss_set_node(const LssCall& call);
  bool lss_conf_bitrate(const LssCall& call);
  bool lss_activate_bitrate(const LssCall& call);
  bool lss_store(const LssCall& call);
  bool lss_inquire_node(const LssCall& call);
  bool lss_inquire_address(const LssCall& call);
  bool lss_identify_non_configured(const LssCall& call);
  bool lss_fastscan(const LssCall& call);
  bool lss_identify_remote(const LssCall& call);
  bool lss_slowscan(const LssCall& call);
  nlohmann::json info() const;
  nlohmann::json events(const nlohmann::json& request) const;
  void record(nlohmann::json event);
  // The gateway's event hooks (boot-ups, EMCYs), and their end: transfers cancelled, answered
  // with `answer_transfers` when given.
  void hook();
  void unhook(const char* why, std::optional<canopen::SdoAbortCode> answer_transfers);

  canopen::io::EventLoop& loop_;
  Gateway* gw_;
  const mapping::Config* config_;
  std::function<void()> rearm_;
  std::vector<std::shared_ptr<Transfer>> transfers_;
  // Cleared by the destructor: LSS answers that come later are dropped.
  std::shared_ptr<bool> alive_ = std::make_shared<bool>(true);
  // The answers of the LSS requests in flight (emptied once given): a reload answers those the
  // old gateway's LSS master never will (it goes with the gateway), 102.
  std::vector<std::shared_ptr<ControlProtocol::Done>> lss_pending_;
  bool fastscan_client_ = false;  // the network manager's fastscan runs for this service
  bool slowscan_client_ = false;  // its slowscan likewise
  std::deque<nlohmann::json> events_;
  std::uint64_t next_event_ = 1;
};

}  // namespace oegw::gateway::control
