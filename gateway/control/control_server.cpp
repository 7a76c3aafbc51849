#include "gateway/control/control_server.hpp"

#include <fcntl.h>
#include <grp.h>
#include <pwd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <vector>

#include "gateway/control/control_protocol.hpp"

namespace oegw::gateway {

namespace ev = canopen::io_events;

namespace {

std::string err(int e) { return std::strerror(e); }

sockaddr_un address(const std::string& path) {
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  std::memcpy(a.sun_path, path.c_str(), std::min(path.size(), sizeof a.sun_path - 1));
  return a;
}

// Somebody listens on `path`: connect() succeeds. ECONNREFUSED: a socket file nobody serves.
int probe(const std::string& path) {
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return errno;
  const sockaddr_un a = address(path);
  const int rc = ::connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a);
  const int e = rc == 0 ? 0 : errno;
  ::close(fd);
  return e;
}

// What is at the path before we bind: nothing, a stale socket (removed), or a refusal.
void clear_the_path(const ControlSocketSettings& s) {
  const std::string& p = s.path;
  struct stat st{};
  if (::lstat(p.c_str(), &st) != 0) {
    if (errno != ENOENT) throw ControlError(s.where + ": control.socket: cannot use " + p + ": " + err(errno));
    const auto folder = std::filesystem::path(p).parent_path();
    if (::mkdir(folder.c_str(), 0755) != 0 && errno != EEXIST)
      throw ControlError(s.where + ": control.socket: cannot create the folder " + folder.string() + " for " + p + ": " +
                         err(errno));
    return;
  }
  if (!S_ISSOCK(st.st_mode))
    throw ControlError(s.where + ": control.socket: " + p + " exists and is not a socket; remove it or choose another control.socket");
  const int e = probe(p);
  if (e == 0)
    throw ControlError(s.where + ": control.socket: " + p + " is served by a running gateway (`oegw status --socket " + p +
                       "` asks it); stop that one first, or give this gateway its own control.socket");
  if (e != ECONNREFUSED) throw ControlError(s.where + ": control.socket: cannot probe " + p + ": " + err(e));
  if (::unlink(p.c_str()) != 0) throw ControlError(s.where + ": control.socket: cannot remove the stale " + p + ": " + err(errno));
  if (s.log) s.log("control: removed the stale socket " + p + " (nobody listened on it: a run that ended without removing it)");
}

}  // namespace

ControlSocketSettings control_settings(const mapping::ControlConfig& c, const std::string& file) {
  ControlSocketSettings s;
  s.path = c.socket;
  s.where = c.socket_where.line != 0 ? c.socket_where.str() : file;
  if (c.group.empty()) return s;
  if (const group* g = ::getgrnam(c.group.c_str())) {
    s.group = g->gr_gid;
    return s;
  }
  const std::string where = c.group_where.line != 0 ? c.group_where.str() : file;
  throw ControlError(where + ": control.group: no group '" + c.group + "' on this machine (getent group " + c.group +
                     "); create it (groupadd --system " + c.group + ") or leave control.group out (the socket is then "
                     "root's only, mode 0600)");
}

ControlServer::ControlServer(canopen::EventLoop& loop, ControlSocketSettings settings, Handler handler)
    : ControlServer(loop, std::move(settings),
                    AsyncHandler([h = std::move(handler)](std::string_view line, Reply reply) { reply(h(line)); })) {}

ControlServer::ControlServer(canopen::EventLoop& loop, ControlSocketSettings settings, AsyncHandler handler)
    : loop_(loop), settings_(std::move(settings)), handler_(std::move(handler)) {
  const std::string& p = settings_.path;
  const ControlSocketSettings& s = settings_;
  if (p.empty() || p.size() > mapping::kMaxControlSocketPath) throw ControlError(s.where + ": control.socket: '" + p + "' is no socket path");
  clear_the_path(settings_);
  fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd_ < 0) throw ControlError(s.where + ": control.socket: socket(AF_UNIX): " + err(errno));
  const sockaddr_un a = address(p);
  // Created as 0600: nobody else can connect between bind() and the chmod below.
  const mode_t old = ::umask(0177);
  const int rc = ::bind(fd_, reinterpret_cast<const sockaddr*>(&a), sizeof a);
  const int bind_errno = errno;
  ::umask(old);
  std::string failure;
  if (rc != 0) failure = "cannot bind " + p + ": " + err(bind_errno);
  else if (settings_.group && (::chown(p.c_str(), static_cast<uid_t>(-1), *settings_.group) != 0 || ::chmod(p.c_str(), 0660) != 0))
    failure = "cannot give " + p + " to group " + std::to_string(*settings_.group) + ": " + err(errno);
  else if (::listen(fd_, 16) != 0)
    failure = "cannot listen on " + p + ": " + err(errno);
  struct stat st{};
  if (failure.empty() && ::stat(p.c_str(), &st) == 0) {
    dev_ = st.st_dev;
    ino_ = st.st_ino;
  }
  if (!failure.empty()) {
    if (rc == 0) ::unlink(p.c_str());
    ::close(fd_);
    throw ControlError(s.where + ": control.socket: " + failure);
  }
  watch_ = loop_.watch(fd_, ev::kReadable, [this](std::uint32_t) { accept_clients(); });
}

