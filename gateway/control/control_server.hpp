// The local control socket of `oegw run` (gateway/control/PROTOCOL.md): a Unix stream socket
// (AF_UNIX only: nothing on a network), served from the gateway's event loop without ever
// blocking it.
//  * The socket file: mode 0600 (its owner, root), or 0660 with the configured group (chown);
//    created so (umask) before anyone could connect. A file already at the path is a stale
//    socket of a run that crashed only when nobody listens on it (connect refused): then it is
//    removed; a socket someone listens on is a live daemon's and is never taken (open() refuses);
//    anything else at the path is refused too. The destructor removes the file if it is still
//    this server's (same inode).
//  * Who is answered: every connection's peer credentials (SO_PEERCRED, SO_PEERGROUPS, unix(7))
//    are checked on accept, whatever the file's mode: root, the daemon's own user, and with a
//    group the processes whose primary or supplementary groups hold it. Anyone else gets one
//    `permission_denied` answer naming the reason and is closed; the refusal is logged with the
//    uid, user name and pid (the first of each uid, then every 100th, so that a local user cannot
//    flood the journal). The file's mode is the first door (the kernel refuses connect() without
//    write permission on it); this is the second, for a mode widened by hand, an fd passed on,
//    a folder of the wrong owner.
//  * Bounds (ControlLimits): the request line's length (longer: an error answer, then the
//    connection is closed), the number of clients (one more: a "busy" answer, closed), the
//    bytes of answers waiting for one client, and two deadlines: a client silent for
//    idle_timeout, or one that has not taken its whole answer within write_timeout, is dropped.
//    Reads and writes are non-blocking; a client that does not read costs the loop nothing.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "canopen/io/event_loop.hpp"
#include "mapping/config.hpp"

namespace oegw::gateway {

// A socket that cannot be served; what() names the setting ("control.socket: ...").
class ControlError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ControlLimits {
  std::size_t max_request = 4096;       // bytes of one request line
  std::size_t max_clients = 8;          // connections served at once
  std::size_t max_waiting = 16;         // requests of one connection waiting for their answers
  std::size_t max_pending = 1u << 20;   // bytes of answers queued for one client
  canopen::Duration idle_timeout = std::chrono::seconds(30);
  canopen::Duration write_timeout = std::chrono::seconds(2);
};

struct ControlSocketSettings {
  std::string where;  // what the errors start with: the setting's file:line:column, or the file
  std::string path;
  std::optional<gid_t> group;  // nullopt: mode 0600
  ControlLimits limits{};
  std::function<void(const std::string&)> log;  // what it did to the file (stale socket removed)
  std::function<void(const std::string&)> warn;  // a client refused (see above); `log` when empty
};

// The settings of the mapping file's `control` section (`file`: the mapping file); ControlError
// naming control.group at its file:line:column when this machine has no such group.
[[nodiscard]] ControlSocketSettings control_settings(const mapping::ControlConfig& c, const std::string& file);

class ControlServer {
 public:
  // The answer line (without newline) to one request line.
  using Handler = std::function<std::string(std::string_view line)>;
  // The same, answered through `reply` — at once or later (an SDO transfer of `oegw ctl`).
  // Answers go out in request order; while a connection waits for one it is not dropped as
  // idle (the command's own time-out bounds the wait). A connection has at most
  // ControlLimits::max_waiting requests waiting; one more is answered `busy` in its turn.
  using Reply = std::function<void(std::string line)>;
  using AsyncHandler = std::function<void(std::string_view line, Reply reply)>;

  // Binds and listens; throws ControlError (see above) and changes nothing on the way out.
  ControlServer(canopen::EventLoop& loop, ControlSocketSettings settings, Handler handler);
  ControlServer(canopen::EventLoop& loop, ControlSocketSettings settings, AsyncHandler handler);
  ~ControlServer();
  ControlServer(const ControlServer&) = delete;
  ControlServer& operator=(const ControlServer&) = delete;

  [[nodiscard]] std::size_t clients() const { return clients_.size(); }
  [[nodiscard]] std::uint64_t dropped() const { return dropped_; }  // clients dropped by a bound
  [[nodiscard]] std::uint64_t answered() const { return answered_; }
  [[nodiscard]] std::uint64_t refused() const { return refused_; }  // peers not allowed (above)

 private:
  struct Client {
    int fd = -1;
    canopen::EventLoop::WatchId watch = 0;
    std::uint32_t events = canopen::io_events::kReadable;  // what `watch` watches
    bool waiting = false;  // an answer waits for the client (write_timeout runs)
    canopen::EventLoop::TimerId timer = 0;
    std::string in, out;
    bool closing = false;  // close once `out` is written (EOF seen, or the request too long)
    // Answers in request order: slot `first_slot` is the oldest request not answered yet.
    std::deque<std::optional<std::string>> slots;
    std::uint64_t first_slot = 0;
    bool reading = false;  // inside read_requests (an answer given at once is flushed there)
  };

  void accept_clients();
  struct Peer {
    uid_t uid = static_cast<uid_t>(-1);
    std::string who = "a client";  // "uid 1001 (anna), pid 4242"
    std::string why;               // empty: may ask; else why not (its answer and the log)
  };
  [[nodiscard]] Peer check_peer(int fd) const;
  void refuse(int fd, const Peer& p);
  void on_client(std::uint64_t id, std::uint32_t events);
  bool read_requests(std::uint64_t id, Client& c);  // false: drop the client
  bool flush(Client& c);          // false: drop the client
  void rewatch(std::uint64_t id, Client& c);
  void arm(std::uint64_t id, Client& c, canopen::Duration d);
  void close_client(std::uint64_t id, bool dropped);
  void on_answer(std::uint64_t id, std::uint64_t slot, std::string line);
  void deliver(Client& c);  // the answers now due, in order, to `out`
  void settle(std::uint64_t id, Client& c, bool ok);  // after reading or writing: close, drop or rewatch

  canopen::EventLoop& loop_;
  ControlSocketSettings settings_;
  AsyncHandler handler_;
  std::shared_ptr<bool> alive_ = std::make_shared<bool>(true);  // answers arriving after the end go nowhere
  int fd_ = -1;
  dev_t dev_ = 0;
  ino_t ino_ = 0;
  canopen::EventLoop::WatchId watch_ = 0;
  std::map<std::uint64_t, Client> clients_;
  std::uint64_t next_id_ = 1;
  std::uint64_t dropped_ = 0;
  std::uint64_t answered_ = 0;
  std::uint64_t refused_ = 0;
  std::map<uid_t, std::uint64_t> refused_by_uid_;
};

}  // namespace oegw::gateway
