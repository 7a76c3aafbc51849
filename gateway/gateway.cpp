#include "gateway/gateway.hpp"

#include <algorithm>
#include <array>

#include <fmt/format.h>

namespace oegw::gateway {

using canopen::TimePoint;
using subdevices::SignalStatus;
namespace sd = oegw::subdevices;

mapping::SignalCatalogue driver_catalogue() {
  return [](std::string_view family, const sd::DriverOptions& options,
            std::string& error) -> std::optional<std::vector<sd::SignalInfo>> {
    // A driver on node 1 with no bus: only its signal list is wanted.
    auto driver = sd::make_driver(family, canopen::NodeId{1}, {}, options, error);
    if (!driver) return std::nullopt;
    return driver->signals();
  };
}

namespace {

OeDeviceConfig oe_config(const mapping::Config& c, const GatewayOptions& o) {
  OeDeviceConfig oe;
  oe.node_id = canopen::NodeId{c.upstream.node_id};
  oe.identity = {c.upstream.identity.vendor_id, c.upstream.identity.product_code, c.upstream.identity.revision,
                 c.upstream.identity.serial};
  oe.heartbeat_ms = c.upstream.heartbeat_ms;
  for (const auto& fe : c.functional_elements) {
    oe.fes.push_back(fe.id);
    // Table 8 distinguishes joysticks with buttons.
    if (fe.id.kind == mapping::FeKind::Joystick &&
        std::none_of(fe.fields.begin(), fe.fields.end(),
                     [](const auto& f) { return f.field.name.rfind("buttons", 0) == 0; }))
      oe.joysticks_without_buttons.insert(fe.id);
    if (!fe.input() && !fe.accepts(mapping::CommandSource::Canopen)) oe.host_may_not_command.insert(fe.id);
  }
  oe.store_path = o.store_path ? *o.store_path : std::filesystem::path(c.upstream.store);
  return oe;
}

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
    : config_(config),
      master_(master_od_, downstream, canopen::MasterConfig{.heartbeat_entries = heartbeat_entries(config), .sdo_timeout = options.sdo_timeout}),
      network_(master_, options.timing) {
  oe_ = std::make_unique<OeDevice>(oe_config(config_, options), std::move(upstream));
  for (const auto& sc : config_.subdevices) {
    std::string error;
    auto driver = sd::make_driver(sc.driver, sc.node(), downstream, sc.options, error);
    if (!driver) throw std::runtime_error(sc.where.str() + ": " + error);  // load_config checked it
    sd::NodeSettings ns = sc.node_settings();
    sd::Driver* d = driver.get();
    const std::string name = sc.name;
    d->on_change = [this, name](std::size_t i, const sd::SignalValue& v) { on_signal(name, i, v); };
    network_.add(std::move(ns), std::move(driver));
    subs_[sc.name] = Sub{&sc, d, false, false, "not booted yet", std::vector<std::vector<std::size_t>>(d->signals().size()), {}};
    batched_.reserve(config_.subdevices.size());  // no allocation in an output batch
  }
  for (const auto& fe : config_.functional_elements) {
    for (const auto& f : fe.fields) {
      Binding b{fe.id, &f, std::nullopt, std::nullopt, {}, 0, SignalStatus::Offline};
      Sub& s = subs_.at(f.subdevice);
      b.signal = *s.driver->find_signal(f.signal);
      if (fe.input()) {
        b.translator.emplace(f.input_params());
        b.target = mapping::find_fe_field(fe.id, f.field.name);
        s.inputs.push_back(bindings_.size());
      } else {
        b.output = f.output_params();
      }
      s.by_signal.at(b.signal).push_back(bindings_.size());
      bindings_.push_back(std::move(b));
    }
  }
  network_.on_node_state = [this](const std::string& name, sd::NodeState st, const std::string& why) {
    auto it = subs_.find(name);
    if (it == subs_.end()) return;
    Sub& s = it->second;
    const bool was = s.operational;
    s.operational = st == sd::NodeState::Operational;
    // An error EMCY holds until the device's error reset 0000h, across losses and the gateway's
    // reset communication (which makes no device repeat its EMCYs); only a boot-up the device
    // made on its own or answering an NMT reset node voids it (on_application_reset). A node
    // lost while it holds one is booted again by reset node: reset, it reports the error again
    // if it persists, and the gateway does not wait for an error reset that may have been lost.
    s.why = std::string(sd::to_string(st)) + " (" + why + ")";
    log(name + ": " + s.why);
    if (s.operational && !was) {
      // Outputs the host set meanwhile reach the device now, all in one frame per RPDO.
      begin_outputs();
      for (auto& b : bindings_) {
        if (b.field->subdevice != name || b.translator) continue;
        const auto v = oe_->get(b.fe, b.field->field.name);
        if (v) on_output(b.fe, b.field->field.name, *v);
      }
      end_outputs(now_);
    }
    // Only a node that failed (not one still booting for the first time) is a fault; only the
    // proof of life the network manager names (`why`) makes it operational again.
    if ((st == sd::NodeState::Missing || st == sd::NodeState::Refused) && s.emcy_error)
      network_.reset_application_next(name);
    if (st == sd::NodeState::Missing || st == sd::NodeState::Refused || s.operational) update_fault(s, why);
  };
  network_.on_emcy = [this](const std::string& name, const canopen::EmcyMessage& e, const sd::DecodedEmcy& d) {
    auto it = subs_.find(name);
    if (it == subs_.end()) return;
    log(name + ": EMCY " + fmt::format("{:04X}h", e.code) + " " + d.text);
    // Fix (e2e test AWarningEmcyDoesNotEndAnActiveSubdeviceError): a warning EMCY (decoded
    // error = false, e.g. elobau 8140h "recovered from bus off") used to end an active error
    // EMCY, so the fault was cleared (EMCY 0000h upstream) while the device still reported it.
    // Only the device's error reset (0000h) ends it; an error EMCY starts it.
    if (e.code == 0) {
      it->second.emcy_error = false;
    } else if (d.error) {
      it->second.emcy_error = true;
    }
    update_fault(it->second, "error reset EMCY 0000h");
  };
  network_.on_application_reset = [this](const std::string& name) {
    if (auto it = subs_.find(name); it != subs_.end()) it->second.emcy_error = false;
  };
  network_.on_bad_input = [this](const std::string& what) { log(what); };
  oe_->on_output([this](mapping::FeId fe, const std::string& field, std::int64_t value) { on_output(fe, field, value); });
  for (const auto& fe : config_.functional_elements)
    if (!fe.input() && fe.command_timeout_ms > 0)
      watches_.push_back({fe.id, std::chrono::milliseconds(fe.command_timeout_ms), TimePoint{}, false});
  oe_->on_host_command([this](mapping::FeId fe) { command_seen(fe); });
  oe_->on_host_write_refused([this](mapping::FeId fe, canopen::Origin origin) {
    const mapping::FunctionalElementConfig* c = config_.find_fe(fe);
    const bool rpdo = origin == canopen::Origin::Pdo;
    refused(fe, rpdo ? "RPDO" : "SDO",
            std::string(rpdo ? "the host's RPDO bytes for it ignored" : "the host's SDO write refused (abort 0800 0021h)") +
                ": its sources are " + mapping::describe_sources(c ? c->sources : 0));
  });
}

canopen::ParameterStore::LoadResult Gateway::start(TimePoint now) {
  now_ = now;
  auto r = oe_->start(now);
  // A command watchdog runs from power-on: a commander that never starts is a silent one.
  for (auto& w : watches_) {
    w.last = now;
    w.expired = false;
  }
  started_ = true;
  // Every input starts at its fault value (the signals are Offline until their node is up).
  for (auto& b : bindings_)
    if (b.translator) (void)oe_->set_input(b.fe, b.field->field.name, b.translator->value(), now);
  network_.start(now);
  return r;
}

void Gateway::log(const std::string& line) {
  if (on_log) on_log(line);
}

bool Gateway::feed(Binding& b, const Sub& s, const sd::SignalValue& v) {
  sd::SignalValue in = v;
  if (s.forced && in.status == SignalStatus::Valid) in.status = SignalStatus::Error;
  const std::int64_t before = b.translator->value();
  const SignalStatus status_before = b.status;
  const std::int64_t fe_value = b.translator->update(in);
  b.status = in.status;
  if (b.target) {
    (void)oe_->set_input(b.fe, *b.target, fe_value, now_);
  } else {
    (void)oe_->set_input(b.fe, b.field->field.name, fe_value, now_);
  }
  return fe_value != before || b.status != status_before;
}

void Gateway::on_signal(const std::string& sub, std::size_t index, const sd::SignalValue& v) {
  // Runs for every changed signal of every PDO: no allocation unless more than kInline FEs change.
  constexpr std::size_t kInline = 8;
  std::array<mapping::FeId, kInline> changed{};
  std::size_t n_changed = 0;
  std::set<mapping::FeId> more;  // only when kInline is exceeded
  auto note = [&](mapping::FeId fe) {  // keeps changed[0, n_changed) sorted and unique
    std::size_t at = 0;
    while (at < n_changed && changed[at] < fe) ++at;
    if (at < n_changed && changed[at] == fe) return;
    if (n_changed == kInline) {
      more.insert(fe);
      return;
    }
    for (std::size_t i = n_changed; i > at; --i) changed[i] = changed[i - 1];
    changed[at] = fe;
    ++n_changed;
  };
  auto s = subs_.find(sub);
  if (s == subs_.end()) return;
  if (index < s->second.by_signal.size()) {
    for (const std::size_t bi : s->second.by_signal[index]) {
      Binding& b = bindings_[bi];
      if (!b.translator) continue;
      if (feed(b, s->second, v)) note(b.fe);
    }
  }
  update_fault(s->second, "fresh PDO");
  if (on_fe_change) {
    // In FE order, each once (as a std::set gave them).
    if (more.empty()) {
      for (std::size_t i = 0; i < n_changed; ++i) on_fe_change(changed[i]);
    } else {
      for (std::size_t i = 0; i < n_changed; ++i) more.insert(changed[i]);
      for (const auto& fe : more) on_fe_change(fe);
    }
  }
}

void Gateway::update_fault(Sub& s, std::string_view evidence) {
  // Fix (e2e test UnknownErrorEmcyStillPutsTheFieldsAtTheirFaultValues): an error EMCY the
  // driver does not map to a signal (e.g. an MCB-402 code it does not know) left every signal
  // Valid, so the fields kept following while the log and EMCY 7000h said "at their fault
  // values". While the error EMCY lasts, the node's inputs are held at their fault values (set
  // before the EMCY goes up); on the error reset they are fed again from the driver's current
  // values, through the neutral interlock.
  const bool forced = s.operational && s.emcy_error;
  if (forced != s.forced) {
    s.forced = forced;
    std::set<mapping::FeId> changed;
    for (const std::size_t bi : s.inputs) {
      Binding& b = bindings_[bi];
      if (feed(b, s, s.driver->value(b.signal))) changed.insert(b.fe);
    }
    if (on_fe_change)
      for (const auto& fe : changed) on_fe_change(fe);
  }
  // A bound input in Error / NotAvailable / Stale counts; Offline is the node's own state. The
  // cause is found without building text: this runs for every PDO, and the reason string is
  // made only when the cause changes (no allocation per frame while a fault lasts).
  const Cause cause = [&] {
    if (!s.operational) return Cause{Cause::Kind::State, 0, SignalStatus::Offline};
    if (s.emcy_error) return Cause{Cause::Kind::Emcy, 0, SignalStatus::Error};
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
                                 std::chrono::duration_cast<std::chrono::milliseconds>(s.driver->freshness(b.signal)).count())
                   : b.field->signal + " " + std::string(sd::to_string(cause.status));
      break;
    }
  }
  s.cause = cause;
  if (!reason.empty() && !was) {
    faults_[name] = reason;
    oe_->raise_subdevice_fault(name, s.config->node(), now_);
    log(name + ": fault (" + reason + "): its inputs are at their fault values, EMCY 7000h sent upstream");
  } else if (reason.empty() && was) {
    faults_.erase(name);
    oe_->clear_subdevice_fault(s.config->node(), now_);
    log(name + ": fault cleared (" + std::string(evidence) + ")");
  } else if (!reason.empty()) {
    faults_[name] = reason;
  }
}

