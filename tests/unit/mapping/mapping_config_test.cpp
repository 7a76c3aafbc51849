// The mapping file: parsing, validation with file:line:column diagnostics (all at once), and
// the resulting Config. Requirements (docs/reference/mapping-file.md): validation refuses before
// anything starts, with file:line:column, what was found and what was expected; all errors at
// once. Signals come from a fake catalogue
// (the drivers are written elsewhere): elobau-mfg, mcb402, novotechnik-406, cia401.
#include "mapping/config.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "mapping/yaml_reader.hpp"

namespace oegw::mapping {
namespace {

using subdevices::DriverOptions;
using subdevices::SignalInfo;
using subdevices::SignalKind;
using ::testing::ElementsAre;

void add_range(std::vector<SignalInfo>& out, const std::string& base, int n, SignalKind k, std::int64_t lo,
               std::int64_t hi, const std::string& unit) {
  for (int i = 1; i <= n; ++i) out.push_back({base + "[" + std::to_string(i) + "]", k, lo, hi, 0, unit});
}

// Options each fake family accepts: elobau-mfg "tolerance", mcb402 "button_bits", cia401 "eds"
// (required). Every option it does not know is refused, each naming its option.
std::optional<std::vector<SignalInfo>> fake_catalogue(std::string_view family, const DriverOptions& options,
                                                      subdevices::OptionRefusals& refusals) {
  std::vector<std::string> allowed;
  std::vector<SignalInfo> s;
  if (family == "elobau-mfg") {
    allowed = {"tolerance"};
    for (const char* n : {"x", "y", "wheel_a", "wheel_b", "wheel_c"})
      s.push_back({n, SignalKind::Axis, -110, 110, 0, "percent"});
    add_range(s, "buttons", 16, SignalKind::Button, 0, 1, "bits");
    add_range(s, "leds", 16, SignalKind::Output, 0, 2, "code");  // off / on / blink
  } else if (family == "mcb402") {
    allowed = {"button_bits"};
    for (const char* n : {"x", "y", "z", "t"}) s.push_back({n, SignalKind::Axis, -32768, 32767, 0, "raw16"});
    add_range(s, "buttons", 7, SignalKind::Button, 0, 1, "bits");
    add_range(s, "leds", 4, SignalKind::Output, 0, 1, "bits");
  } else if (family == "novotechnik-406") {
    s.push_back({"position", SignalKind::Position, 0, 0xFFFFFFFF, 0, "counts"});
    s.push_back({"speed", SignalKind::Speed, -32768, 32767, 0, "counts/s"});
  } else if (family == "cia401") {
    allowed = {"eds"};
    if (!options.get("eds")) refusals.push_back({"", "option 'eds' missing"});
    add_range(s, "in", 8, SignalKind::Digital, 0, 255, "bits");  // one signal per input byte
    add_range(s, "analog", 4, SignalKind::Analog, -32768, 32767, "raw16");
    add_range(s, "out", 8, SignalKind::Output, 0, 255, "bits");  // one signal per output byte
    add_range(s, "aout", 4, SignalKind::Output, -32768, 32767, "raw16");
  } else {
    refusals.push_back({"", "no such family"});
    return std::nullopt;
  }
  for (const auto& [k, v] : options.values)
    if (std::find(allowed.begin(), allowed.end(), k) == allowed.end())
      refusals.push_back({k, "unknown option '" + k + "'"});
  if (!refusals.empty()) return std::nullopt;
  return s;
}

const std::string kHead = R"(upstream: { interface: can0, node_id: 0x20 }
downstream: { interface: can1 }
subdevices:
  right_grip: { driver: elobau-mfg, node_id: 0x11 }
  left_grip: { driver: mcb402, node_id: 0x03 }
  knob: { driver: novotechnik-406, node_id: 0x7F }
  cluster: { driver: cia401, node_id: 0x31, options: { eds: x.eds } }
functional_elements:
)";  // 8 lines: functional elements start on line 9

// The repository root (tests/CMakeLists.txt defines it; the tests run from the build tree).
std::string source_dir() { return OEGW_SOURCE_DIR; }

LoadResult load(const std::string& text) { return load_config_text(text, "t.yaml", fake_catalogue); }

std::vector<std::string> errors(const LoadResult& r) {
  std::vector<std::string> out;
  for (const auto& e : r.errors) out.push_back(e.str());
  return out;
}

// ---- The files in config/ ------------------------------------------------------------------

TEST(MappingConfig, DemoFileLoadsIntoACompleteConfig) {
  const auto r = load_config(source_dir() + "/config/demo.yaml", fake_catalogue);
  ASSERT_TRUE(r.ok()) << r.error_text();
  const Config& c = *r.config;
  EXPECT_EQ(c.upstream.interface, "virtual");
  EXPECT_EQ(c.upstream.node_id, 0x20);
  EXPECT_EQ(c.upstream.bitrate, 250000u);
  EXPECT_EQ(c.upstream.identity.product_code, 0x852u);
  EXPECT_EQ(c.upstream.identity.revision, 0x00010000u);
  EXPECT_EQ(c.upstream.heartbeat_ms, 100);
  EXPECT_EQ(c.downstream.interface, "virtual");
  // The demo publishes on both, host-local (docs/guides/dds-lcm.md#network: test and demo traffic
  // stays on this host).
  EXPECT_TRUE(c.publish.dds.enabled);
  EXPECT_EQ(c.publish.dds.network, "loopback");
  EXPECT_TRUE(c.publish.lcm.enabled);
  EXPECT_EQ(c.publish.lcm.url, "udpm://224.0.0.1:7667?ttl=0");
  // Its own names: never mixed with a real gateway's (partition oegw, OEGW_*) on one computer.
  EXPECT_EQ(c.publish.dds.partition, "oegw-demo");
  EXPECT_EQ(c.publish.lcm.channel_prefix, "OEGW_DEMO_");
  // The cluster's lamps come from the machine application, the MCB-402's LEDs from the host.
  ASSERT_NE(c.find_fe({FeKind::IndicatorCluster, 1}), nullptr);
  EXPECT_EQ(describe_sources(c.find_fe({FeKind::IndicatorCluster, 1})->sources), "dds, lcm");
  EXPECT_EQ(describe_sources(c.find_fe({FeKind::IndicatorCluster, 2})->sources), "canopen");

  ASSERT_EQ(c.subdevices.size(), 5u);
  std::vector<std::pair<std::string, int>> nodes;
  for (const auto& s : c.subdevices) nodes.emplace_back(s.name, s.node_id);
  EXPECT_THAT(nodes,
              ElementsAre(std::pair<std::string, int>{"right_grip", 0x11},
                          std::pair<std::string, int>{"left_grip", 0x03}, std::pair<std::string, int>{"pedal", 0x30},
                          std::pair<std::string, int>{"seat_knob", 0x7F},
                          std::pair<std::string, int>{"cluster", 0x31}));
  const auto* grip = c.find_subdevice("right_grip");
  ASSERT_NE(grip, nullptr);
  EXPECT_TRUE(grip->mandatory);
  EXPECT_EQ(grip->signals.size(), 37u);  // from the catalogue
  const auto* pedal = c.find_subdevice("pedal");
  ASSERT_NE(pedal, nullptr);
  // Written ../subdevices/eds/generic_pedal.eds: taken from config/, the file's folder.
  EXPECT_EQ(pedal->options.get("eds"), std::optional<std::string>(source_dir() + "/subdevices/eds/generic_pedal.eds"));
  const auto* knob = c.find_subdevice("seat_knob");
  ASSERT_NE(knob, nullptr);
  EXPECT_FALSE(knob->identity.device_type.has_value());
  ASSERT_EQ(knob->sdo.size(), 1u);
  const auto w = knob->sdo[0].to_sdo_write();
  EXPECT_EQ(w.index, 0x1800);
  EXPECT_EQ(w.sub, 5);
  EXPECT_EQ(w.data, (std::vector<std::uint8_t>{20, 0}));  // UNSIGNED16, little endian
  const auto settings = knob->node_settings();
  ASSERT_EQ(settings.sdo.size(), 1u);
  EXPECT_EQ(settings.sdo[0].data, w.data);

  // Sorted by FeId: joystick 1, 2, pedal 1, encoder 1, wheel 1, buttons 1, indicators 1, 2.
  std::vector<std::string> fes;
  for (const auto& fe : c.functional_elements) fes.push_back(fe_name(fe.id));
  EXPECT_THAT(fes, ElementsAre("joystick.1", "joystick.2", "pedal.1", "encoder.1", "wheel.1", "buttons.1",
                               "indicators.1", "indicators.2"));
  const auto& j1 = c.functional_elements[0];
  // Dictionary order (profiles/cia852/fe_table.hpp): buttons[1..6] (the grip's, 2100h:01h
  // default 63) before x, y.
  ASSERT_EQ(j1.fields.size(), 8u);
  EXPECT_EQ(j1.fields[0].field.name, "buttons[1]");
  EXPECT_EQ(j1.fields[0].signal, "buttons[1]");
  EXPECT_EQ(j1.fields[0].field.index, 0x6000);
  EXPECT_EQ(j1.fields[0].field.sub, 2);
  EXPECT_EQ(j1.fields[6].field.name, "x");
  EXPECT_EQ(j1.fields[6].subdevice, "right_grip");
  EXPECT_EQ(j1.fields[6].options.deadband, 2);
  EXPECT_EQ(j1.fields[6].field.index, 0x6401);
  EXPECT_EQ(j1.fields[6].field.sub, 1);
  EXPECT_EQ(j1.fields[6].input_params().scale, 32767.0 / 100.0);  // percent: 100 % = full scale
  const auto& j2 = c.functional_elements[1];
  ASSERT_EQ(j2.fields.size(), 10u);  // 7 buttons + x, y, z
  EXPECT_TRUE(j2.fields[8].options.invert);
  EXPECT_EQ(j2.fields[9].options.clamp, (std::pair<std::int64_t, std::int64_t>(-32767, 32767)));
  const auto& pedal1 = c.functional_elements[2];
  ASSERT_EQ(pedal1.fields.size(), 1u);
  EXPECT_EQ(pedal1.fields[0].signal, "analog[1]");
  EXPECT_EQ(pedal1.fields[0].options.fault, std::optional<std::int64_t>(0));
  const auto& ind2 = c.functional_elements[7];
  ASSERT_EQ(ind2.fields.size(), 4u);
  EXPECT_FALSE(ind2.input());
  EXPECT_EQ(ind2.fields[3].field.name, "indicator[4]");
  EXPECT_EQ(ind2.fields[3].signal, "leds[4]");
  EXPECT_EQ(ind2.fields[3].field.index, 0x6200);
  EXPECT_EQ(ind2.fields[3].field.sub, 0x09);  // indicator cluster 2 starts at 6200h sub 09h
  EXPECT_EQ(ind2.fields[3].field.bit, 3);
}

TEST(MappingConfig, BadExampleReportsEveryErrorAtOnceInFileOrder) {
  const auto path = source_dir() + "/config/bad_example.yaml";
  const auto r = load_config(path, fake_catalogue);
  EXPECT_FALSE(r.ok());
  EXPECT_FALSE(r.config.has_value());  // nothing half-built
  const std::string f = path + ":";
  EXPECT_THAT(
      errors(r),
      ElementsAre(
          f + "2:39: node_id 0x80 is out of range; expected 1..127",
          f + "2:45: unknown key 'bitrat' in upstream; expected one of interface, node_id, bitrate, identity, "
              "heartbeat_ms, "
              "store, network_id, sdo_servers (did you mean 'bitrate'?)",
          f + "3:41: bitrate 300000 is not a CiA 301 bit rate; expected one of 10000, 20000, 50000, 125000, 250000, "
              "500000, "
              "800000, 1000000",
          f + "6:41: node_id 0x11 of 'left_grip' is already used by sub-device 'right_grip' (line 5, column 46), so "
              "all "
              "their default COB-IDs clash; expected a node-ID of its own",
          f + "7:55: COB-ID 0x191 of knob TPDO 1800h:01 clashes with right_grip TPDO1 (default); expected a COB-ID no "
              "other "
              "node uses",
          f + "9:3: instance 17 of 'joystick.17' is out of range; expected joystick.1..16 (CiA 852 clause 9)",
          f + "10:3: unknown functional element kind 'joystik' in 'joystik.1'; expected one of joystick, pedal, "
              "encoder, "
              "wheel, buttons, indicators, display (did you mean 'joystick'?)",
          f + "12:8: signal 'right_grip.buttons[1]' is a Button signal; expected an Axis or Analog signal for "
              "joystick.1 x; "
              "a Button signal fits joystick.N (memory_x, memory_y, memory_z, buttons[1..8]), pedal.N memory_x or "
              "buttons.N switch[1..64]",
          f + "13:5: joystick.1 has no field 'w'; expected one of memory_x, memory_y, memory_z, buttons[1..8], x, y, z",
          f + "14:8: unknown sub-device 'rigth_grip' in signal 'rigth_grip.y'; expected one of right_grip, left_grip, "
              "knob "
              "(did you mean 'right_grip'?)",
          f + "15:8: sub-device 'right_grip' (elobau-mfg) has no signal 'q'; expected one of x, y, wheel_a, wheel_b, "
              "wheel_c, buttons[1..16], leds[1..16]",
          f + "17:5: joystick.1 buttons[2] is fed twice (first at line 16, column 5); expected each field fed by one "
              "signal",
          f + "19:20: joystick.2 buttons[1..8] has 8 elements but 'left_grip.buttons[1..7]' has 7; expected ranges of "
              "equal length",
          f + "21:19: signal 'right_grip.x' is an Axis signal; expected an Output signal for indicators.1 indicator[1] "
              "(an "
              "output functional element); an Axis signal fits joystick.N (x, y, z), pedal.N position or wheel.N "
              "position"));
}

// ---- One error at a time, inline -----------------------------------------------------------

TEST(MappingConfig, MinimalFileAndDefaults) {
  const auto r = load(kHead + "  joystick.1: { x: right_grip.x }\n");
  ASSERT_TRUE(r.ok()) << r.error_text();
  EXPECT_EQ(r.config->upstream.bitrate, 250000u);
  EXPECT_EQ(r.config->upstream.heartbeat_ms, 100);  // CiA 852 §8.3: heartbeat "shall be used"
  EXPECT_EQ(r.config->downstream.bitrate, 250000u);
  EXPECT_EQ(r.config->upstream.network_id, 1);
  EXPECT_EQ(r.config->downstream.network_id, 2);
  EXPECT_EQ(r.config->subdevices[0].heartbeat_ms, 100);
  EXPECT_FALSE(r.config->subdevices[0].mandatory);
  EXPECT_FALSE(r.config->publish.dds.enabled);
  EXPECT_FALSE(r.config->publish.lcm.enabled);
  ASSERT_EQ(r.config->functional_elements.size(), 1u);
  EXPECT_EQ(r.config->functional_elements[0].fields[0].where.str(), "t.yaml:9:17");
}

// CiA 302-7 network IDs of the two buses: 1..127 each, distinct, named where written.
TEST(MappingConfig, NetworkIdsAreInRangeAndDistinct) {
  auto with = [](const std::string& up, const std::string& down) {
    std::string t = kHead;
    t.replace(t.find("node_id: 0x20 }"), 15, "node_id: 0x20" + up + " }");
    t.replace(t.find("interface: can1 }"), 17, "interface: can1" + down + " }");
    return load(t + "  joystick.1: { x: right_grip.x }\n");
  };
  const auto ok = with(", network_id: 7", ", network_id: 3");
  ASSERT_TRUE(ok.ok()) << ok.error_text();
  EXPECT_EQ(ok.config->upstream.network_id, 7);
  EXPECT_EQ(ok.config->downstream.network_id, 3);
  EXPECT_EQ(errors(with(", network_id: 0", "")),
            (std::vector<std::string>{"t.yaml:1:57: network_id 0 is out of range; expected 1..127"}));
  EXPECT_EQ(errors(with("", ", network_id: 128")),
            (std::vector<std::string>{"t.yaml:2:44: network_id 128 is out of range; expected 1..127"}));
  EXPECT_EQ(errors(with(", network_id: 4", ", network_id: 4")),
            (std::vector<std::string>{"t.yaml:2:44: downstream network_id 4 names both buses; expected two distinct "
                                      "network IDs 1..127 (defaults: upstream 1, downstream 2)"}));
  EXPECT_EQ(errors(with(", network_id: 2", "")),
            (std::vector<std::string>{"t.yaml:1:57: upstream network_id 2 names both buses; expected two distinct "
                                      "network IDs 1..127 (defaults: upstream 1, downstream 2)"}));
}

// downstream.sdo_timeout_ms: the gateway's SDO client time-out toward the sub-devices.
TEST(MappingConfig, DownstreamSdoTimeoutIsInRange) {
  auto with = [](const std::string& down) {
    std::string t = kHead;
    t.replace(t.find("interface: can1 }"), 17, "interface: can1" + down + " }");
    return load(t + "  joystick.1: { x: right_grip.x }\n");
  };
  const auto dflt = with("");
  ASSERT_TRUE(dflt.ok()) << dflt.error_text();
  EXPECT_EQ(dflt.config->downstream.sdo_timeout_ms, 1000);
  const auto set = with(", sdo_timeout_ms: 200");
  ASSERT_TRUE(set.ok()) << set.error_text();
  EXPECT_EQ(set.config->downstream.sdo_timeout_ms, 200);
  EXPECT_EQ(errors(with(", sdo_timeout_ms: 5")),
            (std::vector<std::string>{"t.yaml:2:48: sdo_timeout_ms 5 is out of range; expected 10..60000"}));
}

// downstream.emcy_forwarding: which sub-device EMCYs go upstream (all by default).
TEST(MappingConfig, EmcyForwardingIsAllFaultsOrNone) {
  auto with = [](const std::string& down) {
    std::string t = kHead;
    t.replace(t.find("interface: can1 }"), 17, "interface: can1" + down + " }");
    return load(t + "  joystick.1: { x: right_grip.x }\n");
  };
  const auto dflt = with("");
  ASSERT_TRUE(dflt.ok()) << dflt.error_text();
  EXPECT_EQ(dflt.config->downstream.emcy_forwarding, oegw::mapping::EmcyForwarding::All);
  const auto faults = with(", emcy_forwarding: faults");
  ASSERT_TRUE(faults.ok()) << faults.error_text();
  EXPECT_EQ(faults.config->downstream.emcy_forwarding, oegw::mapping::EmcyForwarding::Faults);
  const auto none = with(", emcy_forwarding: none");
  ASSERT_TRUE(none.ok()) << none.error_text();
  EXPECT_EQ(none.config->downstream.emcy_forwarding, oegw::mapping::EmcyForwarding::None);
  EXPECT_EQ(with(", emcy_forwarding: all").config->downstream.emcy_forwarding, oegw::mapping::EmcyForwarding::All);
  EXPECT_EQ(errors(with(", emcy_forwarding: errors")),
            (std::vector<std::string>{
                "t.yaml:2:49: found 'errors' for emcy_forwarding; expected one of all, faults, none"}));
  EXPECT_EQ(errors(with(", emcy_forwarding: [all]")),
            (std::vector<std::string>{"t.yaml:2:49: found [all] for emcy_forwarding; expected a text"}));
}

TEST(MappingConfig, YamlSyntaxErrorCarriesItsMarkAndAHintForBracketsInFlowMaps) {
  const auto r = load(kHead + "  joystick.1: { buttons: right_grip.buttons[1..8] }\n");
  EXPECT_THAT(errors(r),
              ElementsAre("t.yaml:9:44: YAML syntax error: end of map flow not found; expected well-formed "
                          "YAML (inside { }, quote names with [ ], e.g. \"buttons[1..8]\", or use block style)"));
  // Quoted, the same line is fine.
  EXPECT_TRUE(load(kHead + "  joystick.1: { buttons: \"right_grip.buttons[1..8]\" }\n").ok());
  const auto r2 = load("upstream: { node_id: 1\n");
  ASSERT_EQ(r2.errors.size(), 1u);
  EXPECT_THAT(r2.errors[0].str(), ::testing::StartsWith("t.yaml:2:1: YAML syntax error: "));
}

TEST(MappingConfig, EmptyFileAndMissingSections) {
  EXPECT_THAT(errors(load("")),
              ElementsAre(
                  "t.yaml:1:1: found nothing at the top; expected a map with upstream, downstream, publish, control, "
                  "record, subdevices, functional_elements"));
  EXPECT_THAT(errors(load("upstream: { interface: can0 }\n")),
              ElementsAre("t.yaml:1:1: no 'downstream' in the file; expected a downstream section",
                          "t.yaml:1:1: no 'subdevices' in the file; expected a subdevices section",
                          "t.yaml:1:1: no 'functional_elements' in the file; expected a functional_elements section",
                          "t.yaml:1:11: no 'node_id' in upstream; expected the gateway's node-ID 1..127"));
}

TEST(MappingConfig, UnknownKeysEverywhereWithNearMissSuggestions) {
  const auto r = load(R"(upstream: { node_id: 1, identity: { vendor: 1 } }
downstream: { interface: can1 }
publsh: {}
subdevices:
  a: { driver: mcb402, node_id: 2, hearbeat_ms: 50, colour: red }
functional_elements:
  joystick.1:
    x: { signal: a.x, deadbnd: 3 }
)");
  EXPECT_THAT(
      errors(r),
      ElementsAre(
          "t.yaml:1:37: unknown key 'vendor' in upstream identity; expected one of vendor_id, product_code, revision, "
          "serial (did you mean 'vendor_id'?)",
          "t.yaml:3:1: unknown key 'publsh' in the file; expected one of upstream, downstream, publish, control, "
          "record, "
          "subdevices, functional_elements (did you mean 'publish'?)",
          "t.yaml:5:36: unknown key 'hearbeat_ms' in sub-device 'a'; expected one of driver, node_id, heartbeat_ms, "
          "heartbeat_timeout_ms, pdo_timeout_ms, mandatory, identity, sdo, options (did you mean 'heartbeat_ms'?)",
          "t.yaml:5:53: unknown key 'colour' in sub-device 'a'; expected one of driver, node_id, heartbeat_ms, "
          "heartbeat_timeout_ms, pdo_timeout_ms, mandatory, identity, sdo, options",
          "t.yaml:8:23: unknown key 'deadbnd' in joystick.1 x; expected one of signal, scale, offset, deadband, "
          "invert, clamp, fault, interlock (did you mean 'deadband'?)"));
}

TEST(MappingConfig, InstanceOutOfRangeKindUnknownAndNoInstance) {
  const auto r = load(kHead + R"(  joystick.0: { x: right_grip.x }
  pedal.17: { position: right_grip.x }
  buttons.9:
    switch[1]: cluster.in[1]
  whel.1: { position: right_grip.wheel_a }
  encoder: { position: knob.position }
  encoder.x: { position: knob.position }
)");
  EXPECT_THAT(
      errors(r),
      ElementsAre(
          "t.yaml:9:3: instance 0 of 'joystick.0' is out of range; expected joystick.1..16 (CiA 852 clause 9)",
          "t.yaml:10:3: instance 17 of 'pedal.17' is out of range; expected pedal.1..16 (CiA 852 clause 9)",
          "t.yaml:11:3: instance 9 of 'buttons.9' is out of range; expected buttons.1..8 (CiA 852 clause 9)",
          "t.yaml:13:3: unknown functional element kind 'whel' in 'whel.1'; expected one of joystick, pedal, encoder, "
          "wheel, buttons, indicators, display (did you mean 'wheel'?)",
          "t.yaml:14:3: functional element 'encoder' has no instance number; expected encoder.N with N 1..8",
          "t.yaml:15:3: functional element 'encoder.x' has no instance number; expected encoder.N with N 1..8"));
}

TEST(MappingConfig, FieldTheElementDoesNotHave) {
  const auto r = load(kHead + R"(  wheel.1: { x: right_grip.wheel_a }
  joystick.1:
    buttons[9]: right_grip.buttons[9]
    buttons[7..9]: right_grip.buttons[7..9]
    memroy_x: right_grip.buttons[1]
)");
  EXPECT_THAT(
      errors(r),
      ElementsAre("t.yaml:9:14: wheel.1 has no field 'x'; expected one of position",
                  "t.yaml:11:5: joystick.1 has no field 'buttons[9]'; expected one of memory_x, memory_y, memory_z, "
                  "buttons[1..8], "
                  "x, y, z",
                  "t.yaml:12:5: joystick.1 has no field 'buttons[7..9]'; expected one of memory_x, memory_y, memory_z, "
                  "buttons[1..8], x, y, z",
                  "t.yaml:13:5: joystick.1 has no field 'memroy_x'; expected one of memory_x, memory_y, memory_z, "
                  "buttons[1..8], "
                  "x, y, z (did you mean 'memory_x'?)"));
}

TEST(MappingConfig, SignalOfAnUnknownSubDeviceOrNotProvidedByTheDriver) {
  const auto r = load(kHead + R"(  joystick.1:
    x: left.x
    y: left_grip.w
    buttons[1..8]: left_grip.buttons[1..8]
    z: left_grip
)");
  EXPECT_THAT(
      errors(r),
      ElementsAre(
          "t.yaml:10:8: unknown sub-device 'left' in signal 'left.x'; expected one of right_grip, left_grip, knob, "
          "cluster "
          "(did you mean 'left_grip'?)",
          "t.yaml:11:8: sub-device 'left_grip' (mcb402) has no signal 'w'; expected one of x, y, z, t, buttons[1..7], "
          "leds[1..4]",
          "t.yaml:12:20: sub-device 'left_grip' (mcb402) has no signal 'buttons[8]'; expected one of x, y, z, t, "
          "buttons[1..7], leds[1..4]",
          "t.yaml:13:8: found 'left_grip' for joystick.1 z; expected a signal as subdevice.signal, "
          "subdevice.signal[a..b] or subdevice.signal.bitN"));
}

// Each kind mismatch also says where that signal kind would fit: the FE kinds
// whose fields take it, read from the FE table, e.g. a Novotechnik position into a wheel.
TEST(MappingConfig, TypesThatDoNotFit) {
  const auto r = load(kHead + R"(  joystick.1:
    x: left_grip.buttons[1]
    y: left_grip.leds[1]
    buttons[1]: left_grip.x
  encoder.1: { position: knob.speed }
  indicators.1:
    indicator[1..8]: cluster.in[1]
  display.1:
    parameter[1]: left_grip.y
    parameter[2]: cluster.aout[1]
  pedal.1:
    position: cluster.analog[1]
  wheel.1: { position: knob.position }
  encoder.2: { position: left_grip.z }
)");
  EXPECT_THAT(
      errors(r),
      ElementsAre(
          "t.yaml:10:8: signal 'left_grip.buttons[1]' is a Button signal; expected an Axis or Analog signal for "
          "joystick.1 x; a Button signal fits joystick.N (memory_x, memory_y, memory_z, buttons[1..8]), pedal.N "
          "memory_x "
          "or buttons.N switch[1..64]",
          "t.yaml:11:8: signal 'left_grip.leds[1]' is an Output signal; expected an Axis or Analog signal for "
          "joystick.1 y; "
          "an Output signal fits indicators.N indicator[1..64] or display.N parameter[1..12]",
          "t.yaml:12:17: signal 'left_grip.x' is an Axis signal; expected a Button or Digital signal for joystick.1 "
          "buttons[1]; an Axis signal fits joystick.N (x, y, z), pedal.N position or wheel.N position",
          "t.yaml:13:26: signal 'knob.speed' is a Speed signal; expected a Position or Analog signal for encoder.1 "
          "position; no functional element field takes a Speed signal (CiA 852 clause 9)",
          "t.yaml:15:22: signal 'cluster.in[1]' is a Digital signal; expected an Output signal for indicators.1 "
          "indicator[1] (an output functional element); a Digital signal fits joystick.N (memory_x, memory_y, "
          "memory_z, "
          "buttons[1..8]), pedal.N memory_x or buttons.N switch[1..64]",
          "t.yaml:17:19: signal 'left_grip.y' is an Axis signal; expected an Output signal for display.1 parameter[1] "
          "(an "
          "output functional element); an Axis signal fits joystick.N (x, y, z), pedal.N position or wheel.N position",
          "t.yaml:21:24: signal 'knob.position' is a Position signal; expected an Axis or Analog signal for wheel.1 "
          "position; a Position signal fits encoder.N position",
          "t.yaml:22:26: signal 'left_grip.z' is an Axis signal; expected a Position or Analog signal for encoder.2 "
          "position; an Axis signal fits joystick.N (x, y, z), pedal.N position or wheel.N position"));
}

TEST(MappingConfig, NodeIdsOutOfRangeBadNumbersAndDuplicates) {
  const auto r = load(R"(upstream: { node_id: 0 }
downstream: { interface: can1 }
subdevices:
  a: { driver: mcb402, node_id: 128 }
  b: { driver: mcb402, node_id: abc }
  c: { driver: mcb402, node_id: -1 }
  d: { driver: mcb402, node_id: 0x7f }
  e: { driver: mcb402, node_id: 127 }
  f: { driver: mcb402, node_id: [1] }
functional_elements: {}
)");
  EXPECT_THAT(
      errors(r),
      ElementsAre(
          "t.yaml:1:22: node_id 0 is out of range; expected 1..127",
          "t.yaml:4:33: node_id 128 is out of range; expected 1..127",
          "t.yaml:5:33: node_id 'abc' is not a number; expected an integer 1..127 (decimal or 0x hex)",
          "t.yaml:6:33: node_id -1 is out of range; expected 1..127",
          "t.yaml:8:33: node_id 127 of 'e' is already used by sub-device 'd' (line 7, column 33), so all their default "
          "COB-IDs clash; expected a node-ID of its own",
          "t.yaml:9:33: found [1] for node_id; expected an integer 1..127"));
}

TEST(MappingConfig, ExplicitCobIdsClashWithDefaultsAndEachOther) {
  const auto r = load(R"(upstream: { node_id: 1 }
downstream: { interface: can1 }
subdevices:
  a:
    driver: mcb402
    node_id: 2
    sdo:
      - { index: 0x1800, sub_index: 1, value: 0x183, type: u32 }
      - { index: 0x1801, sub_index: 1, value: 0x3A0, type: u32 }
      - { index: 0x1400, sub_index: 1, value: 0x80000203, type: u32 }
      - { index: 0x1014, sub_index: 0, value: 0x705, type: u32 }
  b:
    driver: mcb402
    node_id: 3
    sdo:
      - { index: 0x1402, sub_index: 1, value: 0x3A0, type: u32 }
      - { index: 0x1801, sub_index: 1, value: 0x190, type: u32 }
functional_elements: {}
)");
  // a TPDO1 -> 0x183 = b's default TPDO1, which b keeps: clash. a TPDO2 and b RPDO3 both 0x3A0:
  // clash, reported once, at the later one. a RPDO1 -> 0x203 = b's default RPDO1, but bit 31 says
  // the PDO is off: no clash. a EMCY -> 0x705, b's heartbeat range: reserved.
  EXPECT_THAT(
      errors(r),
      ElementsAre(
          "t.yaml:8:9: COB-ID 0x183 of a TPDO 1800h:01 clashes with b TPDO1 (default); expected a COB-ID no other node "
          "uses",
          "t.yaml:11:9: COB-ID 0x705 of a EMCY 1014h:00 is reserved by CiA 301 (NMT, SYNC, TIME, SDO, heartbeat or "
          "LSS); "
          "expected a PDO/EMCY COB-ID",
          "t.yaml:16:9: COB-ID 0x3A0 of b RPDO 1402h:01 clashes with a TPDO 1801h:01; expected a COB-ID no other node "
          "uses"));
}

TEST(MappingConfig, ExplicitCobIdReplacesTheNodesOwnDefault) {
  // b moves its TPDO1 away from 0x183 and a takes it: no clash.
  const auto r = load(R"(upstream: { node_id: 1 }
downstream: { interface: can1 }
subdevices:
  a: { driver: mcb402, node_id: 2, sdo: [ { index: 0x1800, sub_index: 1, value: 0x183, type: u32 } ] }
  b: { driver: mcb402, node_id: 3, sdo: [ { index: 0x1800, sub_index: 1, value: 0x1A0, type: u32 } ] }
functional_elements: {}
)");
  EXPECT_TRUE(r.ok()) << r.error_text();
}

TEST(MappingConfig, FieldFedTwiceAndOutputDrivenTwice) {
  const auto r = load(kHead + R"(  joystick.1:
    buttons: right_grip.buttons[1..8]
    buttons[8]: right_grip.buttons[9]
  joystick.01: { x: right_grip.x }
  buttons.1:
    switch[1..4]: right_grip.buttons[1..4]
    switch[3..6]: right_grip.buttons[3..6]
  indicators.1:
    indicator[1..2]: left_grip.leds[1..2]
    indicator[3]: left_grip.leds[2]
)");
  EXPECT_THAT(
      errors(r),
      ElementsAre(
          "t.yaml:11:5: joystick.1 buttons[8] is fed twice (first at line 10, column 5); expected each field fed by "
          "one "
          "signal",
          "t.yaml:12:3: functional element 'joystick.01' appears twice (first at line 9, column 3); expected each "
          "functional element once",
          "t.yaml:15:5: buttons.1 switch[3] is fed twice (first at line 14, column 5); expected each field fed by one "
          "signal",
          "t.yaml:18:19: output signal 'left_grip.leds[2]' is driven twice (first at line 17, column 5); expected each "
          "output driven by one field"));
}

TEST(MappingConfig, DuplicateKeyInOneMap) {
  const auto r = load(kHead + R"(  joystick.1:
    x: right_grip.x
    x: right_grip.y
)");
  EXPECT_THAT(errors(r), ElementsAre("t.yaml:11:5: duplicate key 'x' in joystick.1; expected each key once"));
}

TEST(MappingConfig, RangesExpandElementWiseAndLengthsMustAgree) {
  const auto r = load(kHead + R"(  buttons.2:
    switch[9]: cluster.in[5].bit0
    switch[10]: cluster.in[6].bit0
    switch[11]: cluster.in[7].bit0
    switch[12]: cluster.in[8].bit7
    switch: right_grip.buttons[1..8]
  indicators.1:
    indicator[1..4]: right_grip.leds[1..4]
)");
  ASSERT_TRUE(r.ok()) << r.error_text();
  const auto& b2 = r.config->functional_elements[0];
  ASSERT_EQ(b2.fields.size(), 12u);
  EXPECT_EQ(b2.fields[0].field.name, "switch[1]");
  EXPECT_EQ(b2.fields[0].signal, "buttons[1]");
  EXPECT_EQ(b2.fields[0].signal_bit, 0xFF);  // a Button: the whole value
  EXPECT_EQ(b2.fields[8].field.name, "switch[9]");
  EXPECT_EQ(b2.fields[8].signal, "in[5]");
  EXPECT_EQ(b2.fields[8].field.sub, 0x3A);  // cluster 2: 39h.., switch 9 is the next byte
  EXPECT_EQ(b2.fields[11].signal, "in[8]");
  EXPECT_EQ(b2.fields[11].signal_bit, 7);
  EXPECT_EQ(r.config->functional_elements[1].fields[3].signal, "leds[4]");

  const auto bad = load(kHead + R"(  joystick.1:
    buttons[1..3]: right_grip.buttons[1]
    x: right_grip.buttons[1..2]
    buttons[4]: right_grip.buttons[2..3]
  buttons.1:
    switch: knob.position
  joystick.2:
    buttons: right_grip.buttons[1..9]
)");
  EXPECT_THAT(
      errors(bad),
      ElementsAre(
          "t.yaml:10:20: joystick.1 buttons[1..3] has 3 elements but 'right_grip.buttons[1]' has 1; expected ranges of "
          "equal length",
          "t.yaml:11:8: joystick.1 x has 1 element but 'right_grip.buttons[1..2]' has 2; expected ranges of equal "
          "length",
          "t.yaml:12:17: joystick.1 buttons[4] has 1 element but 'right_grip.buttons[2..3]' has 2; expected ranges of "
          "equal length",
          "t.yaml:14:13: found the single signal 'knob.position' for the field group buttons.1 switch; expected a "
          "signal range such as knob.buttons[1..8], or a bit-packed signal",
          "t.yaml:16:14: signal range 'right_grip.buttons[1..9]' has 9 elements but joystick.2 has buttons[1..8]; "
          "expected at most 8 signals"));
}

TEST(MappingConfig, BitPackedSignalsFeedOneBitFieldsBitByBit) {
  // cia401 in[k]/out[k] are bytes (0..255, "bits"): one byte feeds eight switches or is driven
  // by eight indicators; `.bitN` picks one bit.
  const auto r = load(kHead + R"(  buttons.1:
    switch: cluster.in[1..2]
  joystick.1:
    buttons[1..8]: cluster.in[3]
    memory_x: cluster.in[4].bit5
  indicators.1:
    indicator[9..16]: cluster.out[2]
    indicator[17]: cluster.out[3].bit2
)");
  ASSERT_TRUE(r.ok()) << r.error_text();
  const auto& j1 = r.config->functional_elements[0];
  ASSERT_EQ(j1.fields.size(), 9u);
  EXPECT_EQ(j1.fields[0].field.name, "memory_x");
  EXPECT_EQ(j1.fields[0].signal, "in[4]");
  EXPECT_EQ(j1.fields[0].signal_bit, 5);
  EXPECT_EQ(j1.fields[8].field.name, "buttons[8]");
  EXPECT_EQ(j1.fields[8].signal_bit, 7);
  const auto& b1 = r.config->functional_elements[1];
  ASSERT_EQ(b1.fields.size(), 16u);  // switch[1..16] from two bytes
  EXPECT_EQ(b1.fields[9].field.name, "switch[10]");
  EXPECT_EQ(b1.fields[9].signal, "in[2]");
  EXPECT_EQ(b1.fields[9].signal_bit, 1);
  const auto& i1 = r.config->functional_elements[2];
  ASSERT_EQ(i1.fields.size(), 9u);
  EXPECT_EQ(i1.fields[0].field.name, "indicator[9]");
  EXPECT_EQ(i1.fields[0].signal, "out[2]");
  EXPECT_EQ(i1.fields[0].signal_bit, 0);
  EXPECT_EQ(i1.fields[8].signal, "out[3]");
  EXPECT_EQ(i1.fields[8].signal_bit, 2);
  EXPECT_EQ(i1.fields[8].output_params().signal_bit, 2);
  EXPECT_EQ(j1.fields[0].input_params().signal_bit, 5);

  const auto bad = load(kHead + R"(  buttons.1:
    switch[1..4]: cluster.in[1]
    switch[5]: cluster.in[2].bit8
    switch[6]: left_grip.buttons[1].bit0
    switch[7]: "cluster.in[1..2].bit0"
  indicators.1:
    indicator[1..8]: cluster.out[1]
    indicator[9]: cluster.out[1].bit3
  joystick.1:
    buttons: cluster.in[1..2]
)");
  EXPECT_THAT(
      errors(bad),
      ElementsAre(
          "t.yaml:10:19: buttons.1 switch[1..4] has 4 elements but 'cluster.in[1]' has 8 bits; expected ranges of "
          "equal "
          "length",
          "t.yaml:11:16: found bit 8 of 'cluster.in[2]'; expected a bit 0..7",
          "t.yaml:12:16: found bit 0 of 'left_grip.buttons[1]', which is not bit-packed; expected the signal without "
          ".bitN",
          "t.yaml:13:16: found 'cluster.in[1..2].bit0' for buttons.1 switch[7]; expected a signal as subdevice.signal, "
          "subdevice.signal[a..b] or subdevice.signal.bitN",
          "t.yaml:16:19: output signal 'cluster.out[1] bit 3' is driven twice (first at line 15, column 5); expected "
          "each output driven by one field",
          "t.yaml:18:14: signal range 'cluster.in[1..2]' has 16 bits but joystick.1 has buttons[1..8]; expected at "
          "most 8 "
          "signals"));
}

TEST(MappingConfig, DriversAndTheirOptionsAreCheckedByTheCatalogue) {
  const auto r = load(R"(upstream: { node_id: 1 }
downstream: { interface: can1 }
subdevices:
  a: { driver: mcb420, node_id: 2 }
  b: { driver: cia401, node_id: 3 }
  c: { driver: elobau-mfg, node_id: 4, options: { colour: red } }
  d: { node_id: 5 }
functional_elements:
  joystick.1: { x: a.x, y: b.analog }
)");
  EXPECT_THAT(
      errors(r),
      ElementsAre(
          "t.yaml:4:16: unknown driver 'mcb420'; expected one of elobau-mfg, mcb402, novotechnik-406, "
          "cia401 (did you mean 'mcb402'?)",
          "t.yaml:5:16: driver cia401 refused sub-device 'b': option 'eds' missing; expected options the cia401 driver "
          "accepts",
          "t.yaml:6:59: driver elobau-mfg refused sub-device 'c': unknown option 'colour'; expected options the "
          "elobau-mfg driver accepts",
          "t.yaml:7:6: no 'driver' in sub-device 'd'; expected one of elobau-mfg, mcb402, novotechnik-406, cia401"));
  // Signals of a refused driver are not reported again; an option refused is reported at its value.
}

TEST(MappingConfig, SdoWritesAreTypedAndRangeChecked) {
  const auto r = load(R"(upstream: { node_id: 1 }
downstream: { interface: can1 }
subdevices:
  a:
    driver: mcb402
    node_id: 2
    sdo:
      - { index: 0x1017, sub_index: 0, value: 70000, type: u16 }
      - { index: 0x2000, sub_index: 1, value: -129, type: i8 }
      - { index: 0x2000, sub_index: 2, value: 1, type: uint8 }
      - { index: 0x0FFF, sub_index: 0, value: 1, type: u8 }
      - { index: 0x2001, value: 1, type: u8 }
      - { index: 0x2002, sub_index: 0, value: -2, type: i16 }
functional_elements: {}
)");
  EXPECT_THAT(errors(r), ElementsAre("t.yaml:8:47: value of type u16 70000 is out of range; expected 0x0..0xFFFF",
                                     "t.yaml:9:47: value of type i8 -129 is out of range; expected -128..127",
                                     "t.yaml:10:56: found 'uint8' for type; expected one of u8, u16, u32, i8, i16, i32",
                                     "t.yaml:11:18: index 0x0FFF is out of range; expected 0x1000..0xFFFF",
                                     "t.yaml:12:9: no 'sub_index' in an sdo write; expected a sub-index 0..255"));
  const auto ok = load(R"(upstream: { node_id: 1 }
downstream: { interface: can1 }
subdevices:
  a: { driver: mcb402, node_id: 2, sdo: [ { index: 0x2002, sub_index: 0, value: -2, type: i16 } ] }
functional_elements: {}
)");
  ASSERT_TRUE(ok.ok()) << ok.error_text();
  EXPECT_EQ(ok.config->subdevices[0].sdo[0].to_sdo_write().data, (std::vector<std::uint8_t>{0xFE, 0xFF}));
}

TEST(MappingConfig, LongFormOptionsAreParsedAndChecked) {
  const auto r = load(kHead + R"(  joystick.1:
    x: { signal: right_grip.x, scale: 300, offset: -5, deadband: 2, invert: true, clamp: [-30000, 30000], fault: 7, interlock: false }
    buttons: { signal: "right_grip.buttons[1..2]", invert: yes }
  indicators.1:
    indicator[1]: { signal: "right_grip.leds[1]", scale: 2 }
)");
  ASSERT_TRUE(r.ok()) << r.error_text();
  const auto& x = r.config->functional_elements[0].fields[2];
  ASSERT_EQ(x.field.name, "x");
  EXPECT_EQ(x.options.scale, std::optional<double>(300.0));
  EXPECT_EQ(x.options.offset, -5);
  EXPECT_EQ(x.options.deadband, 2);
  EXPECT_TRUE(x.options.invert);
  EXPECT_EQ(x.options.clamp, (std::pair<std::int64_t, std::int64_t>(-30000, 30000)));
  EXPECT_EQ(x.options.fault, std::optional<std::int64_t>(7));
  EXPECT_EQ(x.options.interlock, std::optional<bool>(false));
  EXPECT_TRUE(r.config->functional_elements[0].fields[1].options.invert);  // buttons[2]
  EXPECT_EQ(r.config->functional_elements[1].fields[0].output_params().scale, 2.0);

  const auto bad = load(kHead + R"(  joystick.1:
    x: { signal: right_grip.x, clamp: [5, -5], scale: 0 }
    y: { signal: right_grip.y, deadband: -1, invert: maybe }
    z: { scale: 2 }
  indicators.1:
    indicator[1]: { signal: "right_grip.leds[1]", deadband: 2 }
  joystick.2:
    buttons[1]: { signal: "right_grip.buttons[1]", scale: 2, fault: 2 }
    x: { signal: right_grip.x, fault: 40000, clamp: [-40000, 0] }
  encoder.1:
    position: { signal: knob.position, fault: 40000, clamp: [0, 40000] }
)");
  EXPECT_THAT(
      errors(bad),
      ElementsAre(
          "t.yaml:10:39: found [5, -5] for clamp; expected [min, max] with integers -32768 <= min <= max <= 32767",
          "t.yaml:10:55: found '0' for scale; expected a non-zero number",
          "t.yaml:11:42: deadband -1 is out of range; expected 0..2147483647",
          "t.yaml:11:54: found 'maybe' for invert; expected true or false",
          "t.yaml:12:8: no 'signal' in joystick.1 z; expected the feeding signal, e.g. right_grip.x",
          "t.yaml:14:51: unknown key 'deadband' in indicators.1 indicator[1]; expected one of signal, scale, offset, "
          "invert, clamp",
          "t.yaml:16:52: unknown key 'scale' in joystick.2 buttons[1]; expected one of signal, invert, fault, "
          "interlock",
          "t.yaml:16:69: fault 2 is out of range; expected 0..1",
          "t.yaml:17:39: fault 40000 is out of range; expected -32768..32767",
          "t.yaml:17:53: found [-40000, 0] for clamp; expected [min, max] with integers -32768 <= min <= max <= "
          "32767"));
  // An UNSIGNED32 field (6120h) takes what an INTEGER16 one refuses.
  EXPECT_EQ(bad.errors.size(), 10u);
}

TEST(MappingConfig, SubdeviceIdentityHeartbeatAndOptionsAreKept) {
  const auto r = load(R"(upstream: { node_id: 1 }
downstream: { interface: can1 }
subdevices:
  a:
    driver: elobau-mfg
    node_id: 2
    heartbeat_ms: 50
    heartbeat_timeout_ms: 120
    mandatory: true
    identity: { device_type: 0x00010196, vendor_id: 0x0000004B, product_code: 12, revision: 0x00020001, serial: 99 }
    options: { tolerance: 3 }
  b: { driver: mcb402, node_id: 3, identity: { vendor_id: 7 } }
functional_elements: {}
)");
  ASSERT_TRUE(r.ok()) << r.error_text();
  const auto& a = r.config->subdevices[0];
  EXPECT_EQ(a.heartbeat_ms, 50);
  EXPECT_EQ(a.heartbeat_timeout_ms, 120);
  EXPECT_TRUE(a.mandatory);
  EXPECT_EQ(a.identity.device_type, std::optional<std::uint32_t>(0x00010196));
  EXPECT_EQ(a.identity.vendor_id, std::optional<std::uint32_t>(0x4B));
  EXPECT_EQ(a.identity.product_code, std::optional<std::uint32_t>(12));
  EXPECT_EQ(a.identity.revision, std::optional<std::uint32_t>(0x00020001));
  EXPECT_EQ(a.identity.serial, std::optional<std::uint32_t>(99));
  EXPECT_EQ(a.options.get("tolerance"), std::optional<std::string>("3"));
  EXPECT_EQ(a.node(), subdevices::NodeId{2});
  const auto ns = a.node_settings();
  EXPECT_EQ(ns.name, "a");
  EXPECT_EQ(ns.node, subdevices::NodeId{2});
  EXPECT_EQ(ns.heartbeat_ms, 50);
  EXPECT_EQ(ns.heartbeat_timeout_ms, 120);
  EXPECT_TRUE(ns.mandatory);
  EXPECT_EQ(ns.identity.serial, std::optional<std::uint32_t>(99));
  const auto& b = r.config->subdevices[1];
  EXPECT_EQ(b.identity.vendor_id, std::optional<std::uint32_t>(7));
  EXPECT_FALSE(b.identity.product_code.has_value());  // unset: not checked
}

TEST(MappingConfig, HeartbeatTimeoutMustExceedTheHeartbeat) {
  const auto r = load(R"(upstream: { node_id: 1 }
downstream: { interface: can1 }
subdevices:
  a: { driver: mcb402, node_id: 2, heartbeat_ms: 100, heartbeat_timeout_ms: 100 }
  b: { driver: mcb402, node_id: 3, heartbeat_ms: 100, heartbeat_timeout_ms: 250 }
  c: { driver: mcb402, node_id: 4, heartbeat_ms: 0, heartbeat_timeout_ms: 10, pdo_timeout_ms: 100 }
functional_elements: {}
)");
  EXPECT_THAT(errors(r), ElementsAre("t.yaml:4:77: heartbeat_timeout_ms 100 is not longer than heartbeat_ms 100; "
                                     "expected more than 100 (or 0 for 1.5 x heartbeat_ms)"));
}

TEST(MappingConfig, ASubdeviceWithoutHeartbeatNeedsAPdoTimeout) {
  const auto r = load(R"(upstream: { node_id: 1 }
downstream: { interface: can1 }
subdevices:
  a: { driver: mcb402, node_id: 2, heartbeat_ms: 0 }
  b: { driver: mcb402, node_id: 3, heartbeat_ms: 0, pdo_timeout_ms: 200 }
functional_elements: {}
)");
  EXPECT_THAT(errors(r),
              ElementsAre("t.yaml:4:50: heartbeat_ms 0 leaves sub-device 'a' without proof of life; expected "
                          "a heartbeat (heartbeat_ms > 0) or pdo_timeout_ms > 0"));
  const auto ok = load(R"(upstream: { node_id: 1 }
downstream: { interface: can1 }
subdevices:
  b: { driver: mcb402, node_id: 3, heartbeat_ms: 0, pdo_timeout_ms: 200 }
functional_elements: {}
)");
  ASSERT_TRUE(ok.ok()) << ok.error_text();
  EXPECT_EQ(ok.config->subdevices[0].node_settings().pdo_timeout_ms, 200);
}

TEST(MappingConfig, PublishAndUpstreamSectionsKeepTheirData) {
  const auto r = load(R"(upstream:
  interface: can0
  node_id: 0x20
  bitrate: 500000
  identity: { vendor_id: 0x1234, product_code: 2, revision: 3, serial: 4 }
  heartbeat_ms: 250
  store: /var/lib/oegw/x.store
downstream: { interface: can1, bitrate: 125000 }
publish:
  dds: { domain: 7, partition: cab }
  lcm: { enabled: false, url: "udpm://239.255.76.67:7667?ttl=1", channel_prefix: CAB_ }
subdevices: {}
functional_elements: {}
)");
  ASSERT_TRUE(r.ok()) << r.error_text();
  const auto& c = *r.config;
  EXPECT_EQ(c.upstream.bitrate, 500000u);
  EXPECT_EQ(c.upstream.identity.vendor_id, 0x1234u);
  EXPECT_EQ(c.upstream.identity.serial, 4u);
  EXPECT_EQ(c.upstream.heartbeat_ms, 250);
  EXPECT_EQ(c.upstream.store, "/var/lib/oegw/x.store");
  EXPECT_EQ(c.downstream.bitrate, 125000u);
  EXPECT_TRUE(c.publish.dds.enabled);  // a dds section turns it on unless enabled: false
  EXPECT_EQ(c.publish.dds.domain, 7u);
  EXPECT_EQ(c.publish.dds.partition, "cab");
  EXPECT_FALSE(c.publish.lcm.enabled);
  EXPECT_EQ(c.publish.lcm.url, "udpm://239.255.76.67:7667?ttl=1");
  EXPECT_EQ(c.publish.lcm.channel_prefix, "CAB_");
}

// publish.dds.security: six file paths, all required, relative ones from the file's folder. What
// the files hold is checked elsewhere (publish/dds_security.hpp; tests/publish/dds_security_test.cpp).
TEST(MappingConfig, DdsSecurityTakesSixFilesFromTheFilesFolder) {
  const std::string head = R"(upstream: { interface: can0, node_id: 0x20 }
downstream: { interface: can1 }
publish:
  dds:
)";
  const std::string tail = "subdevices: {}\nfunctional_elements: {}\n";
  auto r = load_config_text(head + R"(    security:
      identity_ca: dds/ca.pem
      certificate: dds/gateway.pem
      private_key: /etc/keys/gateway.key
      permissions_ca: dds/ca.pem
      governance: ../shared/governance.p7s
      permissions: dds/permissions.p7s
)" + tail,
                            "/etc/oegw/oegw.yaml", fake_catalogue, std::filesystem::path("/etc/oegw"));
  ASSERT_TRUE(r.ok()) << r.error_text();
  ASSERT_TRUE(r.config->publish.dds.security.has_value());
  const auto& sec = *r.config->publish.dds.security;
  EXPECT_EQ(sec.path[DdsSecurityConfig::IdentityCa], "/etc/oegw/dds/ca.pem");
  EXPECT_EQ(sec.path[DdsSecurityConfig::PrivateKey], "/etc/keys/gateway.key");
  EXPECT_EQ(sec.path[DdsSecurityConfig::Governance], "/etc/shared/governance.p7s");
  EXPECT_EQ(sec.where[DdsSecurityConfig::Certificate].str(), "/etc/oegw/oegw.yaml:7:20");
  EXPECT_EQ(sec.section.str(), "/etc/oegw/oegw.yaml:5:5");
  const auto none = load(head + "    domain: 0\n" + tail);
  ASSERT_TRUE(none.ok()) << none.error_text();
  EXPECT_FALSE(none.config->publish.dds.security) << "absent: none";

  const auto bad = load(head + R"(    security:
      identity_ca: ca.pem
      certificate: ""
      private_key: k.pem
      permissions_ca: ca.pem
      governance: g.p7s
      permisions: p.p7s
)" + tail);
  EXPECT_THAT(errors(bad),
              ElementsAre("t.yaml:5:5: publish dds security has no permissions; expected a map with identity_ca, "
                          "certificate, private_key, permissions_ca, governance, permissions (file paths, from the "
                          "mapping file's folder)",
                          "t.yaml:7:20: found '' for certificate; expected a text",
                          ::testing::StartsWith(
                              "t.yaml:11:7: unknown key 'permisions' in publish dds security; expected "
                              "one of identity_ca, certificate, private_key, permissions_ca, governance, "
                              "permissions (did you mean 'permissions'?)")));
}

