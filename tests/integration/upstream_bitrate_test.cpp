// The upstream bit rate from the mapping file to the device (docs/guides/commission.md#bit-rate):
// LSS configure bit timing takes exactly the rates the EDS lists (one list,
// gateway::upstream_bit_timings), LSS activate bit timing reports the new rate in bit/s at the
// switch, and an LSS-stored rate wins over upstream.bitrate at the next start.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <vector>

#include "canopen/305/lss.hpp"
#include "gateway/gateway.hpp"
#include "gateway/runtime_config.hpp"

namespace {

using namespace oegw;
using namespace std::chrono_literals;
using canopen::CanFrame;
using canopen::TimePoint;

mapping::Config load(const std::string& yaml) {
  auto r = mapping::load_config_text(yaml, "test.yaml", gateway::driver_catalogue());
  if (!r.ok()) throw std::runtime_error(r.error_text());
  return *r.config;
}

std::string file_for(std::uint32_t bitrate, const std::string& store = "") {
  return "upstream: { interface: virtual, node_id: 0x20, bitrate: " + std::to_string(bitrate) +
         (store.empty() ? std::string() : ", store: " + store) +
         " }\n"
         "downstream: { interface: virtual }\n"
         "subdevices:\n"
         "  grip: { driver: elobau-mfg, node_id: 0x11 }\n"
         "functional_elements:\n"
         "  joystick.1: { x: grip.x }\n";
}

// BaudRate_<kbit> of the EDS text: true for "1".
bool eds_lists(const std::string& eds, unsigned kbit) {
  std::smatch m;
  const std::regex re("\nBaudRate_" + std::to_string(kbit) + "=([01])");
  if (!std::regex_search(eds, m, re)) throw std::runtime_error("no BaudRate_" + std::to_string(kbit));
  return m[1] == "1";
}

class Device {
 public:
  explicit Device(const mapping::Config& c, std::optional<std::filesystem::path> store = std::nullopt)
      : dev_(gateway::device_config(c, store), [this](const CanFrame& f) { out.push_back(f); }) {
    dev_.start(now);
  }
  std::vector<CanFrame> lss(std::initializer_list<std::uint8_t> b) {
    std::vector<std::uint8_t> v(b);
    v.resize(8, 0);
    out.clear();
    dev_.on_frame(CanFrame(canopen::cob::kLssMaster, std::span<const std::uint8_t>(v)), now);
    return out;
  }
  void at(TimePoint t) {
    now = t;
    dev_.advance(now);
  }
  gateway::OeDevice& device() { return dev_; }
  std::vector<CanFrame> out;
  TimePoint now{std::chrono::seconds(10)};