void Gateway::on_output(mapping::FeId fe, const std::string& field, std::int64_t value) {
  for (auto& b : bindings_) {
    if (b.translator || !(b.fe == fe) || b.field->field.name != field) continue;
    Sub& s = subs_.at(b.field->subdevice);
    const auto key = std::make_pair(b.field->subdevice, b.signal);
    const std::int64_t current = output_values_.count(key) ? output_values_[key] : 0;
    const std::int64_t next = mapping::apply_output(b.output, value, current);
    output_values_[key] = next;
    if (!s.operational) continue;
    if (output_depth_ > 0 && std::find(batched_.begin(), batched_.end(), s.driver) == batched_.end()) {
      s.driver->begin_outputs();  // sent once, at the outermost end_outputs()
      batched_.push_back(s.driver);
    }
    (void)s.driver->set_output(b.signal, next, now_);
  }
}

void Gateway::begin_outputs() { ++output_depth_; }

void Gateway::end_outputs(TimePoint now) {
  if (output_depth_ == 0 || --output_depth_ != 0) return;
  // Only the drivers on_output() touched are in a batch (nothing to do on most frames).
  for (sd::Driver* d : batched_) d->end_outputs(now);
  batched_.clear();
}

bool Gateway::on_upstream_frame(const canopen::CanFrame& frame, TimePoint now) {
  now_ = now;
  // One host command (an SDO download, an RPDO, the error values of a heartbeat loss) reaches
  // each sub-device as one frame per RPDO, never as the states in between.
  begin_outputs();
  const bool used = oe_->on_frame(frame, now);
  hold_error_values(now);
  end_outputs(now);
  return used;
}