// Who may command an output FE (config.hpp CommandSource): canopen and dds by default (LCM is
// opt-in); a list narrows it; every mistake is named with its place.
TEST(MappingConfig, CommandSourcesPerOutputFe) {
  const std::string head = R"(upstream: { interface: can0, node_id: 0x20 }
downstream: { interface: can1 }
publish: { dds: { enabled: true }, lcm: { enabled: false } }
subdevices:
  grip: { driver: elobau-mfg, node_id: 0x11 }
  cluster: { driver: cia401, node_id: 0x31, options: { eds: x.eds } }
functional_elements:
)";  // functional elements start on line 8
  const auto r = load(head + R"(  indicators.1:
    sources: [dds]
    indicator[1..2]: grip.leds[1..2]
  indicators.2:
    sources: canopen
    indicator[1..8]: cluster.out[1]
  display.1:
    parameter[1]: cluster.aout[1]
)");
  ASSERT_TRUE(r.ok()) << r.error_text();
  const auto* i1 = r.config->find_fe({FeKind::IndicatorCluster, 1});
  const auto* i2 = r.config->find_fe({FeKind::IndicatorCluster, 2});
  const auto* d1 = r.config->find_fe({FeKind::Display, 1});
  ASSERT_TRUE(i1 && i2 && d1);
  EXPECT_TRUE(i1->accepts(CommandSource::Dds));
  EXPECT_FALSE(i1->accepts(CommandSource::Canopen));
  EXPECT_FALSE(i1->accepts(CommandSource::Lcm));
  EXPECT_EQ(describe_sources(i1->sources), "dds");
  EXPECT_EQ(i1->sources_where.str(), "t.yaml:9:14");
  EXPECT_EQ(describe_sources(i2->sources), "canopen");
  EXPECT_EQ(d1->sources, kDefaultCommandSources) << "absent: canopen and dds; LCM only when listed";
  EXPECT_FALSE(d1->accepts(CommandSource::Lcm));
  EXPECT_EQ(describe_sources(d1->sources), "canopen, dds");
  EXPECT_EQ(r.config->find_fe({FeKind::IndicatorCluster, 3}), nullptr);

  const auto bad = load(head + R"(  indicators.1:
    sources: [dds, ddz, dds]
    indicator[1..2]: grip.leds[1..2]
  indicators.2:
    sources: []
    indicator[1..8]: cluster.out[1]
  indicators.3:
    sources: [lcm]
    indicator[3..4]: grip.leds[3..4]
  indicators.4:
    sources: [canopen]
  joystick.1:
    sources: [dds]
    x: grip.x
)");
  EXPECT_THAT(errors(bad),
              ElementsAre("t.yaml:9:20: found 'ddz' in indicators.1 sources; expected one of canopen, dds, lcm "
                          "(did you mean 'dds'?)",
                          "t.yaml:9:25: 'dds' appears twice in indicators.1 sources; expected each source once",
                          "t.yaml:12:14: found [] for indicators.2 sources; expected a list of canopen, "
                          "dds, lcm, e.g. sources: [canopen, dds]",
                          "t.yaml:15:14: indicators.3 takes commands only from lcm, which the publish section does "
                          "not enable; expected publish.lcm.enabled true, or canopen among the sources",
                          "t.yaml:18:5: indicators.4 has only 'sources' and no fields; expected at least one field "
                          "fed by a signal",
                          "t.yaml:20:5: joystick.1 is an input; 'sources' applies to indicators and display "
                          "(commands in)"));
}

