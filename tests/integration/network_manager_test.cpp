// The downstream network manager against real protocol-core nodes on the virtual bus, with a
// simulated clock: boot sequence frame by frame, identity check, missing node back-off,
// heartbeat loss, reboot mid-operation, SDO timeout during configuration, mandatory nodes,
// PDO routing and bad input.
#include "subdevices/network_manager.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>

#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "canopen/node.hpp"
#include "canopen/state.hpp"
#include "tests/unit/canopen/state_twin.hpp"
#include "virtual_network.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace oegw::subdevices;
using namespace std::chrono_literals;

namespace {

constexpr NodeId kNode{0x11};

// A minimal driver: one input byte from TPDO1 (6000h:01).
class ByteDriver final : public Driver {
 public:
  // `cob`: the TPDO's COB-ID, 180h + node-ID unless given.
  ByteDriver(NodeId node, FrameSink sink, std::uint32_t cob = 0) : cob_(cob != 0 ? cob : cob::kTpdo1 + node.value()) {
    signals_ = {SignalInfo{"in", SignalKind::Digital, 0, 255, 0, "bits"}};
    init(node, std::move(sink), signals_.size());
  }
  std::string_view family() const override { return "test-byte"; }
  const std::vector<SignalInfo>& signals() const override { return signals_; }
  ExpectedIdentity expected_identity() const override { return {.device_type = 0x000F0191}; }
  std::vector<SdoWrite> configuration() const override {
    return {SdoWrite{0x1800, 5, encode<std::uint16_t>(50), "TPDO1 event timer 50 ms"}};
  }
  bool on_frame(const CanFrame& f, TimePoint now) override {
    if (f.id != cob_) return false;
    if (f.dlc != 1) {
      ++counters_.wrong_length;
      return false;
    }
    update(0, f.data[0], SignalStatus::Valid, now);
    return true;
  }
  DecodedEmcy on_emcy(const EmcyMessage& e, TimePoint now) override {
    emcys.push_back(e.code);
    if (e.code != 0) update(0, 0, SignalStatus::Error, now);
    return {e.code, "test", e.code != 0, {}};
  }
  std::vector<std::uint32_t> consumed_cob_ids() const override { return {cob_}; }
  bool set_output(std::size_t, std::int64_t, TimePoint) override { return false; }
  std::vector<std::uint16_t> emcys;

 private:
  std::vector<SignalInfo> signals_;
  std::uint32_t cob_;
};

class Device {
 public:
  Device(oegw::testing::VirtualNetwork& net, std::uint32_t vendor = 0x15A, std::filesystem::path store = {},
         NodeId id = kNode) {
    od.add_array(0x6000, "Read input 8-bit", DataType::Unsigned8, Access::ReadOnly, 1, {0}, true);
    install_tpdo(od, 1,
                 PdoParameters{.cob_id = cob::kTpdo1 + kNode.value(),
                               .transmission_type = 0xFF,
                               .mapping = {pdo_map(0x6000, 1, 8)}});
    NodeConfig cfg;
    cfg.node_id = id;
    cfg.device_type = 0x000F0191;
    cfg.identity = {.vendor = vendor, .product = 1, .revision = 1, .serial = 7};
    cfg.store_path = std::move(store);  // LSS "store configuration" needs somewhere to store
    const std::string name = id == kNode ? "device" : "device " + std::to_string(id.value());
    node = std::make_unique<Node>(od, cfg, net.sink(name));
    net.attach(name, *node);
  }
  ObjectDictionary od;
  std::unique_ptr<Node> node;
};

class NetworkManagerTest : public ::testing::Test {
 protected:
  NetworkManagerTest() {
    master_ = std::make_unique<Master>(master_od_, net_.sink("gateway"),
                                       MasterConfig{.heartbeat_entries = 8, .sdo_timeout = 100ms});
    manager_ = std::make_unique<NetworkManager>(*master_);
    net_.attach("gateway", *manager_);
    manager_->on_node_state = [this](const std::string&, NodeState s, const std::string& why) {
      states_.push_back(s);
      reasons_.push_back(why);
    };
    auto drv = std::make_unique<ByteDriver>(kNode, net_.sink("gateway"));
    driver_ = drv.get();
    NodeSettings settings{.name = "grip",
                          .node = kNode,
                          .heartbeat_ms = 100,
                          .heartbeat_timeout_ms = 0,
                          .mandatory = true,
                          .identity = {.vendor_id = 0x15A},
                          .sdo = {}};
    settings.sdo.push_back(SdoWrite{0x1800, 2, {0xFE}, "TPDO1 type 254"});
    EXPECT_TRUE(manager_->add(settings, std::move(drv)));
    net_.bus().set_logging(true);
  }
  void start() {
    manager_->start(net_.now());
    net_.settle();
  }
  std::vector<std::string> frames() {
    std::vector<std::string> out;
    for (const auto& r : net_.bus().log()) out.push_back(r.sender + " " + r.frame.to_string());
    return out;
  }

