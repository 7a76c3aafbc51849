// The upstream CiA 852 device (gateway/oe_device.hpp; its dictionary: profiles/cia852/) frame by
// frame: a vector sink, a manual clock, SDO/NMT/RPDO frames from a "host" written by hand. Each
// vector names its CiA 852 clause.
#include "gateway/oe_device.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <string>
#include <tuple>
#include <vector>

#include "profiles/cia852/device_type.hpp"

namespace oegw::gateway {
namespace {

using namespace std::chrono_literals;
using canopen::CanFrame;
using canopen::NmtState;
using canopen::NodeId;
using canopen::ObjectDictionary;
using canopen::Origin;
using canopen::TimePoint;
using cia852::device_type_for;
using mapping::FeId;
using mapping::FeKind;
using Bytes = std::vector<std::uint8_t>;

constexpr NodeId kId{0x20};

Bytes bytes(const CanFrame& f) { return Bytes(f.data.begin(), f.data.begin() + f.dlc); }

FeId joystick(std::uint8_t n) { return {FeKind::Joystick, n}; }
FeId pedal(std::uint8_t n) { return {FeKind::FootPedal, n}; }
FeId encoder(std::uint8_t n) { return {FeKind::Encoder, n}; }
FeId wheel(std::uint8_t n) { return {FeKind::Wheel, n}; }
FeId buttons(std::uint8_t n) { return {FeKind::ButtonCluster, n}; }
FeId indicators(std::uint8_t n) { return {FeKind::IndicatorCluster, n}; }
FeId display(std::uint8_t n) { return {FeKind::Display, n}; }

// ------------------------------------------------------------------ 1000h (CiA 852 §11.2)

// CiA 852 §11.2 EXAMPLE: joystick with buttons and memory, wheel and push-buttons give the specific
// functionality 1001 1001b and I/O functionality 0101b; with M = 1 (Table 8) and profile 0191h.
TEST(OeDeviceType, Section11_2WorkedExample) {
  const std::uint32_t v = device_type_for({joystick(1), wheel(1), buttons(1)});
  EXPECT_EQ(v >> 24, 0b1001'1001u);
  EXPECT_EQ((v >> 23) & 1u, 1u);
  EXPECT_EQ((v >> 16) & 0xFu, 0b0101u);
  EXPECT_EQ(v & 0xFFFFu, 0x0191u);
  EXPECT_EQ(v, 0x99850191u);
}

// CiA 852 Table 8, one row at a time and in combination.
TEST(OeDeviceType, Table8Rows) {
  EXPECT_EQ(device_type_for({joystick(1)}, {joystick(1)}), 0x81840191u);  // joystick: X1X0
  EXPECT_EQ(device_type_for({joystick(3)}), 0x81850191u);                 // with buttons: X1X1
  EXPECT_EQ(device_type_for({pedal(16)}), 0x82840191u);
  EXPECT_EQ(device_type_for({encoder(2)}), 0x84840191u);
  EXPECT_EQ(device_type_for({wheel(8)}), 0x88840191u);
  EXPECT_EQ(device_type_for({buttons(1)}), 0x90810191u);
  EXPECT_EQ(device_type_for({indicators(1)}), 0xA0820191u);
  EXPECT_EQ(device_type_for({display(1)}), 0xC08A0191u);
  // Every FE: all specific bits, all four I/O bits.
  EXPECT_EQ(device_type_for({joystick(1), pedal(1), encoder(1), wheel(1), buttons(1), indicators(1), display(1)}),
            0xFF8F0191u);
  // One joystick without buttons does not clear what another joystick with buttons sets.
  EXPECT_EQ(device_type_for({joystick(1), joystick(2)}, {joystick(1)}), 0x81850191u);
}

// ------------------------------------------------------------------ the device, frame by frame

class OeDeviceTest : public ::testing::Test {
 protected:
  void make(std::vector<FeId> fes, std::uint16_t host_node = 0, std::uint16_t host_ms = 0,
            std::filesystem::path store = {}) {
    OeDeviceConfig c;
    c.store_path = std::move(store);
    c.node_id = kId;
    c.identity = {.vendor = 0x1234, .product = 0x852, .revision = 0x10000, .serial = 7};
    c.heartbeat_ms = 0;  // no heartbeat frames to filter in these tests
    c.fes = std::move(fes);
    c.host_node = host_node;
    c.host_heartbeat_ms = host_ms;
    dev = std::make_unique<OeDevice>(std::move(c), [this](const CanFrame& f) { out.push_back(f); });
    dev->on_output([this](FeId fe, oegw::gateway::FieldRef r, std::int64_t v, oegw::canopen::TimePoint) {
      outputs.emplace_back(fe, oegw::gateway::field_name(fe, r), v);
    });
    dev->start(now);
    out.clear();
  }
  std::vector<CanFrame> rx(std::uint32_t id, std::initializer_list<std::uint8_t> b) {
    out.clear();
    dev->on_frame(CanFrame(id, b), now);
    return out;
  }
  std::vector<CanFrame> nmt(std::uint8_t cs) { return rx(0x000, {cs, kId.value()}); }
  void sdo_ok(std::uint16_t index, std::uint8_t sub, const Bytes& data) {
    const auto cs = static_cast<std::uint8_t>(0x23 | ((4 - data.size()) << 2));
    Bytes f{cs, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0};
    std::copy(data.begin(), data.end(), f.begin() + 4);
    out.clear();
    dev->on_frame(CanFrame(0x600 + kId.value(), std::span<const std::uint8_t>(f)), now);
    const auto r = frames_with_id(0x580 + kId.value());
    ASSERT_EQ(r.size(), 1u);
    ASSERT_EQ(r[0].data[0], 0x60) << std::hex << index << ":" << int(sub) << " " << r[0].to_string();
  }
  std::vector<CanFrame> frames_with_id(std::uint32_t id) const {
    std::vector<CanFrame> r;
    for (const auto& f : out)
      if (f.id == id) r.push_back(f);
    return r;
  }
  ObjectDictionary& od() { return dev->od(); }
  std::uint32_t u32(std::uint16_t i, std::uint8_t s) { return od().get<std::uint32_t>(i, s); }
  std::uint8_t u8(std::uint16_t i, std::uint8_t s) { return od().get<std::uint8_t>(i, s); }

  TimePoint now{std::chrono::seconds(10)};
  std::vector<CanFrame> out;
  std::vector<std::tuple<FeId, std::string, std::int64_t>> outputs;
  std::unique_ptr<OeDevice> dev;
};

// CiA 852 §11.2 and CiA 301 1000h: the Node publishes the computed value.
TEST_F(OeDeviceTest, DeviceTypeObjectHoldsTheComputedValue) {
  make({joystick(1), wheel(1), buttons(1)});
  EXPECT_EQ(u32(0x1000, 0), 0x99850191u);
  // CiA 852 §11.4: all four 1018h sub-indexes.
  EXPECT_EQ(u32(0x1018, 1), 0x1234u);
  EXPECT_EQ(u32(0x1018, 2), 0x852u);
  EXPECT_EQ(u32(0x1018, 3), 0x10000u);
  EXPECT_EQ(u32(0x1018, 4), 7u);
  EXPECT_NE(od().find(0x1029), nullptr);  // §11.5 / Annex A: error behaviour
  EXPECT_NE(od().find(0x1017), nullptr);  // Annex A: producer heartbeat time, mandatory
}

// CiA 852 clause 12 categories ("Mandatory, if joystick supported (see 1000h)"): the objects and
// PDOs of the configured FE kinds — every instance of the kind the default PDOs map, the
// unconfigured ones at 0 (docs/design/cia852-decisions.md) — and nothing of the other kinds.
TEST_F(OeDeviceTest, ObjectsAndPdosOfTheConfiguredKinds) {
  make({joystick(2), indicators(1)});
  // 6000h: the memory and button bytes of joysticks 1..16 (subs 1..20h); joystick 2's are 3, 4.
  ASSERT_NE(od().find(0x6000), nullptr);
  EXPECT_EQ(u8(0x6000, 0), 0x20);
  for (std::uint8_t s = 1; s <= 0x20; ++s) EXPECT_NE(od().find(0x6000, s), nullptr) << int(s);
  EXPECT_EQ(od().find(0x6000, 0x21), nullptr);  // no pedal
  EXPECT_EQ(od().find(0x6000, 1)->name, "joystick 1 memory (not configured)");
  EXPECT_EQ(od().find(0x6000, 3)->name, "joystick 2 memory");
  std::vector<std::uint8_t> tmp;
  EXPECT_EQ(od().read(0x6000, 1, tmp), canopen::SdoAbortCode::None);
  EXPECT_EQ(tmp, (Bytes{0}));
  // 6401h: x/y/z of joysticks 1..16 = subs 1..30h.
  EXPECT_EQ(u8(0x6401, 0), 0x30);
  EXPECT_EQ(od().find(0x6401, 0x31), nullptr);
  for (std::uint8_t s = 1; s <= 0x30; ++s) {
    const auto* so = od().find(0x6401, s);
    ASSERT_NE(so, nullptr);
    EXPECT_EQ(so->type, canopen::DataType::Integer16);
    EXPECT_EQ(so->access, canopen::Access::ReadOnly);
    EXPECT_TRUE(so->pdo_mappable);
  }
  EXPECT_NE(od().find(0x6423), nullptr);
  EXPECT_EQ(od().find(0x6120), nullptr);
  EXPECT_EQ(od().find(0x6411), nullptr);
  EXPECT_EQ(od().find(0x6443), nullptr);
  EXPECT_EQ(od().find(0x6444), nullptr);
  // Indicators: 6200h rw mappable for clusters 1..8 (01h..40h); 6206h default FFh (every line;
  // docs/design/cia852-decisions.md: Table 6 prints 01h), 6207h default 0 (Table 6), for the
  // configured cluster 1 only.
  for (std::uint8_t s = 1; s <= 8; ++s) {
    ASSERT_NE(od().find(0x6200, s), nullptr);
    EXPECT_EQ(od().find(0x6200, s)->access, canopen::Access::ReadWrite);
    EXPECT_TRUE(od().find(0x6200, s)->pdo_mappable);
    EXPECT_EQ(u8(0x6206, s), 0xFF);
    EXPECT_EQ(u8(0x6207, s), 0x00);
  }
  EXPECT_NE(od().find(0x6200, 9), nullptr);
  EXPECT_NE(od().find(0x6200, 0x40), nullptr);
  EXPECT_EQ(od().find(0x6200, 0x41), nullptr);
  EXPECT_EQ(od().find(0x6206, 9), nullptr);
  EXPECT_NE(od().find(0x1016), nullptr);  // §8.3: outputs need the heartbeat consumer
  // PDOs: TPDO 1, 5..19 (joysticks, §12.2.1/§12.2.2) and RPDO 1, 5..11 (indicator clusters).
  std::vector<std::uint16_t> pdo_objects;
  for (const auto& [i, o] : od().objects())
    if (i >= 0x1400 && i <= 0x1BFF) pdo_objects.push_back(i);
  std::vector<std::uint16_t> want{0x1400, 0x1404, 0x1405, 0x1406, 0x1407, 0x1408, 0x1409, 0x140A, 0x1600,
                                  0x1604, 0x1605, 0x1606, 0x1607, 0x1608, 0x1609, 0x160A, 0x1800};
  for (std::uint16_t i = 0x1804; i <= 0x1812; ++i) want.push_back(i);
  want.push_back(0x1A00);
  for (std::uint16_t i = 0x1A04; i <= 0x1A12; ++i) want.push_back(i);
  EXPECT_EQ(pdo_objects, want);
}

TEST_F(OeDeviceTest, InputOnlyDeviceHasNoConsumerAndButtonsOnlyNo6423) {
  make({buttons(3)});
  EXPECT_EQ(od().find(0x1016), nullptr);
  EXPECT_EQ(od().find(0x6423), nullptr);  // no analogue input FE
  EXPECT_EQ(od().find(0x6401), nullptr);
  // Clusters 1..8 (31h..70h): TPDO 34..41 map them all.
  EXPECT_EQ(u8(0x6000, 0), 0x70);
  EXPECT_EQ(od().find(0x6000, 0x30), nullptr);
  EXPECT_NE(od().find(0x6000, 0x31), nullptr);
}

// CiA 852 §12.2.1 Tables 10 and 12: TPDO 1 of joystick 1.
TEST_F(OeDeviceTest, Tpdo1Defaults) {
  make({joystick(1)});
  EXPECT_EQ(u8(0x1800, 0), 6);                    // sub 0 within 02h..06h
  EXPECT_EQ(u32(0x1800, 1), 0x80000180u + 0x20);  // 8000 0180h + node-ID: disabled
  EXPECT_EQ(u8(0x1800, 2), 0xFF);
  EXPECT_EQ(od().get<std::uint16_t>(0x1800, 3), 0);
  EXPECT_EQ(od().get<std::uint16_t>(0x1800, 5), 0);
  EXPECT_EQ(u8(0x1800, 6), 0);
  EXPECT_EQ(u8(0x1A00, 0), 5);
  EXPECT_EQ(u32(0x1A00, 1), 0x64010110u);
  EXPECT_EQ(u32(0x1A00, 2), 0x64010210u);
  EXPECT_EQ(u32(0x1A00, 3), 0x64010310u);
  EXPECT_EQ(u32(0x1A00, 4), 0x60000108u);
  EXPECT_EQ(u32(0x1A00, 5), 0x60000208u);
  // The default follows the node-ID default of CiA 301 ($NODEID in the EDS).
  EXPECT_EQ(od().find(0x1800, 1)->default_value, canopen::encode<std::uint32_t>(0x800001A0u));
}

// CiA 852 §12.2.2: TPDO 5..19 = joysticks 2..16, COB-ID 8000 0000h, mapping as Table 1.
TEST_F(OeDeviceTest, JoystickTpdos5To19) {
  make({joystick(2), joystick(16)});
  EXPECT_EQ(u32(0x1804, 1), 0x80000000u);  // TPDO 5
  EXPECT_EQ(u8(0x1804, 2), 0xFF);
  EXPECT_EQ(u8(0x1A04, 0), 5);
  EXPECT_EQ(u32(0x1A04, 1), 0x64010410u);
  EXPECT_EQ(u32(0x1A04, 3), 0x64010610u);
  EXPECT_EQ(u32(0x1A04, 4), 0x60000308u);
  EXPECT_EQ(u32(0x1A04, 5), 0x60000408u);
  EXPECT_EQ(u32(0x1812, 1), 0x80000000u);  // TPDO 19 = joystick 16
  EXPECT_EQ(u32(0x1A12, 1), 0x64012E10u);  // Table 1: 2Eh..30h
  EXPECT_EQ(u32(0x1A12, 3), 0x64013010u);
  EXPECT_EQ(u32(0x1A12, 4), 0x60001F08u);
  EXPECT_EQ(u32(0x1A12, 5), 0x60002008u);
  // Joystick 1 not configured: TPDO 1 still exists (joystick supported, §12.2.1).
  EXPECT_EQ(u32(0x1A00, 1), 0x64010110u);
}

// CiA 852 §12.2.3 Table 16 (TPDO 20: pedals 1, 2), §12.2.5 Table 20 (TPDO 28: encoders 1, 2),
// §12.2.7 Table 24 (TPDO 32: wheels 1..4), §12.2.9 Table 28 (TPDO 34: push-button cluster 1).
TEST_F(OeDeviceTest, PedalEncoderWheelButtonTpdos) {
  make({pedal(1), pedal(2), pedal(4), encoder(1), encoder(2), wheel(1), wheel(2), wheel(3), wheel(4), buttons(1),
        buttons(8)});
  // TPDO 20 = 1813h/1A13h (TPDO n at 1800h + n − 1, CiA 301).
  EXPECT_EQ(u32(0x1813, 1), 0x80000000u);
  EXPECT_EQ(u8(0x1813, 2), 0xFF);
  EXPECT_EQ(u8(0x1A13, 0), 4);
  EXPECT_EQ(u32(0x1A13, 1), 0x60002108u);
  EXPECT_EQ(u32(0x1A13, 2), 0x64013110u);
  EXPECT_EQ(u32(0x1A13, 3), 0x60002208u);
  EXPECT_EQ(u32(0x1A13, 4), 0x64013210u);
  // TPDO 21: pedals 3, 4 — only pedal 4 configured; pedal 3's entries stay at subs 1, 2.
  EXPECT_EQ(u8(0x1A14, 0), 4);
  EXPECT_EQ(u32(0x1A14, 1), 0x60002308u);
  EXPECT_EQ(u32(0x1A14, 2), 0x64013310u);
  EXPECT_EQ(u32(0x1A14, 3), 0x60002408u);
  EXPECT_EQ(u32(0x1A14, 4), 0x64013410u);
  // TPDO 28.
  EXPECT_EQ(u32(0x181B, 1), 0x80000000u);
  EXPECT_EQ(u8(0x1A1B, 0), 2);
  EXPECT_EQ(u32(0x1A1B, 1), 0x61208120u);
  EXPECT_EQ(u32(0x1A1B, 2), 0x61208220u);
  // TPDO 32.
  EXPECT_EQ(u8(0x1A1F, 0), 4);
  EXPECT_EQ(u32(0x1A1F, 1), 0x64014110u);
  EXPECT_EQ(u32(0x1A1F, 4), 0x64014410u);
  EXPECT_EQ(u32(0x1A20, 1), 0x64014510u);  // TPDO 33: wheels 5..8, none configured
  // TPDO 34: 6000 31h..38h; TPDO 41: push-button cluster 8 = 6000 69h..70h.
  EXPECT_EQ(u8(0x1A21, 0), 8);
  EXPECT_EQ(u32(0x1A21, 1), 0x60003108u);
  EXPECT_EQ(u32(0x1A21, 8), 0x60003808u);
  EXPECT_EQ(u32(0x1828, 1), 0x80000000u);
  EXPECT_EQ(u32(0x1A28, 1), 0x60006908u);
  EXPECT_EQ(u32(0x1A28, 8), 0x60007008u);
}

// CiA 852 §12.2.11 Tables 30/32 (RPDO 1: indicators 1), §12.2.12 (RPDO 5..11), §12.2.13 Tables
// 34/36 (RPDO 2: display 1 parameters 1..4), §12.2.14 (RPDO 4, 12, 13..34).
TEST_F(OeDeviceTest, IndicatorAndDisplayRpdos) {
  make({indicators(1), indicators(8), display(1), display(2), display(8)});
  EXPECT_EQ(u8(0x1400, 0), 5);  // COB-ID, type, event timer
  EXPECT_EQ(u32(0x1400, 1), 0x80000000u);
  EXPECT_EQ(u8(0x1400, 2), 0xFF);
  EXPECT_EQ(od().get<std::uint16_t>(0x1400, 5), 0);
  EXPECT_EQ(u8(0x1600, 0), 8);
  EXPECT_EQ(u32(0x1600, 1), 0x62000108u);
  EXPECT_EQ(u32(0x1600, 8), 0x62000808u);
  EXPECT_EQ(u32(0x160A, 1), 0x62003908u);  // RPDO 11 = indicator cluster 8
  EXPECT_EQ(u32(0x1401, 1), 0x80000000u);  // RPDO 2
  EXPECT_EQ(u8(0x1601, 0), 4);
  EXPECT_EQ(u32(0x1601, 1), 0x64110110u);
  EXPECT_EQ(u32(0x1601, 4), 0x64110410u);
  EXPECT_EQ(u32(0x1603, 1), 0x64110510u);  // RPDO 4: parameters 5..8
  EXPECT_EQ(u32(0x160B, 4), 0x64110C10u);  // RPDO 12: parameters 9..12
  EXPECT_EQ(u32(0x160C, 1), 0x64110D10u);  // RPDO 13: display 2 parameter 1
  EXPECT_EQ(u32(0x1620, 4), 0x64116010u);  // RPDO 33: display 8 parameter 12 (sub 60h)
  EXPECT_EQ(od().find(0x1402), nullptr);   // RPDO 3 unused by CiA 852
  EXPECT_EQ(od().find(0x1621), nullptr);   // RPDO 34 unused (see header)
  // Display objects: 6443h default 01h, 6444h default 0 (Table 7).
  EXPECT_EQ(u8(0x6443, 0x60), 1);
  EXPECT_EQ(od().get<std::int32_t>(0x6444, 0x60), 0);
  EXPECT_NE(od().find(0x6411, 0x18), nullptr);  // display 2 = 0Dh..18h
  EXPECT_EQ(od().find(0x6411, 0x19)->name, "display 3 parameter 1 (not configured)");
  EXPECT_EQ(od().find(0x6443, 0x19), nullptr);  // no error mode for display 3
}

// CiA 852 §8.6: entering operational with 6423h FALSE sends EMCY 0080h and stays operational.
TEST_F(OeDeviceTest, Emcy0080OnOperationalWith6423False) {
  make({joystick(1)});
  const auto r = nmt(0x01);
  ASSERT_EQ(dev->node().state(), NmtState::Operational);
  const auto e = frames_with_id(0x80 + kId.value());
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(bytes(e[0]), (Bytes{0x80, 0x00, 0x01, 0, 0, 0, 0, 0}));
  EXPECT_EQ(u8(0x1001, 0), 0x01);  // generic bit only (§11.3: no profile-specific bit)
  // Still operational after the EMCY was processed and time passed (1029h not involved).
  now += 1s;
  dev->advance(now);
  EXPECT_EQ(dev->node().state(), NmtState::Operational);
  // Pre-operational clears it (error reset); operational again re-sends it.
  nmt(0x80);
  auto reset = frames_with_id(0x80 + kId.value());
  ASSERT_EQ(reset.size(), 1u);
  EXPECT_EQ(bytes(reset[0]), (Bytes{0, 0, 0, 0, 0, 0, 0, 0}));
  nmt(0x01);
  EXPECT_EQ(frames_with_id(0x80 + kId.value()).size(), 1u);
  // The host enables analogue interrupts: error reset.
  sdo_ok(0x6423, 0, {1});
  reset = frames_with_id(0x80 + kId.value());
  ASSERT_EQ(reset.size(), 1u);
  EXPECT_EQ(reset[0].data[0], 0);
  EXPECT_EQ(reset[0].data[1], 0);
}

TEST_F(OeDeviceTest, NoEmcy0080When6423TrueOrAbsent) {
  make({joystick(1)});
  sdo_ok(0x6423, 0, {1});
  nmt(0x01);
  EXPECT_TRUE(frames_with_id(0xA0).empty());
  make({buttons(1)});  // no analogue input: 6423h absent, nothing to warn about
  nmt(0x01);
  EXPECT_TRUE(frames_with_id(0xA0).empty());
}

// set_input → the event-driven TPDO on the bus with the Table 12 layout.
TEST_F(OeDeviceTest, SetInputSendsTpdo1Bytes) {
  make({joystick(1)});
  sdo_ok(0x1800, 1, canopen::encode<std::uint32_t>(0x1A0));
  sdo_ok(0x6423, 0, {1});
  nmt(0x01);
  auto t = frames_with_id(0x1A0);  // §12.1: every TPDO once on entering operational
  ASSERT_EQ(t.size(), 1u);
  EXPECT_EQ(bytes(t[0]), (Bytes(8, 0)));
  out.clear();
  ASSERT_TRUE(dev->set_input(joystick(1), "x", 1000, now));
  t = frames_with_id(0x1A0);
  ASSERT_EQ(t.size(), 1u);
  EXPECT_EQ(bytes(t[0]), (Bytes{0xE8, 0x03, 0, 0, 0, 0, 0, 0}));
  out.clear();
  ASSERT_TRUE(dev->set_input(joystick(1), "z", -2, now));
  ASSERT_TRUE(dev->set_input(joystick(1), "buttons[2]", 1, now));
  ASSERT_TRUE(dev->set_input(joystick(1), "memory_y", 1, now));
  t = frames_with_id(0x1A0);
  ASSERT_EQ(t.size(), 3u);
  EXPECT_EQ(bytes(t[2]), (Bytes{0xE8, 0x03, 0, 0, 0xFE, 0xFF, 0x02, 0x02}));
  EXPECT_EQ(dev->get(joystick(1), "buttons[2]"), 1);
  EXPECT_EQ(dev->get(joystick(1), "z"), -2);
  // Refused: unknown field, out of range, output FE, unconfigured FE, non-bit value for a bit.
  EXPECT_FALSE(dev->set_input(joystick(1), "w", 1, now));
  EXPECT_FALSE(dev->set_input(joystick(1), "x", 40000, now));
  EXPECT_FALSE(dev->set_input(joystick(2), "x", 1, now));
  EXPECT_FALSE(dev->set_input(joystick(1), "buttons[1]", 2, now));
}

// CiA 401 6423h FALSE: an axis change alone raises no TPDO, but the value is current in the
// dictionary and in the next TPDO sent for a digital change.
TEST_F(OeDeviceTest, AnalogueInputsSilentWhile6423False) {
  make({joystick(1)});
  sdo_ok(0x1800, 1, canopen::encode<std::uint32_t>(0x1A0));
  nmt(0x01);
  out.clear();
  ASSERT_TRUE(dev->set_input(joystick(1), "y", 300, now));
  EXPECT_TRUE(frames_with_id(0x1A0).empty());
  EXPECT_EQ(od().get<std::int16_t>(0x6401, 2), 300);
  ASSERT_TRUE(dev->set_input(joystick(1), "buttons[1]", 1, now));
  const auto t = frames_with_id(0x1A0);
  ASSERT_EQ(t.size(), 1u);
  EXPECT_EQ(bytes(t[0]), (Bytes{0, 0, 0x2C, 0x01, 0, 0, 0, 0x01}));
}

// Push-button cluster 2 → TPDO 35 (§12.2.10), switch[10] = byte 1 bit 1 (Figure 7).
TEST_F(OeDeviceTest, ButtonClusterTpdo) {
  make({buttons(2)});
  sdo_ok(0x1822, 1, canopen::encode<std::uint32_t>(0x290));  // TPDO 35
  nmt(0x01);
  out.clear();
  ASSERT_TRUE(dev->set_input(buttons(2), "switch[10]", 1, now));
  const auto t = frames_with_id(0x290);
  ASSERT_EQ(t.size(), 1u);
  EXPECT_EQ(bytes(t[0]), (Bytes{0, 0x02, 0, 0, 0, 0, 0, 0}));
}

// The FE model's sink: a cluster's 64 switches as one slot value land in its eight 6000h bytes
// (switch k = bit (k−1) mod 8 of byte ⌊(k−1)/8⌋), one TPDO 35 for the whole change; a joystick's
// buttons and memory bytes and its axes likewise.
TEST_F(OeDeviceTest, MirroredSlotsFillEveryByteOfTheirEntries) {
  make({buttons(2), joystick(1)});
  sdo_ok(0x1822, 1, canopen::encode<std::uint32_t>(0x290));  // TPDO 35
  nmt(0x01);
  out.clear();
  const std::uint64_t switches = (std::uint64_t{1} << 9) | (std::uint64_t{1} << 63) | (std::uint64_t{0xA5} << 16);
  dev->mirror_input(buttons(2), oegw::gateway::FeSlot::Switches, static_cast<std::int64_t>(switches), now);
  const auto t = frames_with_id(0x290);
  ASSERT_EQ(t.size(), 1u);
  EXPECT_EQ(bytes(t[0]), (Bytes{0, 0x02, 0xA5, 0, 0, 0, 0, 0x80}));
  EXPECT_EQ(od().get<std::uint8_t>(0x6000, 0x3A), 0x02);  // cluster 2 = subs 39h..40h
  EXPECT_EQ(od().get<std::uint8_t>(0x6000, 0x40), 0x80);
  EXPECT_EQ(dev->get(buttons(2), "switch[64]"), 1);
  EXPECT_EQ(dev->get(buttons(2), "switch[63]"), 0);
  dev->mirror_input(joystick(1), oegw::gateway::FeSlot::Buttons, 0x81, now);
  dev->mirror_input(joystick(1), oegw::gateway::FeSlot::Memory, 0x05, now);
  dev->mirror_input(joystick(1), oegw::gateway::FeSlot::Z, -32768, now);
  EXPECT_EQ(od().get<std::uint8_t>(0x6000, 0x02), 0x81);
  EXPECT_EQ(od().get<std::uint8_t>(0x6000, 0x01), 0x05);
  EXPECT_EQ(od().get<std::int16_t>(0x6401, 0x03), -32768);
  // An unchanged slot writes nothing: no TPDO.
  out.clear();
  dev->mirror_input(buttons(2), oegw::gateway::FeSlot::Switches, static_cast<std::int64_t>(switches), now);
  EXPECT_TRUE(frames_with_id(0x290).empty());
}

// Host writes RPDO 1 (indicators) and SDO 6411h (display) → on_output per changed field.
TEST_F(OeDeviceTest, HostWritesReachOnOutput) {
  make({indicators(1), display(1)});
  sdo_ok(0x1400, 1, canopen::encode<std::uint32_t>(0x220));
  nmt(0x01);
  outputs.clear();
  rx(0x220, {0x05, 0x80, 0, 0, 0, 0, 0, 0});
  using O = std::tuple<FeId, std::string, std::int64_t>;
  EXPECT_EQ(outputs, (std::vector<O>{{indicators(1), "indicator[1]", 1},
                                     {indicators(1), "indicator[3]", 1},
                                     {indicators(1), "indicator[16]", 1}}));
  outputs.clear();
  rx(0x220, {0x04, 0x80, 0, 0, 0, 0, 0, 0});  // only indicator 1 changes
  EXPECT_EQ(outputs, (std::vector<O>{{indicators(1), "indicator[1]", 0}}));
  outputs.clear();
  sdo_ok(0x6411, 3, canopen::encode<std::int16_t>(-1234));
  EXPECT_EQ(outputs, (std::vector<O>{{display(1), "parameter[3]", -1234}}));
  EXPECT_EQ(dev->get(display(1), "parameter[3]"), -1234);
}

// CiA 401 6206h/6207h and 6443h/6444h applied when the host's heartbeat (1016h) times out.
TEST_F(OeDeviceTest, HostHeartbeatLostAppliesErrorValues) {
  make({indicators(1), display(1)}, /*host_node=*/1, /*host_ms=*/100);
  EXPECT_EQ(u32(0x1016, 1), 0x00010064u);
  nmt(0x01);
  sdo_ok(0x6200, 1, {0xFF});  // indicators 1..8 on; 6206h:01 = FFh (default) → all 8 react
  sdo_ok(0x6207, 2, {0x0F});  // byte 2: error value 0Fh...
  sdo_ok(0x6206, 2, {0xF0});  // ...for bits 4..7 only
  sdo_ok(0x6200, 2, {0x3C});
  sdo_ok(0x6411, 1, canopen::encode<std::int16_t>(500));
  sdo_ok(0x6444, 1, canopen::encode<std::int32_t>(-7));
  sdo_ok(0x6411, 2, canopen::encode<std::int16_t>(300));
  sdo_ok(0x6443, 2, {0});  // parameter 2 keeps its value
  rx(0x701, {0x05});       // host heartbeat: monitoring starts
  outputs.clear();
  now += 50ms;
  dev->advance(now);
  EXPECT_TRUE(outputs.empty());
  now += 100ms;
  dev->advance(now);
  EXPECT_EQ(u8(0x6200, 1), 0x00);  // every lamp of the byte at its error value
  EXPECT_EQ(u8(0x6200, 2), 0x0C);  // (3Ch & 0Fh) | (0Fh & F0h)
  EXPECT_EQ(od().get<std::int16_t>(0x6411, 1), -7);
  EXPECT_EQ(od().get<std::int16_t>(0x6411, 2), 300);
  EXPECT_EQ(od().get<std::int16_t>(0x6411, 3), 0);  // already at its error value 0
  using O = std::tuple<FeId, std::string, std::int64_t>;
  EXPECT_EQ(outputs, (std::vector<O>{{indicators(1), "indicator[1]", 0},
                                     {indicators(1), "indicator[2]", 0},
                                     {indicators(1), "indicator[3]", 0},
                                     {indicators(1), "indicator[4]", 0},
                                     {indicators(1), "indicator[5]", 0},
                                     {indicators(1), "indicator[6]", 0},
                                     {indicators(1), "indicator[7]", 0},
                                     {indicators(1), "indicator[8]", 0},
                                     {indicators(1), "indicator[13]", 0},
                                     {indicators(1), "indicator[14]", 0},
                                     {display(1), "parameter[1]", -7}}));
  // CiA 301: the consumer timeout also reported EMCY 8130h.
  EXPECT_TRUE(dev->node().emcy().active(0x8130));
}

// The TPDOs a downstream frame sends (end_batch) advance the Node, and that
// call can be the one that notices the host's heartbeat time-out. The error values must follow in
// that same call, not at the next timer wake-up (which can be a heartbeat period later).
TEST_F(OeDeviceTest, HostHeartbeatLossNoticedWhileSendingInputTpdosAppliesTheErrorValuesAtOnce) {
  make({joystick(1), indicators(1)}, /*host_node=*/1, /*host_ms=*/100);
  sdo_ok(0x6423, 0, {1});
  nmt(0x01);
  sdo_ok(0x6200, 1, {0x01});  // indicator 1 on; 6206h:01 = FFh, 6207h:01 = 0: error value off
  rx(0x701, {0x05});          // host heartbeat: monitoring starts
  outputs.clear();
  now += 150ms;        // past the consumer time, no timer call in between
  dev->begin_batch();  // a downstream frame moves the joystick
  ASSERT_TRUE(dev->set_input(joystick(1), "x", 1000, now));
  dev->end_batch(now);
  EXPECT_TRUE(dev->node().emcy().active(0x8130));
  EXPECT_EQ(u8(0x6200, 1), 0x00) << "the error value, in the same call";
  using O = std::tuple<FeId, std::string, std::int64_t>;
  EXPECT_EQ(outputs, (std::vector<O>{{indicators(1), "indicator[1]", 0}}));
}

// The host's heartbeat comes back in the state it had: that is the evidence that ends EMCY 8130h
// (error reset), and a second loss applies the error values again.
TEST_F(OeDeviceTest, AReturningHostHeartbeatClears8130hAndASecondLossAppliesTheErrorValuesAgain) {
  make({indicators(1)}, /*host_node=*/1, /*host_ms=*/100);
  nmt(0x01);
  rx(0x701, {0x05});
  sdo_ok(0x6200, 1, {0x01});
  now += 150ms;
  dev->advance(now);
  ASSERT_TRUE(dev->node().emcy().active(0x8130));
  ASSERT_EQ(u8(0x6200, 1), 0x00);
  nmt(0x01);                            // the host restarts us (1029h took us to pre-op)
  const auto back = rx(0x701, {0x05});  // the host is back, still operational
  EXPECT_FALSE(dev->node().emcy().active(0x8130));
  bool reset_sent = false;
  for (const auto& f : back)
    reset_sent = reset_sent || (f.id == 0x80 + kId.value() && f.data[0] == 0 && f.data[1] == 0);
  EXPECT_TRUE(reset_sent) << "EMCY error reset upstream";
  sdo_ok(0x6200, 1, {0x01});
  now += 150ms;  // lost again
  dev->advance(now);
  EXPECT_TRUE(dev->node().emcy().active(0x8130));
  EXPECT_EQ(u8(0x6200, 1), 0x00) << "the error value again";
}

// Table 37 7000h for sub-device faults; node-ID and name in the manufacturer bytes.
TEST_F(OeDeviceTest, SubdeviceFaultEmcy) {
  make({joystick(1)});
  sdo_ok(0x6423, 0, {1});
  nmt(0x01);
  out.clear();
  dev->raise_subdevice_fault("grip", NodeId{0x11}, now);
  auto e = frames_with_id(0xA0);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(bytes(e[0]), (Bytes{0x00, 0x70, 0x01, 0x11, 'g', 'r', 'i', 'p'}));
  out.clear();
  dev->raise_subdevice_fault("pedal", NodeId{0x12}, now);
  e = frames_with_id(0xA0);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(bytes(e[0]), (Bytes{0x00, 0x70, 0x01, 0x12, 'p', 'e', 'd', 'a'}));
  out.clear();
  dev->raise_subdevice_fault("pedal", NodeId{0x12}, now);  // already known: nothing
  EXPECT_TRUE(out.empty());
  dev->clear_subdevice_fault(NodeId{0x11}, now);
  e = frames_with_id(0xA0);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(bytes(e[0]), (Bytes{0x00, 0x00, 0x01, 0x11, 'g', 'r', 'i', 'p'}));  // 0x12 still faulty
  out.clear();
  dev->clear_subdevice_fault(NodeId{0x12}, now);
  e = frames_with_id(0xA0);
  ASSERT_EQ(e.size(), 1u);
  // The last one: the error register clear, the recovered node named as before.
  EXPECT_EQ(bytes(e[0]), (Bytes{0x00, 0x00, 0x00, 0x12, 'p', 'e', 'd', 'a'}));
  EXPECT_TRUE(dev->faulty_subdevices().empty());
}

// The extra 7000h of a second faulty sub-device and the 0000h naming a recovered one go through
// the EMCY producer: 1015h holds them back (100 ms here), 1003h records the 7000h with the
// node-ID in bits 16..23, 1001h stays as the active 7000h set it.
TEST_F(OeDeviceTest, ExtraSubdeviceEmcysHonourTheInhibitTimeAndLandIn1003h) {
  make({joystick(1)});
  sdo_ok(0x6423, 0, {1});
  sdo_ok(0x1015, 0, canopen::encode<std::uint16_t>(1000));
  nmt(0x01);
  out.clear();
  dev->raise_subdevice_fault("grip", NodeId{0x11}, now);
  dev->raise_subdevice_fault("pedal", NodeId{0x12}, now);
  auto e = frames_with_id(0xA0);
  ASSERT_EQ(e.size(), 1u) << "the second 7000h waits for the inhibit time";
  EXPECT_EQ(bytes(e[0]), (Bytes{0x00, 0x70, 0x01, 0x11, 'g', 'r', 'i', 'p'}));
  EXPECT_EQ(dev->next_deadline(), now + 100ms);
  now += 99ms;
  dev->advance(now);
  EXPECT_EQ(frames_with_id(0xA0).size(), 1u);
  now += 1ms;
  dev->advance(now);
  e = frames_with_id(0xA0);
  ASSERT_EQ(e.size(), 2u);
  EXPECT_EQ(bytes(e[1]), (Bytes{0x00, 0x70, 0x01, 0x12, 'p', 'e', 'd', 'a'}));
  EXPECT_EQ(u8(0x1003, 0), 2u);
  EXPECT_EQ(u32(0x1003, 1), 0x00127000u);
  EXPECT_EQ(u32(0x1003, 2), 0x00117000u);
  EXPECT_EQ(u8(0x1001, 0), 0x01u);
  // grip recovers 10 ms later: its 0000h waits until 100 ms after the last EMCY.
  now += 10ms;
  dev->clear_subdevice_fault(NodeId{0x11}, now);
  EXPECT_EQ(frames_with_id(0xA0).size(), 2u);
  now += 90ms;
  dev->advance(now);
  e = frames_with_id(0xA0);
  ASSERT_EQ(e.size(), 3u);
  EXPECT_EQ(bytes(e[2]), (Bytes{0x00, 0x00, 0x01, 0x11, 'g', 'r', 'i', 'p'}));
  EXPECT_EQ(u8(0x1003, 0), 2u) << "an error reset is not recorded";
}

// Remote EMCY (oe_device.hpp): a sub-device's EMCY as the gateway's own — its code, the
// gateway's 1001h, then [node-ID, its register, its manufacturer bytes 0..2]; 1003h records
// code | node-ID << 16; 1001h unchanged. MCB-402 [CO4013 "Emergency Messages"] cable break on
// node 03h: 083 [8] 20 31 81 00 81 00 00 00.
TEST_F(OeDeviceTest, ForwardedSubdeviceEmcyCarriesItsCodeRegisterNodeAndBytes) {
  make({joystick(1)});
  sdo_ok(0x6423, 0, {1});
  nmt(0x01);
  out.clear();
  const canopen::EmcyMessage cable{NodeId{0x03}, 0x3120, 0x81, {0x00, 0x81, 0x00, 0x00, 0x00}};
  EXPECT_TRUE(dev->forward_subdevice_emcy(cable, now));
  auto e = frames_with_id(0xA0);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(bytes(e[0]), (Bytes{0x20, 0x31, 0x00, 0x03, 0x81, 0x00, 0x81, 0x00}));
  EXPECT_EQ(u8(0x1001, 0), 0x00u) << "a forward raises nothing on the gateway";
  EXPECT_EQ(u32(0x1003, 1), 0x00033120u);
  // The fault policy's 7000h follows; the sub-device's error reset is forwarded with the
  // gateway's register (7000h still active), and not recorded.
  dev->raise_subdevice_fault("left_grip", NodeId{0x03}, now);
  out.clear();
  EXPECT_TRUE(dev->forward_subdevice_emcy({NodeId{0x03}, 0x0000, 0x00, {}}, now));
  e = frames_with_id(0xA0);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(bytes(e[0]), (Bytes{0x00, 0x00, 0x01, 0x03, 0x00, 0x00, 0x00, 0x00}));
  EXPECT_EQ(u8(0x1003, 0), 2u);
  // Bytes 3..4 of the sub-device's manufacturer field do not fit.
  EXPECT_EQ(OeDevice::forwarded_msef({NodeId{0x11}, 0x1000, 0x00, {0x21, 0x00, 0xFF, 0xAA, 0xBB}}),
            (canopen::EmcyManufacturerField{0x11, 0x00, 0x21, 0x00, 0xFF}));
  // Stopped: the Node holds every EMCY back (CiA 301 Table 47).
  nmt(0x02);
  out.clear();
  (void)dev->forward_subdevice_emcy(cable, now);
  EXPECT_TRUE(frames_with_id(0xA0).empty());
}

// NMT reset node restores the defaults without observers (CiA 301 §7.3.2.2.1): the outputs that
// moved back are still reported, so the sub-devices' LEDs follow the dictionary.
TEST_F(OeDeviceTest, ResetNodeReportsOutputsBackToDefault) {
  make({indicators(2)});
  sdo_ok(0x6200, 9, {0x81});
  outputs.clear();
  nmt(0x81);
  EXPECT_EQ(u8(0x6200, 9), 0);
  using O = std::tuple<FeId, std::string, std::int64_t>;
  EXPECT_EQ(outputs, (std::vector<O>{{indicators(2), "indicator[1]", 0}, {indicators(2), "indicator[8]", 0}}));
}

// CiA 852 Tables 10/30: communication sub 0 is const; §8.5 variable mapping: the host remaps
// TPDO 1 by the CiA 301 procedure and the new layout goes out.
TEST_F(OeDeviceTest, CommSub0ConstAndVariableMapping) {
  make({joystick(1), indicators(1)});
  EXPECT_EQ(od().find(0x1800, 0)->access, canopen::Access::Const);
  EXPECT_EQ(od().find(0x1400, 0)->access, canopen::Access::Const);
  sdo_ok(0x1A00, 0, {0});
  sdo_ok(0x1A00, 1, canopen::encode<std::uint32_t>(0x60000208));
  sdo_ok(0x1A00, 0, {1});
  sdo_ok(0x1800, 1, canopen::encode<std::uint32_t>(0x1A0));
  nmt(0x01);
  out.clear();
  ASSERT_TRUE(dev->set_input(joystick(1), "buttons[8]", 1, now));
  const auto t = frames_with_id(0x1A0);
  ASSERT_EQ(t.size(), 1u);
  EXPECT_EQ(bytes(t[0]), (Bytes{0x80}));
}

// CiA 852 §8.6 / Annex A 1028h: with outputs, other nodes' EMCYs are received; not its own.
TEST_F(OeDeviceTest, EmcyConsumerWithOutputs) {
  make({display(1)});
  std::vector<canopen::EmcyMessage> got;
  dev->on_emcy([&](const canopen::EmcyMessage& m, TimePoint) { got.push_back(m); });
  EXPECT_EQ(u32(0x1028, 0x05), 0x85u);
  EXPECT_EQ(u32(0x1028, 0x20), 0x800000A0u);
  rx(0x85, {0x00, 0x50, 0x01, 1, 2, 3, 4, 5});
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].node.value(), 5);
  EXPECT_EQ(got[0].code, 0x5000);
  rx(0xA0, {0x00, 0x50, 0x01, 0, 0, 0, 0, 0});
  EXPECT_EQ(got.size(), 1u);
  make({joystick(1)});  // inputs only: no 1028h
  EXPECT_EQ(od().find(0x1028), nullptr);
}

// CiA 301 1010h: stored output values come back at power-on and are reported through on_output
// (the sub-devices must show them); inputs are read-only and never stored.
TEST_F(OeDeviceTest, StoredOutputsReportedAtStart) {
  const auto dir = std::filesystem::temp_directory_path() / ("oegw-oe-store-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  make({joystick(1), indicators(1)}, 0, 0, dir / "params.txt");
  sdo_ok(0x6200, 1, {0x03});
  sdo_ok(0x6423, 0, {1});
  ASSERT_TRUE(dev->set_input(joystick(1), "x", 77, now));
  sdo_ok(0x1010, 1, {0x73, 0x61, 0x76, 0x65});
  outputs.clear();
  make({joystick(1), indicators(1)}, 0, 0, dir / "params.txt");
  using O = std::tuple<FeId, std::string, std::int64_t>;
  EXPECT_EQ(outputs, (std::vector<O>{{indicators(1), "indicator[1]", 1}, {indicators(1), "indicator[2]", 1}}));
  EXPECT_EQ(u8(0x6423, 0), 1);
  EXPECT_EQ(dev->get(joystick(1), "x"), 0);
  std::filesystem::remove_all(dir);
}

// CiA 852 §9.1 instance ranges: duplicates count once, out-of-range instances are dropped.
TEST_F(OeDeviceTest, DuplicateAndOutOfRangeFesIgnored) {
  make({indicators(1), indicators(1), indicators(9), joystick(17), joystick(0)});
  EXPECT_EQ(dev->config().fes, (std::vector<FeId>{indicators(1)}));
  EXPECT_EQ(u32(0x1000, 0), 0xA0820191u);
  sdo_ok(0x6200, 1, {0x01});
  EXPECT_EQ(outputs.size(), 1u);  // one report, not two
}

}  // namespace
}  // namespace oegw::gateway
