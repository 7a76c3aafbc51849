// The whole downstream side on the virtual bus: the four device-family simulators (SimBench,
// as oegw-sim runs them) booted and watched by the network manager with the real drivers
// (make_driver), under a simulated clock. Includes the generic CiA 401 node whose PDO mapping
// the manager reads back over SDO at boot (boot reads in rounds) after it was remapped.
#include <gtest/gtest.h>

#include <algorithm>

#include "canopen/master.hpp"
#include "subdevices/device_spec.hpp"
#include "subdevices/network_manager.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "virtual_network.hpp"

using namespace oegw::canopen;
using namespace oegw::subdevices;
using namespace std::chrono_literals;

namespace {

const char* const kDevices[] = {
    "elobau-mfg:0x11:name=grip",
    "mcb402:0x03:name=stick",
    "novotechnik-406:0x7F:name=knob",
    "cia401:0x30:name=pedal,eds=" OEGW_SOURCE_DIR "/subdevices/eds/generic_pedal.eds",
};

class DownstreamNetwork : public ::testing::Test {
 protected:
  DownstreamNetwork() : bench_(net_.sink("sims")) {}
  void SetUp() override {
    for (const char* text : kDevices) {
      std::string error;
      auto spec = parse_device_spec(text, error);
      ASSERT_TRUE(spec) << error;
      ASSERT_TRUE(bench_.add(*spec, error)) << error;
      DeviceSpec driver_spec = *spec;
      std::string name;
      std::erase_if(driver_spec.options.values, [&](const auto& kv) {
        if (kv.first == "name") name = kv.second;
        return kv.first == "name";
      });
      // The bit order the mapping file would give: the simulator's (the document's table).
      if (spec->family == "mcb402") driver_spec.options.values.emplace_back("button_bits", "1,2,3,4,5,7,6");
      auto driver = make_driver(spec->family, spec->node, net_.sink("gateway"), driver_spec.options, error);
      ASSERT_TRUE(driver) << error;
      NodeSettings s;
      s.name = name;
      s.node = spec->node;
      s.heartbeat_ms = 100;
      s.mandatory = true;
      ASSERT_TRUE(network_.add(s, std::move(driver)));
    }
    net_.attach("sims", bench_);
    net_.attach("gateway", network_);
    network_.on_node_state = [this](const std::string& n, NodeState s, const std::string& why) {
      log_.push_back(n + ": " + std::string(to_string(s)) + " (" + why + ")");
    };
  }
  std::int64_t value(const char* node, const char* signal) {
    Driver* d = network_.driver(node);
    return d->value(*d->find_signal(signal)).value;
  }
  SignalStatus status(const char* node, const char* signal) {
    Driver* d = network_.driver(node);
    return d->value(*d->find_signal(signal)).status;
  }
  std::string states() {
    std::string s;
    for (auto& l : log_) s += l + "\n";
    return s;
  }