  oegw::testing::VirtualNetwork net_;
  ObjectDictionary master_od_;
  std::unique_ptr<Master> master_;
  std::unique_ptr<NetworkManager> manager_;
  ByteDriver* driver_ = nullptr;
  std::vector<NodeState> states_;
  std::vector<std::string> reasons_;
};

TEST_F(NetworkManagerTest, BootsTheNodeFrameByFrame) {
  Device dev(net_);
  (void)dev.node->start(net_.now());
  net_.settle();
  net_.bus().clear_log();
  EXPECT_TRUE(manager_->fault()) << "mandatory and not yet operational";
  start();
  net_.run_for(50ms);
  // Started, but no heartbeat in operational yet: no proof of life, inputs not live.
  EXPECT_EQ(manager_->state("grip"), NodeState::Starting);
  EXPECT_TRUE(manager_->fault());
  EXPECT_EQ(dev.node->state(), NmtState::Operational);
  net_.run_for(100ms);  // the node's first heartbeat (1017h = 100 ms) reports operational
  EXPECT_EQ(manager_->state("grip"), NodeState::Operational);
  EXPECT_EQ(reasons_.back(), "first heartbeat in operational after NMT start");
  EXPECT_FALSE(manager_->fault());
  const std::vector<std::string> want = {
      "gateway 000#8211",              // NMT reset communication
      "device 711#00",                 // boot-up
      "gateway 000#8011",              // NMT enter pre-operational before configuring
      "gateway 611#4000100000000000",  // read 1000h
      "device 591#4300100091010F00",   //   000F0191h
      "gateway 611#4018100100000000",  // read 1018h:01
      "device 591#431810015A010000",   //   0000015Ah
      "gateway 611#4018100200000000",  // read 1018h:02..04 (diagnostics)
      "device 591#4318100201000000",
      "gateway 611#4018100300000000",
      "device 591#4318100301000000",
      "gateway 611#4018100400000000",
      "device 591#4318100407000000",
      "gateway 611#4008100000000000",  // read 1008h device name
      "device 591#430810006F656777",   //   "oegw"
      "gateway 611#4009100000000000",  // read 1009h hardware version
      "device 591#4F09100031000000",   //   "1"
      "gateway 611#400A100000000000",  // read 100Ah software version
      "device 591#410A100005000000",   //   5 bytes, segmented
      "gateway 611#6000000000000000",
      "device 591#05302E312E300000",   //   "0.1.0"
      "gateway 611#4001100000000000",  // read 1001h error register
      "device 591#4F01100000000000",   //   00h
      "gateway 611#2B17100064000000",  // 1017h = 100 ms
      "device 591#6017100000000000",
      "gateway 611#2B00180532000000",  // driver: 1800h:05 = 50 ms
      "device 591#6000180500000000",
      "gateway 611#2F001802FE000000",  // configuration file: 1800h:02 = FEh
      "device 591#6000180200000000",
      "gateway 000#0111",  // NMT start
  };
  const auto got = frames();
  ASSERT_GE(got.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) EXPECT_EQ(got[i], want[i]) << "frame " << i;
  (void)dev.od.set<std::uint8_t>(0x6000, 1, 0x42);
  net_.run_for(10ms);
  EXPECT_EQ(driver_->value(0).value, 0x42);
  EXPECT_EQ(driver_->value(0).status, SignalStatus::Valid);
}

TEST_F(NetworkManagerTest, WrongIdentityIsRefusedWithTheReasonAndNotStarted) {
  Device dev(net_, 0x999);
  (void)dev.node->start(net_.now());
  start();
  net_.run_for(50ms);
  EXPECT_EQ(manager_->state("grip"), NodeState::Refused);
  EXPECT_EQ(reasons_.back(), "1018h:01 is 00000999h, the configuration expects 0000015Ah");
  EXPECT_EQ(dev.node->state(), NmtState::PreOperational) << "a wrong device is never started";
  EXPECT_TRUE(manager_->fault());
  // Retried after the back-off: NMT reset communication again at +1 s.
  net_.bus().clear_log();
  net_.run_for(1s);
  ASSERT_FALSE(frames().empty());
  EXPECT_EQ(frames()[0], "gateway 000#8211");
}

TEST_F(NetworkManagerTest, MissingNodeIsRetriedWithDoublingBackOff) {
  std::vector<TimePoint> resets;
  net_.bus().set_tap([&](const BusRecord& r) {
    if (r.frame == CanFrame(0x000, {0x82, 0x11})) resets.push_back(r.time);
  });
  start();
  net_.run_for(30s);
  EXPECT_EQ(manager_->state("grip"), NodeState::Missing);
  EXPECT_EQ(driver_->value(0).status, SignalStatus::Offline);
  // Boot wait 2 s, SDO timeout 100 ms, then back-off 1, 2, 4, 8 s between attempts.
  ASSERT_GE(resets.size(), 4u);
  std::vector<Duration> gaps;
  for (std::size_t i = 1; i < resets.size(); ++i)
    gaps.push_back(std::chrono::duration_cast<Duration>(resets[i] - resets[i - 1]));
  EXPECT_EQ(gaps[0], 2s + 100ms + 1s);
  EXPECT_EQ(gaps[1], 2s + 100ms + 2s);
  EXPECT_EQ(gaps[2], 2s + 100ms + 4s);
  // Within each wait the boot-up probe read 1000h at +100 ms, then after gaps of 200, 400 and
  // 800 ms from each time-out (+400, +900, +1800 ms), and the wait's end read it once more.
  std::vector<Duration> reads;
  for (const auto& r : net_.bus().log())
    if (r.time >= resets[0] && r.time < resets[1] && r.frame == CanFrame(0x611, {0x40, 0x00, 0x10, 0, 0, 0, 0, 0}))
      reads.push_back(std::chrono::duration_cast<Duration>(r.time - resets[0]));
  EXPECT_EQ(reads, (std::vector<Duration>{100ms, 400ms, 900ms, 1800ms, 2s}));
  // The node appears: the next attempt brings it up.
  Device dev(net_);
  (void)dev.node->start(net_.now());
  net_.run_for(20s);
  EXPECT_EQ(manager_->state("grip"), NodeState::Operational);
}

// A boot-up that never arrives (lost on the bus) is not waited out for boot_wait
// (2 s): the probe reads 1000h 100 ms after the reset, the node's answer starts its
// configuration, and it is operational at its first heartbeat after that.
TEST_F(NetworkManagerTest, ALostBootUpIsNotWaitedOutTheProbeFindsTheNode) {
  Device dev(net_);
  (void)dev.node->start(net_.now());
  net_.settle();
  net_.bus().drop_next(1, [](const CanFrame& f) { return f.id == 0x711 && f.dlc == 1 && f.data[0] == 0x00; });
  const TimePoint t0 = net_.now();
  start();
  net_.run_for(99ms);
  EXPECT_EQ(manager_->state("grip"), NodeState::WaitingBootUp);
  EXPECT_EQ(net_.bus().dropped_frames(), 1u) << "the boot-up answering the reset was lost";
  net_.run_for(1ms);
  EXPECT_EQ(reasons_.at(1),
            "no boot-up seen, but the node answered 1000h (it is past its reset): checking identity and configuring");
  ASSERT_NE(manager_->state("grip"), NodeState::WaitingBootUp);
  net_.run_for(150ms);
  ASSERT_EQ(manager_->state("grip"), NodeState::Operational);
  EXPECT_LT(net_.now() - t0, 2s);
  EXPECT_EQ(manager_->node_counters("grip").reboots_seen, 0u);
  EXPECT_EQ(manager_->node_counters("grip").gateway_resets, 0u) << "no boot-up was seen";
  EXPECT_EQ(dev.od.get<std::uint16_t>(0x1017, 0), 100) << "configured";
}

// The probe's answer overtook the boot-up (queued in the device behind it: 591h wins
// arbitration over 711h). The boot-up then comes during the configuration: it is the reset's
// answer, not a reboot of the device — counted so, no application reset reported — and the
// configuration starts over, as it must for a reboot, which would look the same. Once the node
// has proved itself alive, a boot-up is a reboot again.
TEST_F(NetworkManagerTest, ABootUpBehindTheProbesAnswerIsTheResetsAnswer) {
  Device dev(net_);
  (void)dev.node->start(net_.now());
  net_.settle();
  int application_resets = 0;
  manager_->on_application_reset = [&](const std::string&) { ++application_resets; };
  net_.bus().drop_next(1, [](const CanFrame& f) { return f.id == 0x711 && f.dlc == 1 && f.data[0] == 0x00; });
  // The queued boot-up goes out while the gateway reads 1018h:01, the configuration under way.
  bool injected = false;
  net_.bus().set_tap([&](const BusRecord& r) {
    if (!injected && r.frame == CanFrame(0x611, {0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0})) {
      injected = true;
      (void)net_.bus().inject(CanFrame(0x711, {0x00}), "device");
    }
  });
  start();
  net_.run_for(101ms);
  ASSERT_TRUE(injected);
  const auto said = [this](const std::string& why) { return std::count(reasons_.begin(), reasons_.end(), why); };
  EXPECT_EQ(said("boot-up answering the reset after the node's SDO answer (or a reboot meanwhile, which looks the "
                 "same): configuring from the start"),
            1);
  NodeCounters c = manager_->node_counters("grip");
  EXPECT_EQ(c.gateway_resets, 1u);
  EXPECT_EQ(c.reboots_seen, 0u);
  EXPECT_EQ(application_resets, 0) << "a reset communication keeps the device's errors";
  net_.run_for(300ms);
  ASSERT_EQ(manager_->state("grip"), NodeState::Operational);
  dev.node->nmt().reset(false, net_.now());  // now a reboot of its own
  net_.run_for(1ms);
  c = manager_->node_counters("grip");
  EXPECT_EQ(c.reboots_seen, 1u);
  EXPECT_EQ(c.gateway_resets, 1u);
  EXPECT_EQ(application_resets, 1);
}

// A configured node's NMT start is held while another node waits for its boot-up or is being
// configured — their SDO frames would delay its heartbeats past the consumer time (without the
// hold the full set at 250 kbit/s did not boot) — but not for a node that left a probe
// unanswered (likely absent): here 12h, absent, whose probe (at +100 ms) times out at +200 ms.
TEST_F(NetworkManagerTest, TheStartWaitsForTheOtherNodesBootButNotForAnAbsentOne) {
  auto other = std::make_unique<ByteDriver>(NodeId{0x12}, net_.sink("gateway"));
  ASSERT_TRUE(
      manager_->add(NodeSettings{.name = "absent", .node = NodeId{0x12}, .heartbeat_ms = 100}, std::move(other)));
  Device dev(net_);
  (void)dev.node->start(net_.now());
  net_.settle();
  std::optional<TimePoint> started, probe_timed_out;
  net_.bus().set_tap([&](const BusRecord& r) {
    if (r.frame == CanFrame(0x000, {0x01, 0x11})) started = r.time;
    if (r.frame.id == 0x612 && r.frame.data[0] == 0x80) probe_timed_out = r.time;  // the probe's abort
  });
  const TimePoint t0 = net_.now();
  start();
  net_.run_for(50ms);
  EXPECT_EQ(manager_->state("grip"), NodeState::Configuring);
  EXPECT_EQ(reasons_.back(),
            "configured; NMT start held while other nodes are being configured (their SDO frames would delay its "
            "heartbeat)");
  EXPECT_FALSE(started);
  net_.run_for(200ms);
  ASSERT_TRUE(started) << "held for ever";
  ASSERT_TRUE(probe_timed_out);
  EXPECT_EQ(*probe_timed_out - t0, 200ms);
  EXPECT_EQ(*started, *probe_timed_out) << "released when the absent node's probe went unanswered";
  net_.run_for(200ms);
  EXPECT_EQ(manager_->state("grip"), NodeState::Operational);
  EXPECT_EQ(manager_->state("absent"), NodeState::WaitingBootUp);
}

// A probe that timed out is answered late (the device queued it during its reset), after the
// boot-up started the configuration: its answer is taken for the configuration's own 1000h
// read (same object, same value), and that read's real answer, arriving while 1018h:01 is
// asked, is dropped as stale (SdoClient::stale_answers) — it was taken for the 1018h:01 answer
// and the node refused (abort 08000000h) before.
TEST_F(NetworkManagerTest, ALateAnswerToATimedOutProbeDoesNotShiftTheConfiguration) {
  Device dev(net_);
  (void)dev.node->start(net_.now());
  net_.settle();
  // Its boot-up lost; the probe (+100 ms) reaches it still resetting: no answer, the probe
  // times out at +200 ms (one drop_next for both: it holds one rule at a time).
  net_.bus().drop_next(2, [](const CanFrame& f) {
    return (f.id == 0x711 && f.dlc == 1 && f.data[0] == 0x00) ||
           (f.id == 0x591 && f.data[1] == 0x00 && f.data[2] == 0x10);
  });
  start();
  net_.run_for(250ms);
  ASSERT_EQ(manager_->state("grip"), NodeState::WaitingBootUp) << ::testing::PrintToString(reasons_);
  // Its boot-up now, and the late answer to the probe while the configuration reads 1000h.
  bool injected = false;
  net_.bus().set_tap([&](const BusRecord& r) {
    if (!injected && r.frame == CanFrame(0x611, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0})) {
      injected = true;
      (void)net_.bus().inject(CanFrame(0x591, {0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x0F, 0x00}), "device");
    }
  });
  net_.sink("device")(CanFrame(0x711, {0x00}));
  net_.run_for(300ms);
  ASSERT_TRUE(injected);
  EXPECT_EQ(manager_->state("grip"), NodeState::Operational) << reasons_.back();
  EXPECT_EQ(std::count(states_.begin(), states_.end(), NodeState::Refused), 0);
  EXPECT_EQ(master_->sdo(kNode).stale_answers(), 1u);
}