void Gateway::hold_error_values(TimePoint now) {
  // While an FE's commander is silent its outputs stay at their error values, also when the host
  // changes 6206h/6207h/6443h/6444h meanwhile or an NMT reset / 1011h restore puts the outputs
  // back to their defaults (only writes what differs: cheap when nothing changed).
  for (const auto& w : watches_)
    if (w.expired) oe_->apply_error_values(w.fe, now);
}

bool Gateway::on_downstream_frame(const canopen::CanFrame& frame, TimePoint now) {
  now_ = now;
  oe_->begin_batch();  // one upstream TPDO per downstream frame, whatever it changed
  begin_outputs();     // the TPDOs end_batch() sends can notice a host heartbeat loss
  const bool used = network_.on_frame(frame, now);
  oe_->end_batch(now);
  end_outputs(now);
  return used;
}

void Gateway::on_upstream_bus_event(canopen::BusEvent event, TimePoint now) {
  now_ = now;
  oe_->node().on_bus_event(event, now);
}

void Gateway::advance(TimePoint now) {
  now_ = now;
  begin_outputs();
  oe_->advance(now);
  oe_->begin_batch();  // inputs going stale together: one TPDO
  network_.advance(now);
  oe_->end_batch(now);
  for (auto& w : watches_) {
    if (!started_ || w.expired || now - w.last < w.timeout) continue;
    // The FE's commander fell silent: its outputs take their error values (CiA 401 6206h/6207h,
    // 6443h/6444h — what a lost host heartbeat does to every output) until the next command.
    w.expired = true;
    oe_->apply_error_values(w.fe, now);
    log(fmt::format("{}: no command for {} ms: outputs set to their error values until the next command",
                    mapping::fe_name(w.fe),
                    std::chrono::duration_cast<std::chrono::milliseconds>(w.timeout).count()));
  }
  end_outputs(now);
}

