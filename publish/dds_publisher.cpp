#include "publish/dds_publisher.hpp"

#include <net/if.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <vector>

#include "dds/dds.h"
#include "oegw.h"
#include "publish/dds_samples.hpp"

namespace oegw::publish {

std::string dds_config_xml(const std::string& network, const std::optional<DdsSecuritySettings>& security) {
  if (network.empty()) return {};
  const std::string sec = security ? dds_security_xml(*security) : "";
  if (network == "loopback") {
    // Test and demo traffic stays on this host (docs/guides/dds-lcm.md#network): checked to send
    // nothing on eth0 (tests/publish/demo_stays_on_host.sh).
    return "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces>"
           "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
           "<Peers><Peer address=\"127.0.0.1\"/></Peers></Discovery>" +
           sec + "</Domain></CycloneDDS>";
  }
  return "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface name=\"" + network +
         "\"/></Interfaces></General>" + sec + "</Domain></CycloneDDS>";
}

namespace {

dds_entity_t check(dds_entity_t e, const char* what) {
  if (e < 0) throw PublishConfigError(std::string("publish.dds: ") + what + ": " + dds_strretcode(e));
  return e;
}

// Cyclone says why a domain cannot be created only in its log ("Error" is all the return code
// tells): while the domain and participant are created, its error lines are collected here
// (and not printed) to go into the exception.
class CycloneErrors {
 public:
  CycloneErrors() { dds_set_log_sink(&CycloneErrors::sink, this); }
  ~CycloneErrors() { dds_set_log_sink(nullptr, nullptr); }
  CycloneErrors(const CycloneErrors&) = delete;
  CycloneErrors& operator=(const CycloneErrors&) = delete;
  [[nodiscard]] std::string text() const { return text_.empty() ? "" : " — " + text_; }

 private:
  static void sink(void* self, const dds_log_data_t* d) {
    if ((d->priority & (DDS_LC_FATAL | DDS_LC_ERROR | DDS_LC_WARNING)) == 0 || d->message == nullptr) return;
    // `message` is the text alone (the default sink prints a header of `hdrsize` bytes before it).
    std::string m(d->message, d->size);
    while (!m.empty() && (m.back() == '\n' || m.back() == ' ')) m.pop_back();
    auto& t = static_cast<CycloneErrors*>(self)->text_;
    if (!m.empty()) t += (t.empty() ? "" : "; ") + m;
  }
  std::string text_;
};

}  // namespace

struct DdsPublisher::Impl {
  dds_entity_t domain = 0;  // >0 when this publisher created the domain (with the raw config)
  dds_entity_t participant = 0;
  dds_entity_t joystick = 0, pedal = 0, wheel = 0, encoder = 0, buttons = 0, status = 0;  // writers
  dds_entity_t indicators = 0, display = 0;                                               // readers
  int event_fd = -1;
  bool display_first = false;  // poll(): which topic is looked at first (they take turns)

  static void on_data(dds_entity_t /*reader*/, void* arg) {
    const std::uint64_t one = 1;
    // A full counter only means poll() has work already; nothing to do on failure.
    [[maybe_unused]] auto n = ::write(static_cast<Impl*>(arg)->event_fd, &one, sizeof one);
  }

