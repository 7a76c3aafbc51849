// `oegw eds` describes the dictionary the running gateway has: the EDS written from the mapping
// file (upstream_eds, what `oegw eds` prints) equals the EDS of the Gateway's own device, built
// from the same file — for a joystick without buttons (CiA 852 Table 8: no digital-input bit in
// 1000h), output FEs the host may not command, and the full set of FE kinds.
#include <gtest/gtest.h>

#include <filesystem>
#include <regex>

#include <fmt/format.h>

#include "canopen/306/eds_reader.hpp"
#include "gateway/gateway.hpp"
#include "gateway/runtime_config.hpp"
#include "tests/fixtures/fixtures.hpp"

namespace {

using namespace oegw;

mapping::Config load(const std::string& yaml) {
  auto r = mapping::load_config_text(yaml, "test.yaml", gateway::driver_catalogue());
  if (!r.ok()) throw std::runtime_error(r.error_text());
  return *r.config;
}

// The value of `key` in section [name] of an EDS text.
std::string eds_value(const std::string& eds, const std::string& section, const std::string& key) {
  const auto at = eds.find("[" + section + "]\n");
  if (at == std::string::npos) return "";
  const auto end = eds.find("\n[", at + 1);
  const std::string body = eds.substr(at, end == std::string::npos ? std::string::npos : end - at);
  std::smatch m;
  if (!std::regex_search(body, m, std::regex("\n" + key + "=([^\n]*)"))) return "";
  return m[1];
}

const std::string kHead =
    "upstream: { interface: virtual, node_id: 0x20 }\n"
    "downstream: { interface: virtual }\n"
    "subdevices:\n"
    "  grip: { driver: elobau-mfg, node_id: 0x11 }\n"
    "  mcb: { driver: mcb402, node_id: 0x12, options: { button_bits: [1, 2, 3, 4, 5, 7, 6] } }\n";

void expect_eds_equals_device(const std::string& yaml) {
  const mapping::Config c = load(yaml);
  gateway::Gateway gw(c, {}, {});  // never started: its dictionary holds the defaults
  const std::string running = canopen::eds_text(gw.upstream().od(), gateway::eds_info(c, "oegw.eds"));
  const std::string written = gateway::upstream_eds(c, "oegw.eds");
  EXPECT_EQ(written, running);
  EXPECT_EQ(eds_value(written, "1000", "DefaultValue"),
            fmt::format("0x{:08X}", gw.upstream().od().get<std::uint32_t>(0x1000, 0)));
}

TEST(UpstreamEds, AJoystickWithoutButtonsHasNoDigitalInputBitInTheEdsAsInTheDevice) {
  const std::string yaml = kHead +
                           "functional_elements:\n"
                           "  joystick.1: { x: { signal: grip.x }, y: { signal: grip.y } }\n";
  expect_eds_equals_device(yaml);
  const mapping::Config c = load(yaml);
  // CiA 852 Table 8: "joystick" (no buttons) sets the analogue-input bit (18) only.
  const std::string dt = eds_value(gateway::upstream_eds(c, "oegw.eds"), "1000", "DefaultValue");
  ASSERT_FALSE(dt.empty());
  const auto v = std::stoul(dt, nullptr, 16);
  EXPECT_EQ(v & (1u << 16), 0u) << dt << ": digital input bit set for a joystick without buttons";
  EXPECT_NE(v & (1u << 18), 0u) << dt;
  EXPECT_EQ(v & 0xFFFFu, 0x0191u);
}

TEST(UpstreamEds, AJoystickWithButtonsSetsTheDigitalInputBit) {
  const std::string yaml = kHead +
                           "functional_elements:\n"
                           "  joystick.1:\n"
                           "    x: { signal: grip.x }\n"
                           "    buttons[1]: grip.buttons[1]\n";
  expect_eds_equals_device(yaml);
  const auto v =
      std::stoul(eds_value(gateway::upstream_eds(load(yaml), "oegw.eds"), "1000", "DefaultValue"), nullptr, 16);
  EXPECT_NE(v & (1u << 16), 0u);
}

TEST(UpstreamEds, OutputsTheHostMayNotCommandAreNamedAndTheDictionaryMatches) {
  const std::string yaml = kHead +
                           "publish: { dds: { domain: 0, network: loopback } }\n"
                           "functional_elements:\n"
                           "  joystick.2: { x: { signal: mcb.x } }\n"
                           "  indicators.1:\n"
                           "    sources: [dds]\n"
                           "    indicator[1..2]: grip.leds[1..2]\n"
                           "  indicators.2:\n"
                           "    indicator[1]: grip.leds[3]\n";
  expect_eds_equals_device(yaml);
  const std::string eds = gateway::upstream_eds(load(yaml), "oegw.eds");
  EXPECT_NE(eds.find("indicators.1 (6200h sub 01h..08h) takes commands from dds only"), std::string::npos) << eds;
  EXPECT_EQ(eds.find("indicators.2 (6200h"), std::string::npos);
  EXPECT_NE(eds.find("=network IDs: upstream (this device's bus) 1, downstream (its sub-devices) 2\n"),
            std::string::npos);
}

TEST(UpstreamEds, TheDemoFileGivesTheDeviceItsOwnEds) {
  // Its EDS paths are taken from its own folder, whatever the working directory.
  auto r = mapping::load_config(std::string(OEGW_SOURCE_DIR) + "/config/demo.yaml", gateway::driver_catalogue());
  ASSERT_TRUE(r.ok()) << r.error_text();
  gateway::Gateway gw(*r.config, {}, {});
  EXPECT_EQ(gateway::upstream_eds(*r.config, "oegw.eds"),
            canopen::eds_text(gw.upstream().od(), gateway::eds_info(*r.config, "oegw.eds")));
}

}  // namespace

