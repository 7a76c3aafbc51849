#include "gateway/control/ctl_service.hpp"

#include <algorithm>
#include <array>
#include <stdexcept>

#include <fmt/format.h>

namespace oegw::gateway::control {

using canopen::SdoAbortCode;
using nlohmann::json;

// One SDO transfer of a client: its RemoteSdo ticket, its time-out, its answer (once).
struct CtlService::Transfer {
  RemoteSdo::Ticket ticket = 0;
  canopen::io::EventLoop::TimerId timer = 0;
  ControlProtocol::Done done;
  bool finished = false;
};

namespace {

std::vector<std::uint8_t> from_hex(const json& r) {
  const auto it = r.find("data");
  if (it == r.end() || !it->is_string()) throw std::invalid_argument("\"data\": expected the value's bytes in hex");
  std::string why;
  auto bytes = bytes_from_hex(it->get_ref<const std::string&>(), why);
  if (!bytes || bytes->empty())
    throw std::invalid_argument("\"data\": " + (bytes ? std::string("at least one byte") : why));
  return *bytes;
}

// A request's array of N 32-bit numbers (std::invalid_argument naming the field and `what`).
template <std::size_t N>
std::array<std::uint32_t, N> u32_list(const json& r, const char* key, const char* what) {
  const auto it = r.find(key);
  std::array<std::uint32_t, N> v{};
  const auto bad = [&] {
    return std::invalid_argument(fmt::format("\"{}\": expected [{}], integers 0..4294967295", key, what));
  };
  if (it == r.end() || !it->is_array() || it->size() != N) throw bad();
  for (std::size_t i = 0; i < N; ++i) {
    if (!(*it)[i].is_number_unsigned() || (*it)[i].get<std::uint64_t>() > 0xFFFFFFFF) throw bad();
    v[i] = (*it)[i].get<std::uint32_t>();
  }
  return v;
}
constexpr const char* kAddressParts = "vendor, product, revision, serial";

// A CiA 309-3 internal error (canopen/309/ascii_gateway.hpp: 100 not supported, 102 internal
// state, 106 unsupported net, 107 unsupported node) with the gateway's reason.
json gateway_error(int code, std::string message) {
  return json{{"gateway_error", code}, {"message", std::move(message)}};
}

// Gives a request's answer unless it was given already (CtlService::lss_pending_): the LSS
// master's result and a reload's 102 may both come, the client gets the first.
void answer_once(ControlProtocol::Done& pending, json j) {
  if (!pending) return;
  auto d = std::move(pending);
  pending = nullptr;
  d(std::move(j));
}

// CiA 309-3 error 106 (unsupported network) for a network number that is neither of the mapping file's.
json unknown_network(const mapping::Config& c, std::uint64_t net) {
  return gateway_error(106, fmt::format("network {}: this gateway has {} (upstream, its own dictionary) and {} "
                                        "(downstream, the sub-devices)",
                                        net, c.upstream.network_id, c.downstream.network_id));
}

}  // namespace

CtlService::CtlService(canopen::io::EventLoop& loop, Gateway& gw, const mapping::Config& config,
                       ControlProtocol& protocol, std::function<void()> rearm)
    : loop_(loop), gw_(&gw), config_(&config), rearm_(std::move(rearm)) {
  protocol.add_async("sdo_read", [this](const json& r, ControlProtocol::Done done) { sdo(r, false, std::move(done)); });
  protocol.add_async("sdo_write", [this](const json& r, ControlProtocol::Done done) { sdo(r, true, std::move(done)); });
  protocol.add("nmt", [this](const json& r) { return nmt(r); });
  protocol.add_async("lss", [this](const json& r, ControlProtocol::Done done) { lss(r, std::move(done)); });
  protocol.add("info", [this](const json&) { return info(); });
  protocol.add("events", [this](const json& r) { return events(r); });
  hook();
}

void CtlService::hook() {
  const std::uint8_t down = config_->downstream.network_id;
  gw_->on_downstream_boot_up = [this, down](canopen::NodeId n) {
    record(json{{"network", down}, {"node", n.value()}, {"kind", "boot_up"}});
  };
  gw_->on_downstream_emcy = [this, down](const canopen::EmcyMessage& e) {
    record(json{{"network", down},
                {"node", e.node.value()},
                {"kind", "emcy"},
                {"code", e.code},
                {"error_register", e.error_register},
                {"data", std::vector<unsigned>(e.msef.begin(), e.msef.end())}});
  };
}

CtlService::~CtlService() {
  *alive_ = false;
  unhook("the control service ended", std::nullopt);
}

void CtlService::unhook(const char* why, std::optional<SdoAbortCode> answer_transfers) {
  if (auto* fs = gw_->downstream().client_fastscan(); fs != nullptr && fastscan_client_) fs->cancel(why);
  if (auto* ss = gw_->downstream().client_slowscan(); ss != nullptr && slowscan_client_) ss->cancel(why);
  gw_->on_downstream_boot_up = nullptr;
  gw_->on_downstream_emcy = nullptr;
  for (const auto& t : std::vector<std::shared_ptr<Transfer>>(transfers_)) {
    if (t->timer != 0) loop_.cancel(t->timer);
    t->finished = true;
    gw_->remote_sdo(loop_.now()).cancel(t->ticket, SdoAbortCode::GeneralError);
    if (answer_transfers) t->done(json{{"abort", static_cast<std::uint32_t>(*answer_transfers)}});
  }
  transfers_.clear();
  if (answer_transfers) {
    for (const auto& p : std::vector<std::shared_ptr<ControlProtocol::Done>>(lss_pending_))
      answer_once(*p, gateway_error(102, std::string(why) + ": the LSS request ended unanswered; send it again"));
  }
  lss_pending_.clear();
}

void CtlService::detach() {
  // As RemoteSdo answers a transfer the gateway takes back: 0800 0022h (present device state).
  unhook("the gateway reloads its mapping file", SdoAbortCode::CannotTransferDeviceState);
}

void CtlService::attach(Gateway& gw, const mapping::Config& config) {
  gw_ = &gw;
  config_ = &config;
  hook();
}

void CtlService::record(json event) {
  event["seq"] = next_event_++;
  events_.push_back(std::move(event));
  if (events_.size() > kMaxEvents) events_.pop_front();
}

json CtlService::events(const json& r) const {
  const std::uint64_t last = next_event_ - 1;
  if (!r.contains("after")) return json{{"events", json::array()}, {"last", last}, {"lost", 0}};
  const std::uint64_t after = request_field(r, "after", 0, ~std::uint64_t{0});
  json list = json::array();
  for (const auto& e : events_)
    if (e["seq"].get<std::uint64_t>() > after) list.push_back(e);
  const std::uint64_t oldest = events_.empty() ? next_event_ : events_.front()["seq"].get<std::uint64_t>();
  const std::uint64_t lost = oldest > after + 1 && after < last ? oldest - after - 1 : 0;
  return json{{"events", std::move(list)}, {"last", last}, {"lost", lost}};
}

json CtlService::info() const {
  const auto& od = gw_->upstream().od();
  return json{{"vendor_id", od.get<std::uint32_t>(0x1018, 1)},
              {"product_code", od.get<std::uint32_t>(0x1018, 2)},
              {"revision", od.get<std::uint32_t>(0x1018, 3)},
              {"serial", od.get<std::uint32_t>(0x1018, 4)},
              {"gateway_class", 3},  // CiA 309-1 class 3: SDO, NMT master services
              {"upstream_network", config_->upstream.network_id},
              {"downstream_network", config_->downstream.network_id},
              {"downstream_interface", config_->downstream.interface}};  // `oegw scan` (scan_service.hpp)
}

json CtlService::nmt(const json& r) {
  const auto net = request_field(r, "network", 1, 127);
  const auto node = request_field(r, "node", 1, 127);
  const auto it = r.find("service");
  if (it == r.end() || !it->is_string())
    throw std::invalid_argument("\"service\": expected start, stop, preop, reset_node or reset_comm");
  const std::string s = it->get<std::string>();
  canopen::NmtCommand cs{};
  if (s == "start") cs = canopen::NmtCommand::Start;
  else if (s == "stop") cs = canopen::NmtCommand::Stop;
  else if (s == "preop") cs = canopen::NmtCommand::EnterPreOperational;
  else if (s == "reset_node") cs = canopen::NmtCommand::ResetNode;
  else if (s == "reset_comm") cs = canopen::NmtCommand::ResetCommunication;
  else throw std::invalid_argument("\"service\": '" + s + "' is none of start, stop, preop, reset_node, reset_comm");
  if (net == config_->upstream.network_id)
    return gateway_error(100,
                         fmt::format("network {} is the host's bus: the gateway's own NMT state is its NMT master's",
                                     net));
  if (net != config_->downstream.network_id) return unknown_network(*config_, net);
  const std::string why = gw_->downstream_nmt(canopen::NodeId{static_cast<std::uint8_t>(node)}, cs, loop_.now());
  if (rearm_) rearm_();
  if (!why.empty()) return gateway_error(102, why);
  return json::object();
}

namespace {

// The CiA 309-3 answer of an LSS request the slave answered with an error code (CiA 305: 11h,
// 13h, 17h), or that timed out; `what` names the request.
json lss_failure(const canopen::LssMaster::Result& r, const char* what, int refused_code, int second_code = 0) {
  using Status = canopen::LssMaster::Status;
  if (r.status == Status::Timeout || r.status == Status::NoAnswer)
    return gateway_error(103, fmt::format("no LSS slave answered {} (none in LSS configuration mode?)", what));
  if (r.error == 0xFF)
    return gateway_error(501,
                         fmt::format("{} refused with the implementation-specific error {}", what, r.specific_error));
  const int code = r.error == 2 && second_code != 0 ? second_code : refused_code;
  return gateway_error(code, fmt::format("{} refused with LSS error code {}", what, r.error));
}

}  // namespace

// One `lss` request on its way to the LSS master: what its sub-command's handler needs.
struct CtlService::LssCall {
  const json& request;
  subdevices::NetworkManager& network;
  canopen::LssMaster& master;
  canopen::TimePoint now;
  std::weak_ptr<bool> alive;
  std::function<void(json)> done;    // answers now (a refusal before the master is asked)
  std::function<void(json)> answer;  // answers unless the service is ending (its destructor cancels a fastscan) or gone

