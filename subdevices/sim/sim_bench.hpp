// A bench of simulated devices sharing one bus: what `oegw-sim` runs (on SocketCAN) and what
// the demos run (on the virtual bus). Each device is a SimulatedDevice from make_simulator();
// a driver of the same family supplies the signal list, so that "motion" can sweep every axis
// and toggle every button by name, and text commands can move any input:
//   <device> <signal> <value>     e.g. "grip x 50", "pedal analog[1] 12000"
//   <device> silent on|off        cable pulled / plugged back
//   <device> heartbeat on|off     heartbeat stops / resumes (everything else goes on)
//   <device> pdo on|off           TPDOs stop / resume (heartbeat, SDO, EMCY go on)
//   <device> reboot               power cycle
//   <device> cable_break N on|off MCB-402: axis N (1..4) cable broken / mended (EMCY 3120h)
//   <device> fault KIND           Novotechnik: measurement|overflow|underflow|hardware (§9.1
//                                 EMCY and marker position) or clear (out of range: 2100h only)
// Device names are the spec's "name=" option, else family@node ("elobau-mfg@11h").
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "subdevices/device_spec.hpp"
#include "subdevices/sim/simulated_device.hpp"

namespace oegw::subdevices::sim {

class SimBench {
 public:
  explicit SimBench(FrameSink sink) : sink_(std::move(sink)) {}

  // Adds a device; false with `error` for a bad spec.
  bool add(const DeviceSpec& spec, std::string& error);
  void start(TimePoint now);

  bool on_frame(const CanFrame& frame, TimePoint now);
  void advance(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const;

  // Sweeps every axis (sine, 4 s period, 80 % of its range) and presses each button for one
  // second in turn, as of `now`.
  void move(TimePoint now);
  // Runs one text command; returns "ok ..." or "error: ...".
  std::string command(std::string_view line, TimePoint now);

  [[nodiscard]] std::size_t size() const { return devices_.size(); }
  [[nodiscard]] SimulatedDevice* device(std::string_view name);
  [[nodiscard]] std::vector<std::string> names() const;

 private:
  struct Entry {
    std::string name;
    std::unique_ptr<SimulatedDevice> sim;
    std::vector<SignalInfo> signals;  // from the family's driver
  };
  FrameSink sink_;
  std::vector<Entry> devices_;
};

}  // namespace oegw::subdevices::sim