// upstream.sdo_servers: the EDS lists 1201h.. (OptionalObjects, one RECORD each) with the
// defaults the mapping file gives, names where each channel leads in [Comments], and equals the
// running device's.
TEST(UpstreamEds, AdditionalSdoServerChannelsAreListedWithTheirDefaults) {
  const std::string yaml =
      "upstream:\n"
      "  interface: virtual\n"
      "  node_id: 0x20\n"
      "  sdo_servers:\n"
      "    - { subdevice: grip, request: 0x690, response: 0x6B0 }\n"
      "    - {}\n"
      "downstream: { interface: virtual }\n"
      "subdevices:\n"
      "  grip: { driver: elobau-mfg, node_id: 0x11 }\n"
      "functional_elements:\n"
      "  joystick.1: { x: { signal: grip.x } }\n";
  expect_eds_equals_device(yaml);
  const std::string eds = gateway::upstream_eds(load(yaml), "oegw.eds");
  const auto optional = eds.substr(eds.find("[OptionalObjects]"));
  const std::string list = optional.substr(0, optional.find("\n\n") + 1);
  EXPECT_TRUE(std::regex_search(list, std::regex("\n[0-9]+=0x1201\n[0-9]+=0x1202\n"))) << list;
  EXPECT_EQ(eds.find("[1203]"), std::string::npos);
  for (const char* index : {"1201", "1202"}) {
    EXPECT_EQ(eds_value(eds, index, "ParameterName"), "SDO server parameter");
    EXPECT_EQ(eds_value(eds, index, "ObjectType"), "0x9");
    EXPECT_EQ(eds_value(eds, index, "SubNumber"), "4");
    EXPECT_EQ(eds_value(eds, std::string(index) + "sub0", "DefaultValue"), "0x3");
    for (const char* sub : {"sub1", "sub2", "sub3"}) {
      EXPECT_EQ(eds_value(eds, index + std::string(sub), "AccessType"), "rw") << index << sub;
      EXPECT_EQ(eds_value(eds, index + std::string(sub), "PDOMapping"), "0") << index << sub;
    }
    EXPECT_EQ(eds_value(eds, std::string(index) + "sub1", "DataType"), "0x0007");
    EXPECT_EQ(eds_value(eds, std::string(index) + "sub3", "DataType"), "0x0005");
    EXPECT_EQ(eds_value(eds, std::string(index) + "sub3", "DefaultValue"), "0x0");
  }
  EXPECT_EQ(eds_value(eds, "1201sub1", "DefaultValue"), "0x690");
  EXPECT_EQ(eds_value(eds, "1201sub2", "DefaultValue"), "0x6B0");
  EXPECT_EQ(eds_value(eds, "1202sub1", "DefaultValue"), "0x80000000");
  EXPECT_EQ(eds_value(eds, "1202sub2", "DefaultValue"), "0x80000000");
  // The default channel is unchanged: node-relative and read-only.
  EXPECT_EQ(eds_value(eds, "1200sub1", "DefaultValue"), "$NODEID+0x600");
  EXPECT_EQ(eds_value(eds, "1200sub1", "AccessType"), "ro");
  EXPECT_NE(eds.find("=SDO server 1201h (COB-IDs 690h/6B0h): bound to sub-device grip (node 11h on network 2)\n"),
            std::string::npos)
      << eds;
  EXPECT_NE(eds.find("=SDO server 1202h (disabled until the host sets its COB-IDs): the gateway's own dictionary\n"),
            std::string::npos);
}

