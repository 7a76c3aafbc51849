// DDS Security (publish.dds.security, docs/guides/secure-dds.md) end to end, on loopback in a
// private network namespace: the gateway (a simulated elobau grip booted on the virtual bus, its
// LEDs on indicators.1, `sources: [dds]`) with the gateway's identity, and the example programs in
// other processes with the identities scripts/make-dds-security.sh makes in a temporary folder:
//  * the application (app.pem) reads joystick.1 and its indicator command lights the LEDs;
//  * a participant without security sees no operator input and its command never arrives;
//  * the read-only participant (monitor.pem) reads the joystick, and may not even create the
//    command topic (its permissions grant no publish), so the LEDs stay as they were;
//  * a permissions document changed after signing, a key of another identity, a certificate of
//    another CA, an expired certificate, a missing file: refused at start, each naming its
//    setting at file:line:column.
// Each peer is waited for while the gateway is served (its loop here): bounded waits on another
// process, not timing logic. The negative cases run beside a permitted peer that does receive,
// so "nothing arrived" is measured against discovery that works.
#include <gtest/gtest.h>
#include <poll.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "../integration/virtual_network.hpp"
#include "gateway/gateway.hpp"
#include "gateway/publishing.hpp"
#include "publish/dds_publisher.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "tests/publish/child_process.hpp"
#include "tests/publish/private_network.hpp"

using namespace oegw;
using namespace oegw::canopen;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