TEST_F(NetworkManagerTest, HeartbeatLossMarksInputsOfflineAndTheReturningNodeIsRestarted) {
  Device dev(net_);
  (void)dev.node->start(net_.now());
  start();
  net_.run_for(100ms);
  (void)dev.od.set<std::uint8_t>(0x6000, 1, 7);
  net_.run_for(10ms);
  ASSERT_EQ(driver_->value(0).status, SignalStatus::Valid);
  net_.detach("device");  // cable pulled: nothing more from the device
  net_.run_for(200ms);
  EXPECT_EQ(manager_->state("grip"), NodeState::Missing);
  EXPECT_EQ(reasons_.back(), "heartbeat lost");
  EXPECT_EQ(driver_->value(0).status, SignalStatus::Offline);
  EXPECT_EQ(driver_->value(0).value, 0) << "offline inputs go to their neutral value";
  net_.attach("device", *dev.node);
  net_.run_for(5s);
  EXPECT_EQ(manager_->state("grip"), NodeState::Operational);
  EXPECT_EQ(dev.node->state(), NmtState::Operational);
}

TEST_F(NetworkManagerTest, RebootMidOperationIsReconfiguredAndRestarted) {
  Device dev(net_);
  (void)dev.node->start(net_.now());
  start();
  net_.run_for(100ms);
  ASSERT_EQ(dev.node->state(), NmtState::Operational);
  dev.node->nmt().reset(false, net_.now());  // the device reboots on its own
  net_.run_for(100ms);
  EXPECT_EQ(manager_->counters().reboots_seen, 1u);
  EXPECT_EQ(manager_->state("grip"), NodeState::Operational);
  EXPECT_EQ(dev.node->state(), NmtState::Operational);
  EXPECT_EQ(dev.od.get<std::uint16_t>(0x1017, 0), 100) << "reconfigured after the reboot";
}

