// Base of the sub-device simulators: a canopen::Node (the real protocol core) with the device's
// object dictionary, plus the faults a bench test needs: go silent (cable pulled), stop the
// heartbeat only, stop the TPDOs only, reboot. Each family's simulator (sim/<family>_sim.hpp) builds the dictionary
// and PDO layout its document describes and adds its own controls (move an axis, press a button,
// inject an error code).
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "canopen/301/object_dictionary.hpp"
#include "canopen/node.hpp"

namespace oegw::subdevices::sim {

using canopen::CanFrame;
using canopen::FrameSink;
using canopen::NodeId;
using canopen::TimePoint;

class SimulatedDevice {
 public:
  virtual ~SimulatedDevice() = default;
  SimulatedDevice(const SimulatedDevice&) = delete;
  SimulatedDevice& operator=(const SimulatedDevice&) = delete;

  [[nodiscard]] virtual std::string_view family() const = 0;

  [[nodiscard]] canopen::Node& node() { return *node_; }
  [[nodiscard]] canopen::ObjectDictionary& od() { return *od_; }
  [[nodiscard]] const canopen::ObjectDictionary& od() const { return *od_; }

  // Power on: boot-up message, pre-operational.
  virtual void start(TimePoint now);
  // Power cycle: volatile state back to power-on values (the dictionary's defaults plus what
  // the device stored), boot-up again.
  virtual void reboot(TimePoint now);
  // Cable pulled (true) / plugged back (false): nothing is sent or received meanwhile.
  void set_silent(bool silent) { silent_ = silent; }
  [[nodiscard]] bool silent() const { return silent_; }
  // The heartbeat stops while everything else goes on (a firmware fault).
  void set_heartbeat_stopped(bool stopped) { heartbeat_stopped_ = stopped; }
  // Its boot-ups (700h + node-ID, state 00h) never reach the bus while the heartbeat, SDO and
  // the rest go on: a boot-up lost (sent while the transceiver was not yet up, or dropped by
  // the master's receive queue), as a master must expect (CiA 302-2 boot-slave process).
  void set_boot_up_lost(bool lost) { boot_up_lost_ = lost; }
  [[nodiscard]] bool boot_up_lost() const { return boot_up_lost_; }
  // The TPDOs stop while the heartbeat, SDO, EMCY and NMT go on (e.g. a sensor task that hangs
  // while the communication task lives). A TPDO is a frame whose identifier is the COB-ID
  // (sub-index 01h) of a valid TPDO communication parameter 1800h..19FFh (CiA 301 §7.2.2) as
  // the dictionary holds it at the moment of sending; every other frame still goes out.
  void set_pdo_stopped(bool stopped) { pdo_stopped_ = stopped; }
  [[nodiscard]] bool pdo_stopped() const { return pdo_stopped_; }

  // Moves an input by the name its driver gives the signal ("x", "buttons[3]", "position"),
  // in the driver's unit (elobau percent, MCB-402 raw16, encoder counts). For oegw-sim and the
  // demo; tests use the family's own controls. False for an unknown name or a value the device
  // cannot show.
  virtual bool set_input(std::string_view signal, std::int64_t value, TimePoint now) = 0;
  // The current state of an output by its driver signal name ("leds[2]"), or nullopt.
  [[nodiscard]] virtual std::optional<std::int64_t> output(std::string_view signal) const = 0;

  // The device's SDO latency: every answer of its SDO server (1200h) leaves `latency` after
  // the request was received, in order (a device answers from its application cycle, not at
  // once). 0 (the default): at once. Answers still pending at a reboot are lost, as the
  // device's are; a silent device's pending answers are not sent.
  void set_sdo_latency(canopen::Duration latency) { sdo_latency_ = latency; }
  [[nodiscard]] canopen::Duration sdo_latency() const { return sdo_latency_; }

  // The COB-IDs of its valid TPDOs (1800h..19FFh sub-index 01h, CiA 301 §7.5.2.35) as the
  // dictionary holds them now: the identifiers only this device may send (a PDO has exactly one
  // producer, CiA 301), so a data frame on one of them is not meant for it, unless an RPDO of a
  // device beside it listens there (SimBench::tpdo_cob_ids leaves those out).
  [[nodiscard]] std::vector<canopen::CobId> tpdo_cob_ids() const;
  // The COB-IDs of its valid RPDOs (1400h..15FFh sub-index 01h).
  [[nodiscard]] std::vector<canopen::CobId> rpdo_cob_ids() const;

  // Sans-I/O entry points, as canopen::Node's.
  bool on_frame(const CanFrame& frame, TimePoint now);
  void advance(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const;

 protected:
  // `sink` is where the device's frames go (a bus port); the Node built by the subclass must
  // send through out(), which applies the faults.
  explicit SimulatedDevice(FrameSink sink) : sink_(std::move(sink)) {}
  [[nodiscard]] FrameSink out() {
    return [this](const CanFrame& f) { send(f); };
  }
  // Subclasses call this from their constructor, after building `od` (PDOs installed).
  void build(std::unique_ptr<canopen::ObjectDictionary> od, const canopen::NodeConfig& config);
  // The device's own reaction to a power cycle (e.g. elobau's zero-position rule).
  virtual void on_power_cycle(TimePoint /*now*/) {}
  // What the device refuses in its present NMT state (e.g. store parameters while operational):
  // the abort code an SDO download initiate of index/sub gets (CiA 301 §7.2.4.3.17), before the
  // dictionary sees it; SdoAbortCode::None lets it through. Asked for every download initiate
  // (expedited, segmented or block) on the default SDO server channel 1200h.
  [[nodiscard]] virtual canopen::SdoAbortCode refuse_download(std::uint16_t /*index*/, std::uint8_t /*sub*/,
                                                              canopen::NmtState /*state*/) const {
    return canopen::SdoAbortCode::None;
  }
  // An expedited SDO download the device handles itself, outside the dictionary (e.g. a
  // manufacturer's store groups and signatures on 1010h): nullopt passes it on to the dictionary;
  // None answers the download as done (CiA 301 §7.2.4.3.3 initiate download response), any
  // other code aborts it. Asked after refuse_download().
  [[nodiscard]] virtual std::optional<canopen::SdoAbortCode> handle_download(std::uint16_t /*index*/,
                                                                             std::uint8_t /*sub*/,
                                                                             std::span<const std::uint8_t> /*data*/) {
    return std::nullopt;
  }

 private:
  void send(const CanFrame& frame);
  [[nodiscard]] bool is_sdo_answer(const CanFrame& frame) const;
  void release_answers(TimePoint now);  // the delayed SDO answers due by `now`
  [[nodiscard]] bool is_tpdo(const CanFrame& frame) const;
  // The valid COB-IDs in sub-index 01h of the PDO communication parameters first..last.
  [[nodiscard]] std::vector<canopen::CobId> pdo_cob_ids(std::uint16_t first, std::uint16_t last) const;
  bool intercepted(const CanFrame& frame);  // answered refuse_download() or handle_download()

  FrameSink sink_;
  bool silent_ = false;
  bool heartbeat_stopped_ = false;
  bool boot_up_lost_ = false;
  bool pdo_stopped_ = false;
  std::unique_ptr<canopen::ObjectDictionary> od_;
  std::unique_ptr<canopen::Node> node_;
  canopen::Duration sdo_latency_{0};
  TimePoint now_{};  // of the frame or advance() being handled: what send() delays from
  std::deque<std::pair<TimePoint, CanFrame>> delayed_;  // SDO answers waiting for their time
};

}  // namespace oegw::subdevices::sim
