// The local control socket of `oegw run` (docs/reference/control-protocol.md): a Unix stream socket
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
//  * Bounds (ControlLimits), so that no client can hold a CAN frame back or grow the daemon
//    (docs/reference/limits.md#can-first-what-the-event-loop-does-beside-the-buses). Requests are
//    handled in the event loop's deferred slices (EventLoop::defer): one request per slice, the
//    clients in turn, so a bus frame waits for at most one request's work. A client's socket is
//    read at most once per wake-up and only while its unread requests fit in max_request + 1 bytes
//    and its answers not taken stay below max_unsent: what it sends beyond stays in the kernel's
//    socket buffer. A request line longer than max_request gets an error answer, then the
//    connection is closed. At most max_clients connections are served; more wait in the listen
//    queue (the kernel's, SOMAXCONN deep; at most max_clients are accepted per wake-up) until a
//    slot frees, and while one waits, a client that holds a slot without a request in progress
//    (the one idle the longest) is closed to make room: a slow client cannot keep `oegw status`
//    out. Deadlines: idle_timeout from the last complete request (or the connect; bytes that
//    complete none do not count), write_timeout for the oldest answer the client has not taken.
//    Reads and writes never block.
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

namespace oegw::gateway::control {

// A socket that cannot be served; what() names the setting ("control.socket: ...").
class ControlError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ControlLimits {
  std::size_t max_request = 4096;      // bytes of one request line
  std::size_t max_clients = 8;         // connections served at once; more wait in the listen queue
  std::size_t max_waiting = 16;        // requests of one connection waiting for their answers
  std::size_t max_unsent = 64u << 10;  // bytes of answers not taken beyond which a client's requests wait
  canopen::Duration idle_timeout = std::chrono::seconds(30);  // from the last complete request
  canopen::Duration write_timeout = std::chrono::seconds(2);  // for the oldest answer not taken
  // A client that has asked before gives its slot to a waiting connection only after this long
  // without a request (one that never asked, at once): `oegw ctl` between two lines keeps it.
  canopen::Duration evict_after = std::chrono::seconds(1);
};

struct ControlSocketSettings {
  std::string where;  // what the errors start with: the setting's file:line:column, or the file
  std::string path;
  std::optional<gid_t> group;  // nullopt: mode 0600
  ControlLimits limits{};
  std::function<void(const std::string&)> log;   // what it did to the file (stale socket removed)
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
  ControlServer(canopen::io::EventLoop& loop, ControlSocketSettings settings, Handler handler);
  ControlServer(canopen::io::EventLoop& loop, ControlSocketSettings settings, AsyncHandler handler);
  ~ControlServer();
  ControlServer(const ControlServer&) = delete;
  ControlServer& operator=(const ControlServer&) = delete;

  [[nodiscard]] std::size_t clients() const { return clients_.size(); }
  [[nodiscard]] const ControlLimits& limits() const { return settings_.limits; }
  // Clients closed by a bound: idle, write time-out, made room for a waiting one (evicted).
  [[nodiscard]] std::uint64_t dropped() const { return dropped_; }
  [[nodiscard]] std::uint64_t evicted() const { return evicted_; }  // of those, to make room
  [[nodiscard]] std::uint64_t answered() const { return answered_; }
  [[nodiscard]] std::uint64_t handled() const { return handled_; }  // requests given to the handler
  [[nodiscard]] std::uint64_t refused() const { return refused_; }  // peers not allowed (above)
  // Bytes held for the clients now: requests read and not handled, answers not taken. At most
  // max_clients x (max_request + 1 + max_unsent + the answers of max_waiting + 1 requests).
  [[nodiscard]] std::size_t buffered() const;

 private:
  using Id = std::uint64_t;
  struct Client {
    int fd = -1;
    canopen::io::EventLoop::WatchId watch = 0;
    std::uint32_t events = canopen::io::events::kReadable;  // what `watch` waits for
    std::string in;                                         // bytes read and not handled: at most max_request + 1
    std::string out;                                        // answers not taken yet
    // When each answer in `out` was queued, by the stream offset it ends at: the oldest one's
    // age is what write_timeout bounds.
    std::deque<std::pair<std::uint64_t, canopen::TimePoint>> unsent;
    std::uint64_t queued_bytes = 0, sent_bytes = 0;
    // Answers in request order: slot `first_slot` is the oldest request not answered yet.
    std::deque<std::optional<std::string>> slots;
    std::uint64_t first_slot = 0;
    // The last complete request taken or answer given (or the connect): idle_timeout counts from
    // it; bytes that complete no request do not move it.
    canopen::TimePoint last_request{};
    canopen::io::EventLoop::TimerId timer = 0;
    std::optional<canopen::TimePoint> deadline;  // what `timer` is armed for
    bool asked = false;                          // it completed a request once
    bool eof = false;                            // the client shut its sending side: answer what it asked, then close
    bool closing = false;                        // its request was too long: close once that answer is taken
    bool runnable = false;                       // in run_queue_
    bool handling = false;                       // inside the handler: an answer given at once is flushed by the slice
  };
  enum class Front : std::uint8_t { Partial, Complete, TooLong };  // the first line of `in`

  void on_listen();
  struct Peer {
    uid_t uid = static_cast<uid_t>(-1);
    pid_t pid = 0;
    std::string why;  // empty: may ask; else why not (its answer and the log)
  };
  [[nodiscard]] Peer check_peer(int fd) const;
  void refuse(int fd, const Peer& p);
  [[nodiscard]] std::optional<Id> idle_longest() const;  // a client to close for a waiting one
  void evict(Id id);
  void on_client(Id id, std::uint32_t events);
  bool read_some(Client& c);  // one recv; false: drop the client
  [[nodiscard]] Front front(const Client& c) const;
  void run_slice();
  void handle_one(Id id, Client& c);
  bool flush(Client& c);          // false: drop the client
  void settle(Id id, Client& c);  // after any change: close, re-watch, queue, re-arm
  void close_client(Id id, bool dropped);
  void on_answer(Id id, std::uint64_t slot, std::string line);
  void deliver(Client& c);  // the answers now due, in order, to `out`
  void listen_for_more(bool on);
  void accept_failed(int error);  // accept4's errno
  void warn(const std::string& line) const;

  canopen::io::EventLoop& loop_;
  ControlSocketSettings settings_;
  AsyncHandler handler_;
  std::shared_ptr<bool> alive_ = std::make_shared<bool>(true);  // answers arriving after the end go nowhere
  int fd_ = -1;
  dev_t dev_ = 0;
  ino_t ino_ = 0;
  canopen::io::EventLoop::WatchId watch_ = 0;
  bool listening_ = true;                             // the listen socket is watched (off while every slot is busy)
  canopen::io::EventLoop::TimerId listen_again_ = 0;  // while off: when a client may have become idle
  bool accept_failing_ = false;                       // out of descriptors at the last accept: logged once
  std::map<Id, Client> clients_;
  std::deque<Id> run_queue_;  // clients with a request to handle, in turn
  bool slice_deferred_ = false;
  Id next_id_ = 1;
  std::uint64_t dropped_ = 0;
  std::uint64_t evicted_ = 0;
  std::uint64_t answered_ = 0;
  std::uint64_t handled_ = 0;
  std::uint64_t refused_ = 0;
  std::map<uid_t, std::uint64_t> refused_by_uid_;
};

}  // namespace oegw::gateway::control
