// Remote EMCY and the gateway's EMCY consumer, on the virtual buses (rig/cab_rig.hpp, the
// demo cab of tests/fixtures/demo_cab.yaml, a simulated clock). Each simulator sends the EMCYs
// its reference document gives; the host must receive each one as an EMCY of the gateway (node
// 20h) carrying the sub-device's code, its error register, its node-ID and its manufacturer
// bytes 0..2 (gateway/oe_device.hpp), before the fault policy's 7000h, as the mapping file's
// downstream.emcy_forwarding says. Upstream, an EMCY of another node (1028h) is logged and kept
// for the status.
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "gateway/gateway.hpp"
#include "rig/cab_rig.hpp"
#include "subdevices/sim/cia401_sim.hpp"
#include "subdevices/sim/elobau_mfg_sim.hpp"
#include "subdevices/sim/mcb402_sim.hpp"
#include "subdevices/sim/novotechnik_406_sim.hpp"
#include "tests/fixtures/fixtures.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
namespace gw = oegw::gateway;
namespace sim = oegw::subdevices::sim;
using Bytes = std::vector<std::uint8_t>;

namespace {

constexpr std::uint32_t kGatewayEmcy = 0x80 + 0x20;

Bytes bytes(const CanFrame& f) { return Bytes(f.data.begin(), f.data.begin() + f.dlc); }

class RemoteEmcy : public ::testing::Test {
 protected:
  // The demo cab; `forwarding` is the downstream.emcy_forwarding value ("" = the default).
  void build(const std::string& forwarding = "") {
    std::string yaml = oegw::fixtures::mapping_file("demo_cab.yaml");
    if (!forwarding.empty()) {
      const std::string down = "downstream: { interface: virtual, bitrate: 250000";
      const auto at = yaml.find(down);
      ASSERT_NE(at, std::string::npos);
      yaml.insert(at + down.size(), ", emcy_forwarding: " + forwarding);
    }
    auto loaded = oegw::mapping::load_config_text(yaml, "remote_emcy.yaml", gw::driver_catalogue());
    ASSERT_TRUE(loaded.ok()) << loaded.error_text();
    config_ = std::move(*loaded.config);
    rig_ = std::make_unique<oegw::rig::CabRig>(config_, loop_);
    rig_->up().set_tap([this](const BusRecord& r) {
      if (r.frame.id == kGatewayEmcy) up_emcys_.push_back(r);
    });
    rig_->down().set_tap([this](const BusRecord& r) {
      if (r.frame.id > 0x80 && r.frame.id < 0x100) down_emcys_.push_back(r);
    });
    rig_->on_gateway = [this](gw::Gateway& g) {
      gw_ = &g;
      g.on_log = [this](const std::string& l) { log_ += l + "\n"; };
    };
    rig_->build();
    rig_->power_on();
    rig_->run_for(3s);
    for (const auto& n : gw_->downstream().names())
      ASSERT_EQ(gw_->downstream().state(n), oegw::subdevices::NodeState::Operational) << n << "\n" << log_;
    up_emcys_.clear();
    down_emcys_.clear();
  }
  TimePoint now() const { return loop_.now(); }
  // The gateway's EMCY frames with this code.
  std::vector<CanFrame> up(std::uint16_t code) const {
    std::vector<CanFrame> r;
    for (const auto& e : up_emcys_)
      if (get_u16(e.frame.data.data()) == code) r.push_back(e.frame);
    return r;
  }
  // The frame the gateway forwards for a sub-device EMCY `down` from `node` (oe_device.hpp),
  // with the gateway's error register `reg`.
  static Bytes forwarded(std::uint8_t node, const Bytes& down, std::uint8_t reg) {
    return Bytes{down[0], down[1], reg, node, down[2], down[3], down[4], down[5]};
  }
  // Index in up_emcys_ of the first frame equal to `b`.
  std::optional<std::size_t> index_of(const Bytes& b) const {
    for (std::size_t i = 0; i < up_emcys_.size(); ++i)
      if (bytes(up_emcys_[i].frame) == b) return i;
    return std::nullopt;
  }
  std::string dump() const {
    std::string s = log_ + "downstream EMCYs:\n";
    for (const auto& r : down_emcys_) s += "  " + r.to_string() + "\n";
    s += "upstream EMCYs:\n";
    for (const auto& r : up_emcys_) s += "  " + r.to_string() + "\n";
    return s;
  }
  sim::ElobauMfgSim& grip() { return dynamic_cast<sim::ElobauMfgSim&>(*rig_->devices().device("right_grip")); }
  sim::Mcb402Sim& mcb() { return dynamic_cast<sim::Mcb402Sim&>(*rig_->devices().device("left_grip")); }
  sim::Novotechnik406Sim& knob() { return dynamic_cast<sim::Novotechnik406Sim&>(*rig_->devices().device("seat_knob")); }
  sim::Cia401Sim& pedal() { return dynamic_cast<sim::Cia401Sim&>(*rig_->devices().device("pedal")); }

