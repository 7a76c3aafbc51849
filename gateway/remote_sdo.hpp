// Remote SDO through the gateway (CiA 302-7 multi-level networking, recommended by CiA 852 §5.2,
// §8.4, §8.7): the SdoRemote behind every SDO server channel of the upstream device. A host names
// a sub-device with an SDO network indication (canopen/301/sdo_remote.hpp) or uses a channel the
// mapping file binds to one (`upstream.sdo_servers`); each of its transfers is then carried out by
// the gateway's downstream SDO client of that node (the one the network manager boots it with, so
// the two never talk to the node at once) and the answer carried back.
//
// Decisions (docs/guides/remote-sdo.md has the table for users):
//  * Networks: the upstream network ID names the gateway's own bus — only the gateway itself is
//    reached there (its node-ID, or network 0 / node 0: the own dictionary); the downstream
//    network ID names the sub-devices. Abort codes of a refused network indication: an unknown
//    network 0602 0000h (the address names nothing, as "object does not exist"); a node-ID that
//    is no configured sub-device of that network 0609 0011h (as "sub-index does not exist").
//  * Each transfer: a node the network manager holds as missing (heartbeat lost, never
//    answered) 0606 0000h ("access failed due to a hardware error": it is not on the bus); a
//    node not started yet, or being booted or configured by the gateway, 0800 0022h ("present
//    device state": the gateway's own boot and configuration come first and are never delayed
//    by a remote transfer — one in flight when the gateway takes the node back ends with this
//    code too); a node that answers nothing within the SDO time-out 0504 0000h; the sub-device's
//    own abort code is passed on unchanged. A second request on the same server channel while
//    one is in flight: 060A 0023h (canopen/301/sdo_server.hpp).
//  * Writes (CiA 852 leaves the policy open): reads are always allowed. A write is refused with
//    0800 0021h ("data cannot be transferred or stored to the application because of local
//    control", CiA 301 Table 22: the gateway controls that object) when it would re-wire or
//    re-flash the node or change what the gateway configured and relies on — every COB-ID
//    object (SYNC 1005h, 100Eh COB-ID guard of DS 301 v3 devices, TIME 1012h, EMCY 1014h, the
//    EMCY consumer 1028h, the SDO server and client parameters 1200h–12FFh, the PDO communication
//    and mapping parameters 1400h–1BFFh), the heartbeat objects 1016h/1017h, error behaviour
//    1029h, store 1010h and restore 1011h, program download and control 1F50h–1F57h (CiA 302-3),
//    NMT startup 1F80h, every object (all its sub-indexes) the driver or the mapping file's `sdo`
//    list writes at boot, and what the driver names (Driver::protects: node-ID and bit rate by
//    SDO — elobau 5999h, Novotechnik 2000h/2001h —, the elobau's auto NMT start 5000h, the
//    outputs the gateway drives, the objects its decoding depends on) — while functional
//    elements of the mapping file are fed by or drive that sub-device. Other writes (an elobau
//    parameter, ...) are carried out. The gateway does not reconfigure a node behind the host's
//    back: refusing keeps the FE translation exact and is visible to the host at once.
//  * A network indication redirects its channel until another names the gateway or the gateway
//    is reset or stopped: meanwhile every client of that channel reaches the sub-device. The
//    Gateway logs each redirect and its end, and `oegw status` lists those in force
//    (Gateway::sdo_redirects).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "canopen/301/sdo_remote.hpp"
#include "canopen/master.hpp"
#include "mapping/config.hpp"
#include "subdevices/network_manager.hpp"

namespace oegw::gateway {

struct RemoteSdoCounters {
  std::uint64_t transfers = 0;      // carried to a sub-device (whatever their result)
  std::uint64_t refused = 0;        // refused by the gateway (state, write policy, unknown target)
  std::uint64_t remote_aborts = 0;  // aborted by the sub-device or timed out there
};

class RemoteSdo final : public canopen::SdoRemote {
 public:
  // `self`: the gateway's current node-ID upstream.
  RemoteSdo(const mapping::Config& config, canopen::Master& master, subdevices::NetworkManager& network,
            std::function<canopen::NodeId()> self);

  canopen::SdoAbortCode select(const canopen::SdoTarget& target, Selection& selection) override;
  Ticket upload(const canopen::SdoTarget& target, std::uint16_t index, std::uint8_t sub, canopen::TimePoint now,
                Done done) override;
  Ticket download(const canopen::SdoTarget& target, std::uint16_t index, std::uint8_t sub,
                  std::span<const std::uint8_t> data, bool size_indicated, canopen::TimePoint now, Done done) override;
  void cancel(Ticket ticket, canopen::SdoAbortCode why) override;

  // The target a channel bound to sub-device `name` has (the mapping file checked the name).
  [[nodiscard]] canopen::SdoTarget target_of(const std::string& name) const;
  // The configured sub-device a target names ("" for none).
  [[nodiscard]] std::string subdevice_at(const canopen::SdoTarget& target) const;
  // "right_grip (network 2, node 11h)", for the log.
  [[nodiscard]] std::string describe(const canopen::SdoTarget& target) const;
  // True for a write the policy refuses (see the header).
  [[nodiscard]] bool write_refused(const mapping::SubdeviceConfig& sub, std::uint16_t index, std::uint8_t sub_index);
  [[nodiscard]] const RemoteSdoCounters& counters() const { return counters_; }
  // The transfers to one configured sub-device the gateway refused (its state, the write
  // policy); a network indication naming no configured sub-device counts only in counters().
  [[nodiscard]] std::uint64_t refused(const std::string& subdevice) const;
  [[nodiscard]] std::size_t in_flight() const { return pending_.size(); }

  // Run-time state (canopen/state.hpp): the next ticket and the counters. None is taken while
  // a transfer is in flight (its answer's callback is no state): export throws std::logic_error.
  void export_state(canopen::StateWriter& w) const;
  void import_state(const canopen::StateReader& r);

  // A refused request or a remote abort, for the log ("remote SDO: right_grip 1800h:01 write
  // refused: 0800 0021h ...").
  std::function<void(const std::string&)> on_log;

 private:
  struct Pending {
    Ticket ticket = 0;
    std::uint8_t node = 0;
    std::uint32_t client_ticket = 0;
    Done done;
  };
  [[nodiscard]] const mapping::SubdeviceConfig* find(const canopen::SdoTarget& target) const;
  // Checks a transfer's target now; SdoAbortCode::None when it may go.
  canopen::SdoAbortCode check(const canopen::SdoTarget& target, const mapping::SubdeviceConfig*& sub) const;
  // `sub`: the configured sub-device the transfer was for (nullptr: none).
  Ticket refuse(canopen::SdoAbortCode code, const std::string& what, const mapping::SubdeviceConfig* sub, Done& done);
  Ticket track(std::uint8_t node, Done done);
  void finish(Ticket ticket, canopen::SdoAbortCode code, std::vector<std::uint8_t> data);
  void log(const std::string& line);

  const mapping::Config& config_;
  canopen::Master& master_;
  subdevices::NetworkManager& network_;
  std::function<canopen::NodeId()> self_;
  std::set<std::string> in_use_;  // sub-devices the functional elements use
  std::vector<Pending> pending_;
  Ticket next_ = 1;
  RemoteSdoCounters counters_;
  std::map<std::string, std::uint64_t> refused_by_subdevice_;
};

}  // namespace oegw::gateway
