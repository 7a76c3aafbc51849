#include "gateway/reload.hpp"

#include <algorithm>
#include <set>
#include <string>

#include <fmt/format.h>

#include "subdevices/driver.hpp"

namespace oegw::gateway {

namespace {

using mapping::Config;
using mapping::Location;

// The first of these places `next` writes; the file's first line when it writes none.
Location place(const Config& next, std::initializer_list<Location> candidates) {
  for (const Location& l : candidates)
    if (l.line != 0) return l;
  return Location{next.file, 1, 1};
}

// The FE set as the upstream dictionary has it (CiA 852 clause 9), and the joysticks without
// buttons (1000h, Table 8).
std::set<mapping::FeId> fe_set(const Config& c) {
  std::set<mapping::FeId> out;
  for (const auto& fe : c.functional_elements) out.insert(fe.id);
  return out;
}
bool has_buttons(const mapping::FunctionalElementConfig& fe) {
  return std::any_of(fe.fields.begin(), fe.fields.end(),
                     [](const auto& f) { return f.field.name.rfind("buttons", 0) == 0; });
}

std::string hex_id(std::uint32_t v) { return fmt::format("{:X}h", v); }
std::string identity_text(const mapping::UpstreamIdentity& i) {
  return fmt::format("vendor {:08X}h product {:08X}h revision {:08X}h serial {:08X}h", i.vendor_id, i.product_code,
                     i.revision, i.serial);
}
std::string cob_text(const std::optional<std::uint32_t>& v) { return v ? fmt::format("{:03X}h", *v) : "none"; }

class Refusals {
 public:
  // `setting` changed from `was` to `now`.
  void changed(Location where, const std::string& setting, const std::string& was, const std::string& now,
               const std::string& why) {
    out_.push_back({where, setting + " changed from " + was + " to " + now + ": " + why +
                               "; a reload cannot apply it, a restart can (systemctl restart oegw)"});
  }
  void note(Location where, const std::string& text) {
    out_.push_back({where, text + "; a reload cannot apply it, a restart can (systemctl restart oegw)"});
  }
  std::vector<mapping::Diagnostic> take() {
    std::stable_sort(out_.begin(), out_.end(), [](const mapping::Diagnostic& a, const mapping::Diagnostic& b) {
      return std::pair(a.where.line, a.where.column) < std::pair(b.where.line, b.where.column);
    });
    return std::move(out_);
  }

