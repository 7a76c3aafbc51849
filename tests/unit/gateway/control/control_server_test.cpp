// The control socket's server (gateway/control/control_server.hpp) on real Unix sockets in a
// temporary folder, its loop on a simulated clock: descriptors are served by run_once(0), the
// bounds' deadlines fire only when the test moves the clock (nothing sleeps).
#include "gateway/control/control_server.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "canopen/io/clock.hpp"
#include "cli/control_client.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace oegw::gateway;
using namespace oegw::cli;
using namespace oegw::gateway::control;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

namespace {

class ControlServerTest : public ::testing::Test {
 protected:
  ControlServerTest() : loop_(clock_) {
    dir_ = fs::path(::testing::TempDir()) / ("control_server_" + std::to_string(::getpid()) + "_" +
                                             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    path_ = (dir_ / "oegw.sock").string();
  }
  ~ControlServerTest() override { fs::remove_all(dir_); }

  ControlSocketSettings settings(ControlLimits limits = {}) {
    return {"test.yaml", path_, std::nullopt, limits, [this](const std::string& l) { log_ += l + "\n"; }};
  }
  std::unique_ptr<ControlServer> serve(ControlLimits limits = {}) {
    return std::make_unique<ControlServer>(loop_, settings(limits), [this](std::string_view line) {
      return answer_ ? answer_(line) : "answer to " + std::string(line);
    });
  }
  int connect_client() const {
    const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::strncpy(a.sun_path, path_.c_str(), sizeof a.sun_path - 1);
    EXPECT_EQ(::connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a), 0) << std::strerror(errno);
    return fd;
  }
  static void send_text(int fd, const std::string& s) {
    ASSERT_EQ(::send(fd, s.data(), s.size(), MSG_NOSIGNAL), static_cast<ssize_t>(s.size()));
  }
  // What the client has received so far (non-blocking); `eof` says whether the server closed.
  static std::string received(int fd, bool* eof = nullptr) {
    std::string out;
    char buf[65536];
    for (;;) {
      const ssize_t n = ::recv(fd, buf, sizeof buf, MSG_DONTWAIT);
      if (n > 0) {
        out.append(buf, static_cast<std::size_t>(n));
        continue;
      }
      if (eof) *eof = n == 0;
      return out;
    }
  }
  void serve_io(int rounds = 5) {
    for (int i = 0; i < rounds; ++i) loop_.run_once(0ms);
  }