TEST(MappingConfig, CommandTimeoutPerOutputFe) {
  const std::string head = R"(upstream: { interface: can0, node_id: 0x20 }
downstream: { interface: can1 }
subdevices:
  grip: { driver: elobau-mfg, node_id: 0x11 }
functional_elements:
)";  // functional elements start on line 6
  const auto r = load(head + R"(  indicators.1:
    command_timeout_ms: 250
    indicator[1..2]: grip.leds[1..2]
  indicators.2:
    indicator[1..2]: grip.leds[3..4]
)");
  ASSERT_TRUE(r.ok()) << r.error_text();
  EXPECT_EQ(r.config->find_fe({FeKind::IndicatorCluster, 1})->command_timeout_ms, 250u);
  EXPECT_EQ(r.config->find_fe({FeKind::IndicatorCluster, 2})->command_timeout_ms, 0u) << "off by default";
  const auto bad = load(head + R"(  indicators.1:
    command_timeout_ms: 700000
    indicator[1..2]: grip.leds[1..2]
  joystick.1:
    command_timeout_ms: 100
    x: grip.x
  indicators.2:
    command_timeout_ms: 100
)");
  EXPECT_THAT(errors(bad),
              ElementsAre("t.yaml:7:25: indicators.1 command_timeout_ms 700000 is out of range; expected 0..600000",
                          "t.yaml:10:5: joystick.1 is an input; 'command_timeout_ms' applies to indicators and "
                          "display (commands in)",
                          "t.yaml:13:5: indicators.2 has only 'command_timeout_ms' and no fields; expected at least "
                          "one field fed by a signal"));
}