  oegw::mapping::Config config_;
  SimulatedClock clock_;
  EventLoop loop_{clock_};
  std::unique_ptr<oegw::rig::CabRig> rig_;
  gw::Gateway* gw_ = nullptr;
  std::vector<BusRecord> up_emcys_;
  std::vector<BusRecord> down_emcys_;
  std::string log_;
};

// elobau §12.4 / Table 5: a manufacturer error goes as 1000h [code][00][4001h lo hi][FF FF FF];
// Table 6 0021h "Y Axis, Signal 2, Out Of Range"; its clearing sends 0000h.
TEST_F(RemoteEmcy, ElobauErrorAndResetArriveUpstreamWithTheirBytesBeforeThe7000h) {
  build();
  // The MCB-402's power-on EMCY 8100h ([MCB §4]) was counted during the boot.
  const auto left_before = gw_->subdevice_emcy("left_grip").count;
  grip().raise_error(0x0021, now());
  rig_->run_for(300ms);
  const Bytes down_error{0x00, 0x10, 0x00, 0x21, 0x00, 0xFF, 0xFF, 0xFF};
  ASSERT_FALSE(down_emcys_.empty());
  EXPECT_EQ(down_emcys_.front().frame.id, 0x91u);
  EXPECT_EQ(bytes(down_emcys_.front().frame), down_error);
  const auto fwd = index_of(forwarded(0x11, down_error, 0x00));
  ASSERT_TRUE(fwd) << dump();
  EXPECT_EQ(bytes(up_emcys_[*fwd].frame), (Bytes{0x00, 0x10, 0x00, 0x11, 0x00, 0x21, 0x00, 0xFF}));
  const auto fault = index_of({0x00, 0x70, 0x01, 0x11, 'r', 'i', 'g', 'h'});
  ASSERT_TRUE(fault) << dump();
  EXPECT_LT(*fwd, *fault) << "the sub-device's own EMCY first, then the fault policy's";
  // 1003h on the gateway: the 7000h naming node 11h, the forwarded 1000h of node 11h.
  EXPECT_EQ(gw_->upstream().od().get<std::uint32_t>(0x1003, 1), 0x00117000u);
  EXPECT_EQ(gw_->upstream().od().get<std::uint32_t>(0x1003, 2), 0x00111000u);
  // The error reset: forwarded with the gateway's register (7000h is active when it goes).
  up_emcys_.clear();
  grip().clear_error(0x0021, now());
  rig_->run_for(300ms);
  ASSERT_TRUE(index_of({0x00, 0x00, 0x01, 0x11, 0x00, 0x00, 0x00, 0xFF})) << dump();
  // The status: the grip's last EMCY and its count.
  const auto rec = gw_->subdevice_emcy("right_grip");
  EXPECT_EQ(rec.count, 2u);
  EXPECT_EQ(rec.last.code, 0x0000);
  EXPECT_EQ(rec.last.msef, (EmcyManufacturerField{0x00, 0x00, 0xFF, 0xFF, 0xFF}));
  EXPECT_EQ(gw_->subdevice_emcy("left_grip").count, left_before);
}

// MCB-402 [CO4013 "Emergency Messages"]: cable break 3120h "20 31 81 00 8x 00 00 00"; mended,
// error reset 0000h. Axis 2 (Y): x = 2.
TEST_F(RemoteEmcy, Mcb402CableBreakAndItsResetArriveUpstream) {
  build();
  const auto before = gw_->subdevice_emcy("left_grip").count;  // its power-on 8100h ([MCB §4])
  mcb().cable_break(2, true, now());
  rig_->run_for(300ms);
  ASSERT_FALSE(down_emcys_.empty());
  const Bytes down_break = bytes(down_emcys_.front().frame);
  EXPECT_EQ(down_break, (Bytes{0x20, 0x31, 0x81, 0x00, 0x82, 0x00, 0x00, 0x00}));
  // Byte 2 = 00h: it leaves before the 7000h its decoding causes (the driver marks y in error).
  const auto fwd = index_of({0x20, 0x31, 0x00, 0x03, 0x81, 0x00, 0x82, 0x00});
  ASSERT_TRUE(fwd) << dump();
  const auto fault = index_of({0x00, 0x70, 0x01, 0x03, 'l', 'e', 'f', 't'});
  ASSERT_TRUE(fault) << dump();
  EXPECT_LT(*fwd, *fault);
  mcb().cable_break(2, false, now());
  rig_->run_for(300ms);
  ASSERT_TRUE(index_of({0x00, 0x00, 0x01, 0x03, 0x00, 0x00, 0x00, 0x00})) << dump();
  const auto rec = gw_->subdevice_emcy("left_grip");
  EXPECT_EQ(rec.count, before + 2u);
  EXPECT_EQ(rec.time, down_emcys_.back().time) << "the reception time of its last EMCY";
  EXPECT_EQ(rec.last.code, 0x0000);
}

// Novotechnik §9.1: "0x5000 1 0 0 Device Hardware Fault"; the internal error bit back to 0: EMCY
// 0000h. Bytes 4..7 as the simulator sends them.
TEST_F(RemoteEmcy, NovotechnikHardwareFaultAndResetArriveUpstream) {
  build();
  knob().inject_fault(sim::Novotechnik406Sim::Fault::HardwareFault, now());
  rig_->run_for(300ms);
  ASSERT_FALSE(down_emcys_.empty()) << dump();
  const Bytes down_fault = bytes(down_emcys_.front().frame);
  ASSERT_EQ(down_fault.size(), 8u);
  EXPECT_EQ(down_emcys_.front().frame.id, 0xFFu);
  EXPECT_EQ(get_u16(down_fault.data()), 0x5000);
  EXPECT_EQ(down_fault[2], 0x01);
  EXPECT_EQ(down_fault[3], 0x00);
  ASSERT_TRUE(index_of(forwarded(0x7F, down_fault, 0x00))) << dump();
  down_emcys_.clear();
  ASSERT_TRUE(knob().clear_fault(now()));
  rig_->run_for(300ms);
  ASSERT_FALSE(down_emcys_.empty()) << dump();
  const Bytes down_reset = bytes(down_emcys_.front().frame);
  EXPECT_EQ(get_u16(down_reset.data()), 0x0000);
  ASSERT_TRUE(index_of(forwarded(0x7F, down_reset, 0x01))) << dump();
}

// A generic CiA 401 node (the pedal, from its EDS): CiA 301 Table 26 5000h "device hardware",
// sent by its CiA 301 EMCY producer, and its error reset.
TEST_F(RemoteEmcy, GenericCia401EmcyAndResetArriveUpstream) {
  build();
  pedal().node().emcy().raise(0x5000, 0x00, {0xA1, 0xA2, 0xA3, 0xA4, 0xA5}, now());
  rig_->run_for(300ms);
  ASSERT_FALSE(down_emcys_.empty());
  EXPECT_EQ(bytes(down_emcys_.front().frame), (Bytes{0x00, 0x50, 0x01, 0xA1, 0xA2, 0xA3, 0xA4, 0xA5}));
  ASSERT_TRUE(index_of({0x00, 0x50, 0x00, 0x30, 0x01, 0xA1, 0xA2, 0xA3})) << dump();
  pedal().node().emcy().clear(0x5000, now());
  rig_->run_for(300ms);
  ASSERT_TRUE(index_of({0x00, 0x00, 0x01, 0x30, 0x00, 0x00, 0x00, 0x00})) << dump();
  EXPECT_EQ(gw_->subdevice_emcy("pedal").count, 2u);
}

// emcy_forwarding: faults: the errors and the error resets, not the warnings (elobau 8140h
// "recovered from bus off", decoded as no error).
TEST_F(RemoteEmcy, FaultsForwardsErrorsAndResetsButNoWarnings) {
  build("faults");
  grip().bus_off(now());  // 8140h with the bus-off count
  rig_->run_for(300ms);
  ASSERT_FALSE(down_emcys_.empty());
  EXPECT_EQ(get_u16(down_emcys_.front().frame.data.data()), 0x8140);
  EXPECT_TRUE(up(0x8140).empty()) << dump();
  EXPECT_EQ(gw_->subdevice_emcy("right_grip").count, 1u) << "counted all the same";
  EXPECT_EQ(gw_->subdevice_emcy("right_grip").last.code, 0x8140);
  grip().raise_error(0x0021, now());
  rig_->run_for(300ms);
  ASSERT_TRUE(index_of({0x00, 0x10, 0x00, 0x11, 0x00, 0x21, 0x00, 0xFF})) << dump();
  grip().clear_error(0x0021, now());
  rig_->run_for(300ms);
  ASSERT_TRUE(index_of({0x00, 0x00, 0x01, 0x11, 0x00, 0x00, 0x00, 0xFF})) << dump();
}

// emcy_forwarding: none: no sub-device EMCY goes up, the fault policy's 7000h still does.
TEST_F(RemoteEmcy, NoneForwardsNothingButThe7000hStays) {
  build("none");
  const auto before = gw_->subdevice_emcy("left_grip").count;  // its power-on 8100h ([MCB §4])
  mcb().cable_break(2, true, now());
  rig_->run_for(300ms);
  EXPECT_TRUE(up(0x3120).empty()) << dump();
  ASSERT_EQ(up(0x7000).size(), 1u) << dump();
  EXPECT_EQ(bytes(up(0x7000)[0]), (Bytes{0x00, 0x70, 0x01, 0x03, 'l', 'e', 'f', 't'}));
  mcb().cable_break(2, false, now());
  rig_->run_for(300ms);
  for (const auto& f : up(0x0000))
    EXPECT_NE(bytes(f), (Bytes{0x00, 0x00, 0x01, 0x03, 0x00, 0x00, 0x00, 0x00})) << dump();
  EXPECT_EQ(gw_->subdevice_emcy("left_grip").count, before + 2u) << "counted all the same";
}

// The host sets 1015h = 100 ms: a second faulty sub-device's extra 7000h leaves 100 ms after
// the first 7000h, and the gateway's 1003h records both with the node-IDs.
TEST_F(RemoteEmcy, TheExtra7000hOfASecondFaultySubdeviceRespectsTheInhibitTime) {
  build("none");
  ASSERT_EQ(gw_->upstream().od().write(0x1015, 0, encode<std::uint16_t>(1000)), SdoAbortCode::None);
  rig_->command("right_grip heartbeat off");
  rig_->command("left_grip heartbeat off");
  rig_->run_for(600ms);
  const auto e = up(0x7000);
  ASSERT_EQ(e.size(), 2u) << dump();
  std::vector<TimePoint> at;
  for (const auto& r : up_emcys_)
    if (get_u16(r.frame.data.data()) == 0x7000) at.push_back(r.time);
  ASSERT_EQ(at.size(), 2u);
  EXPECT_GE(at[1] - at[0], 100ms) << dump();
  const auto& od = gw_->upstream().od();
  std::vector<std::uint32_t> history{od.get<std::uint32_t>(0x1003, 1), od.get<std::uint32_t>(0x1003, 2)};
  std::sort(history.begin(), history.end());
  EXPECT_EQ(history, (std::vector<std::uint32_t>{0x00037000u, 0x00117000u}));
}

// 1028h: the gateway consumes an EMCY of another upstream node (05h), logs it and keeps it.
TEST_F(RemoteEmcy, AnUpstreamEmcyOfAnotherNodeIsLoggedAndKept) {
  build();
  ASSERT_TRUE(gw_->upstream_emcys().empty());
  (void)rig_->host_port().send(CanFrame(0x085, {0x30, 0x81, 0x11, 0x01, 0x02, 0x03, 0x04, 0x05}));
  rig_->run_for(10ms);
  (void)rig_->host_port().send(CanFrame(0x085, {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}));
  rig_->run_for(10ms);
  EXPECT_NE(log_.find("upstream EMCY from node 05h: 8130h register 11h, manufacturer bytes 01 02 03 04 05"),
            std::string::npos)
      << log_;
  const auto& u = gw_->upstream_emcys();
  ASSERT_EQ(u.size(), 1u);
  EXPECT_EQ(u.begin()->first, 0x05);
  EXPECT_EQ(u.begin()->second.count, 2u);
  EXPECT_EQ(u.begin()->second.last.code, 0x0000);
  EXPECT_GT(u.begin()->second.time.time_since_epoch().count(), 0);
  // Its own EMCY (node 20h) is not consumed.
  (void)rig_->host_port().send(CanFrame(0x0A0, {0x00, 0x10, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00}));
  rig_->run_for(10ms);
  EXPECT_EQ(gw_->upstream_emcys().size(), 1u);
}

// A flood of forwarded EMCYs (17 x elobau 8140h, with 1015h = 1 s) fills the inhibit queue; the
// gateway's own 7000h for a sub-device lost meanwhile still goes out (it takes the place of a
// forwarded one), and before the forwarded ones still queued.
TEST_F(RemoteEmcy, ForwardedEmcysNeverCrowdOutTheGatewaysOwn7000h) {
  build();
  ASSERT_EQ(gw_->upstream().od().write(0x1015, 0, encode<std::uint16_t>(10000)), SdoAbortCode::None);
  for (int i = 0; i < 17; ++i) grip().bus_off(now());  // 17 warnings 8140h
  rig_->run_for(20ms);
  (void)rig_->command("left_grip heartbeat off");
  rig_->run_for(1s);
  ASSERT_FALSE(gw_->faults().empty());
  rig_->run_for(25s);
  EXPECT_EQ(up(0x7000).size(), 1u) << "the gateway's 7000h for left_grip never went out\n" << dump().substr(0, 4000);
  EXPECT_LT(up(0x8140).size(), 17u) << "a forwarded one gave its place";
  EXPECT_GE(gw_->upstream().node().emcy().dropped(), 1u);
}

}  // namespace
