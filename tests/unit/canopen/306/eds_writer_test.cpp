// The EDS writer (CiA 306 INI) on the CiA 852 device's dictionary. EdsFile.* also writes the EDS
// of a device with every FE kind to $OEGW_EDS_OUT when set: tests/tools/eds_parse_check.py runs
// it and parses the file with python3's configparser (an independent reader).
#include "canopen/306/eds_writer.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "gateway/oe_device.hpp"

namespace oegw::gateway {
namespace {

using canopen::eds_text;
using canopen::EdsInfo;
using canopen::write_eds;
using mapping::FeId;
using mapping::FeKind;

// A minimal INI reader for the assertions: section -> key -> value, duplicates counted.
struct Ini {
  std::map<std::string, std::map<std::string, std::string>> sections;
  int duplicate_sections = 0;
  int duplicate_keys = 0;
};
Ini parse(const std::string& text) {
  Ini ini;
  std::istringstream in(text);
  std::string line, current;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    if (line.front() == '[') {
      current = line.substr(1, line.find(']') - 1);
      if (ini.sections.count(current)) ++ini.duplicate_sections;
      ini.sections[current];
      continue;
    }
    const auto eq = line.find('=');
    const std::string k = line.substr(0, eq);
    if (ini.sections[current].count(k)) ++ini.duplicate_keys;
    ini.sections[current][k] = line.substr(eq + 1);
  }
  return ini;
}

OeDeviceConfig full_config() {
  OeDeviceConfig c;
  c.node_id = canopen::NodeId{0x20};
  c.identity = {.vendor = 0x00001234, .product = 0x852, .revision = 0x00010002, .serial = 9};
  c.fes = {{FeKind::Joystick, 1}, {FeKind::Joystick, 2},      {FeKind::FootPedal, 1},        {FeKind::Encoder, 1},
           {FeKind::Wheel, 1},    {FeKind::ButtonCluster, 1}, {FeKind::IndicatorCluster, 1}, {FeKind::Display, 1}};
  c.host_node = 1;
  c.host_heartbeat_ms = 500;
  return c;
}

EdsInfo info_for(const OeDeviceConfig& c) {
  EdsInfo i;
  i.vendor = c.identity.vendor;
  i.product = c.identity.product;
  i.revision = c.identity.revision;
  i.node_id = c.node_id;
  return i;
}

class EdsWriterTest : public ::testing::Test {
 protected:
  EdsWriterTest() : dev(full_config(), [](const canopen::CanFrame&) {}) {
    text = eds_text(dev.od(), info_for(dev.config()));
    ini = parse(text);
  }
  OeDevice dev;
  std::string text;
  Ini ini;
};

// CiA 306 §4.5 / §4.6: the file and device sections, with the values CiA 852 asks for.
TEST_F(EdsWriterTest, DeviceInfo) {
  EXPECT_EQ(ini.duplicate_sections, 0);
  EXPECT_EQ(ini.duplicate_keys, 0);
  const auto& d = ini.sections.at("DeviceInfo");
  EXPECT_EQ(d.at("VendorNumber"), "0x00001234");
  EXPECT_EQ(d.at("ProductNumber"), "0x00000852");
  EXPECT_EQ(d.at("RevisionNumber"), "0x00010002");
  // CiA 852 §6.2: 125, 250, 500, 1000 kbit/s.
  EXPECT_EQ(d.at("BaudRate_125"), "1");
  EXPECT_EQ(d.at("BaudRate_250"), "1");
  EXPECT_EQ(d.at("BaudRate_500"), "1");
  EXPECT_EQ(d.at("BaudRate_1000"), "1");
  EXPECT_EQ(d.at("BaudRate_800"), "0");
  EXPECT_EQ(d.at("LSS_Supported"), "1");  // CiA 852 §8.2
  // Every PDO of each kind (CiA 852 clause 12): TPDO 1, 5..19 (joysticks), 20..27 (pedals),
  // 28..31 (encoders), 32, 33 (wheels), 34..41 (push-button clusters); RPDO 1, 5..11
  // (indicator clusters), 2, 4, 12..33 (displays).
  EXPECT_EQ(d.at("NrOfTXPDO"), "38");
  EXPECT_EQ(d.at("NrOfRXPDO"), "32");
  EXPECT_EQ(ini.sections.at("FileInfo").at("EDSVersion"), "4.0");
  EXPECT_EQ(ini.sections.at("DummyUsage").at("Dummy0007"), "1");
}

// CiA 306 §4.6.2: object lists; every object of the dictionary appears once with a section.
TEST_F(EdsWriterTest, ObjectListsCoverTheDictionary) {
  const auto& m = ini.sections.at("MandatoryObjects");
  EXPECT_EQ(m.at("SupportedObjects"), "3");
  EXPECT_EQ(m.at("1"), "0x1000");
  EXPECT_EQ(m.at("2"), "0x1001");
  EXPECT_EQ(m.at("3"), "0x1018");
  std::size_t listed = 3;
  const auto& o = ini.sections.at("OptionalObjects");
  listed += std::stoul(o.at("SupportedObjects"));
  listed += std::stoul(ini.sections.at("ManufacturerObjects").at("SupportedObjects"));
  std::size_t in_od = 0;
  for (const auto& [index, obj] : dev.od().objects()) {
    if (index < 0x1000) continue;
    ++in_od;
    char name[8];
    std::snprintf(name, sizeof name, "%04X", index);
    EXPECT_TRUE(ini.sections.count(name)) << name;
  }
  EXPECT_EQ(listed, in_od);
}

// CiA 306 §4.6.3: VAR, ARRAY and RECORD descriptions, sparse ARRAYs, node-relative COB-IDs.
TEST_F(EdsWriterTest, ObjectSections) {
  const auto& dt = ini.sections.at("1000");
  EXPECT_EQ(dt.at("ObjectType"), "0x7");
  EXPECT_EQ(dt.at("DataType"), "0x0007");
  EXPECT_EQ(dt.at("AccessType"), "const");
  EXPECT_EQ(dt.at("DefaultValue"), "0xFF8F0191");  // every FE kind: Table 8
  EXPECT_EQ(dt.at("PDOMapping"), "0");
  // 6000h: joysticks 1..16 (01h..20h), pedals 1..16 (21h..30h), push-button clusters 1..8
  // (31h..70h), the default PDOs of the three kinds map them all; + sub 0.
  const auto& a = ini.sections.at("6000");
  EXPECT_EQ(a.at("ObjectType"), "0x8");
  EXPECT_EQ(a.at("SubNumber"), "113");
  EXPECT_EQ(ini.sections.at("6000sub0").at("DefaultValue"), "0x70");
  EXPECT_TRUE(ini.sections.count("6000sub21"));
  EXPECT_EQ(ini.sections.at("6000sub2").at("ParameterName"), "joystick 1 buttons 1-8");
  EXPECT_EQ(ini.sections.at("6000sub38").at("ParameterName"), "buttons 1 switch 57-64");
  EXPECT_EQ(ini.sections.at("6000sub5").at("ParameterName"), "joystick 3 memory (not configured)");
  EXPECT_FALSE(ini.sections.count("6000sub71"));
  const auto& in = ini.sections.at("6401sub1");
  EXPECT_EQ(in.at("DataType"), "0x0003");
  EXPECT_EQ(in.at("AccessType"), "ro");
  EXPECT_EQ(in.at("PDOMapping"), "1");
  EXPECT_EQ(in.at("DefaultValue"), "0");
  EXPECT_EQ(ini.sections.at("6423").at("DataType"), "0x0001");
  EXPECT_EQ(ini.sections.at("6423").at("DefaultValue"), "0");
  EXPECT_EQ(ini.sections.at("6206sub1").at("DefaultValue"), "0xFF");
  EXPECT_EQ(ini.sections.at("6443sub1").at("HighLimit"), "0x1");
  EXPECT_EQ(ini.sections.at("6444sub1").at("DataType"), "0x0004");
  // RECORD: TPDO 1 with a node-relative COB-ID, TPDO 5 absolute (CiA 852 §12.2.1 / §12.2.2).
  EXPECT_EQ(ini.sections.at("1800").at("ObjectType"), "0x9");
  EXPECT_EQ(ini.sections.at("1800").at("SubNumber"), "6");
  EXPECT_EQ(ini.sections.at("1800sub1").at("DefaultValue"), "$NODEID+0x80000180");
  EXPECT_EQ(ini.sections.at("1804sub1").at("DefaultValue"), "0x80000000");
  EXPECT_EQ(ini.sections.at("1800sub2").at("DefaultValue"), "0xFF");
  EXPECT_EQ(ini.sections.at("1A00sub1").at("DefaultValue"), "0x64010110");
  EXPECT_EQ(ini.sections.at("1014").at("DefaultValue"), "$NODEID+0x80");
  EXPECT_EQ(ini.sections.at("1200sub1").at("DefaultValue"), "$NODEID+0x600");
  EXPECT_EQ(ini.sections.at("1200sub1").at("AccessType"), "ro");
  EXPECT_EQ(ini.sections.at("1016sub1").at("DefaultValue"), "0x101F4");
  EXPECT_EQ(ini.sections.at("1008").at("DataType"), "0x0009");
  EXPECT_EQ(ini.sections.at("1008").at("DefaultValue"), "oegw OE interface module");
  EXPECT_EQ(ini.sections.at("1029sub1").at("HighLimit"), "0x2");
}

// Writes the EDS of the full device to $OEGW_EDS_OUT (for eds_parse_check.py) or a temp file.
TEST(EdsFile, WritesFullDevice) {
  OeDevice dev(full_config(), [](const canopen::CanFrame&) {});
  const char* env = std::getenv("OEGW_EDS_OUT");
  const std::filesystem::path path =
      env != nullptr ? std::filesystem::path(env)
                     : std::filesystem::temp_directory_path() / ("oegw-eds-" + std::to_string(::getpid()) + ".eds");
  std::string error;
  ASSERT_TRUE(write_eds(path, dev.od(), info_for(dev.config()), error)) << error;
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  EXPECT_EQ(ss.str(), eds_text(dev.od(), info_for(dev.config())));
  if (env == nullptr) std::filesystem::remove(path);
  EXPECT_FALSE(write_eds("/nonexistent-dir/x.eds", dev.od(), info_for(dev.config()), error));
  EXPECT_NE(error.find("/nonexistent-dir/x.eds"), std::string::npos);
}

}  // namespace
}  // namespace oegw::gateway
