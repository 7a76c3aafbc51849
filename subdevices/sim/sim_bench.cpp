#include "subdevices/sim/sim_bench.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <numbers>
#include <optional>
#include <sstream>

#include "subdevices/sim/elobau_mfg_sim.hpp"
#include "subdevices/sim/mcb402_sim.hpp"
#include "subdevices/sim/novotechnik_406_sim.hpp"
#include "subdevices/sim/sim_registry.hpp"

namespace oegw::subdevices::sim {

bool SimBench::add(const DeviceSpec& spec, std::string& error) {
  DeviceSpec sim_spec = spec;
  std::string name = spec.name();
  std::optional<std::string> bootup;  // bootup=on|off: the device's boot-ups sent / lost
  std::erase_if(sim_spec.options.values, [&name, &bootup](const auto& kv) {
    if (kv.first == "name") name = kv.second;
    else if (kv.first == "bootup") bootup = kv.second;
    else return false;
    return true;
  });
  if (bootup && *bootup != "on" && *bootup != "off") {
    error = spec.name() + ": bootup '" + *bootup + "' is not on or off";
    return false;
  }
  for (const auto& e : devices_) {
    if (e.name == name) {
      error = "device name '" + name + "' used twice";
      return false;
    }
  }
  // The simulator takes its own options; the driver (for the signal list) only the EDS of a
  // generic node (its signals come from it).
  DeviceSpec driver_spec = sim_spec;
  std::erase_if(driver_spec.options.values, [](const auto& kv) { return kv.first != "eds"; });
  auto sim = make_simulator(sim_spec, sink_, error);
  if (!sim) return false;
  // The MCB-402 driver requires the button bit order; its signal names do not depend on it, and
  // this driver decodes nothing: the simulated board's own wiring satisfies it.
  if (const auto* mcb = dynamic_cast<const Mcb402Sim*>(sim.get())) {
    std::string bits;
    for (const auto b : mcb->config().button_bits) bits += (bits.empty() ? "" : ",") + std::to_string(b);
    driver_spec.options.values.emplace_back("button_bits", bits);
  }
  auto driver = make_driver(spec.family, spec.node, {}, driver_spec.options, error);
  if (!driver) return false;
  sim->set_sdo_latency(sdo_latency_);
  sim->set_boot_up_lost(bootup == "off");
  devices_.push_back({name, std::move(sim), driver->signals()});
  return true;
}

void SimBench::set_sdo_latency(canopen::Duration latency) {
  sdo_latency_ = latency;
  for (auto& e : devices_) e.sim->set_sdo_latency(latency);
}

void SimBench::start(TimePoint now) {
  for (auto& e : devices_) e.sim->start(now);
}

bool SimBench::on_frame(const CanFrame& frame, TimePoint now) {
  bool used = false;
  for (auto& e : devices_) used = e.sim->on_frame(frame, now) || used;  // NMT/SYNC reach every node
  return used;
}

std::vector<canopen::CobId> SimBench::tpdo_cob_ids() const {
  std::vector<canopen::CobId> ids, consumed;
  for (const auto& e : devices_) {
    const auto own = e.sim->tpdo_cob_ids();
    ids.insert(ids.end(), own.begin(), own.end());
    const auto rx = e.sim->rpdo_cob_ids();
    consumed.insert(consumed.end(), rx.begin(), rx.end());
  }
  // A PDO may have several consumers: one that another device of the bench listens to stays in.
  std::erase_if(ids,
                [&](canopen::CobId id) { return std::find(consumed.begin(), consumed.end(), id) != consumed.end(); });
  std::sort(ids.begin(), ids.end(), [](canopen::CobId a, canopen::CobId b) { return a.raw() < b.raw(); });
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  return ids;
}

void SimBench::advance(TimePoint now) {
  for (auto& e : devices_) e.sim->advance(now);
}

std::optional<TimePoint> SimBench::next_deadline() const {
  std::optional<TimePoint> best;
  for (const auto& e : devices_) {
    const auto t = e.sim->next_deadline();
    if (t && (!best || *t < *best)) best = t;
  }
  return best;
}

void SimBench::move(TimePoint now) {
  const double t = std::chrono::duration<double>(now.time_since_epoch()).count();
  for (auto& e : devices_) {
    std::size_t axis = 0;
    std::size_t buttons = 0;
    for (const auto& s : e.signals) buttons += s.kind == SignalKind::Button ? 1 : 0;
    std::size_t button = 0;
    for (const auto& s : e.signals) {
      if (s.kind == SignalKind::Axis || s.kind == SignalKind::Analog || s.kind == SignalKind::Position) {
        const double phase = 2 * std::numbers::pi * t / 4.0 + 0.7 * static_cast<double>(axis++);
        const double span =
            std::min<double>(static_cast<double>(s.max - s.neutral), static_cast<double>(s.neutral - s.min));
        const double amplitude = s.kind == SignalKind::Position ? 1000.0 : 0.8 * span;
        // A position (an encoder's count) turns about a point 2000 counts above its neutral: a
        // knob that swings through zero would cross the sensor's lower work-area limit and its
        // minimum every two seconds (Novotechnik §5.7.1: an EMCY 9090h each time), which a
        // hand turning a knob does not do.
        const double centre = s.kind == SignalKind::Position ? 2000.0 : 0.0;
        const long long v = s.neutral + std::llround(centre + amplitude * std::sin(phase));
        (void)e.sim->set_input(s.name, std::clamp<long long>(v, s.min, s.max), now);
      } else if (s.kind == SignalKind::Button && buttons > 0) {
        const auto pressed = static_cast<std::size_t>(t) % buttons;
        (void)e.sim->set_input(s.name, button++ == pressed ? 1 : 0, now);
      }
    }
  }
}

SimulatedDevice* SimBench::device(std::string_view name) {
  for (auto& e : devices_)
    if (e.name == name) return e.sim.get();
  return nullptr;
}

std::vector<std::string> SimBench::names() const {
  std::vector<std::string> out;
  for (const auto& e : devices_) out.push_back(e.name);
  return out;
}

namespace {

struct NumberAndState {
  long number;
  bool on;
};

// The "<number> on|off" of a command ("left_grip cable_break 1 on", "grip error 0x61 off"): `value`
// (decimal or 0x hex) within lo..hi, then the state read from `in`; nullopt otherwise.
std::optional<NumberAndState> number_and_state(const std::string& value, std::istream& in, long lo, long hi) {
  std::string state;
  in >> state;
  char* end = nullptr;
  const long number = std::strtol(value.c_str(), &end, 0);
  if (value.empty() || *end != '\0' || number < lo || number > hi || (state != "on" && state != "off"))
    return std::nullopt;
  return NumberAndState{number, state == "on"};
}

}  // namespace

std::string SimBench::command(std::string_view line, TimePoint now) {
  std::istringstream in{std::string(line)};
  std::string name, what, value;
  in >> name >> what >> value;
  if (name.empty()) return "error: empty command";
  SimulatedDevice* d = device(name);
  if (d == nullptr) {
    std::string known;
    for (const auto& n : names()) known += (known.empty() ? "" : ", ") + n;
    return "error: no device '" + name + "' (devices: " + known + ")";
  }
  if (what == "reboot") {
    d->reboot(now);
    return "ok " + name + " rebooted";
  }
  if (what == "silent" || what == "heartbeat" || what == "pdo" || what == "bootup") {
    if (value != "on" && value != "off") return "error: " + what + " takes on or off";
    if (what == "silent") d->set_silent(value == "on");
    else if (what == "heartbeat") d->set_heartbeat_stopped(value == "off");
    else if (what == "bootup") d->set_boot_up_lost(value == "off");
    else d->set_pdo_stopped(value == "off");
    return "ok " + name + " " + what + " " + value;
  }
  if (what == "cable_break") {
    // MCB-402 only: axis 1..4 cable broken / mended (EMCY 3120h and its error reset).
    auto* mcb = dynamic_cast<Mcb402Sim*>(d);
    if (mcb == nullptr) return "error: " + name + " is no MCB-402: cable_break is an MCB-402 fault";
    const auto axis = number_and_state(value, in, 1, 4);
    if (!axis) return "error: expected <device> cable_break <axis 1..4> on|off";
    mcb->cable_break(static_cast<std::size_t>(axis->number), axis->on, now);
    return "ok " + name + " cable_break " + value + (axis->on ? " on" : " off");
  }
  if (what == "bus_off" || what == "life_guarding") {
    // The documents' CAN warnings: elobau §12.4 8140h (with the zero-position rule, §4); MCB-402
    // "40 81 11 ..." / "30 81 11 ..." ([CO4013 "Emergency Messages"]).
    if (auto* mcb = dynamic_cast<Mcb402Sim*>(d)) {
      if (what == "bus_off") mcb->bus_off_recovered(now);
      else mcb->life_guarding(now);
      return "ok " + name + " " + what;
    }
    if (auto* grip = dynamic_cast<ElobauMfgSim*>(d); grip && what == "bus_off") {
      grip->bus_off(now);
      return "ok " + name + " bus_off";
    }
    return "error: " + what + " is an MCB-402 (bus_off, life_guarding) or elobau (bus_off) command";
  }
  if (what == "error") {
    // elobau only: a Table 6 manufacturer error (4001h) raised or cleared, e.g. "grip error 0x61 on".
    auto* grip = dynamic_cast<ElobauMfgSim*>(d);
    if (grip == nullptr) return "error: " + name + " is no elobau grip: error is an elobau command";
    const auto code = number_and_state(value, in, 1, 0xFFFF);
    if (!code) return "error: expected <device> error <4001h code, e.g. 0x61> on|off";
    if (code->on) grip->raise_error(static_cast<std::uint16_t>(code->number), now);
    else grip->clear_error(static_cast<std::uint16_t>(code->number), now);
    return "ok " + name + " error " + value + (code->on ? " on" : " off");
  }
  if (what == "fault") {
    // Novotechnik only: a §9.1 position fault, or its clearing (measurement / hardware faults:
    // "valid position" or 0000h; out of range only through 2100h, refused here).
    auto* knob = dynamic_cast<Novotechnik406Sim*>(d);
    if (knob == nullptr) return "error: " + name + " is no Novotechnik sensor: fault is a Novotechnik fault";
    using F = Novotechnik406Sim::Fault;
    static const std::pair<const char*, F> kFaults[] = {{"measurement", F::Measurement},
                                                        {"overflow", F::Overflow},
                                                        {"underflow", F::Underflow},
                                                        {"hardware", F::HardwareFault}};
    if (value == "clear") {
      return knob->clear_fault(now) ? "ok " + name + " fault cleared"
                                    : "error: " + name + " has no fault it can clear (out of range: write 2100h)";
    }
    for (const auto& [n, f] : kFaults) {
      if (value != n) continue;
      knob->inject_fault(f, now);
      return "ok " + name + " fault " + value;
    }
    return "error: expected <device> fault measurement|overflow|underflow|hardware|clear";
  }
  char* end = nullptr;
  const long long v = std::strtoll(value.c_str(), &end, 0);
  if (what.empty() || value.empty() || *end != '\0') return "error: expected <device> <signal> <value>";
  if (!d->set_input(what, v, now)) return "error: " + name + " has no input '" + what + "' taking " + value;
  return "ok " + name + " " + what + " = " + value;
}

}  // namespace oegw::subdevices::sim
