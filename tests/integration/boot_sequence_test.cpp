// The boot sequence of the downstream network manager against the family simulators, as the
// manufacturers' documents describe the devices: configuration in pre-operational (a
// Novotechnik sensor that starts itself, 1F80h bit 3, refuses remapping while operational,
// §8.2), SYNC produced for synchronous TPDOs (CiA 301 §7.5.2.35) and the freshness deadline
// they follow, the identity revision compared by its major part (CiA 301 §7.5.2.13), and the
// boot diagnostics 1018h/1008h/1009h/100Ah/1001h.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "canopen/master.hpp"
#include "subdevices/network_manager.hpp"
#include "subdevices/sim/cia401_sim.hpp"
#include "subdevices/sim/elobau_mfg_sim.hpp"
#include "subdevices/sim/mcb402_sim.hpp"
#include "subdevices/sim/novotechnik_406_sim.hpp"
#include "virtual_network.hpp"

using namespace oegw::canopen;
using namespace oegw::subdevices;
using namespace std::chrono_literals;

namespace {

constexpr std::uint32_t kSave = 0x65766173;  // "save"

std::filesystem::path temp_store(const std::string& name) {
  auto p = std::filesystem::temp_directory_path() / ("oegw_boot_" + std::to_string(::getpid()) + "_" + name);
  std::filesystem::remove(p);
  std::filesystem::remove(std::filesystem::path(p.string() + ".lss"));
  return p;
}

// One simulator, the gateway's master (optionally producing SYNC) and its network manager.
class Boot : public ::testing::Test {
 protected:
  void make_gateway(Duration sync_period = Duration{0}) {
    master_ = std::make_unique<Master>(od_, net_.sink("gateway"),
                                       MasterConfig{.heartbeat_entries = 8,
                                                    .sdo_timeout = 200ms,
                                                    .sync_period = sync_period});
    network_ = std::make_unique<NetworkManager>(*master_);
    net_.attach("gateway", *network_);
    network_->on_node_state = [this](const std::string& n, NodeState s, const std::string& why) {
      log_ += n + ": " + std::string(to_string(s)) + " (" + why + ")\n";
    };
    network_->on_diagnostics = [this](const std::string& n, const NodeDiagnostics& d) {
      diag_lines_.push_back(n + ": " + d.describe());
    };
  }
  void add(const std::string& family, NodeId node, NodeSettings s, DriverOptions options = {}) {
    std::string error;
    auto driver = make_driver(family, node, net_.sink("gateway"), options, error);
    ASSERT_TRUE(driver) << error;
    s.node = node;
    ASSERT_TRUE(network_->add(std::move(s), std::move(driver)));
  }
  std::vector<std::string> frames() {
    std::vector<std::string> out;
    for (const auto& r : net_.bus().log()) out.push_back(r.sender + " " + r.frame.to_string());
    return out;
  }
  // SDO download from a plain host client on the bus (not the network manager).
  SdoAbortCode download(Master& host, NodeId node, std::uint16_t index, std::uint8_t sub,
                        std::vector<std::uint8_t> data) {
    std::optional<SdoAbortCode> result;
    host.sdo(node).download(index, sub, std::move(data),
                            [&](SdoAbortCode c, std::vector<std::uint8_t>) { result = c; });
    net_.run_for(50ms);
    return result.value_or(SdoAbortCode::Timeout);
  }