// The host-local LCM default uses the all-hosts group 224.0.0.1 with ttl=0; a link-local group
// with a ttl above 0 would reach every device on the cab network and is refused.
TEST(MappingConfig, LcmLinkLocalGroupOnlyWithTtlZero) {
  auto with_url = [](const std::string& url) {
    return load(
        "upstream: { interface: can0, node_id: 0x20 }\ndownstream: { interface: can1 }\n"
        "publish:\n  lcm: { url: \"" +
        url + "\" }\nsubdevices: {}\nfunctional_elements: {}\n");
  };
  EXPECT_EQ(LcmConfig{}.url, "udpm://224.0.0.1:7667?ttl=0");
  EXPECT_TRUE(with_url("udpm://224.0.0.1:7667?ttl=0").ok());
  EXPECT_TRUE(with_url("udpm://224.0.0.1:7667").ok()) << "LCM's default ttl is 0";
  EXPECT_TRUE(with_url("udpm://239.255.76.67:7667?ttl=1").ok());
  EXPECT_TRUE(with_url("udpm://224.0.1.5:7667?ttl=1").ok()) << "not link-local";
  EXPECT_THAT(errors(with_url("udpm://224.0.0.1:7667?recv_buf_size=65536&ttl=1")),
              ElementsAre("t.yaml:4:15: publish lcm url 'udpm://224.0.0.1:7667?recv_buf_size=65536&ttl=1' sends to "
                          "the link-local group 224.0.0.1 with ttl '1', so every host on the network would receive "
                          "it; expected ttl=0 (this host only) or a 239.x.x.x group for a network, e.g. "
                          "udpm://239.255.76.67:7667?ttl=1"));
  // Whatever liblcm would read as a ttl above 0, or as a 224.0.0.x address, never a crash.
  for (const char* url : {"udpm://224.0.0.1:7667?ttl=99999999999999999999", "udpm://224.0.0.1:7667?ttl=0x1",
                          "udpm://224.0.0.1:7667?ttl=-1", "udpm://224.0.0.1:7667?ttl=1x", "udpm://224.0.1:7667?ttl=1",
                          "udpm://0xE0000001:7667?ttl=1", "udpm://224.0.0.1:7667?ttl=0&ttl=1"}) {
    const auto r = with_url(url);
    ASSERT_EQ(r.errors.size(), 1u) << url;
    EXPECT_NE(r.errors[0].message.find("link-local group 224.0.0.1"), std::string::npos) << r.error_text();
  }
  EXPECT_TRUE(with_url("udpm://224.0.0.1:7667?ttl=1&ttl=0").ok()) << "the last ttl counts, as in liblcm";
}

