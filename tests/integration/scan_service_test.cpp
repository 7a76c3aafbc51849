// `oegw scan` through the running gateway (gateway/control/scan_service.hpp):
// the control protocol's `scan` command on a Gateway with the demo cab's simulators, one more
// simulator at a node-ID the mapping file does not configure, and (in one test) the button
// cluster's node-ID taken away by LSS frames sent by hand. Judged on the downstream bus and on
// the simulators' dictionaries (written from the manufacturers' documents): the gateway's own
// sub-devices are never probed and stay operational, the other node is found, LSS runs on the
// network manager's master, and the draft names the sub-devices as the mapping file does.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "gateway/control/control_protocol.hpp"
#include "gateway/control/scan_service.hpp"
#include "gateway/gateway.hpp"
#include "gateway/programs.hpp"
#include "mapping/draft.hpp"
#include "rig/cab_rig.hpp"
#include "subdevices/device_spec.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "tests/fixtures/fixtures.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
namespace gw = oegw::gateway;
namespace sd = oegw::subdevices;
using nlohmann::json;

namespace {

constexpr std::uint8_t kSpare = 0x40;  // a Novotechnik encoder the mapping file does not name
// The sub-devices of demo_cab.yaml: their SDO request COB-IDs (600h + node-ID).
const std::set<std::uint32_t> kSubdeviceRequests = {0x611, 0x603, 0x630, 0x67F, 0x631};

class ScanThroughGateway : public ::testing::Test {
 protected:
  void SetUp() override {
    auto loaded = oegw::mapping::load_config_text(oegw::fixtures::mapping_file("demo_cab.yaml"), "scan.yaml",
                                                  gw::driver_catalogue());
    ASSERT_TRUE(loaded.ok()) << loaded.error_text();
    config_ = std::move(*loaded.config);
    std::filesystem::create_directories(dir_);
    rig_ = std::make_unique<oegw::rig::CabRig>(config_, loop_, oegw::rig::CabRigOptions{.store = dir_ / "gw.store"});
    rig_->down().set_tap([this](const BusRecord& r) { down_.push_back(r.frame); });
    rig_->on_gateway = [this](gw::Gateway& g) { g.on_log = [this](const std::string& l) { log_ += l + "\n"; }; };
    rig_->build();
    std::string error;
    const auto spec = sd::parse_device_spec(fmt::format("novotechnik-406:{:#x}:name=spare", kSpare), error);
    ASSERT_TRUE(spec) << error;
    ASSERT_TRUE(rig_->devices().add(*spec, error)) << error;
    rig_->power_on();
    rig_->run_for(3s);
    all_operational();
    service_ =
        std::make_unique<gw::control::ScanService>(loop_, rig_->gw(), config_, protocol_, [this] { rig_->rearm(); });
  }
  void TearDown() override {
    service_.reset();
    rig_.reset();
    std::filesystem::remove_all(dir_);
  }

  void all_operational() {
    for (const auto& n : rig_->gw().downstream().names())
      ASSERT_EQ(rig_->gw().downstream().state(n), sd::NodeState::Operational) << n << "\n" << log_;
  }
  json ask(const json& request) {
    std::optional<std::string> answer;
    protocol_.answer(gw::control::json_line(request), [&answer](std::string a) { answer = std::move(a); });
    EXPECT_TRUE(answer);
    return json::parse(answer.value_or("{}"));
  }
  // Starts a scan and runs the loop until its status says done; the status's "scan" object.
  json scan(json settings = json::object()) {
    settings["command"] = "scan";
    settings["action"] = "start";
    const json started = ask(settings);
    EXPECT_TRUE(started.value("ok", false)) << started.dump();
    const auto id = started["scan"]["id"].get<std::uint64_t>();
    json s;
    for (int i = 0; i < 600; ++i) {
      rig_->run_for(50ms);
      s = ask(json{{"command", "scan"}, {"action", "status"}, {"id", id}});
      if (!s["scan"].value("running", true)) break;
    }
    EXPECT_FALSE(s["scan"].value("running", true)) << s.dump();
    return s["scan"];
  }
  sd::ScanResult result_of(const json& status) {
    std::string why;
    auto r = gw::control::scan_result_from_json(status.at("result"), why);
    EXPECT_TRUE(r) << why;
    return r.value_or(sd::ScanResult{});
  }
  static const sd::ScannedNode* find(const sd::ScanResult& r, std::uint8_t id) {
    for (const auto& n : r.nodes)
      if (n.node.value() == id) return &n;
    return nullptr;
  }
  std::uint32_t sim_u32(const char* device, std::uint16_t index, std::uint8_t sub) {
    return rig_->devices().device(device)->od().get<std::uint32_t>(index, sub);
  }

