#include "publish/lcm_publisher.hpp"

#include <lcm/lcm.h>

#include <algorithm>
#include <array>
#include <regex>
#include <vector>

#include "oegw/button_cluster_t.hpp"
#include "oegw/display_command_t.hpp"
#include "oegw/emcy_t.hpp"
#include "oegw/encoder_t.hpp"
#include "oegw/gateway_status_t.hpp"
#include "oegw/indicator_command_t.hpp"
#include "oegw/joystick_t.hpp"
#include "oegw/pedal_t.hpp"
#include "oegw/subdevice_state_t.hpp"
#include "oegw/upstream_emcy_t.hpp"
#include "oegw/wheel_t.hpp"
#include "publish/lcm_url.hpp"

namespace oegw::publish {

namespace {
std::int8_t status_of(gateway::FeStatus s) { return static_cast<std::int8_t>(s); }

// The FE channels, "<prefix>JOYSTICK_<n>" …, for instances 1..16: built once, so a sample
// costs no string building.
enum Channel : std::size_t { kJoystick, kPedal, kWheel, kEncoder, kButtons, kChannels };
constexpr std::array<const char*, kChannels> kChannelNames = {"JOYSTICK_", "PEDAL_", "WHEEL_", "ENCODER_", "BUTTONS_"};
}  // namespace

struct LcmPublisher::Impl {
  lcm_t* lcm = nullptr;
  LcmPublisher* owner = nullptr;
  std::string indicators_prefix, display_prefix;
  std::array<std::array<std::string, 17>, kChannels> channels;
  std::vector<std::uint8_t> buf;  // reused: grows to the largest message once

  // Instances are 1..16 (CiA 852 §9.1; the FE model holds no other).
  const std::string& channel(Channel c, std::uint8_t instance) const {
    return channels[c][instance < 17 ? instance : 0];
  }

  // Encodes into the reused buffer and publishes (no allocation for a size seen before).
  template <class M>
  void send(const std::string& ch, const M& m) {
    buf.resize(static_cast<std::size_t>(m.getEncodedSize()));
    if (m.encode(buf.data(), 0, static_cast<int>(buf.size())) < 0) return;
    lcm_publish(lcm, ch.c_str(), buf.data(), static_cast<unsigned>(buf.size()));
  }

  static void on_message(const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
    auto* self = static_cast<Impl*>(user);
    const std::string ch(channel);
    if (ch.rfind(self->indicators_prefix, 0) == 0) {
      oegw::indicator_command_t m;
      if (m.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) < 0) return;
      if (self->owner->on_indicator_command)
        self->owner->on_indicator_command(
            gateway::IndicatorCommand{static_cast<std::uint8_t>(m.instance), static_cast<std::uint64_t>(m.indicators)});
    } else if (ch.rfind(self->display_prefix, 0) == 0) {
      oegw::display_command_t m;
      if (m.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) < 0) return;
      gateway::DisplayCommand c{static_cast<std::uint8_t>(m.instance), {}};
      for (std::size_t k = 0; k < c.parameters.size(); ++k) c.parameters[k] = m.parameters[k];
      if (self->owner->on_display_command) self->owner->on_display_command(c);
    }
  }
};

LcmPublisher::LcmPublisher(const LcmSettings& s) : impl_(std::make_unique<Impl>()), prefix_(s.channel_prefix) {
  // lcm_create() says little on failure (a line on stderr); check the shape first to name it.
  static const std::regex shape(R"(^[a-z]+://[^?]*(\?[A-Za-z_]+=[^&]*(&[A-Za-z_]+=[^&]*)*)?$)");
  if (!std::regex_match(s.url, shape))
    throw PublishConfigError("publish.lcm.url: \"" + s.url +
                             "\" does not parse (expected provider://address[?option=value&...], e.g. "
                             "udpm://224.0.0.1:7667?ttl=0)");
  if (s.channel_prefix.empty() || s.channel_prefix.find_first_of(".*?[]()|^$\\ ") != std::string::npos)
    throw PublishConfigError("publish.lcm.channel_prefix: \"" + s.channel_prefix +
                             "\" must be non-empty, without spaces or regex characters");
  // No route for the group (a controller whose only interface is lo): the machine's state, not
  // the URL's; lcm_create() would fail on it after a page on stderr. Reported, opened later.
  if (const auto problem = lcm_route_problem(s.url))
    throw PublishUnavailable("publish.lcm.url: \"" + s.url + "\": " + *problem +
                             " — add one: " + lcm_route_command(s.url, ""));
  impl_->lcm = lcm_create(s.url.c_str());
  if (impl_->lcm == nullptr) {
    // A tcpq:// server not (yet) listening is the machine's state too.
    if (s.url.rfind("tcpq://", 0) == 0)
      throw PublishUnavailable("publish.lcm.url: cannot open \"" + s.url + "\" (is its LCM server running?)");
    throw PublishConfigError("publish.lcm.url: cannot open \"" + s.url +
                             "\" (unknown provider, bad address or option, or the socket could not be set up)");
  }
  impl_->owner = this;
  for (std::size_t c = 0; c < kChannels; ++c)
    for (std::size_t n = 0; n < 17; ++n) impl_->channels[c][n] = prefix_ + kChannelNames[c] + std::to_string(n);
  impl_->buf.reserve(256);
  impl_->indicators_prefix = prefix_ + "INDICATORS_";
  impl_->display_prefix = prefix_ + "DISPLAY_";
  const std::string pattern = prefix_ + "(INDICATORS|DISPLAY)_[0-9]+";
  if (lcm_subscribe(impl_->lcm, pattern.c_str(), &Impl::on_message, impl_.get()) == nullptr) {
    lcm_destroy(impl_->lcm);
    impl_->lcm = nullptr;
    // udpm: liblcm's self-test did not see its own message (a firewall dropping multicast), or
    // its receive socket could not join the group: the machine's state.
    throw PublishUnavailable("publish.lcm.url: cannot subscribe to the command channels on \"" + s.url +
                             "\" (liblcm's self-test failed: check the multicast route and the firewall)");
  }
}