  SimulatedClock clock_;
  EventLoop loop_;
  fs::path dir_;
  std::string path_;
  std::string log_;
  std::function<std::string(std::string_view)> answer_;
};

TEST_F(ControlServerTest, AnswersEachRequestLineInOrderAndRemovesItsSocketAtTheEnd) {
  auto server = serve();
  struct stat st {};
  ASSERT_EQ(::lstat(path_.c_str(), &st), 0);
  EXPECT_TRUE(S_ISSOCK(st.st_mode));
  EXPECT_EQ(st.st_mode & 0777, 0600u) << "without control.group: its owner's only";
  const int fd = connect_client();
  send_text(fd, "one\ntwo\r\nthr");
  serve_io();
  EXPECT_EQ(received(fd), "answer to one\nanswer to two\n");
  send_text(fd, "ee\n");
  serve_io();
  EXPECT_EQ(received(fd), "answer to three\n");
  ::shutdown(fd, SHUT_WR);  // the client is done: the server closes its end
  serve_io();
  bool eof = false;
  EXPECT_EQ(received(fd, &eof), "");
  EXPECT_TRUE(eof);
  EXPECT_EQ(server->clients(), 0u);
  ::close(fd);
  server.reset();
  EXPECT_FALSE(fs::exists(fs::symlink_status(path_))) << "removed at exit";
}

TEST_F(ControlServerTest, TheGroupGetsTheSocketWithMode0660) {
  auto s = settings();
  s.group = ::getgid();  // a group this process may give its files to
  ControlServer server(loop_, s, [](std::string_view) { return std::string("x"); });
  struct stat st {};
  ASSERT_EQ(::lstat(path_.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0660u);
  EXPECT_EQ(st.st_gid, ::getgid());
}

TEST_F(ControlServerTest, AStaleSocketIsReplacedAndALiveOneIsNeverTaken) {
  {  // a run that crashed: its socket file stays, nobody listens
    const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::strncpy(a.sun_path, path_.c_str(), sizeof a.sun_path - 1);
    ASSERT_EQ(::bind(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a), 0);
    ::close(fd);
  }
  auto live = serve();
  EXPECT_NE(log_.find("control: removed the stale socket " + path_), std::string::npos) << log_;
  try {
    auto second = serve();
    FAIL() << "a second server took a live socket";
  } catch (const ControlError& e) {
    EXPECT_EQ(std::string(e.what()),
              "test.yaml: control.socket: " + path_ + " is served by a running gateway (`oegw status --socket " +
                  path_ + "` asks it); stop that one first, or give this gateway its own control.socket");
  }
  const int fd = connect_client();  // the first still answers on its file
  send_text(fd, "still\n");
  serve_io();
  EXPECT_EQ(received(fd), "answer to still\n");
  ::close(fd);
}

TEST_F(ControlServerTest, AFileThatIsNoSocketIsRefusedAndKept) {
  std::ofstream(path_) << "mine";
  EXPECT_THROW(
      {
        try {
          serve();
        } catch (const ControlError& e) {
          EXPECT_EQ(std::string(e.what()),
                    "test.yaml: control.socket: " + path_ +
                        " exists and is not a socket; remove it or choose another control.socket");
          throw;
        }
      },
      ControlError);
  std::ifstream in(path_);
  std::string text;
  in >> text;
  EXPECT_EQ(text, "mine");
}

TEST_F(ControlServerTest, AMissingFolderIsCreated) {
  path_ = (dir_ / "run" / "oegw.sock").string();
  auto server = serve();
  EXPECT_TRUE(fs::is_socket(path_));
}

TEST_F(ControlServerTest, ARequestLongerThanTheBoundIsAnsweredWithAnErrorAndClosed) {
  auto server = serve(ControlLimits{.max_request = 64});
  const int fd = connect_client();
  send_text(fd, std::string(65, 'a'));  // no newline yet, already too long
  serve_io();
  bool eof = false;
  const std::string got = received(fd, &eof);
  EXPECT_NE(got.find("\"code\":\"request_too_long\""), std::string::npos) << got;
  EXPECT_NE(got.find("at most 64 bytes"), std::string::npos) << got;
  EXPECT_TRUE(eof);
  EXPECT_EQ(server->handled(), 0u) << "the handler never saw it";
  ::close(fd);
}

// Short requests, then a line longer than the bound, sent at once: the first read ends inside the
// long line, and once the short ones are handled what is left of it (more than half the bound) is
// still read, found too long, answered and the connection closed, not left waiting for the idle
// time-out.
TEST_F(ControlServerTest, ALongLineAfterShortOnesIsStillReadAndFoundTooLong) {
  auto server = serve();
  const int fd = connect_client();
  send_text(fd, "a\nb\n" + std::string(5000, 'x') + "\n");
  serve_io(20);
  const std::string got = received(fd);
  EXPECT_EQ(got.rfind("answer to a\nanswer to b\n", 0), 0u) << got;
  EXPECT_NE(got.find("\"code\":\"request_too_long\""), std::string::npos) << got;
  EXPECT_EQ(server->clients(), 0u) << "closed (the client sees ECONNRESET: bytes it sent were left unread)";
  ::close(fd);
}

TEST_F(ControlServerTest, OneClientMoreThanTheBoundWaitsInTheListenQueueUntilASlotFrees) {
  auto server = serve(ControlLimits{.max_clients = 2});
  const int a = connect_client(), b = connect_client();
  send_text(a, "a\n");
  send_text(b, "b\n");
  serve_io();
  const int c = connect_client();  // the kernel queues it: connect() succeeds
  send_text(c, "c\n");
  serve_io();
  EXPECT_EQ(server->clients(), 2u);
  EXPECT_EQ(received(a), "answer to a\n");
  EXPECT_EQ(received(c), "") << "both slots hold clients that asked just now";
  ::close(a);
  serve_io();
  EXPECT_EQ(received(c), "answer to c\n") << "a's slot went to the waiting client";
  EXPECT_EQ(server->evicted(), 0u);
  for (const int fd : {b, c}) ::close(fd);
}

// Out of descriptors, accept4 fails (EMFILE) with the connection still queued and the socket still
// readable: the listener pauses for evict_after instead of waking the loop again at once, and takes
// the connection once it can.
TEST_F(ControlServerTest, OutOfDescriptorsTheListenerPausesInsteadOfWakingTheLoopAgainAtOnce) {
  auto server = serve();
  const int a = connect_client();  // queued by the kernel
  send_text(a, "a\n");
  rlimit old{};
  ASSERT_EQ(::getrlimit(RLIMIT_NOFILE, &old), 0);
  const int lowest_free = ::dup(0);
  ASSERT_GE(lowest_free, 0);
  ::close(lowest_free);
  rlimit tight = old;
  tight.rlim_cur = static_cast<rlim_t>(lowest_free);  // no new descriptor: the accept gets EMFILE
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &tight), 0);
  const std::size_t first = loop_.run_once(0ms);
  const std::size_t second = loop_.run_once(0ms);
  const std::size_t third = loop_.run_once(0ms);
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &old), 0);
  EXPECT_EQ(first, 1u) << "the accept that failed";
  EXPECT_EQ(second + third, 0u) << "the loop woke again for a connection it cannot take";
  EXPECT_EQ(server->clients(), 0u);
  EXPECT_NE(log_.find("control: cannot accept a connection: Too many open files"), std::string::npos) << log_;
  serve_io();
  EXPECT_EQ(received(a), "") << "taken before the pause ended";
  loop_.advance_by(ControlLimits{}.evict_after);
  serve_io();
  EXPECT_EQ(received(a), "answer to a\n");
  EXPECT_NE(log_.find("control: accepting connections again"), std::string::npos) << log_;
  ::close(a);
}

