// `oegw scan`'s core and draft against the simulators of every family (written from the
// manufacturers' documents, subdevices/sim) on the in-process bus: each node is found and named,
// and the draft mapping file passes `oegw check` as written, and again with every suggested FE
// line uncommented.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <unistd.h>

#include "gateway/programs.hpp"
#include "mapping/draft.hpp"
#include "subdevices/bus_scan.hpp"
#include "subdevices/device_spec.hpp"
#include "subdevices/sim/sim_registry.hpp"
#include "virtual_network.hpp"

namespace {

using namespace std::chrono_literals;
using namespace oegw;
namespace sd = oegw::subdevices;

const std::filesystem::path kRoot = OEGW_SOURCE_DIR;

class ScanDraft : public ::testing::Test {
 protected:
  void add(const std::string& spec_text) {
    std::string error;
    auto spec = sd::parse_device_spec(spec_text, error);
    ASSERT_TRUE(spec) << error;
    const std::string name = spec->name();
    auto sim = sd::sim::make_simulator(*spec, net_.sink(name), error);
    ASSERT_TRUE(sim) << error;
    net_.attach(name, *sim);
    sim->start(net_.now());
    sims_.push_back(std::move(sim));
  }

  sd::ScanResult scan(sd::ScanConfig cfg = {}) {
    sd::BusScanner scanner(net_.sink("scanner"), cfg);
    net_.attach("scanner", scanner);
    scanner.start(net_.now());
    for (int i = 0; i < 100 && !scanner.done(); ++i) net_.run_for(100ms);
    EXPECT_TRUE(scanner.done());
    net_.detach("scanner");
    return scanner.result();
  }

  // `oegw check` (`here`: `oegw check --here`) on `text`, written to a file of its own.
  int check(const std::string& text, const std::string& name, bool here = false) {
    const auto file = dir_ / name;
    std::ofstream(file) << text;
    return gateway::run_check(file.string(), false, here);
  }
  // The draft's settings: its upstream store in this test's folder (the default's folder,
  // /var/lib/oegw, is made by the package, not here).
  mapping::DraftSettings settings() const {
    return {.downstream = "can1", .upstream = "can0", .bitrate = 250000, .store = (dir_ / "upstream.store").string()};
  }
  void SetUp() override { std::filesystem::create_directories(dir_); }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  const std::filesystem::path dir_ =
      std::filesystem::temp_directory_path() / ("oegw-scan-draft-" + std::to_string(::getpid()));