  oegw::testing::VirtualNetwork net_;
  sim::SimBench bench_;
  ObjectDictionary od_;
  Master master_{od_, net_.sink("gateway"), MasterConfig{.heartbeat_entries = 8, .sdo_timeout = 200ms}};
  NetworkManager network_{master_};
  std::vector<std::string> log_;
};

TEST_F(DownstreamNetwork, EveryFamilyBootsAndItsInputsArrive) {
  bench_.start(net_.now());
  network_.start(net_.now());
  net_.run_for(3s);
  for (const char* n : {"grip", "stick", "knob", "pedal"})
    EXPECT_EQ(network_.state(n), NodeState::Operational) << n << "\n" << states();
  EXPECT_FALSE(network_.fault());
  EXPECT_EQ(bench_.command("grip x 40", net_.now()), "ok grip x = 40");
  EXPECT_EQ(bench_.command("stick y -12000", net_.now()), "ok stick y = -12000");
  EXPECT_EQ(bench_.command("knob position 123456", net_.now()), "ok knob position = 123456");
  EXPECT_EQ(bench_.command("pedal analog[1] 20000", net_.now()), "ok pedal analog[1] = 20000");
  EXPECT_EQ(bench_.command("grip buttons[2] 1", net_.now()), "ok grip buttons[2] = 1");
  net_.run_for(500ms);
  EXPECT_EQ(value("grip", "x"), 40);
  EXPECT_EQ(status("grip", "x"), SignalStatus::Valid);
  EXPECT_EQ(value("grip", "buttons[2]"), 1);
  EXPECT_EQ(value("stick", "y"), -12000);
  EXPECT_EQ(value("knob", "position"), 123456);
  EXPECT_EQ(value("pedal", "analog[1]"), 20000);
  // Bad commands are refused with what was wrong.
  EXPECT_EQ(bench_.command("grip x 500", net_.now()), "error: grip has no input 'x' taking 500");
  EXPECT_EQ(bench_.command("nobody x 1", net_.now()).rfind("error: no device 'nobody'", 0), 0u);
}

TEST_F(DownstreamNetwork, SilentGripGoesOfflineAndComesBackAfterReboot) {
  bench_.start(net_.now());
  network_.start(net_.now());
  net_.run_for(3s);
  ASSERT_EQ(network_.state("grip"), NodeState::Operational) << states();
  (void)bench_.command("grip x 30", net_.now());
  net_.run_for(200ms);
  ASSERT_EQ(value("grip", "x"), 30);
  EXPECT_EQ(bench_.command("grip silent on", net_.now()), "ok grip silent on");
  net_.run_for(300ms);
  EXPECT_EQ(network_.state("grip"), NodeState::Missing);
  EXPECT_EQ(status("grip", "x"), SignalStatus::Offline);
  EXPECT_EQ(value("grip", "x"), 0);
  EXPECT_TRUE(network_.fault()) << "the grip is mandatory";
  EXPECT_EQ(network_.state("stick"), NodeState::Operational) << "the others are not affected";
  (void)bench_.command("grip silent off", net_.now());
  (void)bench_.command("grip reboot", net_.now());
  net_.run_for(5s);
  EXPECT_EQ(network_.state("grip"), NodeState::Operational) << states();
  EXPECT_FALSE(network_.fault());
}

TEST_F(DownstreamNetwork, HeartbeatStoppedAloneIsAlsoALostNode) {
  bench_.start(net_.now());
  network_.start(net_.now());
  net_.run_for(3s);
  (void)bench_.command("stick heartbeat off", net_.now());
  net_.run_for(300ms);
  EXPECT_EQ(network_.state("stick"), NodeState::Missing);
  EXPECT_EQ(status("stick", "x"), SignalStatus::Offline);
}

TEST_F(DownstreamNetwork, ARemappedGenericNodeIsDecodedFromItsActualMapping) {
  bench_.start(net_.now());
  // Before the gateway starts, somebody remapped the pedal's TPDO1 to carry 6401h:01 only, on
  // a different COB-ID: the driver must read the real mapping rather than trust the EDS.
  auto* pedal = bench_.device("pedal");
  ASSERT_NE(pedal, nullptr);
  auto& od = pedal->od();
  ASSERT_EQ(od.set<std::uint32_t>(0x1800, 1, 0x800001B0u, Origin::Sdo), SdoAbortCode::None);
  ASSERT_EQ(od.set<std::uint8_t>(0x1A00, 0, 0, Origin::Sdo), SdoAbortCode::None);
  ASSERT_EQ(od.set<std::uint32_t>(0x1A00, 1, 0x64010110u, Origin::Sdo), SdoAbortCode::None);
  ASSERT_EQ(od.set<std::uint8_t>(0x1A00, 0, 1, Origin::Sdo), SdoAbortCode::None);
  ASSERT_EQ(od.set<std::uint32_t>(0x1800, 1, 0x1B0u, Origin::Sdo), SdoAbortCode::None);
  network_.start(net_.now());
  net_.run_for(3s);
  ASSERT_EQ(network_.state("pedal"), NodeState::Operational) << states();
  (void)bench_.command("pedal analog[1] -777", net_.now());
  net_.run_for(200ms);
  EXPECT_EQ(value("pedal", "analog[1]"), -777);
}

// oegw-sim filters out the data frames on these COB-IDs (its port's acceptance filter), so the
// list must follow the dictionaries: a TPDO made invalid leaves it, a new COB-ID enters it, each
// once and in order.
TEST_F(DownstreamNetwork, TheBenchsTpdoCobIdsFollowTheDictionaries) {
  bench_.start(net_.now());
  const auto has = [&](std::uint32_t raw) {
    const auto ids = bench_.tpdo_cob_ids();
    return std::find(ids.begin(), ids.end(), CobId{raw}) != ids.end();
  };
  EXPECT_TRUE(has(0x191));  // the grip's TPDO #0 (elobau §14.1)
  EXPECT_TRUE(has(0x1B0));  // the pedal's TPDO1, 180h + 30h
  auto& od = bench_.device("pedal")->od();
  ASSERT_EQ(od.set<std::uint32_t>(0x1800, 1, 0x800001B0u, Origin::Sdo), SdoAbortCode::None);
  EXPECT_FALSE(has(0x1B0));
  ASSERT_EQ(od.set<std::uint32_t>(0x1800, 1, 0x1B5u, Origin::Sdo), SdoAbortCode::None);
  EXPECT_TRUE(has(0x1B5));
  const auto ids = bench_.tpdo_cob_ids();
  EXPECT_TRUE(std::is_sorted(ids.begin(), ids.end(), [](CobId a, CobId b) { return a.raw() < b.raw(); }));
  EXPECT_EQ(std::adjacent_find(ids.begin(), ids.end()), ids.end());
  for (const CobId cob : ids) EXPECT_TRUE(cob.valid()) << std::hex << cob.raw();
  // A PDO may have several consumers: with the grip's RPDO listening to the pedal's TPDO, that
  // TPDO's frames are not filtered out
  // (the elobau grip's RPDO COB-IDs are read-only to SDO: set as its firmware would).
  auto& grip = bench_.device("grip")->od();
  ASSERT_EQ(grip.set<std::uint32_t>(0x1400, 1, 0x800001B5u, Origin::Local), SdoAbortCode::None);
  ASSERT_EQ(grip.set<std::uint32_t>(0x1400, 1, 0x1B5u, Origin::Local), SdoAbortCode::None);
  EXPECT_FALSE(has(0x1B5));
}

// MasterConfig::sdo_request_gap paces the requests of every SDO client the master hands out
// (Master::sdo), whichever node they go to: four nodes asked at once go out a gap apart.
TEST(MasterSdoPacing, EveryClientOfTheMasterSharesItsPacer) {
  const TimePoint t0{std::chrono::seconds(20)};
  ObjectDictionary od;
  std::vector<std::pair<TimePoint, CanFrame>> sent;
  TimePoint now = t0;
  Master master(
      od, [&](const CanFrame& f) { sent.emplace_back(now, f); }, MasterConfig{.sdo_request_gap = 3ms});
  EXPECT_EQ(master.sdo_pacer().gap(), 3ms);
  for (std::uint8_t n = 1; n <= 4; ++n)
    master.sdo(NodeId{n}).upload(0x1000, 0, [](SdoAbortCode, std::vector<std::uint8_t>) {});
  for (int i = 0; i < 20 && master.next_deadline(); ++i) {
    now = std::max(now, *master.next_deadline());
    if (now > t0 + 20ms) break;
    master.advance(now);
  }
  ASSERT_EQ(sent.size(), 4u);
  for (std::size_t i = 0; i < sent.size(); ++i) {
    EXPECT_EQ(sent[i].first, t0 + 3ms * static_cast<int>(i)) << sent[i].second.to_string();
    EXPECT_EQ(sent[i].second.id & 0x780u, 0x600u);
  }
}

}  // namespace