// Connections waiting at once are accepted in one wake-up while a slot is free, each with its
// request read, not one per wake-up; the rest wait in the listen queue.
TEST_F(ControlServerTest, ConnectionsWaitingAtOnceAreAcceptedInOneWakeUpWhileASlotIsFree) {
  auto server = serve(ControlLimits{.max_clients = 4});
  std::vector<int> fds;
  for (int i = 0; i < 6; ++i) {
    fds.push_back(connect_client());
    send_text(fds.back(), "q" + std::to_string(i) + "\n");
  }
  loop_.run_once(0ms);
  EXPECT_EQ(server->clients(), 4u) << "the four a slot was free for, in one wake-up";
  serve_io(10);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(received(fds[i]), "answer to q" + std::to_string(i) + "\n");
  EXPECT_EQ(received(fds[4]), "") << "waits in the listen queue: every slot holds a client that asked just now";
  for (int i = 0; i < 4; ++i) ::close(fds[i]);
  serve_io(10);
  EXPECT_EQ(received(fds[4]), "answer to q4\n");
  EXPECT_EQ(received(fds[5]), "answer to q5\n");
  EXPECT_EQ(server->evicted(), 0u);
  for (int i = 4; i < 6; ++i) ::close(fds[i]);
}

TEST_F(ControlServerTest, AClientThatDoesNotReadIsDroppedWithoutBlockingTheLoop) {
  answer_ = [](std::string_view) { return std::string(4 * 1024 * 1024, 'x'); };  // more than socket buffers hold
  auto server = serve(ControlLimits{.write_timeout = 2s});
  const int fd = connect_client();
  send_text(fd, "status\n");
  serve_io();  // returns: the rest waits in the server, the loop goes on
  EXPECT_EQ(server->clients(), 1u);
  loop_.advance_by(1900ms);
  EXPECT_EQ(server->clients(), 1u) << "within write_timeout";
  loop_.advance_by(200ms);
  EXPECT_EQ(server->clients(), 0u);
  EXPECT_EQ(server->dropped(), 1u);
  ::close(fd);
}