namespace {

constexpr const char* kPartition = "oegw-security-test";

fs::path set_dir() { return fs::path(::testing::TempDir()) / ("oegw_dds_security_" + std::to_string(::getpid())); }

// The gateway's mapping file, in the folder of the security set: its paths are relative.
std::string mapping_text(const std::string& permissions = "permissions.p7s",
                         const std::string& private_key = "gateway.key",
                         const std::string& certificate = "gateway.pem") {
  return std::string(
             "upstream: { interface: virtual, node_id: 0x20 }\n"
             "downstream: { interface: virtual }\n"
             "publish:\n"
             "  period_ms: 50\n"
             "  dds:\n"
             "    partition: ") +
         kPartition +
         "\n"
         "    network: loopback\n"
         "    security:\n"
         "      identity_ca: ca.pem\n"
         "      certificate: " +
         certificate +
         "\n"
         "      private_key: " +
         private_key +
         "\n"
         "      permissions_ca: ca.pem\n"
         "      governance: governance.p7s\n"
         "      permissions: " +
         permissions +
         "\n"
         "subdevices:\n"
         "  grip: { driver: elobau-mfg, node_id: 0x11, heartbeat_ms: 100 }\n"
         "functional_elements:\n"
         "  joystick.1: { x: grip.x, y: grip.y }\n"
         "  indicators.1:\n"
         "    sources: [dds]\n"
         "    indicator[1..4]: grip.leds[1..4]\n";
}

mapping::LoadResult load(const std::string& name, const std::string& text) {
  const fs::path file = set_dir() / name;
  std::ofstream(file) << text;
  return mapping::load_config(file.string(), gateway::driver_catalogue());
}

// The example program's security options for one identity of the set ("" for none).
std::vector<std::string> peer(const std::string& program, const std::string& identity, std::vector<std::string> args) {
  std::vector<std::string> argv{program, "--partition", kPartition, "--network", "loopback"};
  if (!identity.empty()) {
    const std::string d = set_dir().string() + "/";
    for (const auto& [opt, file] :
         std::vector<std::pair<std::string, std::string>>{{"--identity-ca", "ca.pem"},
                                                          {"--certificate", identity + ".pem"},
                                                          {"--private-key", identity + ".key"},
                                                          {"--permissions-ca", "ca.pem"},
                                                          {"--governance", "governance.p7s"},
                                                          {"--permissions", "permissions.p7s"}}) {
      argv.push_back(opt);
      argv.push_back(d + file);
    }
  }
  argv.insert(argv.end(), args.begin(), args.end());
  return argv;
}

class DdsSecurity : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    fs::remove_all(set_dir());
    const std::string cmd =
        std::string(OEGW_MAKE_DDS_SECURITY) + " --partition " + kPartition + " " + set_dir().string() + " >/dev/null";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  }
  static void TearDownTestSuite() { fs::remove_all(set_dir()); }

  // The gateway with its grip, publishing with the gateway's identity.
  void start_gateway() {
    auto loaded = load("oegw.yaml", mapping_text());
    ASSERT_TRUE(loaded.ok()) << loaded.error_text();
    config_ = std::move(*loaded.config);
    bench_ = std::make_unique<subdevices::sim::SimBench>(down_.sink("sims"));
    std::string error;
    auto spec = subdevices::parse_device_spec("elobau-mfg:0x11:name=grip", error);
    ASSERT_TRUE(spec && bench_->add(*spec, error)) << error;
    gateway::GatewayOptions opt;
    opt.store_path = "";
    gw_ = std::make_unique<gateway::Gateway>(config_, up_.sink("gateway"), down_.sink("gateway"), opt);
    down_.attach("sims", *bench_);
    side_ = std::make_unique<Side>(Side{*gw_});
    down_.attach("gateway", *side_);
    pub_ = std::make_unique<gateway::GatewayPublishing>(*gw_, config_.publish, [this] { return down_.now(); });
    ASSERT_TRUE(pub_->active());
    (void)gw_->start(down_.now());
    bench_->start(down_.now());
    down_.run_for(2s);
    ASSERT_EQ(gw_->downstream().state("grip"), subdevices::NodeState::Operational);
    (void)bench_->command("grip x 0", down_.now());
    down_.run_for(100ms);
  }

  // Serves the gateway (commands in, samples out, the bus) until `done` or 30 s.
  bool serve_until(const std::function<bool()>& done) {
    const auto give_up = std::chrono::steady_clock::now() + 30s;
    while (!done()) {
      if (std::chrono::steady_clock::now() > give_up) return false;
      for (auto* p : pub_->publishers()) {
        pollfd fd{p->fd(), POLLIN, 0};
        if (p->fd() >= 0 && ::poll(&fd, 1, 10) > 0) p->poll();
      }
      pub_->tick();
      down_.run_for(10ms);
    }
    return true;
  }

  // A peer's joystick lines (the sample lines, not "ready") until it exits; its exit status.
  struct Run {
    int exit_code = -1;
    std::vector<std::string> lines;
  };
  static void drain(test::ChildProcess& c, Run& r) {
    while (auto l = c.read_line(5ms))
      if (l->rfind("joystick ", 0) == 0 || l->rfind("sent ", 0) == 0) r.lines.push_back(*l);
  }

  // dds_subscriber --count 1 as `identity`, the gateway served until it exits.
  Run one_joystick_sample(const std::string& identity) {
    test::ChildProcess sub(peer(OEGW_DDS_SUBSCRIBER, identity, {"--count", "1", "--timeout", "30"}));
    Run r;
    const bool done = serve_until([&] {
      drain(sub, r);
      return sub.exited().has_value();
    });
    drain(sub, r);
    r.exit_code = done ? sub.exited().value_or(-1) : -1;
    return r;
  }

  std::string leds() {
    auto* grip = bench_->device("grip");
    std::string s;
    for (int i = 1; i <= 4; ++i) s += std::to_string(grip->output("leds[" + std::to_string(i) + "]").value_or(-1));
    return s;
  }

  struct Side {
    gateway::Gateway& gw;
    bool on_frame(const CanFrame& f, TimePoint t) { return gw.on_downstream_frame(f, t); }
    void advance(TimePoint t) { gw.advance(t); }
    std::optional<TimePoint> next_deadline() const { return gw.next_deadline(); }
  };
  oegw::testing::VirtualNetwork down_, up_;
  mapping::Config config_;
  std::unique_ptr<subdevices::sim::SimBench> bench_;
  std::unique_ptr<gateway::Gateway> gw_;
  std::unique_ptr<Side> side_;
  std::unique_ptr<gateway::GatewayPublishing> pub_;
};

TEST_F(DdsSecurity, ThePermittedApplicationReadsTheJoystickAndCommandsTheLeds) {
  start_gateway();
  const Run s = one_joystick_sample("app");
  EXPECT_EQ(s.exit_code, 0);
  ASSERT_EQ(s.lines.size(), 1u);
  EXPECT_NE(s.lines[0].find("joystick instance=1 status=valid"), std::string::npos) << s.lines[0];

  EXPECT_EQ(leds(), "0000");
  test::ChildProcess cmd(peer(OEGW_DDS_COMMAND, "app", {"--timeout", "30", "indicators", "1", "--on", "1,3"}));
  Run c;
  ASSERT_TRUE(serve_until([&] { return cmd.exited().has_value() && leds() == "1010"; })) << leds();
  drain(cmd, c);
  EXPECT_EQ(cmd.exited(), 0);
  EXPECT_EQ(gw_->refused_commands(), 0u);
}

