#include "gateway/publishing.hpp"

#include "gateway/publish/dds_publisher.hpp"
#include "gateway/publish/lcm_publisher.hpp"

namespace oegw::gateway {

namespace mk = oegw::mapping;

GatewayPublishing::GatewayPublishing(Gateway& gateway, const mapping::PublishConfig& config,
                                     std::function<canopen::TimePoint()> clock)
    : gw_(gateway), clock_(std::move(clock)), schedule_(fan_, std::int64_t{config.period_ms} * 1000) {
  if (config.dds.enabled) {
    DdsSettings s;
    s.domain = config.dds.domain;
    s.partition = config.dds.partition;
    s.network = config.dds.network;
    s.period_us = std::int64_t{config.period_ms} * 1000;
    dds_ = std::make_unique<DdsPublisher>(s);
    fan_.add(dds_.get());
  }
  if (config.lcm.enabled) {
    lcm_ = std::make_unique<LcmPublisher>(LcmSettings{config.lcm.url, config.lcm.channel_prefix});
    fan_.add(lcm_.get());
  }
  auto take_commands = [this](Publisher* p, mk::CommandSource source) {
    if (p == nullptr) return;
    p->on_indicator_command = [this, source](const IndicatorCommand& c) {
      (void)gw_.command_indicators(c.instance, c.indicators, clock_(), source);
    };
    p->on_display_command = [this, source](const DisplayCommand& c) {
      (void)gw_.command_display(c.instance, c.parameters, clock_(), source);
    };
  };
  take_commands(dds_.get(), mk::CommandSource::Dds);
  take_commands(lcm_.get(), mk::CommandSource::Lcm);
  if (!active()) return;
  auto previous = std::move(gw_.on_fe_change);
  gw_.on_fe_change = [this, previous](mapping::FeId fe) {
    if (previous) previous(fe);
    publish_fe(fe);
  };
  for (const auto& fe : gw_.fes()) publish_fe(fe);
  publish_status();
}

GatewayPublishing::~GatewayPublishing() {
  if (active()) gw_.on_fe_change = nullptr;
}

std::int64_t GatewayPublishing::now_us() const {
  return std::chrono::duration_cast<canopen::Duration>(clock_().time_since_epoch()).count();
}

void GatewayPublishing::publish_fe(mapping::FeId fe) {
  if (!active()) return;
  SampleHeader h;
  h.instance = fe.instance;
  h.status = gw_.status(fe);
  h.timestamp_us = now_us();
  const auto fields = gw_.fields(fe);
  auto value = [&fields](std::string_view name) -> std::int64_t {
    for (const auto& f : fields)
      if (f.name == name) return f.value;
    return 0;
  };
  // Bit i of the result = field base[i+1] (buttons[1..8], switch[1..64]).
  auto bits = [&fields](std::string_view base) {
    std::uint64_t out = 0;
    for (const auto& f : fields) {
      if (f.name.size() <= base.size() + 2 || f.name.compare(0, base.size(), base) != 0 || f.name[base.size()] != '[') continue;
      const unsigned i = static_cast<unsigned>(std::stoul(f.name.substr(base.size() + 1)));
      if (i >= 1 && i <= 64 && f.value != 0) out |= std::uint64_t{1} << (i - 1);
    }
    return out;
  };
  const std::int64_t now = now_us();
  switch (fe.kind) {
    case mk::FeKind::Joystick: {
      JoystickSample s{h};
      s.x = static_cast<std::int16_t>(value("x"));
      s.y = static_cast<std::int16_t>(value("y"));
      s.z = static_cast<std::int16_t>(value("z"));
      s.buttons = static_cast<std::uint8_t>(bits("buttons"));
      s.memory = static_cast<std::uint8_t>((value("memory_x") ? 1 : 0) | (value("memory_y") ? 2 : 0) | (value("memory_z") ? 4 : 0));
      schedule_.update(s, now);
      break;
    }
    case mk::FeKind::FootPedal: {
      PedalSample s{h};
      s.position = static_cast<std::int16_t>(value("position"));
      s.memory = static_cast<std::uint8_t>(value("memory_x") ? 1 : 0);
      schedule_.update(s, now);
      break;
    }
    case mk::FeKind::Wheel: {
      WheelSample s{h};
      s.position = static_cast<std::int16_t>(value("position"));
      schedule_.update(s, now);
      break;
    }
    case mk::FeKind::Encoder: {
      EncoderSample s{h};
      s.position = static_cast<std::int32_t>(value("position"));
      schedule_.update(s, now);
      break;
    }
    case mk::FeKind::ButtonCluster: {
      ButtonClusterSample s{h};
      s.switches = bits("switch");
      schedule_.update(s, now);
      break;
    }
    case mk::FeKind::IndicatorCluster:
    case mk::FeKind::Display: break;  // outputs: commanded, not published
  }
}

void GatewayPublishing::publish_status() {
  GatewayStatus st;
  st.timestamp_us = now_us();
  st.seq = ++status_seq_;
  st.upstream_state = std::string(canopen::to_string(gw_.upstream().node().state()));
  for (const auto& name : gw_.downstream().names()) {
    std::uint8_t node = 0;
    if (auto* d = gw_.downstream().driver(name)) node = d->node().value();
    st.subdevices.push_back({name, node, std::string(subdevices::to_string(gw_.downstream().state(name)))});
  }
  if (!gw_.faults().empty()) st.active_emcys.push_back(OeDevice::kEmcyAdditionalModules);
  st.refused_commands = gw_.refused_commands();
  fan_.publish(st);
}

void GatewayPublishing::run_on(canopen::EventLoop& loop, std::function<void()> rearm) {
  if (!active()) return;
  for (Publisher* p : publishers())
    if (p->fd() >= 0)
      loop.watch(p->fd(), canopen::io_events::kReadable, [p, rearm](std::uint32_t) {
        p->poll();
        rearm();
      });
  loop.call_every(loop.now(), std::chrono::microseconds(period_us()), [this, rearm] {
    tick();
    rearm();
  });
}

void GatewayPublishing::tick() {
  if (!active()) return;
  schedule_.tick(now_us());
  publish_status();
}

}  // namespace oegw::gateway