  // The master's result as the answer: {} when done, else the CiA 309-3 error (lss_failure).
  [[nodiscard]] canopen::LssMaster::Callback ok_or(const char* what, int refused_code, int second_code = 0) const {
    return [answer = answer, what, refused_code, second_code](const canopen::LssMaster::Result& res) {
      answer(res.status == canopen::LssMaster::Status::Ok ? json::object()
                                                          : lss_failure(res, what, refused_code, second_code));
    };
  }
};

void CtlService::lss(const json& r, ControlProtocol::Done first_done) {
  // One answer per request, whoever gives it first: the LSS master's result, or a reload
  // (unhook) that ends the gateway whose master would have given it.
  std::erase_if(lss_pending_, [](const auto& p) { return !*p; });
  auto pending = std::make_shared<ControlProtocol::Done>(std::move(first_done));
  lss_pending_.push_back(pending);
  auto done = [pending](json j) { answer_once(*pending, std::move(j)); };
  const auto net = request_field(r, "network", 1, 127);
  const auto it = r.find("service");
  if (it == r.end() || !it->is_string())
    throw std::invalid_argument(
        "\"service\": expected switch_global, switch_selective, set_node, conf_bitrate, activate_bitrate, store, "
        "inquire_address, inquire_node, identify_non_configured or fastscan");
  const std::string s = it->get<std::string>();
  if (net == config_->upstream.network_id)
    return done(
        gateway_error(100, fmt::format("network {} is the host's bus: LSS is served on the downstream network {} "
                                       "only (the gateway is no LSS master upstream)",
                                       net, config_->downstream.network_id)));
  if (net != config_->downstream.network_id) return done(unknown_network(*config_, net));
  auto& network = gw_->downstream();
  canopen::LssMaster* master = network.client_lss();
  if (master == nullptr)
    return done(gateway_error(102, "the gateway is commissioning a device by LSS itself; try again when it is done"));
  const std::weak_ptr<bool> alive = alive_;
  const LssCall call{r, network, *master, loop_.now(), alive, done, [alive, done](json j) {
                       if (const auto a = alive.lock(); !a || !*a) return;
                       done(std::move(j));
                     }};
  gw_->log_control(fmt::format("LSS {} on network {}", s, net));
  // A handler per sub-command; each answers true when it asked the master (the loop is rearmed).
  static const struct {
    const char* service;
    bool (CtlService::*handle)(const LssCall&);
  } kServices[] = {{"switch_global", &CtlService::lss_switch_global},
                   {"switch_selective", &CtlService::lss_switch_selective},
                   {"set_node", &CtlService::lss_set_node},
                   {"conf_bitrate", &CtlService::lss_conf_bitrate},
                   {"activate_bitrate", &CtlService::lss_activate_bitrate},
                   {"store", &CtlService::lss_store},
                   {"inquire_node", &CtlService::lss_inquire_node},
                   {"inquire_address", &CtlService::lss_inquire_address},
                   {"identify_non_configured", &CtlService::lss_identify_non_configured},
                   {"fastscan", &CtlService::lss_fastscan},
                   {"identify_remote", &CtlService::lss_identify_remote},
                   {"slowscan", &CtlService::lss_slowscan}};
  const auto* row =
      std::find_if(std::begin(kServices), std::end(kServices), [&](const auto& e) { return s == e.service; });
  if (row == std::end(kServices))
    throw std::invalid_argument("\"service\": '" + s + "' is no LSS service of this gateway");
  if ((this->*row->handle)(call) && rearm_) rearm_();
}

bool CtlService::lss_switch_global(const LssCall& c) {
  const auto mode = request_field(c.request, "mode", 0, 1);
  c.master.switch_state_global(mode == 1 ? canopen::lss::Mode::Configuration : canopen::lss::Mode::Waiting, c.now,
                               c.ok_or("switch state global", 102));
  return true;
}

bool CtlService::lss_switch_selective(const LssCall& c) {
  const auto v = u32_list<4>(c.request, "address", kAddressParts);
  c.master.switch_state_selective({v[0], v[1], v[2], v[3]}, c.now, c.ok_or("switch state selective", 102));
  return true;
}

bool CtlService::lss_set_node(const LssCall& c) {
  const auto node = request_field(c.request, "node", 1, 255);
  if (node > 127 && node != 255) throw std::invalid_argument("\"node\": expected 1..127, or 255 (none)");
  // A node-ID a configured sub-device uses while it is on the bus would collide at the next
  // reset communication: refused while the network manager has proof of it (starting after
  // its configuration, operational, or refused for what it answered). A missing node cycles
  // through missing, waiting for boot-up and configuring (asking its identity, unanswered):
  // its node-ID may be given — that is how a replacement device gets the node-ID the mapping
  // file expects.
  for (const auto& sub : config_->subdevices) {
    if (sub.node_id != node) continue;
    const auto st = c.network.state(sub.name);
    if (st == subdevices::NodeState::Operational || st == subdevices::NodeState::Starting ||
        st == subdevices::NodeState::Refused) {
      c.done(gateway_error(102, fmt::format("node-ID {} is {}'s, which is on the bus ({}); only a sub-device the "
                                            "gateway holds missing gives its node-ID away",
                                            node, sub.name, subdevices::to_string(st))));
      return false;
    }
  }
  c.master.configure_node_id(canopen::NodeId{static_cast<std::uint8_t>(node)}, c.now,
                             c.ok_or("configure node-ID", 502));
  return true;
}

bool CtlService::lss_conf_bitrate(const LssCall& c) {
  const auto index = static_cast<std::uint8_t>(request_field(c.request, "table_index", 0, 255));
  if (!canopen::lss::standard_bit_rate_kbit(index)) {
    c.done(gateway_error(503, fmt::format("table index {} is not in the CiA 305 table", index)));
    return false;
  }
  c.master.configure_bit_timing(index, c.now, c.ok_or("configure bit timing", 503));
  return true;
}

bool CtlService::lss_activate_bitrate(const LssCall& c) {
  const auto delay = static_cast<std::uint16_t>(request_field(c.request, "delay_ms", 0, 0xFFFF));
  c.master.activate_bit_timing(delay, c.now, c.ok_or("activate bit timing", 102));
  return true;
}

bool CtlService::lss_store(const LssCall& c) {
  c.master.store_configuration(c.now, c.ok_or("store configuration", 504, 505));
  return true;
}

bool CtlService::lss_inquire_node(const LssCall& c) {
  c.master.inquire(canopen::LssMaster::Inquiry::NodeId, c.now,
                   [answer = c.answer](const canopen::LssMaster::Result& res) {
                     answer(res.status == canopen::LssMaster::Status::Ok ? json{{"node", res.value}}
                                                                         : lss_failure(res, "inquire node-ID", 102));
                   });
  return true;
}

bool CtlService::lss_inquire_address(const LssCall& c) {
  using canopen::LssMaster;
  using Status = LssMaster::Status;
  static constexpr LssMaster::Inquiry kParts[] = {LssMaster::Inquiry::Vendor, LssMaster::Inquiry::Product,
                                                  LssMaster::Inquiry::Revision, LssMaster::Inquiry::Serial};
  if (c.request.contains("part")) {
    const auto part = request_field(c.request, "part", 0, 3);
    c.master.inquire(kParts[part], c.now, [answer = c.answer](const LssMaster::Result& res) {
      answer(res.status == Status::Ok ? json{{"value", res.value}} : lss_failure(res, "inquire identity", 102));
    });
    return true;
  }
  // The four inquiries queued at once (CiA 305 5Ah..5Dh); answered after the last, or at the
  // first that fails.
  auto got = std::make_shared<std::vector<std::uint32_t>>();
  auto failed = std::make_shared<bool>(false);
  for (const auto part : kParts) {
    c.master.inquire(part, c.now, [answer = c.answer, got, failed](const LssMaster::Result& res) {
      if (*failed) return;
      if (res.status != Status::Ok) {
        *failed = true;
        return answer(lss_failure(res, "inquire identity", 102));
      }
      got->push_back(res.value);
      if (got->size() == 4) answer(json{{"address", *got}});
    });
  }
  return true;
}

bool CtlService::lss_identify_non_configured(const LssCall& c) {
  c.master.identify_non_configured(c.now, [answer = c.answer](const canopen::LssMaster::Result& res) {
    answer(res.status == canopen::LssMaster::Status::Ok
               ? json::object()
               : gateway_error(103, "no LSS slave without node-ID answered identify non-configured remote slave"));
  });
  return true;
}

bool CtlService::lss_fastscan(const LssCall& c) {
  const json& r = c.request;
  auto* fastscan = c.network.client_fastscan();
  if (c.network.client_scan_running()) {
    c.done(gateway_error(102, "a fastscan or slowscan of another client is running"));
    return false;
  }
  std::optional<canopen::Duration> step;
  if (r.contains("timeout_ms")) step = std::chrono::milliseconds(request_field(r, "timeout_ms", 1, 0xFFFF));
  canopen::LssFastscan::Known known;
  if (r.contains("known") || r.contains("mask")) {
    const auto value = u32_list<4>(r, "known", kAddressParts);
    known.value = {value[0], value[1], value[2], value[3]};
    known.mask = u32_list<4>(r, "mask", kAddressParts);
  }
  fastscan_client_ = true;
  fastscan->start(
      c.now,
      [this, alive = c.alive, answer = c.answer](const canopen::LssFastscan::Result& f) {
        if (alive.expired()) return;
        fastscan_client_ = false;  // (the destructor is still running when it cancels)
        if (f.address)
          return answer(
              json{{"address", {f.address->vendor, f.address->product, f.address->revision, f.address->serial}}});
        answer(gateway_error(f.outcome == canopen::LssFastscan::Outcome::Cancelled ? 102 : 103, f.note));
      },
      step, known);
  return true;
}

namespace {
// identify_remote's and slowscan's range (CiA 305 46h..4Bh).
canopen::lss::AddressRange lss_range(const json& r) {
  const auto v = u32_list<6>(r, "range", "vendor, product, revision low, high, serial low, high");
  return canopen::lss::AddressRange{v[0], v[1], v[2], v[3], v[4], v[5]};
}
}  // namespace

bool CtlService::lss_identify_remote(const LssCall& c) {
  c.master
      .identify_remote_slave(lss_range(c.request), c.now, [answer = c.answer](const canopen::LssMaster::Result& res) {
        answer(res.status == canopen::LssMaster::Status::Ok
                   ? json::object()
                   : gateway_error(103, "no LSS slave in the range answered identify remote slave"));
      });
  return true;
}

bool CtlService::lss_slowscan(const LssCall& c) {
  const auto range = lss_range(c.request);
  auto* slowscan = c.network.client_slowscan();
  if (c.network.client_scan_running()) {
    c.done(gateway_error(102, "a fastscan or slowscan of another client is running"));
    return false;
  }
  slowscan_client_ = true;
  slowscan->start(range, c.now, [this, alive = c.alive, answer = c.answer](const canopen::LssSlowscan::Result& f) {
    if (alive.expired()) return;
    slowscan_client_ = false;
    if (f.address)
      return answer(json{{"address", {f.address->vendor, f.address->product, f.address->revision, f.address->serial}}});
    answer(gateway_error(f.outcome == canopen::LssSlowscan::Outcome::Cancelled ? 102 : 103, f.note));
  });
  return true;
}

void CtlService::sdo(const json& r, bool write, ControlProtocol::Done done) {
  const auto net = request_field(r, "network", 1, 127);
  const auto node = request_field(r, "node", 1, 127);
  const auto index = static_cast<std::uint16_t>(request_field(r, "index", 0, 0xFFFF));
  const auto sub = static_cast<std::uint8_t>(request_field(r, "sub", 0, 0xFF));
  const std::uint64_t timeout_ms = r.contains("timeout_ms") ? request_field(r, "timeout_ms", 1, kMaxTimeoutMs) : 0;
  const std::vector<std::uint8_t> data = write ? from_hex(r) : std::vector<std::uint8_t>{};
  const auto answer = [](SdoAbortCode code, const std::vector<std::uint8_t>& bytes, bool with_data) {
    json j{{"abort", static_cast<std::uint32_t>(code)}};
    if (with_data && code == SdoAbortCode::None) j["data"] = bytes_to_hex(bytes);
    return j;
  };

  if (net == config_->upstream.network_id) {
    // The gateway's own dictionary, as its SDO server reads and writes it.
    const std::uint8_t self = gw_->upstream().node().node_id().value();
    if (node != self)
      return done(gateway_error(107, fmt::format("network {} is the host's bus: only the gateway itself, node {}, is "
                                                 "reached there",
                                                 net, self)));
    auto& od = gw_->upstream().od();
    if (write) {
      const SdoAbortCode code = od.write(index, sub, data, canopen::Origin::Sdo);
      if (rearm_) rearm_();
      return done(answer(code, {}, false));
    }
    std::vector<std::uint8_t> out;
    const SdoAbortCode code = od.read(index, sub, out, canopen::Origin::Sdo);
    return done(answer(code, out, true));
  }
  if (net != config_->downstream.network_id) return done(unknown_network(*config_, net));

  // A sub-device: the host's remote SDO path (RemoteSdo), with its policy.
  auto t = std::make_shared<Transfer>();
  t->done = std::move(done);
  transfers_.push_back(t);
  const auto complete = [this](const std::shared_ptr<Transfer>& tr, json fields) {
    if (tr->finished) return;
    tr->finished = true;
    if (tr->timer != 0) loop_.cancel(tr->timer);
    tr->timer = 0;
    transfers_.erase(std::remove(transfers_.begin(), transfers_.end(), tr), transfers_.end());
    tr->done(std::move(fields));
  };
  const std::weak_ptr<Transfer> weak = t;
  auto finish = [complete, answer, weak, write](SdoAbortCode code, std::vector<std::uint8_t> bytes) {
    if (const auto tr = weak.lock()) complete(tr, answer(code, bytes, !write));
  };
  const canopen::SdoTarget target{config_->downstream.network_id, static_cast<std::uint8_t>(node)};
  const canopen::TimePoint now = loop_.now();
  RemoteSdo& remote = gw_->remote_sdo(now);
  t->ticket = write ? remote.download(target, index, sub, data, true, now, std::move(finish))
                    : remote.upload(target, index, sub, now, std::move(finish));
  if (!t->finished && timeout_ms != 0) {
    t->timer = loop_.call_after(std::chrono::milliseconds(timeout_ms), [this, complete, answer, weak] {
      const auto tr = weak.lock();
      if (!tr || tr->finished) return;
      tr->timer = 0;
      tr->finished = true;  // cancel() calls no done; answer here
      gw_->remote_sdo(loop_.now()).cancel(tr->ticket, SdoAbortCode::Timeout);
      tr->finished = false;
      complete(tr, answer(SdoAbortCode::Timeout, {}, false));
      if (rearm_) rearm_();
    });
  }
  if (rearm_) rearm_();
}

}  // namespace oegw::gateway::control
