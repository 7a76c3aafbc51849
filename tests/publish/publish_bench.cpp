// Latency from publish() to the subscriber's callback in ANOTHER process on this host, for DDS
// and LCM: each sample carries its CLOCK_MONOTONIC publish time (timestamp_us); the example
// subscriber stamps the reception (rx_us) with the same clock and prints both. One sample in
// flight at a time (the next goes out once the previous line is read), 10,000 per transport
// after a warm-up. A timed harness, not Google Benchmark: it accepts and ignores
// --benchmark_* flags so scripts/test-all.sh can run it with the other benchmarks. Figures only,
// never asserted. Loopback DDS configuration and LCM ttl=0: nothing leaves the host.
// DDS three times in one run: plain, and with DDS Security (publish.dds.security) as
// scripts/make-dds-security.sh makes it with --protection sign (every data submessage MAC'd) and
// --protection encrypt (the payload AES-GCM encrypted, the submessage signed); the subscriber
// then runs as the application's identity. The sets are made in a temporary folder and removed.
//
//   oegw_bench_publish [--samples N]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <functional>
#include <string>
#include <vector>

#include "publish/dds_publisher.hpp"
#include "publish/lcm_publisher.hpp"
#include "tests/publish/child_process.hpp"
#include "tests/publish/private_network.hpp"

namespace {

using namespace std::chrono_literals;
using oegw::gateway::JoystickSample;
using oegw::gateway::Publisher;

std::int64_t now_us() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000 + ts.tv_nsec / 1000;
}

struct Result {
  std::vector<std::int64_t> lat;
  long lost = 0;
};

Result run(Publisher& pub, oegw::test::ChildProcess& sub, long warmup, long n) {
  Result r;
  JoystickSample s;
  s.h.instance = 1;
  s.h.status = oegw::gateway::FeStatus::Valid;
  for (long i = 0; i < warmup + n; ++i) {
    s.h.seq = static_cast<std::uint32_t>(i + 1);
    s.x = static_cast<std::int16_t>(i % 30000);
    s.h.timestamp_us = now_us();
    pub.publish(s);
    auto line = sub.read_line(1s);
    if (!line) {
      ++r.lost;
      continue;
    }
    const char* ts = std::strstr(line->c_str(), " ts_us=");
    const char* rx = std::strstr(line->c_str(), " rx_us=");
    if (ts == nullptr || rx == nullptr) {
      ++r.lost;
      continue;
    }
    if (i >= warmup) r.lat.push_back(std::atoll(rx + 7) - std::atoll(ts + 7));
  }
  return r;
}

void report(const char* name, Result r) {
  if (r.lat.empty()) {
    std::printf("%-13s no samples received (lost %ld)\n", name, r.lost);
    return;
  }
  std::sort(r.lat.begin(), r.lat.end());
  const auto pct = [&](double p) { return r.lat[static_cast<std::size_t>(p * static_cast<double>(r.lat.size() - 1))]; };
  std::printf(
      "%-13s publish -> subscriber callback (other process): n=%zu lost=%ld  p50=%lld us  p99=%lld us  "
      "p99.9=%lld us  max=%lld us\n",
      name, r.lat.size(), r.lost, static_cast<long long>(pct(0.5)), static_cast<long long>(pct(0.99)),
      static_cast<long long>(pct(0.999)), static_cast<long long>(r.lat.back()));
}

}  // namespace

int main(int argc, char** argv) {
  // lo only, for this process and the subscribers (see private_network.hpp: LCM's IGMP join).
  const bool private_net = oegw::test::enter_private_network();
  std::printf("network: %s\n", private_net ? "private namespace, lo only" : "host (loopback settings)");
  long n = 10'000;
  for (int i = 1; i + 1 < argc; ++i)
    if (std::strcmp(argv[i], "--samples") == 0) n = std::atol(argv[i + 1]);
  const long warmup = 200;
  const std::string total = std::to_string(warmup + n);
  const std::string tag = std::to_string(::getpid());

  const std::string sets = "/tmp/oegw-bench-dds-security-" + tag;
  for (const char* protection : {"", "sign", "encrypt"}) {
    oegw::publish::DdsSettings s;
    s.partition = "oegw-bench-" + tag;
    std::vector<std::string> sub_argv{OEGW_DDS_SUBSCRIBER, "--count",  total, "--timeout", "120",
                                      "--partition",       s.partition};
    if (*protection != 0) {
      const std::string dir = sets + "/" + protection;
      const std::string make = std::string(OEGW_MAKE_DDS_SECURITY) + " --protection " + protection + " --partition " +
                               s.partition + " " + dir + " >/dev/null";
      if (std::system(make.c_str()) != 0) return 1;
      oegw::publish::DdsSecuritySettings sec;
      sec.path = {dir + "/ca.pem", dir + "/gateway.pem",    dir + "/gateway.key",
                  dir + "/ca.pem", dir + "/governance.p7s", dir + "/permissions.p7s"};
      s.security = sec;
      for (const auto& [opt, file] :
           std::vector<std::pair<std::string, std::string>>{{"--identity-ca", "ca.pem"},
                                                            {"--certificate", "app.pem"},
                                                            {"--private-key", "app.key"},
                                                            {"--permissions-ca", "ca.pem"},
                                                            {"--governance", "governance.p7s"},
                                                            {"--permissions", "permissions.p7s"}}) {
        sub_argv.push_back(opt);
        sub_argv.push_back(dir + "/" + file);
      }
    }
    oegw::publish::DdsPublisher dds(s);
    oegw::test::ChildProcess sub(sub_argv);
    if (sub.read_line(10s) != "ready") return 1;
    // A secure reader matches only after the handshake (authentication, then the keys).
    const auto end = std::chrono::steady_clock::now() + 20s;
    while (dds.joystick_readers() == 0 && std::chrono::steady_clock::now() < end) oegw::test::ChildProcess::pause_ms(5);
    const std::string name =
        *protection == 0 ? "DDS" : std::string("DDS ") + (protection[0] == 's' ? "signed" : "encrypted");
    report(name.c_str(), run(dds, sub, warmup, n));
  }
  (void)!std::system(("rm -rf " + sets).c_str());
  {
    oegw::publish::LcmSettings s;
    s.channel_prefix = "B" + tag + "_";
    oegw::publish::LcmPublisher lcm(s);
    oegw::test::ChildProcess sub(
        {OEGW_LCM_SUBSCRIBER, "--count", total, "--timeout", "120", "--channel", s.channel_prefix + "JOYSTICK_[0-9]+"});
    if (sub.read_line(10s) != "ready") return 1;
    report("LCM", run(lcm, sub, warmup, n));
  }
  return 0;
}