TEST(MappingConfig, EveryPrefixOfTheDemoFileGivesAConfigOrErrorsNeverACrash) {
  std::ifstream in(source_dir() + "/config/demo.yaml");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(text.size(), 1000u);
  std::size_t ok = 0;
  for (std::size_t n = 0; n <= text.size(); n += 7) {
    const auto r = load(text.substr(0, n));
    EXPECT_NE(r.ok(), !r.errors.empty()) << n;  // exactly one of the two
    for (const auto& e : r.errors) {
      EXPECT_GE(e.where.line, 1);
      EXPECT_GE(e.where.column, 1);
    }
    ok += r.ok() ? 1 : 0;
  }
  EXPECT_GT(ok, 0u);  // the cuts after the last element's lines load
}

// An option may be a list of single values (the MCB-402's button_bits): the driver gets them
// joined by ','; a list holding a map or a list is an error at that list.
TEST(MappingConfig, ListOptionsReachTheDriverJoinedByCommas) {
  const auto r = load(R"(upstream: { node_id: 1 }
downstream: { interface: can1 }
subdevices:
  a: { driver: mcb402, node_id: 2, options: { button_bits: [1, 2, 3, 4, 5, 7, 6] } }
  b: { driver: mcb402, node_id: 3, options: { button_bits: "0,1,2,3,4,5,6" } }
functional_elements: {}
)");
  ASSERT_TRUE(r.ok()) << r.error_text();
  EXPECT_EQ(r.config->subdevices[0].options.get("button_bits"), std::optional<std::string>("1,2,3,4,5,7,6"));
  EXPECT_EQ(r.config->subdevices[1].options.get("button_bits"), std::optional<std::string>("0,1,2,3,4,5,6"));
  const auto bad = load(R"(upstream: { node_id: 1 }
downstream: { interface: can1 }
subdevices:
  a: { driver: mcb402, node_id: 2, options: { button_bits: [1, [2]] } }
functional_elements: {}
)");
  EXPECT_THAT(errors(bad), ElementsAre("t.yaml:4:60: found a list for option 'button_bits'; expected a single value "
                                       "or a list of single values"));
}

TEST(MappingConfig, MissingFileIsAnErrorNotACrash) {
  const auto r = load_config("/nonexistent/oegw.yaml", fake_catalogue);
  EXPECT_THAT(errors(r),
              ElementsAre(
                  "/nonexistent/oegw.yaml:1:1: cannot open: No such file or directory; expected a readable file"));
}

// ---- upstream.sdo_servers ------------------------------------------------------------------

namespace sdo_servers {

// The list entries start on line 4, each "    - " + entry; the file has one input FE, or with
// `outputs` also an indicator cluster (the gateway then consumes the other nodes' EMCYs, 1028h).
std::string file(const std::vector<std::string>& entries, bool outputs = false) {
  std::string t = "upstream:\n  node_id: 0x20\n  sdo_servers:\n";
  for (const auto& e : entries) t += "    - " + e + "\n";
  t += R"(downstream: { interface: can1 }
subdevices:
  right_grip: { driver: elobau-mfg, node_id: 0x11 }
  left_grip: { driver: mcb402, node_id: 0x03 }
functional_elements:
  joystick.1: { x: right_grip.x }
)";
  if (outputs) t += "  indicators.1:\n    indicator[1..2]: left_grip.leds[1..2]\n";
  return t;
}

}  // namespace sdo_servers

// Entry k is 1200h + k: bound or not, with both COB-IDs or none (disabled until the host writes them).
TEST(MappingConfig, SdoServersAreReadInOrder) {
  const auto r = load(sdo_servers::file(
      {"{ subdevice: right_grip, request: 0x690, response: 0x6B0 }", "{}", "{ request: 1700, response: 0x6A5 }"}));
  ASSERT_TRUE(r.ok()) << r.error_text();
  const auto& s = r.config->upstream.sdo_servers;
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(s[0].subdevice, "right_grip");
  EXPECT_EQ(s[0].request, 0x690u);
  EXPECT_EQ(s[0].response, 0x6B0u);
  EXPECT_TRUE(s[0].enabled());
  EXPECT_EQ(s[0].where.str(), "t.yaml:4:7");
  EXPECT_EQ(s[0].subdevice_where.str(), "t.yaml:4:20");
  EXPECT_EQ(s[0].request_where.str(), "t.yaml:4:41");
  EXPECT_EQ(s[0].response_where.str(), "t.yaml:4:58");
  EXPECT_TRUE(s[1].subdevice.empty());
  EXPECT_FALSE(s[1].enabled());
  EXPECT_FALSE(s[1].request.has_value());
  EXPECT_EQ(s[2].request, 0x6A4u);
  EXPECT_EQ(s[2].response, 0x6A5u);
  // None at all: the default.
  EXPECT_TRUE(load(kHead + "  joystick.1: { x: right_grip.x }\n").config->upstream.sdo_servers.empty());
}

