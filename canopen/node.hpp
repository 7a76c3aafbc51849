// A CANopen slave device (CiA 301 + CiA 305 LSS slave) assembled from the services in 301/ and
// 305/: NMT slave, heartbeat producer/consumer, SDO server, EMCY producer, SYNC, PDOs, LSS slave
// and the parameter store. The application builds its object dictionary (its own objects and
// its PDOs with install_rpdo/install_tpdo) and hands it to a Node, which adds the communication
// objects and routes frames. Still sans I/O: frames and time come in, frames go to the sink.
//
// What the Node wires (CiA 301 §7.3.2, CiA 305 §4):
//  * NMT state gates the services: SDO and EMCY in pre-operational and operational, PDOs only in
//    operational, heartbeat and NMT/LSS in every state.
//  * Reset communication restores 1000h–1FFFh to defaults, then re-applies the stored values;
//    reset node does the same for the whole dictionary. Reset node also restarts the EMCY
//    producer (no active error, 1001h 0, nothing sent: EmcyProducer::restart); what still holds
//    is raised again once pre-operational: EMCY 6000h for a store the reset refused again, 8120h
//    while the controller is error passive. Reset communication keeps the active errors. A node-ID configured by LSS
//    becomes active here: every COB-ID default of the form "function code + node-ID" follows it.
//  * LSS "store configuration" persists node-ID and bit timing beside the parameter file
//    (canopen/305/lss_store.hpp); at power-on both are applied (bit_timing_index() is then the
//    stored one; the program sets the interface to it before the node starts).
//  * LSS "configure bit timing" takes the table-0 indexes of NodeConfig::supported_bit_timings
//    only (error 1 otherwise). "Activate bit timing" with switch delay d (CiA 305): from the
//    command on the node sends nothing (every service, heartbeat, LSS) until 2·d have passed;
//    at d it switches (bit_timing_index() becomes the pending index, on_bit_timing_switch is
//    called for the transport), between d and 2·d the other nodes switch. Frames produced while
//    silent are dropped; the heartbeat producer keeps its timing. Received frames are served.
//  * Additional SDO server channels 1201h..127Fh (NodeConfig::sdo_servers, CiA 301 §7.2.4,
//    §7.5.2.33): one SdoServer each on the COB-IDs of its sub 1/2, under the same NMT gating,
//    timers and resets as the default channel 1200h. A channel serves only while both COB-IDs
//    are valid (bit 31 = 0); with one of them not valid it is disabled as a whole (a request
//    without a way to answer would change the dictionary unconfirmed). Writes of sub 1/2 (SDO;
//    the application's own Local writes are not checked):
//      - bits 0..29 may change only while bit 31 is set (0609 0030h otherwise), as for PDOs;
//      - an 11-bit COB-ID with bits 11..28 set (valid or not: CobId::well_formed), a valid one on
//        a restricted CAN-ID (cob::restricted) or one the device already uses is refused with
//        0609 0030h. "In use": 1005h SYNC, 1012h TIME (when consumed or produced), and the
//        valid entries of 1014h EMCY, 1028h EMCY consumer, 1200h..12FFh sub 1/2, 1400h..15FFh
//        sub 1 and 1800h..19FFh sub 1;
//      - a change takes effect at once and drops a transfer in progress on that channel; a write
//        that arrives through that very channel takes effect after its confirmation was sent (so
//        disabling a channel through itself is confirmed on it).
//    The defaults in NodeConfig are not checked (the owner validates them, e.g. the mapping
//    file). Sub 3 "node-ID of the SDO client" (0..127, 0 = not given) is stored, not used.
//  * LSS node-ID FFh (CiA 305 §4, "unconfigured"): a reset with pending node-ID FFh leaves the
//    node in NMT initialisation, silent but for LSS, and the LSS slave's active node-ID becomes
//    FFh, so it answers "identify non-configured remote slave". NMT commands are ignored there
//    (NmtSlave). Configuring a valid node-ID and switching LSS back to waiting starts NMT: the
//    reset communication moves the COB-ID defaults from the last valid node-ID to the new one
//    and boots with it.
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "canopen/301/emcy.hpp"
#include "canopen/301/heartbeat.hpp"
#include "canopen/301/nmt_slave.hpp"
#include "canopen/301/object_dictionary.hpp"
#include "canopen/301/pdo.hpp"
#include "canopen/301/sdo_server.hpp"
#include "canopen/301/storage.hpp"
#include "canopen/301/sync.hpp"
#include "canopen/305/lss_slave.hpp"
#include "canopen/bus_event.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

