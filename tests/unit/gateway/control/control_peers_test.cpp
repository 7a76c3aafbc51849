// Who the control socket answers (gateway/control/control_server.hpp): root, the daemon's own
// user and the members of control.group, as a second user sees it. The test is root (CI runs as
// root) and makes that user with useradd; each client is a child process that sets its own
// credentials (setgroups/setgid/setuid) and runs `oegw status --json` (run_status), so the exit
// code and message are those of the program. Two doors: the socket file's mode (the kernel
// refuses connect(), EACCES) and, behind it, the server's SO_PEERCRED/SO_PEERGROUPS check, which
// answers `permission_denied` with the reason and logs it. The server runs on a real-time loop:
// the test waits for the child in epoll_wait, not in a sleep.
#include <fcntl.h>
#include <grp.h>
#include <gtest/gtest.h>
#include <pwd.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "cli/status_command.hpp"
#include "gateway/control/control_server.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace oegw::gateway;
using namespace oegw::cli;
using namespace oegw::gateway::control;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

namespace {

constexpr const char* kPeer = "oegw-ctl-peer";   // the second user
constexpr const char* kGroup = "oegw-ctl-test";  // control.group

struct Credentials {
  uid_t uid;
  gid_t gid;
  std::vector<gid_t> groups;  // supplementary
};

struct Outcome {
  int exit_code = -1;
  std::string err;  // the child's stderr
  std::string out;  // its stdout
};

std::string read_all(int fd) {
  std::string s;
  char buf[4096];
  for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) > 0;) s.append(buf, static_cast<std::size_t>(n));
  return s;
}

class ControlPeers : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(::geteuid(), 0u) << "this test becomes a second user (setuid) and makes it with useradd: run it as root, "
                                  "as CI does";
    {
      // CTest runs these cases as parallel processes: the first to take the lock makes the user
      // and group, the others find them (CI's run-to-run failure: "groupadd: group 'oegw-ctl-test'
      // already exists", and useradd/groupadd refuse to run while another holds /etc/passwd's lock).
      const int lock = ::open("/tmp/oegw-control-peers.lock", O_CREAT | O_RDWR | O_CLOEXEC, 0600);
      ASSERT_GE(lock, 0);
      ASSERT_EQ(::flock(lock, LOCK_EX), 0);
      if (::getgrnam(kGroup) == nullptr) {
        EXPECT_EQ(std::system((std::string("groupadd --system ") + kGroup).c_str()), 0);
      }
      if (::getpwnam(kPeer) == nullptr) {
        EXPECT_EQ(std::system(
                      (std::string("useradd --system --no-create-home --user-group --shell /usr/sbin/nologin ") + kPeer)
                          .c_str()),
                  0);
      }
      ::close(lock);  // ends the lock
    }
    const passwd* p = ::getpwnam(kPeer);
    const group* g = ::getgrnam(kGroup);
    ASSERT_TRUE(p && g);
    peer_uid_ = p->pw_uid;
    peer_gid_ = p->pw_gid;
    group_ = g->gr_gid;
    dir_ = fs::path(::testing::TempDir()) / ("control_peers_" + std::to_string(::getpid()) + "_" +
                                             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    fs::permissions(dir_, fs::perms(0755));  // the second user may look for the socket
    path_ = (dir_ / "oegw.sock").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::unique_ptr<ControlServer> serve(std::optional<gid_t> group) {
    ControlSocketSettings s{"test.yaml", path_, group, {}, [this](const std::string& l) { log_ += l + "\n"; }};
    s.warn = [this](const std::string& l) { warnings_ += l + "\n"; };
    return std::make_unique<ControlServer>(loop_, s, [](std::string_view) {
      return std::string(R"({"protocol": 1, "ok": true, "command": "status", "status": {}})");
    });
  }

  // `oegw status --json --socket path_` in a child with these credentials; the server answers
  // from this process's loop meanwhile.
  Outcome ask_as(const Credentials& c) {
    int err[2], out[2];
    EXPECT_EQ(::pipe2(err, O_CLOEXEC), 0);
    EXPECT_EQ(::pipe2(out, O_CLOEXEC), 0);
    const pid_t pid = ::fork();
    if (pid == 0) {
      ::dup2(err[1], 2);
      ::dup2(out[1], 1);
      if (::setgroups(c.groups.size(), c.groups.data()) != 0 || ::setgid(c.gid) != 0 || ::setuid(c.uid) != 0) {
        std::perror("cannot become the peer");
        ::_exit(99);
      }
      StatusOptions o;
      o.socket = path_;
      o.json = true;
      o.timeout_s = 5;
      const int rc = run_status(o);
      std::fflush(stdout);
      ::_exit(rc);
    }
    ::close(err[1]);
    ::close(out[1]);
    int status = 0;
    const auto give_up = std::chrono::steady_clock::now() + 10s;
    while (::waitpid(pid, &status, WNOHANG) == 0) {
      if (std::chrono::steady_clock::now() > give_up) {
        ::kill(pid, SIGKILL);
        ::waitpid(pid, &status, 0);
        ADD_FAILURE() << "the client did not finish";
        break;
      }
      loop_.run_once(10ms);  // serves the socket; returns at the next event or after 10 ms
    }
    Outcome r;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.err = read_all(err[0]);
    r.out = read_all(out[0]);
    ::close(err[0]);
    ::close(out[0]);
    return r;
  }

  void widen_the_mode_by_hand() { ASSERT_EQ(::chmod(path_.c_str(), 0666), 0); }

  EventLoop loop_;  // real time
  fs::path dir_;
  std::string path_;
  std::string log_, warnings_;
  uid_t peer_uid_ = 0;
  gid_t peer_gid_ = 0;
  gid_t group_ = 0;
};