  ~Impl() {
    if (participant > 0) dds_delete(participant);
    if (domain > 0) dds_delete(domain);
    if (event_fd >= 0) ::close(event_fd);
  }
};

DdsPublisher::DdsPublisher(const DdsSettings& s) : impl_(std::make_unique<Impl>()) {
  if (s.period_us <= 0) throw PublishConfigError("publish.dds.period: must be > 0");
  if (s.security) {
    // Cyclone's plugins would refuse these too, but say so only in its log, naming no setting.
    const auto problems = check_dds_security(*s.security);
    if (!problems.empty()) {
      std::string text;
      for (const auto& p : problems) text += (text.empty() ? "" : "; ") + dds_security_setting(p.file) + " " + p.text;
      throw PublishConfigError(text);
    }
    if (s.network.empty())
      throw PublishConfigError(
          "publish.dds.security: needs publish.dds.network loopback or an interface (with \"\" "
          "CYCLONEDDS_URI configures the domain)");
  }
  // An interface that is not there (yet: a cab network brought up after the daemon) is the
  // machine's state, not a wrong setting: reported as such, and opened again later.
  if (!s.network.empty() && s.network != "loopback" && ::if_nametoindex(s.network.c_str()) == 0)
    throw PublishUnavailable("publish.dds.network: interface " + s.network + " is not on this machine (" +
                             std::strerror(errno) + ")");
  const std::string xml = dds_config_xml(s.network, s.security);
  CycloneErrors errors;
  if (!xml.empty()) {
    // The configuration travels with the domain (dds_create_domain's raw config) rather than the
    // process environment: no other component's CYCLONEDDS_URI changes it, and nothing to clean up.
    // A domain this process created already (another publisher, a test's command writer) is shared.
    const dds_entity_t d = dds_create_domain(s.domain, xml.c_str());
    if (d > 0) {
      impl_->domain = d;
    } else if (d != DDS_RETCODE_PRECONDITION_NOT_MET) {
      throw PublishConfigError("publish.dds.domain: cannot create domain " + std::to_string(s.domain) + ": " +
                               dds_strretcode(d) + (s.network.empty() ? "" : " (network '" + s.network + "')") +
                               errors.text());
    }
  }
  impl_->participant = dds_create_participant(s.domain, nullptr, nullptr);
  if (impl_->participant < 0)
    throw PublishConfigError(std::string(s.security ? "publish.dds.security" : "publish.dds.domain") +
                             ": cannot create domain " + std::to_string(s.domain) + ": " +
                             dds_strretcode(impl_->participant) + errors.text());

  const dds_entity_t pp = impl_->participant;
  dds_qos_t* pqos = dds_create_qos();
  dds_qset_partition1(pqos, s.partition.c_str());
  const dds_entity_t pub = dds_create_publisher(pp, pqos, nullptr);
  const dds_entity_t sub = dds_create_subscriber(pp, pqos, nullptr);
  dds_delete_qos(pqos);
  check(pub, "create publisher");
  check(sub, "create subscriber");

  // Control data: reliable, the newest value per instance only, a deadline of one period.
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_MSECS(10));
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1);
  dds_qset_deadline(q, DDS_USECS(s.period_us));
  auto writer = [&](const dds_topic_descriptor_t* desc, const char* kind, const dds_qos_t* qos) {
    const std::string name = s.topic_prefix + kind;
    const dds_entity_t t = check(dds_create_topic(pp, desc, name.c_str(), nullptr, nullptr), name.c_str());
    return check(dds_create_writer(pub, t, qos, nullptr), name.c_str());
  };
  impl_->joystick = writer(&oegw_Joystick_desc, "joystick", q);
  impl_->pedal = writer(&oegw_Pedal_desc, "pedal", q);
  impl_->wheel = writer(&oegw_Wheel_desc, "wheel", q);
  impl_->encoder = writer(&oegw_Encoder_desc, "encoder", q);
  impl_->buttons = writer(&oegw_ButtonCluster_desc, "buttons", q);
  dds_delete_qos(q);

  dds_qos_t* sq = dds_create_qos();
  dds_qset_reliability(sq, DDS_RELIABILITY_RELIABLE, DDS_MSECS(10));
  dds_qset_history(sq, DDS_HISTORY_KEEP_LAST, 1);
  dds_qset_durability(sq, DDS_DURABILITY_TRANSIENT_LOCAL);
  impl_->status = writer(&oegw_GatewayStatus_desc, "status", sq);
  dds_delete_qos(sq);

  // Commands: a listener (Cyclone's thread) only signals the eventfd; poll() takes them.
  impl_->event_fd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (impl_->event_fd < 0) throw PublishConfigError(std::string("publish.dds: eventfd: ") + std::strerror(errno));
  dds_listener_t* l = dds_create_listener(impl_.get());
  dds_lset_data_available(l, &Impl::on_data);
  dds_qos_t* cq = dds_create_qos();
  dds_qset_reliability(cq, DDS_RELIABILITY_RELIABLE, DDS_MSECS(10));
  dds_qset_history(cq, DDS_HISTORY_KEEP_LAST, 1);
  auto reader = [&](const dds_topic_descriptor_t* desc, const char* kind) {
    const std::string name = s.topic_prefix + kind;
    const dds_entity_t t = check(dds_create_topic(pp, desc, name.c_str(), nullptr, nullptr), name.c_str());
    return check(dds_create_reader(sub, t, cq, l), name.c_str());
  };
  impl_->indicators = reader(&oegw_IndicatorCommand_desc, "indicators");
  impl_->display = reader(&oegw_DisplayCommand_desc, "display");
  dds_delete_qos(cq);
  dds_delete_listener(l);
}

DdsPublisher::~DdsPublisher() = default;

