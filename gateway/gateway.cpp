#include "gateway/gateway.hpp"

#include "gateway/runtime_config.hpp"

#include <algorithm>
#include <array>
#include <stdexcept>

#include <fmt/format.h>
#include <fmt/ranges.h>

namespace oegw::gateway {

using canopen::TimePoint;
using subdevices::SignalStatus;
namespace sd = oegw::subdevices;

mapping::SignalCatalogue driver_catalogue() {
  return [](std::string_view family, const sd::DriverOptions& options,
            sd::OptionRefusals& refusals) -> std::optional<std::vector<sd::SignalInfo>> {
    // A driver on node 1 with no bus: only its signal list is wanted.
    auto driver = sd::make_driver(family, canopen::NodeId{1}, {}, options, refusals);
    if (!driver) return std::nullopt;
    return driver->signals();
  };
}

namespace {

SignalStatus worse(SignalStatus a, SignalStatus b) {
  auto rank = [](SignalStatus s) {
    switch (s) {
      case SignalStatus::Valid: return 0;
      case SignalStatus::Stale: return 1;
      case SignalStatus::NotAvailable: return 2;
      case SignalStatus::Error: return 3;
      case SignalStatus::Offline: return 4;
    }
    return 4;
  };
  return rank(a) >= rank(b) ? a : b;
}

// 1016h entries of the downstream master: one per sub-device whose heartbeat is watched (at
// least the 32 it always had, at most the 127 sub-indexes 1016h has). A fixed 32 left the 33rd
// and later sub-devices unwatched: Master::monitor_heartbeat() found no free entry, and a node
// that went silent stayed "operational" with its inputs frozen at their last values.
std::uint8_t heartbeat_entries(const mapping::Config& c) {
  std::size_t n = 0;
  for (const auto& s : c.subdevices) n += s.heartbeat_ms != 0 ? 1 : 0;
  return static_cast<std::uint8_t>(std::clamp<std::size_t>(n, 32, 127));
}

}  // namespace

Gateway::Gateway(const mapping::Config& config, canopen::FrameSink upstream, canopen::FrameSink downstream,
                 GatewayOptions options)
    : Gateway(config, nullptr, std::move(upstream), std::move(downstream), options) {}

Gateway::Gateway(const mapping::Config& config, HandedOver upstream, canopen::FrameSink downstream,
                 GatewayOptions options)
    : Gateway(config, std::move(upstream.device), {}, std::move(downstream), options, std::move(upstream.drivers)) {}

Gateway::Gateway(const mapping::Config& config, std::unique_ptr<OeDevice> handed_over, canopen::FrameSink upstream,
                 canopen::FrameSink downstream, const GatewayOptions& options,
                 std::vector<std::unique_ptr<sd::Driver>> drivers)
    : tap_(options.tap),
      downstream_out_(tapped(Bus::Down, std::move(downstream))),
      config_(config),
      master_(master_od_, downstream_out_,
              canopen::MasterConfig{.heartbeat_entries = heartbeat_entries(config),
                                    .sdo_timeout = options.sdo_timeout.value_or(
                                        std::chrono::milliseconds(config.downstream.sdo_timeout_ms)),
                                    .sync_period = std::chrono::milliseconds(config.downstream.sync_period_ms),
                                    .sdo_request_gap =
                                        canopen::SdoPacer::gap_for(config.downstream.bitrate, options.sdo_bus_share)}),
      network_(master_, options.timing),
      remote_sdo_(std::make_unique<RemoteSdo>(config_, master_, network_, [this] { return oe_->node().node_id(); })),
      oe_(handed_over ? std::move(handed_over)
                      : std::make_unique<OeDevice>(device_config(config_, options.store_path), std::move(upstream))),
      model_(oe_->config().fes) {
  connect_upstream_device();
  // The CiA 852 device mirrors every changed input slot into its dictionary at once.
  model_.on_slot_change([this](mapping::FeId fe, FeSlot slot, std::int64_t v) {
    if (mapping::is_input(fe.kind)) oe_->mirror_input(fe, slot, v, now_);
  });
  arbiter_ = std::make_unique<CommandArbiter>(config_, *oe_, model_);
  arbiter_->log = [this](const std::string& line) { log(line); };
  arbiter_->drive = [this](mapping::FeId fe, FieldRef ref, std::int64_t v) { on_output(fe, ref, v); };
  add_subdevices(std::move(drivers));
  bind_functional_elements();
  hook_network();
  hook_master();
  hook_upstream_device();
}

// The upstream device's hooks: log, tap, store reloads and its SDO server channels.
void Gateway::connect_upstream_device() {
  // Every SDO server channel of the device reaches the sub-devices (remote SDO); a channel the
  // mapping file binds to a sub-device goes nowhere else (gateway/remote_sdo.hpp).
  remote_sdo_->on_log = [this](const std::string& line) { log(line); };
  // What the upstream device sends, to the tap (a handed-over device's too: release_upstream()
  // takes this hook away with it).
  oe_->on_sent([this](const canopen::CanFrame& f) {
    if (tap_ != nullptr) tap_->sent(*this, Bus::Up, f);
  });
  canopen::Node& device = oe_->node();
  // A store refused at a reset is as one refused at power-on (programs.cpp logs that one): the
  // device runs on defaults and the host gets EMCY 6000h; the log says which and why.
  device.on_store_reload = [this](const canopen::ParameterStore::LoadResult& r, bool communication_only) {
    if (!r.ok)
      log(fmt::format("upstream store refused at NMT reset {}: {}; running on defaults, EMCY 6000h sent upstream",
                      communication_only ? "communication" : "node", r.error));
  };
  for (std::size_t k = 0; k < device.sdo_server_count(); ++k) {
    canopen::SdoServer& server = device.sdo_server(k);
    server.set_remote(remote_sdo_.get());
    if (k >= 1 && k <= config_.upstream.sdo_servers.size() && !config_.upstream.sdo_servers[k - 1].subdevice.empty())
      server.bind(remote_sdo_->target_of(config_.upstream.sdo_servers[k - 1].subdevice));
    server.on_redirect = [this, k](const auto& before, const auto& after, canopen::SdoServer::RedirectChange why) {
      log_redirect(k, before, after, why);
    };
  }
}

// A driver per sub-device of the mapping file, in the network manager, with its entry in subs_:
// those `built` beforehand (a reload's: HandedOver) bound to this gateway's downstream, else made.
void Gateway::add_subdevices(std::vector<std::unique_ptr<sd::Driver>> built) {
  if (!built.empty() && built.size() != config_.subdevices.size())
    throw std::logic_error("Gateway: " + std::to_string(built.size()) + " drivers built for " +
                           std::to_string(config_.subdevices.size()) + " sub-devices");
  for (std::size_t k = 0; k < config_.subdevices.size(); ++k) {
    const auto& sc = config_.subdevices[k];
    std::unique_ptr<sd::Driver> driver;
    if (built.empty()) {
      std::string error;
      driver = sd::make_driver(sc.driver, sc.node(), downstream_out_, sc.options, error);
      if (!driver) throw std::runtime_error(sc.where.str() + ": " + error);  // load_config checked it
    } else {
      driver = std::move(built[k]);
      driver->bind_sink(downstream_out_);
    }
    sd::NodeSettings ns = sc.node_settings();
    sd::Driver* d = driver.get();
    network_.add(std::move(ns), std::move(driver));
    const std::size_t n = d->signals().size();
    Sub& s = subs_[sc.name];
    s = Sub{&sc,
            d,
            false,
            false,
            "not booted yet",
            std::vector<std::vector<std::size_t>>(n),
            {},
            {},
            std::vector<std::int64_t>(n, 0)};
    // The sub-device's entry is found once, here: no look-up by name per signal.
    d->on_change = [this, sp = &s](std::size_t i, const sd::SignalValue& v) { on_signal(*sp, i, v); };
    batched_.reserve(config_.subdevices.size());  // no allocation in an output batch
  }
}

// A binding per field of each functional element, indexed by FE, sub-device and signal.
void Gateway::bind_functional_elements() {
  for (const auto& fe : config_.functional_elements) {
    std::size_t group = 0;
    if (fe.input()) {
      group = groups_.size();
      groups_.push_back({fe.id, {}});
    } else {
      output_groups_.push_back({fe.id, std::vector<std::vector<std::size_t>>(mapping::fe_fields(fe.id).size())});
      (void)model_.set_status(fe.id, FeStatus::Valid, {});  // commanded, not fed: always Valid
    }
    const std::size_t first = bindings_.size();
    for (const auto& f : fe.fields) {
      Binding b{fe.id, &f, *field_ref(fe.id, f.field.name), std::nullopt, {}, 0, group, SignalStatus::Offline};
      Sub& s = subs_.at(f.subdevice);
      b.sub = &s;
      b.signal = *s.driver->find_signal(f.signal);
      const std::size_t bi = bindings_.size();
      if (fe.input()) {
        b.translator.emplace(f.input_params());
        s.inputs.push_back(bi);
        groups_.back().inputs.push_back(bi);
      } else {
        b.output = f.output_params();
        s.outputs.push_back(bi);
        output_groups_.back().by_field.at(b.ref.bit).push_back(bi);
      }
      s.by_signal.at(b.signal).push_back(bi);
      bindings_.push_back(std::move(b));
    }
    // The mapping file names each FE once (mapping/sections: "appears twice" is refused).
    if (!fe_bindings_.emplace(fe.id, std::pair{first, bindings_.size()}).second)
      throw std::logic_error(mapping::fe_name(fe.id) + " is configured twice");
  }
}

std::span<const Gateway::Binding> Gateway::bindings_of(mapping::FeId fe) const {
  const auto it = fe_bindings_.find(fe);
  if (it == fe_bindings_.end()) return {};
  return std::span<const Binding>(bindings_).subspan(it->second.first, it->second.second - it->second.first);
}

// The network manager's reports, to the named handlers below.
void Gateway::hook_network() {
  network_.on_node_state = [this](const std::string& name, sd::NodeState st, const std::string& why) {
    on_node_state(name, st, why);
  };
  network_.on_emcy = [this](const std::string& name, const canopen::EmcyMessage& e, const sd::DecodedEmcy& d) {
    on_subdevice_emcy(name, e, d);
  };
  network_.on_fault_evidence = [this](const std::string& name, const std::string& what) {
    on_fault_evidence(name, what);
  };
  network_.on_application_reset = [this](const std::string& name) {
    if (auto it = subs_.find(name); it != subs_.end()) it->second.driver->on_application_reset(now_);
  };
  network_.on_bad_input = [this](const std::string& what) { log(what); };
  network_.on_diagnostics = [this](const std::string& name, const subdevices::NodeDiagnostics& d) {
    log(name + ": boot diagnostics: " + d.describe());
  };
}

void Gateway::on_node_state(const std::string& name, sd::NodeState st, const std::string& why) {
  auto it = subs_.find(name);
  if (it == subs_.end()) return;
  Sub& s = it->second;
  const bool was = s.operational;
  s.operational = st == sd::NodeState::Operational;
  // A fault the driver holds (Driver::faulted) lasts until the device's evidence: its clear
  // code, or its error state read back at the next start (boot_reads). A node lost while its
  // driver holds one is booted again by reset node: reset, it reports the error again if it
  // persists, and the gateway does not wait for a clear code that may have been lost.
  s.why = std::string(sd::to_string(st)) + " (" + why + ")";
  if (tap_ != nullptr) tap_->node_state(name, st, why);
  log(name + ": " + s.why);
  if (s.operational && !was) {
    // Output values commanded meanwhile reach the device now, all in one frame per RPDO.
    begin_outputs();
    for (const std::size_t bi : s.outputs) drive(bindings_[bi], s, model_.read(bindings_[bi].fe, bindings_[bi].ref));
    end_outputs(now_);
  }
  // Only a node that failed (not one still booting for the first time) is a fault; only the
  // proof of life the network manager names (`why`) makes it operational again.
  if ((st == sd::NodeState::Missing || st == sd::NodeState::Refused) && s.driver->any_fault())
    network_.reset_application_next(name);
  // A node that leaves operational for any reason (lost, refused, or its own boot-up: a reboot
  // while in use) has failed until it is operational again: its inputs are in doubt and the
  // host is told now, not when (or if) a reboot loop ever settles.
  if (st == sd::NodeState::Missing || st == sd::NodeState::Refused || (was && !s.operational)) s.failed = true;
  if (s.operational) s.failed = false;
  if (s.failed || s.operational) update_fault(s, why);
  if (reloading_) settle_reload();
}

void Gateway::on_subdevice_emcy(const std::string& name, const canopen::EmcyMessage& e, const sd::DecodedEmcy& d) {
  auto it = subs_.find(name);
  if (it == subs_.end()) return;
  it->second.emcy = EmcyRecord{e, now_, it->second.emcy.count + 1};
  if (tap_ != nullptr) tap_->subdevice_emcy(name, e);
  log(name + ": EMCY " + fmt::format("{:04X}h", e.code) + " " + d.text);
  // Remote EMCY: upstream first, then the 7000h the fault policy may raise for it below.
  const mapping::EmcyForwarding fwd = config_.downstream.emcy_forwarding;
  if (fwd == mapping::EmcyForwarding::All || (fwd == mapping::EmcyForwarding::Faults && (e.code == 0 || d.error)))
    (void)oe_->forward_subdevice_emcy(e, now_);
  // What the EMCY faults or clears is the driver's (d.affected, Driver::faulted): a warning
  // (81xxh) faults nothing, a clear code ends only what it clears.
  update_fault(it->second, fmt::format("EMCY {:04X}h {}", e.code, d.text));
}

// A fault the device ended without an EMCY, shown by the object its driver polls while the
// fault lasts (the MCB-402's 1001h after a cable break,
// docs/design/device-documents.md#mcb-402-mcb402-document-003-co4013-emergency-messages).
void Gateway::on_fault_evidence(const std::string& name, const std::string& what) {
  auto it = subs_.find(name);
  if (it == subs_.end()) return;
  log(name + ": " + what);
  update_fault(it->second, what);
}

// The downstream master's EMCYs and boot-ups: the network manager's handlers first, then the gateway's.
void Gateway::hook_master() {
  // A sub-device's EMCY reaches the host before the 7000h it causes: its driver's decoding
  // (inside the network manager's EMCY handler) already moves signals and so the fault policy,
  // whose fault EMCYs wait (fault_emcy) until network_.on_emcy above has forwarded it.
  master_.on_emcy = [this, decode = std::move(master_.on_emcy)](const canopen::EmcyMessage& e, TimePoint t) {
    decoding_emcy_ = true;
    if (decode) decode(e, t);
    decoding_emcy_ = false;
    for (const auto& [node, raise] : held_fault_emcys_) fault_emcy(*node, raise);  // sent now
    held_fault_emcys_.clear();
    if (on_downstream_emcy) on_downstream_emcy(e);
  };
  // Boot-ups: the network manager's first (it decides what they mean), then the observers'.
  master_.on_boot = [this, manage = std::move(master_.on_boot)](canopen::NodeId n) {
    if (manage) manage(n);
    if (on_downstream_boot_up) on_downstream_boot_up(n);
  };
}

// The upstream device's 3000h writes and the EMCYs of the other upstream nodes.
void Gateway::hook_upstream_device() {
  if (auto* cmd = oe_->od().find(cia852::kSubdeviceCommand))
    command_hook_ =
        cmd->add_write_hook([this](canopen::Object&, std::uint8_t, std::span<const std::uint8_t> b, canopen::Origin) {
          std::uint32_t v = 0;
          for (std::size_t i = 0; i < b.size() && i < 4; ++i) v |= static_cast<std::uint32_t>(b[i]) << (8 * i);
          return host_subdevice_command(v);
        });
  // 1028h: EMCYs of other upstream nodes, logged and kept for the status.
  oe_->on_emcy([this](const canopen::EmcyMessage& m, TimePoint t) { on_upstream_emcy(m, t); });
}

void Gateway::on_upstream_emcy(const canopen::EmcyMessage& m, TimePoint t) {
  EmcyRecord& r = upstream_emcys_[m.node.value()];
  r = EmcyRecord{m, t, r.count + 1};
  log(fmt::format("upstream EMCY from node {:02X}h: {:04X}h register {:02X}h, manufacturer bytes {:02X}",
                  m.node.value(), m.code, m.error_register, fmt::join(m.msef, " ")));
}

canopen::FrameSink Gateway::tapped(Bus bus, canopen::FrameSink sink) {
  return [this, bus, sink = std::move(sink)](const canopen::CanFrame& f) {
    if (tap_ != nullptr) tap_->sent(*this, bus, f);
    sink(f);
  };
}

void Gateway::send_downstream(const canopen::CanFrame& frame) {
  if (tap_ != nullptr) tap_->control("send_downstream", now_);
  master_.sink()(frame);
}

canopen::ParameterStore::LoadResult Gateway::start(TimePoint now) {
  if (tap_ != nullptr) tap_->started(now);
  now_ = now;
  auto r = oe_->start(now);
  arbiter_->start(now);
  // Every input starts at its fault value (the signals are Offline until their node is up),
  // stamped with the time the gateway decided it.
  for (auto& b : bindings_)
    if (b.translator) (void)model_.write(b.fe, b.ref, b.translator->value(), now);
  for (const auto& fe : model_.fes()) model_.stamp(fe, now);
  network_.start(now);
  publish_changes();
  return r;
}

void Gateway::log(const std::string& line) {
  if (tap_ != nullptr) tap_->logged(line);
  if (on_log) on_log(line);
}

std::vector<Gateway::SdoRedirect> Gateway::sdo_redirects() const {
  std::vector<SdoRedirect> out;
  const canopen::Node& device = oe_->node();
  for (std::size_t k = 0; k < device.sdo_server_count(); ++k) {
    const canopen::SdoServer& server = device.sdo_server(k);
    if (!server.redirect()) continue;
    out.push_back({static_cast<std::uint16_t>(0x1200 + k), server.rx_cob_id(), server.tx_cob_id(), *server.redirect(),
                   remote_sdo_->subdevice_at(server.redirect()->target)});
  }
  return out;
}

void Gateway::log_redirect(std::size_t channel, const std::optional<canopen::SdoServer::Redirect>& before,
                           const std::optional<canopen::SdoServer::Redirect>& after,
                           canopen::SdoServer::RedirectChange why) {
  using Change = canopen::SdoServer::RedirectChange;
  const canopen::SdoServer& server = oe_->node().sdo_server(channel);
  const std::string head = fmt::format("remote SDO: SDO server {:04X}h ({:03X}h/{:03X}h)", 0x1200 + channel,
                                       server.rx_cob_id().can_id(), server.tx_cob_id().can_id());
  if (after) {
    const auto& r = after->request;
    log(fmt::format(
        "{} redirected to {} by the network indication {:02X}: every client on {:03X}h now reaches {}, not "
        "the gateway, until a network indication names the gateway (network {}, node {:02X}h, or network 0, "
        "node 0) or the gateway is reset or stopped (NMT){}",
        head, remote_sdo_->describe(after->target), fmt::join(r, " "), server.rx_cob_id().can_id(),
        remote_sdo_->subdevice_at(after->target), config_.upstream.network_id, oe_->node().node_id().value(),
        before ? "; it reached " + remote_sdo_->describe(before->target) + " before" : ""));
    return;
  }
  const char* cause = why == Change::Indication ? "a network indication named the gateway"
                      : why == Change::Reset    ? "NMT reset or stop of the gateway"
                      : why == Change::CobIds   ? "its COB-IDs changed"
                                                : "the channel was reconfigured";
  const double seconds = std::chrono::duration<double>(now_ - before->since).count();
  log(fmt::format("{} reaches the gateway's own dictionary again ({}): its redirect to {} lasted {:.1f} s", head, cause,
                  remote_sdo_->describe(before->target), seconds));
}

void Gateway::feed(Binding& b, const Sub& s, const sd::SignalValue& v, bool decided_now) {
  sd::SignalValue in = v;
  if (s.forced && in.status == SignalStatus::Valid) in.status = SignalStatus::Error;
  const SignalStatus status_before = b.status;
  const std::int64_t fe_value = b.translator->update(in);
  b.status = in.status;
  // The source time: the reception of the frame that carried the value, or now when the
  // gateway decided the value itself (the fault hold and its end, which re-feeds the driver's
  // last values: their frames are older than what the FE has already shown).
  const TimePoint source = !decided_now && in.status == v.status ? v.timestamp : now_;
  (void)model_.write(b.fe, b.ref, fe_value, source);
  if (b.status == status_before) return;
  SignalStatus worst = SignalStatus::Valid;
  bool any = false;
  for (const std::size_t bi : groups_[b.group].inputs) {
    worst = any ? worse(worst, bindings_[bi].status) : bindings_[bi].status;
    any = true;
  }
  (void)model_.set_status(b.fe, static_cast<FeStatus>(static_cast<std::uint8_t>(worst)), now_);
}

void Gateway::on_signal(Sub& s, std::size_t index, const sd::SignalValue& v) {
  // Runs for every changed signal of every PDO: no look-up by name, no allocation.
  if (index < s.by_signal.size())
    for (const std::size_t bi : s.by_signal[index]) {
      Binding& b = bindings_[bi];
      if (b.translator) feed(b, s, v);
    }
  update_fault(s, "fresh PDO");
}

void Gateway::publish_changes() {
  // Also without a consumer: the marks are cleared.
  model_.for_each_changed([this](mapping::FeId fe) {
    if (tap_ != nullptr) tap_->fe_changed(*this, fe);
    if (on_fe_change) on_fe_change(fe);
  });
}

void Gateway::update_fault(Sub& s, std::string_view evidence) {
  // The driver holds the faults its device reported (Driver::faulted): its faulted inputs are
  // Error and at their fault values before the EMCY goes up. While it holds any (also on a
  // signal no FE uses, an LED), the node is faulty and every input of it is held at its fault
  // value: a device that reports a fault is in doubt as a whole. When the driver clears its
  // last fault (on the device's evidence) they are fed again from the driver's current values,
  // through the neutral interlock. The hold is the driver's state, not a latch of the gateway.
  const bool forced = s.operational && s.driver->any_fault();
  if (forced != s.forced) {
    s.forced = forced;
    for (const std::size_t bi : s.inputs) feed(bindings_[bi], s, s.driver->value(bindings_[bi].signal), true);
  }
  // A bound input in Error / NotAvailable / Stale counts; Offline is the node's own state. The
  // cause is found without building text: this runs for every PDO, and the reason string is
  // made only when the cause changes (no allocation per frame while a fault lasts).
  // A node booting for the first time is not faulty (its fields are at their fault values,
  // Offline): an EMCY or a signal change meanwhile (the MCB-402's power-on 8100h) does not make
  // it so; only its state does (on_node_state: missing, refused, or leaving operational).
  if (!s.operational && !s.failed && s.cause.kind == Cause::Kind::None) return;
  const Cause cause = [&] {
    if (!s.operational) return Cause{Cause::Kind::State, 0, SignalStatus::Offline};
    if (s.driver->any_fault()) return Cause{Cause::Kind::Emcy, 0, SignalStatus::Error};
    for (const std::size_t bi : s.inputs) {  // this sub-device's input bindings only (per PDO)
      const SignalStatus st = bindings_[bi].status;
      if (st == SignalStatus::Error || st == SignalStatus::NotAvailable || st == SignalStatus::Stale)
        return Cause{Cause::Kind::Input, bi, st};
    }
    return Cause{};
  }();
  const std::string& name = s.config->name;
  const bool was = s.cause.kind != Cause::Kind::None;
  if (cause == s.cause && cause.kind != Cause::Kind::State) return;
  std::string reason;
  switch (cause.kind) {
    case Cause::Kind::None: break;
    case Cause::Kind::State: reason = s.why; break;
    case Cause::Kind::Emcy: reason = "error EMCY"; break;
    case Cause::Kind::Input: {
      const Binding& b = bindings_[cause.binding];
      reason = cause.status == SignalStatus::Stale
                   ? fmt::format("{} stale (no PDO for {} ms)", b.field->signal,
                                 std::chrono::duration_cast<std::chrono::milliseconds>(s.driver->freshness(b.signal))
                                     .count())
                   : b.field->signal + " " + std::string(sd::to_string(cause.status));
      break;
    }
  }
  s.cause = cause;
  if (!reason.empty() && !was) {
    faults_[name] = reason;
    if (tap_ != nullptr) tap_->fault(name, true, reason);
    fault_emcy(s, true);
    log(name + ": fault (" + reason + "): its inputs are at their fault values, EMCY 7000h sent upstream");
  } else if (reason.empty() && was) {
    faults_.erase(name);
    if (tap_ != nullptr) tap_->fault(name, false, evidence);
    fault_emcy(s, false);
    log(name + ": fault cleared (" + std::string(evidence) + ")");
  } else if (!reason.empty()) {
    faults_[name] = reason;
  }
}

void Gateway::fault_emcy(Sub& s, bool raise) {
  if (decoding_emcy_) {
    held_fault_emcys_.emplace_back(&s, raise);
  } else if (raise) {
    oe_->raise_subdevice_fault(s.config->name, s.config->node(), now_);
  } else {
    oe_->clear_subdevice_fault(s.config->node(), now_);
  }
}

void Gateway::on_output(mapping::FeId fe, FieldRef ref, std::int64_t value) {
  for (auto& g : output_groups_) {
    if (!(g.fe == fe)) continue;
    if (ref.bit >= g.by_field.size()) return;
    for (const std::size_t bi : g.by_field[ref.bit]) drive(bindings_[bi], *bindings_[bi].sub, value);
    return;
  }
}

void Gateway::drive(Binding& b, Sub& s, std::int64_t value) {
  std::int64_t& current = s.output_values[b.signal];
  current = mapping::apply_output(b.output, value, current);
  if (!s.operational) return;  // sent when the node comes back (on_node_state)
  if (output_depth_ > 0 && std::find(batched_.begin(), batched_.end(), s.driver) == batched_.end()) {
    s.driver->begin_outputs();  // sent once, at the outermost end_outputs()
    batched_.push_back(s.driver);
  }
  (void)s.driver->set_output(b.signal, current, now_);
}

void Gateway::begin_outputs() { ++output_depth_; }

void Gateway::end_outputs(TimePoint now) {
  if (output_depth_ == 0 || --output_depth_ != 0) return;
  // Only the drivers on_output() touched are in a batch (nothing to do on most frames).
  for (sd::Driver* d : batched_) d->end_outputs(now);
  batched_.clear();
}

bool Gateway::on_upstream_frame(const canopen::CanFrame& frame, TimePoint now) {
  if (tap_ != nullptr) tap_->received(Bus::Up, frame, now);
  now_ = now;
  // One host command (an SDO download, an RPDO, the error values of a heartbeat loss) reaches
  // each sub-device as one frame per RPDO, never as the states in between.
  begin_outputs();
  const bool used = oe_->on_frame(frame, now);
  // An NMT reset node restarted the EMCY producer (canopen/node.hpp): a downstream interface
  // still down is raised again.
  if (downstream_down_ && !oe_->node().emcy().active(kEmcyHardware)) oe_->node().emcy().raise(kEmcyHardware, 0x00, now);
  arbiter_->hold_error_values(now);
  end_outputs(now);
  publish_changes();
  return used;
}

bool Gateway::on_downstream_frame(const canopen::CanFrame& frame, TimePoint now) {
  if (tap_ != nullptr) tap_->received(Bus::Down, frame, now);
  now_ = now;
  // A frame received: the downstream interface works again.
  downstream_down_ = false;
  if (oe_->node().emcy().active(kEmcyHardware)) oe_->node().emcy().clear(kEmcyHardware, now);
  oe_->begin_batch();  // one upstream TPDO per downstream frame, whatever it changed
  begin_outputs();     // the TPDOs end_batch() sends can notice a host heartbeat loss
  const bool used = network_.on_frame(frame, now);
  oe_->end_batch(now);
  end_outputs(now);
  publish_changes();
  if (on_downstream_frame_seen) on_downstream_frame_seen(frame, now);
  return used;
}

void Gateway::on_upstream_bus_event(canopen::BusEvent event, TimePoint now) {
  if (tap_ != nullptr) tap_->bus_event(Bus::Up, event, now);
  now_ = now;
  begin_outputs();
  oe_->node().on_bus_event(event, now);
  end_outputs(now);
  publish_changes();
}

void Gateway::on_downstream_bus_event(canopen::BusEvent event, TimePoint now) {
  if (tap_ != nullptr) tap_->bus_event(Bus::Down, event, now);
  now_ = now;
  if (event != canopen::BusEvent::InterfaceDown) return;
  downstream_down_ = true;
  auto& emcy = oe_->node().emcy();
  if (!emcy.active(kEmcyHardware)) emcy.raise(kEmcyHardware, 0x00, now);
}

void Gateway::advance(TimePoint now) {
  if (tap_ != nullptr) tap_->advanced(now);
  now_ = now;
  begin_outputs();
  oe_->advance(now);
  oe_->begin_batch();  // inputs going stale together: one TPDO
  network_.advance(now);
  oe_->end_batch(now);
  arbiter_->advance(now);
  end_outputs(now);
  publish_changes();
}

std::optional<TimePoint> Gateway::next_deadline() const {
  auto best = oe_->next_deadline();
  auto take = [&best](std::optional<TimePoint> t) {
    if (t && (!best || *t < *best)) best = t;
  };
  take(network_.next_deadline());
  take(arbiter_->next_deadline());
  return best;
}

std::vector<Gateway::FieldState> Gateway::fields(mapping::FeId fe) const {
  std::vector<FieldSample> samples;
  field_samples(fe, samples);
  std::vector<FieldState> out;
  std::size_t k = 0;
  for (const auto& b : bindings_of(fe)) {
    const FieldSample& f = samples[k++];
    out.push_back(FieldState{b.field->field.name, f.value, f.status, f.interlocked});
  }
  return out;
}

void Gateway::field_samples(mapping::FeId fe, std::vector<FieldSample>& out) const {
  out.clear();
  for (const auto& b : bindings_of(fe)) {
    out.push_back(FieldSample{model_.read(fe, b.ref), b.translator ? b.status : SignalStatus::Valid,
                              b.translator && b.translator->interlocked() && b.status == SignalStatus::Valid});
  }
}

void Gateway::count_refused(Sub* s) {
  ++subdevice_commands_refused_;
  if (s != nullptr) ++s->refused_commands;
}

std::uint64_t Gateway::subdevice_refused_commands() const {
  return subdevice_commands_refused_ + remote_sdo_->counters().refused;
}

std::uint64_t Gateway::subdevice_refused_commands(const std::string& name) const {
  const auto it = subs_.find(name);
  return it == subs_.end() ? 0 : it->second.refused_commands + remote_sdo_->refused(name);
}

canopen::SdoAbortCode Gateway::host_subdevice_command(std::uint32_t value) {
  const auto node = static_cast<std::uint8_t>(value & 0xFF);
  const auto code = static_cast<std::uint8_t>((value >> 8) & 0xFF);
  Sub* s = nullptr;
  for (auto& [name, sub] : subs_)
    if (sub.config->node_id == node) s = &sub;
  if (s == nullptr) {
    count_refused(nullptr);
    return canopen::SdoAbortCode::SubIndexDoesNotExist;  // as remote SDO: node not configured
  }
  std::string_view command;
  for (const auto& [c, name] : kSubdeviceCommands)
    if (c == code) command = name;
  if ((value >> 16) != 0 || command.empty() || s->driver->command(command).empty()) {
    count_refused(s);
    return canopen::SdoAbortCode::InvalidValue;
  }
  if (!s->operational) {
    count_refused(s);
    return canopen::SdoAbortCode::CannotTransferDeviceState;
  }
  log("host: 3000h sub-device command " + std::string(command) + " to " + s->config->name);
  // subdevice_command() counts its own refusals.
  return run_subdevice_command(s->config->name, command, now_) ? canopen::SdoAbortCode::None
                                                               : canopen::SdoAbortCode::CannotTransferDeviceState;
}

bool Gateway::subdevice_command(const std::string& name, std::string_view command, TimePoint now) {
  if (tap_ == nullptr) return run_subdevice_command(name, command, now);
  tap_->subdevice_command(name, command, now);
  const bool taken = run_subdevice_command(name, command, now);
  tap_->command_outcome(taken, {});
  return taken;
}

bool Gateway::run_subdevice_command(const std::string& name, std::string_view command, TimePoint now) {
  now_ = now;
  const auto it = subs_.find(name);
  if (it == subs_.end()) {
    count_refused(nullptr);
    log("command " + std::string(command) + ": no sub-device '" + name + "'");
    return false;
  }
  Sub& s = it->second;
  const std::vector<sd::SdoWrite> writes = s.driver->command(command);
  if (writes.empty()) {
    count_refused(&s);
    std::string known;
    for (const auto& c : s.driver->commands()) known += (known.empty() ? "" : ", ") + c;
    log(name + ": no command '" + std::string(command) + "' (" + std::string(s.driver->family()) +
        " has: " + (known.empty() ? "none" : known) + ")");
    return false;
  }
  if (!s.operational) {
    count_refused(&s);
    log(name + ": command " + std::string(command) + " refused: the node is " + s.why);
    return false;
  }
  // The writes go as SDO downloads; what they change shows only in what the device reports
  // afterwards (an EMCY, its PDOs), never in the answer itself.
  for (const sd::SdoWrite& w : writes) {
    master_.sdo(s.config->node())
        .download(w.index, w.sub, w.data,
                  [this, name, what = w.what](canopen::SdoAbortCode code, const std::vector<std::uint8_t>&) {
                    log(name + ": " + what +
                        (code == canopen::SdoAbortCode::None ? std::string(": done")
                                                             : ": abort " + std::string(canopen::to_string(code))));
                  });
  }
  log(name + ": command " + std::string(command) + " sent");
  return true;
}

Gateway::EmcyRecord Gateway::subdevice_emcy(const std::string& name) const {
  const auto it = subs_.find(name);
  return it == subs_.end() ? EmcyRecord{} : it->second.emcy;
}

FeStatus Gateway::status(mapping::FeId fe) const { return model_.has(fe) ? model_.status(fe) : FeStatus::Valid; }

bool Gateway::command_indicators(std::uint8_t instance, std::uint64_t bits, TimePoint now,
                                 mapping::CommandSource source) {
  if (tap_ != nullptr) tap_->indicators(instance, bits, source, now);
  now_ = now;
  begin_outputs();  // all 64 bits of the command: one frame per RPDO of each sub-device
  const bool taken = arbiter_->command_indicators(instance, bits, source, now);
  end_outputs(now);
  publish_changes();
  if (tap_ != nullptr) tap_->command_outcome(taken, {});
  return taken;
}

bool Gateway::command_display(std::uint8_t instance, const std::array<std::int16_t, 12>& parameters, TimePoint now,
                              mapping::CommandSource source) {
  if (tap_ != nullptr) tap_->display(instance, parameters, source, now);
  now_ = now;
  begin_outputs();
  const bool taken = arbiter_->command_display(instance, parameters, source, now);
  end_outputs(now);
  publish_changes();
  if (tap_ != nullptr) tap_->command_outcome(taken, {});
  return taken;
}

RemoteSdo& Gateway::remote_sdo(TimePoint now) {
  if (tap_ != nullptr) tap_->control("remote_sdo", now);
  now_ = now;
  return *remote_sdo_;
}

std::string Gateway::downstream_nmt(canopen::NodeId node, canopen::NmtCommand cs, TimePoint now) {
  if (tap_ == nullptr) return run_downstream_nmt(node, cs, now);
  tap_->downstream_nmt(node, cs, now);
  std::string why = run_downstream_nmt(node, cs, now);
  tap_->command_outcome(why.empty(), why);
  return why;
}

std::string Gateway::run_downstream_nmt(canopen::NodeId node, canopen::NmtCommand cs, TimePoint now) {
  now_ = now;
  const Sub* s = nullptr;
  for (const auto& [name, sub] : subs_)
    if (sub.config->node_id == node.value()) s = &sub;
  if (s != nullptr) {
    const sd::NodeState st = network_.state(s->config->name);
    // The gateway's own boot and configuration come first (as for remote SDO, 0800 0022h there).
    if (st == sd::NodeState::Idle || st == sd::NodeState::WaitingBootUp || st == sd::NodeState::Configuring)
      return fmt::format("{} is being booted by the gateway ({}); try again when it is operational", s->config->name,
                         sd::to_string(st));
    // Starting a node the gateway has not configured and started itself would bypass its boot
    // checks (a refused identity, a lost node): only the network manager starts nodes it boots.
    if (cs == canopen::NmtCommand::Start && st != sd::NodeState::Operational && st != sd::NodeState::Starting)
      return fmt::format("{} is {}: the gateway starts it itself once its boot succeeds (reset node boots it again)",
                         s->config->name, sd::to_string(st));
  }
  log(fmt::format("control: NMT {:02X}h to node {:02X}h{}", static_cast<unsigned>(cs), node.value(),
                  s != nullptr ? " (" + s->config->name + ")" : std::string(" (no sub-device of the mapping file)")));
  master_.nmt().send(cs, node);
  return {};
}

// ------------------------------------------------------------------ reload (gateway/reload.hpp)

void Gateway::hand_over(const mapping::Config& next, TimePoint now) {
  now_ = now;
  begin_outputs();  // the error values: one frame per RPDO of each operational sub-device
  oe_->apply_error_values(std::nullopt, now);
  end_outputs(now);
  for (const auto& sc : config_.subdevices) {
    const bool kept = std::any_of(next.subdevices.begin(), next.subdevices.end(),
                                  [&sc](const mapping::SubdeviceConfig& n) { return n.node_id == sc.node_id; });
    if (kept) continue;
    master_.nmt().enter_pre_operational(sc.node());
    log(fmt::format("{}: no longer in the mapping file: NMT enter pre-operational sent to node {:02X}h", sc.name,
                    sc.node_id));
  }
  publish_changes();
}

std::unique_ptr<OeDevice> Gateway::release_upstream() {
  command_hook_ = {};
  canopen::Node& device = oe_->node();
  for (std::size_t k = 0; k < device.sdo_server_count(); ++k) {
    // A transfer in progress ends with this gateway: its client is told at once (0800 0022h,
    // the device's state: a reload), not left to its own time-out.
    device.sdo_server(k).abort_in_progress(canopen::SdoAbortCode::CannotTransferDeviceState);
    device.sdo_server(k).set_remote(nullptr);
    device.sdo_server(k).bind(std::nullopt);
    device.sdo_server(k).on_redirect = {};  // a redirect ended above is logged by this gateway
  }
  oe_->on_emcy({});
  oe_->on_sent({});
  oe_->on_output({});
  oe_->on_host_write({});
  return std::move(oe_);
}

void Gateway::resume(TimePoint now) {
  now_ = now;
  begin_outputs();
  oe_->begin_batch();  // the inputs' fault values: one TPDO per PDO
  arbiter_->start(now);
  for (auto& b : bindings_)
    if (b.translator) (void)model_.write(b.fe, b.ref, b.translator->value(), now);
  for (const auto& fe : model_.fes()) {
    model_.stamp(fe, now);
    // The device's dictionary still holds the old gateway's inputs, and a fault value equal to
    // the fresh model's 0 changed no slot above: every input slot is mirrored.
    if (!mapping::is_input(fe.kind)) continue;
    for (std::size_t k = 0; k < kFeSlots; ++k)
      oe_->mirror_input(fe, static_cast<FeSlot>(k), model_.slot_value(fe, static_cast<FeSlot>(k)), now);
  }
  oe_->announce_outputs(now);  // into the FE model and the output bindings (sent at each node's start)
  oe_->end_batch(now);
  end_outputs(now);
  // Faults of the device's 7000h: kept for a sub-device this file keeps, ended for the others.
  const std::map<std::uint8_t, std::string> faulty = oe_->faulty_subdevices();
  for (const auto& [node, name] : faulty) {
    const auto it = subs_.find(name);
    if (it == subs_.end() || it->second.config->node_id != node) {
      oe_->clear_subdevice_fault(canopen::NodeId{node}, now);
      log(fmt::format("{}: fault ended: node {:02X}h is no longer this sub-device of the mapping file", name, node));
      continue;
    }
    Sub& s = it->second;
    s.failed = true;
    s.why = "faulty before the reload";
    s.cause = Cause{Cause::Kind::State, 0, SignalStatus::Offline};
    faults_[name] = s.why;
  }
  auto& emcy = oe_->node().emcy();
  if (!emcy.active(kEmcyReload)) emcy.raise(kEmcyReload, 0x00, now);
  reloading_ = true;
  log(
      fmt::format("reload: every input at its fault value, every output at its error value, EMCY {:04X}h; booting "
                  "the {} sub-devices again",
                  kEmcyReload, subs_.size()));
  network_.start(now);
  settle_reload();
  publish_changes();
}

void Gateway::settle_reload() {
  for (const auto& [name, s] : subs_)
    if (!s.operational && !s.failed) return;
  reloading_ = false;
  auto& emcy = oe_->node().emcy();
  emcy.clear(kEmcyReload, now_);
  // Other errors still active (a faulty sub-device's 7000h): the producer stays silent, so the
  // end is reported as a sub-device's recovery among others is, EMCY 0000h with the remaining
  // error register (OeDevice::clear_subdevice_fault).
  if (emcy.active_count() != 0) (void)emcy.report(canopen::EmcyProducer::kErrorReset, {}, 0, now_);
  log(fmt::format("reload: every sub-device operational or reported faulty: EMCY {:04X}h cleared", kEmcyReload));
}

namespace {

void put_emcy(canopen::StateWriter& w, const Gateway::EmcyRecord& e) {
  w.put("node", e.last.node.value());
  w.put("code", e.last.code);
  w.put("register", e.last.error_register);
  w.put_bytes("msef", e.last.msef);
  w.put("time", e.time);
  w.put("count", e.count);
}

Gateway::EmcyRecord get_emcy(const canopen::StateReader& r) {
  Gateway::EmcyRecord e;
  e.last.node = canopen::NodeId{r.get<std::uint8_t>("node")};
  e.last.code = r.get<std::uint16_t>("code");
  e.last.error_register = r.get<std::uint8_t>("register");
  const std::vector<std::uint8_t> msef = r.bytes("msef");
  if (msef.size() != e.last.msef.size()) r.fail("msef", "is not 5 bytes (CiA 301 §7.2.7.3.1)");
  std::copy(msef.begin(), msef.end(), e.last.msef.begin());
  e.time = r.time("time");
  e.count = r.get<std::uint64_t>("count");
  return e;
}

}  // namespace

std::string Gateway::busy() const {
  if (output_depth_ != 0 || decoding_emcy_) throw std::logic_error("Gateway::busy inside a call");
  if (std::string why = network_.busy(); !why.empty()) return why;
  if (remote_sdo_->in_flight() != 0) return "a remote SDO transfer is in flight";
  return oe_->busy();
}

void Gateway::export_state(canopen::StateWriter& w) const {
  if (const std::string why = busy(); !why.empty()) throw std::logic_error("Gateway::export_state: " + why);
  w.put("now", now_);
  w.put("downstream_down", downstream_down_);
  w.put("reloading", reloading_);
  w.put("commands_refused", subdevice_commands_refused_);
  w.put_state("master", master_);
  w.put_state("network", network_);
  w.put_state("remote_sdo", *remote_sdo_);
  w.put_state("device", *oe_);
  w.put_state("model", model_);
  w.put_state("arbiter", *arbiter_);
  w.put_list("bindings", bindings_.size(), [&](std::size_t i) {
    const Binding& b = bindings_[i];
    w.put("status", b.status);
    if (b.translator) w.put_state("translator", *b.translator);
  });
  // In the mapping file's order: names are no state keys.
  w.put_list("subdevices", config_.subdevices.size(), [&](std::size_t i) {
    const Sub& s = subs_.at(config_.subdevices[i].name);
    w.put("operational", s.operational);
    w.put("failed", s.failed);
    w.put_text("why", s.why);
    w.put_list("outputs", s.output_values.size(), [&](std::size_t k) { w.put("value", s.output_values[k]); });
    w.put("forced", s.forced);
    w.put("cause.kind", s.cause.kind);
    w.put("cause.binding", s.cause.binding);
    w.put("cause.status", s.cause.status);
    if (const auto it = faults_.find(config_.subdevices[i].name); it != faults_.end()) w.put_text("fault", it->second);
    w.put("refused_commands", s.refused_commands);
    const canopen::StateWriter::Scope emcy(w, "emcy");
    put_emcy(w, s.emcy);
  });
  w.put_list("upstream_emcys", upstream_emcys_.size(), [&, it = upstream_emcys_.begin()](std::size_t) mutable {
    put_emcy(w, it->second);
    ++it;
  });
}

void Gateway::import_state(const canopen::StateReader& r) {
  if (output_depth_ != 0 || decoding_emcy_) throw std::logic_error("Gateway::import_state inside a call");
  // The parts in the order they depend on each other: the master's dictionary and clients
  // before the network manager (which routes to them), the device before the model it mirrors.
  master_.import_state(r.in("master"));
  network_.import_state(r.in("network"));
  remote_sdo_->import_state(r.in("remote_sdo"));
  oe_->import_state(r.in("device"));
  model_.import_state(r.in("model"));
  arbiter_->import_state(r.in("arbiter"));
  std::size_t n = 0;
  r.read_list("bindings", bindings_.size(), [&](const canopen::StateReader& item) {
    Binding& b = bindings_[n++];
    b.status = subdevices::get_signal_status(item, "status");
    if (b.translator) b.translator->import_state(item.in("translator"));
  });
  if (n != bindings_.size()) r.fail("bindings.count", "differs from the mapping file's fields");
  std::map<std::string, std::string> faults;
  n = 0;
  r.read_list("subdevices", config_.subdevices.size(), [&](const canopen::StateReader& item) {
    const std::string& name = config_.subdevices[n++].name;
    Sub& s = subs_.at(name);
    s.operational = item.get<bool>("operational");
    s.failed = item.get<bool>("failed");
    s.why = item.text("why", kMaxStateText);
    std::size_t k = 0;
    item.read_list("outputs", s.output_values.size(),
                   [&](const canopen::StateReader& o) { s.output_values[k++] = o.integer("value"); });
    if (k != s.output_values.size()) item.fail("outputs.count", "differs from the driver's signals");
    s.forced = item.get<bool>("forced");
    const auto kind = item.get<std::uint8_t>("cause.kind");
    if (kind > static_cast<std::uint8_t>(Cause::Kind::Input)) item.fail("cause.kind", "is no fault cause");
    const auto binding = item.get<std::uint64_t>("cause.binding");
    if (binding >= std::max<std::size_t>(bindings_.size(), 1)) item.fail("cause.binding", "is no field binding");
    s.cause = Cause{static_cast<Cause::Kind>(kind), static_cast<std::size_t>(binding),
                    subdevices::get_signal_status(item, "cause.status")};
    // update_fault(): a sub-device has a fault reason exactly while it has a cause.
    if (item.has("fault") != (s.cause.kind != Cause::Kind::None)) item.fail("fault", "differs from the fault's cause");
    if (item.has("fault")) faults[name] = item.text("fault", kMaxStateText);
    s.emcy = get_emcy(item.in("emcy"));
    s.refused_commands = item.get<std::uint64_t>("refused_commands");
  });
  if (n != config_.subdevices.size()) r.fail("subdevices.count", "differs from the mapping file's sub-devices");
  std::map<std::uint8_t, EmcyRecord> upstream;
  r.read_list("upstream_emcys", 127, [&](const canopen::StateReader& item) {
    const EmcyRecord e = get_emcy(item);
    upstream[e.last.node.value()] = e;
  });
  upstream_emcys_ = std::move(upstream);
  faults_ = std::move(faults);
  now_ = r.time("now");
  downstream_down_ = r.get<bool>("downstream_down");
  reloading_ = r.get<bool>("reloading");
  subdevice_commands_refused_ = r.get<std::uint64_t>("commands_refused");
}

}  // namespace oegw::gateway