// ---------------------------------------------------------------- EDS versus SDO upload
//
// Every object of the EDS `oegw eds` writes, read back with the CiA 306 reader, against the
// running device built from the same Config (device_config(), as `oegw run` builds it): the
// default value equals an SDO upload from the started device, a read-only/const entry refuses an
// SDO download (0601 0002h), a write-only one refuses an upload (0601 0001h).
namespace eds_vs_device {

using canopen::CanFrame;
using Bytes = std::vector<std::uint8_t>;

struct Host {
  std::unique_ptr<gateway::Gateway> gw;
  std::vector<CanFrame> up;
  canopen::TimePoint now{std::chrono::seconds(10)};
  canopen::NodeId node;

  explicit Host(const mapping::Config& c) : node(c.upstream.node_id) {
    gateway::GatewayOptions o;
    o.store_path = std::filesystem::path("/nonexistent/oegw-eds-vs-device.store");
    gw = std::make_unique<gateway::Gateway>(
        c, [this](const CanFrame& f) { up.push_back(f); }, [](const CanFrame&) {}, o);
    (void)gw->start(now);
  }
  std::optional<CanFrame> request(const Bytes& b) {
    up.clear();
    CanFrame f(0x600 + node.value(), std::span<const std::uint8_t>(b));
    (void)gw->on_upstream_frame(f, now);
    for (const auto& r : up)
      if (r.id == 0x580u + node.value()) return r;
    return std::nullopt;
  }
  // Expedited or segmented upload: the bytes, or the abort code.
  std::pair<Bytes, std::uint32_t> upload(std::uint16_t index, std::uint8_t sub) {
    const auto lo = static_cast<std::uint8_t>(index), hi = static_cast<std::uint8_t>(index >> 8);
    auto r = request({0x40, lo, hi, sub, 0, 0, 0, 0});
    if (!r) return {{}, 0xFFFFFFFFu};
    if (r->data[0] == 0x80) return {{}, canopen::get_u32(&r->data[4])};
    if ((r->data[0] & 0x02) != 0) {  // expedited
      const std::size_t n = (r->data[0] & 0x01) ? 4 - ((r->data[0] >> 2) & 3) : 4;
      return {Bytes(r->data.begin() + 4, r->data.begin() + 4 + n), 0};
    }
    Bytes out;
    std::uint8_t toggle = 0;
    for (int guard = 0; guard < 64; ++guard) {
      auto s = request({static_cast<std::uint8_t>(0x60 | toggle), 0, 0, 0, 0, 0, 0, 0});
      if (!s) return {{}, 0xFFFFFFFFu};
      if (s->data[0] == 0x80) return {{}, canopen::get_u32(&s->data[4])};
      const std::size_t n = 7 - ((s->data[0] >> 1) & 7);
      out.insert(out.end(), s->data.begin() + 1, s->data.begin() + 1 + n);
      if (s->data[0] & 0x01) break;
      toggle ^= 0x10;
    }
    return {out, 0};
  }
  std::uint32_t download(std::uint16_t index, std::uint8_t sub, const Bytes& data) {
    const auto cs = static_cast<std::uint8_t>(0x23 | ((4 - data.size()) << 2));
    Bytes f{cs, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0};
    std::copy(data.begin(), data.end(), f.begin() + 4);
    auto r = request(f);
    if (!r) return 0xFFFFFFFFu;
    return r->data[0] == 0x80 ? canopen::get_u32(&r->data[4]) : 0;
  }
};

// The EDS default as the device's bytes (little endian, the type's size; strings as written).
Bytes expected_bytes(const canopen::eds::SubEntry& e, canopen::NodeId node) {
  const auto& v = *e.default_value;
  if (!v.numeric) return Bytes(v.text.begin(), v.text.end());
  const std::uint64_t n = v.number + (v.node_relative ? node.value() : 0);
  const std::size_t w = canopen::fixed_size(e.type);
  Bytes b(w);
  for (std::size_t i = 0; i < w; ++i) b[i] = static_cast<std::uint8_t>(n >> (8 * i));
  return b;
}

void expect_eds_matches_uploads(const std::string& yaml, const std::string& what) {
  SCOPED_TRACE(what);
  const mapping::Config c = load(yaml);
  std::string error;
  const auto file = canopen::eds::parse(gateway::upstream_eds(c, "oegw.eds"), "oegw.eds", error);
  ASSERT_TRUE(file) << error;
  Host host(c);
  // The device as the EDS describes it at power-on: 1003h and 1001h may hold what start()
  // raised, the store is absent (so no 6000h), nothing else moved.
  std::size_t compared = 0;
  for (const auto& [index, obj] : file->objects) {
    for (const auto& [sub, e] : obj.subs) {
      SCOPED_TRACE(fmt::format("{:04X}h sub {:02X}h", index, sub));
      const bool readable = e.access != canopen::Access::WriteOnly;
      const auto [bytes, abort] = host.upload(index, sub);
      if (!readable) {
        EXPECT_EQ(abort, 0x06010001u);
        continue;
      }
      ASSERT_EQ(abort, 0u) << std::hex << abort;
      if (e.default_value) {
        EXPECT_EQ(bytes, expected_bytes(e, host.node));
        ++compared;
      }
      // A read-only or const entry refuses a download of its own value (cheap: no state change).
      if ((e.access == canopen::Access::ReadOnly || e.access == canopen::Access::Const) && !bytes.empty() &&
          bytes.size() <= 4) {
        EXPECT_EQ(host.download(index, sub, bytes), 0x06010002u);
      }
    }
  }
  EXPECT_GT(compared, 20u);
}

TEST(UpstreamEdsVersusDevice, DemoCab) {
  expect_eds_matches_uploads(fixtures::mapping_file("demo_cab.yaml"), "demo_cab.yaml");
}
TEST(UpstreamEdsVersusDevice, OneGrip) {
  expect_eds_matches_uploads(fixtures::mapping_file("one_grip.yaml"), "one_grip.yaml");
}
TEST(UpstreamEdsVersusDevice, FullFeSet) {
  expect_eds_matches_uploads(fixtures::mapping_file("full_fe_set.yaml"), "full_fe_set.yaml");
}
TEST(UpstreamEdsVersusDevice, SdoServers) {
  expect_eds_matches_uploads(fixtures::mapping_file("sdo_servers.yaml"), "sdo_servers.yaml");
}
TEST(UpstreamEdsVersusDevice, AJoystickWithoutButtons) {
  expect_eds_matches_uploads(kHead +
                                 "functional_elements:\n"
                                 "  joystick.1: { x: { signal: grip.x }, y: { signal: grip.y } }\n",
                             "joystick without buttons");
}

}  // namespace eds_vs_device