// Every sample is zero-filled first, padding included (dds_samples.hpp: Cyclone copies it onto the wire).
template <class Sample, class Dds>
static void write(dds_entity_t writer, const Sample& s) {
  Dds m;
  dds_samples::fill(s, m);
  dds_write(writer, &m);
}
void DdsPublisher::publish(const gateway::JoystickSample& s) {
  write<gateway::JoystickSample, oegw_Joystick>(impl_->joystick, s);
}
void DdsPublisher::publish(const gateway::PedalSample& s) { write<gateway::PedalSample, oegw_Pedal>(impl_->pedal, s); }
void DdsPublisher::publish(const gateway::WheelSample& s) { write<gateway::WheelSample, oegw_Wheel>(impl_->wheel, s); }
void DdsPublisher::publish(const gateway::EncoderSample& s) {
  write<gateway::EncoderSample, oegw_Encoder>(impl_->encoder, s);
}
void DdsPublisher::publish(const gateway::ButtonClusterSample& s) {
  write<gateway::ButtonClusterSample, oegw_ButtonCluster>(impl_->buttons, s);
}
void DdsPublisher::publish(const gateway::GatewayStatus& s) {
  // dds_write serialises; the sample only borrows these buffers.
  auto emcy = [](const gateway::EmcySample& e) {
    oegw_Emcy m;
    dds_samples::fill(e, m);
    return m;
  };
  // string<32>: a fixed array of 33 chars in the generated type.
  auto bounded = [](char* to, std::size_t size, const std::string& from) {
    const std::size_t n = std::min(size - 1, from.size());
    std::copy_n(from.data(), n, to);
    to[n] = '\0';
  };
  std::vector<oegw_SubdeviceState> subs;
  subs.reserve(s.subdevices.size());
  for (const auto& d : s.subdevices) {
    oegw_SubdeviceState x{};
    x.name = const_cast<char*>(d.name.c_str());
    x.node_id = d.node_id;
    x.state = const_cast<char*>(d.state.c_str());
    x.last_emcy = emcy(d.last_emcy);
    x.emcy_count = d.emcy_count;
    const gateway::SubdeviceIdentity& i = d.identity;
    x.identity.vendor_id = i.vendor_id;
    x.identity.product_code = i.product_code;
    x.identity.revision = i.revision;
    x.identity.serial = i.serial;
    bounded(x.identity.device_name, sizeof x.identity.device_name, i.device_name);
    bounded(x.identity.hardware_version, sizeof x.identity.hardware_version, i.hardware_version);
    bounded(x.identity.software_version, sizeof x.identity.software_version, i.software_version);
    x.identity.error_register = i.error_register;
    x.identity.present = i.present;
    subs.push_back(x);
  }
  std::vector<std::uint16_t> emcys(s.active_emcys);
  std::vector<oegw_UpstreamEmcy> upstream;
  upstream.reserve(s.upstream_emcys.size());
  for (const auto& u : s.upstream_emcys) {
    oegw_UpstreamEmcy x{};  // value-initialised: zero, padding included
    x.node_id = u.node_id;
    x.last = emcy(u.last);
    x.count = u.count;
    upstream.push_back(x);
  }
  oegw_GatewayStatus m{};
  m.timestamp_us = s.timestamp_us;
  m.seq = s.seq;
  m.upstream_state = const_cast<char*>(s.upstream_state.c_str());
  m.subdevices._maximum = m.subdevices._length = static_cast<std::uint32_t>(subs.size());
  m.subdevices._buffer = subs.data();
  m.subdevices._release = false;
  m.active_emcys._maximum = m.active_emcys._length = static_cast<std::uint32_t>(emcys.size());
  m.active_emcys._buffer = emcys.data();
  m.active_emcys._release = false;
  m.refused_commands = s.refused_commands;
  m.upstream_emcys._maximum = m.upstream_emcys._length = static_cast<std::uint32_t>(upstream.size());
  m.upstream_emcys._buffer = upstream.data();
  m.upstream_emcys._release = false;
  dds_write(impl_->status, &m);
}

int DdsPublisher::fd() const { return impl_->event_fd; }

namespace {
// Takes one sample of `reader` (keep-last 1 per instance: at most one per commanded instance
// waits) and hands its data to `use`; false when none was there.
template <class Sample, class Use>
bool take_one(dds_entity_t reader, Use&& use) {
  void* ptr = nullptr;
  dds_sample_info_t info{};
  if (dds_take(reader, &ptr, &info, 1, 1) <= 0) return false;
  if (info.valid_data) use(*static_cast<const Sample*>(ptr));
  dds_return_loan(reader, &ptr, 1);
  return true;
}
}  // namespace

void DdsPublisher::poll() {
  // One command per call
  // (docs/reference/limits.md#can-first-what-the-event-loop-does-beside-the-buses): a command taken
  // signals the eventfd again, so the loop comes back for the next one after the buses had their
  // turn. The two topics take turns.
  std::uint64_t n = 0;
  [[maybe_unused]] auto r = ::read(impl_->event_fd, &n, sizeof n);  // EAGAIN: nothing signalled; take anyway
  const auto indicators = [this] {
    return take_one<oegw_IndicatorCommand>(impl_->indicators, [this](const oegw_IndicatorCommand& m) {
      if (on_indicator_command) on_indicator_command(gateway::IndicatorCommand{m.instance, m.indicators});
    });
  };
  const auto display = [this] {
    return take_one<oegw_DisplayCommand>(impl_->display, [this](const oegw_DisplayCommand& m) {
      gateway::DisplayCommand c{m.instance, {}};
      for (std::size_t k = 0; k < c.parameters.size(); ++k) c.parameters[k] = m.parameters[k];
      if (on_display_command) on_display_command(c);
    });
  };
  impl_->display_first = !impl_->display_first;
  const bool took = impl_->display_first ? (display() || indicators()) : (indicators() || display());
  if (took) Impl::on_data(0, impl_.get());
}

std::uint32_t DdsPublisher::joystick_readers() const {
  dds_publication_matched_status_t st{};
  if (dds_get_publication_matched_status(impl_->joystick, &st) < 0) return 0;
  return st.current_count;
}

}  // namespace oegw::publish