  oegw::testing::VirtualNetwork net_;
  ObjectDictionary od_;
  std::unique_ptr<Master> master_;
  std::unique_ptr<NetworkManager> network_;
  std::string log_;
  std::vector<std::string> diag_lines_;
};

constexpr NodeId kKnob{0x7F};
constexpr NodeId kStick{0x03};
constexpr NodeId kGrip{0x11};

// A Novotechnik sensor whose stored 1F80h has bit 3 set: operational after every boot-up.
std::unique_ptr<sim::Novotechnik406Sim> self_starting_knob(oegw::testing::VirtualNetwork& net,
                                                           const std::filesystem::path& store,
                                                           std::uint32_t revision = 0x00010003) {
  auto knob =
      std::make_unique<sim::Novotechnik406Sim>(net.sink("knob"), sim::Novotechnik406SimConfig{.node_id = kKnob,
                                                                                              .revision = revision,
                                                                                              .heartbeat_ms = 50,
                                                                                              .store_path = store});
  (void)knob->od().set<std::uint32_t>(0x1F80, 0, 0x08, Origin::Local);
  (void)knob->od().write(0x1010, 1, encode<std::uint32_t>(kSave), Origin::Local);
  return knob;
}

TEST_F(Boot, NovotechnikRefusesRemappingAndStoreWhileOperational) {
  // §8.2 "For changing of mapping, the sensor must be in pre-operational mode"; §11 storing "is
  // only admitted in the pre-operational status"; §7.3 abort 0x08000022 "wrong state".
  sim::Novotechnik406Sim knob(net_.sink("knob"),
                              sim::Novotechnik406SimConfig{.node_id = kKnob, .store_path = temp_store("refuse")});
  net_.attach("knob", knob);
  ObjectDictionary host_od;
  Master host(host_od, net_.sink("host"), MasterConfig{.heartbeat_entries = 2, .sdo_timeout = 100ms});
  net_.attach("host", host);
  knob.start(net_.now());
  net_.settle();
  EXPECT_EQ(download(host, kKnob, 0x1800, 1, encode<std::uint32_t>(0xC00001FF)), SdoAbortCode::None);
  EXPECT_EQ(download(host, kKnob, 0x1A00, 0, {0}), SdoAbortCode::None) << "pre-operational: allowed";
  host.nmt().start(kKnob);
  net_.settle();
  ASSERT_EQ(knob.node().state(), NmtState::Operational);
  EXPECT_EQ(download(host, kKnob, 0x1A00, 0, {2}), SdoAbortCode::CannotTransferDeviceState);
  EXPECT_EQ(download(host, kKnob, 0x1A00, 1, encode<std::uint32_t>(0x60200120)),
            SdoAbortCode::CannotTransferDeviceState);
  EXPECT_EQ(download(host, kKnob, 0x1010, 1, encode<std::uint32_t>(kSave)), SdoAbortCode::CannotTransferDeviceState);
  EXPECT_EQ(download(host, kKnob, 0x1800, 5, encode<std::uint16_t>(10)), SdoAbortCode::None)
      << "other parameters stay writable";
  host.nmt().enter_pre_operational(kKnob);
  net_.settle();
  EXPECT_EQ(download(host, kKnob, 0x1A00, 0, {2}), SdoAbortCode::None);
  EXPECT_EQ(download(host, kKnob, 0x1010, 1, encode<std::uint32_t>(kSave)), SdoAbortCode::None);
}

TEST_F(Boot, McbAndElobauRefuseStoreWhileOperational) {
  // MCB-402 [CO4013 1010h/1011h] "only allowed in preoperational mode" (no code given: 0800
  // 0022h); elobau: the document is silent, the simulator takes CiA 301's 0800 0022h.
  sim::Mcb402Sim stick(net_.sink("stick"), sim::Mcb402SimConfig{.node_id = kStick, .store_path = temp_store("mcb")});
  sim::ElobauMfgSim grip(net_.sink("grip"),
                         sim::ElobauMfgSimConfig{.node_id = kGrip, .store_path = temp_store("elobau")});
  net_.attach("stick", stick);
  net_.attach("grip", grip);
  ObjectDictionary host_od;
  Master host(host_od, net_.sink("host"), MasterConfig{.heartbeat_entries = 2, .sdo_timeout = 100ms});
  net_.attach("host", host);
  stick.start(net_.now());
  grip.start(net_.now());
  net_.settle();
  host.nmt().start(kStick);
  host.nmt().start(kGrip);
  net_.settle();
  EXPECT_EQ(download(host, kStick, 0x1010, 1, encode<std::uint32_t>(kSave)), SdoAbortCode::CannotTransferDeviceState);
  EXPECT_EQ(download(host, kStick, 0x1011, 1, encode<std::uint32_t>(0x64616F6C)),
            SdoAbortCode::CannotTransferDeviceState);
  EXPECT_EQ(download(host, kStick, 0x1801, 5, encode<std::uint16_t>(20)), SdoAbortCode::None)
      << "the CO4013 takes PDO parameters in operational";
  EXPECT_EQ(download(host, kGrip, 0x1010, 1, encode<std::uint32_t>(kSave)), SdoAbortCode::CannotTransferDeviceState);
  EXPECT_EQ(download(host, kGrip, 0x5999, 3, encode<std::uint32_t>(kSave)), SdoAbortCode::CannotTransferDeviceState);
  host.nmt().enter_pre_operational(kStick);
  host.nmt().enter_pre_operational(kGrip);
  net_.settle();
  EXPECT_EQ(download(host, kStick, 0x1010, 1, encode<std::uint32_t>(kSave)), SdoAbortCode::None);
  EXPECT_EQ(download(host, kGrip, 0x1010, 1, encode<std::uint32_t>(kSave)), SdoAbortCode::None);
}

TEST_F(Boot, ASelfStartingSensorIsPutInPreOperationalAndConfigured) {
  auto knob = self_starting_knob(net_, temp_store("self"));
  net_.attach("knob", *knob);
  knob->start(net_.now());
  net_.settle();
  ASSERT_EQ(knob->node().state(), NmtState::Operational) << "1F80h bit 3: operational at power-on";
  make_gateway();
  add("novotechnik-406", kKnob, NodeSettings{.name = "knob", .heartbeat_ms = 50, .mandatory = true});
  net_.bus().set_logging(true);
  network_->start(net_.now());
  net_.run_for(2s);
  ASSERT_EQ(network_->state("knob"), NodeState::Operational) << log_;
  // After the boot-up (reset communication, the sensor starts itself again) the gateway sends
  // NMT enter pre-operational before its first SDO request.
  const auto got = frames();
  const auto boot = std::find(got.begin(), got.end(), "knob 77F#00");
  ASSERT_NE(boot, got.end());
  const auto preop = std::find(boot, got.end(), "gateway 000#807F");
  ASSERT_NE(preop, got.end()) << "no NMT enter pre-operational after the boot-up";
  const auto first_sdo =
      std::find_if(boot, got.end(), [](const std::string& f) { return f.rfind("gateway 67F#", 0) == 0; });
  EXPECT_LT(preop - got.begin(), first_sdo - got.begin());
  EXPECT_EQ(std::count_if(got.begin(), got.end(), [](const std::string& f) { return f.rfind("knob 5FF#80", 0) == 0; }),
            0)
      << "no SDO abort";
  (void)knob->set_input("position", 4242, net_.now());
  net_.run_for(100ms);
  Driver* d = network_->driver("knob");
  EXPECT_EQ(d->value(*d->find_signal("position")).value, 4242);
}

TEST_F(Boot, RevisionIsComparedByItsMajorPartUnlessExact) {
  auto knob = self_starting_knob(net_, temp_store("rev"), 0x00010007);  // firmware 1.7
  net_.attach("knob", *knob);
  knob->start(net_.now());
  make_gateway();
  NodeSettings s{.name = "knob", .heartbeat_ms = 50};
  s.identity.revision = 0x00010003;  // configured for 1.3
  add("novotechnik-406", kKnob, s);
  network_->start(net_.now());
  net_.run_for(2s);
  EXPECT_EQ(network_->state("knob"), NodeState::Operational) << "a minor update is compatible\n" << log_;
}

TEST_F(Boot, ExactRevisionAndAnotherMajorRevisionAreRefused) {
  auto knob = self_starting_knob(net_, temp_store("rev2"), 0x00020003);  // firmware 2.3
  net_.attach("knob", *knob);
  knob->start(net_.now());
  make_gateway();
  NodeSettings s{.name = "knob", .heartbeat_ms = 50};
  s.identity.revision = 0x00010003;
  add("novotechnik-406", kKnob, s);
  network_->start(net_.now());
  net_.run_for(1s);
  EXPECT_EQ(network_->state("knob"), NodeState::Refused) << log_;
  EXPECT_NE(log_.find("1018h:03 is 00020003h: major revision 0002h, the configuration expects 0001h"),
            std::string::npos)
      << log_;

  oegw::testing::VirtualNetwork net2;
  auto knob2 = self_starting_knob(net2, temp_store("rev3"), 0x00010007);
  net2.attach("knob", *knob2);
  knob2->start(net2.now());
  ObjectDictionary od2;
  Master master2(od2, net2.sink("gateway"), MasterConfig{.heartbeat_entries = 8, .sdo_timeout = 200ms});
  NetworkManager network2(master2);
  net2.attach("gateway", network2);
  std::string why;
  network2.on_node_state = [&why](const std::string&, NodeState, const std::string& w) { why = w; };
  std::string error;
  NodeSettings e{.name = "knob", .node = kKnob, .heartbeat_ms = 50};
  e.identity.revision = 0x00010003;
  e.exact_revision = true;
  ASSERT_TRUE(network2.add(e, make_driver("novotechnik-406", kKnob, net2.sink("gateway"), {}, error)));
  network2.start(net2.now());
  net2.run_for(1s);
  EXPECT_EQ(network2.state("knob"), NodeState::Refused);
  EXPECT_EQ(why, "1018h:03 is 00010007h, the configuration expects 00010003h");
}

TEST_F(Boot, BootDiagnosticsAreReadKeptAndReportedOncePerBoot) {
  auto knob = self_starting_knob(net_, temp_store("diag"));
  sim::Mcb402Sim stick(net_.sink("stick"), sim::Mcb402SimConfig{.node_id = kStick, .heartbeat_ms = 50});
  net_.attach("knob", *knob);
  net_.attach("stick", stick);
  knob->start(net_.now());
  stick.start(net_.now());
  make_gateway();
  add("novotechnik-406", kKnob, NodeSettings{.name = "knob", .heartbeat_ms = 50});
  add("mcb402", kStick, NodeSettings{.name = "stick", .heartbeat_ms = 50},
      DriverOptions{{{"button_bits", "1,2,3,4,5,7,6"}}});
  network_->start(net_.now());
  net_.run_for(2s);
  ASSERT_EQ(network_->state("knob"), NodeState::Operational) << log_;
  ASSERT_EQ(network_->state("stick"), NodeState::Operational) << log_;
  // Novotechnik §4.1 / §6: vendor 182h, product 0BE0h, revision 00010003h, serial 12345678h, the
  // 1008h/1009h/100Ah examples (1008h is 20 characters: a segmented upload).
  const NodeDiagnostics* k = network_->diagnostics("knob");
  ASSERT_NE(k, nullptr);
  EXPECT_EQ(k->vendor_id, 0x182u);
  EXPECT_EQ(k->product_code, 0x0BE0u);
  EXPECT_EQ(k->revision, 0x00010003u);
  EXPECT_EQ(k->serial, 0x12345678u);
  EXPECT_EQ(k->device_name, "MC1-2832-A7F-614-511");
  EXPECT_EQ(k->hardware_version, "400000000.00");
  EXPECT_EQ(k->software_version, "V 1.03.0");
  EXPECT_EQ(k->error_register, 0u);
  // MCB-402: 1018h has no serial (sub 0 = 3) and there is no 100Ah: not present, not a failure.
  const NodeDiagnostics* m = network_->diagnostics("stick");
  ASSERT_NE(m, nullptr);
  EXPECT_EQ(m->device_name, "CO4013A");
  EXPECT_FALSE(m->serial.has_value());
  EXPECT_FALSE(m->software_version.has_value());
  EXPECT_TRUE(m->vendor_id.has_value());
  ASSERT_EQ(diag_lines_.size(), 2u) << "once per boot";
  if (diag_lines_[0].rfind("stick", 0) == 0) std::swap(diag_lines_[0], diag_lines_[1]);
  EXPECT_EQ(diag_lines_[0].rfind("knob: vendor 00000182h, product 00000BE0h, revision 00010003h, serial 12345678h, "
                                 "name \"MC1-2832-A7F-614-511\", hardware \"400000000.00\", software \"V 1.03.0\", "
                                 "error register 00h",
                                 0),
            0u)
      << diag_lines_[0];
  EXPECT_NE(diag_lines_[1].find("serial -"), std::string::npos) << diag_lines_[1];
  EXPECT_NE(diag_lines_[1].find("software -"), std::string::npos) << diag_lines_[1];
  stick.reboot(net_.now());
  net_.run_for(2s);
  EXPECT_EQ(diag_lines_.size(), 3u) << "again after the reboot";
}

TEST_F(Boot, SynchronousTpdoWithoutSyncIsRefusedWithTheReason) {
  auto knob = self_starting_knob(net_, temp_store("nosync"));
  net_.attach("knob", *knob);
  knob->start(net_.now());
  make_gateway();
  add("novotechnik-406", kKnob, NodeSettings{.name = "knob", .heartbeat_ms = 50},
      DriverOptions{{{"transmission_type", "2"}}});
  network_->start(net_.now());
  net_.run_for(1s);
  EXPECT_EQ(network_->state("knob"), NodeState::Refused) << log_;
  EXPECT_NE(log_.find(
                "the TPDO of 1800h has a synchronous transmission type (0..240: sent only at a SYNC) and no SYNC is "
                "produced downstream (downstream.sync_period_ms not set)"),
            std::string::npos)
      << log_;
}

TEST_F(Boot, SyncIsProducedAndASynchronousTpdoComesEveryNthSync) {
  auto knob = self_starting_knob(net_, temp_store("sync"));
  net_.attach("knob", *knob);
  knob->start(net_.now());
  make_gateway(20ms);
  // No freshness floor (its 200 ms would hide the SYNC product this test looks at).
  add("novotechnik-406", kKnob, NodeSettings{.name = "knob", .heartbeat_ms = 50},
      DriverOptions{{{"transmission_type", "2"}, {"freshness_floor_ms", "0"}}});
  network_->start(net_.now());
  net_.run_for(1s);
  ASSERT_EQ(network_->state("knob"), NodeState::Operational) << log_;
  Driver* d = network_->driver("knob");
  const std::size_t pos = *d->find_signal("position");
  // CiA 301 §7.5.2.35: type 2 = after every 2nd SYNC: 2 × 20 ms, stale after 3 such periods.
  EXPECT_EQ(d->freshness(pos), 120ms);
  (void)knob->set_input("position", 777, net_.now());
  net_.bus().set_logging(true);
  net_.run_for(400ms);
  EXPECT_EQ(d->value(pos).value, 777);
  EXPECT_EQ(d->value(pos).status, SignalStatus::Valid);
  const auto got = frames();
  const auto syncs = std::count(got.begin(), got.end(), "gateway 080#");
  const auto tpdos =
      std::count_if(got.begin(), got.end(), [](const std::string& f) { return f.rfind("knob 1FF#", 0) == 0; });
  EXPECT_GE(syncs, 19);
  EXPECT_LE(syncs, 21);
  EXPECT_GE(tpdos, syncs / 2 - 1);
  EXPECT_LE(tpdos, syncs / 2 + 1);
  // The sensor stops sending (its SYNC-triggered TPDO too): stale after 3 × 2 × 20 ms.
  knob->set_pdo_stopped(true);
  // The last TPDO came at most 2 × 20 ms before: due between +80 ms and +120 ms.
  net_.run_for(70ms);
  EXPECT_EQ(d->value(pos).status, SignalStatus::Valid);
  net_.run_for(60ms);
  EXPECT_EQ(d->value(pos).status, SignalStatus::Stale);
}

// A generic CiA 401 node described by a vendor-style EDS (tests/fixtures/vendor_io_module.eds):
// it boots with a newer minor revision than configured, its diagnostics come from the EDS
// (the simulator has what the EDS lists), and 6423h is enabled because TPDO2 maps analogue
// inputs event-driven (transmission type 255): only then does a new analogue value arrive.
TEST_F(Boot, GenericNodeFromAVendorEdsBootsAndItsAnalogueInputsSendOnChange) {
  const std::string eds = OEGW_SOURCE_DIR "/tests/fixtures/vendor_io_module.eds";
  constexpr NodeId kIo{0x22};
  std::string error;
  auto io = sim::Cia401Sim::from_file(eds, kIo, net_.sink("io"), error);
  ASSERT_TRUE(io) << error;
  net_.attach("io", *io);
  io->start(net_.now());
  make_gateway();
  NodeSettings s{.name = "io", .heartbeat_ms = 50};
  s.identity.revision = 0x00030001;  // configured for 3.1, the module has 3.4
  add("cia401", kIo, s, DriverOptions{{{"eds", eds}}});
  network_->start(net_.now());
  net_.run_for(2s);
  ASSERT_EQ(network_->state("io"), NodeState::Operational) << log_;
  EXPECT_EQ(io->od().get<std::uint8_t>(0x6423, 0), 1) << "6423h enabled at configuration";
  const NodeDiagnostics* d = network_->diagnostics("io");
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->device_name, "IOM-8DI2AI");
  EXPECT_EQ(d->hardware_version, "HW 2.1");
  EXPECT_EQ(d->software_version, "FW 3.04.17");
  EXPECT_EQ(d->revision, 0x00030004u);
  EXPECT_EQ(d->serial, 0x0001E240u);
  ASSERT_TRUE(io->set_input("analog[2]", -1234, net_.now()));
  net_.run_for(50ms);
  Driver* drv = network_->driver("io");
  EXPECT_EQ(drv->value(*drv->find_signal("analog[2]")).value, -1234);
}

TEST_F(Boot, GenericSimulatorLacksTheStringsItsEdsLacks) {
  constexpr NodeId kPedal{0x30};
  std::string error;
  auto pedal =
      sim::Cia401Sim::from_file(OEGW_SOURCE_DIR "/subdevices/eds/generic_pedal.eds", kPedal, net_.sink("p"), error);
  ASSERT_TRUE(pedal) << error;
  EXPECT_EQ(pedal->od().find(0x1008), nullptr);
  EXPECT_EQ(pedal->od().find(0x100A), nullptr);
}

}  // namespace
