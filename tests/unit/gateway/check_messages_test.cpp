// What `oegw check` says of a sub-device's options with the real drivers' catalogue (the one
// `oegw check` and `oegw run` load a file with, gateway::driver_catalogue): every refused option
// its own error, at that option's value, saying what is wrong once (docs/reference/mapping-file.md,
// docs/reference/drivers.md). The loader's own messages with a fake catalogue are in
// mapping_config_test.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "gateway/gateway.hpp"
#include "mapping/config.hpp"

namespace oegw {
namespace {

using ::testing::ElementsAre;

std::vector<std::string> errors(const mapping::LoadResult& r) {
  std::vector<std::string> out;
  for (const auto& e : r.errors) out.push_back(e.str());
  return out;
}

mapping::LoadResult load(const std::string& text, std::optional<std::filesystem::path> base = std::nullopt) {
  return mapping::load_config_text(text, "c.yaml", gateway::driver_catalogue(), std::move(base));
}

const std::string kHead =
    "upstream: { interface: can0, node_id: 0x20 }\ndownstream: { interface: can1 }\nsubdevices:\n";

// A folder of its own for the files a test writes, removed after it.
class Folder {
 public:
  Folder() : path_(std::filesystem::temp_directory_path() / ("oegw_check_messages_" + std::to_string(::getpid()))) {
    std::filesystem::create_directories(path_);
  }
  ~Folder() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  Folder(const Folder&) = delete;
  Folder& operator=(const Folder&) = delete;
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// An EDS path to nothing was two "expected" clauses at the `options` key: it is one error at the
// eds value, naming the path the driver looked for.
TEST(CheckMessages, AMissingEdsFileIsNamedAtItsValue) {
  const std::string fes = "functional_elements:\n  pedal.1: { position: \"pedal.analog[1]\" }\n";
  EXPECT_THAT(errors(load(kHead + "  pedal: { driver: cia401, node_id: 0x30, options: { eds: eds/pedal.eds } }\n" + fes,
                          std::filesystem::path("/etc/oegw-test"))),
              ElementsAre("c.yaml:4:59: driver cia401 refused sub-device 'pedal': cia401: EDS file "
                          "/etc/oegw-test/eds/pedal.eds does not exist; expected the path of an existing file, "
                          "absolute or relative to the mapping file's folder"));
  // Written with '~' (as in a shell): the path as taken, and that no shell expands it.
  EXPECT_THAT(errors(load(kHead + "  pedal: { driver: cia401, node_id: 0x30, options: { eds: ~/pedal.eds } }\n" + fes,
                          std::filesystem::path("/etc/oegw-test"))),
              ElementsAre("c.yaml:4:59: driver cia401 refused sub-device 'pedal': cia401: EDS file "
                          "/etc/oegw-test/~/pedal.eds does not exist ('~/pedal.eds' was written: '~' is not expanded, "
                          "no shell reads the mapping file); expected the path of an existing file, absolute or "
                          "relative to the mapping file's folder"));
}

// A binary file given for an EDS was 40 escaped bytes of its first "line": it is one short
// sentence with the first byte that is no text and its offset.
TEST(CheckMessages, ABinaryEdsIsNotATextFile) {
  const Folder dir;
  const auto eds = dir.path() / "pedal.eds";
  {
    std::ofstream out(eds, std::ios::binary);
    out << "[FileInfo]\nFileName=pedal.eds\n";
    for (int i = 0; i < 256; ++i) out << static_cast<char>(i);
  }
  const auto e = errors(load(kHead + "  pedal: { driver: cia401, node_id: 0x30, options: { eds: pedal.eds } }\n"
                                     "functional_elements: {}\n",
                             dir.path()));
  EXPECT_THAT(e, ElementsAre("c.yaml:4:59: driver cia401 refused sub-device 'pedal': cia401: " + eds.string() +
                             ":3: not a text file (byte 0x00 at offset 30); expected an EDS, a text file (CiA 306)"));
  ASSERT_EQ(e.size(), 1u);
  EXPECT_LT(e[0].size(), 250u);
}

// Two wrong options of one grip were reported one at a time: both are, each at its value.
TEST(CheckMessages, EveryRefusedOptionOfASubdeviceIsReported) {
  const auto r = load(kHead + R"(  grip:
    driver: elobau-mfg
    node_id: 0x11
    options: { channel_tolerance: 200, detent: round, cycle_ms: 50, colour: red }
functional_elements:
  joystick.1: { x: grip.x }
)");
  EXPECT_THAT(errors(r),
              ElementsAre("c.yaml:7:35: driver elobau-mfg refused sub-device 'grip': elobau-mfg: channel_tolerance "
                          "'200' is not an integer 0..100 (percent); expected options the elobau-mfg driver accepts",
                          "c.yaml:7:48: driver elobau-mfg refused sub-device 'grip': elobau-mfg: detent 'round' must "
                          "be 'pass' or 'clamp'; expected options the elobau-mfg driver accepts",
                          "c.yaml:7:77: driver elobau-mfg refused sub-device 'grip': elobau-mfg: unknown option "
                          "'colour' (expected channel_tolerance, detent, channel2_timeout_ms, cycle_ms, "
                          "parameter_checksum, freshness_floor_ms); expected options the elobau-mfg driver accepts"));
  // Two options that disagree: at the one written to be larger.
  EXPECT_THAT(errors(load(kHead + "  grip: { driver: elobau-mfg, node_id: 0x11, options: { cycle_ms: 50, "
                                  "channel2_timeout_ms: 40 } }\nfunctional_elements: {}\n")),
              ElementsAre("c.yaml:4:92: driver elobau-mfg refused sub-device 'grip': elobau-mfg: channel2_timeout_ms "
                          "must exceed cycle_ms (50 ms); expected options the elobau-mfg driver accepts"));
}

// A bit given twice in the MCB-402's button_bits names the bit and both positions.
TEST(CheckMessages, ARepeatedButtonBitNamesTheBitAndBothPositions) {
  const auto r = load(kHead +
                      "  base: { driver: mcb402, node_id: 0x03, options: { button_bits: [1, 2, 3, 3, 4, 5, 6] } }\n"
                      "functional_elements: {}\n");
  EXPECT_THAT(errors(r),
              ElementsAre("c.yaml:4:66: driver mcb402 refused sub-device 'base': mcb402: button_bits '1,2,3,3,4,5,6': "
                          "bit 3 is given twice, at positions 3 and 4 (BP3 and BP4); expected 7 distinct bit numbers "
                          "0..7 of 6000h:03 for BP1..BP7, separated by ',' or '/' (as `oegw signals mcb402 "
                          "--find-button-bits` prints them)"));
}

}  // namespace
}  // namespace oegw
