// The EDS reader (canopen/306/eds_reader.hpp), against CiA 306 (EDS file format, §4.5 object sections,
// §4.5.3 number formats and $NODEID, §4.6 object lists) and the sample files shipped in
// subdevices/eds/. Malformed files must give "file:line: what was expected", never a crash.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "canopen/306/eds_reader.hpp"

namespace oegw::canopen::eds {
namespace {

using canopen::Access;
using canopen::DataType;
using canopen::NodeId;
using canopen::ObjectCode;
using canopen::SdoAbortCode;

const std::filesystem::path kRoot = OEGW_SOURCE_DIR;  // the source tree (tests/CMakeLists.txt)
const std::filesystem::path kPedal = kRoot / "subdevices/eds/generic_pedal.eds";
const std::filesystem::path kCluster = kRoot / "subdevices/eds/button_cluster.eds";

std::string read_text(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

File must_load(const std::filesystem::path& p) {
  std::string error;
  auto f = load(p, error);
  EXPECT_TRUE(f.has_value()) << error;
  return f ? *f : File{};
}

// A minimal, valid EDS with one 8-bit input array; tests break one thing in it.
constexpr const char* kMinimal =
    "[DeviceInfo]\n"                    // 1
    "VendorNumber=0x1234\n"             // 2
    "[MandatoryObjects]\n"              // 3
    "SupportedObjects=2\n"              // 4
    "1=0x1000\n"                        // 5
    "2=0x6000\n"                        // 6
    "[1000]\n"                          // 7
    "ParameterName=Device type\n"       // 8
    "ObjectType=0x7\n"                  // 9
    "DataType=0x0007\n"                 // 10
    "AccessType=ro\n"                   // 11
    "DefaultValue=0x00010191\n"         // 12
    "[6000]\n"                          // 13
    "ParameterName=Read input 8-bit\n"  // 14
    "ObjectType=0x8\n"                  // 15
    "SubNumber=2\n"                     // 16
    "[6000sub0]\n"                      // 17
    "ParameterName=Count\n"             // 18
    "DataType=0x0005\n"                 // 19
    "AccessType=ro\n"                   // 20
    "DefaultValue=1\n"                  // 21
    "[6000sub1]\n"                      // 22
    "ParameterName=Input 1\n"           // 23
    "DataType=0x0005\n"                 // 24
    "AccessType=ro\n"                   // 25
    "DefaultValue=0\n"                  // 26
    "PDOMapping=1\n";                   // 27

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const auto pos = text.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  if (pos != std::string::npos) text.replace(pos, from.size(), to);
  return text;
}

std::string parse_error(const std::string& text) {
  std::string error;
  auto f = parse(text, "t.eds", error);
  EXPECT_FALSE(f.has_value()) << "accepted:\n" << text;
  return error;
}

TEST(Eds, MinimalFileParses) {
  std::string error;
  auto f = parse(kMinimal, "t.eds", error);
  ASSERT_TRUE(f) << error;
  EXPECT_EQ(f->device_number("VendorNumber"), 0x1234u);
  ASSERT_NE(f->find(0x6000), nullptr);
  EXPECT_EQ(f->find(0x6000)->code, ObjectCode::Array);
  EXPECT_EQ(f->find(0x6000)->sub_number, 2);
  ASSERT_NE(f->find(0x6000, 1), nullptr);
  EXPECT_TRUE(f->find(0x6000, 1)->pdo_mapping);
  EXPECT_EQ(f->find(0x6000, 1)->type, DataType::Unsigned8);
  EXPECT_EQ(f->find(0x1000)->code, ObjectCode::Var);
  EXPECT_EQ(f->default_number(0x1000, 0, NodeId{1}), 0x00010191u);
}

TEST(Eds, SamplePedalFile) {
  const File f = must_load(kPedal);
  EXPECT_EQ(f.objects.size(), 10u);
  EXPECT_EQ(f.find(0x1000)->list, "MandatoryObjects");
  EXPECT_EQ(f.find(0x6401)->list, "OptionalObjects");
  const SubEntry* cob = f.find(0x1800, 1);
  ASSERT_NE(cob, nullptr);
  ASSERT_TRUE(cob->default_value);
  EXPECT_TRUE(cob->default_value->node_relative);  // CiA 306 §4.5.3 "$NODEID+0x180"
  EXPECT_EQ(cob->default_value->number, 0x180u);
  EXPECT_EQ(f.default_number(0x1800, 1, NodeId{0x21}), 0x1A1u);
  EXPECT_EQ(f.find(0x6401, 2)->type, DataType::Integer16);
  EXPECT_EQ(f.find(0x6401, 2)->access, Access::ReadOnly);
  EXPECT_EQ(f.device_number("ProductNumber"), 0x401u);
}

// CiA 306 §4.5.3: decimal, 0x hexadecimal, leading-0 octal; $NODEID before or after.
TEST(Eds, NumberFormatsAndNodeIdForms) {
  std::string text = replace(kMinimal, "DefaultValue=0x00010191", "DefaultValue=0x180+$NODEID");
  text = replace(text, "DefaultValue=1\n", "DefaultValue=010\n");  // octal 8
  text = replace(text, "[6000sub1]\nParameterName=Input 1\nDataType=0x0005",
                 "[6000sub1]\nParameterName=Input 1\nDataType=0x0003");
  text =
      replace(text, "DefaultValue=0\nPDOMapping=1", "DefaultValue=-300\nLowLimit=-1000\nHighLimit=1000\nPDOMapping=1");
  std::string error;
  auto f = parse(text, "t.eds", error);
  ASSERT_TRUE(f) << error;
  EXPECT_EQ(f->default_number(0x1000, 0, NodeId{5}), 0x185u);
  EXPECT_EQ(f->default_number(0x6000, 0, NodeId{5}), 8u);
  auto od = build_dictionary(*f, NodeId{5});
  EXPECT_EQ(od->get<std::uint32_t>(0x1000, 0), 0x185u);
  EXPECT_EQ(od->get<std::int16_t>(0x6000, 1), -300);
  // The limits reach the dictionary: a write above HighLimit is refused (CiA 301 0609 0031h).
  EXPECT_EQ(od->write(0x6000, 1, canopen::encode<std::int16_t>(1001), canopen::Origin::Local),
            SdoAbortCode::ValueTooHigh);
  EXPECT_EQ(od->write(0x6000, 1, canopen::encode<std::int16_t>(-1001), canopen::Origin::Local),
            SdoAbortCode::ValueTooLow);
  EXPECT_EQ(od->write(0x6000, 1, canopen::encode<std::int16_t>(999), canopen::Origin::Local), SdoAbortCode::None);
  // A signed value in hex is the type's two's complement (0x8000 = -32768 for INTEGER16).
  text = replace(text, "LowLimit=-1000", "LowLimit=0x8000");
  f = parse(text, "t.eds", error);
  ASSERT_TRUE(f) << error;
  od = build_dictionary(*f, NodeId{5});
  EXPECT_EQ(od->write(0x6000, 1, canopen::encode<std::int16_t>(-32768), canopen::Origin::Local), SdoAbortCode::None);
  auto plain = replace(kMinimal, "DefaultValue=0x00010191", "DefaultValue=$NODEID");
  f = parse(plain, "t.eds", error);
  ASSERT_TRUE(f) << error;
  EXPECT_EQ(f->default_number(0x1000, 0, NodeId{0x7F}), 0x7Fu);
}

TEST(Eds, DictionaryFromPedalFile) {
  const File f = must_load(kPedal);
  auto od = build_dictionary(f, NodeId{0x30});
  const canopen::Object* in = od->find(0x6000);
  ASSERT_NE(in, nullptr);
  EXPECT_EQ(in->code(), ObjectCode::Array);
  EXPECT_EQ(od->get<std::uint8_t>(0x6000, 0), 1);
  const canopen::SubObject* a2 = od->find(0x6401, 2);
  ASSERT_NE(a2, nullptr);
  EXPECT_EQ(a2->type, DataType::Integer16);
  EXPECT_TRUE(a2->pdo_mappable);
  EXPECT_EQ(a2->access, Access::ReadOnly);
  EXPECT_EQ(a2->value.size(), 2u);
  EXPECT_EQ(od->find(0x1800)->code(), ObjectCode::Record);
  EXPECT_EQ(od->get<std::uint32_t>(0x1800, 1), 0x1B0u) << "$NODEID+0x180 for node 30h";
  EXPECT_EQ(od->get<std::uint32_t>(0x1801, 1), 0x800002B0u);
  EXPECT_EQ(od->get<std::uint32_t>(0x1A00, 2), 0x64010210u);
  // SDO access rules follow AccessType (CiA 301 0601 0002h for a read-only object).
  EXPECT_EQ(od->write(0x6401, 1, canopen::encode<std::int16_t>(1)), SdoAbortCode::WriteOfReadOnly);
}

TEST(Eds, PdoDefaultsFromEds) {
  const File f = must_load(kPedal);
  auto t1 = pdo_defaults(f, true, 1, NodeId{0x21});
  ASSERT_TRUE(t1);
  EXPECT_EQ(t1->cob_id, 0x1A1u);
  EXPECT_EQ(t1->transmission_type, 0xFF);
  EXPECT_EQ(t1->event_timer, 50);
  EXPECT_EQ(t1->mapping, (std::vector<std::uint32_t>{0x64010110, 0x64010210, 0x60000108}));
  EXPECT_EQ(t1->mapping_capacity, 4);
  auto t2 = pdo_defaults(f, true, 2, NodeId{0x21});
  ASSERT_TRUE(t2);
  EXPECT_FALSE(canopen::CobId{t2->cob_id}.valid());
  EXPECT_TRUE(t2->mapping.empty());
  EXPECT_FALSE(pdo_defaults(f, true, 3, NodeId{0x21})) << "no 1802h in the EDS";
  EXPECT_FALSE(pdo_defaults(f, false, 1, NodeId{0x21})) << "a pedal has no RPDO";
  const File c = must_load(kCluster);
  auto r1 = pdo_defaults(c, false, 1, NodeId{0x21});
  ASSERT_TRUE(r1);
  EXPECT_EQ(r1->cob_id, 0x221u);
  EXPECT_EQ(pdo_defaults(c, true, 2, NodeId{0x21})->cob_id, 0x2A1u) << "the 0x280+$NODEID form";
}

TEST(Eds, RoundTripThroughWriter) {
  for (const auto& path : {kPedal, kCluster}) {
    const File f = must_load(path);
    const std::string text = write(f);
    std::string error;
    auto back = parse(text, "written.eds", error);
    ASSERT_TRUE(back) << error << "\n" << text;
    EXPECT_EQ(*back, f) << path;
    EXPECT_EQ(write(*back), text) << "writing is stable";
    // And the dictionaries built from both agree value by value.
    auto a = build_dictionary(f, NodeId{9});
    auto b = build_dictionary(*back, NodeId{9});
    ASSERT_EQ(a->objects().size(), b->objects().size());
    for (const auto& [idx, obj] : a->objects()) {
      for (const auto& [si, s] : obj.subs()) {
        const canopen::SubObject* t = b->find(idx, si);
        ASSERT_NE(t, nullptr);
        EXPECT_EQ(t->value, s.value);
        EXPECT_EQ(t->type, s.type);
        EXPECT_EQ(t->access, s.access);
        EXPECT_EQ(t->pdo_mappable, s.pdo_mappable);
      }
    }
  }
}

struct Broken {
  std::string from;
  std::string to;
  std::string expected;  // the full "file:line: ..." prefix or a distinctive part
};

TEST(Eds, MalformedFilesGiveFileLineAndWhatWasExpected) {
  const std::vector<Broken> cases = {
      {"[1000]\n", "[1000\n", "t.eds:7: expected ']' closing the section name"},
      {"[DeviceInfo]\n", "VendorName=x\n[DeviceInfo]\n", "t.eds:1: expected a [section] before 'VendorName'="},
      {"ObjectType=0x7\n", "ObjectType 0x7\n", "t.eds:9: expected 'key=value', '[section]' or a ';' comment"},
      {"ObjectType=0x7\n", "=0x7\n", "t.eds:9: expected a key before '='"},
      {"[6000]\n", "[1000]\n", "t.eds:13: duplicate section [1000] (first at line 7)"},
      {"2=0x6000\n", "2=0x6001\n", "t.eds:6: expected a section [6001] for the object listed in [MandatoryObjects]"},
      {"SupportedObjects=2\n", "SupportedObjects=3\n", "t.eds:4: [MandatoryObjects] expected an entry 3=<index>"},
      {"2=0x6000\n", "2=0x6000\n7=0x1000\n", "t.eds:7: [MandatoryObjects] expected entries 1..2=<index>, got key '7'"},
      {"2=0x6000\n", "2=0x1000\n", "t.eds:6: [MandatoryObjects] object 1000h is listed twice"},
      {"2=0x6000\n", "2=zz\n", "t.eds:6: [MandatoryObjects] expected an object index such as 0x1000, got 'zz'"},
      {"DataType=0x0007\n", "DataType=0x0E\n", "t.eds:10: [1000] DataType: expected a CiA 301 data type number"},
      {"DataType=0x0007\n", "", "t.eds:7: [1000] expected DataType="},
      {"AccessType=ro\nDefaultValue=0x0001", "AccessType=read\nDefaultValue=0x0001",
       "t.eds:11: [1000] AccessType: expected ro, wo, rw, rwr, rww or const, got 'read'"},
      {"DefaultValue=0\nPDOMapping=1", "DefaultValue=256\nPDOMapping=1",
       "t.eds:26: [6000sub1] DefaultValue: expected a value that fits UNSIGNED8, got '256'"},
      {"DefaultValue=0x00010191", "DefaultValue=0x1G", "t.eds:12: [1000] DefaultValue: expected a number"},
      {"DefaultValue=0x00010191", "DefaultValue=$NODEID+$NODEID", "t.eds:12: [1000] DefaultValue: expected a number"},
      {"DefaultValue=0x00010191", "DefaultValue=0x10-$NODEID", "t.eds:12: [1000] DefaultValue: expected a number"},
      {"PDOMapping=1", "PDOMapping=2", "t.eds:27: [6000sub1] PDOMapping: expected 0 or 1, got '2'"},
      {"SubNumber=2\n", "SubNumber=3\n", "t.eds:16: [6000] SubNumber: expected 3 sections [6000subN], found 2"},
      {"SubNumber=2\n", "", "t.eds:13: [6000] expected SubNumber= for an ARRAY/RECORD"},
      {"SubNumber=2\n", "SubNumber=0\n", "t.eds:16: [6000] SubNumber: expected 1..256, got '0'"},
      {"[6000sub0]\n", "[6000sub2]\n", "t.eds:13: [6000] expected a section [6000sub0]"},
      {"ObjectType=0x8\n", "ObjectType=0x3\n", "t.eds:15: [6000] ObjectType: expected 0x7 (VAR), 0x8 (ARRAY), 0x9"},
      {"ObjectType=0x8\n", "ObjectType=0x8\nCompactSubObj=300\n",
       "t.eds:16: [6000] CompactSubObj: expected the number of sub-objects 0..254, got '300'"},
      {"ParameterName=Input 1\n", "", "t.eds:22: [6000sub1] expected ParameterName="},
      {"[6000sub1]\n", "[6000sub1]\nObjectType=0x9\n",
       "t.eds:23: [6000sub1] ObjectType: expected 0x7 (VAR) for a sub-object"},
      {"DefaultValue=0\nPDOMapping=1", "DefaultValue=0\nLowLimit=10\nHighLimit=5\nPDOMapping=1",
       "t.eds:28: [6000sub1] HighLimit: expected a value not below LowLimit"},
      {"[MandatoryObjects]\n", "[Objects]\n", "t.eds:27: expected a [MandatoryObjects] section"},
      {"[6000sub0]\n", "[6000sub0] [x]\n", "t.eds:17: expected one section name in"},
      {"[6000sub0]\n", "[]\n", "t.eds:17: expected a section name between '[' and ']'"},
      {"[6000sub0]\n", "[6000sub00]\n[6000sub0]\n",
       "t.eds:18: section [6000sub0] names the same object as [6000sub00]"},
  };
  for (const auto& c : cases) {
    const std::string error = parse_error(replace(kMinimal, c.from, c.to));
    EXPECT_EQ(error.rfind(c.expected, 0), 0u) << "got:      " << error << "\nexpected: " << c.expected;
  }
  EXPECT_EQ(parse_error(""), "t.eds:0: expected a [MandatoryObjects] section (the file lists no objects)");
  // Control bytes are no text: a binary file given for an EDS is said to be one, at its first
  // such byte, in one short line (its escaped bytes were quoted before).
  EXPECT_EQ(parse_error(std::string("[A]\nk=v\n\x01\x02\xff\n")),
            "t.eds:3: not a text file (byte 0x01 at offset 8); expected an EDS, a text file (CiA 306)");
  std::string
      elf("\x7F"
          "ELF\x02\x01\x01",
          7);
  elf += std::string(200, '\0');
  EXPECT_EQ(parse_error(elf),
            "t.eds:1: not a text file (byte 0x7F at offset 0); expected an EDS, a text file (CiA 306)");
  // Tab, CR LF, the DOS end-of-file mark and Windows-1252 letters are text.
  EXPECT_EQ(parse_error("[FileInfo]\r\nFileName=p\xE9"
                        "dale.eds\t\r\n\x1A")
                .find("not a text file"),
            std::string::npos);
}

TEST(Eds, UnreadableFileIsReported) {
  std::string error;
  EXPECT_FALSE(load("/nonexistent/oegw/pedal.eds", error));
  EXPECT_EQ(error.rfind("/nonexistent/oegw/pedal.eds: cannot open:", 0), 0u) << error;
}

// `eds: /dev/zero` once filled memory until std::bad_alloc; a directory read as an empty file.
TEST(Eds, OnlyARegularFileIsRead) {
  std::string error;
  EXPECT_FALSE(load("/dev/zero", error));
  EXPECT_EQ(error, "/dev/zero: is a character device; expected a regular file (an EDS file)");
  EXPECT_FALSE(load("/", error));
  EXPECT_EQ(error, "/: is a directory; expected a regular file (an EDS file)");
}

// No input crashes the reader: every truncation and many byte mutations of the sample files
// either parse or give a "file:line:" error.
TEST(Eds, NoCrashOnMutatedInput) {
  const std::string base = read_text(kCluster);
  ASSERT_FALSE(base.empty());
  std::uint32_t seed = 12345;
  auto rnd = [&seed]() {
    seed = seed * 1103515245u + 12345u;
    return seed >> 8;
  };
  const char alphabet[] = "[]=;$+-0x1F\n\r\t sub NODEID\x00\xff";
  std::size_t errors = 0;
  for (int i = 0; i < 4000; ++i) {
    std::string text = base;
    if (i < 1000) {
      text.resize(rnd() % base.size());
    } else {
      const int edits = 1 + static_cast<int>(rnd() % 4);
      for (int e = 0; e < edits; ++e) {
        const std::size_t pos = rnd() % text.size();
        const char ch = alphabet[rnd() % (sizeof(alphabet) - 1)];
        switch (rnd() % 3) {
          case 0: text[pos] = ch; break;
          case 1: text.insert(pos, 1, ch); break;
          default: text.erase(pos, 1 + rnd() % 8); break;
        }
      }
    }
    std::string error;
    auto f = parse(text, "m.eds", error);
    if (!f) {
      ++errors;
      ASSERT_EQ(error.rfind("m.eds:", 0), 0u) << error;
      ASSERT_NE(error.find(": ", 6), std::string::npos) << error;
    } else {
      (void)build_dictionary(*f, NodeId{1});
      (void)write(*f);
    }
  }
  EXPECT_GT(errors, 1000u) << "most mutations break the file";
}

// ---- cross-check with an independent reader (Python configparser, tests/tools/eds_check.py) ----

std::string summary_value(const SubEntry& e) {
  if (!e.default_value) return "-";
  const Value& v = *e.default_value;
  const std::size_t n = canopen::fixed_size(e.type);
  if (n == 0 || canopen::is_real(e.type)) return "'" + v.text + "'";
  std::string out = v.node_relative ? "$NODEID+" : "";
  if (canopen::is_signed_integer(e.type)) {
    out += std::to_string(canopen::decode_signed(canopen::encode_width(v.number, n)));
  } else {
    out += std::to_string(v.number);
  }
  return out;
}

std::vector<std::string> cpp_summary(const File& f) {
  std::vector<std::string> lines;
  for (const auto& [idx, o] : f.objects) {
    for (const auto& [si, e] : o.subs) {
      char head[32];
      std::snprintf(head, sizeof head, "%04X:%02X %04X ", idx, si, static_cast<unsigned>(e.type));
      lines.push_back(std::string(head) + std::string(canopen::to_string(e.access)) + " " +
                      (e.pdo_mapping ? "1" : "0") + " " + summary_value(e));
    }
  }
  std::sort(lines.begin(), lines.end());
  return lines;
}

TEST(Eds, AgreesWithPythonConfigparser) {
  // python3 is part of every Debian machine this runs on (the VM tier needs it too): fail loudly if not.
  ASSERT_TRUE(std::filesystem::exists("/usr/bin/python3"))
      << "no /usr/bin/python3: the independent EDS reader cannot run";
  for (const auto& path : {kPedal, kCluster}) {
    const std::string cmd =
        "/usr/bin/python3 " + (kRoot / "tests/tools/eds_check.py").string() + " --summary " + path.string();
    FILE* p = ::popen(cmd.c_str(), "r");
    ASSERT_NE(p, nullptr);
    std::string out;
    char buf[512];
    while (std::fgets(buf, sizeof buf, p) != nullptr) out += buf;
    ASSERT_EQ(::pclose(p), 0) << out;
    std::vector<std::string> py;
    std::istringstream ss(out);
    for (std::string line; std::getline(ss, line);)
      if (!line.empty()) py.push_back(line);
    std::sort(py.begin(), py.end());
    const auto cpp = cpp_summary(must_load(path));
    EXPECT_GT(cpp.size(), 30u);
    EXPECT_EQ(py, cpp) << path;
  }
}

}  // namespace
}  // namespace oegw::canopen::eds

