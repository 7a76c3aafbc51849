#include "gateway/publishing.hpp"

#include <algorithm>

#include "publish/dds_publisher.hpp"
#include "publish/lcm_publisher.hpp"

namespace oegw::gateway {

namespace mk = oegw::mapping;

static_assert(std::size_t{publish::kDdsSecurityFiles} == std::size_t{mapping::DdsSecurityConfig::kFiles},
              "one list of publish.dds.security's files");

publish::DdsSecuritySettings dds_security_settings(const mapping::DdsSecurityConfig& c) {
  publish::DdsSecuritySettings s;
  s.path = c.path;
  return s;
}

std::vector<mapping::Diagnostic> dds_security_errors(const mapping::Config& c) {
  std::vector<mapping::Diagnostic> out;
  if (!c.publish.dds.enabled || !c.publish.dds.security) return out;
  const auto& sec = *c.publish.dds.security;
  for (const auto& p : publish::check_dds_security(dds_security_settings(sec)))
    out.push_back({sec.where[p.file].line != 0 ? sec.where[p.file] : sec.section,
                   publish::dds_security_setting(p.file) + " " + p.text});
  return out;
}

PublisherFactories real_publishers(const mapping::PublishConfig& config) {
  PublisherFactories f;
  if (config.dds.enabled) {
    publish::DdsSettings s;
    s.domain = config.dds.domain;
    s.partition = config.dds.partition;
    s.network = config.dds.network;
    if (config.dds.security) s.security = dds_security_settings(*config.dds.security);
    s.period_us = std::int64_t{config.period_ms} * 1000;
    f.dds = [s] { return std::make_unique<publish::DdsPublisher>(s); };
  }
  if (config.lcm.enabled) {
    const publish::LcmSettings s{config.lcm.url, config.lcm.channel_prefix};
    f.lcm = [s] { return std::make_unique<publish::LcmPublisher>(s); };
  }
  return f;
}

GatewayPublishing::GatewayPublishing(Gateway& gateway, const mapping::PublishConfig& config,
                                     std::function<canopen::TimePoint()> clock, PublisherFactories factories,
                                     PublisherLink::Log log)
    : gw_(&gateway), clock_(std::move(clock)), schedule_(fan_, std::int64_t{config.period_ms} * 1000) {
  const PublisherFactories real = real_publishers(config);
  const auto add = [&](const char* name, bool enabled, PublisherLink::Factory given, PublisherLink::Factory own,
                       mk::CommandSource source) {
    if (!enabled) return;
    auto link = std::make_unique<PublisherLink>(name, given ? std::move(given) : std::move(own));
    link->on_log = log;
    link->on_indicator_command = [this, source](const IndicatorCommand& c) {
      (void)gw_->command_indicators(c.instance, c.indicators, clock_(), source);
    };
    link->on_display_command = [this, source](const DisplayCommand& c) {
      (void)gw_->command_display(c.instance, c.parameters, clock_(), source);
    };
    link->open(clock_());  // PublishConfigError: refused, nothing left open
    fan_.add(link.get());
    links_.push_back(std::move(link));
  };
  add("dds", config.dds.enabled, std::move(factories.dds), real.dds, mk::CommandSource::Dds);
  add("lcm", config.lcm.enabled, std::move(factories.lcm), real.lcm, mk::CommandSource::Lcm);
  attach(gateway);
}

void GatewayPublishing::attach(Gateway& gw) {
  gw_ = &gw;
  if (!active()) return;
  auto previous = std::move(gw_->on_fe_change);
  gw_->on_fe_change = [this, previous](mapping::FeId fe) {
    if (previous) previous(fe);
    publish_fe(fe);
  };
  for (const auto& fe : gw_->fes()) publish_fe(fe);
  publish_status();
}

void GatewayPublishing::detach() {
  if (!active()) return;
  if (!changed_.empty()) flush();  // the old gateway's last changes
  gw_->on_fe_change = nullptr;
}

std::vector<Publisher*> GatewayPublishing::publishers() const {
  std::vector<Publisher*> out;
  for (const auto& l : links_)
    if (l->transport() != nullptr) out.push_back(l->transport());
  return out;
}

std::vector<TransportState> GatewayPublishing::transports() const {
  std::vector<TransportState> out;
  const canopen::TimePoint now = clock_();
  for (const auto& l : links_) {
    TransportState t{l->name(), l->up(), l->reason(), l->failures(), {}, {}};
    if (!l->up()) {
      t.down_for = now - l->down_since();
      if (const auto next = l->next_attempt()) t.next_attempt_in = std::max(canopen::Duration{0}, *next - now);
    }
    out.push_back(std::move(t));
  }
  return out;
}

std::vector<std::string> GatewayPublishing::degraded() const {
  std::vector<std::string> out;
  for (const auto& l : links_)
    if (!l->up()) out.push_back(l->name() + " down: " + l->reason());
  return out;
}

GatewayPublishing::~GatewayPublishing() {
  if (active() && gw_ != nullptr) gw_->on_fe_change = nullptr;
}

std::int64_t GatewayPublishing::now_us() const {
  return std::chrono::duration_cast<canopen::Duration>(clock_().time_since_epoch()).count();
}

namespace {
std::int64_t to_us(canopen::TimePoint t) {
  return std::chrono::duration_cast<std::chrono::microseconds>(t.time_since_epoch()).count();
}
// The header of a sample: the FE's status and source time (the reception of the frame that
// carried its latest value; fe_model.hpp).
template <class State>
SampleHeader header_of(mapping::FeId fe, const State& st) {
  return SampleHeader{fe.instance, st.h.status, to_us(st.h.source_time), 0};
}
// A node's last EMCY for the status: all zeros before the first.
EmcySample emcy_sample(const Gateway::EmcyRecord& r) {
  if (r.count == 0) return {};
  return EmcySample{r.last.code, r.last.error_register, r.last.msef, to_us(r.time)};
}
// A node's boot diagnostics for the status; `present` marks what it had.
SubdeviceIdentity identity_of(const subdevices::NodeDiagnostics* d) {
  SubdeviceIdentity out;
  if (d == nullptr) return out;
  const std::optional<std::uint32_t>* ids[4] = {&d->vendor_id, &d->product_code, &d->revision, &d->serial};
  std::uint32_t* to[4] = {&out.vendor_id, &out.product_code, &out.revision, &out.serial};
  for (std::size_t k = 0; k < 4; ++k)
    if (*ids[k]) {
      *to[k] = **ids[k];
      out.present = static_cast<std::uint8_t>(out.present | (1u << k));
    }
  const std::optional<std::string>* texts[3] = {&d->device_name, &d->hardware_version, &d->software_version};
  std::string* tt[3] = {&out.device_name, &out.hardware_version, &out.software_version};
  for (std::size_t k = 0; k < 3; ++k)
    if (*texts[k]) {
      *tt[k] = **texts[k];
      out.present = static_cast<std::uint8_t>(out.present | (1u << (4 + k)));
    }
  if (d->error_register) {
    out.error_register = *d->error_register;
    out.present = static_cast<std::uint8_t>(out.present | 0x80u);
  }
  return out;
}
}  // namespace

namespace {
// What a merge of two samples of one FE would lose: everything but the axes' positions.
bool same_discrete(const JoystickSample& a, const JoystickSample& b) {
  return a.h.status == b.h.status && a.buttons == b.buttons && a.memory == b.memory;
}
bool same_discrete(const PedalSample& a, const PedalSample& b) {
  return a.h.status == b.h.status && a.memory == b.memory;
}
bool same_discrete(const WheelSample& a, const WheelSample& b) { return a.h.status == b.h.status; }
bool same_discrete(const EncoderSample& a, const EncoderSample& b) { return a.h.status == b.h.status; }
bool same_discrete(const ButtonClusterSample& a, const ButtonClusterSample& b) {
  return a.h.status == b.h.status && a.switches == b.switches;
}
}  // namespace

void GatewayPublishing::publish_fe(mapping::FeId fe) {
  if (!active()) return;
  std::optional<Sample> s = sample_of(fe);
  if (!s) return;
  if (loop_ == nullptr) {
    send(*s);
    return;
  }
  auto it = std::find_if(changed_.begin(), changed_.end(), [fe](const auto& c) { return c.first == fe; });
  if (it == changed_.end()) {
    changed_.emplace_back(fe, std::move(*s));
  } else {
    const bool mergeable = std::visit(
        [&s](const auto& waiting) {
          using T = std::decay_t<decltype(waiting)>;
          return same_discrete(waiting, std::get<T>(*s));
        },
        it->second);
    if (!mergeable) send(it->second);
    it->second = std::move(*s);
  }
  if (flush_posted_) return;
  flush_posted_ = true;
  loop_->post([this, alive = std::weak_ptr<bool>(alive_)] {
    if (!alive.expired()) flush();
  });
}

void GatewayPublishing::flush() {
  // (A flush the loop never ran, e.g. its batch dropped by a throwing callback, is caught up
  // by the next tick(), which flushes first.)
  flush_posted_ = false;
  for (const auto& [fe, s] : changed_) send(s);
  changed_.clear();  // keeps the capacity: no allocation per wake-up
}

void GatewayPublishing::send(const Sample& s) {
  const std::int64_t now = now_us();
  std::visit([this, now](const auto& sample) { schedule_.update(sample, now); }, s);
}

std::optional<GatewayPublishing::Sample> GatewayPublishing::sample_of(mapping::FeId fe) const {
  // The typed state, as the translators wrote it: no field names, no allocation.
  const FeModel& m = gw_->model();
  switch (fe.kind) {
    case mk::FeKind::Joystick:
      if (const auto* st = m.get<JoystickState>(fe))
        return JoystickSample{header_of(fe, *st), st->x, st->y, st->z, st->buttons, st->memory};
      break;
    case mk::FeKind::FootPedal:
      if (const auto* st = m.get<PedalState>(fe)) return PedalSample{header_of(fe, *st), st->position, st->memory};
      break;
    case mk::FeKind::Wheel:
      if (const auto* st = m.get<WheelState>(fe)) return WheelSample{header_of(fe, *st), st->position};
      break;
    case mk::FeKind::Encoder:
      if (const auto* st = m.get<EncoderState>(fe)) return EncoderSample{header_of(fe, *st), st->position};
      break;
    case mk::FeKind::ButtonCluster:
      if (const auto* st = m.get<ButtonClusterState>(fe)) return ButtonClusterSample{header_of(fe, *st), st->switches};
      break;
    case mk::FeKind::IndicatorCluster:
    case mk::FeKind::Display: break;  // outputs: commanded, not published
  }
  return std::nullopt;
}

void GatewayPublishing::publish_status() {
  GatewayStatus st;
  st.timestamp_us = now_us();
  st.seq = ++status_seq_;
  st.upstream_state = std::string(canopen::to_string(gw_->upstream().node().state()));
  for (const auto& name : gw_->downstream().names()) {
    std::uint8_t node = 0;
    if (auto* d = gw_->downstream().driver(name)) node = d->node().value();
    const Gateway::EmcyRecord e = gw_->subdevice_emcy(name);
    st.subdevices.push_back({name, node, std::string(subdevices::to_string(gw_->downstream().state(name))),
                             emcy_sample(e), e.count, identity_of(gw_->downstream().diagnostics(name))});
  }
  if (!gw_->faults().empty()) st.active_emcys.push_back(OeDevice::kEmcyAdditionalModules);
  if (gw_->reloading()) st.active_emcys.push_back(Gateway::kEmcyReload);
  st.refused_commands = gw_->refused_commands();
  for (const auto& [node, e] : gw_->upstream_emcys()) st.upstream_emcys.push_back({node, emcy_sample(e), e.count});
  fan_.publish(st);
}

void GatewayPublishing::run_on(canopen::io::EventLoop& loop, std::function<void()> rearm,
                               PublisherLink::Attempts attempts) {
  if (!active()) return;
  loop_ = &loop;
  // A transport that comes up gets the status at once; every FE follows within a period (the
  // schedule republishes each one whose last sample is a period old).
  for (auto& l : links_) l->run_on(loop, attempts, rearm, [this] { publish_status(); });
  loop.call_every(loop.now(), std::chrono::microseconds(period_us()), [this, rearm] {
    tick();
    rearm();
  });
}

void GatewayPublishing::tick() {
  if (!active()) return;
  // Changes waiting for this wake-up's flush go first: the timer runs before the flush, and a
  // republish of the older value must not follow the decision that replaced it.
  if (!changed_.empty()) flush();
  schedule_.tick(now_us());
  publish_status();
}

}  // namespace oegw::gateway
