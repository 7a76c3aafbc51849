#include "gateway/control/status_report.hpp"

#include <chrono>

namespace oegw::gateway::control {

using nlohmann::json;
namespace sd = subdevices;

namespace {

std::int64_t ms_between(canopen::TimePoint from, canopen::TimePoint to) {
  return std::chrono::duration_cast<std::chrono::milliseconds>(to - from).count();
}

template <class T>
json optional_value(const std::optional<T>& v) {
  return v ? json(*v) : json(nullptr);
}

// The last EMCY of a node, or null before the first (CiA 301 §7.2.7: code, 1001h, 5 bytes).
json emcy_json(const Gateway::EmcyRecord& r, canopen::TimePoint now) {
  if (r.count == 0) return nullptr;
  return json{{"code", r.last.code},
              {"error_register", r.last.error_register},
              {"data", json::array({r.last.msef[0], r.last.msef[1], r.last.msef[2], r.last.msef[3], r.last.msef[4]})},
              {"age_ms", ms_between(r.time, now)},
              {"count", r.count}};
}

// What the node said about itself at its last boot (1018h, 1008h, 1009h, 100Ah, 1001h).
void add_identity(json& out, const sd::NodeDiagnostics* d) {
  const sd::NodeDiagnostics none;
  if (d == nullptr) d = &none;
  out["identity"] = json{{"vendor_id", optional_value(d->vendor_id)},
                         {"product_code", optional_value(d->product_code)},
                         {"revision", optional_value(d->revision)},
                         {"serial", optional_value(d->serial)}};
  out["device_name"] = optional_value(d->device_name);
  out["hardware_version"] = optional_value(d->hardware_version);
  out["software_version"] = optional_value(d->software_version);
  out["error_register"] = optional_value(d->error_register);
}

json counters_json(const sd::NodeCounters& n, const sd::InputCounters* c, std::uint64_t refused) {
  const sd::InputCounters none;
  if (c == nullptr) c = &none;
  return json{{"frames", n.frames},
              {"bad_frames", c->wrong_length + c->unknown_cob + c->unknown_emcy},
              {"wrong_length", c->wrong_length},
              {"unknown_cob", c->unknown_cob},
              {"unknown_emcy", c->unknown_emcy},
              {"channel_mismatches", c->mismatches},
              {"reboots_seen", n.reboots_seen},
              {"gateway_resets", n.gateway_resets},
              {"refused_commands", refused}};
}

json subdevice_json(const Gateway& gw, const mapping::SubdeviceConfig& s, canopen::TimePoint now) {
  const sd::NetworkManager& net = gw.downstream();
  const sd::NodeState state = net.state(s.name);
  const auto fault = gw.faults().find(s.name);
  const bool faulty = fault != gw.faults().end();
  json out{{"name", s.name},
           {"node_id", s.node_id},
           {"driver", s.driver},
           {"mandatory", s.mandatory},
           {"state", subdevice_summary(state, faulty)},
           {"network_state", std::string(sd::to_string(state))},
           {"fault", faulty ? json(fault->second) : json(nullptr)}};
  add_identity(out, net.diagnostics(s.name));
  out["last_emcy"] = emcy_json(gw.subdevice_emcy(s.name), now);
  const sd::Driver* d = net.driver(s.name);
  out["counters"] =
      counters_json(net.node_counters(s.name), d ? &d->counters() : nullptr, gw.subdevice_refused_commands(s.name));
  return out;
}

json fe_json(const Gateway& gw, mapping::FeId fe) {
  json fields = json::array();
  for (const auto& f : gw.fields(fe))
    fields.push_back(json{{"name", f.name},
                          {"value", f.value},
                          {"status", std::string(sd::to_string(f.status))},
                          {"interlocked", f.interlocked}});
  // FeStatus mirrors SignalStatus (fe_samples.hpp).
  const auto status = static_cast<sd::SignalStatus>(gw.status(fe));
  return json{{"name", mapping::fe_name(fe)},
              {"status", std::string(sd::to_string(status))},
              {"fields", fields},
              {"refused_commands", gw.refused_commands(fe)}};
}

json upstream_json(const Gateway& gw, const mapping::Config& c, canopen::TimePoint now) {
  json consumed = json::array();
  for (const auto& [node, e] : gw.upstream_emcys())
    consumed.push_back(json{{"node_id", node}, {"last_emcy", emcy_json(e, now)}});
  json active = json::array();
  if (!gw.faults().empty()) active.push_back(OeDevice::kEmcyAdditionalModules);
  if (gw.reloading()) active.push_back(Gateway::kEmcyReload);
  // SDO server channels a network indication redirected to a sub-device: a client on one
  // reaches the sub-device, not the gateway (docs/guides/remote-sdo.md).
  json redirects = json::array();
  for (const auto& r : gw.sdo_redirects()) {
    json request = json::array();
    for (const std::uint8_t b : r.redirect.request) request.push_back(b);
    redirects.push_back(json{{"sdo_server", r.server},
                             {"request_cob_id", r.request.can_id()},
                             {"response_cob_id", r.response.can_id()},
                             {"network_id", r.redirect.target.network},
                             {"node_id", r.redirect.target.node},
                             {"subdevice", r.subdevice},
                             {"age_ms", ms_between(r.redirect.since, now)},
                             {"indication", request}});
  }
  return json{{"interface", c.upstream.interface},
              {"network_id", c.upstream.network_id},
              {"node_id", c.upstream.node_id},
              {"nmt_state", std::string(canopen::to_string(gw.upstream().node().state()))},
              {"active_emcys", active},
              {"consumed_emcys", consumed},
              {"sdo_redirects", redirects}};
}

}  // namespace

std::string subdevice_summary(sd::NodeState state, bool faulty) {
  switch (state) {
    case sd::NodeState::Operational: return faulty ? "faulty" : "operational";
    case sd::NodeState::WaitingBootUp:
    case sd::NodeState::Configuring:
    case sd::NodeState::Starting: return "booting";
    case sd::NodeState::Missing: return "missing";
    case sd::NodeState::Refused: return "refused";
    case sd::NodeState::Idle: return "idle";
  }
  return "unknown";
}

namespace {
json bus_json(const canopen::io::TransportCounters& c) {
  return json{{"rx_frames", c.rx_frames},   {"tx_frames", c.tx_frames},       {"rx_dropped", c.rx_dropped},
              {"tx_dropped", c.tx_dropped}, {"error_frames", c.error_frames}, {"errors", c.errors}};
}
}  // namespace

json publishing_status(const std::vector<TransportState>& transports) {
  json out = json::array();
  for (const TransportState& t : transports) {
    json j{{"transport", t.name}, {"state", t.up ? "up" : "down"}};
    if (!t.up) {
      j["reason"] = t.reason;
      j["failed_attempts"] = t.failures;
      j["down_ms"] = std::chrono::duration_cast<std::chrono::milliseconds>(t.down_for).count();
      j["next_attempt_ms"] =
          t.next_attempt_in ? json(std::chrono::duration_cast<std::chrono::milliseconds>(*t.next_attempt_in).count())
                            : json(nullptr);  // null: an attempt is running
    }
    out.push_back(std::move(j));
  }
  return out;
}

json status_report(const Gateway& gw, const mapping::Config& config, const StatusContext& at) {
  json subs = json::array();
  for (const auto& s : config.subdevices) subs.push_back(subdevice_json(gw, s, at.now));
  json fes = json::array();
  for (const auto& fe : gw.fes()) fes.push_back(fe_json(gw, fe));
  const sd::NetworkCounters& n = gw.downstream().counters();
  const canopen::SdoPacer& pacer = gw.master().sdo_pacer();
  json report{{"mapping_file", config.file},
              {"uptime_ms", ms_between(at.started, at.now)},
              {"upstream", upstream_json(gw, config, at.now)},
              {"downstream",
               json{{"interface", config.downstream.interface},
                    {"network_id", config.downstream.network_id},
                    {"counters", json{{"unknown_pdo", n.unknown_pdo},
                                      {"unknown_emcy", n.unknown_emcy},
                                      {"reboots_seen", n.reboots_seen},
                                      {"gateway_resets", n.gateway_resets}}},
                    {"sdo_pacing", json{{"gap_us", pacer.gap().count()}, {"delayed_starts", pacer.delayed_starts()}}}}},
              {"subdevices", subs},
              {"functional_elements", fes},
              {"commands",
               json{{"refused", gw.refused_commands()}, {"subdevice_refused", gw.subdevice_refused_commands()}}}};
  if (at.upstream_bus != nullptr) report["upstream"]["bus"] = bus_json(*at.upstream_bus);
  if (at.downstream_bus != nullptr) report["downstream"]["bus"] = bus_json(*at.downstream_bus);
  return report;
}

}  // namespace oegw::gateway::control
