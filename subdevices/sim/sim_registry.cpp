#include "subdevices/sim/sim_registry.hpp"

#include <cstdlib>
#include <functional>

#include "subdevices/sim/cia401_sim.hpp"
#include "subdevices/sim/elobau_mfg_sim.hpp"
#include "subdevices/sim/mcb402_sim.hpp"
#include "subdevices/sim/novotechnik_406_sim.hpp"

namespace oegw::subdevices::sim {

namespace {

// One option a simulator takes: its name, the family it belongs to ("" = every family), what it
// accepts (for the refusal) and how it applies a value (false: refused).
struct SimOption {
  std::string_view name;
  std::string_view family;
  std::string accepts;
  std::function<bool(const std::string& value)> apply;
};

std::optional<long> number(const std::string& text, long lo, long hi) {
  char* end = nullptr;
  const long v = std::strtol(text.c_str(), &end, 0);
  if (text.empty() || *end != '\0' || v < lo || v > hi) return std::nullopt;
  return v;
}

// An integer option lo..hi into `target`.
template <class T>
SimOption integer(std::string_view name, std::string_view family, std::string_view accepts, long lo, long hi,
                  T& target) {
  return {name, family, std::string(accepts), [lo, hi, &target](const std::string& v) {
            const auto n = number(v, lo, hi);
            if (n) target = static_cast<T>(*n);
            return n.has_value();
          }};
}

// A two-way option: `a` (-> true) or `b` (-> false) into `target`.
SimOption either(std::string_view name, std::string_view family, std::string_view a, std::string_view b, bool& target) {
  return {name, family, std::string(a) + " or " + std::string(b), [a, b, &target](const std::string& v) {
            if (v != a && v != b) return false;
            target = v == a;
            return true;
          }};
}

}  // namespace

std::unique_ptr<SimulatedDevice> make_simulator(const DeviceSpec& spec, FrameSink sink, std::string& error) {
  std::uint16_t heartbeat_ms = 0;
  std::filesystem::path store;
  std::string eds;
  Mcb402SimConfig mcb;
  ElobauMfgSimConfig elobau;
  Novotechnik406SimConfig knob;
  const std::vector<SimOption> table = {
      integer("heartbeat_ms", "", "0..65535", 0, 0xFFFF, heartbeat_ms),
      {"store", "", "a file path", [&](const std::string& v) { return !(store = v).empty(); }},
      {"eds", "cia401", "an EDS file path", [&](const std::string& v) { return !(eds = v).empty(); }},
      // MCB-402 corners (mcb402_sim.hpp).
      {"wiring", "mcb402", "7 distinct bits 0..7 of 6000h:03 for BP1..BP7, e.g. wiring=1/2/3/4/5/7/6",
       [&](const std::string& v) {
         const auto w = co4013::parse_wiring(v);
         if (w) mcb.button_bits = *w;
         return w.has_value();
       }},
      either("clear_after_break", "mcb402", "0000h", "none", mcb.clear_with_error_reset),
      either("power_on_1001h", "mcb402", "11h", "00h", mcb.keep_communication_bits),
      // elobau corners (elobau_mfg_sim.hpp).
      either("tpdo", "elobau-mfg", "change", "timer", elobau.tpdo_on_change),
      either("saved", "elobau-mfg", "yes", "no", elobau.parameters_saved),
      integer("buttons", "elobau-mfg", "2100h:01h, 0..255 (bit n-1: button n fitted)", 0, 255, elobau.buttons_1_8),
      integer("buttons_9_16", "elobau-mfg", "2100h:02h, 0..255 (bit n-9: button n fitted)", 0, 255,
              elobau.buttons_9_16),
      // Novotechnik corners (novotechnik_406_sim.hpp).
      integer("error_register_size", "novotechnik-406", "1 or 2 (bytes of 1001h)", 1, 2, knob.error_register_bytes),
      integer("emcy_behaviour", "novotechnik-406", "0..3 (2104h as stored)", 0, 3, knob.emcy_behaviour),
      either("has_6020h", "novotechnik-406", "yes", "no", knob.has_6020h),
      either("work_area_emcy", "novotechnik-406", "bits", "enum", knob.work_area_bits),
      either("load", "novotechnik-406", "defaults", "stored", knob.load_restores_defaults),
  };
  for (const auto& [key, value] : spec.options.values) {
    const SimOption* found = nullptr;
    for (const SimOption& o : table)
      if (o.name == key && (o.family.empty() || o.family == spec.family)) found = &o;
    if (found == nullptr) {
      std::string known;
      for (const SimOption& o : table)
        if (o.family.empty() || o.family == spec.family) known += (known.empty() ? "" : ", ") + std::string(o.name);
      error = spec.name() + ": unknown simulator option '" + key + "' (expected " + known + ")";
      return nullptr;
    }
    if (!found->apply(value)) {
      error = spec.name() + ": " + key + " '" + value + "' is not " + found->accepts;
      return nullptr;
    }
  }
  if (spec.family == "mcb402") {
    mcb.node_id = spec.node;
    mcb.heartbeat_ms = heartbeat_ms;
    mcb.store_path = store;
    return std::make_unique<Mcb402Sim>(std::move(sink), mcb);
  }
  if (spec.family == "elobau-mfg") {
    elobau.node_id = spec.node;
    elobau.heartbeat_ms = heartbeat_ms;
    elobau.store_path = store;
    return std::make_unique<ElobauMfgSim>(std::move(sink), elobau);
  }
  if (spec.family == "novotechnik-406") {
    knob.node_id = spec.node;
    knob.heartbeat_ms = heartbeat_ms;
    knob.store_path = store;
    return std::make_unique<Novotechnik406Sim>(std::move(sink), knob);
  }
  if (spec.family == "cia401") {
    if (eds.empty()) {
      error = spec.name() + ": the cia401 simulator needs eds=<file>";
      return nullptr;
    }
    auto sim = Cia401Sim::from_file(eds, spec.node, std::move(sink), error, store);
    if (!sim) return nullptr;
    return sim;
  }
  error = "unknown simulator family '" + spec.family + "' (expected elobau-mfg, mcb402, novotechnik-406, cia401)";
  return nullptr;
}

}  // namespace oegw::subdevices::sim