  SimulatedClock clock_;
  EventLoop loop_{clock_};
  oegw::mapping::Config config_;
  const std::filesystem::path dir_ =
      std::filesystem::path(::testing::TempDir()) / fmt::format("oegw-scan-service-{}", ::getpid());
  std::unique_ptr<oegw::rig::CabRig> rig_;
  gw::control::ControlProtocol protocol_;
  std::unique_ptr<gw::control::ScanService> service_;
  std::vector<CanFrame> down_;
  std::string log_;
};

TEST_F(ScanThroughGateway, ProbesOnlyOtherNodeIdsAndReportsItsSubdevicesByName) {
  const std::size_t mark = down_.size();
  const auto before = rig_->gw().downstream().counters();
  const json status = scan();
  // Not one SDO request to a sub-device: their channels are the gateway's own clients'.
  std::size_t to_spare = 0, lss = 0;
  for (std::size_t i = mark; i < down_.size(); ++i) {
    EXPECT_FALSE(kSubdeviceRequests.count(down_[i].id)) << fmt::format("{:03X}h during the scan", down_[i].id);
    to_spare += down_[i].id == 0x600u + kSpare ? 1 : 0;
    lss += down_[i].id == 0x7E5 ? 1 : 0;
  }
  EXPECT_EQ(to_spare, 6u);  // 1000h, 1018h:01..04, 1017h
  EXPECT_GE(lss, 1u);       // identify non-configured, on the network manager's master
  all_operational();
  EXPECT_EQ(rig_->gw().downstream().counters().reboots_seen, before.reboots_seen);
  EXPECT_EQ(rig_->gw().downstream().counters().gateway_resets, before.gateway_resets);

  const sd::ScanResult r = result_of(status);
  EXPECT_EQ(r.nodes.size(), 6u);
  EXPECT_FALSE(r.unconfigured);
  const auto* spare = find(r, kSpare);
  ASSERT_NE(spare, nullptr);
  EXPECT_EQ(spare->family.family, "novotechnik-406");
  EXPECT_TRUE(spare->configured_as.empty());
  EXPECT_EQ(spare->identity.vendor_id, sim_u32("spare", 0x1018, 1));
  const auto* grip = find(r, 0x11);
  ASSERT_NE(grip, nullptr);
  EXPECT_EQ(grip->configured_as, "right_grip");
  EXPECT_EQ(grip->gateway_state, "operational");
  EXPECT_EQ(grip->family.family, "elobau-mfg");
  // What the gateway read at the grip's boot, the simulator's own values.
  EXPECT_EQ(grip->identity.device_type, sim_u32("right_grip", 0x1000, 0));
  EXPECT_EQ(grip->identity.vendor_id, sim_u32("right_grip", 0x1018, 1));
  EXPECT_EQ(grip->identity.product_code, sim_u32("right_grip", 0x1018, 2));
  EXPECT_TRUE(grip->heard);  // its heartbeats, during the scan
  EXPECT_EQ(status["downstream"]["interface"], config_.downstream.interface);

  // The draft keeps the mapping file's names and, its placeholders filled (no draft passes
  // `oegw check` on a guess: the MCB-402's button_bits is TODO), passes `oegw check`.
  const std::string draft = oegw::mapping::draft_mapping(r, {.downstream = "can1",
                                                             .upstream = "can0",
                                                             .bitrate = 250000,
                                                             .store = (dir_ / "draft.store").string(),
                                                             .through_gateway = true});
  for (const char* entry : {"\n  right_grip:\n", "\n  left_grip:\n", "\n  novotechnik_406_40:\n"})
    EXPECT_NE(draft.find(entry), std::string::npos) << entry << "\n" << draft;
  EXPECT_NE(draft.find("through the gateway running on"), std::string::npos);
  const auto file = dir_ / "draft.yaml";
  std::ofstream(file) << draft;
  EXPECT_EQ(gw::run_check(file.string()), 1) << draft;
  std::string filled = draft;
  const std::string placeholder = "button_bits: TODO";
  ASSERT_NE(filled.find(placeholder), std::string::npos) << draft;
  filled.replace(filled.find(placeholder), placeholder.size(), "button_bits: [1, 2, 3, 4, 5, 7, 6]");
  std::ofstream(file) << filled;
  EXPECT_EQ(gw::run_check(file.string()), 0) << filled;
}

TEST_F(ScanThroughGateway, FindsANodeWithoutNodeIdByTheGatewaysLssMaster) {
  // The cluster (button_cluster.eds 1018h: vendor A5Ah, product 402h, revision 00010002h,
  // serial 0) loses its node-ID: switch state selective, configure node-ID FFh, waiting, NMT
  // reset communication (CiA 305 §8.4.2, §8.4.3.2; frames as tests/vm/guest/scan.sh sends them).
  auto tool = rig_->down().attach("tool");
  for (const CanFrame& f :
       {CanFrame(0x7E5, {0x40, 0x5A, 0x0A, 0, 0, 0, 0, 0}), CanFrame(0x7E5, {0x41, 0x02, 0x04, 0, 0, 0, 0, 0}),
        CanFrame(0x7E5, {0x42, 0x02, 0x00, 0x01, 0, 0, 0, 0}), CanFrame(0x7E5, {0x43, 0, 0, 0, 0, 0, 0, 0}),
        CanFrame(0x7E5, {0x11, 0xFF, 0, 0, 0, 0, 0, 0}), CanFrame(0x7E5, {0x04, 0, 0, 0, 0, 0, 0, 0}),
        CanFrame(0x000, {0x82, 0x31})}) {
    (void)tool->send(f);
    rig_->run_for(2ms);
  }
  rig_->run_for(500ms);
  ASSERT_NE(rig_->gw().downstream().state("cluster"), sd::NodeState::Operational);

  const std::size_t lss_mark = down_.size();
  const json status = scan();
  std::string lss_frames;
  for (std::size_t i = lss_mark; i < down_.size(); ++i)
    if (down_[i].id == 0x7E5 || down_[i].id == 0x7E4)
      lss_frames += fmt::format("{:03X}#{:02X}{:02X} ", down_[i].id, down_[i].data[0], down_[i].data[5]);
  SCOPED_TRACE(lss_frames);
  ASSERT_TRUE(status.contains("result")) << status.dump();
  const sd::ScanResult r = result_of(status);
  EXPECT_TRUE(r.unconfigured);
  ASSERT_TRUE(r.unconfigured_address) << r.lss_note;
  EXPECT_EQ(*r.unconfigured_address, (lss::Address{0xA5A, 0x402, 0x00010002, 0}));
  const auto* cluster = find(r, 0x31);
  ASSERT_NE(cluster, nullptr);
  EXPECT_EQ(cluster->configured_as, "cluster");
  EXPECT_NE(cluster->gateway_state, "operational");
  // The scan left it without node-ID, in LSS waiting: identify non-configured is answered again.
  const std::size_t mark = down_.size();
  (void)tool->send(CanFrame(0x7E5, {0x4C, 0, 0, 0, 0, 0, 0, 0}));
  rig_->run_for(20ms);
  bool answered = false;
  for (std::size_t i = mark; i < down_.size(); ++i) answered |= down_[i].id == 0x7E4 && down_[i].data[0] == 0x50;
  EXPECT_TRUE(answered);
}

TEST_F(ScanThroughGateway, OneScanAtATimeAndTheStatusOfItsOwnId) {
  const json d = ask(json{{"command", "scan"}, {"action", "start"}, {"parallel", 0}});
  EXPECT_FALSE(d.value("ok", true)) << d.dump();  // refused, naming the field, starting nothing
  EXPECT_NE(d.dump().find("parallel"), std::string::npos) << d.dump();
  const json a = ask(json{{"command", "scan"}, {"action", "start"}});
  ASSERT_TRUE(a.value("ok", false)) << a.dump();
  EXPECT_EQ(a["scan"]["id"], 1) << a.dump();
  const json b = ask(json{{"command", "scan"}, {"action", "start"}});
  EXPECT_EQ(b.value("gateway_error", 0), 102) << b.dump();
  const json c = ask(json{{"command", "scan"}, {"action", "status"}, {"id", 7}});
  EXPECT_EQ(c.value("gateway_error", 0), 102) << c.dump();
  const json e = ask(json{{"command", "scan"}, {"action", "stop"}});
  EXPECT_FALSE(e.value("ok", true)) << e.dump();
}

TEST(ScanResultJson, RoundTripsAndNamesWhatIsMissing) {
  sd::ScanResult r;
  sd::ScannedNode n;
  n.node = NodeId{0x11};
  n.answered_sdo = n.heard = true;
  n.state = NmtState::Operational;
  n.identity = {0x00050191, 0xB4, 0x1, 0x00010003, std::nullopt};
  n.producer_heartbeat_ms = 100;
  n.heartbeat_period = 99ms;
  n.family = {"elobau-mfg", "vendor 000000B4h (elobau)"};
  n.configured_as = "right_grip";
  n.gateway_state = "operational";
  r.nodes.push_back(n);
  r.unconfigured = true;
  r.unconfigured_address = lss::Address{1, 2, 3, 4};
  std::string why;
  const auto back = gw::control::scan_result_from_json(gw::control::scan_result_json(r), why);
  ASSERT_TRUE(back) << why;
  ASSERT_EQ(back->nodes.size(), 1u);
  const auto& m = back->nodes[0];
  EXPECT_EQ(m.node.value(), 0x11);
  EXPECT_EQ(m.state, NmtState::Operational);
  EXPECT_EQ(m.identity.device_type, 0x00050191u);
  EXPECT_EQ(m.identity.serial, std::nullopt);
  EXPECT_EQ(m.heartbeat_period, std::optional<Duration>(99ms));
  EXPECT_EQ(m.configured_as, "right_grip");
  EXPECT_EQ(back->unconfigured_address, r.unconfigured_address);
  json broken = gw::control::scan_result_json(r);
  broken["nodes"][0].erase("family");
  EXPECT_FALSE(gw::control::scan_result_from_json(broken, why));
  EXPECT_NE(why.find("family"), std::string::npos) << why;
}

}  // namespace