TEST_F(ControlPeers, TheSocketFileKeepsOutAUserNotInTheGroupAndLetsAMemberIn) {
  auto server = serve(group_);
  Outcome r = ask_as({peer_uid_, peer_gid_, {}});
  EXPECT_EQ(r.exit_code, kStatusPermission) << r.err;
  EXPECT_NE(r.err.find("permission denied on " + path_ + " (root:" + kGroup +
                       ", mode 0660): ask as root or as a member "
                       "of group " +
                       kGroup),
            std::string::npos)
      << r.err;
  EXPECT_EQ(server->refused(), 0u) << "the kernel refused the connect(): the server never saw it";

  r = ask_as({peer_uid_, peer_gid_, {group_}});  // a member (supplementary group)
  EXPECT_EQ(r.exit_code, kStatusOk) << r.err;
  EXPECT_NE(r.out.find(R"("ok": true)"), std::string::npos) << r.out;
  EXPECT_EQ(server->refused(), 0u);
}

TEST_F(ControlPeers, BehindAWidenedModeTheServerRefusesANonMemberWithTheReasonAndLogsIt) {
  auto server = serve(group_);
  widen_the_mode_by_hand();
  Outcome r = ask_as({peer_uid_, peer_gid_, {}});
  EXPECT_EQ(r.exit_code, kStatusPermission) << r.err << r.out;
  const std::string who = "uid " + std::to_string(peer_uid_) + " (" + kPeer + "), pid ";
  EXPECT_NE(r.out.find(R"("code":"permission_denied")"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("refused " + who), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(std::string("not root and not in group ") + kGroup + " (control.group)"), std::string::npos)
      << r.out;
  EXPECT_EQ(server->refused(), 1u);
  EXPECT_NE(warnings_.find("control: refused " + who), std::string::npos) << warnings_;
  EXPECT_NE(warnings_.find(std::string(": not root and not in group ") + kGroup + " (control.group)\n"),
            std::string::npos)
      << warnings_;

  // The same user again: refused and counted, not logged again (the first of each uid, then
  // every 100th: a local user cannot flood the journal).
  r = ask_as({peer_uid_, peer_gid_, {}});
  EXPECT_EQ(r.exit_code, kStatusPermission);
  EXPECT_EQ(server->refused(), 2u);
  EXPECT_EQ(warnings_.find("control: refused", warnings_.find("control: refused") + 1), std::string::npos) << warnings_;

  // Members are answered: by supplementary group, by primary group; and root.
  EXPECT_EQ(ask_as({peer_uid_, peer_gid_, {group_}}).exit_code, kStatusOk);
  EXPECT_EQ(ask_as({peer_uid_, group_, {}}).exit_code, kStatusOk);
  EXPECT_EQ(ask_as({0, 0, {0}}).exit_code, kStatusOk);
  EXPECT_EQ(server->refused(), 2u);
}

TEST_F(ControlPeers, WithoutAGroupOnlyRootIsAnswered) {
  auto server = serve(std::nullopt);
  struct stat st {};
  ASSERT_EQ(::lstat(path_.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  EXPECT_EQ(ask_as({peer_uid_, peer_gid_, {group_}}).exit_code, kStatusPermission) << "the file's mode";
  widen_the_mode_by_hand();
  const Outcome r = ask_as({peer_uid_, peer_gid_, {group_}});
  EXPECT_EQ(r.exit_code, kStatusPermission) << r.out;
  EXPECT_NE(r.out.find("not root: without control.group the gateway answers root only"), std::string::npos) << r.out;
  EXPECT_NE(warnings_.find("not root: without control.group the gateway answers root only"), std::string::npos);
  EXPECT_EQ(ask_as({0, 0, {0}}).exit_code, kStatusOk);
  EXPECT_EQ(server->refused(), 1u);
}

}  // namespace