LcmPublisher::~LcmPublisher() {
  if (impl_->lcm != nullptr) lcm_destroy(impl_->lcm);
}

// The fields every FE message starts with (oegw/*.lcm).
template <class M>
void set_header(M& m, const gateway::SampleHeader& h) {
  m.instance = static_cast<std::int8_t>(h.instance);
  m.status = status_of(h.status);
  m.timestamp_us = h.timestamp_us;
  m.seq = static_cast<std::int32_t>(h.seq);
}

void LcmPublisher::publish(const gateway::JoystickSample& s) {
  oegw::joystick_t m;
  set_header(m, s.h);
  m.x = s.x;
  m.y = s.y;
  m.z = s.z;
  m.buttons = s.buttons;
  m.memory = s.memory;
  impl_->send(impl_->channel(kJoystick, s.h.instance), m);
}
void LcmPublisher::publish(const gateway::PedalSample& s) {
  oegw::pedal_t m;
  set_header(m, s.h);
  m.position = static_cast<std::int32_t>(s.position);  // the 32 bits of UNSIGNED32 (LCM has no unsigned type)
  m.memory = s.memory;
  impl_->send(impl_->channel(kPedal, s.h.instance), m);
}
void LcmPublisher::publish(const gateway::WheelSample& s) {
  oegw::wheel_t m;
  set_header(m, s.h);
  m.position = s.position;
  impl_->send(impl_->channel(kWheel, s.h.instance), m);
}
void LcmPublisher::publish(const gateway::EncoderSample& s) {
  oegw::encoder_t m;
  set_header(m, s.h);
  m.position = s.position;
  impl_->send(impl_->channel(kEncoder, s.h.instance), m);
}
void LcmPublisher::publish(const gateway::ButtonClusterSample& s) {
  oegw::button_cluster_t m;
  set_header(m, s.h);
  m.switches = static_cast<std::int64_t>(s.switches);
  impl_->send(impl_->channel(kButtons, s.h.instance), m);
}
void LcmPublisher::publish(const gateway::GatewayStatus& s) {
  oegw::gateway_status_t m;
  m.timestamp_us = s.timestamp_us;
  m.seq = static_cast<std::int32_t>(s.seq);
  m.upstream_state = s.upstream_state;
  auto emcy = [](const gateway::EmcySample& e) {
    oegw::emcy_t out;
    out.code = static_cast<std::int16_t>(e.code);
    out.error_register = e.error_register;
    std::copy(e.msef.begin(), e.msef.end(), out.msef);
    out.timestamp_us = e.timestamp_us;
    return out;
  };
  for (const auto& d : s.subdevices) {
    oegw::subdevice_state_t sd;
    sd.name = d.name;
    sd.node_id = d.node_id;
    sd.state = d.state;
    sd.last_emcy = emcy(d.last_emcy);
    sd.emcy_count = static_cast<std::int64_t>(d.emcy_count);
    sd.identity.vendor_id = static_cast<std::int32_t>(d.identity.vendor_id);
    sd.identity.product_code = static_cast<std::int32_t>(d.identity.product_code);
    sd.identity.revision = static_cast<std::int32_t>(d.identity.revision);
    sd.identity.serial = static_cast<std::int32_t>(d.identity.serial);
    sd.identity.device_name = d.identity.device_name;
    sd.identity.hardware_version = d.identity.hardware_version;
    sd.identity.software_version = d.identity.software_version;
    sd.identity.error_register = d.identity.error_register;
    sd.identity.present = d.identity.present;
    m.subdevices.push_back(sd);
  }
  m.n_subdevices = static_cast<std::int32_t>(m.subdevices.size());
  for (auto c : s.active_emcys) m.active_emcys.push_back(static_cast<std::int16_t>(c));
  m.n_active_emcys = static_cast<std::int32_t>(m.active_emcys.size());
  m.refused_commands = static_cast<std::int64_t>(s.refused_commands);
  for (const auto& u : s.upstream_emcys) {
    oegw::upstream_emcy_t ue;
    ue.node_id = u.node_id;
    ue.last = emcy(u.last);
    ue.count = static_cast<std::int64_t>(u.count);
    m.upstream_emcys.push_back(ue);
  }
  m.n_upstream_emcys = static_cast<std::int32_t>(m.upstream_emcys.size());
  impl_->send(prefix_ + "STATUS", m);  // once per period: the channel name may be built
}

int LcmPublisher::fd() const { return lcm_get_fileno(impl_->lcm); }

void LcmPublisher::poll() {
  // One message per call
  // (docs/reference/limits.md#can-first-what-the-event-loop-does-beside-the-buses): liblcm's notify
  // pipe stays readable while more wait (lcm_udpm.c writes it again), so the loop comes back after
  // the buses had their turn.
  (void)lcm_handle_timeout(impl_->lcm, 0);
}

}  // namespace oegw::publish
