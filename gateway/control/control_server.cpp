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

#include "canopen/io/user_db.hpp"
#include "gateway/control/control_protocol.hpp"

namespace oegw::gateway::control {

namespace ev = canopen::io::events;

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
  struct stat st {};
  if (::lstat(p.c_str(), &st) != 0) {
    if (errno != ENOENT) throw ControlError(s.where + ": control.socket: cannot use " + p + ": " + err(errno));
    const auto folder = std::filesystem::path(p).parent_path();
    if (::mkdir(folder.c_str(), 0755) != 0 && errno != EEXIST)
      throw ControlError(s.where + ": control.socket: cannot create the folder " + folder.string() + " for " + p +
                         ": " + err(errno));
    return;
  }
  if (!S_ISSOCK(st.st_mode))
    throw ControlError(s.where + ": control.socket: " + p +
                       " exists and is not a socket; remove it or choose another control.socket");
  const int e = probe(p);
  if (e == 0)
    throw ControlError(s.where + ": control.socket: " + p + " is served by a running gateway (`oegw status --socket " +
                       p + "` asks it); stop that one first, or give this gateway its own control.socket");
  if (e != ECONNREFUSED) throw ControlError(s.where + ": control.socket: cannot probe " + p + ": " + err(e));
  if (::unlink(p.c_str()) != 0)
    throw ControlError(s.where + ": control.socket: cannot remove the stale " + p + ": " + err(errno));
  if (s.log)
    s.log("control: removed the stale socket " + p + " (nobody listened on it: a run that ended without removing it)");
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
                     "); create it (groupadd --system " + c.group +
                     ") or leave control.group out (the socket is then "
                     "root's only, mode 0600)");
}

ControlServer::ControlServer(canopen::io::EventLoop& loop, ControlSocketSettings settings, Handler handler)
    : ControlServer(loop, std::move(settings),
                    AsyncHandler([h = std::move(handler)](std::string_view line, Reply reply) { reply(h(line)); })) {}

ControlServer::ControlServer(canopen::io::EventLoop& loop, ControlSocketSettings settings, AsyncHandler handler)
    : loop_(loop), settings_(std::move(settings)), handler_(std::move(handler)) {
  const std::string& p = settings_.path;
  const ControlSocketSettings& s = settings_;
  if (p.empty() || p.size() > mapping::kMaxControlSocketPath)
    throw ControlError(s.where + ": control.socket: '" + p + "' is no socket path");
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
  else if (settings_.group &&
           (::chown(p.c_str(), static_cast<uid_t>(-1), *settings_.group) != 0 || ::chmod(p.c_str(), 0660) != 0))
    failure = "cannot give " + p + " to group " + std::to_string(*settings_.group) + ": " + err(errno);
  else if (::listen(fd_, SOMAXCONN) != 0)  // connections beyond max_clients wait here
    failure = "cannot listen on " + p + ": " + err(errno);
  struct stat st {};
  if (failure.empty() && ::stat(p.c_str(), &st) == 0) {
    dev_ = st.st_dev;
    ino_ = st.st_ino;
  }
  if (!failure.empty()) {
    if (rc == 0) ::unlink(p.c_str());
    ::close(fd_);
    throw ControlError(s.where + ": control.socket: " + failure);
  }
  watch_ = loop_.watch(fd_, ev::kReadable, [this](std::uint32_t) { on_listen(); });
}

ControlServer::~ControlServer() {
  *alive_ = false;
  while (!clients_.empty()) close_client(clients_.begin()->first, false);
  if (listen_again_ != 0) loop_.cancel(listen_again_);
  loop_.unwatch(watch_);
  ::close(fd_);
  // Only our own socket: a later daemon may have replaced a file we were told was stale.
  struct stat st {};
  if (::lstat(settings_.path.c_str(), &st) == 0 && st.st_dev == dev_ && st.st_ino == ino_)
    ::unlink(settings_.path.c_str());
}