 private:
  std::vector<mapping::Diagnostic> out_;
};

constexpr const char* kDevice = "the upstream device goes on through a reload";

void upstream_refusals(const Config& a, const Config& b, Refusals& r) {
  const auto& u = a.upstream;
  const auto& v = b.upstream;
  const Location section = place(b, {v.where});
  if (u.interface != v.interface)
    r.changed(place(b, {v.interface_where, v.where}), "upstream.interface", u.interface, v.interface, kDevice);
  if (u.node_id != v.node_id)
    r.changed(section, "upstream.node_id", hex_id(u.node_id), hex_id(v.node_id),
              "the host knows the device by it (heartbeat 700h + node-ID)");
  if (u.bitrate != v.bitrate)
    r.changed(section, "upstream.bitrate", std::to_string(u.bitrate), std::to_string(v.bitrate), kDevice);
  if (u.heartbeat_ms != v.heartbeat_ms)
    r.changed(section, "upstream.heartbeat_ms", std::to_string(u.heartbeat_ms), std::to_string(v.heartbeat_ms),
              "1017h is the host's to change (SDO), the file's at power-on");
  if (u.identity.vendor_id != v.identity.vendor_id || u.identity.product_code != v.identity.product_code ||
      u.identity.revision != v.identity.revision || u.identity.serial != v.identity.serial)
    r.changed(section, "upstream.identity", identity_text(u.identity), identity_text(v.identity),
              "1018h is the LSS address");
  if (u.store != v.store) r.changed(place(b, {v.store_where, v.where}), "upstream.store", u.store, v.store, kDevice);
  const std::size_t n = std::max(u.sdo_servers.size(), v.sdo_servers.size());
  for (std::size_t k = 0; k < n; ++k) {
    const auto setting = fmt::format("upstream.sdo_servers[{}] ({:04X}h) COB-IDs", k + 1, 0x1201 + k);
    if (k >= u.sdo_servers.size() || k >= v.sdo_servers.size()) {
      r.note(k < v.sdo_servers.size() ? place(b, {v.sdo_servers[k].where, v.where}) : section,
             fmt::format("upstream.sdo_servers: {} channels before, {} now: the SDO server objects 1201h.. of the "
                         "upstream device",
                         u.sdo_servers.size(), v.sdo_servers.size()));
      break;
    }
    const auto& x = u.sdo_servers[k];
    const auto& y = v.sdo_servers[k];
    if (x.request != y.request || x.response != y.response)
      r.changed(place(b, {y.request_where, y.response_where, y.where}), setting,
                cob_text(x.request) + "/" + cob_text(x.response), cob_text(y.request) + "/" + cob_text(y.response),
                kDevice);
  }
}

void fe_refusals(const Config& a, const Config& b, Refusals& r) {
  const auto before = fe_set(a);
  const auto after = fe_set(b);
  const Location first = place(b, {b.functional_elements.empty() ? Location{} : b.functional_elements.front().where});
  for (const auto& fe : b.functional_elements)
    if (!before.contains(fe.id))
      r.note(fe.where, mapping::fe_name(fe.id) +
                           " is new: it adds to the upstream device's dictionary (CiA 852 clause 9) and 1000h");
  for (const auto& id : before)
    if (!after.contains(id))
      r.note(first, mapping::fe_name(id) +
                        " is no longer in the file: it leaves the upstream device's dictionary (CiA 852 clause 9) "
                        "and 1000h");
  for (const auto& fe : b.functional_elements) {
    if (fe.id.kind != mapping::FeKind::Joystick) continue;
    const auto* old = a.find_fe(fe.id);
    if (old != nullptr && has_buttons(*old) != has_buttons(fe))
      r.note(fe.where, mapping::fe_name(fe.id) + (has_buttons(fe) ? " gains" : " loses") +
                           " its buttons: 1000h, the device type, changes (CiA 852 Table 8)");
  }
  if (a.subdevices.empty() != b.subdevices.empty())
    r.note(place(b, {b.subdevices.empty() ? Location{} : b.subdevices.front().where}),
           std::string("the file ") + (b.subdevices.empty() ? "no longer has" : "now has") +
               " sub-devices: 3000h (sub-device command) " + (b.subdevices.empty() ? "leaves" : "joins") +
               " the upstream device's dictionary");
}

void program_refusals(const Config& a, const Config& b, Refusals& r) {
  const auto& d = a.downstream;
  const auto& e = b.downstream;
  if (d.interface != e.interface)
    r.changed(place(b, {e.interface_where, e.where}), "downstream.interface", d.interface, e.interface,
              "the gateway's sockets are opened at start");
  if (d.bitrate != e.bitrate)
    r.changed(place(b, {e.where}), "downstream.bitrate", std::to_string(d.bitrate), std::to_string(e.bitrate),
              "the interface's bit rate is set at start");
  const auto& c = a.control;
  const auto& k = b.control;
  if (c.enabled != k.enabled || c.socket != k.socket || c.group != k.group)
    r.note(place(b, {k.socket_where, k.group_where, k.where}),
           "control changed (socket " + c.socket + (c.enabled ? "" : " off") + " group '" + c.group + "' before, " +
               k.socket + (k.enabled ? "" : " off") + " group '" + k.group +
               "' now): the control socket is made at start, and it answers through the reload");
  const auto& ra = a.record;
  const auto& rb = b.record;
  if (ra.enabled != rb.enabled || ra.dir != rb.dir || ra.max_mib != rb.max_mib || ra.span_s != rb.span_s ||
      ra.segments != rb.segments || ra.queue_kib != rb.queue_kib)
    r.note(place(b, {rb.dir_where, rb.where}),
           "record changed: the black box's writer is made at start, and it records through the reload");
  const auto& p = a.publish;
  const auto& q = b.publish;
  const bool dds_same = p.dds.enabled == q.dds.enabled && p.dds.domain == q.dds.domain &&
                        p.dds.partition == q.dds.partition && p.dds.network == q.dds.network &&
                        p.dds.security.has_value() == q.dds.security.has_value() &&
                        (!p.dds.security || p.dds.security->path == q.dds.security->path);
  const bool lcm_same =
      p.lcm.enabled == q.lcm.enabled && p.lcm.url == q.lcm.url && p.lcm.channel_prefix == q.lcm.channel_prefix;
  std::string what;
  const auto add = [&what](bool changed, const char* part) {
    if (changed) what += (what.empty() ? "" : ", ") + std::string(part);
  };
  add(p.period_ms != q.period_ms, "period_ms");
  add(!dds_same, "dds");
  add(!lcm_same, "lcm");
  if (!what.empty())
    r.note(place(b, {q.lcm.url_where, q.lcm.where, q.dds.network_where}),
           "publish changed (" + what +
               "): the DDS participant and the LCM instance are made at start, and their readers keep them");
}

}  // namespace

std::vector<mapping::Diagnostic> reload_refusals(const Config& running, const Config& next) {
  Refusals r;
  upstream_refusals(running, next, r);
  fe_refusals(running, next, r);
  program_refusals(running, next, r);
  return r.take();
}

ReloadDrivers build_reload_drivers(const Config& next) {
  ReloadDrivers out;
  for (const auto& sc : next.subdevices) {
    std::string error;
    auto d = subdevices::make_driver(sc.driver, sc.node(), {}, sc.options, error);
    if (!d)
      out.refusals.push_back({sc.where, error + "; the file changed while it was read: nothing of it is applied"});
    else out.drivers.push_back(std::move(d));
  }
  if (!out.refusals.empty()) out.drivers.clear();
  return out;
}

std::unique_ptr<Gateway> reload_gateway(std::unique_ptr<Gateway> running, const Config& next,
                                        canopen::FrameSink downstream, GatewayOptions options, canopen::TimePoint now,
                                        std::vector<std::unique_ptr<subdevices::Driver>> drivers) {
  running->hand_over(next, now);
  auto log = running->on_log;
  std::unique_ptr<OeDevice> device = running->release_upstream();
  running.reset();
  auto gw = std::make_unique<Gateway>(next, Gateway::HandedOver(std::move(device), std::move(drivers)),
                                      std::move(downstream), std::move(options));
  gw->on_log = std::move(log);
  gw->resume(now);
  return gw;
}

}  // namespace oegw::gateway
