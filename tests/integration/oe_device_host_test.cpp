// Tier 2: the CiA 852 device (OeDevice) and a host (canopen::Master) on the virtual bus with a
// simulated clock: the host reads 1000h, configures the clause 12 PDOs by SDO, starts the node and
// exchanges process data; every frame crosses the bus.
#include <gtest/gtest.h>

#include <string>
#include <tuple>
#include <vector>

#include "canopen/master.hpp"
#include "gateway/oe_device.hpp"
#include "virtual_network.hpp"

using namespace oegw::canopen;
using namespace std::chrono_literals;
using oegw::gateway::OeDevice;
using oegw::gateway::OeDeviceConfig;
using oegw::mapping::FeId;
using oegw::mapping::FeKind;
using Bytes = std::vector<std::uint8_t>;

namespace {

constexpr NodeId kGw{0x30};
const FeId kJoy{FeKind::Joystick, 1};
const FeId kWheel{FeKind::Wheel, 1};
const FeId kButtons{FeKind::ButtonCluster, 1};
const FeId kLeds{FeKind::IndicatorCluster, 1};

class OeDeviceHost : public ::testing::Test {
 protected:
  OeDeviceHost() {
    OeDeviceConfig c;
    c.node_id = kGw;
    c.identity = {.vendor = 0x1234, .product = 0x852, .revision = 1, .serial = 5};
    c.heartbeat_ms = 100;
    c.fes = {kJoy, kWheel, kButtons, kLeds};
    gw_ = std::make_unique<OeDevice>(c, net_.sink("gw"));
    net_.attach("gw", *gw_);
    gw_->on_output([this](FeId fe, oegw::gateway::FieldRef r, std::int64_t v, oegw::canopen::TimePoint) {
      outputs_.emplace_back(fe, oegw::gateway::field_name(fe, r), v);
    });
    host_ = std::make_unique<Master>(host_od_, net_.sink("host"), MasterConfig{.heartbeat_entries = 4});
    net_.attach("host", *host_);
    host_->on_emcy = [this](const EmcyMessage& m, TimePoint) { emcys_.push_back(m); };
    host_->on_other_frame = [this](const CanFrame& f, TimePoint) { others_.push_back(f); };
    (void)gw_->start(net_.now());
    net_.settle();
  }
  SdoAbortCode download(std::uint16_t index, std::uint8_t sub, Bytes data) {
    SdoAbortCode code = SdoAbortCode::GeneralError;
    bool done = false;
    host_->sdo(kGw).download(index, sub, std::move(data), [&](SdoAbortCode c, Bytes) {
      code = c;
      done = true;
    });
    net_.run_for(1s);
    EXPECT_TRUE(done);
    return code;
  }
  std::uint32_t upload_u32(std::uint16_t index, std::uint8_t sub) {
    std::uint32_t v = 0;
    host_->sdo(kGw).upload(index, sub, [&](SdoAbortCode c, Bytes d) {
      EXPECT_EQ(c, SdoAbortCode::None);
      if (d.size() == 4) v = decode_unsigned(d);
    });
    net_.run_for(1s);
    return v;
  }
  std::vector<CanFrame> others_with(std::uint32_t id) const {
    std::vector<CanFrame> r;
    for (const auto& f : others_)
      if (f.id == id) r.push_back(f);
    return r;
  }