TEST_F(DdsSecurity, AParticipantWithoutSecuritySeesNoInputAndItsCommandNeverArrives) {
  start_gateway();
  // Beside it, the application: it receives, so discovery on this loopback works meanwhile.
  test::ChildProcess plain_sub(peer(OEGW_DDS_SUBSCRIBER, "", {"--count", "1", "--timeout", "8"}));
  test::ChildProcess plain_cmd(peer(OEGW_DDS_COMMAND, "", {"--timeout", "8", "indicators", "1", "--on", "1-4"}));
  test::ChildProcess app_sub(peer(OEGW_DDS_SUBSCRIBER, "app", {"--count", "5", "--timeout", "30"}));
  Run plain_s, plain_c, app_s;
  ASSERT_TRUE(serve_until([&] {
    drain(plain_sub, plain_s);
    drain(plain_cmd, plain_c);
    drain(app_sub, app_s);
    return plain_sub.exited().has_value() && plain_cmd.exited().has_value() && app_sub.exited().has_value();
  }));
  EXPECT_EQ(app_sub.exited(), 0);
  EXPECT_EQ(app_s.lines.size(), 5u) << "the application read the joystick meanwhile";
  EXPECT_EQ(plain_sub.exited(), 3) << "timed out";
  EXPECT_TRUE(plain_s.lines.empty()) << plain_s.lines.front();
  EXPECT_EQ(plain_cmd.exited(), 3) << "no reader of oegw/indicators: the gateway's reader never matched it";
  EXPECT_TRUE(plain_c.lines.empty());
  EXPECT_EQ(leds(), "0000");
  EXPECT_EQ(gw_->refused_commands(), 0u) << "nothing arrived to be refused";
}

TEST_F(DdsSecurity, TheReadOnlyParticipantReadsButCannotCommand) {
  start_gateway();
  const Run s = one_joystick_sample("monitor");
  EXPECT_EQ(s.exit_code, 0);
  ASSERT_EQ(s.lines.size(), 1u);
  // Its permissions grant no publish: Cyclone refuses it the command topic and writer (exit 1).
  test::ChildProcess cmd(peer(OEGW_DDS_COMMAND, "monitor", {"--timeout", "10", "indicators", "1", "--on", "1-4"}));
  ASSERT_TRUE(serve_until([&] { return cmd.exited().has_value(); }));
  EXPECT_EQ(cmd.exited(), 1);
  // The application's command afterwards shows the gateway was listening all along.
  test::ChildProcess app(peer(OEGW_DDS_COMMAND, "app", {"--timeout", "30", "indicators", "1", "--on", "2"}));
  ASSERT_TRUE(serve_until([&] { return app.exited().has_value() && leds() == "0100"; })) << leds();
  EXPECT_EQ(app.exited(), 0);
}

