// serve_gateway (`oegw run` once its buses are open) natively, on AF_UNIX socketpairs standing in
// for the two CAN buses (canopen/io/seqpacket_transport.hpp), in a thread of its own as in the
// daemon; the test plays the host on the upstream socket. What it checks is what the buses see
// while something beside them goes on: a SIGHUP reload reads and checks its file in a thread of
// its own, and the upstream device answers the host meanwhile.
//
// The waits below are bounds on something that must happen (10 s for what takes microseconds),
// never measurements: nothing here depends on how fast the machine is.
#include "gateway/serve_gateway.hpp"

#include <gtest/gtest.h>
#include <linux/can.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdlib.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <optional>
#include <string>
#include <thread>

#include "canopen/io/seqpacket_transport.hpp"
#include "gateway/gateway.hpp"
#include "mapping/config.hpp"

namespace {

using namespace oegw;
using namespace std::chrono_literals;
using canopen::io::SeqpacketCanTransport;

constexpr canid_t kNode = 0x20;
constexpr auto kBound = 10s;  // for what must happen at all

// One elobau grip that is not there (the downstream peer answers nothing): the gateway boots it in
// vain, and its upstream device runs on regardless. Nothing published, no control socket.
std::string mapping_text(const std::filesystem::path& dir) {
  return "upstream:\n"
         "  interface: can0\n"
         "  node_id: 0x20\n"
         "  heartbeat_ms: 100\n"
         "  store: " +
         (dir / "upstream.store").string() +
         "\n"
         "downstream:\n"
         "  interface: can1\n"
         "subdevices:\n"
         "  grip: { driver: elobau-mfg, node_id: 0x11, heartbeat_ms: 100, mandatory: true }\n"
         "functional_elements:\n"
         "  joystick.1:\n"
         "    x: { signal: grip.x, deadband: 2 }\n"
         "    y: { signal: grip.y, deadband: 2 }\n"
         "control:\n"
         "  enabled: false\n";
}

bool is_bootup(const can_frame& f) { return f.can_id == 0x700 + kNode && f.len == 1 && f.data[0] == 0x00; }
bool is_sdo_answer_of_1000h(const can_frame& f) {
  return f.can_id == 0x580 + kNode && f.data[0] == 0x43 && f.data[1] == 0x00 && f.data[2] == 0x10 && f.data[3] == 0x00;
}
// EMCY 6300h: the gateway holds it from a reload's hand-over until its sub-devices are back.
bool is_reload_emcy(const can_frame& f) { return f.can_id == 0x80 + kNode && f.data[0] == 0x00 && f.data[1] == 0x63; }

class ServeGatewayTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char tmpl[] = "/tmp/oegw-serve-XXXXXX";
    ASSERT_NE(::mkdtemp(tmpl), nullptr);
    dir_ = tmpl;
    file_ = (dir_ / "cab.yaml").string();
    std::ofstream(file_) << mapping_text(dir_);
    auto loaded = mapping::load_config(file_, gateway::driver_catalogue());
    ASSERT_TRUE(loaded.ok()) << loaded.error_text();
    config_ = std::move(*loaded.config);
  }

  void TearDown() override {
    try {
      release_.set_value();               // a reading still held ends
    } catch (const std::future_error&) {  // released by the test already
    }
    if (thread_.joinable()) {
      // SIGTERM only once the gateway takes it (its loop's signalfd, set up before its boot-up):
      // before, it would end the whole test program.
      if (started_) {
        ::pthread_kill(thread_.native_handle(), SIGTERM);
        thread_.join();
      } else {
        thread_.detach();
      }
    }
    for (const int fd : {host_, sub_})
      if (fd >= 0) ::close(fd);
    std::filesystem::remove_all(dir_);
  }

  // serve_gateway in its thread; the test keeps the other end of each socketpair.
  void start() {
    int up[2];
    int down[2];
    SeqpacketCanTransport::make_socketpair(up);
    SeqpacketCanTransport::make_socketpair(down);
    host_ = up[1];
    sub_ = down[1];
    thread_ = std::thread([this, gw_up = up[0], gw_down = down[0]] {
      canopen::io::EventLoop loop;
      auto upstream = SeqpacketCanTransport::adopt(gw_up);
      auto downstream = SeqpacketCanTransport::adopt(gw_down);
      status_ = gateway::serve_gateway(file_, config_, loop, gateway::GatewayBuses{*upstream, *downstream}, hooks_);
    });
  }

  void send_upstream(canid_t id, std::array<std::uint8_t, 8> data) {
    can_frame f{};
    f.can_id = id;
    f.len = 8;
    std::memcpy(f.data, data.data(), 8);
    ASSERT_EQ(::write(host_, &f, sizeof f), static_cast<ssize_t>(sizeof f));
  }

  // The first upstream frame `match` takes within kBound (downstream frames read and dropped
  // meanwhile: the sub-device is not there); nullopt when none came.
  std::optional<can_frame> wait_upstream(const std::function<bool(const can_frame&)>& match) {
    return wait_until(match, {});
  }

  // Boot-up seen: the gateway's signals are its loop's from now on.
  [[nodiscard]] bool wait_started() {
    started_ = wait_upstream(is_bootup).has_value();
    return started_;
  }

  // Serves both peers until `done` holds (checked between frames and at least every 10 ms).
  bool wait_for(const std::function<bool()>& done) {
    return wait_until([](const can_frame&) { return false; }, done).has_value() || done();
  }

  void signal_gateway(int signo) { ASSERT_EQ(::pthread_kill(thread_.native_handle(), signo), 0); }

  std::filesystem::path dir_;
  std::string file_;
  mapping::Config config_;
  gateway::ServeHooks hooks_;
  // What the hooks count (members: the gateway thread may call a hook until TearDown joins it).
  std::atomic<int> reads_{0};
  std::atomic<int> applied_{0};
  std::atomic<int> refused_{0};
  std::atomic<int> queued_{0};  // SIGHUPs that came while a reading was under way
  std::promise<void> release_;
  std::shared_future<void> released_ = release_.get_future().share();
  std::atomic<bool> started_{false};
  std::thread thread_;
  int status_ = -1;
  int host_ = -1;
  int sub_ = -1;

  std::optional<can_frame> wait_until(const std::function<bool(const can_frame&)>& match,
                                      const std::function<bool()>& done) {
    const auto until = std::chrono::steady_clock::now() + kBound;
    while (std::chrono::steady_clock::now() < until) {
      if (done && done()) return std::nullopt;
      std::array<pollfd, 2> fds{pollfd{host_, POLLIN, 0}, pollfd{sub_, POLLIN, 0}};
      if (::poll(fds.data(), fds.size(), 10) <= 0) continue;
      can_frame f{};
      if ((fds[1].revents & POLLIN) != 0) (void)!::read(sub_, &f, sizeof f);
      if ((fds[0].revents & POLLIN) != 0 && ::read(host_, &f, sizeof f) == static_cast<ssize_t>(sizeof f) && match(f))
        return f;
    }
    return std::nullopt;
  }
};