namespace oegw::canopen::eds {
namespace {

const std::filesystem::path kVendor = kRoot / "tests/fixtures/vendor_io_module.eds";

// What real vendors' tools write (tests/fixtures/vendor_io_module.eds, written in their style):
// accepted as CiA 306 allows, with a warning where CiA 306 does not.
TEST(Eds, VendorStyleFileIsReadWithWarnings) {
  const File f = must_load(kVendor);
  // UTF-8 byte-order mark and CRLF line ends: the first section is found.
  EXPECT_EQ(f.device_number("VendorNumber"), 0x1F4u);
  // CompactSubObj (CiA 306 §4.5.2.2): sub 0 UNSIGNED8 ro = n, subs 1..n from the object's
  // section, names from [6401Name], defaults from [6401Value].
  const ObjectEntry* ai = f.find(0x6401);
  ASSERT_NE(ai, nullptr);
  EXPECT_EQ(ai->code, ObjectCode::Array);
  ASSERT_EQ(ai->subs.size(), 3u);
  EXPECT_EQ(ai->find(0)->type, DataType::Unsigned8);
  EXPECT_EQ(ai->find(0)->access, Access::ReadOnly);
  EXPECT_EQ(f.default_number(0x6401, 0, NodeId{1}), 2u);
  EXPECT_EQ(ai->find(1)->name, "Analogue input 1");
  EXPECT_EQ(ai->find(2)->type, DataType::Integer16);
  EXPECT_TRUE(ai->find(2)->pdo_mapping);
  EXPECT_EQ(f.default_number(0x6401, 1, NodeId{1}), 0u);
  EXPECT_EQ(f.default_number(0x6401, 2, NodeId{1}), 100u);
  ASSERT_TRUE(ai->find(2)->low.has_value());
  EXPECT_EQ(static_cast<std::int64_t>(ai->find(2)->low->number), -32768);
  EXPECT_EQ(f.find(0x6000, 1)->name, "Digital inputs 1..8");
  // ObjectType 2 DOMAIN without DataType, 5 DEFTYPE, 6 DEFSTRUCT.
  EXPECT_EQ(f.find(0x1F50, 0)->type, DataType::Domain);
  EXPECT_EQ(f.find(0x1F50)->object_type, 2);
  EXPECT_EQ(f.find(0x0005)->code, ObjectCode::Var);
  EXPECT_EQ(f.default_number(0x0005, 0, NodeId{1}), 8u);
  EXPECT_EQ(f.find(0x0020)->code, ObjectCode::Record);
  EXPECT_EQ(f.find(0x0020)->object_type, 6);
  // Empty limits on strings: none, silently.
  EXPECT_FALSE(f.find(0x1008, 0)->low.has_value());
  EXPECT_EQ(f.find(0x1008, 0)->default_value->text, "IOM-8DI2AI");
  // Warnings: the duplicate key (first wins) and the default outside its limits (kept).
  const std::string p = kVendor.string();
  ASSERT_EQ(f.warnings.size(), 2u);
  EXPECT_EQ(f.warnings[0].rfind(p + ":"), 0u);
  EXPECT_NE(f.warnings[0].find(": warning: duplicate key 'PDOMapping' in [1017] ignored: the first, at line"),
            std::string::npos)
      << f.warnings[0];
  EXPECT_NE(f.warnings[1].find("warning: [2000] DefaultValue '0' is outside LowLimit..HighLimit: kept as written"),
            std::string::npos)
      << f.warnings[1];
  EXPECT_EQ(f.default_number(0x2000, 0, NodeId{1}), 0u);
  // The dictionary has them all; written and read back it is the same file.
  auto od = build_dictionary(f, NodeId{0x22});
  EXPECT_NE(od->find(0x6401, 2), nullptr);
  EXPECT_EQ(od->get<std::int16_t>(0x6401, 2), 100);
  EXPECT_NE(od->find(0x1F50, 0), nullptr);
  std::string error;
  const auto back = parse(write(f), "back.eds", error);
  ASSERT_TRUE(back) << error;
  EXPECT_EQ(*back, f);
}

TEST(Eds, DuplicateKeyFirstWinsAndLimitsOnStringsAreIgnored) {
  std::string error;
  const std::string text = replace(kMinimal, "AccessType=ro\nDefaultValue=0x00010191",
                                   "AccessType=ro\nDefaultValue=0x00010191\ndefaultvalue=0x00020191");
  const auto f = parse(text, "t.eds", error);
  ASSERT_TRUE(f) << error;
  EXPECT_EQ(f->default_number(0x1000, 0, NodeId{1}), 0x00010191u);
  ASSERT_EQ(f->warnings.size(), 1u);
  EXPECT_EQ(f->warnings[0],
            "t.eds:13: warning: duplicate key 'defaultvalue' in [1000] ignored: the first, at line 12, counts");
  const auto g = parse(replace(kMinimal, "DataType=0x0007\nAccessType=ro\nDefaultValue=0x00010191",
                               "DataType=0x0009\nAccessType=ro\nDefaultValue=abc\nLowLimit=1\nHighLimit="),
                       "t.eds", error);
  ASSERT_TRUE(g) << error;
  ASSERT_EQ(g->warnings.size(), 1u);
  EXPECT_EQ(g->warnings[0],
            "t.eds:13: warning: [1000] LowLimit: a limit on a VISIBLE_STRING entry means nothing: ignored");
}

}  // namespace
}  // namespace oegw::canopen::eds