namespace {

// Reentrant (canopen/io/user_db.hpp): a reload's thread may look groups up meanwhile.
std::string user_name(uid_t uid) {
  std::vector<char> buf;
  const auto p = canopen::io::look_up<passwd>([uid](passwd* e, char* b, std::size_t n,
                                                    passwd** found) { return ::getpwuid_r(uid, e, b, n, found); },
                                              buf);
  return p ? p->pw_name : "no user of that uid";
}
std::string group_name(gid_t gid) {
  std::vector<char> buf;
  const auto g = canopen::io::look_up<group>([gid](group* e, char* b, std::size_t n,
                                                   group** found) { return ::getgrgid_r(gid, e, b, n, found); },
                                             buf);
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
  p.pid = cred.pid;
  if (cred.uid == 0 || cred.uid == ::geteuid()) return p;
  if (!settings_.group) {
    p.why = "not root: without control.group the gateway answers root only";
    return p;
  }
  const gid_t g = *settings_.group;
  if (cred.gid == g) return p;
  const auto groups = peer_groups(fd);
  if (!groups) p.why = "not root, and its groups cannot be read (SO_PEERGROUPS: " + err(errno) + ")";
  else if (std::find(groups->begin(), groups->end(), g) == groups->end())
    p.why = "not root and not in group " + group_name(g) + " (control.group)";
  return p;
}

void ControlServer::refuse(int fd, const Peer& p) {
  // The user name only here: a name service lookup is no cost an allowed client makes.
  const std::string who = p.uid == static_cast<uid_t>(-1) ? std::string("a client")
                                                          : "uid " + std::to_string(p.uid) + " (" + user_name(p.uid) +
                                                                "), pid " + std::to_string(p.pid);
  const std::string answer = control_error("permission_denied", "refused " + who + ": " + p.why) + "\n";
  (void)!::send(fd, answer.data(), answer.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
  ::close(fd);
  ++refused_;
  const std::uint64_t n = ++refused_by_uid_[p.uid];
  if (n == 1 || n % 100 == 0)
    warn("control: refused " + who + ": " + p.why +
         (n == 1 ? "" : " (" + std::to_string(n) + " refusals of this uid so far)"));
}

std::size_t ControlServer::buffered() const {
  std::size_t n = 0;
  for (const auto& [id, c] : clients_) {
    n += c.in.size() + c.out.size();
    for (const auto& s : c.slots) n += s ? s->size() : 0;
  }
  return n;
}

// The waiting connections while a slot is free, at most max_clients per wake-up: each costs an
// accept, a credentials check and one read, so a wake-up's work stays bounded. With every slot
// taken, one waiting connection per wake-up takes the slot of the client idle the longest, if one
// is idle (never one accepted in this wake-up, which had no time to send); else the listen socket
// is left alone until a slot frees (the connections wait in the kernel's queue, which costs the
// daemon nothing). A peer refused ends the wake-up's accepting: a refusal looks up a user name.
void ControlServer::on_listen() {
  for (std::size_t accepted = 0; accepted < std::max<std::size_t>(settings_.limits.max_clients, 1); ++accepted) {
    std::optional<Id> room;
    if (clients_.size() >= settings_.limits.max_clients) {
      if (accepted > 0) return;  // still readable: the next wake-up
      room = idle_longest();
      if (!room) return listen_for_more(false);
    }
    const int fd = ::accept4(fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) return accept_failed(errno);
    if (accept_failing_) {
      accept_failing_ = false;
      warn("control: accepting connections again");
    }
    if (const Peer p = check_peer(fd); !p.why.empty()) return refuse(fd, p);
    if (room) evict(*room);
    const Id id = next_id_++;
    Client& c = clients_[id];
    c.fd = fd;
    c.last_request = loop_.now();
    c.watch = loop_.watch(fd, ev::kReadable, [this, id](std::uint32_t e) { on_client(id, e); });
    // A request sent with the connect (as `oegw status` does) is read at once: a client with a
    // request in hand is never the one closed to make room.
    if (!read_some(c)) close_client(id, false);
    else settle(id, c);
  }
}

// A client refused, accepting stopped or resumed: `warn`, else `log`.
void ControlServer::warn(const std::string& line) const {
  const auto& out = settings_.warn ? settings_.warn : settings_.log;
  if (out) out(line);
}

// EAGAIN: none waits. Out of descriptors (EMFILE, ENFILE) or kernel memory: the connection stays
// in the listen queue and the socket readable, so the loop would wake for it again at once, and
// again, until a descriptor frees: it listens again after evict_after instead, the connection
// waiting meanwhile. Anything else (the peer gone before its accept): the next readable tries again.
void ControlServer::accept_failed(int error) {
  if (error != EMFILE && error != ENFILE && error != ENOBUFS && error != ENOMEM) return;
  if (!accept_failing_)
    warn("control: cannot accept a connection: " + std::string(std::strerror(error)) +
         "; it waits in the listen queue, and the socket is listened to again every " +
         std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(settings_.limits.evict_after).count()) +
         " ms until one can be");
  accept_failing_ = true;
  listen_for_more(false);
}

void ControlServer::listen_for_more(bool on) {
  if (on == listening_) return;
  listening_ = on;
  loop_.modify(watch_, on ? ev::kReadable : 0u);
  if (listen_again_ != 0) loop_.cancel(listen_again_);
  listen_again_ = 0;
  // Off: a client becomes idle enough by the clock alone; look again then.
  if (!on)
    listen_again_ = loop_.call_after(settings_.limits.evict_after, [this] {
      listen_again_ = 0;
      listen_for_more(true);
    });
}

// A client without a request in progress: none to handle, none owed, no answer waiting to be
// taken (bytes of an unfinished line do not count), and, if it asked before, none for
// evict_after. The one whose last request (or connect) is the oldest.
std::optional<ControlServer::Id> ControlServer::idle_longest() const {
  std::optional<Id> best;
  canopen::TimePoint oldest{};
  const canopen::TimePoint now = loop_.now();
  for (const auto& [id, c] : clients_) {
    if (c.runnable || c.closing || !c.slots.empty() || !c.out.empty() || front(c) != Front::Partial) continue;
    if (c.asked && now - c.last_request < settings_.limits.evict_after) continue;
    if (!best || c.last_request < oldest) {
      best = id;
      oldest = c.last_request;
    }
  }
  return best;
}

void ControlServer::evict(Id id) {
  Client& c = clients_.at(id);
  const auto idle_ms = std::chrono::duration_cast<std::chrono::milliseconds>(loop_.now() - c.last_request).count();
  const std::string line =
      control_error("evicted",
                    "closed to make room for a waiting client: all " + std::to_string(settings_.limits.max_clients) +
                        " connections were taken and this one had no request for " + std::to_string(idle_ms) + " ms") +
      "\n";
  (void)!::send(c.fd, line.data(), line.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
  ++evicted_;
  close_client(id, true);
}

void ControlServer::on_client(Id id, std::uint32_t events) {
  const auto it = clients_.find(id);
  if (it == clients_.end()) return;
  Client& c = it->second;
  // Hang-up: the client closed its socket entirely; no answer can reach it any more.
  if ((events & (ev::kHangup | ev::kError)) != 0) return close_client(id, false);
  if ((events & ev::kReadable) != 0 && !read_some(c)) return close_client(id, false);
  if ((events & ev::kWritable) != 0 && !flush(c)) return close_client(id, false);
  settle(id, c);
}

bool ControlServer::read_some(Client& c) {
  const std::size_t room = settings_.limits.max_request + 1 - std::min(c.in.size(), settings_.limits.max_request + 1);
  if (room == 0 || c.eof || c.closing) return true;
  char buf[8192];
  const ssize_t n = ::recv(c.fd, buf, std::min(room, sizeof buf), MSG_DONTWAIT);
  if (n == 0) {
    c.eof = true;  // the client is done sending: answer what it asked, then close
    return true;
  }
  if (n < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
  c.in.append(buf, static_cast<std::size_t>(n));
  return true;
}

ControlServer::Front ControlServer::front(const Client& c) const {
  const std::size_t nl = c.in.find('\n');
  if (nl == std::string::npos) return c.in.size() > settings_.limits.max_request ? Front::TooLong : Front::Partial;
  return nl > settings_.limits.max_request ? Front::TooLong : Front::Complete;
}

void ControlServer::run_slice() {
  slice_deferred_ = false;
  while (!run_queue_.empty()) {
    const Id id = run_queue_.front();
    run_queue_.pop_front();
    const auto it = clients_.find(id);
    if (it == clients_.end()) continue;  // closed meanwhile
    Client& c = it->second;
    c.runnable = false;
    handle_one(id, c);
    if (!flush(c)) {
      close_client(id, false);
    } else {
      settle(id, c);  // queues it again, behind the others, if it has more
    }
    break;  // one request per slice: the buses come next
  }
  if (!run_queue_.empty() && !slice_deferred_) {
    slice_deferred_ = true;
    loop_.defer([this, alive = std::weak_ptr<bool>(alive_)] {
      if (const auto a = alive.lock(); a && *a) run_slice();
    });
  }
}

void ControlServer::handle_one(Id id, Client& c) {
  const Front f = front(c);
  if (f == Front::Partial) return;
  const std::uint64_t slot = c.first_slot + c.slots.size();
  c.slots.emplace_back();
  c.last_request = loop_.now();
  c.asked = true;
  if (f == Front::TooLong) {
    c.slots.back() = control_error("request_too_long", "a request line is at most " +
                                                           std::to_string(settings_.limits.max_request) + " bytes");
    c.in.clear();
    c.closing = true;
    return deliver(c);
  }
  const std::size_t nl = c.in.find('\n');
  std::string_view line(c.in.data(), nl);
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  const auto waiting = static_cast<std::size_t>(
      std::count_if(c.slots.begin(), c.slots.end(), [](const auto& a) { return !a.has_value(); }));
  if (waiting > settings_.limits.max_waiting) {
    c.slots.back() = control_error("busy", std::to_string(settings_.limits.max_waiting) +
                                               " requests of this connection wait for their answers already");
  } else {
    c.handling = true;  // an answer given at once is taken below, not flushed from inside
    ++handled_;
    handler_(line, [this, id, slot, alive = std::weak_ptr<bool>(alive_)](std::string answer) {
      if (const auto a = alive.lock(); a && *a) on_answer(id, slot, std::move(answer));
    });
    c.handling = false;
  }
  c.in.erase(0, nl + 1);
  deliver(c);
}

void ControlServer::deliver(Client& c) {
  const canopen::TimePoint now = loop_.now();
  if (!c.slots.empty() && c.slots.front()) c.last_request = now;  // an owed answer came: idle from here
  while (!c.slots.empty() && c.slots.front()) {
    c.out += *c.slots.front();
    c.out += '\n';
    c.queued_bytes += c.slots.front()->size() + 1;
    c.unsent.emplace_back(c.queued_bytes, now);
    c.slots.pop_front();
    ++c.first_slot;
    ++answered_;
  }
}

void ControlServer::on_answer(Id id, std::uint64_t slot, std::string line) {
  const auto it = clients_.find(id);
  if (it == clients_.end()) return;  // the client went away meanwhile
  Client& c = it->second;
  if (slot < c.first_slot || slot - c.first_slot >= c.slots.size()) return;
  c.slots[slot - c.first_slot] = std::move(line);
  if (c.handling) return;  // the slice delivers and flushes
  deliver(c);
  if (!flush(c)) return close_client(id, false);
  settle(id, c);
}

bool ControlServer::flush(Client& c) {
  while (!c.out.empty()) {
    const ssize_t n = ::send(c.fd, c.out.data(), c.out.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK) break;
      if (errno == EINTR) continue;
      return false;  // EPIPE: the client went away
    }
    c.out.erase(0, static_cast<std::size_t>(n));
    c.sent_bytes += static_cast<std::uint64_t>(n);
  }
  while (!c.unsent.empty() && c.unsent.front().first <= c.sent_bytes) c.unsent.pop_front();
  return true;
}

void ControlServer::settle(Id id, Client& c) {
  const ControlLimits& lim = settings_.limits;
  const Front f = front(c);
  const bool owed = !c.slots.empty();
  if (c.closing && c.out.empty() && !owed) return close_client(id, false);
  if (c.eof && c.out.empty() && !owed && f != Front::Complete) return close_client(id, false);
  // Requests to handle: queued for a slice while its answers not taken stay below the bound.
  const bool can_run = f != Front::Partial && !c.closing && c.out.size() < lim.max_unsent;
  if (can_run && !c.runnable) {
    c.runnable = true;
    run_queue_.push_back(id);
    if (!slice_deferred_) {
      slice_deferred_ = true;
      loop_.defer([this, alive = std::weak_ptr<bool>(alive_)] {
        if (const auto a = alive.lock(); a && *a) run_slice();
      });
    }
  }
  // Read while there is room for a request (again once half of it is free: one recv per
  // request of a pipelining client would cost a wake-up each) and the answers are taken.
  // A line still partial is read on at once, whatever its length: only more bytes complete it
  // or show it too long.
  const std::size_t room_from =
      (c.events & ev::kReadable) != 0 || f == Front::Partial ? lim.max_request + 1 : lim.max_request / 2 + 1;
  const bool read = !c.eof && !c.closing && c.in.size() < room_from && c.out.size() < lim.max_unsent;
  const std::uint32_t want = (read ? ev::kReadable : 0u) | (c.out.empty() ? 0u : ev::kWritable);
  if (want != c.events) {
    loop_.modify(c.watch, want);
    c.events = want;
  }
  // The one deadline that applies: the oldest answer not taken must be taken within
  // write_timeout; with requests to handle or answers owed none (the command's own time-out
  // bounds an owed answer); else idle_timeout from the last complete request.
  std::optional<canopen::TimePoint> deadline;
  if (!c.unsent.empty()) deadline = c.unsent.front().second + lim.write_timeout;
  else if (!c.runnable && !owed) deadline = c.last_request + lim.idle_timeout;
  if (deadline != c.deadline) {
    if (c.timer != 0) loop_.cancel(c.timer);
    c.timer = 0;
    c.deadline = deadline;
    if (deadline)
      c.timer = loop_.call_at(*deadline, [this, id] {
        if (auto it = clients_.find(id); it != clients_.end()) {
          it->second.timer = 0;
          close_client(id, true);
        }
      });
  }
}

void ControlServer::close_client(Id id, bool dropped) {
  const auto it = clients_.find(id);
  if (it == clients_.end()) return;
  Client& c = it->second;
  loop_.unwatch(c.watch);
  if (c.timer != 0) loop_.cancel(c.timer);
  ::close(c.fd);
  clients_.erase(it);  // a run_queue_ entry of it is skipped
  if (dropped) ++dropped_;
  listen_for_more(true);
}

}  // namespace oegw::gateway::control
