// The black box's view of one Gateway (docs/guides/black-box.md): the Gateway's tap
// (gateway/gateway_tap.hpp) turned into records — every frame in and out, and one line of text
// per other input and per decision — for a RecordSink: the recorder's files in `oegw run`, the
// comparison in `oegw replay`. Both use this one class, so a replay that makes the same
// decisions writes the same lines.
//
// The event lines (docs/guides/black-box.md#the-files):
//   inputs   start | tick | bus up|down EVENT | indicators N BITS SOURCE |
//            display N P1,..,P12 SOURCE | subdevice_command NAME COMMAND | nmt NODE CS |
//            control WHAT
//   outcomes outcome accepted|refused [WHY]
//   decisions fe NAME STATUS FIELD=VALUE[STATUS](held)... (the fields that changed) |
//            node NAME STATE (WHY) | fault NAME raised|cleared TEXT |
//            emcy NAME CODE REG BYTES (a sub-device's) | emcy_sent CODE REG BYTES (the gateway's) |
//            log TEXT
#pragma once

#include <map>
#include <string>
#include <vector>

#include "gateway/gateway.hpp"
#include "gateway/gateway_tap.hpp"
#include "gateway/record/record_format.hpp"

namespace oegw::gateway::record {

class GatewayRecorder final : public GatewayTap {
 public:
  // The tap of one gateway after another (GatewayOptions::tap, Gateway::set_tap): it must
  // outlive each gateway it taps, or be removed from it first.
  explicit GatewayRecorder(RecordSink& sink) : sink_(sink) {}
  GatewayRecorder(const GatewayRecorder&) = delete;
  GatewayRecorder& operator=(const GatewayRecorder&) = delete;

  // Called by the gateway.
  void started(canopen::TimePoint now) override;
  void received(Bus bus, const canopen::CanFrame& f, canopen::TimePoint t) override;
  void bus_event(Bus bus, canopen::BusEvent e, canopen::TimePoint now) override;
  void advanced(canopen::TimePoint now) override;
  void indicators(std::uint8_t instance, std::uint64_t bits, mapping::CommandSource source,
                  canopen::TimePoint now) override;
  void display(std::uint8_t instance, const std::array<std::int16_t, 12>& parameters, mapping::CommandSource source,
               canopen::TimePoint now) override;
  void subdevice_command(const std::string& name, std::string_view command, canopen::TimePoint now) override;
  void downstream_nmt(canopen::NodeId node, canopen::NmtCommand cs, canopen::TimePoint now) override;
  void control(std::string_view what, canopen::TimePoint now) override;
  void sent(const Gateway& gw, Bus bus, const canopen::CanFrame& f) override;
  void command_outcome(bool taken, std::string_view why) override;
  void node_state(const std::string& name, subdevices::NodeState state, const std::string& why) override;
  void fault(const std::string& name, bool raised, std::string_view text) override;
  void subdevice_emcy(const std::string& name, const canopen::EmcyMessage& e) override;
  void fe_changed(const Gateway& gw, mapping::FeId fe) override;
  // An input of the daemon around the gateway that the gateway's calls do not show: "reload
  // FILE" (the mapping file reloaded, SIGHUP).
  void note(canopen::TimePoint t, std::string_view text) { input(t, text); }
  // A segment begins here (its `state` line): each FE's next line names every field again, so
  // that a segment read without those before it shows whole FEs. The replay calls it where the
  // recording has a `state` line, so that its lines are the recording's.
  void segment_started() {
    for (auto& [fe, c] : fes_) c.seen = false;
  }
  void logged(const std::string& line) override;

 private:
  struct FeCache {
    std::string prefix;              // "fe joystick.1 "
    std::vector<std::string> names;  // " x=", one per field
    std::vector<Gateway::FieldSample> last;
    bool seen = false;
  };
  void input(canopen::TimePoint t, std::string_view text);
  void emit();  // line_ to the sink at now_

  RecordSink& sink_;
  canopen::TimePoint now_{};
  std::string line_;  // reused: no allocation per line once grown
  std::map<mapping::FeId, FeCache> fes_;
  std::vector<Gateway::FieldSample> samples_;
};

}  // namespace oegw::gateway::record
