// `oegw eds` describes the dictionary the running gateway has: the EDS written from the mapping
// file (upstream_eds, what `oegw eds` prints) equals the EDS of the Gateway's own device, built
// from the same file — for a joystick without buttons (CiA 852 Table 8: no digital-input bit in
// 1000h), output FEs the host may not command, and the full set of FE kinds.
#include <gtest/gtest.h>

#include <filesystem>
#include <regex>

#include <fmt/format.h>

#include "gateway/gateway.hpp"
#include "gateway/runtime_config.hpp"

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
    "  mcb: { driver: mcb402, node_id: 0x12 }\n";

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
  const auto v = std::stoul(eds_value(gateway::upstream_eds(load(yaml), "oegw.eds"), "1000", "DefaultValue"), nullptr, 16);
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
  EXPECT_NE(eds.find("=network IDs: upstream (this device's bus) 1, downstream (its sub-devices) 2\n"), std::string::npos);
}

TEST(UpstreamEds, TheDemoFileGivesTheDeviceItsOwnEds) {
  std::filesystem::current_path(OEGW_SOURCE_DIR);  // its EDS paths are relative to the source tree
  auto r = mapping::load_config("config/demo.yaml", gateway::driver_catalogue());
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