  oegw::testing::VirtualNetwork net_;
  std::vector<std::unique_ptr<sd::sim::SimulatedDevice>> sims_;
};

// Every "  # " line after functional_elements uncommented ("  ## " notes stay), its {} removed.
std::string with_fe_lines(const std::string& draft) {
  std::istringstream in(draft);
  std::string out, line;
  bool fes = false;
  while (std::getline(in, line)) {
    if (line.rfind("functional_elements:", 0) == 0) {
      fes = true;
      line = "functional_elements:";
    } else if (fes && line.rfind("  # ", 0) == 0) {
      line = "  " + line.substr(4);
    }
    out += line + "\n";
  }
  return out;
}

TEST_F(ScanDraft, FindsEveryFamilyNamesItAndTheDraftPassesCheck) {
  add("elobau-mfg:0x11");
  add("mcb402:0x03");
  add("novotechnik-406:0x7F");
  add("cia401:0x30:eds=" + (kRoot / "subdevices/eds/generic_pedal.eds").string());
  add("elobau-mfg:0x12:heartbeat_ms=0");
  const sd::ScanResult r = scan();
  ASSERT_EQ(r.nodes.size(), 5u);
  std::map<int, std::string> families;
  for (const auto& n : r.nodes) {
    EXPECT_TRUE(n.answered_sdo) << int(n.node.value());
    families[n.node.value()] = n.family.family;
  }
  EXPECT_EQ(families, (std::map<int, std::string>{{0x03, "mcb402"},
                                                  {0x11, "elobau-mfg"},
                                                  {0x12, "elobau-mfg"},
                                                  {0x30, "cia401"},
                                                  {0x7F, "novotechnik-406"}}));
  EXPECT_FALSE(r.unconfigured);

  std::string draft = mapping::draft_mapping(r, settings());
  // The required commissioning choice is the placeholder TODO, which check refuses until a value
  // is written (no draft passes check on a guess); cia401 needs its EDS: left out.
  EXPECT_NE(draft.find("button_bits: TODO  # `oegw check` refuses this"), std::string::npos) << draft;
  EXPECT_EQ(check(draft, "draft.yaml"), 1) << draft;
  draft.replace(draft.find("button_bits: TODO"), std::string("button_bits: TODO").size(),
                "button_bits: [1, 2, 3, 4, 5, 7, 6]");
  EXPECT_EQ(check(draft, "draft.yaml"), 0) << draft;
  EXPECT_NE(draft.find("  # cia401_30:"), std::string::npos) << draft;
  EXPECT_NE(draft.find("  elobau_mfg_11:\n    driver: elobau-mfg\n    node_id: 0x11\n"), std::string::npos) << draft;
  EXPECT_NE(draft.find("identity: { vendor_id: 0x000000B4, product_code: 0x00010003 }"), std::string::npos) << draft;

  const std::string uncommented = with_fe_lines(draft);
  EXPECT_NE(uncommented.find("\n  joystick.1:\n"), std::string::npos) << uncommented;
  EXPECT_NE(uncommented.find("encoder.1:"), std::string::npos) << uncommented;
  EXPECT_EQ(check(uncommented, "uncommented.yaml"), 0) << uncommented;
}

TEST_F(ScanDraft, NoNodeGivesADraftWithoutSubdevicesThatStillPassesCheck) {
  sd::ScanConfig cfg;
  cfg.parallel = 127;
  const sd::ScanResult r = scan(cfg);
  EXPECT_TRUE(r.nodes.empty());
  const std::string draft = mapping::draft_mapping(r, settings());
  EXPECT_NE(draft.find("subdevices: {}"), std::string::npos);
  EXPECT_EQ(check(draft, "empty.yaml"), 0) << draft;
}

// A draft made on one computer for another (an integrator's laptop without the cab's store
// folder): the file is right, so `oegw check` passes it, warning of the folder among this
// machine's findings at the store's place; `oegw check --here` refuses it there, as oegw run would.
TEST_F(ScanDraft, ADraftWhoseStoreFolderThisMachineLacksPassesCheckAndCheckHereRefusesIt) {
  add("elobau-mfg:0x11");
  const sd::ScanResult r = scan();
  ASSERT_EQ(r.nodes.size(), 1u);
  mapping::DraftSettings s = settings();
  const std::filesystem::path missing = dir_ / "not-made";  // no folder of that name exists
  s.store = (missing / "upstream.store").string();
  const std::string draft = mapping::draft_mapping(r, s);
  // The store's place in the draft: its line, the column of its value.
  const std::string key = "  store: ";
  const auto at = draft.find("\n" + key);
  ASSERT_NE(at, std::string::npos) << draft;
  const auto line = 2 + std::count(draft.begin(), draft.begin() + static_cast<std::ptrdiff_t>(at), '\n');
  const std::string file = (dir_ / "draft.yaml").string();
  const std::string place = file + ":" + std::to_string(line) + ":" + std::to_string(key.size() + 1) + ": ";
  const std::string finding = place + "upstream.store " + s.store + ": its folder " + missing.string() +
                              " does not exist; expected a file in an existing folder";

  ::testing::internal::CaptureStdout();
  ::testing::internal::CaptureStderr();
  const int plain = check(draft, "draft.yaml");
  std::fflush(stdout);
  const std::string out = ::testing::internal::GetCapturedStdout();
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(plain, 0) << draft << out << err;
  EXPECT_NE(out.find("on this machine (oegw check --here, and oegw run, refuse these):\nwarning: " + finding),
            std::string::npos)
      << out;

  ::testing::internal::CaptureStdout();
  ::testing::internal::CaptureStderr();
  const int here = check(draft, "draft.yaml", true);
  std::fflush(stdout);
  const std::string here_out = ::testing::internal::GetCapturedStdout();
  const std::string here_err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(here, 1) << here_out << here_err;
  EXPECT_EQ(here_err.rfind(finding, 0), 0u) << here_err;
  EXPECT_NE(here_err.find(file + ": 1 error; nothing was started"), std::string::npos) << here_err;

  std::filesystem::create_directories(missing);  // the folder made: nothing left to refuse
  EXPECT_EQ(check(draft, "draft.yaml", true), 0) << draft;
}

}  // namespace