ControlServer::~ControlServer() {
  *alive_ = false;
  while (!clients_.empty()) close_client(clients_.begin()->first, false);
  loop_.unwatch(watch_);
  ::close(fd_);
  // Only our own socket: a later daemon may have replaced a file we were told was stale.
  struct stat st{};
  if (::lstat(settings_.path.c_str(), &st) == 0 && st.st_dev == dev_ && st.st_ino == ino_) ::unlink(settings_.path.c_str());
}

namespace {

std::string user_name(uid_t uid) {
  const passwd* p = ::getpwuid(uid);
  return p ? p->pw_name : "no user of that uid";
}
std::string group_name(gid_t gid) {
  const group* g = ::getgrgid(gid);
  return g ? g->gr_name : std::to_string(gid);
}

// The peer's supplementary groups as the kernel recorded them at connect() (SO_PEERGROUPS,
// Linux 4.13): its own credentials, not what /etc/group says of its user name.
std::optional<std::vector<gid_t>> peer_groups(int fd) {
  std::vector<gid_t> groups(64);
  for (int attempt = 0; attempt < 2; ++attempt) {
    socklen_t len = static_cast<socklen_t>(groups.size() * sizeof(gid_t));
    if (::getsockopt(fd, SOL_SOCKET, SO_PEERGROUPS, groups.data(), &len) == 0) {
      groups.resize(len / sizeof(gid_t));
      return groups;
    }
    if (errno != ERANGE) return std::nullopt;
    groups.resize(len / sizeof(gid_t) + 1);  // ERANGE: len says how many there are
  }
  return std::nullopt;
}

}  // namespace

ControlServer::Peer ControlServer::check_peer(int fd) const {
  Peer p;
  ucred cred{};
  socklen_t len = sizeof cred;
  if (::getsockopt(fd, SOL_SOCKET, SO_PEERCRED, &cred, &len) != 0) {
    p.why = std::string("its credentials cannot be read (SO_PEERCRED: ") + err(errno) + ")";
    return p;
  }
  p.uid = cred.uid;
  p.who = "uid " + std::to_string(cred.uid) + " (" + user_name(cred.uid) + "), pid " + std::to_string(cred.pid);
  if (cred.uid == 0 || cred.uid == ::geteuid()) return p;
  if (!settings_.group) {
    p.why = "not root: without control.group the gateway answers root only";
    return p;
  }
  const gid_t g = *settings_.group;
  if (cred.gid == g) return p;
  const auto groups = peer_groups(fd);
  if (!groups)
    p.why = "not root, and its groups cannot be read (SO_PEERGROUPS: " + err(errno) + ")";
  else if (std::find(groups->begin(), groups->end(), g) == groups->end())
    p.why = "not root and not in group " + group_name(g) + " (control.group)";
  return p;
}