TEST(MappingConfig, SdoServerEntryErrors) {
  using sdo_servers::file;
  EXPECT_EQ(errors(load(file({"{ subdevice: rigth_grip, request: 0x690, response: 0x6B0 }"}))),
            (std::vector<std::string>{"t.yaml:4:20: unknown sub-device 'rigth_grip' for SDO server 1201h; expected one "
                                      "of right_grip, left_grip (did you mean 'right_grip'?)"}));
  EXPECT_EQ(errors(load(file({"{}", "{ request: 0x690 }"}))),
            (std::vector<std::string>{"t.yaml:5:18: request of SDO server 1202h without response; expected both "
                                      "COB-IDs, or neither (the channel is then disabled until the host writes "
                                      "1202h:01/02)"}));
  EXPECT_EQ(errors(load(file({"{ subdevice: left_grip, response: 0x6B0 }"}))),
            (std::vector<std::string>{"t.yaml:4:41: response of SDO server 1201h without request; expected both "
                                      "COB-IDs, or neither (the channel is then disabled until the host writes "
                                      "1201h:01/02)"}));
  EXPECT_EQ(errors(load(file({"{ subdevice: right_grip, requets: 0x690, response: 0x6B0 }"}))),
            (std::vector<std::string>{
                "t.yaml:4:32: unknown key 'requets' in upstream sdo_servers entry 1 (1201h); expected one of "
                "subdevice, request, response (did you mean 'request'?)",
                "t.yaml:4:58: response of SDO server 1201h without request; expected both COB-IDs, or neither (the "
                "channel is then disabled until the host writes 1201h:01/02)"}));
  EXPECT_EQ(errors(load(file({"{ request: 0x800, response: 0x6B0 }"}))),
            (std::vector<std::string>{"t.yaml:4:18: request 0x800 is out of range; expected 0x0..0x7FF"}));
  EXPECT_EQ(errors(load(file({"[0x690, 0x6B0]"}))),
            (std::vector<std::string>{"t.yaml:4:7: found [0x690, 0x6B0] for upstream sdo_servers entry 1 (1201h); "
                                      "expected a map with subdevice, request, response"}));
  const std::string not_a_list = "upstream:\n  node_id: 0x20\n  sdo_servers: { request: 0x690 }\n" +
                                 sdo_servers::file({}).substr(sdo_servers::file({}).find("downstream"));
  EXPECT_EQ(errors(load(not_a_list)),
            (std::vector<std::string>{"t.yaml:3:16: found a map for sdo_servers; expected a list of {subdevice, "
                                      "request, response}"}));
}

// Restricted CAN-IDs (CiA 301 §7.3.5), each named with its range.
TEST(MappingConfig, SdoServerRestrictedCanIdsNameTheirRange) {
  const auto r =
      load(sdo_servers::file({"{ request: 0x605, response: 0x585 }", "{ request: 0x000, response: 0x07F }",
                              "{ request: 0x101, response: 0x6E0 }", "{ request: 0x720, response: 0x7E5 }"}));
  EXPECT_THAT(
      errors(r),
      ElementsAre(
          "t.yaml:4:18: request COB-ID 0x605 of SDO server 1201h is a CAN-ID CiA 301 restricts: 601h..67Fh (the "
          "default "
          "SDO client->server identifiers); expected an 11-bit COB-ID outside 000h..07Fh, 101h..180h, 581h..5FFh, "
          "601h..67Fh, 6E0h..6FFh, 701h..7FFh",
          "t.yaml:4:35: response COB-ID 0x585 of SDO server 1201h is a CAN-ID CiA 301 restricts: 581h..5FFh (the "
          "default SDO server->client identifiers); expected an 11-bit COB-ID outside 000h..07Fh, 101h..180h, "
          "581h..5FFh, 601h..67Fh, 6E0h..6FFh, 701h..7FFh",
          "t.yaml:5:18: request COB-ID 0x000 of SDO server 1202h is a CAN-ID CiA 301 restricts: 000h (NMT); expected "
          "an 11-bit COB-ID outside 000h..07Fh, 101h..180h, 581h..5FFh, 601h..67Fh, 6E0h..6FFh, 701h..7FFh",
          "t.yaml:5:35: response COB-ID 0x07F of SDO server 1202h is a CAN-ID CiA 301 restricts: 001h..07Fh "
          "(reserved); expected an 11-bit COB-ID outside 000h..07Fh, 101h..180h, 581h..5FFh, 601h..67Fh, 6E0h..6FFh, "
          "701h..7FFh",
          "t.yaml:6:18: request COB-ID 0x101 of SDO server 1203h is a CAN-ID CiA 301 restricts: 101h..180h "
          "(reserved); expected an 11-bit COB-ID outside 000h..07Fh, 101h..180h, 581h..5FFh, 601h..67Fh, 6E0h..6FFh, "
          "701h..7FFh",
          "t.yaml:6:35: response COB-ID 0x6E0 of SDO server 1203h is a CAN-ID CiA 301 restricts: 6E0h..6FFh "
          "(reserved); expected an 11-bit COB-ID outside 000h..07Fh, 101h..180h, 581h..5FFh, 601h..67Fh, 6E0h..6FFh, "
          "701h..7FFh",
          "t.yaml:7:18: request COB-ID 0x720 of SDO server 1204h is a CAN-ID CiA 301 restricts: 701h..77Fh (NMT error "
          "control); expected an 11-bit COB-ID outside 000h..07Fh, 101h..180h, 581h..5FFh, 601h..67Fh, 6E0h..6FFh, "
          "701h..7FFh",
          "t.yaml:7:35: response COB-ID 0x7E5 of SDO server 1204h is a CAN-ID CiA 301 restricts: 780h..7FFh "
          "(reserved, LSS); expected an 11-bit COB-ID outside 000h..07Fh, 101h..180h, 581h..5FFh, 601h..67Fh, "
          "6E0h..6FFh, 701h..7FFh"));
}

// A COB-ID used twice: among the channels (at the later, naming the earlier), and against the
// gateway's own COB-IDs on the host's bus.
TEST(MappingConfig, SdoServerCobIdsClash) {
  using sdo_servers::file;
  EXPECT_THAT(errors(load(file({"{ request: 0x690, response: 0x6B0 }", "{ request: 0x6B0, response: 0x6C0 }",
                                "{ request: 0x6D0, response: 0x6D0 }"}))),
              ElementsAre("t.yaml:5:18: request COB-ID 0x6B0 of SDO server 1202h is already used by SDO server 1201h "
                          "response (line 4, column 35); expected a COB-ID no other object of the gateway uses",
                          "t.yaml:6:35: response COB-ID 0x6D0 of SDO server 1203h is already used by SDO server 1203h "
                          "request (line 6, column 18); expected a COB-ID no other object of the gateway uses"));
  EXPECT_THAT(
      errors(load(file({"{ request: 0x1A0, response: 0x0A0 }", "{ request: 0x080, response: 0x100 }",
                        "{ request: 0x520, response: 0x2A0 }"}))),
      ElementsAre("t.yaml:4:18: request COB-ID 0x1A0 of SDO server 1201h clashes with the gateway's TPDO1 (180h "
                  "+ node-ID 20h); expected a COB-ID no other object of the gateway uses",
                  "t.yaml:4:35: response COB-ID 0x0A0 of SDO server 1201h clashes with the gateway's EMCY (080h "
                  "+ node-ID 20h); expected a COB-ID no other object of the gateway uses",
                  "t.yaml:5:18: request COB-ID 0x080 of SDO server 1202h clashes with the gateway's SYNC "
                  "(1005h); expected a COB-ID no other object of the gateway uses",
                  "t.yaml:5:35: response COB-ID 0x100 of SDO server 1202h clashes with TIME (100h, CiA 301 "
                  "predefined connection set); expected a COB-ID no other object of the gateway uses",
                  "t.yaml:6:18: request COB-ID 0x520 of SDO server 1203h clashes with the gateway's RPDO4 "
                  "(500h + node-ID 20h); expected a COB-ID no other object of the gateway uses",
                  "t.yaml:6:35: response COB-ID 0x2A0 of SDO server 1203h clashes with the gateway's TPDO2 "
                  "(280h + node-ID 20h); expected a COB-ID no other object of the gateway uses"));
  // The other nodes' EMCYs only when the gateway consumes them (1028h, with output FEs).
  const std::vector<std::string> emcy{"{ request: 0x091, response: 0x0FF }"};
  EXPECT_TRUE(load(file(emcy)).ok());
  EXPECT_THAT(errors(load(file(emcy, true))),
              ElementsAre("t.yaml:4:18: request COB-ID 0x091 of SDO server 1201h clashes with the EMCY of node 11h, "
                          "which the gateway consumes (1028h); expected a COB-ID no other object of the gateway uses",
                          "t.yaml:4:35: response COB-ID 0x0FF of SDO server 1201h clashes with the EMCY of node 7Fh, "
                          "which the gateway consumes (1028h); expected a COB-ID no other object of the gateway uses"));
}

TEST(MappingConfig, AtMost127SdoServers) {
  const std::vector<std::string> max(127, "{}");
  const auto ok = load(sdo_servers::file(max));
  ASSERT_TRUE(ok.ok()) << ok.error_text();
  EXPECT_EQ(ok.config->upstream.sdo_servers.size(), 127u);
  std::vector<std::string> more(129, "{}");
  EXPECT_EQ(errors(load(sdo_servers::file(more))),
            (std::vector<std::string>{"t.yaml:131:7: sdo_servers entry 128 is beyond 127Fh; expected at most 127 "
                                      "additional SDO server channels (1201h..127Fh)"}));
}

// ---- Bad input: what yaml-cpp would silently accept, limits, messages a new user can act on -----

TEST(MappingConfig, ASecondDocumentIsRefusedWhereItStarts) {
  const std::string one = kHead + "  joystick.1: { x: right_grip.x }\n";  // lines 1-9
  EXPECT_TRUE(load(one).ok()) << load(one).error_text();
  // yaml-cpp's Load reads the first document and drops the rest: a second node_id, junk, or an
  // empty document after "---" would never be seen.
  for (const std::string tail : {"---\nupstream: { node_id: 5 }\n", "---\n", "...\n---\n[unclosed\n"}) {
    const auto r = load(one + tail);
    ASSERT_FALSE(r.ok()) << tail;
    ASSERT_EQ(r.errors.size(), 1u);
    if (tail.back() == '\n' && tail.find('[') == std::string::npos) {
      EXPECT_EQ(r.errors[0].where.line, 10) << tail;
      EXPECT_THAT(r.errors[0].message, ::testing::HasSubstr("a second YAML document starts here")) << tail;
    }
  }
  // A leading "---" (one document) is fine.
  EXPECT_TRUE(load("---\n" + one).ok());
}

TEST(MappingConfig, BytesThatAreNotUtf8TextAreRefusedAtTheirPosition) {
  const std::string good = kHead + "  joystick.1: { x: right_grip.x }\n";
  auto with = [&](std::size_t at, std::string bytes) {
    std::string t = good;
    t.insert(at, bytes);
    return errors(load(t));
  };
  const auto line2 = good.find("downstream");
  EXPECT_EQ(with(line2 + 4, std::string(1, '\0')),
            (std::vector<std::string>{"t.yaml:2:5: byte 0x00 (NUL) is not text; expected a UTF-8 text file"}));
  EXPECT_EQ(with(3, "\x07"),  // inside a comment or not: a control character is no text
            (std::vector<std::string>{"t.yaml:1:4: byte 0x07 (a control character) is not text; expected a UTF-8 "
                                      "text file"}));
  EXPECT_EQ(with(line2, "\x8F"),
            (std::vector<std::string>{"t.yaml:2:1: byte 0x8F is not UTF-8; expected a UTF-8 text file"}));
  EXPECT_EQ(with(line2, "\xC0\xAF"),
            (std::vector<std::string>{"t.yaml:2:1: byte 0xC0 is not UTF-8; expected a UTF-8 text file"}));
  // UTF-8 itself, and a byte-order mark, are text.
  EXPECT_TRUE(load("\xEF\xBB\xBF" + good + "# Fahrersitz links, Knopf \xC3\xA4\n").ok());
}

TEST(MappingConfig, ATabInTheIndentationIsNamed) {
  std::string t = kHead + "  joystick.1:\n\tx: right_grip.x\n";
  const auto e = errors(load(t));
  ASSERT_EQ(e.size(), 1u);
  EXPECT_THAT(e[0], ::testing::StartsWith("t.yaml:10:1: YAML syntax error: "));
  EXPECT_THAT(e[0], ::testing::HasSubstr("(line 10 is indented with a tab: YAML indents with spaces only)"));
}

// Found by mapping_fuzz: on this 636-byte file yaml-cpp's LoadAll yields documents without end
// until memory runs out; the loader asks the parser for two documents at most.
TEST(MappingConfig, AFileOfEndlessDocumentsIsOneErrorNotAllTheMemory) {
  const auto r = load_config(source_dir() + "/tests/fuzz/regressions/mapping_loadall_oom.yaml", fake_catalogue);
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_THAT(r.errors[0].message, ::testing::HasSubstr("a second YAML document starts here"));
}

TEST(MappingConfig, AnIntegerBeyond64BitsIsOutOfRangeNotNaN) {
  const std::string t = "upstream: { interface: can0, node_id: 0x20, heartbeat_ms: 99999999999999999999999 }\n" +
                        kHead.substr(kHead.find("downstream")) + "  joystick.1: { x: right_grip.x }\n";
  EXPECT_EQ(errors(load(t)), (std::vector<std::string>{"t.yaml:1:59: heartbeat_ms 99999999999999999999999 is out of "
                                                       "range; expected 0..65535"}));
}

TEST(MappingConfig, AnUnknownDriverIsReportedOnce) {
  std::string t = kHead + "  joystick.1: { x: right_grip.x }\n";
  t.replace(t.find("elobau-mfg"), 10, "elobau-mgf");
  const auto e = errors(load(t));
  ASSERT_FALSE(e.empty());
  EXPECT_EQ(e[0],
            "t.yaml:4:25: unknown driver 'elobau-mgf'; expected one of elobau-mfg, mcb402, novotechnik-406, "
            "cia401 (did you mean 'elobau-mfg'?)");
}