// A client that asks and never reads: once its answers not taken reach max_unsent, nothing more
// of it is read or handled (what it sends stays in the kernel's buffer, the daemon holds at most
// the bound and one answer), and it is closed write_timeout after the oldest answer it left.
TEST_F(ControlServerTest, AClientThatDoesNotReadItsAnswersGetsNothingMoreHandledAndIsClosed) {
  int handled = 0;
  answer_ = [&handled](std::string_view) {
    ++handled;
    return std::string(16 * 1024, 'x');
  };
  const ControlLimits limits{.max_unsent = 64 * 1024, .write_timeout = 2s};
  auto server = serve(limits);
  const int fd = connect_client();
  std::size_t sent = 0;
  for (int round = 0; round < 2000; ++round) {  // as much as the socket takes, never reading
    const std::string line = "status\n";
    if (::send(fd, line.data(), line.size(), MSG_NOSIGNAL | MSG_DONTWAIT) > 0) ++sent;
    loop_.run_once(0ms);
    EXPECT_LE(server->buffered(), limits.max_request + 1 + limits.max_unsent + 16 * 1024 + 1);
  }
  EXPECT_GT(sent, static_cast<std::size_t>(handled) + 100) << "the rest waits in the kernel, unread";
  const int at_bound = handled;
  serve_io(50);
  EXPECT_EQ(handled, at_bound) << "nothing more handled while its answers are not taken";
  EXPECT_EQ(server->clients(), 1u);
  loop_.advance_by(2100ms);
  EXPECT_EQ(server->clients(), 0u) << "closed after the write time-out";
  EXPECT_EQ(server->dropped(), 1u);
  ::close(fd);
}

TEST_F(ControlServerTest, ASilentClientIsDroppedAfterTheIdleTimeout) {
  auto server = serve(ControlLimits{.idle_timeout = 30s});
  const int fd = connect_client();
  serve_io();
  loop_.advance_by(29s);
  EXPECT_EQ(server->clients(), 1u);
  send_text(fd, "x\n");  // a request restarts the count
  serve_io();
  loop_.advance_by(29s);
  EXPECT_EQ(server->clients(), 1u);
  loop_.advance_by(2s);
  EXPECT_EQ(server->clients(), 0u);
  ::close(fd);
}

// `oegw ctl`'s SDO commands answer later: answers still go out in request order, a connection
// waiting for one is not dropped as idle, one whose client left gets nothing (and nothing breaks),
// and more requests waiting than the bound are answered busy in their turn.
TEST_F(ControlServerTest, LaterAnswersGoOutInRequestOrder) {
  std::vector<ControlServer::Reply> later;
  auto server = std::make_unique<ControlServer>(loop_, settings(ControlLimits{.max_waiting = 2, .idle_timeout = 30s}),
                                                ControlServer::AsyncHandler(
                                                    [&later](std::string_view line, ControlServer::Reply reply) {
                                                      if (line == "now") return reply("at once");
                                                      later.push_back(std::move(reply));
                                                    }));
  const int fd = connect_client();
  send_text(fd, "slow\nnow\nslow\nnow\n");
  serve_io();
  // Two wait ("slow", "slow"); the first "now" waits behind the first; the last "now" is one
  // request more than max_waiting may wait: answered busy, in its turn.
  ASSERT_EQ(later.size(), 2u);
  EXPECT_EQ(received(fd), "");
  loop_.advance_by(31s);  // owed answers: no idle drop
  EXPECT_EQ(server->clients(), 1u);
  later[1]("second");
  serve_io();
  EXPECT_EQ(received(fd), "");  // the first is still owed
  later[0]("first");
  serve_io();
  const std::string got = received(fd);
  EXPECT_EQ(got.substr(0, got.find("{")), "first\nat once\nsecond\n");
  EXPECT_NE(got.find("\"busy\""), std::string::npos) << got;
  EXPECT_EQ(server->answered(), 4u);
  // A client that shut its sending side still gets what it asked, then is closed.
  send_text(fd, "slow\n");
  serve_io();
  ASSERT_EQ(later.size(), 3u);
  ::shutdown(fd, SHUT_WR);
  serve_io();
  EXPECT_EQ(server->clients(), 1u);  // a client that only shut down its side still gets it
  later[2]("in time");
  serve_io();
  EXPECT_EQ(received(fd), "in time\n");
  EXPECT_EQ(server->clients(), 0u);
  ::close(fd);
  // A client gone entirely (its socket closed): closed at once, its answer goes nowhere.
  const int gone = connect_client();
  send_text(gone, "slow\n");
  serve_io();
  ASSERT_EQ(later.size(), 4u);
  ::close(gone);
  serve_io();
  EXPECT_EQ(server->clients(), 0u);
  later[3]("too late");
  serve_io();
  // And one given after the server is gone changes nothing either.
  const int fd2 = connect_client();
  send_text(fd2, "slow\n");
  serve_io();
  ASSERT_EQ(later.size(), 5u);
  server.reset();
  later[4]("after the end");
  ::close(fd2);
}

