#include "gateway/control/ctl_service.hpp"

#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>

namespace oegw::gateway {

using canopen::SdoAbortCode;
using nlohmann::json;

// One SDO transfer of a client: its RemoteSdo ticket, its time-out, its answer (once).
struct CtlService::Transfer {
  RemoteSdo::Ticket ticket = 0;
  canopen::EventLoop::TimerId timer = 0;
  ControlProtocol::Done done;
  bool finished = false;
};

namespace {

// A request's unsigned integer field in [lo, hi] (std::invalid_argument: a `failed` answer
// naming the field).
std::uint64_t field(const json& r, const char* key, std::uint64_t lo, std::uint64_t hi) {
  const auto it = r.find(key);
  if (it == r.end() || !it->is_number_unsigned() || it->get<std::uint64_t>() < lo || it->get<std::uint64_t>() > hi)
    throw std::invalid_argument(fmt::format("\"{}\": expected an integer {}..{}", key, lo, hi));
  return it->get<std::uint64_t>();
}

std::vector<std::uint8_t> from_hex(const json& r) {
  const auto it = r.find("data");
  if (it == r.end() || !it->is_string()) throw std::invalid_argument("\"data\": expected the value's bytes in hex");
  std::string why;
  auto bytes = bytes_from_hex(it->get_ref<const std::string&>(), why);
  if (!bytes || bytes->empty()) throw std::invalid_argument("\"data\": " + (bytes ? std::string("at least one byte") : why));
  return *bytes;
}

// A CiA 309-3 internal error (canopen/309/ascii_gateway.hpp: 100 not supported, 102 internal
// state, 106 unsupported net, 107 unsupported node) with the gateway's reason.
json gateway_error(int code, std::string message) { return json{{"gateway_error", code}, {"message", std::move(message)}}; }

}  // namespace

CtlService::CtlService(canopen::EventLoop& loop, Gateway& gw, const mapping::Config& config, ControlProtocol& protocol,
                       std::function<void()> rearm)
    : loop_(loop), gw_(gw), config_(config), rearm_(std::move(rearm)) {
  protocol.add_async("sdo_read", [this](const json& r, ControlProtocol::Done done) { sdo(r, false, std::move(done)); });
  protocol.add_async("sdo_write", [this](const json& r, ControlProtocol::Done done) { sdo(r, true, std::move(done)); });
  protocol.add("nmt", [this](const json& r) { return nmt(r); });
  protocol.add("info", [this](const json&) { return info(); });
  protocol.add("events", [this](const json& r) { return events(r); });
  const std::uint8_t down = config_.downstream.network_id;
  gw_.on_downstream_boot_up = [this, down](canopen::NodeId n) {
    record(json{{"network", down}, {"node", n.value()}, {"kind", "boot_up"}});
  };
  gw_.on_downstream_emcy = [this, down](const canopen::EmcyMessage& e) {
    record(json{{"network", down},
                {"node", e.node.value()},
                {"kind", "emcy"},
                {"code", e.code},
                {"error_register", e.error_register},
                {"data", std::vector<unsigned>(e.msef.begin(), e.msef.end())}});
  };
}

CtlService::~CtlService() {
  gw_.on_downstream_boot_up = nullptr;
  gw_.on_downstream_emcy = nullptr;
  for (const auto& t : transfers_) {
    if (t->timer != 0) loop_.cancel(t->timer);
    t->finished = true;
    gw_.remote_sdo(loop_.now()).cancel(t->ticket, SdoAbortCode::GeneralError);
  }
}

void CtlService::record(json event) {
  event["seq"] = next_event_++;
  events_.push_back(std::move(event));
  if (events_.size() > kMaxEvents) events_.pop_front();
}

json CtlService::events(const json& r) const {
  const std::uint64_t last = next_event_ - 1;
  if (!r.contains("after")) return json{{"events", json::array()}, {"last", last}, {"lost", 0}};
  const std::uint64_t after = field(r, "after", 0, ~std::uint64_t{0});
  json list = json::array();
  for (const auto& e : events_)
    if (e["seq"].get<std::uint64_t>() > after) list.push_back(e);
  const std::uint64_t oldest = events_.empty() ? next_event_ : events_.front()["seq"].get<std::uint64_t>();
  const std::uint64_t lost = oldest > after + 1 && after < last ? oldest - after - 1 : 0;
  return json{{"events", std::move(list)}, {"last", last}, {"lost", lost}};
}

json CtlService::info() const {
  const auto& od = const_cast<Gateway&>(gw_).upstream().od();
  return json{{"vendor_id", od.get<std::uint32_t>(0x1018, 1)},
              {"product_code", od.get<std::uint32_t>(0x1018, 2)},
              {"revision", od.get<std::uint32_t>(0x1018, 3)},
              {"serial", od.get<std::uint32_t>(0x1018, 4)},
              {"gateway_class", 3},  // CiA 309-1 class 3: SDO, NMT master services
              {"upstream_network", config_.upstream.network_id},
              {"downstream_network", config_.downstream.network_id}};
}

json CtlService::nmt(const json& r) {
  const auto net = field(r, "network", 1, 127);
  const auto node = field(r, "node", 1, 127);
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
  if (net == config_.upstream.network_id)
    return gateway_error(100, fmt::format("network {} is the host's bus: the gateway's own NMT state is its NMT master's", net));
  if (net != config_.downstream.network_id)
    return gateway_error(106, fmt::format("network {}: this gateway has {} (upstream, its own dictionary) and {} (downstream, "
                                          "the sub-devices)",
                                          net, config_.upstream.network_id, config_.downstream.network_id));
  const std::string why = gw_.downstream_nmt(canopen::NodeId{static_cast<std::uint8_t>(node)}, cs, loop_.now());
  if (rearm_) rearm_();
  if (!why.empty()) return gateway_error(102, why);
  return json::object();
}

void CtlService::sdo(const json& r, bool write, ControlProtocol::Done done) {
  const auto net = field(r, "network", 1, 127);
  const auto node = field(r, "node", 1, 127);
  const auto index = static_cast<std::uint16_t>(field(r, "index", 0, 0xFFFF));
  const auto sub = static_cast<std::uint8_t>(field(r, "sub", 0, 0xFF));
  const std::uint64_t timeout_ms = r.contains("timeout_ms") ? field(r, "timeout_ms", 1, kMaxTimeoutMs) : 0;
  const std::vector<std::uint8_t> data = write ? from_hex(r) : std::vector<std::uint8_t>{};
  const auto answer = [](SdoAbortCode code, const std::vector<std::uint8_t>& bytes, bool with_data) {
    json j{{"abort", static_cast<std::uint32_t>(code)}};
    if (with_data && code == SdoAbortCode::None) j["data"] = bytes_to_hex(bytes);
    return j;
  };

  if (net == config_.upstream.network_id) {
    // The gateway's own dictionary, as its SDO server reads and writes it.
    const std::uint8_t self = gw_.upstream().node().node_id().value();
    if (node != self)
      return done(gateway_error(107, fmt::format("network {} is the host's bus: only the gateway itself, node {}, is "
                                                 "reached there",
                                                 net, self)));
    auto& od = gw_.upstream().od();
    if (write) {
      const SdoAbortCode code = od.write(index, sub, data, canopen::Origin::Sdo);
      if (rearm_) rearm_();
      return done(answer(code, {}, false));
    }
    std::vector<std::uint8_t> out;
    const SdoAbortCode code = od.read(index, sub, out, canopen::Origin::Sdo);
    return done(answer(code, out, true));
  }
  if (net != config_.downstream.network_id)
    return done(gateway_error(106, fmt::format("network {}: this gateway has {} (upstream, its own dictionary) and {} "
                                               "(downstream, the sub-devices)",
                                               net, config_.upstream.network_id, config_.downstream.network_id)));

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
  const canopen::SdoTarget target{config_.downstream.network_id, static_cast<std::uint8_t>(node)};
  RemoteSdo& remote = gw_.remote_sdo(loop_.now());
  t->ticket = write ? remote.download(target, index, sub, data, true, std::move(finish))
                    : remote.upload(target, index, sub, std::move(finish));
  if (!t->finished && timeout_ms != 0) {
    t->timer = loop_.call_after(std::chrono::milliseconds(timeout_ms), [this, complete, answer, weak] {
      const auto tr = weak.lock();
      if (!tr || tr->finished) return;
      tr->timer = 0;
      tr->finished = true;  // cancel() calls no done; answer here
      gw_.remote_sdo(loop_.now()).cancel(tr->ticket, SdoAbortCode::Timeout);
      tr->finished = false;
      complete(tr, answer(SdoAbortCode::Timeout, {}, false));
      if (rearm_) rearm_();
    });
  }
  if (rearm_) rearm_();
}

}  // namespace oegw::gateway