// A driver family written in another case, with '-' where the name has none, or without its
// suffix is named: the did-you-mean ignores case and takes a name's first part.
TEST(MappingConfig, AFamilyWrittenNearlyRightIsNamed) {
  const auto r = load(R"(upstream: { node_id: 1 }
downstream: { interface: can1 }
subdevices:
  a: { driver: MCB402, node_id: 2 }
  b: { driver: mcb-402, node_id: 3 }
  c: { driver: novotechnik, node_id: 4 }
  d: { driver: Elobau, node_id: 5 }
  e: { driver: CiA401, node_id: 6 }
  f: { driver: elobau_mfg, node_id: 7 }
  g: { driver: joystick, node_id: 8 }
functional_elements: {}
)");
  const std::string families = "expected one of elobau-mfg, mcb402, novotechnik-406, cia401";
  EXPECT_THAT(errors(r),
              ElementsAre("t.yaml:4:16: unknown driver 'MCB402'; " + families + " (did you mean 'mcb402'?)",
                          "t.yaml:5:16: unknown driver 'mcb-402'; " + families + " (did you mean 'mcb402'?)",
                          "t.yaml:6:16: unknown driver 'novotechnik'; " + families +
                              " (did you mean 'novotechnik-406'?)",
                          "t.yaml:7:16: unknown driver 'Elobau'; " + families + " (did you mean 'elobau-mfg'?)",
                          "t.yaml:8:16: unknown driver 'CiA401'; " + families + " (did you mean 'cia401'?)",
                          "t.yaml:9:16: unknown driver 'elobau_mfg'; " + families + " (did you mean 'elobau-mfg'?)",
                          "t.yaml:10:16: unknown driver 'joystick'; " + families));
}

TEST(MappingConfig, NearMissComparesWithoutCaseAndTakesANamesFirstPart) {
  const std::vector<std::string_view> names = {"elobau-mfg", "mcb402", "novotechnik-406", "cia401"};
  EXPECT_EQ(near_miss("MCB402", names), "mcb402");
  EXPECT_EQ(near_miss("Novotechnik", names), "novotechnik-406");
  EXPECT_EQ(near_miss("mcb402", names), std::nullopt) << "a name of the list is no near miss";
  EXPECT_EQ(near_miss("mcb", names), std::nullopt) << "three letters of six are no near miss";
  EXPECT_EQ(near_miss("elo", names), std::nullopt) << "a first part is the whole part before '-'";
  EXPECT_EQ(did_you_mean("sub_devices", std::vector<std::string_view>{"subdevices", "functional_elements"}),
            " (did you mean 'subdevices'?)");
}

// A misspelt subdevices key was ten errors: the key, the missing section, and every FE naming a
// sub-device. It is one, at the key, naming the section it stands for.
TEST(MappingConfig, AMisspeltSubdevicesKeyIsOneErrorNotACascade) {
  const std::string fes = R"(functional_elements:
  joystick.1: { x: grip.x, y: grip.y, buttons: "grip.buttons[1..8]" }
  joystick.2: { x: base.x, y: base.y, z: base.z }
  indicators.1: { "indicator[1..2]": "grip.leds[1..2]", "indicator[3]": "base.leds[1]" }
)";
  const std::string devices = R"(
  grip: { driver: elobau-mfg, node_id: 0x11 }
  base: { driver: mcb402, node_id: 0x03 }
)";
  const std::string head = "upstream: { node_id: 1 }\ndownstream: { interface: can1 }\n";
  for (const std::string key : {"subdevice", "sub_devices", "Subdevices", "subdevics"})
    EXPECT_THAT(errors(load(head + key + ":" + devices + fes)),
                ElementsAre("t.yaml:3:1: unknown key '" + key +
                            "' in the file; expected one of upstream, downstream, "
                            "publish, control, record, subdevices, functional_elements (did you mean 'subdevices'?)"))
        << key;
  // Missing, or no map: that one error, not one per sub-device named.
  EXPECT_THAT(errors(load(head + fes)),
              ElementsAre("t.yaml:1:1: no 'subdevices' in the file; expected a subdevices section"));
  EXPECT_THAT(errors(load(head + "subdevices: [grip, base]\n" + fes)),
              ElementsAre("t.yaml:3:13: found [grip, base] for subdevices; expected a map of sub-device name -> "
                          "{driver, node_id, ...}"));
  // A section that is there still has every unknown name reported.
  EXPECT_THAT(errors(load(head + "subdevices:\n  grip: { driver: elobau-mfg, node_id: 0x11 }\n" + fes)),
              ElementsAre("t.yaml:7:20: unknown sub-device 'base' in signal 'base.x'; expected one of grip",
                          "t.yaml:7:31: unknown sub-device 'base' in signal 'base.y'; expected one of grip",
                          "t.yaml:7:42: unknown sub-device 'base' in signal 'base.z'; expected one of grip",
                          "t.yaml:8:73: unknown sub-device 'base' in signal 'base.leds[1]'; expected one of grip"));
}

// An elobau LED takes the codes 0..2 (off / on / blink): an indicator bit's scale or offset that
// drives it beyond is refused at that option, with the range; one that fits, or an explicit
// clamp, is not.
TEST(MappingConfig, AnIndicatorsScaleBeyondItsOutputsRangeIsRefused) {
  const auto r = load(kHead + R"(  indicators.1:
    indicator[1]: { signal: "right_grip.leds[1]", scale: 3 }
    indicator[2]: { signal: "right_grip.leds[2]", offset: -1 }
    indicator[3..4]: { signal: "right_grip.leds[3..4]", scale: 2, offset: 1 }
    indicator[5]: { signal: "right_grip.leds[5]", scale: 2 }
    indicator[6]: { signal: "right_grip.leds[6]", scale: 3, clamp: [0, 2] }
    indicator[7]: { signal: "right_grip.leds[7]", scale: 2, invert: true }
)");
  EXPECT_THAT(errors(r),
              ElementsAre("t.yaml:10:58: scale 3 gives indicators.1 indicator[1] on as 3, beyond the range 0..2 of "
                          "output signal 'right_grip.leds[1]'; expected off and on inside 0..2",
                          "t.yaml:11:59: offset -1 gives indicators.1 indicator[2] off as -1, beyond the range 0..2 of "
                          "output signal 'right_grip.leds[2]'; expected off and on inside 0..2",
                          "t.yaml:12:64: scale 2, offset 1 gives indicators.1 indicator[3] on as 3, beyond the range "
                          "0..2 of output signal 'right_grip.leds[3]'; expected off and on inside 0..2"));
  const auto ok = load(kHead + R"(  indicators.1:
    indicator[5]: { signal: "right_grip.leds[5]", scale: 2 }
    indicator[6]: { signal: "right_grip.leds[6]", scale: 3, clamp: [0, 2] }
)");
  ASSERT_TRUE(ok.ok()) << ok.error_text();
}

// A source an output FE lists whose transport is off can never deliver a command: an error
// naming the setting, whether or not another source can.
TEST(MappingConfig, AListedSourceWhoseTransportIsOffIsRefused) {
  const std::string head = R"(upstream: { interface: can0, node_id: 0x20 }
downstream: { interface: can1 }
subdevices:
  grip: { driver: elobau-mfg, node_id: 0x11 }
)";
  const std::string fes = R"(functional_elements:
  indicators.1:
    sources: [canopen, lcm]
    indicator[1..2]: grip.leds[1..2]
  indicators.2:
    sources: [canopen, dds]
    indicator[1..2]: grip.leds[3..4]
  indicators.3:
    indicator[1..2]: grip.leds[5..6]
)";
  EXPECT_THAT(errors(load(head + fes)),
              ElementsAre("t.yaml:7:14: indicators.1 sources list lcm, but the file has no publish.lcm section "
                          "(publish.lcm.enabled is false): no LCM command can reach it; expected publish.lcm.enabled "
                          "true, or lcm off the sources",
                          "t.yaml:10:14: indicators.2 sources list dds, but the file has no publish.dds section "
                          "(publish.dds.enabled is false): no DDS command can reach it; expected publish.dds.enabled "
                          "true, or dds off the sources"));
  EXPECT_THAT(errors(load(head + "publish: { lcm: { enabled: false }, dds: { enabled: true } }\n" + fes)),
              ElementsAre("t.yaml:8:14: indicators.1 sources list lcm, but publish.lcm.enabled is false: no LCM "
                          "command can reach it; expected publish.lcm.enabled true, or lcm off the sources"));
  const auto ok = load(head + "publish: { lcm: {}, dds: {} }\n" + fes);
  EXPECT_TRUE(ok.ok()) << ok.error_text();
}

TEST(MappingConfig, ARefusedSubdeviceNameIsNoSuggestion) {
  std::string t = kHead + "  joystick.1: { x: right_gripp.x }\n";
  t.replace(t.find("right_grip:"), 10, "Right_grip");
  for (const auto& e : errors(load(t)))
    EXPECT_THAT(e, ::testing::Not(::testing::HasSubstr("did you mean 'Right_grip'")));
  EXPECT_THAT(errors(load(t)),
              ::testing::Contains(::testing::HasSubstr("sub-device name 'Right_grip' has characters")));
}

TEST(MappingConfig, MergeKeysWriteTwinGrips) {
  const std::string t = R"(upstream: { interface: can0, node_id: 0x20 }
downstream: { interface: can1 }
subdevices:
  right_grip: &grip { driver: elobau-mfg, node_id: 0x11, heartbeat_ms: 50, mandatory: true }
  left_grip:
    <<: *grip
    node_id: 0x12
functional_elements:
  joystick.1: { x: right_grip.x }
  joystick.2: { x: left_grip.x }
)";
  const auto r = load(t);
  ASSERT_TRUE(r.ok()) << r.error_text();
  const auto* left = r.config->find_subdevice("left_grip");
  ASSERT_NE(left, nullptr);
  EXPECT_EQ(left->driver, "elobau-mfg");
  EXPECT_EQ(left->node_id, 0x12);  // its own key wins over the merged one
  EXPECT_EQ(left->heartbeat_ms, 50);
  EXPECT_TRUE(left->mandatory);
  // Several merged maps: the first that sets a key wins; a merge of a non-map is an error.
  const std::string several = R"(upstream: { interface: can0, node_id: 0x20 }
downstream: { interface: can1 }
subdevices:
  a: &a { driver: elobau-mfg, node_id: 0x11, heartbeat_ms: 50 }
  b: &b { driver: mcb402, node_id: 0x12, heartbeat_ms: 200, mandatory: true }
  c: { <<: [*b, *a], node_id: 0x13 }
functional_elements:
  joystick.1: { x: c.x }
)";
  const auto r2 = load(several);
  ASSERT_TRUE(r2.ok()) << r2.error_text();
  EXPECT_EQ(r2.config->find_subdevice("c")->driver, "mcb402");
  EXPECT_EQ(r2.config->find_subdevice("c")->heartbeat_ms, 200);
  EXPECT_TRUE(r2.config->find_subdevice("c")->mandatory);
  EXPECT_THAT(errors(load(R"(upstream: { interface: can0, node_id: 0x20, <<: 5 })")),
              ::testing::Contains(
                  ::testing::HasSubstr("for the merge key '<<' in upstream; expected an alias of a map")));
}

TEST(MappingConfig, LimitsAreNamedBeforeAnythingIsRead) {
  // 10^6 nested brackets: refused where the 33rd opens, before yaml-cpp recurses into them.
  const std::string deep = "upstream: " + std::string(1000000, '[');
  EXPECT_EQ(errors(load(deep)),
            (std::vector<std::string>{"t.yaml:1:43: [ ] and { } nested deeper than 32 levels; expected at most 32 "
                                      "(docs/reference/mapping-file.md#the-file-itself-limits-text-one-document)"}));
  // Brackets inside quotes and comments are text.
  EXPECT_TRUE(load(kHead + "  joystick.1: { x: right_grip.x }  # [[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[\n").ok());
  // Lists nested on one line ("- - - -") are as deep as they are wide.
  std::string dashes;
  for (int i = 0; i < 100; ++i) dashes += "- ";
  EXPECT_THAT(errors(load("subdevices:\n  " + dashes + "x\n")),
              ::testing::ElementsAre("t.yaml:2:1: indentation of 202 columns; expected at most 128 "
                                     "(docs/reference/mapping-file.md#the-file-itself-limits-text-one-document)"));
  // A 5000-byte value.
  EXPECT_THAT(errors(load("upstream: { interface: " + std::string(5000, 'c') + " }\n")),
              ::testing::ElementsAre("t.yaml:1:24: a value of 5000 bytes; expected at most 4096 "
                                     "(docs/reference/mapping-file.md#the-file-itself-limits-text-one-document)"));
  // Aliases that expand to 10^9 values.
  std::string laughs = "a0: &a0 [x, x, x, x, x, x, x, x, x, x]\n";
  for (int i = 1; i <= 9; ++i) {
    laughs += "a" + std::to_string(i) + ": &a" + std::to_string(i) + " [";
    for (int k = 0; k < 10; ++k) laughs += std::string(k ? ", " : "") + "*a" + std::to_string(i - 1);
    laughs += "]\n";
  }
  const auto e = errors(load(laughs));
  ASSERT_EQ(e.size(), 1u);
  EXPECT_THAT(e[0], ::testing::HasSubstr("more than 200000 values (an alias counted each time it is used)"));
  // The text itself.
  EXPECT_THAT(errors(load(std::string(1024 * 1024 + 1, '#'))),
              ::testing::ElementsAre("t.yaml:1:1: a text of 1048577 bytes; expected at most 1048576 "
                                     "(docs/reference/mapping-file.md#the-file-itself-limits-text-one-document)"));
}