std::optional<TimePoint> Gateway::next_deadline() const {
  auto best = oe_->next_deadline();
  auto take = [&best](std::optional<TimePoint> t) {
    if (t && (!best || *t < *best)) best = t;
  };
  take(network_.next_deadline());
  for (const auto& w : watches_)
    if (started_ && !w.expired) take(w.last + w.timeout);
  return best;
}

void Gateway::command_seen(mapping::FeId fe) {
  for (auto& w : watches_) {
    if (!(w.fe == fe)) continue;
    w.last = now_;
    if (w.expired)
      log(mapping::fe_name(fe) + ": commands again");
    w.expired = false;
  }
}

std::vector<mapping::FeId> Gateway::fes() const {
  std::vector<mapping::FeId> out;
  for (const auto& fe : config_.functional_elements) out.push_back(fe.id);
  return out;
}

std::vector<Gateway::FieldState> Gateway::fields(mapping::FeId fe) const {
  std::vector<FieldState> out;
  for (const auto& b : bindings_) {
    if (!(b.fe == fe)) continue;
    FieldState f;
    f.name = b.field->field.name;
    f.value = oe_->get(fe, b.field->field).value_or(0);  // the binding's field, looked up at load
    f.status = b.translator ? b.status : SignalStatus::Valid;
    f.interlocked = b.translator && b.translator->interlocked() && b.status == SignalStatus::Valid;
    out.push_back(f);
  }
  return out;
}

