// The command arbiter: the one owner of who may command an output FE (indicator clusters,
// displays) and of what happens when its commander falls silent.
//
//   DDS / LCM command ──────────────┐
//   host SDO download / RPDO ─ OeDevice (CiA 401 output objects) ─┤
//                                   └→ CommandArbiter → FeModel (output state) → drive → sub-devices
//
//  * Sources: each output FE takes commands only from the sources its mapping-file entry lists
//    (`sources`: canopen, dds, lcm); among them the last writer wins. A command from another
//    source changes nothing and is counted (refused()); it is logged once per FE and way.
//  * Host writes reach the arbiter through the device (OeDevice::on_host_write) before they
//    commit; a refused one is aborted 0800 0021h (SDO) or ignored (its RPDO bytes).
//  * Watchdog (`command_timeout_ms`): an output FE whose commander is silent that long takes
//    its CiA 401 error values (6206h/6207h, 6443h/6444h — what a lost host heartbeat does to
//    every output) and keeps them, also against host writes of the error objects, NMT resets
//    and 1011h restores, until the next accepted command.
//  * Every change of an output value — a command, the error values, an NMT reset putting the
//    defaults back — arrives from the device's dictionary (the CiA 401 store the host reads
//    back) as output_changed(), updates the FE model and is driven to the sub-devices.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "canopen/types.hpp"
#include "gateway/fe_model.hpp"
#include "gateway/oe_device.hpp"
#include "mapping/config.hpp"

namespace oegw::gateway {

class CommandArbiter {
 public:
  CommandArbiter(const mapping::Config& config, OeDevice& device, FeModel& model);
  CommandArbiter(const CommandArbiter&) = delete;
  CommandArbiter& operator=(const CommandArbiter&) = delete;

  // The watchdogs run from here (a commander that never starts is a silent one).
  void start(canopen::TimePoint now);

  // Commands of the machine application. False, changing nothing, for a source the FE does not
  // take or an FE the mapping file does not configure.
  bool command_indicators(std::uint8_t instance, std::uint64_t bits, mapping::CommandSource source,
                          canopen::TimePoint now);
  bool command_display(std::uint8_t instance, const std::array<std::int16_t, 12>& parameters,
                       mapping::CommandSource source, canopen::TimePoint now);

  // After each upstream frame: an FE whose commander is silent keeps its error values.
  void hold_error_values(canopen::TimePoint now);
  // Watchdog expiry.
  void advance(canopen::TimePoint now);
  [[nodiscard]] std::optional<canopen::TimePoint> next_deadline() const;

  // Commands refused so far: all of them, and those of one configured output FE (a source it
  // does not take; zero for an FE the mapping file does not configure, whose refusals only the
  // total counts).
  [[nodiscard]] std::uint64_t refused() const { return refused_; }
  [[nodiscard]] std::uint64_t refused(mapping::FeId fe) const;

  // Run-time state (canopen/state.hpp): each output FE's last command time, its watchdog verdict
  // and refusals, whether the watchdogs run, and which refusals were logged already.
  void export_state(canopen::StateWriter& w) const;
  void import_state(const canopen::StateReader& r);

  // Where accepted output values go (the gateway's output bindings).
  std::function<void(mapping::FeId, FieldRef, std::int64_t)> drive;
  std::function<void(const std::string&)> log;

 private:
  struct Output {
    mapping::FeId id;
    mapping::CommandSources sources = 0;
    canopen::Duration timeout{};  // zero: no watchdog
    canopen::TimePoint last{};
    bool expired = false;
    std::uint64_t refused = 0;  // its commands refused (refused(fe))
  };
  Output* find(mapping::FeId fe);
  bool host_write(mapping::FeId fe, canopen::Origin origin, canopen::TimePoint now);
  void output_changed(mapping::FeId fe, FieldRef ref, std::int64_t value, canopen::TimePoint now);
  bool take(mapping::FeId fe, mapping::CommandSource source, canopen::TimePoint now);
  void seen(Output& o, canopen::TimePoint now);
  void refuse(mapping::FeId fe, std::string_view way, const std::string& why);
  void say(const std::string& line) const;

  OeDevice& device_;
  FeModel& model_;
  std::vector<Output> outputs_;
  bool started_ = false;
  std::uint64_t refused_ = 0;
  std::set<std::pair<mapping::FeId, std::string>> refused_logged_;  // (FE, way) already logged
};

}  // namespace oegw::gateway
