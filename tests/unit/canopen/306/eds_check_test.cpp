// The EDS's default PDO mappings against the objects they name (canopen/306/eds_check.hpp,
// CiA 301 §7.5.2.36/.38): the shipped sample files pass; each way a mapping entry can be wrong
// (a missing object, a wrong length, PDOMapping=0, a count beyond the entries, more than 64 bits)
// is reported with the file's line. A mutated copy of generic_pedal.eds (TPDO 1: 6401h:01,
// 6401h:02, 6000h:01) is each case.
#include "canopen/306/eds_check.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "subdevices/families.hpp"

namespace oegw::canopen::eds {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;

const std::filesystem::path kRoot = OEGW_SOURCE_DIR;

std::string pedal_text() {
  std::ifstream in(kRoot / "subdevices/eds/generic_pedal.eds", std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct Edit {
  std::string after, from, to;  // `from`, first found after `after`, becomes `to`
};

// The pedal file with `edits` made, checked.
std::vector<std::string> check_edited(const std::vector<Edit>& edits) {
  std::string t = pedal_text();
  for (const auto& e : edits) {
    const auto a = t.find(e.after);
    const auto at = a == std::string::npos ? a : t.find(e.from, a);
    if (at == std::string::npos) {
      ADD_FAILURE() << "not in the pedal file: " << e.after << " ... " << e.from;
      return {};
    }
    t.replace(at, e.from.size(), e.to);
  }
  std::string error;
  const auto f = parse(t, "pedal.eds", error);
  EXPECT_TRUE(f.has_value()) << error;
  return f ? check_pdo_mappings(*f) : std::vector<std::string>{error};
}
std::vector<std::string> check_with(const std::string& after, const std::string& from, const std::string& to) {
  return check_edited({{after, from, to}});
}

TEST(EdsCheck, ShippedFilesPass) {
  for (const char* name : {"generic_pedal.eds", "button_cluster.eds"}) {
    std::string error;
    const auto f = load(kRoot / "subdevices/eds" / name, error);
    ASSERT_TRUE(f.has_value()) << error;
    EXPECT_THAT(check_pdo_mappings(*f), IsEmpty()) << name;
  }
}

TEST(EdsCheck, AnEntryNamingAMissingObject) {
  EXPECT_THAT(check_with("[1A00sub1]", "DefaultValue=0x64010110", "DefaultValue=0x64010910"),
              ElementsAre("pedal.eds:237: 1A00h sub 1 default 64010910h maps 6401h:09, which the file does not "
                          "describe; expected an object of this EDS"));
}

TEST(EdsCheck, AnEntryOfTheWrongLength) {
  EXPECT_THAT(check_with("[1A00sub2]", "DefaultValue=0x64010210", "DefaultValue=0x64010208"),
              ElementsAre(HasSubstr("pedal.eds:245: 1A00h sub 2 default 64010208h maps 6401h:02 with 8 bits; "
                                    "expected 16 (INTEGER16, line ")));
}

TEST(EdsCheck, AnEntryThatIsNotMappable) {
  EXPECT_THAT(check_with("[6401sub1]", "PDOMapping=1", "PDOMapping=0"),
              ElementsAre(HasSubstr("pedal.eds:237: 1A00h sub 1 default 64010110h maps 6401h:01, which is not "
                                    "PDO-mappable (PDOMapping=0, line 348); expected a mappable object")));
}

TEST(EdsCheck, ACountBeyondTheEntries) {
  EXPECT_THAT(check_with("[1A00sub0]", "DefaultValue=3", "DefaultValue=9"),
              ElementsAre("pedal.eds:229: 1A00h sub 0 default 9 counts more entries than the object has (4); "
                          "expected at most 4"));
}

TEST(EdsCheck, DummyEntriesAndTheFrameLimit) {
  // A dummy UNSIGNED16 gap (0006h) of 16 bits is fine; of 8 bits it is not.
  EXPECT_THAT(check_with("[1A00sub3]", "DefaultValue=0x60000108", "DefaultValue=0x00060010"), IsEmpty());
  EXPECT_THAT(check_with("[1A00sub3]", "DefaultValue=0x60000108", "DefaultValue=0x00060008"),
              ElementsAre(HasSubstr("maps 0006h:00 with 8 bits; expected 16 (a dummy entry of UNSIGNED16)")));
  // 32 + 16 + 32 bits (dummy UNSIGNED32 gaps): beyond one frame.
  const auto e = check_edited({{"[1A00sub1]", "DefaultValue=0x64010110", "DefaultValue=0x00070020"},
                               {"[1A00sub3]", "DefaultValue=0x60000108", "DefaultValue=0x00070020"}});
  EXPECT_THAT(e, ElementsAre("pedal.eds:224: 1A00h maps 80 bits; expected at most 64 (one CAN frame)"));
}

// A PDO disabled by default (COB-ID bit 31) is not checked: a vendor's sloppy unused TPDO does
// not refuse the node.
TEST(EdsCheck, APdoDisabledByDefaultIsNotChecked) {
  const auto e = check_edited({{"[1A00sub1]", "DefaultValue=0x64010110", "DefaultValue=0x64010910"},
                               {"[1800sub1]", "DefaultValue=$NODEID+0x180", "DefaultValue=0x800001B0"}});
  EXPECT_THAT(e, IsEmpty());
}

// The generic CiA 401 driver refuses such a file when it is configured, so `oegw check` names the
// line instead of the node failing at boot.
TEST(EdsCheck, TheCia401DriverRefusesAnInconsistentFile) {
  std::string t = pedal_text();
  t.replace(t.find("DefaultValue=0x64010210"), 23, "DefaultValue=0x64010208");
  const auto path = std::filesystem::temp_directory_path() / ("oegw-edscheck-" + std::to_string(::getpid()) + ".eds");
  std::ofstream(path) << t;
  std::string error;
  EXPECT_EQ(subdevices::make_cia401_driver(canopen::NodeId{0x30}, {},
                                           subdevices::DriverOptions{{{"eds", path.string()}}}, error),
            nullptr);
  EXPECT_THAT(error, ::testing::StartsWith("cia401: " + path.string() +
                                           ":245: 1A00h sub 2 default 64010208h maps "
                                           "6401h:02 with 8 bits; expected 16"));
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace oegw::canopen::eds