// `oegw status`'s per-node counters: every frame the device sent (boot-ups, SDO answers,
// heartbeats, its TPDO, an EMCY) counts for it, nothing of another node or of the gateway does.
TEST_F(NetworkManagerTest, CountsEachNodesFramesAndReboots) {
  Device dev(net_);
  (void)dev.node->start(net_.now());
  start();
  net_.run_for(100ms);
  (void)dev.od.set<std::uint8_t>(0x6000, 1, 7);
  dev.node->emcy().raise(0x1000, 0x01, net_.now());
  net_.run_for(300ms);
  auto stranger = net_.sink("stranger");
  stranger(CanFrame(0x712, {0x05}));         // another node's heartbeat
  stranger(CanFrame(0x192, {0x01}));         // and its PDO
  dev.node->nmt().reset(false, net_.now());  // the device reboots on its own
  net_.run_for(300ms);
  std::uint64_t from_device = 0;
  for (const auto& r : net_.bus().log()) from_device += r.sender == "device" ? 1 : 0;
  const NodeCounters c = manager_->node_counters("grip");
  EXPECT_GT(from_device, 10u);
  EXPECT_EQ(c.frames, from_device);
  EXPECT_EQ(c.reboots_seen, 1u);
  EXPECT_EQ(manager_->node_counters("nobody").frames, 0u);
}

// "reboots seen" are the device's own: the boot-ups answering the gateway's NMT resets (the
// first boot, the retry of a lost node) are counted apart, as gateway_resets.
TEST_F(NetworkManagerTest, RebootsSeenAreOnlyTheOnesTheGatewayDidNotCause) {
  Device dev(net_);
  (void)dev.node->start(net_.now());
  start();
  net_.run_for(100ms);
  ASSERT_EQ(manager_->state("grip"), NodeState::Operational);
  EXPECT_EQ(manager_->node_counters("grip").gateway_resets, 1u) << "the boot-up answering start()'s reset";
  EXPECT_EQ(manager_->node_counters("grip").reboots_seen, 0u);
  net_.detach("device");  // lost; the gateway's retry resets it when it is back
  net_.run_for(200ms);
  ASSERT_EQ(manager_->state("grip"), NodeState::Missing);
  net_.attach("device", *dev.node);
  net_.run_for(5s);
  ASSERT_EQ(manager_->state("grip"), NodeState::Operational);
  NodeCounters c = manager_->node_counters("grip");
  EXPECT_EQ(c.gateway_resets, 2u) << "the retry's reset communication, answered";
  EXPECT_EQ(c.reboots_seen, 0u) << "the gateway caused that boot-up";
  dev.node->nmt().reset(false, net_.now());  // now the device reboots on its own
  net_.run_for(300ms);
  c = manager_->node_counters("grip");
  EXPECT_EQ(c.reboots_seen, 1u);
  EXPECT_EQ(c.gateway_resets, 2u);
  EXPECT_EQ(manager_->counters().reboots_seen, 1u);
  EXPECT_EQ(manager_->counters().gateway_resets, 2u);
}

// Each boot-up is reported as what it is (the demo logged "configuring" twice with one reason):
// the answer to the gateway's reset, another during the configuration, one while operational.
TEST_F(NetworkManagerTest, EachBootUpSaysWhichItIs) {
  Device dev(net_);
  (void)dev.node->start(net_.now());
  start();
  net_.run_for(1ms);
  const auto said = [this](const std::string& why) { return std::count(reasons_.begin(), reasons_.end(), why); };
  ASSERT_EQ(manager_->state("grip"), NodeState::Starting) << "configured, NMT start sent, no heartbeat yet";
  EXPECT_EQ(said("boot-up seen: checking identity and configuring"), 1);
  const std::string again = "boot-up again during its configuration (the node reset): configuring from the start";
  const auto before = said(again);
  dev.node->nmt().reset(false, net_.now());  // a second boot-up before it is operational
  net_.run_for(1ms);
  EXPECT_EQ(said("boot-up seen: checking identity and configuring"), 1);
  EXPECT_EQ(said(again), before + 1);
  net_.run_for(300ms);
  ASSERT_EQ(manager_->state("grip"), NodeState::Operational);
  dev.node->nmt().reset(false, net_.now());
  net_.run_for(1ms);
  EXPECT_EQ(said("boot-up while operational (the node rebooted): configuring again"), 1);
}

