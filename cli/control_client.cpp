#include "cli/control_client.hpp"

#include <grp.h>
#include <poll.h>
#include <pwd.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace oegw::cli {

namespace {

// "root:oegw, mode 0660" from the socket file, for the permission message.
std::string owner_of(const std::string& path, std::string& group) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return "";
  const passwd* u = ::getpwuid(st.st_uid);
  const struct group* g = ::getgrgid(st.st_gid);
  group = g ? g->gr_name : std::to_string(st.st_gid);
  char mode[8];
  std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
  return (u ? std::string(u->pw_name) : std::to_string(st.st_uid)) + ":" + group + ", mode " + mode;
}

AskResult connect_failed(const std::string& path, int e) {
  if (e == ENOENT)
    return {AskStatus::NoDaemon,
            "no gateway is running: " + path + " does not exist (is `oegw run` started, with this control.socket?)"};
  if (e == ECONNREFUSED)
    return {AskStatus::NoDaemon, "no gateway is running: nobody listens on " + path + " (left by a run that ended)"};
  if (e == EACCES || e == EPERM) {
    std::string group;
    const std::string owner = owner_of(path, group);
    std::string text = "permission denied on " + path;
    if (!owner.empty()) text += " (" + owner + ")";
    text += group.empty() || group == "root" ? ": ask as root, or set control.group in the mapping file"
                                             : ": ask as root or as a member of group " + group;
    return {AskStatus::PermissionDenied, text};
  }
  return {AskStatus::Failed, "cannot connect to " + path + ": " + std::strerror(e)};
}

}  // namespace

AskResult ask_daemon(const std::string& socket_path, const std::string& request_line,
                     std::chrono::milliseconds timeout) {
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  if (socket_path.empty() || socket_path.size() >= sizeof a.sun_path)
    return {AskStatus::Failed, "'" + socket_path + "' is no socket path"};
  std::memcpy(a.sun_path, socket_path.c_str(), socket_path.size());
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return {AskStatus::Failed, std::string("socket(AF_UNIX): ") + std::strerror(errno)};
  // The daemon serves at most its 8 connections at once; the others wait in its listen queue,
  // and when that is full connect() waits for room: SO_SNDTIMEO bounds that wait (unix(7)), so
  // `timeout` covers the connect too.
  const auto whole = std::chrono::duration_cast<std::chrono::microseconds>(timeout).count();
  const timeval tv{static_cast<time_t>(whole / 1'000'000), static_cast<suseconds_t>(whole % 1'000'000)};
  (void)::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0) {
    const int e = errno;
    ::close(fd);
    if (e == EAGAIN || e == EINPROGRESS)
      return {AskStatus::Timeout, "no answer from " + socket_path + " within " + std::to_string(timeout.count()) +
                                      " ms (its listen queue stayed full)"};
    return connect_failed(socket_path, e);
  }
  const std::string out = request_line + "\n";
  std::size_t sent = 0;
  std::string in;
  AskResult r{AskStatus::Timeout,
              "no answer from " + socket_path + " within " + std::to_string(timeout.count()) + " ms"};
  while (true) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) break;
    pollfd p{fd, static_cast<short>(POLLIN | (sent < out.size() ? POLLOUT : 0)), 0};
    if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) continue;
    if (sent < out.size() && (p.revents & POLLOUT)) {
      const ssize_t n = ::send(fd, out.data() + sent, out.size() - sent, MSG_NOSIGNAL);
      if (n > 0) sent += static_cast<std::size_t>(n);
    }
    if ((p.revents & (POLLIN | POLLHUP | POLLERR)) == 0) continue;
    char buf[65536];
    const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
    if (n <= 0) {
      r = {AskStatus::Failed, "the gateway closed " + socket_path + " without a whole answer"};
      break;
    }
    in.append(buf, static_cast<std::size_t>(n));
    if (const auto nl = in.find('\n'); nl != std::string::npos) {
      r = {AskStatus::Ok, in.substr(0, nl)};
      break;
    }
  }
  ::close(fd);
  return r;
}

}  // namespace oegw::cli