 private:
  gateway::OeDevice dev_;
};

// For several upstream.bitrate values: every table-0 index is acknowledged (error 0) exactly when
// the EDS lists its rate (BaudRate_xxx=1), error 1 otherwise.
TEST(UpstreamBitRate, LssConfigureBitTimingTakesExactlyTheRatesTheEdsLists) {
  for (const std::uint32_t bitrate : {250000u, 1000000u, 800000u, 20000u, 10000u}) {
    const mapping::Config c = load(file_for(bitrate));
    const std::string eds = gateway::upstream_eds(c, "oegw.eds");
    Device d(c);
    EXPECT_TRUE(d.lss({0x04, 0x01}).empty());
    unsigned listed = 0;
    for (std::uint8_t index = 0; index <= 9; ++index) {
      const auto kbit = canopen::lss::standard_bit_rate_kbit(index);
      const bool in_eds = kbit && eds_lists(eds, *kbit);
      listed += in_eds ? 1 : 0;
      const auto r = d.lss({0x13, 0x00, index});
      ASSERT_EQ(r.size(), 1u);
      EXPECT_EQ(r[0].data[1], in_eds ? 0 : 1) << "upstream.bitrate " << bitrate << ", index " << int(index);
    }
    // CiA 852 §6.2's four, and the configured rate when it is another one.
    const bool mandatory = bitrate == 125000 || bitrate == 250000 || bitrate == 500000 || bitrate == 1000000;
    EXPECT_EQ(listed, mandatory ? 4u : 5u) << bitrate;
    EXPECT_TRUE(eds_lists(eds, bitrate / 1000));
  }
}

// The device starts on upstream.bitrate's index, which activate bit timing keeps until a
// configure changes it.
TEST(UpstreamBitRate, TheDeviceRunsAtUpstreamBitrate) {
  Device d(load(file_for(500000)));
  EXPECT_EQ(d.device().node().bit_timing_index(), 2u);
  EXPECT_EQ(d.device().node().lss().pending_bit_timing(), 2u);
}

// Activate bit timing: the program is told the new rate in bit/s at the switch, after the first
// switch delay (canopen/node.hpp has the silence frame by frame).
TEST(UpstreamBitRate, ActivateBitTimingReportsTheNewRateInBitPerSecondAtTheSwitch) {
  Device d(load(file_for(250000)));
  std::vector<std::pair<TimePoint, std::uint32_t>> switches;
  d.device().on_bit_rate_switch([&](std::uint32_t rate) { switches.emplace_back(d.now, rate); });
  EXPECT_TRUE(d.lss({0x04, 0x01}).empty());
  ASSERT_EQ(d.lss({0x13, 0x00, 0x04})[0].data[1], 0);
  const TimePoint t0 = d.now;
  EXPECT_TRUE(d.lss({0x15, 0xC8, 0x00}).empty());  // 200 ms
  d.at(t0 + 199ms);
  EXPECT_TRUE(switches.empty());
  d.at(t0 + 200ms);
  ASSERT_EQ(switches.size(), 1u);
  EXPECT_EQ(switches[0].second, 125000u);
  d.out.clear();
  d.at(t0 + 399ms);
  EXPECT_TRUE(d.out.empty());
  // Then the heartbeat (100 ms, the default) goes on.
  for (auto t = t0 + 400ms; t <= t0 + 700ms; t += 10ms) d.at(t);
  ASSERT_GE(d.out.size(), 3u);
  EXPECT_EQ(d.out[0].id, 0x720u);
  EXPECT_EQ(d.out[0].data[0], 0x7F);
}

class StoredRate : public ::testing::Test {
 protected:
  StoredRate() {
    dir_ = std::filesystem::temp_directory_path() / ("oegw-bitrate-test-" + std::to_string(::getpid()) + "-" +
                                                     ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  ~StoredRate() override { std::filesystem::remove_all(dir_); }
  std::string store() const { return (dir_ / "upstream.store").string(); }
  void write_lss(int node, int bit_timing) const {
    std::ofstream(store() + ".lss") << "node_id=" << node << "\nbit_timing=" << bit_timing << "\n";
  }
  std::filesystem::path dir_;
};

TEST_F(StoredRate, WithoutAStoreUpstreamBitrateApplies) {
  const auto r = gateway::upstream_bit_rate(load(file_for(250000, store())));
  EXPECT_EQ(r.bitrate, 250000u);
  EXPECT_FALSE(r.lss_stored);
  EXPECT_TRUE(r.note.empty());
}

TEST_F(StoredRate, AnLssStoredRateOverridesUpstreamBitrateAndSaysSo) {
  write_lss(0x20, 4);
  const auto r = gateway::upstream_bit_rate(load(file_for(250000, store())));
  EXPECT_EQ(r.bitrate, 125000u);
  EXPECT_TRUE(r.lss_stored);
  EXPECT_EQ(r.note, "the LSS-stored bit rate 125000 bit/s (" + store() +
                        ".lss) overrides upstream.bitrate 250000: CiA 305 store configuration keeps the rate the host "
                        "configured last");
}

TEST_F(StoredRate, AStoredRateEqualToUpstreamBitrateIsNamedAsSuch) {
  write_lss(0x20, 3);
  const auto r = gateway::upstream_bit_rate(load(file_for(250000, store())));
  EXPECT_EQ(r.bitrate, 250000u);
  EXPECT_TRUE(r.lss_stored);
  EXPECT_NE(r.note.find("is upstream.bitrate's"), std::string::npos) << r.note;
}

TEST_F(StoredRate, AStoredIndexWithoutARateLeavesUpstreamBitrate) {
  write_lss(0x20, 9);  // table 0 index 9: automatic bit rate detection, no rate
  const auto r = gateway::upstream_bit_rate(load(file_for(250000, store())));
  EXPECT_EQ(r.bitrate, 250000u);
  EXPECT_FALSE(r.lss_stored);
  EXPECT_NE(r.note.find("upstream.bitrate 250000 applies"), std::string::npos) << r.note;
}

// The whole way: configure 125 kbit/s, store; the next start of a device from the same file runs
// at the stored index, and upstream_bit_rate() says the same rate for the interface.
TEST_F(StoredRate, AConfiguredAndStoredRateIsTheDevicesAtTheNextStart) {
  const mapping::Config c = load(file_for(250000, store()));
  {
    Device d(c);
    EXPECT_TRUE(d.lss({0x04, 0x01}).empty());
    ASSERT_EQ(d.lss({0x13, 0x00, 0x04})[0].data[1], 0);
    ASSERT_EQ(d.lss({0x17})[0].data[1], 0);
  }
  Device again(c);
  EXPECT_EQ(again.device().node().bit_timing_index(), 4u);
  EXPECT_EQ(gateway::upstream_bit_rate(c).bitrate, 125000u);
}

}  // namespace

namespace {

// The same through the Gateway (what `oegw run` drives): silent for 2 x 100 ms, then the
// heartbeat goes on.
TEST(UpstreamBitRate, TheGatewaysHeartbeatGoesOnAfterAnActivate) {
  const mapping::Config c = load(file_for(250000));
  std::vector<CanFrame> up;
  gateway::Gateway gw(
      c, [&](const CanFrame& f) { up.push_back(f); }, [](const CanFrame&) {});
  std::vector<std::uint32_t> switches;
  gw.upstream().on_bit_rate_switch([&](std::uint32_t r) { switches.push_back(r); });
  TimePoint now{std::chrono::seconds(5)};
  gw.start(now);
  auto lss = [&](std::initializer_list<std::uint8_t> b) {
    std::vector<std::uint8_t> v(b);
    v.resize(8, 0);
    gw.on_upstream_frame(CanFrame(canopen::cob::kLssMaster, std::span<const std::uint8_t>(v)), now);
  };
  lss({0x04, 0x01});
  lss({0x13, 0x00, 0x04});
  lss({0x15, 0x64, 0x00});
  lss({0x04, 0x00});
  up.clear();
  const TimePoint t0 = now;
  for (now = t0; now <= t0 + 1s; now += 10ms) gw.advance(now);
  EXPECT_EQ(switches, std::vector<std::uint32_t>{125000});
  unsigned heartbeats = 0;
  for (const auto& f : up) heartbeats += f.id == 0x720 ? 1 : 0;
  EXPECT_GE(heartbeats, 7u);
}

}  // namespace
