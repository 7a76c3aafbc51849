// A CANopen manager (CiA 301 NMT master side): NMT commands, one SDO client per server node
// (each with its own request queue), heartbeat consumer, EMCY consumer and, when a SYNC period
// is configured, the network's SYNC producer (CiA 301 §7.2.5: 1005h bit 30 set, 1006h the
// period, no counter; the first SYNC one period after the first advance()). Sans I/O like every
// service here. Used by the gateway's downstream network manager and by built-in test hosts.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "canopen/301/emcy.hpp"
#include "canopen/301/heartbeat.hpp"
#include "canopen/301/nmt_master.hpp"
#include "canopen/301/object_dictionary.hpp"
#include "canopen/301/sdo_client.hpp"
#include "canopen/301/sync.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

struct MasterConfig {
  std::uint8_t heartbeat_entries = 16;  // 1016h size in the master's own dictionary
  Duration sdo_timeout = std::chrono::seconds(1);
  // SYNC produced on 080h every this often (1006h, whole µs); 0: the master produces no SYNC.
  Duration sync_period{0};
  // The least time between the starts of two SDO requests of this master's clients, whichever
  // nodes they go to (canopen/301/sdo_pacer.hpp: SdoPacer::gap_for); 0: not paced.
  Duration sdo_request_gap{0};
};

class Master {
 public:
  // `od` is the master's own dictionary (1016h and 1028h are added to it).
  Master(ObjectDictionary& od, FrameSink sink, MasterConfig config = {});
  Master(const Master&) = delete;
  Master& operator=(const Master&) = delete;

  [[nodiscard]] NmtMaster& nmt() { return nmt_; }
  // The master's way out onto the bus, for services layered on it (LSS master).
  [[nodiscard]] const FrameSink& sink() const { return sink_; }
  // The SDO client toward `server` (created on first use, default COB-IDs of CiA 301 §7.3.5).
  [[nodiscard]] SdoClient& sdo(NodeId server);
  // The pacer every client of sdo() shares (MasterConfig::sdo_request_gap).
  [[nodiscard]] const SdoPacer& sdo_pacer() const { return sdo_pacer_; }

  // Watches `node`'s heartbeat with the given consumer time (writes a 1016h entry). Returns the
  // SDO abort code of that write (e.g. 0x06040043 if the node is already watched differently).
  SdoAbortCode monitor_heartbeat(NodeId node, std::uint16_t ms);

  // The SYNC period the master produces (MasterConfig::sync_period; 0: none).
  [[nodiscard]] Duration sync_period() const { return cfg_.sync_period; }

  // The first server whose SDO client has a transfer under way or queued; nullopt when all idle.
  [[nodiscard]] std::optional<NodeId> busy_sdo_server() const;
  // Run-time state (canopen/state.hpp): the master's dictionary values (the 1016h entries it
  // watches), the heartbeat consumer, the pacer, the SYNC producer and each SDO client (by its
  // server's node-ID; the import creates them). Only with every client idle: a transfer under
  // way throws std::logic_error (busy_sdo_server()). For a Master of the same configuration on
  // a fresh dictionary; no callback is called. Throws StateError; a Master whose import threw
  // is thrown away.
  void export_state(StateWriter& w) const;
  void import_state(const StateReader& r);

  std::function<void(NodeId)> on_heartbeat_timeout;
  // A boot-up message from any node (watched or not).
  std::function<void(NodeId)> on_boot;
  std::function<void(NodeId, NmtState)> on_state;
  // Every heartbeat of a watched node (HeartbeatConsumer::on_heartbeat), after on_state.
  std::function<void(NodeId, NmtState)> on_heartbeat;
  std::function<void(const EmcyMessage&, TimePoint)> on_emcy;
  // Every frame no service claimed (PDOs, foreign traffic).
  std::function<void(const CanFrame&, TimePoint)> on_other_frame;

  bool on_frame(const CanFrame& frame, TimePoint now);
  void advance(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const;

 private:
  ObjectDictionary& od_;
  FrameSink sink_;
  MasterConfig cfg_;
  NmtMaster nmt_;
  HeartbeatConsumer hb_;
  EmcyConsumer emcy_;
  std::map<std::uint8_t, std::unique_ptr<SdoClient>> sdo_;
  // sdo_'s clients in its order (by node-ID), contiguous: on_frame() walks them for an SDO
  // answer, advance() in this order (the order their queued requests start in).
  std::vector<SdoClient*> clients_;
  // Those of them that may have work: next_deadline(), called after every frame, asks only
  // these; advance() drops the idle ones.
  SdoWorkList working_;
  // The standard COB-IDs a client answers on, so that a frame none answers on (a PDO, most of
  // the bus) skips the walk over clients_. Rebuilt when a client was added or changed its
  // COB-IDs since (SdoClient counts cob_changes_ up); an extended response COB-ID sends every
  // extended frame through the walk.
  [[nodiscard]] bool some_client_answers_on(const CanFrame& frame);
  static constexpr std::uint32_t kStandardIds = 0x800;  // 11-bit identifiers
  std::vector<bool> answer_ids_ = std::vector<bool>(kStandardIds);
  bool answer_extended_ = false;
  std::uint64_t cob_changes_ = 0;
  std::uint64_t answer_ids_built_ = ~std::uint64_t{0};  // cob_changes_ when built
  SdoPacer sdo_pacer_;
  std::unique_ptr<SyncService> sync_;  // only with a SYNC period
};

}  // namespace oegw::canopen
