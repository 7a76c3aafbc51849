// The control socket's server (gateway/control/control_server.hpp) on real Unix sockets in a
// temporary folder, its loop on a simulated clock: descriptors are served by run_once(0), the
// bounds' deadlines fire only when the test moves the clock (nothing sleeps).
#include "gateway/control/control_server.hpp"

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "canopen/io/clock.hpp"

using namespace oegw::canopen;
using namespace oegw::gateway;
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
  struct stat st{};
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
  struct stat st{};
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
    EXPECT_EQ(std::string(e.what()), "test.yaml: control.socket: " + path_ + " is served by a running gateway (`oegw status --socket " +
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
          EXPECT_EQ(std::string(e.what()), "test.yaml: control.socket: " + path_ +
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
  EXPECT_EQ(server->answered(), 0u) << "the handler never saw it";
  ::close(fd);
}

TEST_F(ControlServerTest, OneClientMoreThanTheBoundIsToldBusy) {
  auto server = serve(ControlLimits{.max_clients = 2});
  const int a = connect_client(), b = connect_client(), c = connect_client();
  serve_io();
  EXPECT_EQ(server->clients(), 2u);
  bool eof = false;
  const std::string got = received(c, &eof);
  EXPECT_NE(got.find("\"code\":\"busy\""), std::string::npos) << got;
  EXPECT_TRUE(eof);
  send_text(a, "a\n");
  serve_io();
  EXPECT_EQ(received(a), "answer to a\n") << "the others are served";
  for (const int fd : {a, b, c}) ::close(fd);
}

TEST_F(ControlServerTest, AClientThatDoesNotReadIsDroppedWithoutBlockingTheLoop) {
  answer_ = [](std::string_view) { return std::string(4 * 1024 * 1024, 'x'); };  // more than socket buffers hold
  auto server = serve(ControlLimits{.max_pending = 8 * 1024 * 1024, .write_timeout = 2s});
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

TEST_F(ControlServerTest, AClientThatAsksForMoreThanItReadsIsDroppedAtThePendingBound) {
  answer_ = [](std::string_view) { return std::string(64 * 1024, 'x'); };
  auto server = serve(ControlLimits{.max_pending = 512 * 1024});
  const int fd = connect_client();
  std::string many;
  for (int i = 0; i < 40; ++i) many += "status\n";
  send_text(fd, many);
  serve_io(20);
  EXPECT_EQ(server->clients(), 0u) << "40 x 64 KiB never read: over the bound";
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
  auto server = std::make_unique<ControlServer>(
      loop_, settings(ControlLimits{.max_waiting = 2, .idle_timeout = 30s}),
      ControlServer::AsyncHandler([&later](std::string_view line, ControlServer::Reply reply) {
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
  // A client that leaves before its answer: the answer goes nowhere.
  send_text(fd, "slow\n");
  serve_io();
  ASSERT_EQ(later.size(), 3u);
  ::close(fd);
  serve_io();
  EXPECT_EQ(server->clients(), 1u);  // a client that only shut down its side still gets it
  later[2]("too late");
  serve_io();
  EXPECT_EQ(server->clients(), 0u);
  // And one given after the server is gone changes nothing either.
  const int fd2 = connect_client();
  send_text(fd2, "slow\n");
  serve_io();
  ASSERT_EQ(later.size(), 4u);
  server.reset();
  later[3]("after the end");
  ::close(fd2);
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
