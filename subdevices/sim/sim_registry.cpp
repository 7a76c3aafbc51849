#include "subdevices/sim/sim_registry.hpp"

#include <cstdlib>

#include "subdevices/sim/cia401_sim.hpp"
#include "subdevices/sim/elobau_mfg_sim.hpp"
#include "subdevices/sim/mcb402_sim.hpp"
#include "subdevices/sim/novotechnik_406_sim.hpp"

namespace oegw::subdevices::sim {

namespace {
// The families configured by node-ID, heartbeat and store alone.
template <class Sim, class Config>
std::unique_ptr<SimulatedDevice> make(const DeviceSpec& spec, FrameSink sink, std::uint16_t heartbeat_ms,
                                      const std::filesystem::path& store) {
  Config c;
  c.node_id = spec.node;
  c.heartbeat_ms = heartbeat_ms;
  c.store_path = store;
  return std::make_unique<Sim>(std::move(sink), c);
}
}  // namespace

std::unique_ptr<SimulatedDevice> make_simulator(const DeviceSpec& spec, FrameSink sink, std::string& error) {
  std::uint16_t heartbeat_ms = 0;
  std::filesystem::path store;
  std::string eds;
  std::optional<co4013::ButtonBits> wiring;
  for (const auto& [key, value] : spec.options.values) {
    if (key == "heartbeat_ms") {
      char* end = nullptr;
      const long v = std::strtol(value.c_str(), &end, 0);
      if (value.empty() || *end != '\0' || v < 0 || v > 0xFFFF) {
        error = spec.name() + ": heartbeat_ms '" + value + "' is not 0..65535";
        return nullptr;
      }
      heartbeat_ms = static_cast<std::uint16_t>(v);
    } else if (key == "store") {
      store = value;
    } else if (key == "eds" && spec.family == "cia401") {
      eds = value;
    } else if (key == "wiring" && spec.family == "mcb402") {
      wiring = co4013::parse_wiring(value);
      if (!wiring) {
        error = spec.name() + ": wiring '" + value +
                "' is not 7 distinct bits 0..7 of 6000h:03 for BP1..BP7, e.g. wiring=1/2/3/4/5/7/6";
        return nullptr;
      }
    } else {
      error = spec.name() + ": unknown simulator option '" + key + "' (expected heartbeat_ms, store" +
              (spec.family == "cia401" ? ", eds)" : spec.family == "mcb402" ? ", wiring)" : ")");
      return nullptr;
    }
  }
  if (spec.family == "mcb402") {
    Mcb402SimConfig c;
    c.node_id = spec.node;
    c.heartbeat_ms = heartbeat_ms;
    c.store_path = store;
    if (wiring) c.button_bits = *wiring;
    return std::make_unique<Mcb402Sim>(std::move(sink), c);
  }
  if (spec.family == "elobau-mfg") return make<ElobauMfgSim, ElobauMfgSimConfig>(spec, std::move(sink), heartbeat_ms, store);
  if (spec.family == "novotechnik-406") return make<Novotechnik406Sim, Novotechnik406SimConfig>(spec, std::move(sink), heartbeat_ms, store);
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