TEST_F(NetworkManagerTest, SdoTimeoutDuringConfigurationLeavesTheNodeStoppedAndRetries) {
  Device dev(net_);
  (void)dev.node->start(net_.now());
  net_.bus().drop_next(1, [](const CanFrame& f) { return f.id == 0x591 && f.data[1] == 0x17; });
  start();
  net_.run_for(150ms);
  EXPECT_EQ(manager_->state("grip"), NodeState::Missing);
  EXPECT_NE(reasons_.back().find("writing 1017h:00 (producer heartbeat): no answer (SDO timeout)"), std::string::npos)
      << reasons_.back();
  EXPECT_EQ(dev.node->state(), NmtState::PreOperational);
  net_.run_for(2s);
  EXPECT_EQ(manager_->state("grip"), NodeState::Operational);
}

TEST_F(NetworkManagerTest, BadInputIsCountedAndNeverPassedThrough) {
  Device dev(net_);
  (void)dev.node->start(net_.now());
  start();
  net_.run_for(100ms);
  (void)dev.od.set<std::uint8_t>(0x6000, 1, 9);
  net_.run_for(10ms);
  std::vector<std::string> logged;
  manager_->on_bad_input = [&](const std::string& what) { logged.push_back(what); };
  net_.bus().inject(CanFrame(0x191, {0x01, 0x02}), "intruder");        // wrong length for this PDO
  net_.bus().inject(CanFrame(0x191, {0x01, 0x02, 0x03}), "intruder");  // again: counted, not logged again
  net_.bus().inject(CanFrame(0x1A5, {0x01}), "intruder");              // a node not configured
  net_.bus().inject(CanFrame(0x0A5, {0x00, 0x10, 0x01, 0, 0, 0, 0, 0}), "intruder");  // its EMCY
  net_.run_for(10ms);
  EXPECT_EQ(driver_->value(0).value, 9);
  EXPECT_EQ(driver_->counters().wrong_length, 2u);
  EXPECT_EQ(manager_->counters().unknown_pdo, 1u);
  EXPECT_EQ(manager_->counters().unknown_emcy, 1u);
  EXPECT_EQ(logged,
            (std::vector<std::string>{"grip: PDO of the wrong length ignored (counted from now on)",
                                      "PDO 1A5h from a node not in the configuration ignored (counted from now on)",
                                      "EMCY from node 37, not in the configuration, ignored"}));
  // An EMCY from the configured node reaches its driver.
  dev.node->emcy().raise(0x1000, 0, net_.now());
  net_.run_for(10ms);
  ASSERT_EQ(driver_->emcys.size(), 1u);
  EXPECT_EQ(driver_->value(0).status, SignalStatus::Error);
}

}  // namespace

namespace {

TEST_F(NetworkManagerTest, CommissionsADeviceFoundAtItsDefaultNodeIdByLss) {
  const auto store = std::filesystem::temp_directory_path() / ("oegw-nm-lss-" + std::to_string(::getpid()));
  Device dev(net_, 0x15A, store);  // at 11h, the elobau default
  (void)dev.node->start(net_.now());
  net_.settle();
  std::optional<std::pair<bool, std::string>> result;
  manager_->commission(lss::Address{.vendor = 0x15A, .product = 1, .revision = 1, .serial = 7}, NodeId{0x12}, 2,
                       net_.now(), [&](bool ok, const std::string& why) { result.emplace(ok, why); });
  net_.run_for(1s);
  ASSERT_TRUE(result.has_value());
  EXPECT_TRUE(result->first) << result->second;
  EXPECT_EQ(dev.node->lss().pending_node_id(), NodeId{0x12});
  net_.bus().clear_log();
  master_->nmt().reset_communication(kNode);
  net_.run_for(10ms);
  ASSERT_FALSE(frames().empty());
  EXPECT_EQ(frames()[1], "device 712#00") << "boots with the new node-ID";

  // A node-ID out of range is refused by the device, and said so.
  result.reset();
  manager_->commission(std::nullopt, NodeId{0x80}, std::nullopt, net_.now(),
                       [&](bool ok, const std::string& why) { result.emplace(ok, why); });
  net_.run_for(1s);
  ASSERT_TRUE(result.has_value());
  EXPECT_FALSE(result->first);
  EXPECT_EQ(result->second, "LSS configure node-ID: refused with error 1");
  std::filesystem::remove(store.string() + ".lss");
}

}  // namespace

