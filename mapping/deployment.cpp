#include "mapping/deployment.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <string>

#include "gateway/publish/lcm_url.hpp"

namespace oegw::mapping {

namespace {

// IFNAMSIZ (linux/if.h) counts the terminating NUL.
constexpr std::size_t kMaxInterfaceName = 15;

// Why the kernel refuses `name` as an interface name (net/core/dev.c dev_valid_name), or "".
std::string interface_name_problem(const std::string& name) {
  if (name.empty()) return "is empty";
  if (name.size() > kMaxInterfaceName)
    return "is " + std::to_string(name.size()) + " bytes long, longer than the kernel's 15 (IFNAMSIZ - 1)";
  if (name == "." || name == "..") return "is '" + name + "', which the kernel refuses";
  for (const char c : name) {
    if (c == '/' || c == ':') return std::string("contains '") + c + "'";
    if (std::isspace(static_cast<unsigned char>(c)) != 0) return "contains white space";
  }
  return "";
}

// The place of a value, or of its section when the value is the default.
Location at(const Location& value, const Location& section) { return value.line != 0 ? value : section; }

struct Bus {
  const char* setting;  // "upstream.interface"
  const std::string& name;
  Location where;
};

void check_interface(const Bus& b, std::vector<Diagnostic>& out) {
  if (b.name == "virtual") {
    out.push_back({b.where, std::string(b.setting) +
                                ": interface virtual is the embedded demo's bus: use oegw demo, or name a CAN "
                                "interface (can0, can1, vcan0, ...)"});
    return;
  }
  if (const std::string why = interface_name_problem(b.name); !why.empty())
    out.push_back({b.where, std::string(b.setting) + " '" + b.name + "' " + why +
                                "; expected a network interface name of 1..15 bytes without '/', ':' or white space"});
}

void check_store(const UpstreamConfig& u, std::vector<Diagnostic>& out) {
  const std::filesystem::path folder = std::filesystem::path(u.store).parent_path();
  std::error_code ec;
  if (folder.empty() || std::filesystem::is_directory(folder, ec)) return;
  const bool written = u.store_where.line != 0;
  out.push_back({at(u.store_where, u.where),
                 "upstream.store " + u.store + (written ? "" : " (the default)") + ": its folder " + folder.string() +
                     " does not exist; expected a file in an existing folder (the unit's StateDirectory=oegw makes "
                     "/var/lib/oegw)"});
}

// LCM commands are opt-in (`sources` listing lcm, config.hpp): liblcm authenticates nothing and
// does not name a message's sender, so an FE taking LCM commands on a URL others can send to is
// commanded by whoever is on that network (SECURITY.md). Warned, not refused: a cab network may
// be closed by other means (a firewall, a cable of its own).
void check_lcm_commands(const Config& c, std::vector<Diagnostic>& out) {
  const auto& lcm = c.publish.lcm;
  if (!lcm.enabled) return;
  std::string fes;
  for (const auto& fe : c.functional_elements)
    if (!fe.input() && fe.accepts(CommandSource::Lcm)) fes += (fes.empty() ? "" : ", ") + fe_name(fe.id);
  if (fes.empty()) return;
  const auto why = gateway::lcm_reaches_beyond_host(lcm.url);
  if (!why) return;
  out.push_back({at(lcm.url_where, lcm.where),
                 "publish.lcm.url " + lcm.url + (lcm.url_where.line != 0 ? "" : " (the default)") +
                     " carries commands for " + fes + " (sources list lcm), and " + *why +
                     "; LCM has no authentication: keep lcm out of their sources, use udpm://224.0.0.1:7667?ttl=0 "
                     "with inbound UDP port 7667 dropped on every interface but lo, or DDS with publish.dds.security"});
}

}  // namespace

std::vector<Diagnostic> deployment_errors(const Config& c) {
  std::vector<Diagnostic> out;
  const Bus up{"upstream.interface", c.upstream.interface, at(c.upstream.interface_where, c.upstream.where)};
  const Bus down{"downstream.interface", c.downstream.interface, at(c.downstream.interface_where, c.downstream.where)};
  check_interface(up, out);
  check_interface(down, out);
  // The gateway is a device on one bus and the master of another (CiA 852 §5): one interface
  // for both would put the sub-devices on the host's bus.
  if (up.name == down.name && up.name != "virtual")
    out.push_back({down.where, "downstream.interface " + down.name + " is upstream.interface too (" +
                                   up.where.line_column() +
                                   "); expected two CAN interfaces: the host's bus and the sub-devices' bus"});
  check_store(c.upstream, out);
  std::stable_sort(out.begin(), out.end(), [](const Diagnostic& a, const Diagnostic& b) {
    return std::pair(a.where.line, a.where.column) < std::pair(b.where.line, b.where.column);
  });
  return out;
}

std::vector<Diagnostic> deployment_warnings(const Config& c) {
  std::vector<Diagnostic> out;
  for (const auto& s : c.subdevices) {
    if (s.mandatory && s.heartbeat_ms == 0)
      out.push_back({s.where, "sub-device '" + s.name +
                                  "' is mandatory with heartbeat_ms 0: its loss is seen only when its PDOs stop "
                                  "(pdo_timeout_ms), not by a heartbeat; give it heartbeat_ms > 0"});
    const bool used = std::any_of(c.functional_elements.begin(), c.functional_elements.end(), [&](const auto& fe) {
      return std::any_of(fe.fields.begin(), fe.fields.end(),
                         [&](const FieldBinding& b) { return b.subdevice == s.name; });
    });
    if (!used)
      out.push_back({s.where, "sub-device '" + s.name +
                                  "' feeds no functional element: it is booted and supervised, but nothing of it "
                                  "reaches the host or the machine application"});
  }
  check_lcm_commands(c, out);
  return out;
}

}  // namespace oegw::mapping
