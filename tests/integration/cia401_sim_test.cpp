// Tier 2: the generic CiA 401 driver against its simulator over the virtual bus, with a Master
// doing what the network manager does at boot: identity check, the driver's mapping read
// (SDO uploads of 1400h–1403h/1600h–1603h/1800h–1803h/1A00h–1A03h, CiA 301 §7.5.2.35–38), NMT
// start (CiA 301 §7.2.8.3.1), then PDOs both ways (CiA 301 §7.2.2) and EMCY (§7.2.7).
#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "canopen/master.hpp"
#include "subdevices/cia401.hpp"
#include "subdevices/families.hpp"
#include "subdevices/sim/cia401_sim.hpp"
#include "virtual_network.hpp"

namespace {

using namespace oegw::canopen;
using namespace oegw::subdevices;
using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

const std::filesystem::path kRoot = OEGW_SOURCE_DIR;  // the source tree (tests/CMakeLists.txt)
const std::string kPedal = (kRoot / "subdevices/eds/generic_pedal.eds").string();
const std::string kCluster = (kRoot / "subdevices/eds/button_cluster.eds").string();
constexpr NodeId kNode{0x2C};

class Cia401Bus : public ::testing::Test {
 protected:
  void make(const std::string& eds_path) {
    std::string error;
    sim_ = oegw::subdevices::sim::Cia401Sim::from_file(eds_path, kNode, net_.sink("node"), error);
    ASSERT_TRUE(sim_) << error;
    net_.attach("node", *sim_);
    host_ = std::make_unique<Master>(host_od_, net_.sink("host"),
                                     MasterConfig{.heartbeat_entries = 4, .sdo_timeout = 200ms});
    net_.attach("host", *host_);
    auto d = make_cia401_driver(kNode, net_.sink("host"), DriverOptions{{{"eds", eds_path}}}, error);
    ASSERT_TRUE(d) << error;
    drv_.reset(static_cast<Cia401Driver*>(d.release()));
    host_->on_other_frame = [this](const CanFrame& f, TimePoint now) {
      bus_pdos_.push_back(f);
      for (std::uint32_t id : drv_->consumed_cob_ids())
        if (id == f.id) (void)drv_->on_frame(f, now);
    };
    host_->on_emcy = [this](const EmcyMessage& m, TimePoint now) {
      if (m.node == kNode) emcys_.push_back(drv_->on_emcy(m, now));
    };
    host_->on_boot = [this](NodeId n) { boots_.push_back(n); };
    sim_->start(net_.now());
    net_.settle();
  }

  Bytes upload(std::uint16_t index, std::uint8_t sub) {
    Bytes out;
    bool done = false;
    host_->sdo(kNode).upload(index, sub, [&](SdoAbortCode c, Bytes d) {
      EXPECT_EQ(c, SdoAbortCode::None) << std::hex << index << ":" << int(sub);
      out = std::move(d);
      done = true;
    });
    net_.run_for(500ms);
    EXPECT_TRUE(done);
    return out;
  }
  SdoAbortCode download(std::uint16_t index, std::uint8_t sub, Bytes data) {
    SdoAbortCode code = SdoAbortCode::GeneralError;
    host_->sdo(kNode).download(index, sub, std::move(data), [&](SdoAbortCode c, Bytes) { code = c; });
    net_.run_for(500ms);
    return code;
  }
  static Bytes u32(std::uint32_t v) { return encode<std::uint32_t>(v); }

  // The network manager's boot: identity, mapping read (repeated until nothing is left), start.
  void boot_and_start() {
    const auto id = drv_->expected_identity();
    ASSERT_TRUE(id.device_type);
    EXPECT_EQ(decode_unsigned(upload(0x1000, 0)), *id.device_type);
    EXPECT_EQ(decode_unsigned(upload(0x1018, 1)), *id.vendor_id);
    EXPECT_EQ(decode_unsigned(upload(0x1018, 2)), *id.product_code);
    drv_->reset_mapping();
    int rounds = 0;
    for (auto reads = drv_->mapping_reads(); !reads.empty(); reads = drv_->mapping_reads()) {
      ASSERT_LT(++rounds, 5) << "the mapping read converges in a few rounds";
      for (const auto& r : reads) {
        ++sdo_reads_;
        host_->sdo(kNode).upload(r.index, r.sub, [this, r](SdoAbortCode c, Bytes d) {
          if (c == SdoAbortCode::None) {
            EXPECT_EQ(drv_->apply_mapping_read(r.index, r.sub, d), SdoAbortCode::None) << r.what;
          } else {
            drv_->apply_mapping_abort(r.index, r.sub, c);
          }
        });
      }
      net_.run_for(1s);
    }
    ASSERT_TRUE(drv_->mapping_complete());
    host_->nmt().start(kNode);
    net_.run_for(10ms);
    ASSERT_EQ(sim_->node().state(), NmtState::Operational);
    drv_->on_online(net_.now());
  }