namespace {

// The gateway's side of a downstream bus for a test of its own: the master and its network
// manager on a virtual network, as NetworkManagerTest has them.
struct Downstream {
  Downstream() { net.attach("gateway", manager); }
  oegw::testing::VirtualNetwork net;
  ObjectDictionary master_od;
  Master master{master_od, net.sink("gateway"), MasterConfig{.heartbeat_entries = 8, .sdo_timeout = 100ms}};
  NetworkManager manager{master};
};

// A node without heartbeat (heartbeat_ms 0, pdo_timeout_ms set, as the mapping file requires):
// after the NMT start its first PDO is the proof of life; once its PDOs stop (here: another
// master stops it, which no heartbeat would tell), the input is Stale past pdo_timeout_ms.
TEST(NetworkManagerProofOfLife, WithoutHeartbeatTheFirstPdoIsTheProofAndOverduePdosMakeTheInputStale) {
  Downstream d;
  auto& net = d.net;
  auto& master = d.master;
  auto& manager = d.manager;
  std::vector<std::string> reasons;
  std::vector<NodeState> states;
  manager.on_node_state = [&](const std::string&, NodeState s, const std::string& why) {
    states.push_back(s);
    reasons.push_back(why);
  };
  auto drv = std::make_unique<ByteDriver>(kNode, net.sink("gateway"));
  ByteDriver* driver = drv.get();
  NodeSettings settings{.name = "grip",
                        .node = kNode,
                        .heartbeat_ms = 0,
                        .heartbeat_timeout_ms = 0,
                        .pdo_timeout_ms = 200,
                        .mandatory = false,
                        .identity = {},
                        .sdo = {}};
  ASSERT_TRUE(manager.add(settings, std::move(drv)));
  Device dev(net);
  (void)dev.node->start(net.now());
  net.settle();
  manager.start(net.now());
  net.run_for(20ms);
  // Started, then the PDO the node sends on entering operational proves it alive.
  ASSERT_GE(states.size(), 2u);
  EXPECT_EQ(states[states.size() - 2], NodeState::Starting);
  EXPECT_EQ(reasons[reasons.size() - 2], "configured, NMT start sent: waiting 200 ms for a first PDO");
  ASSERT_EQ(manager.state("grip"), NodeState::Operational);
  EXPECT_EQ(reasons.back(), "first PDO after NMT start");
  (void)dev.od.set<std::uint8_t>(0x6000, 1, 0x42);
  net.run_for(10ms);
  EXPECT_EQ(driver->value(0).status, SignalStatus::Valid);
  EXPECT_EQ(driver->value(0).value, 0x42);
  EXPECT_EQ(driver->freshness(0), 200ms);
  // The event timer (50 ms, the driver's boot write) keeps the value fresh...
  net.run_for(500ms);
  EXPECT_EQ(driver->value(0).status, SignalStatus::Valid);
  master.nmt().stop(kNode);  // ...until the node stops sending
  net.run_for(150ms);
  EXPECT_EQ(driver->value(0).status, SignalStatus::Valid) << "within pdo_timeout_ms";
  net.run_for(100ms);
  EXPECT_EQ(driver->value(0).status, SignalStatus::Offline) << "every PDO overdue: the node is lost";
  EXPECT_EQ(manager.state("grip"), NodeState::Missing);
  EXPECT_EQ(reasons.back(), "no PDO within its deadline (no heartbeat watched)");
}

// CiA 301 §7.2.2: a PDO has one producer. A second node whose TPDO is on the first one's COB-ID
// (configured so elsewhere, read back at boot) is refused: its frames and the first one's could
// not be told apart. The first stays operational, and its inputs keep coming from its frames.
TEST(NetworkManagerCobIds, ASecondNodeOnAnotherNodesPdoCobIdIsRefused) {
  Downstream d;
  auto& net = d.net;
  auto& manager = d.manager;
  std::map<std::string, std::string> why;
  manager.on_node_state = [&](const std::string& name, NodeState, const std::string& w) { why[name] = w; };
  constexpr NodeId kCopy{0x12};
  auto grip = std::make_unique<ByteDriver>(kNode, net.sink("gateway"));
  ByteDriver* grip_driver = grip.get();
  auto copy = std::make_unique<ByteDriver>(kCopy, net.sink("gateway"), cob::kTpdo1 + kNode.value());
  NodeSettings settings{.name = "grip", .node = kNode, .heartbeat_ms = 100};
  ASSERT_TRUE(manager.add(settings, std::move(grip)));
  settings.name = "copy";
  settings.node = kCopy;
  ASSERT_TRUE(manager.add(settings, std::move(copy)));
  Device first(net);
  Device second(net, 0x15A, {}, kCopy);
  (void)first.node->start(net.now());
  (void)second.node->start(net.now());
  net.settle();
  manager.start(net.now());
  net.run_for(500ms);
  EXPECT_EQ(manager.state("grip"), NodeState::Operational) << why["grip"];
  EXPECT_EQ(manager.state("copy"), NodeState::Refused) << why["copy"];
  EXPECT_EQ(why["copy"], "its PDO COB-ID 191h is also grip's: the frames on it cannot be told apart");
  (void)first.od.set<std::uint8_t>(0x6000, 1, 0x42);
  net.run_for(20ms);
  EXPECT_EQ(grip_driver->value(0).status, SignalStatus::Valid);
  EXPECT_EQ(grip_driver->value(0).value, 0x42);
}

// Without pdo_timeout_ms a TPDO's deadline is 3 x the event timer actually written at boot: the
// driver's default, replaced by the mapping file's `sdo` write of 18xxh:05 when there is one.
TEST(DriverFreshness, TheDeadlineFollowsTheEventTimerWrittenAtBoot) {
  struct Carried final : Driver {
    Carried() {
      signals_ = {SignalInfo{"a", SignalKind::Analog, -100, 100, 0, "raw16"},
                  SignalInfo{"b", SignalKind::Button, 0, 1, 0, "bits"}};
      init(NodeId{5}, {}, signals_.size());
      set_carriers({Carrier{.cob_id = 0x185,
                            .comm_index = 0x1800,
                            .event_timer_ms = 20,
                            .transmission_type = 0xFE,
                            .signals = {0}},
                    Carrier{.cob_id = 0x285,
                            .comm_index = 0x1801,
                            .event_timer_ms = 0,
                            .transmission_type = 0xFE,
                            .signals = {1}}});
    }
    std::string_view family() const override { return "test"; }
    const std::vector<SignalInfo>& signals() const override { return signals_; }
    bool on_frame(const CanFrame&, TimePoint) override { return false; }
    DecodedEmcy on_emcy(const EmcyMessage&, TimePoint) override { return {}; }
    std::vector<std::uint32_t> consumed_cob_ids() const override { return {}; }
    bool set_output(std::size_t, std::int64_t, TimePoint) override { return false; }
    void feed(std::size_t i, std::int64_t v, TimePoint t) { update(i, v, SignalStatus::Valid, t); }
    std::vector<SignalInfo> signals_;
  } d;
  EXPECT_EQ(d.freshness(0), 60ms);
  EXPECT_EQ(d.freshness(1), 0ms) << "sent on change only: no deadline";
  d.apply_boot_writes({SdoWrite{0x1800, 5, encode<std::uint16_t>(20), "driver"},
                       SdoWrite{0x1800, 5, encode<std::uint16_t>(500), "file"}});
  EXPECT_EQ(d.freshness(0), 1500ms) << "the last write wins";
  d.apply_boot_writes({SdoWrite{0x1800, 2, {0x01}, "every SYNC"}});
  EXPECT_EQ(d.freshness(0), 0ms) << "a synchronous PDO has no event-timer deadline";
  d.set_pdo_timeout(250ms);
  EXPECT_EQ(d.freshness(0), 250ms);
  EXPECT_EQ(d.freshness(1), 250ms) << "pdo_timeout_ms covers PDOs sent on change too";
  const TimePoint t0{std::chrono::seconds(1)};
  d.pdo_received(0x185, t0);  // only the carrier PDO itself refreshes (the network manager calls this)
  d.feed(0, 7, t0);
  d.pdo_received(0x285, t0 + 100ms);
  d.feed(1, 1, t0 + 100ms);
  EXPECT_EQ(d.next_deadline(), t0 + 250ms);
  d.advance(t0 + 249ms);
  EXPECT_EQ(d.value(0).status, SignalStatus::Valid);
  d.advance(t0 + 250ms);
  EXPECT_EQ(d.value(0).status, SignalStatus::Stale);
  EXPECT_EQ(d.value(0).value, 7) << "the last value, no longer vouched for";
  EXPECT_EQ(d.value(1).status, SignalStatus::Valid);
  EXPECT_EQ(d.next_deadline(), t0 + 350ms);
  d.feed(0, 8, t0 + 300ms);  // republished without its PDO: no evidence
  EXPECT_EQ(d.value(0).status, SignalStatus::Stale);
  d.pdo_received(0x185, t0 + 400ms);  // a late PDO, then its value
  d.feed(0, 8, t0 + 400ms);
  EXPECT_EQ(d.value(0).status, SignalStatus::Valid);
}

// ---- run-time state (NetworkManager::export_state, Master::export_state) -------------------

// A cab of one device and the gateway's downstream side, whose every act is logged with its
// time: node states with their reasons, the input's changes, and the frames on the bus.
struct Rig {
  oegw::testing::VirtualNetwork net;
  ObjectDictionary master_od;
  Master master{master_od, net.sink("gateway"), MasterConfig{.heartbeat_entries = 8, .sdo_timeout = 100ms}};
  NetworkManager manager{master};
  ByteDriver* driver = nullptr;
  std::unique_ptr<Device> dev;
  bool dev_attached = true;  // a detached device runs no timers: its state stands still
  std::vector<std::string> log;