// One additional SDO server channel, 1200h + k (CiA 301 §7.5.2.33): the defaults of its
// COB-IDs, bit 31 set = not valid. Both not valid (the default): disabled until the host
// writes them.
struct SdoServerChannel {
  std::uint32_t request = CobId::kInvalidBit;   // sub 1 "COB-ID client to server"
  std::uint32_t response = CobId::kInvalidBit;  // sub 2 "COB-ID server to client"
};

struct NodeConfig {
  NodeId node_id{0x20};
  std::uint32_t device_type = 0;           // 1000h
  std::string device_name = "oegw";        // 1008h
  std::string hardware_version = "1";      // 1009h
  std::string software_version = "0.1.0";  // 100Ah
  lss::Address identity{};                 // 1018h:01..04, and the LSS address
  std::uint16_t heartbeat_ms = 0;          // 1017h default
  std::uint8_t heartbeat_consumers = 0;    // 1016h entries (0: no 1016h)
  std::uint8_t bit_timing_index = 3;       // CiA 305 table 0: 3 = 250 kbit/s
  // Bit i set = table-0 index i is a rate this device runs at (LSS configure bit timing).
  lss::BitTimings supported_bit_timings = lss::kAllStandardBitTimings;
  std::filesystem::path store_path;  // empty: no 1010h/1011h, LSS store unsupported
  EmcyConfig emcy{};
  SyncConfig sync{};
  Duration sdo_timeout = std::chrono::seconds(1);
  // 1201h, 1202h, ... in this order; at most 127 (1201h..127Fh), more throws std::invalid_argument.
  std::vector<SdoServerChannel> sdo_servers;
};

class Node {
 public:
  // `od` holds the application's objects and PDOs; the Node adds the communication objects.
  Node(ObjectDictionary& od, NodeConfig config, FrameSink sink);
  Node(const Node&) = delete;
  Node& operator=(const Node&) = delete;

  // Power-on: applies the stored parameters (and an LSS-stored node-ID), sends the boot-up
  // message and enters pre-operational. Returns the store's load result so that a refused
  // (corrupt) file can be reported by the owner; the node then runs on defaults and holds EMCY
  // 6000h "generic software error" (CiA 852 Table 37) active until a reset loads an intact
  // store file again (e.g. after the host saved with 1010h) or the file is gone.
  ParameterStore::LoadResult start(TimePoint now);

