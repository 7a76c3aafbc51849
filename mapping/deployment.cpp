#include "mapping/deployment.hpp"

#include <grp.h>
#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "canopen/io/interface_name.hpp"
#include "canopen/io/user_db.hpp"
#include "publish/lcm_url.hpp"

namespace oegw::mapping {

namespace {

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
  if (const std::string why = canopen::io::interface_name_problem(b.name); !why.empty())
    out.push_back({b.where, std::string(b.setting) + " '" + b.name + "' " + why +
                                "; expected a network interface name of 1..15 bytes without '/', ':' or white space"});
}

std::string store_setting(const UpstreamConfig& u) {
  return "upstream.store " + u.store + (u.store_where.line != 0 ? "" : " (the default)");
}

void check_store(const UpstreamConfig& u, std::vector<Diagnostic>& out) {
  if (u.store.empty()) return;
  const std::filesystem::path folder = std::filesystem::path(u.store).parent_path();
  std::error_code ec;
  // The store is read without following a link and replaced by rename (canopen/301/storage.hpp):
  // a link there would be refused at every start, the device running on defaults.
  if (std::filesystem::is_symlink(u.store, ec)) {
    out.push_back({at(u.store_where, u.where),
                   store_setting(u) + " is a symbolic link (to " + std::filesystem::read_symlink(u.store, ec).string() +
                       "); expected a plain file or none: the gateway never follows a link there; name the file "
                       "itself"});
    return;
  }
  if (folder.empty() || std::filesystem::is_directory(folder, ec)) return;
  out.push_back({at(u.store_where, u.where),
                 store_setting(u) + ": its folder " + folder.string() +
                     " does not exist; expected a file in an existing folder (the unit's StateDirectory=oegw makes "
                     "/var/lib/oegw)"});
}

// A store folder every user may write: anyone on the machine can put a store file there before
// the gateway's first save (its parameters are loaded at the next start: PDO mappings, COB-IDs,
// output error values) or a link (the device then runs on defaults). It still runs: a warning.
void check_store_folder(const UpstreamConfig& u, std::vector<Diagnostic>& out) {
  if (u.store.empty()) return;
  std::filesystem::path folder = std::filesystem::path(u.store).parent_path();
  if (folder.empty()) folder = ".";
  struct stat st {};
  if (::stat(folder.c_str(), &st) != 0 || !S_ISDIR(st.st_mode) || (st.st_mode & S_IWOTH) == 0) return;
  char mode[8];
  std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
  out.push_back({at(u.store_where, u.where),
                 store_setting(u) + ": its folder " + folder.string() + " is writable by every user (mode " + mode +
                     "): anyone on this machine can place the parameters the gateway loads at start; keep the store "
                     "in a folder only the daemon's user writes (the unit's StateDirectory=oegw makes /var/lib/oegw, "
                     "mode 0755)"});
}

// The black box's folder (docs/guides/black-box.md): `oegw run` makes it when missing; a
// file at its path, or a path under a file, cannot be a folder.
void check_record(const RecordConfig& r, std::vector<Diagnostic>& out) {
  if (!r.enabled) return;
  std::error_code ec;
  std::filesystem::path p = r.dir;
  const std::string what = "record.dir " + r.dir + (r.dir_where.line != 0 ? "" : " (the default)");
  for (; !p.empty() && p != p.root_path(); p = p.parent_path()) {
    if (!std::filesystem::exists(p, ec)) continue;
    if (std::filesystem::is_directory(p, ec)) return;
    out.push_back(
        {at(r.dir_where, r.where),
         what + ": " + p.string() + " is a file, not a folder; expected a folder oegw run may make or write"});
    return;
  }
}

// Reentrant (canopen/io/user_db.hpp): this may run in a reload's thread beside the event loop.
bool group_exists(const std::string& name) {
  std::vector<char> buf;
  return canopen::io::look_up<group>([&name](group* e, char* b, std::size_t n,
                                             group** found) { return ::getgrnam_r(name.c_str(), e, b, n, found); },
                                     buf)
      .has_value();
}

// What `oegw run` refuses of the control socket on this machine (gateway/control/
// control_server.cpp, which does the same at start): a group the machine lacks; a folder it
// cannot make (it makes the last one only, mode 0755, as /run/oegw below /run); something at
// the path that is no socket. A socket a running gateway serves is not refused here: `oegw
// check` of the running daemon's own file must pass (run says it at start).
void check_control(const ControlConfig& c, std::vector<Diagnostic>& out) {
  if (!c.enabled) return;
  if (!c.group.empty() && !group_exists(c.group))
    out.push_back(
        {at(c.group_where, c.where), "control.group: no group '" + c.group + "' on this machine (getent group " +
                                         c.group + "); create it (groupadd --system " + c.group +
                                         ") or leave control.group out (the socket is then root's only, mode 0600)"});
  namespace fs = std::filesystem;
  const fs::path socket(c.socket);
  const fs::path folder = socket.parent_path();
  const Location where = at(c.socket_where, c.where);
  const std::string what = "control.socket " + c.socket + (c.socket_where.line != 0 ? "" : " (the default)");
  std::error_code ec;
  const fs::file_status f = fs::status(folder, ec);
  if (fs::exists(f) && !fs::is_directory(f)) {
    out.push_back({where, what + ": " + folder.string() + " is not a folder; expected a socket path in a folder"});
    return;
  }
  if (!fs::exists(f)) {
    if (!fs::is_directory(folder.parent_path(), ec))
      out.push_back({where, what + ": its folder " + folder.string() + " does not exist, nor does " +
                                folder.parent_path().string() +
                                " (oegw run makes only the socket's own folder); expected a socket path whose "
                                "folder or its parent exists, e.g. " +
                                std::string(kDefaultControlSocket)});
    return;
  }
  const fs::file_status at_path = fs::symlink_status(socket, ec);
  if (fs::exists(at_path) && !fs::is_socket(at_path))
    out.push_back({where, what + ": " + c.socket +
                              " exists and is not a socket (oegw run would not replace it); remove it or choose "
                              "another control.socket"});
}

// LCM commands are opt-in (`sources` listing lcm, config.hpp): liblcm authenticates nothing and
// does not name a message's sender, so an FE taking LCM commands on a URL others can send to is
// commanded by whoever is on that network (docs/design/threat-model.md). Warned, not refused: a cab
// network may be closed by other means (a firewall, a cable of its own).
void check_lcm_commands(const Config& c, std::vector<Diagnostic>& out) {
  const auto& lcm = c.publish.lcm;
  if (!lcm.enabled) return;
  std::string fes;
  for (const auto& fe : c.functional_elements)
    if (!fe.input() && fe.accepts(CommandSource::Lcm)) fes += (fes.empty() ? "" : ", ") + fe_name(fe.id);
  if (fes.empty()) return;
  const auto why = publish::lcm_reaches_beyond_host(lcm.url);
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
  sort_by_place(out);
  return out;
}

std::vector<Diagnostic> machine_errors(const Config& c) {
  std::vector<Diagnostic> out;
  check_store(c.upstream, out);
  check_control(c.control, out);
  check_record(c.record, out);
  sort_by_place(out);
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

std::vector<Diagnostic> machine_warnings(const Config& c) {
  std::vector<Diagnostic> out;
  check_store_folder(c.upstream, out);
  return out;
}

void sort_by_place(std::vector<Diagnostic>& d) {
  std::stable_sort(d.begin(), d.end(), [](const Diagnostic& a, const Diagnostic& b) {
    return std::pair(a.where.line, a.where.column) < std::pair(b.where.line, b.where.column);
  });
}

}  // namespace oegw::mapping