FeStatus Gateway::status(mapping::FeId fe) const {
  SignalStatus worst = SignalStatus::Valid;
  bool any = false;
  for (const auto& b : bindings_) {
    if (!(b.fe == fe) || !b.translator) continue;
    worst = any ? worse(worst, b.status) : b.status;
    any = true;
  }
  return static_cast<FeStatus>(static_cast<std::uint8_t>(worst));
}

void Gateway::refused(mapping::FeId fe, std::string_view way, const std::string& why) {
  ++refused_commands_;
  // Logged once per FE and way (dds, lcm, SDO, RPDO): a commander at 100 Hz must not flood the
  // journal; refused_commands() keeps the count.
  if (refused_logged_.emplace(fe, std::string(way)).second) log(mapping::fe_name(fe) + ": " + why);
}

bool Gateway::take_command(mapping::FeId fe, mapping::CommandSource source, TimePoint now) {
  now_ = now;
  const mapping::FunctionalElementConfig* c = config_.find_fe(fe);  // none: instance outside 1..8 too
  if (c == nullptr || !c->accepts(source)) {
    const auto src = std::string(mapping::to_string(source));
    refused(fe, src,
            "a command from " + src + " ignored: " +
                (c == nullptr ? "the mapping file does not configure " + mapping::fe_name(fe)
                              : "its sources are " + mapping::describe_sources(c->sources)));
    return false;
  }
  command_seen(fe);
  return true;
}

bool Gateway::command_indicators(std::uint8_t instance, std::uint64_t bits, TimePoint now,
                                 mapping::CommandSource source) {
  const mapping::FeId fe{mapping::FeKind::IndicatorCluster, instance};
  if (!take_command(fe, source, now)) return false;
  begin_outputs();  // all 64 bits of the command: one frame per RPDO of each sub-device
  // fe_fields() lists indicator[1..64] in order (mapping/functional_elements.hpp): one pass.
  const auto fields = mapping::fe_fields(fe);
  for (std::size_t k = 0; k < fields.size(); ++k) {
    const mapping::FeField* f = &fields[k];
    const std::int64_t bit = static_cast<std::int64_t>((bits >> k) & 1u);
    auto* sub = oe_->od().find(f->index, f->sub);
    if (sub == nullptr) continue;
    std::uint8_t byte = sub->value.empty() ? 0 : sub->value[0];
    byte = static_cast<std::uint8_t>(bit ? (byte | (1u << f->bit)) : (byte & ~(1u << f->bit)));
    // Written as the host would: the dictionary's observers report the change to on_output.
    (void)oe_->od().write(f->index, f->sub, std::span<const std::uint8_t>(&byte, 1), canopen::Origin::Local);
  }
  end_outputs(now);
  return true;
}

bool Gateway::command_display(std::uint8_t instance, const std::array<std::int16_t, 12>& parameters, TimePoint now,
                              mapping::CommandSource source) {
  const mapping::FeId fe{mapping::FeKind::Display, instance};
  if (!take_command(fe, source, now)) return false;
  begin_outputs();
  // fe_fields() lists parameter[1..12] in order: one pass.
  const auto fields = mapping::fe_fields(fe);
  for (std::size_t p = 0; p < fields.size() && p < parameters.size(); ++p) {
    const mapping::FeField& f = fields[p];
    if (oe_->od().find(f.index, f.sub) == nullptr) continue;
    (void)oe_->od().set<std::int16_t>(f.index, f.sub, parameters[p], canopen::Origin::Local);
  }
  end_outputs(now);
  return true;
}

}  // namespace oegw::gateway