TEST_F(ServeGatewayTest, ASighupReadsTheFileBesideTheBusesAndAnotherOneReadsItAgainAfter) {
  hooks_.reload_reading = [this] {
    ++reads_;
    released_.wait();  // a file on a slow or hung file system
  };
  hooks_.reload_done = [this](bool ok) { ++(ok ? applied_ : refused_); };
  hooks_.reload_signal = [this](bool while_reading) { queued_ += while_reading ? 1 : 0; };
  start();
  ASSERT_TRUE(wait_started()) << "the gateway did not start";

  signal_gateway(SIGHUP);
  ASSERT_TRUE(wait_for([this] { return reads_ == 1; })) << "the reload did not start reading";
  // While the file is being read, the upstream device answers the host: the loop is not waiting.
  send_upstream(0x600 + kNode, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0});  // SDO upload 1000h
  EXPECT_TRUE(wait_upstream(is_sdo_answer_of_1000h)) << "no SDO answer while the reload read its file";
  signal_gateway(SIGHUP);  // taken after the reload under way, not lost, not run beside it
  ASSERT_TRUE(wait_for([this] { return queued_ == 1; })) << "the second SIGHUP was not taken while reading";
  EXPECT_EQ(reads_, 1) << "a second reading beside the first";

  release_.set_value();
  EXPECT_TRUE(wait_upstream(is_reload_emcy)) << "the reload was not applied once its file was read";
  EXPECT_TRUE(wait_for([this] { return applied_ == 2; })) << "the second SIGHUP did not reload the file again";
  EXPECT_EQ(reads_, 2);
  EXPECT_EQ(refused_, 0);
  signal_gateway(SIGTERM);
  thread_.join();
  EXPECT_EQ(status_, 0);
}

TEST_F(ServeGatewayTest, AFileRefusedAtAReloadChangesNothingAndTheGatewayRunsOn) {
  hooks_.reload_done = [this](bool ok) { ++(ok ? applied_ : refused_); };
  start();
  ASSERT_TRUE(wait_started());
  std::ofstream(file_) << "upstream: [\n";  // broken YAML
  signal_gateway(SIGHUP);
  bool emcy = false;
  const auto watch_emcy = [&emcy](const can_frame& f) {
    emcy = emcy || is_reload_emcy(f);
    return false;
  };
  (void)wait_until(watch_emcy, [this] { return refused_ == 1; });
  ASSERT_EQ(refused_, 1) << "the broken file was not refused";
  send_upstream(0x600 + kNode, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0});
  EXPECT_TRUE(wait_upstream([&](const can_frame& f) { return watch_emcy(f) || is_sdo_answer_of_1000h(f); }))
      << "the gateway no longer answers after a refused reload";
  EXPECT_FALSE(emcy) << "a refused file was handed over";
  EXPECT_EQ(applied_, 0);
  signal_gateway(SIGTERM);
  thread_.join();
  EXPECT_EQ(status_, 0);
}

}  // namespace