  // `event_timer_ms`: the TPDO's, written by the mapping file's `sdo` list (0: on change only).
  explicit Rig(std::uint16_t event_timer_ms = 50) {
    net.attach("gateway", manager);
    auto drv = std::make_unique<ByteDriver>(kNode, net.sink("gateway"));
    driver = drv.get();
    driver->on_change = [this](std::size_t, const SignalValue& v) {
      add("in " + std::to_string(v.value) + " " + std::string(to_string(v.status)));
    };
    manager.on_node_state = [this](const std::string& name, NodeState s, const std::string& why) {
      add(name + " " + std::string(to_string(s)) + ": " + why);
    };
    manager.on_application_reset = [this](const std::string& name) { add(name + ": application reset"); };
    NodeSettings settings{.name = "grip", .node = kNode, .heartbeat_ms = 100, .mandatory = true};
    settings.sdo.push_back(SdoWrite{0x1800, 5, encode<std::uint16_t>(event_timer_ms), "TPDO1 event timer"});
    EXPECT_TRUE(manager.add(settings, std::move(drv)));
    dev = std::make_unique<Device>(net);
    net.bus().set_logging(true);
  }
  void add(const std::string& what) {
    log.push_back(std::to_string(net.now().time_since_epoch() / 1ms) + " ms: " + what);
  }
  // Until the manager holds no request on the wire (a snapshot's point, as the recorder waits).
  void until_quiet() {
    for (int i = 0; i < 1000 && !manager.busy().empty(); ++i) net.run_for(1ms);
    ASSERT_EQ(manager.busy(), "");
  }
  void pull_cable() {
    net.detach("device");
    dev_attached = false;
  }
  void plug_in() {
    net.attach("device", *dev->node);
    dev_attached = true;
  }
  void clear() {
    log.clear();
    net.bus().clear_log();
  }
  [[nodiscard]] std::vector<std::string> frames() {
    std::vector<std::string> out;
    for (const auto& r : net.bus().log())
      out.push_back(std::to_string(r.time.time_since_epoch() / 1ms) + " ms: " + r.to_string());
    return out;
  }
};

template <class T>
std::string state_of(const T& part) {
  StateWriter w;
  part.export_state(w);
  return w.text();
}

// Rig B takes over from rig A at A's time: device, master and manager each from A's state.
void take_over(Rig& a, Rig& b) {
  b.net.run_for(a.net.now() - b.net.now());
  const std::string device = state_of(*a.dev->node);
  const std::string master = state_of(a.master);
  const std::string manager = state_of(a.manager);
  const StateReader rd = StateReader::parse(device);
  const StateReader rm = StateReader::parse(master);
  const StateReader rn = StateReader::parse(manager);
  if (!a.dev_attached) b.pull_cable();
  b.dev->node->import_state(rd);
  b.master.import_state(rm);
  b.manager.import_state(rn);
  EXPECT_THAT(rd.unread(), ::testing::IsEmpty()) << device;
  EXPECT_EQ(state_of(*b.dev->node), device) << "a round trip changes the state";
  EXPECT_THAT(rm.unread(), ::testing::IsEmpty()) << master;
  EXPECT_THAT(rn.unread(), ::testing::IsEmpty()) << manager;
  EXPECT_EQ(state_of(b.master), master) << "a round trip changes the state";
  EXPECT_EQ(state_of(b.manager), manager) << "a round trip changes the state";
  b.net.settle();
  a.clear();
  b.clear();
}

// Twin test of the downstream side: B, given A's state at a quiet moment, then living through the
// same incident, does and reports exactly what A does, at the same times; the same cab started
// afresh at that moment does not.
void expect_twins(const std::function<void(Rig&)>& before, const std::function<void(Rig&)>& incident,
                  std::uint16_t event_timer_ms = 50) {
  Rig a(event_timer_ms);
  before(a);
  a.until_quiet();
  Rig b(event_timer_ms);
  take_over(a, b);
  EXPECT_EQ(b.driver->value(0), a.driver->value(0)) << "the input as it stood";
  Rig fresh(event_timer_ms);
  fresh.net.run_for(a.net.now() - fresh.net.now());
  (void)fresh.dev->node->start(fresh.net.now());
  fresh.manager.start(fresh.net.now());
  fresh.net.settle();
  fresh.clear();
  for (Rig* r : {&a, &b, &fresh}) incident(*r);
  EXPECT_EQ(b.log, a.log);
  EXPECT_EQ(b.frames(), a.frames());
  EXPECT_NE(fresh.log, a.log);
  EXPECT_EQ(b.manager.node_counters("grip").frames, a.manager.node_counters("grip").frames);
  EXPECT_EQ(b.manager.counters().gateway_resets, a.manager.counters().gateway_resets);
}

// Booted up to the NMT start: the gateway waits for the proof of life.
void start_until_started(Rig& r) {
  (void)r.dev->node->start(r.net.now());
  r.net.settle();
  r.manager.start(r.net.now());
  for (int i = 0; i < 100 && r.manager.state("grip") != NodeState::Starting; ++i) r.net.run_for(1ms);
  ASSERT_EQ(r.manager.state("grip"), NodeState::Starting);
}

void boot(Rig& r) {
  (void)r.dev->node->start(r.net.now());
  r.net.settle();
  r.manager.start(r.net.now());
  r.net.run_for(300ms);
  ASSERT_EQ(r.manager.state("grip"), NodeState::Operational);
}

// The device reboots on its own (a reboot seen: the gateway had started it), then its cable is
// pulled and plugged back: the heartbeat is lost at the same time, the retries back off as the
// original's, the node is found and booted again.
void reboot_and_cable_pull(Rig& r) {
  (void)r.dev->od.set<std::uint8_t>(0x6000, 1, 9);
  r.net.run_for(30ms);
  r.dev->node->nmt().reset(false, r.net.now());
  r.net.run_for(500ms);
  r.add("reboots seen " + std::to_string(r.manager.counters().reboots_seen));
  r.pull_cable();
  r.net.run_for(2500ms);
  r.plug_in();
  r.net.run_for(3s);
}

TEST(NetworkManagerState, AnOperationalNodeGoesOnAsTheOriginal) {
  expect_twins(
      [](Rig& r) {
        boot(r);
        (void)r.dev->od.set<std::uint8_t>(0x6000, 1, 7);
        // The gateway holds an error the device reported: its next boot resets the application.
        r.manager.reset_application_next("grip");
        r.net.run_for(125ms);  // between two heartbeats and two event-timer PDOs
      },
      reboot_and_cable_pull);
}

// The cable pulled just before the state was taken: the heartbeat is lost at the time the
// original's consumer (CiA 301 §7.2.8.3.2.2: the consumer time from the last heartbeat) says,
// though no heartbeat reaches the copy to start its own.
TEST(NetworkManagerState, AnOverdueHeartbeatIsLostAtTheOriginalsTime) {
  expect_twins(
      [](Rig& r) {
        boot(r);
        r.pull_cable();
        r.net.run_for(60ms);
        ASSERT_EQ(r.manager.state("grip"), NodeState::Operational);
      },
      [](Rig& r) {
        r.net.run_for(2s);
        r.plug_in();
        r.net.run_for(3s);
      });
}

TEST(NetworkManagerState, AMissingNodeIsRetriedAsTheOriginalWouldHave) {
  expect_twins(
      [](Rig& r) {
        boot(r);
        r.pull_cable();
        r.net.run_for(1700ms);  // lost, then one retry's boot-up wait with its probes
      },
      [](Rig& r) {
        r.net.run_for(4s);  // absent longer: the probes' gaps and the back-off double on
        r.plug_in();
        r.net.run_for(5s);
      });
}

// Started, its PDO came before its first heartbeat in operational: held, and passed on with its
// own time when the proof of life comes (a TPDO sent on change only: none follows it).
TEST(NetworkManagerState, PdosHeldForTheProofOfLifeCarryOver) {
  expect_twins(
      [](Rig& r) {
        start_until_started(r);
        (void)r.dev->od.set<std::uint8_t>(0x6000, 1, 5);
        r.net.run_for(1ms);
        ASSERT_EQ(r.manager.state("grip"), NodeState::Starting);
        EXPECT_NE(state_of(r.manager).find("nodes.0.held.count 1\n"), std::string::npos) << "its PDO is held";
      },
      [](Rig& r) { r.net.run_for(1s); }, 0);
}

TEST(NetworkManagerState, ANodeWaitingForItsProofOfLifeIsJudgedAsTheOriginal) {
  expect_twins(
      [](Rig& r) {
        start_until_started(r);
        r.pull_cable();  // its heartbeat in operational never comes
      },
      [](Rig& r) { r.net.run_for(3s); });
}

// A state is taken only when no request is on the wire: its callback is no state.
TEST(NetworkManagerState, ABootUnderWayIsNoState) {
  Rig a;
  std::vector<std::string> seen;
  a.manager.on_node_state = [&](const std::string&, NodeState s, const std::string&) {
    if (s != NodeState::Configuring) return;
    seen.push_back(a.manager.busy());
    StateWriter w;
    EXPECT_THROW(a.manager.export_state(w), std::logic_error);
  };
  boot(a);
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.front(), "grip: configuring (an SDO request on the wire or held)");
  EXPECT_EQ(a.manager.busy(), "");
}

