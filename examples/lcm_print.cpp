#include "lcm_print.hpp"

#include <cinttypes>
#include <cstdarg>
#include <cstdio>
#include <regex>

#include "oegw/button_cluster_t.hpp"
#include "oegw/display_command_t.hpp"
#include "oegw/encoder_t.hpp"
#include "oegw/gateway_status_t.hpp"
#include "oegw/indicator_command_t.hpp"
#include "oegw/joystick_t.hpp"
#include "oegw/pedal_t.hpp"
#include "oegw/wheel_t.hpp"

namespace oegw_examples {

namespace {

std::string format(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
std::string format(const char* fmt, ...) {
  char b[512];
  va_list ap;
  va_start(ap, fmt);
  std::vsnprintf(b, sizeof b, fmt, ap);
  va_end(ap);
  return b;
}

unsigned u8(std::int8_t v) { return static_cast<std::uint8_t>(v); }
unsigned u32(std::int32_t v) { return static_cast<std::uint32_t>(v); }

// "KIND instance=1 status=valid seq=7 ts_us=123": what every FE sample starts with.
template <class Sample>
std::string header(const char* kind, const Sample& s) {
  static const char* const names[] = {"valid", "error", "not_available", "stale", "offline"};
  return format("%s instance=%u status=%s seq=%u ts_us=%lld", kind, u8(s.instance),
                s.status >= 0 && s.status <= 4 ? names[s.status] : "?", u32(s.seq),
                static_cast<long long>(s.timestamp_us));
}

template <class T>
bool decode(T& out, const void* data, std::size_t size) {
  return out.decode(data, 0, static_cast<int>(size)) == static_cast<int>(size);
}

std::vector<std::string> status_lines(const oegw::gateway_status_t& s) {
  std::string active;
  for (const auto code : s.active_emcys)
    active += format("%s%04Xh", active.empty() ? "" : ",", static_cast<unsigned>(static_cast<std::uint16_t>(code)));
  std::vector<std::string> out{format("status seq=%u upstream=%s subdevices=%d emcys=%d refused=%lld active=%s",
                                      u32(s.seq), s.upstream_state.c_str(), s.n_subdevices, s.n_active_emcys,
                                      static_cast<long long>(s.refused_commands),
                                      active.empty() ? "none" : active.c_str())};
  for (const auto& d : s.subdevices)
    out.push_back(format("  subdevice %s node=%02Xh state=%s emcys=%lld", d.name.c_str(),
                         static_cast<unsigned>(d.node_id), d.state.c_str(), static_cast<long long>(d.emcy_count)) +
                  emcy_text(d.last_emcy) + identity_text(d.identity));
  for (const auto& u : s.upstream_emcys)
    out.push_back(format("  upstream_emcy node=%02Xh emcys=%lld", static_cast<unsigned>(u.node_id),
                         static_cast<long long>(u.count)) +
                  emcy_text(u.last));
  return out;
}

}  // namespace

Kind kind_of(const std::string& channel) {
  static const std::regex numbered("(JOYSTICK|PEDAL|WHEEL|ENCODER|BUTTONS|INDICATORS|DISPLAY)_[0-9]+$");
  static const std::pair<const char*, Kind> kinds[] = {{"JOYSTICK", Kind::Joystick}, {"PEDAL", Kind::Pedal},
                                                       {"WHEEL", Kind::Wheel},       {"ENCODER", Kind::Encoder},
                                                       {"BUTTONS", Kind::Buttons},   {"INDICATORS", Kind::Indicators},
                                                       {"DISPLAY", Kind::Display}};
  std::smatch m;
  if (std::regex_search(channel, m, numbered))
    for (const auto& [name, kind] : kinds)
      if (m[1] == name) return kind;
  const std::string status = "STATUS";
  if (channel.size() >= status.size() && channel.compare(channel.size() - status.size(), status.size(), status) == 0)
    return Kind::Status;
  return Kind::Unknown;
}

const char* lcm_type_name(Kind kind) {
  switch (kind) {
    case Kind::Joystick: return "oegw.joystick_t";
    case Kind::Pedal: return "oegw.pedal_t";
    case Kind::Wheel: return "oegw.wheel_t";
    case Kind::Encoder: return "oegw.encoder_t";
    case Kind::Buttons: return "oegw.button_cluster_t";
    case Kind::Indicators: return "oegw.indicator_command_t";
    case Kind::Display: return "oegw.display_command_t";
    case Kind::Status: return "oegw.gateway_status_t";
    case Kind::Unknown: break;
  }
  return "(not an oegw channel)";
}

std::vector<std::string> describe(Kind kind, const void* data, std::size_t size) {
  switch (kind) {
    case Kind::Joystick: {
      oegw::joystick_t j;
      if (!decode(j, data, size)) break;
      return {header("joystick", j) + format(" x=%d y=%d z=%d buttons=0x%02x memory=0x%02x", j.x, j.y, j.z,
                                             static_cast<unsigned>(j.buttons), static_cast<unsigned>(j.memory))};
    }
    case Kind::Pedal: {
      oegw::pedal_t p;
      if (!decode(p, data, size)) break;
      return {header("pedal", p) + format(" position=%d memory=0x%02x", p.position, static_cast<unsigned>(p.memory))};
    }
    case Kind::Wheel: {
      oegw::wheel_t w;
      if (!decode(w, data, size)) break;
      return {header("wheel", w) + format(" position=%d", w.position)};
    }
    case Kind::Encoder: {
      oegw::encoder_t e;
      if (!decode(e, data, size)) break;
      return {header("encoder", e) + format(" position=%d", e.position)};
    }
    case Kind::Buttons: {
      oegw::button_cluster_t b;
      if (!decode(b, data, size)) break;
      return {header("buttons", b) + format(" switches=0x%016" PRIx64, static_cast<std::uint64_t>(b.switches))};
    }
    case Kind::Indicators: {
      oegw::indicator_command_t c;
      if (!decode(c, data, size)) break;
      return {format("indicators instance=%u indicators=0x%016" PRIx64, u8(c.instance),
                     static_cast<std::uint64_t>(c.indicators))};
    }
    case Kind::Display: {
      oegw::display_command_t c;
      if (!decode(c, data, size)) break;
      std::string p;
      for (const auto v : c.parameters) p += format("%s%d", p.empty() ? "" : ",", v);
      return {format("display instance=%u parameters=%s", u8(c.instance), p.c_str())};
    }
    case Kind::Status: {
      oegw::gateway_status_t s;
      if (!decode(s, data, size)) break;
      return status_lines(s);
    }
    case Kind::Unknown: break;
  }
  return {};
}

std::string emcy_text(const oegw::emcy_t& e) {
  return format(" last=%04Xh reg=%02Xh msef=%02x %02x %02x %02x %02x ts_us=%lld",
                static_cast<unsigned>(static_cast<std::uint16_t>(e.code)), static_cast<unsigned>(e.error_register),
                static_cast<unsigned>(e.msef[0]), static_cast<unsigned>(e.msef[1]), static_cast<unsigned>(e.msef[2]),
                static_cast<unsigned>(e.msef[3]), static_cast<unsigned>(e.msef[4]),
                static_cast<long long>(e.timestamp_us));
}

std::string identity_text(const oegw::subdevice_identity_t& id) {
  if (id.present == 0) return " identity=none";
  const std::uint32_t numbers[] = {u32(id.vendor_id), u32(id.product_code), u32(id.revision), u32(id.serial)};
  static const char* const number_names[] = {"vendor", "product", "revision", "serial"};
  const std::string* texts[] = {&id.device_name, &id.hardware_version, &id.software_version};
  static const char* const text_names[] = {"name", "hw", "sw"};
  std::string out;
  for (int k = 0; k < 4; ++k)
    if (id.present & (1u << k)) out += format(" %s=%08Xh", number_names[k], numbers[k]);
  for (int k = 0; k < 3; ++k)
    if (id.present & (1u << (4 + k))) out += format(" %s=\"%s\"", text_names[k], texts[k]->c_str());
  if (id.present & 0x80u) out += format(" err=%02Xh", static_cast<unsigned>(id.error_register));
  return out;
}

void say_nothing_received(const char* prog, const std::string& channels, const char* url, double seconds,
                          const std::string& demo_option) {
  const std::string when = seconds > 0 ? format("within %g s", seconds) : std::string("before it was stopped");
  std::fprintf(stderr, "%s: nothing on the channels matching %s %s (URL %s)\n", prog, channels.c_str(), when.c_str(),
               url);
  if (!demo_option.empty())
    std::fprintf(stderr,
                 "%s: the demo publishes channels OEGW_DEMO_*: %s; a gateway its publish.lcm.channel_prefix "
                 "(default OEGW_) on its publish.lcm.url\n",
                 prog, demo_option.c_str());
  else
    std::fprintf(stderr,
                 "%s: is `oegw demo` running on this computer? A gateway publishes its publish.lcm.channel_prefix "
                 "(default OEGW_) on its publish.lcm.url\n",
                 prog);
}

}  // namespace oegw_examples