// The budget (docs/reference/limits.md#can-first-what-the-event-loop-does-beside-the-buses): 20,000
// requests pipelined on one connection are handled one per wake-up, in the loop's deferred slices,
// and a bus descriptor that is ready the whole time is served between every two of them: a bus
// frame waits for at most one request's work. The daemon's buffers stay within their bounds
// throughout. Counted, not timed.
TEST_F(ControlServerTest, PipelinedRequestsAreHandledOnePerWakeUpWithTheBusServedBetween) {
  int handled = 0;
  answer_ = [&handled](std::string_view line) {
    ++handled;
    return "answer to " + std::string(line);
  };
  const ControlLimits limits{};
  auto server = serve(limits);
  int bus_pipe[2];
  ASSERT_EQ(::pipe2(bus_pipe, O_NONBLOCK | O_CLOEXEC), 0);
  ASSERT_EQ(::write(bus_pipe[1], "f", 1), 1);  // a CAN socket with a backlog: readable throughout
  int bus_turns = 0;
  int handled_at_last_turn = 0;
  int most_between_turns = 0;
  loop_.watch(bus_pipe[0], events::kReadable, [&](std::uint32_t) {
    ++bus_turns;
    most_between_turns = std::max(most_between_turns, handled - handled_at_last_turn);
    handled_at_last_turn = handled;
  });
  const int fd = connect_client();
  constexpr int kRequests = 20'000;
  const std::string request = R"({"command":"status"})";
  std::string to_send;
  for (int i = 0; i < kRequests; ++i) to_send += request + "\n";
  std::size_t sent = 0;
  std::size_t answers = 0;
  int most_per_wake_up = 0;
  std::size_t most_buffered = 0;
  char buf[65536];
  for (int wake_ups = 0; answers < kRequests && wake_ups < 10 * kRequests; ++wake_ups) {
    if (sent < to_send.size()) {
      const ssize_t n = ::send(fd, to_send.data() + sent, to_send.size() - sent, MSG_NOSIGNAL | MSG_DONTWAIT);
      if (n > 0) sent += static_cast<std::size_t>(n);
    }
    const int before = handled;
    loop_.run_once(0ms);
    most_per_wake_up = std::max(most_per_wake_up, handled - before);
    most_buffered = std::max(most_buffered, server->buffered());
    for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, MSG_DONTWAIT)) > 0;)
      answers += static_cast<std::size_t>(std::count(buf, buf + n, '\n'));
  }
  EXPECT_EQ(answers, static_cast<std::size_t>(kRequests));
  EXPECT_EQ(handled, kRequests);
  EXPECT_EQ(most_per_wake_up, 1) << "one request per wake-up";
  EXPECT_EQ(most_between_turns, 1) << "the bus descriptor is served between every two requests";
  EXPECT_GE(bus_turns, kRequests);
  EXPECT_LE(most_buffered, limits.max_request + 1 + limits.max_unsent) << "bounded memory per client";
  ::close(fd);
  ::close(bus_pipe[0]);
  ::close(bus_pipe[1]);
}