// What `oegw check` and `oegw run` print (dds_security_errors at the settings' places), and the
// publisher's own refusal at start (a demo or a test that skips the check).
TEST_F(DdsSecurity, ATamperedPermissionsDocumentAndWrongFilesAreRefusedAtStartNamingTheSetting) {
  // The grant of the read-only participant widened after signing: the signature no longer holds.
  std::ifstream in(set_dir() / "permissions.p7s");
  std::string p7s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto at = p7s.find("<grant name=\"oegw-monitor\">");
  ASSERT_NE(at, std::string::npos);
  const auto sub = p7s.find("<subscribe>", at);
  ASSERT_NE(sub, std::string::npos);
  p7s.replace(sub, std::string("<subscribe>").size(),
              "<publish><topics><topic>oegw/indicators</topic></topics>"
              "<partitions><partition>*</partition></partitions></publish><subscribe>");
  std::ofstream(set_dir() / "tampered.p7s") << p7s;
  auto loaded = load("tampered.yaml", mapping_text("tampered.p7s"));
  ASSERT_TRUE(loaded.ok()) << loaded.error_text();
  auto errors = gateway::dds_security_errors(*loaded.config);
  ASSERT_EQ(errors.size(), 1u);
  const std::string file = (set_dir() / "tampered.yaml").string();
  EXPECT_EQ(errors[0].str().rfind(file + ":14:20: publish.dds.security.permissions " +
                                      (set_dir() / "tampered.p7s").string() +
                                      ": is not signed by publish.dds.security.permissions_ca",
                                  0),
            0u)
      << errors[0].str();
  try {
    publish::DdsSettings s;
    s.partition = kPartition;
    s.security = gateway::dds_security_settings(*loaded.config->publish.dds.security);
    publish::DdsPublisher refused(s);
    ADD_FAILURE() << "a tampered permissions document was taken";
  } catch (const publish::PublishConfigError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("publish.dds.security.permissions " + (set_dir() / "tampered.p7s").string() +
                                              ": is not signed by publish.dds.security.permissions_ca",
                                          0),
              0u)
        << e.what();
  }

  // Another identity's key; a certificate of another CA; a missing file: each at its setting.
  ASSERT_EQ(std::system(
                (std::string(OEGW_MAKE_DDS_SECURITY) + " " + (set_dir() / "other").string() + " >/dev/null").c_str()),
            0);
  loaded = load("wrong.yaml", mapping_text("missing.p7s", "app.key", "other/gateway.pem"));
  ASSERT_TRUE(loaded.ok()) << loaded.error_text();
  errors = gateway::dds_security_errors(*loaded.config);
  std::string all;
  for (const auto& e : errors) all += e.str() + "\n";
  ASSERT_EQ(errors.size(), 3u) << all;
  const std::string wrong = (set_dir() / "wrong.yaml").string();
  EXPECT_NE(all.find(wrong + ":10:20: publish.dds.security.certificate " + (set_dir() / "other/gateway.pem").string() +
                     ": unable to get local issuer certificate: it was not issued by publish.dds.security.identity_ca"),
            std::string::npos)
      << all;
  EXPECT_NE(all.find(wrong + ":11:20: publish.dds.security.private_key " + (set_dir() / "app.key").string() +
                     ": is not the key of publish.dds.security.certificate"),
            std::string::npos)
      << all;
  EXPECT_NE(all.find(wrong + ":14:20: publish.dds.security.permissions " + (set_dir() / "missing.p7s").string() +
                     ": cannot be read: No such file or directory"),
            std::string::npos)
      << all;

  // The gateway's certificate, issued by the CA but valid until yesterday (openssl's -days -1).
  const std::string d = set_dir().string();
  ASSERT_EQ(std::system(("cd " + d +
                         " && openssl req -new -key gateway.key -subj '/O=oegw cab/CN=oegw-gateway' | "
                         "openssl x509 -req -CA ca.pem -CAkey ca.key -days -1 -out expired.pem 2>/dev/null")
                            .c_str()),
            0);
  loaded = load("expired.yaml", mapping_text("permissions.p7s", "gateway.key", "expired.pem"));
  ASSERT_TRUE(loaded.ok()) << loaded.error_text();
  errors = gateway::dds_security_errors(*loaded.config);
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_EQ(errors[0].str().rfind((set_dir() / "expired.yaml").string() + ":10:20: publish.dds.security.certificate " +
                                      d + "/expired.pem: certificate has expired (not after ",
                                  0),
            0u)
      << errors[0].str();
}

// docs/design/threat-model.md asks the private key at mode 0600: a key its group or every user may
// read is refused by `oegw check` and `oegw run` (dds_security_errors) and by the publisher, naming
// the setting, the mode and the command that mends it; 0600 and 0400 are taken.
TEST_F(DdsSecurity, APrivateKeyOthersMayReadIsRefusedNamingItsModeAndTheChmod) {
  const fs::path key = set_dir() / "open.key";
  for (const auto& [mode, who] :
       std::vector<std::pair<fs::perms, std::string>>{{fs::perms(0644), "0644 lets every user"},
                                                      {fs::perms(0666), "0666 lets every user"},
                                                      {fs::perms(0640), "0640 lets its group"},
                                                      {fs::perms(0600), ""},
                                                      {fs::perms(0400), ""}}) {
    fs::remove(key);
    fs::copy_file(set_dir() / "gateway.key", key);
    fs::permissions(key, mode, fs::perm_options::replace);
    auto loaded = load("open.yaml", mapping_text("permissions.p7s", "open.key"));
    ASSERT_TRUE(loaded.ok()) << loaded.error_text();
    const auto errors = gateway::dds_security_errors(*loaded.config);
    if (who.empty()) {
      EXPECT_TRUE(errors.empty()) << errors.front().str();
      continue;
    }
    ASSERT_EQ(errors.size(), 1u) << who;
    EXPECT_EQ(errors[0].str(),
              (set_dir() / "open.yaml").string() + ":11:20: publish.dds.security.private_key " + key.string() +
                  ": mode " + who +
                  " read or change the private key; expected 0600, owner the daemon's user: chmod 0600 " +
                  key.string());
    publish::DdsSettings s;
    s.partition = kPartition;
    s.network = "loopback";
    s.security = gateway::dds_security_settings(*loaded.config->publish.dds.security);
    EXPECT_THROW(publish::DdsPublisher refused(s), publish::PublishConfigError) << who;
  }
  fs::remove(key);
}

}  // namespace

int main(int argc, char** argv) {
  oegw::test::enter_private_network();
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