TEST(MappingConfig, AtMost127Subdevices) {
  auto file = [](int n) {
    std::string t = "upstream: { interface: can0, node_id: 0x20 }\ndownstream: { interface: can1 }\nsubdevices:\n";
    for (int i = 1; i <= n; ++i)
      t += "  g" + std::to_string(i) + ": { driver: novotechnik-406, node_id: " + std::to_string(i > 127 ? 1 : i) +
           " }\n";
    return t + "functional_elements:\n  encoder.1: { position: g1.position }\n";
  };
  EXPECT_TRUE(load(file(127)).ok()) << load(file(127)).error_text();
  EXPECT_EQ(errors(load(file(128))),
            (std::vector<std::string>{"t.yaml:131:3: sub-device 128 ('g128'); expected at most 127 (one per CANopen "
                                      "node-ID)"}));
}

TEST(MappingConfig, OnlyARegularFileIsRead) {
  const auto one = [](const std::string& path) { return errors(load_config(path, fake_catalogue)); };
  EXPECT_EQ(one("/dev/zero"),
            (std::vector<std::string>{"/dev/zero:1:1: is a character device; expected a regular file"}));
  EXPECT_EQ(one(source_dir()),
            (std::vector<std::string>{source_dir() + ":1:1: is a directory; expected a regular file"}));
  EXPECT_EQ(one("/nonexistent/x.yaml"),
            (std::vector<std::string>{"/nonexistent/x.yaml:1:1: cannot open: No such file or directory; expected a "
                                      "readable file"}));
  // A FIFO with no writer: refused at once instead of blocking forever.
  const std::string fifo = ::testing::TempDir() + "oegw_mapping_fifo";
  std::remove(fifo.c_str());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_EQ(one(fifo), (std::vector<std::string>{fifo + ":1:1: is a FIFO; expected a regular file"}));
  std::remove(fifo.c_str());
}

}  // namespace
}  // namespace oegw::mapping

namespace oegw::mapping {
namespace {

// downstream.sync_period_ms: the SYNC the gateway produces for synchronous TPDOs (0 = none); a
// sub-device configured with a synchronous transmission type needs it.
TEST(MappingConfig, SyncPeriodIsInRangeAndNeededBySynchronousTypes) {
  auto with = [](const std::string& down, const std::string& knob_sdo) {
    std::string t = kHead;
    t.replace(t.find("interface: can1 }"), 17, "interface: can1" + down + " }");
    t.replace(t.find("node_id: 0x7F }"), 15, "node_id: 0x7F" + knob_sdo + " }");
    return load(t + "  joystick.1: { x: right_grip.x }\n");
  };
  const auto dflt = with("", "");
  ASSERT_TRUE(dflt.ok()) << dflt.error_text();
  EXPECT_EQ(dflt.config->downstream.sync_period_ms, 0);
  const std::string sync_tpdo = ", sdo: [ { index: 0x1800, sub_index: 2, value: 4, type: u8 } ]";
  const auto set = with(", sync_period_ms: 20", sync_tpdo);
  ASSERT_TRUE(set.ok()) << set.error_text();
  EXPECT_EQ(set.config->downstream.sync_period_ms, 20);
  EXPECT_EQ(errors(with(", sync_period_ms: 10001", "")),
            (std::vector<std::string>{"t.yaml:2:48: sync_period_ms 10001 is out of range; expected 0..10000"}));
  EXPECT_EQ(
      errors(with("", sync_tpdo)),
      (std::vector<std::string>{
          "t.yaml:6:58: sub-device 'knob' sdo write 1800h:02 (TPDO transmission type) 4 is a synchronous "
          "transmission type (the PDO is sent only at a SYNC, CiA 301 §7.5.2.35) and downstream.sync_period_ms is "
          "0, so no SYNC is produced; expected downstream.sync_period_ms 1..10000, or an asynchronous type (254, "
          "255)"}));
  EXPECT_TRUE(with("", ", sdo: [ { index: 0x1800, sub_index: 2, value: 254, type: u8 } ]").ok());
}

// identity.revision_match: the revision's major part (default) or all of it.
TEST(MappingConfig, RevisionMatchIsMajorOrExact) {
  auto with = [](const std::string& id) {
    std::string t = kHead;
    t.replace(t.find("node_id: 0x7F }"), 15, "node_id: 0x7F, identity: { revision: 0x00010003" + id + " } }");
    return load(t + "  joystick.1: { x: right_grip.x }\n");
  };
  const auto dflt = with("");
  ASSERT_TRUE(dflt.ok()) << dflt.error_text();
  EXPECT_FALSE(dflt.config->find_subdevice("knob")->exact_revision);
  EXPECT_FALSE(dflt.config->find_subdevice("knob")->node_settings().exact_revision);
  const auto exact = with(", revision_match: exact");
  ASSERT_TRUE(exact.ok()) << exact.error_text();
  EXPECT_TRUE(exact.config->find_subdevice("knob")->node_settings().exact_revision);
  EXPECT_TRUE(with(", revision_match: major").ok());
  const auto bad = errors(with(", revision_match: minor"));
  ASSERT_EQ(bad.size(), 1u);
  EXPECT_NE(
      bad[0].find(
          "found 'minor' for revision_match; expected major (the upper 16 bits of 1018h:03, the default) or exact"),
      std::string::npos)
      << bad[0];
}

// ---- Paths: taken from the mapping file's folder (docs/reference/mapping-file.md#paths) ----

// A file naming its EDS file `eds` and its store `store`, as written.
std::string with_paths(const std::string& eds, const std::string& store) {
  return "upstream: { interface: can0, node_id: 0x20, store: '" + store +
         "' }\n"
         "downstream: { interface: can1 }\n"
         "subdevices:\n  io: { driver: cia401, node_id: 0x31, options: { eds: '" +
         eds +
         "' } }\n"
         "functional_elements:\n  pedal.1: { position: \"io.analog[1]\" }\n";
}

struct Paths {
  std::string eds, store;
};
Paths paths_of(const LoadResult& r) {
  if (!r.ok()) return {"not loaded: " + r.error_text(), ""};
  return {*r.config->subdevices[0].options.get("eds"), r.config->upstream.store};
}

TEST(MappingPaths, RelativePathsAreTakenFromTheBaseFolder) {
  const auto p = paths_of(load_config_text(with_paths("pedal.eds", "state/up.store"), "cab.yaml", fake_catalogue,
                                           std::filesystem::path("/etc/oegw")));
  EXPECT_EQ(p.eds, "/etc/oegw/pedal.eds");
  EXPECT_EQ(p.store, "/etc/oegw/state/up.store");
  // ".." leads out of the folder, and is folded: ../eds from /etc/oegw is /etc/eds.
  EXPECT_EQ(paths_of(load_config_text(with_paths("../eds/p.eds", "/var/lib/oegw/u.store"), "cab.yaml", fake_catalogue,
                                      std::filesystem::path("/etc/oegw")))
                .eds,
            "/etc/eds/p.eds");
}

TEST(MappingPaths, AbsolutePathsStayAsWrittenAndTildeIsNotExpanded) {
  const auto p = paths_of(load_config_text(with_paths("/usr/share/oegw/eds/p.eds", "~/u.store"), "cab.yaml",
                                           fake_catalogue, std::filesystem::path("/etc/oegw")));
  EXPECT_EQ(p.eds, "/usr/share/oegw/eds/p.eds");
  EXPECT_EQ(p.store, "/etc/oegw/~/u.store");  // no shell reads the file: "~" is a folder's name
}

TEST(MappingPaths, TextWithoutABaseFolderKeepsItsPathsAsWritten) {
  const auto p = paths_of(load(with_paths("subdevices/eds/p.eds", "u.store")));
  EXPECT_EQ(p.eds, "subdevices/eds/p.eds");
  EXPECT_EQ(p.store, "u.store");
}

TEST(MappingPaths, AFileOnDiskTakesItsPathsFromItsOwnFolderNotTheWorkingDirectory) {
  const auto dir = std::filesystem::temp_directory_path() / ("oegw-paths-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir / "cab");
  std::ofstream(dir / "cab/oegw.yaml") << with_paths("eds/p.eds", "u.store");
  const auto p = paths_of(load_config((dir / "cab/oegw.yaml").string(), fake_catalogue));
  EXPECT_EQ(p.eds, (dir / "cab/eds/p.eds").string());
  EXPECT_EQ(p.store, (dir / "cab/u.store").string());
  // Named from another folder by a relative path: still its own folder.
  const auto cwd = std::filesystem::current_path();
  std::filesystem::current_path(dir);
  const auto q = paths_of(load_config("cab/oegw.yaml", fake_catalogue));
  std::filesystem::current_path(cwd);
  EXPECT_EQ(q.eds, "cab/eds/p.eds");
  std::filesystem::remove_all(dir);
}

// ---- control: the local control socket (docs/reference/control-protocol.md) ----------------

const std::string kWhole = kHead + "  joystick.1: { x: right_grip.x }\n";

TEST(MappingConfig, ControlDefaultsWithoutTheSection) {
  const auto r = load(kWhole);
  ASSERT_TRUE(r.ok()) << r.error_text();
  EXPECT_TRUE(r.config->control.enabled);
  EXPECT_EQ(r.config->control.socket, "/run/oegw/oegw.sock");
  EXPECT_EQ(r.config->control.group, "");  // root's only (mode 0600)
}

TEST(MappingConfig, ControlSectionReadWithTheGroupsPosition) {
  const auto r = load("control: { socket: /run/cab2/oegw.sock, group: oegw }\n" + kWhole);
  ASSERT_TRUE(r.ok()) << r.error_text();
  EXPECT_EQ(r.config->control.socket, "/run/cab2/oegw.sock");
  EXPECT_EQ(r.config->control.group, "oegw");
  EXPECT_EQ(r.config->control.group_where.str(), "t.yaml:1:48");  // `oegw run` names it there
  const auto off = load("control: { enabled: false }\n" + kWhole);
  ASSERT_TRUE(off.ok()) << off.error_text();
  EXPECT_FALSE(off.config->control.enabled);
}

TEST(MappingConfig, ControlSectionErrorsNameTheSetting) {
  const std::string long_path = "/run/" + std::string(103, 'x');  // 108 characters
  EXPECT_THAT(errors(load("control: { socket: oegw.sock, group: \"Oegw Users\", enable: true }\n" + kWhole)),
              ElementsAre("t.yaml:1:20: control socket 'oegw.sock' is a relative path; expected an absolute path, "
                          "e.g. /run/oegw/oegw.sock",
                          "t.yaml:1:38: control group 'Oegw Users' is not a group name; expected a-z, 0-9, _ and - "
                          "(starting with a letter or _, at most 32), e.g. oegw",
                          "t.yaml:1:52: unknown key 'enable' in control; expected one of enabled, socket, group (did "
                          "you mean 'enabled'?)"));
  EXPECT_THAT(errors(load("control: { socket: " + long_path + " }\n" + kWhole)),
              ElementsAre("t.yaml:1:20: control socket path of 108 characters; expected at most 107 (a Unix socket "
                          "address holds no more)"));
  EXPECT_THAT(errors(load("control: { socket: /run/oegw/ }\n" + kWhole)),
              ElementsAre("t.yaml:1:20: control socket '/run/oegw/' names a folder; expected the socket file's path, "
                          "e.g. /run/oegw/oegw.sock"));
  EXPECT_THAT(errors(load("control: /run/oegw.sock\n" + kWhole)),
              ElementsAre(
                  "t.yaml:1:10: found '/run/oegw.sock' for control; expected a map with enabled, socket, group"));
}

// ---- record: the black box (docs/guides/black-box.md) ---------------------------------

TEST(MappingConfig, RecordIsOffWithoutTheSection) {
  const auto r = load(kWhole);
  ASSERT_TRUE(r.ok()) << r.error_text();
  EXPECT_FALSE(r.config->record.enabled);
  EXPECT_EQ(r.config->record.dir, "/var/lib/oegw/record");
  EXPECT_EQ(r.config->record.max_mib, 256u);
  EXPECT_EQ(r.config->record.span_s, 600u);
}

TEST(MappingConfig, RecordSectionReadWithItsFolderFromTheFilesFolder) {
  const auto r = load_config_text(
      "record: { enabled: true, dir: rec/, max_mib: 32, span_s: 120, segments: 4, "
      "queue_kib: 1024 }\n" +
          kWhole,
      "/etc/oegw/t.yaml", fake_catalogue, std::filesystem::path("/etc/oegw"));
  ASSERT_TRUE(r.ok()) << r.error_text();
  const RecordConfig& c = r.config->record;
  EXPECT_TRUE(c.enabled);
  EXPECT_EQ(c.dir, "/etc/oegw/rec");
  EXPECT_EQ(c.dir_where.str(), "/etc/oegw/t.yaml:1:31");
  EXPECT_EQ(c.max_mib, 32u);
  EXPECT_EQ(c.span_s, 120u);
  EXPECT_EQ(c.segments, 4u);
  EXPECT_EQ(c.queue_kib, 1024u);
}

TEST(MappingConfig, RecordSectionErrorsNameTheSetting) {
  EXPECT_THAT(errors(load("record: { enabled: maybe, max_mib: 0, span_s: 5, segments: 1, queue_kib: 32, size: 3 }\n" +
                          kWhole)),
              ElementsAre("t.yaml:1:20: found 'maybe' for record enabled; expected true or false",
                          "t.yaml:1:36: record max_mib 0 is out of range; expected 1..1048576",
                          "t.yaml:1:47: record span_s 5 is out of range; expected 10..604800",
                          "t.yaml:1:60: record segments 1 is out of range; expected 2..1000",
                          "t.yaml:1:74: record queue_kib 32 is out of range; expected 64..262144",
                          "t.yaml:1:78: unknown key 'size' in record; expected one of enabled, dir, max_mib, span_s, "
                          "segments, queue_kib"));
}

}  // namespace
}  // namespace oegw::mapping