// The idle time-out counts from the last complete request: a client that trickles bytes of a
// request it never completes is closed idle_timeout after its connect, however often it sends.
TEST_F(ControlServerTest, AClientThatTricklesBytesWithoutCompletingARequestIsClosedWhenIdle) {
  auto server = serve(ControlLimits{.idle_timeout = 30s});
  const int fd = connect_client();
  serve_io();
  for (int s = 0; s < 29; ++s) {
    send_text(fd, "{");
    serve_io();
    loop_.advance_by(1s);
    ASSERT_EQ(server->clients(), 1u) << "within idle_timeout of its connect, at " << s << " s";
  }
  send_text(fd, "{");
  serve_io();
  loop_.advance_by(1s);
  EXPECT_EQ(server->clients(), 0u) << "30 s after its connect, the bytes in between did not count";
  EXPECT_EQ(server->dropped(), 1u);
  ::close(fd);
}

// Slow clients cannot keep others out: with every slot held, a waiting connection takes the slot
// of a client without a request in progress — one that never completed a request at once, one
// that did after evict_after — and that client is told why. One that asked just now keeps its.
TEST_F(ControlServerTest, AWaitingClientTakesTheSlotOfAnIdleOne) {
  auto server = serve(ControlLimits{.max_clients = 8, .evict_after = 1s});
  std::vector<int> slow;
  for (int i = 0; i < 8; ++i) {
    slow.push_back(connect_client());
    send_text(slow.back(), "{\"comm");  // a request it never completes
    serve_io();
  }
  EXPECT_EQ(server->clients(), 8u);
  const int status = connect_client();
  send_text(status, "status\n");
  serve_io();
  EXPECT_EQ(received(status), "answer to status\n");
  EXPECT_EQ(server->evicted(), 1u);
  bool eof = false;
  const std::string told = received(slow.front(), &eof);
  EXPECT_NE(told.find("\"code\":\"evicted\""), std::string::npos) << told;
  EXPECT_TRUE(eof) << "the one connected first made room";
  for (const int fd : slow) ::close(fd);
  ::close(status);
  serve_io();
  EXPECT_EQ(server->clients(), 0u);
}

// With every slot taken, one waiting connection per wake-up takes an idle client's slot: a
// wake-up's accepting never closes a client it accepted itself.
TEST_F(ControlServerTest, OneIdleClientIsClosedPerWakeUpToMakeRoom) {
  auto server = serve(ControlLimits{.max_clients = 2});
  const int idle1 = connect_client(), idle2 = connect_client();  // they never ask
  serve_io();
  EXPECT_EQ(server->clients(), 2u);
  const int a = connect_client(), b = connect_client();
  send_text(a, "a\n");
  send_text(b, "b\n");
  loop_.run_once(0ms);
  EXPECT_EQ(server->evicted(), 1u) << "one per wake-up";
  loop_.run_once(0ms);
  EXPECT_EQ(server->evicted(), 2u);
  serve_io();
  EXPECT_EQ(received(a), "answer to a\n");
  EXPECT_EQ(received(b), "answer to b\n");
  for (const int fd : {idle1, idle2, a, b}) ::close(fd);
}

TEST_F(ControlServerTest, AClientThatAskedKeepsItsSlotForEvictAfter) {
  auto server = serve(ControlLimits{.max_clients = 1, .evict_after = 1s});
  const int ctl = connect_client();  // `oegw ctl` between two lines
  send_text(ctl, "events\n");
  serve_io();
  EXPECT_EQ(received(ctl), "answer to events\n");
  const int other = connect_client();
  send_text(other, "status\n");
  serve_io();
  EXPECT_EQ(received(other), "") << "waits: the one slot's client asked just now";
  loop_.advance_by(999ms);
  serve_io();
  EXPECT_EQ(received(other), "");
  loop_.advance_by(1ms);
  serve_io();
  EXPECT_EQ(received(other), "answer to status\n") << "1 s without a request: the slot went to the waiting one";
  EXPECT_EQ(server->evicted(), 1u);
  for (const int fd : {ctl, other}) ::close(fd);
}