  oegw::testing::VirtualNetwork net_;
  std::unique_ptr<OeDevice> gw_;
  ObjectDictionary host_od_;
  std::unique_ptr<Master> host_;
  std::vector<EmcyMessage> emcys_;
  std::vector<CanFrame> others_;
  std::vector<std::tuple<FeId, std::string, std::int64_t>> outputs_;
};

// CiA 852 §11.2 (1000h over SDO), §12 (enable TPDO 1/32/34 and RPDO 1), §8.6 (EMCY 0080h at
// start with 6423h FALSE), then process data both ways.
TEST_F(OeDeviceHost, HostConfiguresStartsAndExchangesProcessData) {
  EXPECT_EQ(upload_u32(0x1000, 0), 0xB9870191u);  // joystick+buttons, wheel, push-buttons, indicators (Table 8)
  EXPECT_EQ(upload_u32(0x1800, 1), 0x800001B0u);  // TPDO 1: 8000 0180h + node-ID
  ASSERT_EQ(download(0x1800, 1, encode<std::uint32_t>(0x1B0)), SdoAbortCode::None);
  ASSERT_EQ(download(0x181F, 1, encode<std::uint32_t>(0x2B0)), SdoAbortCode::None);  // TPDO 32
  ASSERT_EQ(download(0x1821, 1, encode<std::uint32_t>(0x3B0)), SdoAbortCode::None);  // TPDO 34
  ASSERT_EQ(download(0x1400, 1, encode<std::uint32_t>(0x230)), SdoAbortCode::None);  // RPDO 1
  host_->nmt().start(kGw);
  net_.run_for(10ms);
  ASSERT_EQ(gw_->node().state(), NmtState::Operational);
  ASSERT_EQ(emcys_.size(), 1u);
  EXPECT_EQ(emcys_[0].code, 0x0080);
  EXPECT_EQ(emcys_[0].error_register, 0x01);
  // Entering operational sends each enabled TPDO once (§12.1).
  EXPECT_EQ(others_with(0x1B0).size(), 1u);
  EXPECT_EQ(others_with(0x2B0).size(), 1u);
  EXPECT_EQ(others_with(0x3B0).size(), 1u);

  ASSERT_EQ(download(0x6423, 0, {1}), SdoAbortCode::None);
  ASSERT_EQ(emcys_.size(), 2u);
  EXPECT_EQ(emcys_[1].code, 0x0000);  // error reset once analogue interrupts are enabled
  others_.clear();
  ASSERT_TRUE(gw_->set_input(kWheel, "position", -32767, net_.now()));
  ASSERT_TRUE(gw_->set_input(kButtons, "switch[64]", 1, net_.now()));
  ASSERT_TRUE(gw_->set_input(kJoy, "y", 16384, net_.now()));
  net_.run_for(1ms);
  auto w = others_with(0x2B0);
  ASSERT_EQ(w.size(), 1u);
  // Table 24: wheel 1 at bytes 0-1, wheels 2..4 (not configured) read 0.
  EXPECT_EQ(Bytes(w[0].data.begin(), w[0].data.begin() + w[0].dlc), (Bytes{0x01, 0x80, 0, 0, 0, 0, 0, 0}));
  auto b = others_with(0x3B0);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_EQ(Bytes(b[0].data.begin(), b[0].data.begin() + b[0].dlc), (Bytes{0, 0, 0, 0, 0, 0, 0, 0x80}));
  auto j = others_with(0x1B0);
  ASSERT_EQ(j.size(), 1u);
  EXPECT_EQ(Bytes(j[0].data.begin(), j[0].data.begin() + j[0].dlc), (Bytes{0, 0, 0x00, 0x40, 0, 0, 0, 0}));

  // Host → indicators by RPDO 1.
  outputs_.clear();
  host_->sink()(CanFrame(0x230, {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01}));
  net_.run_for(1ms);
  using O = std::tuple<FeId, std::string, std::int64_t>;
  EXPECT_EQ(outputs_, (std::vector<O>{{kLeds, "indicator[57]", 1}}));

  // A sub-device fault reaches the host as EMCY 7000h naming node 11h.
  gw_->raise_subdevice_fault("grip", NodeId{0x11}, net_.now());
  net_.run_for(1ms);
  ASSERT_EQ(emcys_.size(), 3u);
  EXPECT_EQ(emcys_[2].code, 0x7000);
  EXPECT_EQ(emcys_[2].msef[0], 0x11);
}

}  // namespace