void ControlServer::refuse(int fd, const Peer& p) {
  const std::string answer = control_error("permission_denied", "refused " + p.who + ": " + p.why) + "\n";
  (void)!::send(fd, answer.data(), answer.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
  ::close(fd);
  ++refused_;
  const std::uint64_t n = ++refused_by_uid_[p.uid];
  const auto& out = settings_.warn ? settings_.warn : settings_.log;
  if (out && (n == 1 || n % 100 == 0))
    out("control: refused " + p.who + ": " + p.why +
        (n == 1 ? "" : " (" + std::to_string(n) + " refusals of this uid so far)"));
}

void ControlServer::accept_clients() {
  for (;;) {
    const int fd = ::accept4(fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) return;  // EAGAIN: all taken; anything else: the next readable tries again
    if (const Peer p = check_peer(fd); !p.why.empty()) {
      refuse(fd, p);
      continue;
    }
    if (clients_.size() >= settings_.limits.max_clients) {
      const std::string busy = control_error("busy", "the gateway serves " + std::to_string(clients_.size()) +
                                                         " clients already; try again") + "\n";
      (void)!::send(fd, busy.data(), busy.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      ::close(fd);
      ++dropped_;
      continue;
    }
    const std::uint64_t id = next_id_++;
    Client& c = clients_[id];
    c.fd = fd;
    c.watch = loop_.watch(fd, ev::kReadable, [this, id](std::uint32_t e) { on_client(id, e); });
    arm(id, c, settings_.limits.idle_timeout);
  }
}

void ControlServer::on_client(std::uint64_t id, std::uint32_t events) {
  const auto it = clients_.find(id);
  if (it == clients_.end()) return;
  Client& c = it->second;
  const bool ok = ((events & (ev::kReadable | ev::kHangup | ev::kError)) == 0 || c.closing || read_requests(id, c)) &&
                  ((events & ev::kWritable) == 0 || flush(c));
  settle(id, c, ok);
}

void ControlServer::settle(std::uint64_t id, Client& c, bool ok) {
  if (!ok) return close_client(id, false);
  if (c.closing && c.out.empty() && c.slots.empty()) return close_client(id, false);
  if (c.out.size() > settings_.limits.max_pending) return close_client(id, true);
  rewatch(id, c);
}

void ControlServer::deliver(Client& c) {
  while (!c.slots.empty() && c.slots.front()) {
    c.out += *c.slots.front() + "\n";
    c.slots.pop_front();
    ++c.first_slot;
    ++answered_;
  }
}

void ControlServer::on_answer(std::uint64_t id, std::uint64_t slot, std::string line) {
  const auto it = clients_.find(id);
  if (it == clients_.end()) return;  // the client went away meanwhile
  Client& c = it->second;
  if (slot < c.first_slot || slot - c.first_slot >= c.slots.size()) return;
  c.slots[slot - c.first_slot] = std::move(line);
  deliver(c);
  if (!c.reading) settle(id, c, flush(c));
}

bool ControlServer::read_requests(std::uint64_t id, Client& c) {
  char buf[4096];
  for (;;) {
    const ssize_t n = ::recv(c.fd, buf, sizeof buf, MSG_DONTWAIT);
    if (n == 0) {
      c.closing = true;  // the client is done sending: answer what it asked, then close
      break;
    }
    if (n < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK) break;
      if (errno == EINTR) continue;
      return false;
    }
    c.in.append(buf, static_cast<std::size_t>(n));
    for (std::size_t nl; (nl = c.in.find('\n')) != std::string::npos;) {
      std::string_view line(c.in.data(), nl);
      if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
      if (nl > settings_.limits.max_request) break;
      const std::uint64_t slot = c.first_slot + c.slots.size();
      c.slots.emplace_back();
      const auto waiting = static_cast<std::size_t>(
          std::count_if(c.slots.begin(), c.slots.end(), [](const auto& a) { return !a.has_value(); }));
      if (waiting > settings_.limits.max_waiting) {
        c.slots.back() = control_error("busy", std::to_string(settings_.limits.max_waiting) +
                                                   " requests of this connection wait for their answers already");
      } else {
        c.reading = true;  // an answer given at once is taken below, not flushed from inside
        handler_(line, [this, id, slot, alive = std::weak_ptr<bool>(alive_)](std::string answer) {
          if (const auto a = alive.lock(); a && *a) on_answer(id, slot, std::move(answer));
        });
        c.reading = false;
      }
      deliver(c);
      c.in.erase(0, nl + 1);
    }
    if (c.in.size() > settings_.limits.max_request) {
      c.out += control_error("request_too_long", "a request line is at most " +
                                                     std::to_string(settings_.limits.max_request) + " bytes") + "\n";
      c.in.clear();
      c.closing = true;
      break;
    }
  }
  return flush(c);
}

bool ControlServer::flush(Client& c) {
  while (!c.out.empty()) {
    const ssize_t n = ::send(c.fd, c.out.data(), c.out.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK) return true;
      if (errno == EINTR) continue;
      return false;  // EPIPE: the client went away
    }
    c.out.erase(0, static_cast<std::size_t>(n));
  }
  return true;
}

void ControlServer::rewatch(std::uint64_t id, Client& c) {
  // Readable while the client may send (not after its EOF: that would wake the loop for ever),
  // writable while an answer waits.
  const std::uint32_t want = (c.closing ? 0u : ev::kReadable) | (c.out.empty() ? 0u : ev::kWritable);
  if (want != c.events) {
    loop_.unwatch(c.watch);
    c.watch = loop_.watch(c.fd, want, [this, id](std::uint32_t e) { on_client(id, e); });
    c.events = want;
  }
  // An answer waiting: the client has write_timeout to take all of it; then idle_timeout again.
  const bool waiting = !c.out.empty();
  if (!waiting && !c.slots.empty()) {
    // The gateway owes an answer (an SDO transfer): no idle time-out meanwhile, the command's
    // own time-out bounds the wait.
    if (c.timer != 0) loop_.cancel(c.timer);
    c.timer = 0;
    c.waiting = false;
    return;
  }
  if (waiting != c.waiting || !waiting) arm(id, c, waiting ? settings_.limits.write_timeout : settings_.limits.idle_timeout);
  c.waiting = waiting;
}

void ControlServer::arm(std::uint64_t id, Client& c, canopen::Duration d) {
  if (c.timer != 0) loop_.cancel(c.timer);
  c.timer = loop_.call_after(d, [this, id] {
    if (auto it = clients_.find(id); it != clients_.end()) {
      it->second.timer = 0;
      close_client(id, true);
    }
  });
}

void ControlServer::close_client(std::uint64_t id, bool dropped) {
  const auto it = clients_.find(id);
  if (it == clients_.end()) return;
  Client& c = it->second;
  loop_.unwatch(c.watch);
  if (c.timer != 0) loop_.cancel(c.timer);
  ::close(c.fd);
  clients_.erase(it);
  if (dropped) ++dropped_;
}

}  // namespace oegw::gateway
