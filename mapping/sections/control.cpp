// The `control` section: the local control socket of `oegw run`
// (docs/reference/control-protocol.md). Only the form is checked here: whether the group exists, or
// the socket's folder, is a fact of the machine, which `oegw check` and `oegw run` ask
// (mapping/deployment.cpp), naming the setting at its file:line:column; the demo and the tests load
// files without them.
#include "mapping/sections/sections.hpp"

namespace oegw::mapping::sections {

namespace {

// A group name as Debian's adduser takes it (NAME_REGEX: a letter or _, then letters, digits,
// _ and -; at most 32 characters, useradd's limit).
bool valid_group_name(std::string_view g) {
  if (g.empty() || g.size() > 32) return false;
  const auto lower = [](char c) { return c >= 'a' && c <= 'z'; };
  if (!lower(g[0]) && g[0] != '_') return false;
  for (const char c : g)
    if (!lower(c) && !(c >= '0' && c <= '9') && c != '_' && c != '-') return false;
  return true;
}

void read_socket(YamlReader& r, const MapEntry& e, ControlConfig& c) {
  const auto s = r.string(e, "control socket");
  if (!s) return;
  if (s->front() != '/') {
    r.error(e.value, "control socket '" + *s + "' is a relative path; expected an absolute path, e.g. " +
                         std::string(kDefaultControlSocket));
  } else if (s->size() > kMaxControlSocketPath) {
    r.error(e.value, "control socket path of " + std::to_string(s->size()) + " characters; expected at most " +
                         std::to_string(kMaxControlSocketPath) + " (a Unix socket address holds no more)");
  } else if (s->back() == '/') {
    r.error(e.value, "control socket '" + *s + "' names a folder; expected the socket file's path, e.g. " +
                         std::string(kDefaultControlSocket));
  } else {
    c.socket = *s;
    c.socket_where = r.loc(e.value);
  }
}

}  // namespace

void read_control(YamlReader& r, const MapEntry& sec, ControlConfig& c) {
  c.where = r.loc(sec.key);
  const auto es = r.entries(sec.value, "control", {"enabled", "socket", "group"}, "a map with enabled, socket, group");
  if (const auto* e = r.find(es, "enabled"))
    if (auto b = r.boolean(*e, "control enabled")) c.enabled = *b;
  if (const auto* e = r.find(es, "socket")) read_socket(r, *e, c);
  if (const auto* e = r.find(es, "group"))
    if (auto g = r.string(*e, "control group")) {
      if (valid_group_name(*g)) {
        c.group = *g;
        c.group_where = r.loc(e->value);
      } else {
        r.error(e->value, "control group '" + *g +
                              "' is not a group name; expected a-z, 0-9, _ and - (starting with a letter or _, at "
                              "most 32), e.g. oegw");
      }
    }
}

}  // namespace oegw::mapping::sections