TEST(NetworkManagerState, AStateOfAnotherConfigurationIsRefused) {
  Rig a;
  boot(a);
  const std::string manager = state_of(a.manager);
  oegw::testing::VirtualNetwork net;
  ObjectDictionary od;
  Master master{od, net.sink("gateway"), MasterConfig{.heartbeat_entries = 8}};
  NetworkManager other{master};
  ASSERT_TRUE(other.add(NodeSettings{.name = "grip", .node = NodeId{0x12}, .heartbeat_ms = 100},
                        std::make_unique<ByteDriver>(NodeId{0x12}, net.sink("gateway"))));
  try {
    other.import_state(StateReader::parse(manager));
    ADD_FAILURE() << "accepted";
  } catch (const StateError& e) {
    EXPECT_STREQ(e.what(), "state: 'nodes.0.node' differs: the state is of another configuration");
  }
  // A master producing SYNC cannot take the state of one that does not.
  ObjectDictionary od2;
  Master with_sync{od2, net.sink("gateway"), MasterConfig{.heartbeat_entries = 8, .sync_period = 10ms}};
  EXPECT_EQ(test_support::refusal(with_sync, state_of(a.master)),
            "state: 'produces_sync' differs: this master produces SYNC");
  // A missing node with no retry time would never be retried.
  a.pull_cable();
  a.net.run_for(300ms);
  ASSERT_EQ(a.manager.state("grip"), NodeState::Missing);
  Rig b;
  EXPECT_EQ(test_support::refusal(b.manager, test_support::with_value(state_of(a.manager), "nodes.0.deadline", {})),
            "state: 'nodes.0.deadline' is missing: a missing node waits for it");
}

}  // namespace