// 200 clients connecting at once, each asking once and closing after its answer (as `oegw
// status` does), with 8 slow clients holding every slot: every one is answered, the daemon's
// buffers bounded.
TEST_F(ControlServerTest, TwoHundredClientsAtOnceAreAllAnsweredBesideEightSlowOnes) {
  const ControlLimits limits{};
  auto server = serve(limits);
  std::vector<int> slow;
  for (int i = 0; i < 8; ++i) {
    slow.push_back(connect_client());
    send_text(slow.back(), "{");
  }
  serve_io(10);
  std::vector<int> many;
  for (int i = 0; i < 200; ++i) {
    many.push_back(connect_client());
    send_text(many.back(), "status\n");
  }
  std::vector<std::string> got(many.size());
  std::size_t most_buffered = 0;
  for (int round = 0; round < 2000; ++round) {
    loop_.run_once(0ms);
    most_buffered = std::max(most_buffered, server->buffered());
    for (std::size_t i = 0; i < many.size(); ++i) {
      if (many[i] < 0) continue;
      got[i] += received(many[i]);
      if (got[i].find('\n') == std::string::npos) continue;
      ::close(many[i]);
      many[i] = -1;
    }
  }
  for (std::size_t i = 0; i < many.size(); ++i) EXPECT_EQ(got[i], "answer to status\n") << "client " << i;
  EXPECT_LE(server->clients(), limits.max_clients);
  EXPECT_LE(most_buffered, limits.max_clients * (limits.max_request + 1 + limits.max_unsent));
  for (const int fd : slow) ::close(fd);
  for (const int fd : many)
    if (fd >= 0) ::close(fd);
}

// A daemon whose listen queue is full (connect() would wait for room): the client's time-out
// covers the connect too, and it says so rather than hanging.
TEST(ControlClient, AFullListenQueueIsATimeOutNotAHang) {
  const fs::path dir = fs::path(::testing::TempDir()) / ("control_client_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string path = (dir / "full.sock").string();
  fs::remove(path);
  const int server = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  std::strncpy(a.sun_path, path.c_str(), sizeof a.sun_path - 1);
  ASSERT_EQ(::bind(server, reinterpret_cast<const sockaddr*>(&a), sizeof a), 0);
  ASSERT_EQ(::listen(server, 0), 0);  // never accepts
  std::vector<int> queued;
  for (;;) {  // fill the queue
    const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (::connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0) {
      ::close(fd);
      break;
    }
    queued.push_back(fd);
    ASSERT_LT(queued.size(), 100u);
  }
  const AskResult r = ask_daemon(path, R"({"command":"status"})", std::chrono::milliseconds(100));
  EXPECT_EQ(r.status, AskStatus::Timeout) << r.text;
  EXPECT_NE(r.text.find("listen queue"), std::string::npos) << r.text;
  for (const int fd : queued) ::close(fd);
  ::close(server);
  fs::remove_all(dir);
}

TEST(ControlSettings, AGroupThisMachineLacksIsRefusedNamingTheSetting) {
  oegw::mapping::ControlConfig c;
  c.group = "oegw_no_such_group_x";
  c.group_where = {"/etc/oegw/oegw.yaml", 3, 12};
  try {
    (void)control_settings(c, "/etc/oegw/oegw.yaml");
    FAIL() << "no error";
  } catch (const ControlError& e) {
    EXPECT_EQ(std::string(e.what()),
              "/etc/oegw/oegw.yaml:3:12: control.group: no group 'oegw_no_such_group_x' on this machine (getent group "
              "oegw_no_such_group_x); create it (groupadd --system oegw_no_such_group_x) or leave control.group out "
              "(the socket is then root's only, mode 0600)");
  }
  c.group = "root";
  EXPECT_EQ(control_settings(c, "f").group, std::optional<gid_t>(0));
  c.group.clear();
  EXPECT_EQ(control_settings(c, "f").group, std::nullopt);
}

}  // namespace
