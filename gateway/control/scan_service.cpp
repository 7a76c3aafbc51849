#include "gateway/control/scan_service.hpp"

#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>

namespace oegw::gateway::control {

using nlohmann::json;
namespace sd = subdevices;

namespace {

// The inverse of canopen::to_string(NmtState).
std::optional<canopen::NmtState> state_from(const std::string& s) {
  using canopen::NmtState;
  for (const NmtState n :
       {NmtState::Initialisation, NmtState::Stopped, NmtState::Operational, NmtState::PreOperational})
    if (canopen::to_string(n) == s) return n;
  return std::nullopt;
}

template <class T>
void put(json& j, const char* key, const std::optional<T>& v) {
  if (v) j[key] = *v;
}

// A field of an answer that must be there with its type (std::invalid_argument naming it).
template <class T>
T need(const json& j, const char* key) {
  const auto it = j.find(key);
  if (it == j.end()) throw std::invalid_argument(fmt::format("\"{}\" missing", key));
  try {
    return it->get<T>();
  } catch (const json::exception&) {
    throw std::invalid_argument(fmt::format("\"{}\": wrong type", key));
  }
}

template <class T>
std::optional<T> maybe(const json& j, const char* key) {
  if (!j.contains(key)) return std::nullopt;
  return need<T>(j, key);
}

json progress_json(const sd::ScanProgress& p) {
  return json{{"probed", p.probed}, {"total", p.total}, {"found", p.found}, {"lss", p.lss}};
}

}  // namespace

json scan_result_json(const sd::ScanResult& r) {
  json nodes = json::array();
  for (const sd::ScannedNode& n : r.nodes) {
    json j{{"node", n.node.value()}, {"answered_sdo", n.answered_sdo}, {"heard", n.heard},
           {"booted", n.booted},     {"family", n.family.family},      {"family_reason", n.family.reason}};
    if (n.state) j["state"] = canopen::to_string(*n.state);
    put(j, "device_type", n.identity.device_type);
    put(j, "vendor_id", n.identity.vendor_id);
    put(j, "product_code", n.identity.product_code);
    put(j, "revision", n.identity.revision);
    put(j, "serial", n.identity.serial);
    put(j, "producer_heartbeat_ms", n.producer_heartbeat_ms);
    if (n.heartbeat_period)
      j["heartbeat_period_us"] = std::chrono::duration_cast<std::chrono::microseconds>(*n.heartbeat_period).count();
    if (!n.configured_as.empty()) j["configured_as"] = n.configured_as;
    if (!n.gateway_state.empty()) j["gateway_state"] = n.gateway_state;
    nodes.push_back(std::move(j));
  }
  json out{{"nodes", std::move(nodes)}, {"unconfigured", r.unconfigured}, {"lss_note", r.lss_note}};
  if (const auto& a = r.unconfigured_address)
    out["unconfigured_address"] =
        json{{"vendor", a->vendor}, {"product", a->product}, {"revision", a->revision}, {"serial", a->serial}};
  return out;
}

std::optional<sd::ScanResult> scan_result_from_json(const json& j, std::string& error) {
  try {
    if (!j.is_object()) throw std::invalid_argument("expected an object");
    sd::ScanResult r;
    for (const json& n : need<json>(j, "nodes")) {
      if (!n.is_object()) throw std::invalid_argument("a node: expected an object");
      sd::ScannedNode s;
      const auto id = need<unsigned>(n, "node");
      if (id < 1 || id > 127) throw std::invalid_argument(fmt::format("\"node\": {} is no node-ID", id));
      s.node = canopen::NodeId{static_cast<std::uint8_t>(id)};
      s.answered_sdo = need<bool>(n, "answered_sdo");
      s.heard = need<bool>(n, "heard");
      s.booted = need<bool>(n, "booted");
      s.family.family = need<std::string>(n, "family");
      s.family.reason = need<std::string>(n, "family_reason");
      if (const auto st = maybe<std::string>(n, "state")) s.state = state_from(*st);
      s.identity.device_type = maybe<std::uint32_t>(n, "device_type");
      s.identity.vendor_id = maybe<std::uint32_t>(n, "vendor_id");
      s.identity.product_code = maybe<std::uint32_t>(n, "product_code");
      s.identity.revision = maybe<std::uint32_t>(n, "revision");
      s.identity.serial = maybe<std::uint32_t>(n, "serial");
      s.producer_heartbeat_ms = maybe<std::uint16_t>(n, "producer_heartbeat_ms");
      if (const auto us = maybe<std::int64_t>(n, "heartbeat_period_us"))
        s.heartbeat_period = std::chrono::microseconds(*us);
      s.configured_as = maybe<std::string>(n, "configured_as").value_or("");
      s.gateway_state = maybe<std::string>(n, "gateway_state").value_or("");
      r.nodes.push_back(std::move(s));
    }
    r.unconfigured = need<bool>(j, "unconfigured");
    r.lss_note = need<std::string>(j, "lss_note");
    if (const auto a = maybe<json>(j, "unconfigured_address"))
      r.unconfigured_address =
          canopen::lss::Address{need<std::uint32_t>(*a, "vendor"), need<std::uint32_t>(*a, "product"),
                                need<std::uint32_t>(*a, "revision"), need<std::uint32_t>(*a, "serial")};
    return r;
  } catch (const std::invalid_argument& e) {
    error = e.what();
    return std::nullopt;
  }
}

ScanService::ScanService(canopen::io::EventLoop& loop, Gateway& gw, const mapping::Config& config,
                         ControlProtocol& protocol, std::function<void()> rearm)
    : loop_(loop), gw_(&gw), config_(&config), rearm_(std::move(rearm)) {
  protocol.add("scan", [this](const json& r) {
    const auto it = r.find("action");
    const std::string action = it != r.end() && it->is_string() ? it->get<std::string>() : "";
    if (action == "start") return start(r);
    if (action == "status") return status(r);
    throw std::invalid_argument("\"action\": expected start or status");
  });
  hook();
}

void ScanService::hook() {
  // Installed for the service's life (and the gateway's): the scan in progress (if any) sees
  // every frame after the gateway has handled it.
  gw_->on_downstream_frame_seen = [this](const canopen::CanFrame& f, canopen::TimePoint now) {
    if (!scanner_ || scanner_->done()) return;
    scanner_->on_frame(f, now);
    settle();
  };
}

ScanService::~ScanService() {
  gw_->on_downstream_frame_seen = nullptr;
  driver_.reset();
  scanner_.reset();
}

void ScanService::detach() {
  gw_->on_downstream_frame_seen = nullptr;
  if (!scanner_ || scanner_->done()) return;  // a result stays readable
  ended_ = id_;
  gw_->log_control(fmt::format("scan {}: ended by a reload of the mapping file", id_));
  driver_.reset();
  scanner_.reset();  // its fastscan on the old network manager's master cancelled
}

void ScanService::attach(Gateway& gw, const mapping::Config& config) {
  gw_ = &gw;
  config_ = &config;
  hook();
}

json ScanService::start(const json& r) {
  if (scanner_ && !scanner_->done())
    return json{{"gateway_error", 102}, {"message", fmt::format("scan {} is running; ask its status", id_)}};
  sd::ScanConfig cfg;
  const auto ms = [](std::uint64_t v) { return std::chrono::milliseconds(v); };
  cfg.sdo_timeout = ms(request_field_or(r, "timeout_ms", 1, 10000, 100));
  cfg.listen = ms(request_field_or(r, "listen_ms", 0, 600000, 1000));
  cfg.lss_timeout = ms(request_field_or(r, "lss_timeout_ms", 1, 10000, 25));
  cfg.parallel = request_field_or(r, "parallel", 1, 127, 8);
  if (const auto it = r.find("lss"); it != r.end()) {
    if (!it->is_boolean()) throw std::invalid_argument("\"lss\": expected true or false");
    cfg.lss = it->get<bool>();
  }
  for (const mapping::SubdeviceConfig& s : config_->subdevices) cfg.skip.insert(s.node_id);
  driver_.reset();  // (the last scan's: it has no deadline left)
  scanner_ = std::make_unique<sd::BusScanner>([this](const canopen::CanFrame& f) { gw_->send_downstream(f); }, cfg,
                                              [this] {
                                                sd::SharedLss s;
                                                auto& network = gw_->downstream();
                                                s.master = network.client_lss();
                                                s.fastscan = network.client_fastscan();
                                                if (network.own_lss_busy())
                                                  s.why_not = "the gateway's own LSS commissioning is running";
                                                else if (network.client_scan_running())
                                                  s.why_not = "an `oegw ctl` fastscan or slowscan is running";
                                                return s;
                                              });
  result_.reset();
  scanner_->on_wake = [this] { settle(); };
  ++id_;
  gw_->log_control(fmt::format("scan {}: probing the node-IDs of no sub-device ({} skipped){}", id_, cfg.skip.size(),
                               cfg.lss ? ", then LSS" : ""));
  scanner_->start(loop_.now());
  driver_ = std::make_unique<canopen::io::ServiceDriver>(
      loop_, [this] { return scanner_->next_deadline(); },
      [this](canopen::TimePoint now) {
        if (scanner_->done()) return;
        scanner_->advance(now);
        settle();
      });
  if (rearm_) rearm_();
  return json{{"scan", json{{"id", id_}}}};
}

void ScanService::settle() {
  if (scanner_->done() && !result_) {
    const sd::ScanResult r = with_subdevices(scanner_->result());
    result_ = scan_result_json(r);
    gw_->log_control(fmt::format("scan {}: done, {} node(s) found", id_, r.nodes.size()));
  }
  if (driver_) driver_->rearm();  // (not yet made while start() runs)
  if (rearm_) rearm_();
}

sd::ScanResult ScanService::with_subdevices(sd::ScanResult r) const {
  const auto& network = gw_->downstream();
  for (const mapping::SubdeviceConfig& s : config_->subdevices) {
    auto it = std::find_if(r.nodes.begin(), r.nodes.end(),
                           [&](const sd::ScannedNode& n) { return n.node.value() == s.node_id; });
    if (it == r.nodes.end()) {
      sd::ScannedNode n;
      n.node = canopen::NodeId{s.node_id};
      it = r.nodes.insert(std::upper_bound(r.nodes.begin(), r.nodes.end(), n,
                                           [](const sd::ScannedNode& a, const sd::ScannedNode& b) {
                                             return a.node.value() < b.node.value();
                                           }),
                          std::move(n));
    }
    sd::ScannedNode& n = *it;
    n.configured_as = s.name;
    n.gateway_state = std::string(sd::to_string(network.state(s.name)));
    n.family = {s.driver, "the running gateway drives it as " + s.name};
    if (s.heartbeat_ms > 0) n.producer_heartbeat_ms = s.heartbeat_ms;  // what the gateway writes to its 1017h
    if (const sd::NodeDiagnostics* d = network.diagnostics(s.name); d != nullptr && d->vendor_id) {
      // read at the node's last boot (1018h:01 is mandatory: present once the reads ran)
      n.answered_sdo = true;
      n.identity = {d->device_type, d->vendor_id, d->product_code, d->revision, d->serial};
    }
  }
  return r;
}

json ScanService::status(const json& r) const {
  const auto id = request_field(r, "id", 1, UINT64_MAX);
  if (id == id_ && ended_ == id_)
    return json{{"gateway_error", 102},
                {"message", fmt::format("scan {} ended: the gateway reloaded its mapping file; start it again", id)}};
  if (id != id_)
    return json{{"gateway_error", 102},
                {"message", id_ == 0 ? std::string("no scan was started")
                                     : fmt::format("scan {} is not the last one ({})", id, id_)}};
  json s{{"id", id_}, {"running", !result_}, {"progress", progress_json(scanner_->progress())}};
  if (result_) {
    s["result"] = *result_;
    s["downstream"] = json{{"interface", config_->downstream.interface}, {"bitrate", config_->downstream.bitrate}};
    s["upstream"] = json{{"interface", config_->upstream.interface},
                         {"bitrate", config_->upstream.bitrate},
                         {"store", config_->upstream.store}};
  }
  return json{{"scan", std::move(s)}};
}

}  // namespace oegw::gateway::control
