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
//   <device> bus_off              MCB-402 "40 81 11 ...", elobau 8140h (a bus off recovered)
//   <device> life_guarding        MCB-402 "30 81 11 ..."
//   <device> error CODE on|off    elobau: Table 6 manufacturer error CODE (e.g. 0x61) raised / cleared
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

// The SDO latency the simulators get on the timed bus (rig/cab_rig.hpp) unless told
// otherwise: the time from an SDO request on the bus to the device's answer. None of the
// reference documents (/work/shared/reference: elobau MFG, MCB-402, Novotechnik, CiA 852)
// states an SDO response time; what they state is their application cycles - the Novotechnik
// sensor measures every 1 ms (TPDO1 "synchronous to measurement cycle, 1 ms"), the elobau grip
// scans its inputs every 5 ms. A small CANopen device serves SDO from a main loop of that
// order; 1 ms, a typical answer time of such devices (about one task cycle), is the default.
// The benchmarks take another value (--sdo-latency-us) to show how the boot scales with it.
inline constexpr canopen::Duration kTypicalSdoLatency = std::chrono::milliseconds(1);

class SimBench {
 public:
  explicit SimBench(FrameSink sink) : sink_(std::move(sink)) {}

  // Adds a device; false with `error` for a bad spec.
  bool add(const DeviceSpec& spec, std::string& error);
  void start(TimePoint now);
  // Every device's SDO latency (SimulatedDevice::set_sdo_latency), also of devices added later.
  void set_sdo_latency(canopen::Duration latency);

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
  // Every device's TPDO COB-IDs (SimulatedDevice::tpdo_cob_ids) that no device's RPDO listens
  // to, ascending by raw value, each once: what a bus port may filter out, as a real device's
  // acceptance filter would.
  [[nodiscard]] std::vector<canopen::CobId> tpdo_cob_ids() const;

 private:
  struct Entry {
    std::string name;
    std::unique_ptr<SimulatedDevice> sim;
    std::vector<SignalInfo> signals;  // from the family's driver
  };
  FrameSink sink_;
  std::vector<Entry> devices_;
  canopen::Duration sdo_latency_{0};
};

}  // namespace oegw::subdevices::sim