  bool on_frame(const CanFrame& frame, TimePoint now);
  void advance(TimePoint now);
  // What the CAN controller reports (SocketCAN error frames). CiA 301 Table 26: error passive
  // raises EMCY 8120h (cleared when error-active again), leaving bus-off sends 8140h, a
  // controller overrun 8110h; bus-off and a heartbeat-consumer timeout are communication errors
  // handled as 1029h:01 says (0 = pre-operational, 1 = no change, 2 = stopped).
  void on_bus_event(BusEvent event, TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const;

  [[nodiscard]] NmtState state() const { return nmt_.state(); }
  [[nodiscard]] NodeId node_id() const { return nmt_.node_id(); }
  [[nodiscard]] ObjectDictionary& od() { return od_; }
  [[nodiscard]] EmcyProducer& emcy() { return emcy_; }
  [[nodiscard]] PdoService& pdo() { return pdo_; }
  [[nodiscard]] HeartbeatConsumer& heartbeat_consumer() { return hb_consumer_; }
  [[nodiscard]] NmtSlave& nmt() { return nmt_; }
  [[nodiscard]] LssSlave& lss() { return lss_; }
  [[nodiscard]] SyncService& sync() { return sync_; }
  [[nodiscard]] std::uint8_t bit_timing_index() const { return bit_timing_; }
  // The SDO server channels: 1 (the default 1200h) + NodeConfig::sdo_servers.size().
  [[nodiscard]] std::size_t sdo_server_count() const { return 1 + extra_sdo_.size(); }
  // Channel 0 = 1200h (the default server), k = 1200h + k; out of range throws std::out_of_range.
  [[nodiscard]] SdoServer& sdo_server(std::size_t channel);
  [[nodiscard]] const SdoServer& sdo_server(std::size_t channel) const {
    return const_cast<Node*>(this)->sdo_server(channel);
  }

  // Called on every NMT state change, after the Node has applied it.
  std::function<void(NmtState)> on_state_change;
  // The heartbeat consumer timed out (after EMCY 8130h was raised), on whichever path noticed it.
  std::function<void(NodeId)> on_heartbeat_timeout;
  // The parameter store read again at an NMT reset (reset node: all of it; reset communication:
  // 1000h-1FFFh), with its result; a refused one is EMCY 6000h once pre-operational. The
  // power-on's is start()'s return.
  std::function<void(const ParameterStore::LoadResult&, bool communication_only)> on_store_reload;
  // LSS activate bit timing, at the switch (after the first switch delay): the transport must
  // now switch to the bit rate of table-0 index `table_index`.
  std::function<void(std::uint8_t table_index)> on_bit_timing_switch;
  // True from an LSS activate bit timing until twice its switch delay have passed.
  [[nodiscard]] bool bit_timing_silent() const { return bt_resume_at_.has_value(); }

  // Run-time state (canopen/state.hpp): the dictionary's values, each service's state (the SDO
  // servers' only when idle: a transfer under way throws std::logic_error), the node-ID the
  // COB-ID defaults follow, the bit timing and a switch under way, the controller's last word
  // and a store result not yet raised. import_state() is for a Node built on a fresh dictionary
  // of the same application objects and configuration, in place of start(): nothing is sent,
  // no callback is called, the parameter store is not read. It moves the COB-ID defaults to the
  // state's node-ID (as an LSS-configured reset does) before the values, then reloads the
  // services from the dictionary before their own state. Throws StateError; a Node whose import
  // threw is thrown away.
  void export_state(StateWriter& w) const;
  void import_state(const StateReader& r);

 private:
  void install_communication_objects();
  void handle_reset(bool communication_only, TimePoint now);
  void handle_state(NmtState s);
  void rebase_node_id(NodeId from, NodeId to);
  void load_lss_file();
  std::uint8_t store_lss(NodeId id, std::uint8_t bit_timing);
  void begin_bit_timing_switch(std::uint8_t index, Duration delay);
  void advance_bit_timing(TimePoint now);
  // Every frame of the node goes out here (silent during an LSS bit-timing switch); send() adds
  // the NMT-state gate.
  void emit(const CanFrame& frame);
  void send(const CanFrame& frame);
  void apply_store_result(bool refused);
  void communication_error(TimePoint now);
  void install_sdo_channel_objects();
  void install_sdo_channels();
  [[nodiscard]] SdoAbortCode check_sdo_channel_write(std::uint16_t index, std::uint8_t sub,
                                                     std::span<const std::uint8_t> bytes) const;
  [[nodiscard]] bool cob_in_use(CobId cob, std::uint16_t except_index, std::uint8_t except_sub) const;
  // Gives channel k (1-based) the COB-IDs its entries hold now; a change drops its transfer.
  void apply_sdo_channel(std::size_t k);
  void reload_sdo_channels();

  ObjectDictionary& od_;
  NodeConfig cfg_;
  FrameSink sink_;
  NmtState gate_ = NmtState::Initialisation;  // what the sink lets through, see send()
  TimePoint now_{};
  std::uint8_t bit_timing_;
  // LSS activate bit timing in progress: the switch, then the end of the silence.
  std::optional<TimePoint> bt_switch_at_;
  std::optional<TimePoint> bt_resume_at_;
  std::uint8_t bt_next_ = 0;
  bool bus_off_ = false;
  bool error_passive_ = false;  // the controller's last word: error passive (8120h), not yet active again
  // The node-ID the "function code + node-ID" COB-ID defaults are built on: the last valid
  // active node-ID (the node-ID itself may be FFh, unconfigured, meanwhile).
  NodeId cob_base_;
  std::optional<bool> store_refused_;  // a reset's load result, applied once pre-operational

  // Construction order matters: the services read the objects installed before them.
  bool installed_;
  std::unique_ptr<ParameterStore> store_;
  NmtSlave nmt_;
  HeartbeatProducer hb_producer_;
  HeartbeatConsumer hb_consumer_;
  EmcyProducer emcy_;
  SyncService sync_;
  PdoService pdo_;
  SdoServer sdo_;
  LssSlave lss_;
  std::vector<std::unique_ptr<SdoServer>> extra_sdo_;  // channel k at [k - 1]
  bool dispatching_ = false;                           // inside on_frame: channel changes wait
  std::vector<bool> pending_;                          // channel k changed while dispatching
  Subscriptions subs_;  // declared last: unregisters the OD callbacks first on destruction
};

}  // namespace oegw::canopen