  std::size_t sig(const std::string& name) {
    auto i = drv_->find_signal(name);
    EXPECT_TRUE(i) << name;
    return i.value_or(0);
  }
  std::int64_t val(const std::string& name) { return drv_->value(sig(name)).value; }
  SignalStatus status(const std::string& name) { return drv_->value(sig(name)).status; }

  oegw::testing::VirtualNetwork net_;
  ObjectDictionary host_od_;
  std::unique_ptr<oegw::subdevices::sim::Cia401Sim> sim_;
  std::unique_ptr<Master> host_;
  std::unique_ptr<Cia401Driver> drv_;
  std::vector<CanFrame> bus_pdos_;
  std::vector<DecodedEmcy> emcys_;
  std::vector<NodeId> boots_;
  int sdo_reads_ = 0;
};

TEST_F(Cia401Bus, PedalMappingReadThenInputsFlow) {
  make(kPedal);
  ASSERT_EQ(boots_, std::vector<NodeId>{kNode});
  boot_and_start();
  // Round 1: 1800h:1, :2, 1A00h:0 and 1801h:1, :2, 1A01h:0; round 2: 1A00h:1..3 and TPDO1's
  // event timer 1800h:5 (TPDO2's COB-ID is not valid, so its entries are not read).
  EXPECT_EQ(sdo_reads_, 10);
  EXPECT_EQ(drv_->consumed_cob_ids(), (std::vector<std::uint32_t>{0x180u + kNode.value()}));
  // CiA 852 §12.1 / the PDO service: entering Operational sends the event-driven TPDO once.
  EXPECT_EQ(status("analog[1]"), SignalStatus::Valid);
  EXPECT_EQ(val("analog[1]"), 0);
  ASSERT_EQ(sim_->set_object(0x6401, 1, -1234), SdoAbortCode::None);
  ASSERT_EQ(sim_->set_object(0x6401, 2, 20000), SdoAbortCode::None);
  ASSERT_EQ(sim_->set_object(0x6000, 1, 0x5A), SdoAbortCode::None);
  net_.run_for(5ms);
  EXPECT_EQ(val("analog[1]"), -1234);
  EXPECT_EQ(val("analog[2]"), 20000);
  EXPECT_EQ(val("in[1]"), 0x5A);
  EXPECT_EQ(drv_->counters().wrong_length, 0u);
  EXPECT_EQ(drv_->counters().unknown_cob, 0u);
  // The EDS event timer (1800h:5 = 50 ms) keeps the TPDO coming without changes.
  const std::size_t before = bus_pdos_.size();
  net_.run_for(200ms);
  EXPECT_GE(bus_pdos_.size() - before, 4u);
}

TEST_F(Cia401Bus, OutputsReachTheSimulatorsObjects) {
  make(kCluster);
  boot_and_start();
  EXPECT_EQ(drv_->consumed_cob_ids(), (std::vector<std::uint32_t>{0x180u + kNode.value(), 0x280u + kNode.value()}));
  ASSERT_TRUE(drv_->set_output(sig("out[1]"), 0x3C, net_.now()));
  net_.run_for(5ms);
  EXPECT_EQ(sim_->object_value(0x6200, 1), 0x3C);
  ASSERT_TRUE(drv_->set_output(sig("aout[1]"), 777, net_.now()));
  net_.run_for(5ms);
  EXPECT_EQ(sim_->object_value(0x6411, 1), 777);
  EXPECT_EQ(sim_->object_value(0x6200, 1), 0x3C) << "the other mapped outputs were sent as remembered";
  ASSERT_TRUE(drv_->set_output(sig("out[2]"), 0xFF, net_.now()));
  net_.run_for(5ms);
  EXPECT_EQ(sim_->object_value(0x6200, 2), 0xFF);
  EXPECT_EQ(sim_->object_value(0x6411, 1), 777);
  // Inputs of the cluster: 16 buttons in 6000h:1..2, a 32-bit group in 6120h:1.
  ASSERT_EQ(sim_->set_object(0x6000, 2, 0x80), SdoAbortCode::None);
  ASSERT_EQ(sim_->set_object(0x6120, 1, 0xDEADBEEF), SdoAbortCode::None);
  net_.run_for(5ms);
  EXPECT_EQ(val("in[2]"), 0x80);
  EXPECT_EQ(val("in32[1]"), 0xDEADBEEFll);
}

// The node's TPDO1 is remapped by SDO before boot (CiA 301 §7.3.5 mapping procedure): a driver
// that trusted the EDS default (6401h:1, 6401h:2, 6000h:1) would swap every value. The driver
// reads the actual mapping and decodes it right.
TEST_F(Cia401Bus, RemappedTpdoIsDecodedFromTheMappingReadBack) {
  make(kPedal);
  ASSERT_EQ(download(0x1800, 1, u32(CobId::kInvalidBit | (0x180u + kNode.value()))), SdoAbortCode::None);
  ASSERT_EQ(download(0x1A00, 0, {0}), SdoAbortCode::None);
  ASSERT_EQ(download(0x1A00, 1, u32(pdo_map(0x6000, 1, 8))), SdoAbortCode::None);
  ASSERT_EQ(download(0x1A00, 2, u32(pdo_map(0x6401, 2, 16))), SdoAbortCode::None);
  ASSERT_EQ(download(0x1A00, 3, u32(pdo_map(0x6401, 1, 16))), SdoAbortCode::None);
  ASSERT_EQ(download(0x1A00, 0, {3}), SdoAbortCode::None);
  ASSERT_EQ(download(0x1800, 1, u32(0x180u + kNode.value())), SdoAbortCode::None);
  // And TPDO2 enabled on another COB-ID carrying 6401h:1 alone.
  ASSERT_EQ(download(0x1A01, 1, u32(pdo_map(0x6401, 1, 16))), SdoAbortCode::None);
  ASSERT_EQ(download(0x1A01, 0, {1}), SdoAbortCode::None);
  ASSERT_EQ(download(0x1801, 1, u32(0x380u + kNode.value())), SdoAbortCode::None);
  boot_and_start();
  EXPECT_EQ(drv_->consumed_cob_ids(), (std::vector<std::uint32_t>{0x180u + kNode.value(), 0x380u + kNode.value()}));
  bus_pdos_.clear();
  ASSERT_EQ(sim_->set_object(0x6000, 1, 0x0F), SdoAbortCode::None);
  ASSERT_EQ(sim_->set_object(0x6401, 1, 100), SdoAbortCode::None);
  ASSERT_EQ(sim_->set_object(0x6401, 2, -200), SdoAbortCode::None);
  net_.run_for(5ms);
  // The frame on the bus is in the new layout: 6000h:1 first.
  ASSERT_FALSE(bus_pdos_.empty());
  const CanFrame& last = [&]() -> const CanFrame& {
    for (auto it = bus_pdos_.rbegin(); it != bus_pdos_.rend(); ++it)
      if (it->id == 0x180u + kNode.value()) return *it;
    return bus_pdos_.back();
  }();
  EXPECT_EQ(last, CanFrame(0x180 + kNode.value(), {0x0F, 0x38, 0xFF, 0x64, 0x00}));
  EXPECT_EQ(val("in[1]"), 0x0F);
  EXPECT_EQ(val("analog[1]"), 100);
  EXPECT_EQ(val("analog[2]"), -200);
  EXPECT_EQ(drv_->counters().wrong_length, 0u);
}

TEST_F(Cia401Bus, RemappedRpdoCarriesOutputsWhereTheNodeExpectsThem) {
  make(kCluster);
  ASSERT_EQ(download(0x1400, 1, u32(CobId::kInvalidBit | (0x200u + kNode.value()))), SdoAbortCode::None);
  ASSERT_EQ(download(0x1600, 0, {0}), SdoAbortCode::None);
  ASSERT_EQ(download(0x1600, 1, u32(pdo_map(0x6411, 1, 16))), SdoAbortCode::None);
  ASSERT_EQ(download(0x1600, 2, u32(pdo_map(0x6200, 2, 8))), SdoAbortCode::None);
  ASSERT_EQ(download(0x1600, 0, {2}), SdoAbortCode::None);
  ASSERT_EQ(download(0x1400, 1, u32(0x200u + kNode.value())), SdoAbortCode::None);
  boot_and_start();
  EXPECT_FALSE(drv_->set_output(sig("out[1]"), 1, net_.now())) << "6200h:1 is no longer mapped";
  ASSERT_TRUE(drv_->set_output(sig("out[2]"), 0xA5, net_.now()));
  ASSERT_TRUE(drv_->set_output(sig("aout[1]"), 321, net_.now()));
  net_.run_for(5ms);
  EXPECT_EQ(sim_->object_value(0x6200, 2), 0xA5);
  EXPECT_EQ(sim_->object_value(0x6411, 1), 321);
  EXPECT_EQ(sim_->object_value(0x6200, 1), 0);
}

TEST_F(Cia401Bus, EmcyFromTheNodePutsInputsInErrorUntilReset) {
  make(kPedal);
  boot_and_start();
  ASSERT_EQ(sim_->set_object(0x6401, 1, 500), SdoAbortCode::None);
  net_.run_for(5ms);
  ASSERT_EQ(val("analog[1]"), 500);
  // CiA 301 Table 26: 5000h device hardware.
  ASSERT_TRUE(sim_->node().emcy().raise(0x5000, 0x00, net_.now()));
  net_.run_for(5ms);
  ASSERT_FALSE(emcys_.empty());
  EXPECT_TRUE(emcys_.back().error);
  EXPECT_EQ(status("analog[1]"), SignalStatus::Error);
  EXPECT_EQ(val("analog[1]"), 0);
  ASSERT_TRUE(sim_->node().emcy().clear(0x5000, net_.now()));  // sends 0000h
  net_.run_for(1ms);
  EXPECT_FALSE(emcys_.back().error);
  EXPECT_NE(status("analog[1]"), SignalStatus::Error);
  net_.run_for(60ms);  // the event timer brings a fresh value
  EXPECT_EQ(status("analog[1]"), SignalStatus::Valid);
  EXPECT_EQ(val("analog[1]"), 500);
}

}  // namespace
