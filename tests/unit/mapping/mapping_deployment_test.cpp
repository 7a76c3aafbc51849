// The checks `oegw check` and `oegw run` add to the loader's (mapping/deployment.hpp), on Configs
// built here: the file's (deployment_errors, refused everywhere) apart from this machine's
// (machine_errors: `oegw check` warns, `oegw check --here` and `oegw run` refuse); the built
// program's messages are tested outside in (tests/CMakeLists.txt oegw_check_cab_*).
#include "mapping/deployment.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace oegw::mapping {
namespace {

Config cab() {
  Config c;
  c.upstream.interface = "can0";
  c.upstream.interface_where = {"cab.yaml", 2, 14};
  c.upstream.store = "/var/lib/up.store";  // a folder only root writes (not /tmp: warned)
  c.upstream.where = {"cab.yaml", 1, 1};
  c.downstream.interface = "can1";
  c.downstream.interface_where = {"cab.yaml", 5, 14};
  SubdeviceConfig grip;
  grip.name = "grip";
  grip.where = {"cab.yaml", 8, 3};
  c.subdevices.push_back(grip);
  FunctionalElementConfig fe;
  FieldBinding b;
  b.subdevice = "grip";
  fe.fields.push_back(b);
  c.functional_elements.push_back(fe);
  return c;
}

std::vector<std::string> strs(const std::vector<Diagnostic>& d) {
  std::vector<std::string> out;
  for (const auto& x : d) out.push_back(x.str());
  return out;
}
// The file's errors.
std::vector<std::string> errors(const Config& c) { return strs(deployment_errors(c)); }
// This machine's, after asserting that none of them is among the file's: a file is right or
// wrong whichever computer checks it.
std::vector<std::string> here(const Config& c) {
  EXPECT_TRUE(deployment_errors(c).empty()) << deployment_errors(c).front().str();
  return strs(machine_errors(c));
}

TEST(Deployment, ACabFileHasNothingToRefuseOrWarnAbout) {
  EXPECT_TRUE(deployment_errors(cab()).empty());
  EXPECT_TRUE(machine_errors(cab()).empty());
  EXPECT_TRUE(deployment_warnings(cab()).empty());
  EXPECT_TRUE(machine_warnings(cab()).empty());
}

// The file's mistakes are never this machine's: machine_errors() does not repeat them.
TEST(Deployment, TheFilesMistakesAreNotThisMachines) {
  Config c = cab();
  c.upstream.interface = "virtual";
  c.downstream.interface = "can/1";
  EXPECT_EQ(errors(c).size(), 2u);
  EXPECT_TRUE(machine_errors(c).empty());
}

TEST(Deployment, InterfaceNamesTheKernelRefuses) {
  for (const auto& [name, why] :
       std::vector<std::pair<std::string, std::string>>{{"", "'' is empty"},
                                                        {"can0123456789abc", "is 16 bytes long"},
                                                        {"can/0", "contains '/'"},
                                                        {"can0:1", "contains ':'"},
                                                        {"can\t0", "contains white space"},
                                                        {"..", "which the kernel refuses"}}) {
    Config c = cab();
    c.upstream.interface = name;
    const auto e = errors(c);
    ASSERT_EQ(e.size(), 1u) << name;
    EXPECT_NE(e[0].find("cab.yaml:2:14: upstream.interface '" + name + "' "), std::string::npos) << e[0];
    EXPECT_NE(e[0].find(why), std::string::npos) << e[0];
  }
  Config c = cab();
  c.upstream.interface = "can0123456789ab";  // 15 bytes: IFNAMSIZ - 1
  EXPECT_TRUE(errors(c).empty());
}

TEST(Deployment, VirtualIsTheDemosBusAndBothBusesOnVirtualAreTwoErrorsNotThree) {
  Config c = cab();
  c.upstream.interface = "virtual";
  c.downstream.interface = "virtual";
  const auto e = errors(c);
  ASSERT_EQ(e.size(), 2u);
  EXPECT_EQ(e[0],
            "cab.yaml:2:14: upstream.interface: interface virtual is the embedded demo's bus: use oegw demo, "
            "or name a CAN interface (can0, can1, vcan0, ...)");
  EXPECT_EQ(e[1].rfind("cab.yaml:5:14: downstream.interface: interface virtual", 0), 0u) << e[1];
}

TEST(Deployment, OneInterfaceForBothBusesIsRefusedAtTheDownstreamOne) {
  Config c = cab();
  c.downstream.interface = "can0";
  EXPECT_EQ(errors(c), std::vector<std::string>{"cab.yaml:5:14: downstream.interface can0 is upstream.interface too "
                                                "(line 2, column 14); expected two CAN interfaces: the host's bus and "
                                                "the sub-devices' bus"});
}

TEST(Deployment, AStoreWhoseFolderDoesNotExistIsThisMachinesAtItsSettingOrItsSection) {
  Config c = cab();
  c.upstream.store = "/nonexistent/oegw/up.store";
  c.upstream.store_where = {"cab.yaml", 3, 10};
  auto e = here(c);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].rfind("cab.yaml:3:10: upstream.store /nonexistent/oegw/up.store: its folder /nonexistent/oegw does "
                       "not exist",
                       0),
            0u)
      << e[0];
  c.upstream.store_where = {};  // the default, not written: at the upstream section
  e = here(c);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].rfind("cab.yaml:1:1: upstream.store /nonexistent/oegw/up.store (the default)", 0), 0u) << e[0];
  c.upstream.store = "up.store";  // in the working directory: a folder that is there
  EXPECT_TRUE(here(c).empty());
}

// The black box's folder (docs/guides/black-box.md): oegw run makes a missing one; a path
// through a file cannot be made. Not checked while recording is off.
TEST(Deployment, ARecordFolderUnderAFileIsThisMachinesAtItsSetting) {
  char tmpl[] = "/tmp/oegw-deploy-record-XXXXXX";
  const std::filesystem::path dir = ::mkdtemp(tmpl);
  std::ofstream(dir / "plain") << "x";
  Config c = cab();
  c.record.dir = (dir / "plain" / "record").string();
  c.record.dir_where = {"cab.yaml", 12, 25};
  c.record.where = {"cab.yaml", 12, 1};
  EXPECT_TRUE(here(c).empty()) << "recording is off";
  c.record.enabled = true;
  EXPECT_THAT(here(c),
              ::testing::ElementsAre("cab.yaml:12:25: record.dir " + c.record.dir + ": " + (dir / "plain").string() +
                                     " is a file, not a folder; expected a folder oegw run may make or write"));
  c.record.dir = (dir / "not" / "yet").string();  // made by oegw run
  EXPECT_TRUE(here(c).empty());
  std::filesystem::remove_all(dir);
}

// The store is never read through a link nor replaced over one (canopen/301/storage.hpp): a
// link there would leave the device on defaults at every start. Refused at the setting.
TEST(Deployment, ASymlinkedStoreIsThisMachinesAtItsSetting) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("oegw-deploy-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  ::chmod(dir.c_str(), 0755);
  std::filesystem::create_symlink(dir / "elsewhere.store", dir / "up.store");
  Config c = cab();
  c.upstream.store = (dir / "up.store").string();
  c.upstream.store_where = {"cab.yaml", 3, 10};
  const auto e = here(c);
  std::filesystem::remove_all(dir);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0], "cab.yaml:3:10: upstream.store " + (dir / "up.store").string() + " is a symbolic link (to " +
                      (dir / "elsewhere.store").string() +
                      "); expected a plain file or none: the gateway never follows a link there; name the file itself");
}

// A folder every user may write (/tmp, mode 1777 — the sticky bit stops nobody from placing a
// store file or its .lss there first): the gateway runs, `oegw check` warns at the setting.
TEST(Deployment, WarnsOnAStoreFolderEveryUserMayWrite) {
  Config c = cab();
  EXPECT_TRUE(machine_warnings(c).empty());
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("oegw-deploy-w-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  ::chmod(dir.c_str(), 0777);
  c.upstream.store = (dir / "up.store").string();
  c.upstream.store_where = {"cab.yaml", 3, 10};
  const std::vector<std::string> w = strs(machine_warnings(c));
  const bool file_silent = deployment_warnings(c).empty();  // a fact of this machine, not of the file
  const bool runs = errors(c).empty() && machine_errors(c).empty();
  ::chmod(dir.c_str(), 0755);
  const auto none = machine_warnings(c).empty();
  std::filesystem::remove_all(dir);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].rfind("cab.yaml:3:10: upstream.store " + (dir / "up.store").string() + ": its folder " + dir.string() +
                           " is writable by every user (mode 0777): anyone on this machine can place the parameters",
                       0),
            0u)
      << w[0];
  EXPECT_TRUE(none);
  EXPECT_TRUE(file_silent);
  EXPECT_TRUE(runs);
}

TEST(Deployment, TheControlSocketRunWouldRefuseOnThisMachine) {
  Config c = cab();
  c.control.where = {"cab.yaml", 12, 1};
  c.control.socket = "/tmp/oegw-deployment-test.sock";  // /tmp exists: fine
  EXPECT_TRUE(here(c).empty());
  c.control.socket = "/tmp/oegw-deployment-test-no-such-dir/oegw.sock";  // its folder made by run
  EXPECT_TRUE(here(c).empty());
  c.control.group = "root";
  EXPECT_TRUE(here(c).empty());
  c.control.group = "oegw_no_such_group_x";
  c.control.group_where = {"cab.yaml", 12, 40};
  c.control.socket = "/nonexistent-oegw/run/oegw.sock";
  c.control.socket_where = {"cab.yaml", 12, 20};
  // In the file's order: the socket (column 20), then the group (column 40).
  EXPECT_THAT(here(c),
              ::testing::ElementsAre(
                  ::testing::StartsWith("cab.yaml:12:20: control.socket /nonexistent-oegw/run/oegw.sock: its folder "
                                        "/nonexistent-oegw/run does not exist, nor does /nonexistent-oegw (oegw run "
                                        "makes only the socket's own folder)"),
                  ::testing::StartsWith(
                      "cab.yaml:12:40: control.group: no group 'oegw_no_such_group_x' on this machine")));
  c.control.group.clear();
  // One socket path each: the only error (or "" when there is none, or several).
  const auto only = [&c](const char* socket) {
    c.control.socket = socket;
    const auto all = here(c);
    return all.size() == 1 ? all[0] : std::string();
  };
  EXPECT_EQ(only("/etc/hostname"),  // a plain file: run does not take it
            "cab.yaml:12:20: control.socket /etc/hostname: /etc/hostname exists and is not a socket (oegw run "
            "would not replace it); remove it or choose another control.socket");
  EXPECT_NE(only("/etc/hostname/oegw.sock").find("/etc/hostname is not a folder"), std::string::npos);
  c.control.socket_where = {};  // the default's place: the section
  EXPECT_EQ(only("/nonexistent-oegw/run/oegw.sock")
                .rfind("cab.yaml:12:1: control.socket /nonexistent-oegw/run/oegw.sock (the default): ", 0),
            0u);
  c.control.enabled = false;  // no socket: nothing to refuse
  c.control.group = "oegw_no_such_group_x";
  EXPECT_TRUE(here(c).empty());
}

TEST(Deployment, WarnsOnAMandatorySubDeviceWithoutHeartbeatAndOnOneNoFeUses) {
  Config c = cab();
  c.subdevices[0].mandatory = true;
  c.subdevices[0].heartbeat_ms = 0;
  SubdeviceConfig spare;
  spare.name = "spare";
  spare.where = {"cab.yaml", 9, 3};
  c.subdevices.push_back(spare);
  const auto w = deployment_warnings(c);
  ASSERT_EQ(w.size(), 2u);
  EXPECT_EQ(w[0].str().rfind("cab.yaml:8:3: sub-device 'grip' is mandatory with heartbeat_ms 0", 0), 0u) << w[0].str();
  EXPECT_EQ(w[1].str().rfind("cab.yaml:9:3: sub-device 'spare' feeds no functional element", 0), 0u) << w[1].str();
  EXPECT_TRUE(deployment_errors(c).empty());  // warnings only
}

// An FE that takes LCM commands (sources listing lcm) on a URL others can send to is warned about
// at the URL, naming publish.lcm.url and the FEs; LCM commands are opt-in (config.hpp).
Config cab_with_lamps(CommandSources sources, std::string url) {
  Config c = cab();
  c.publish.lcm.enabled = true;
  c.publish.lcm.where = {"cab.yaml", 12, 3};
  c.publish.lcm.url = std::move(url);
  c.publish.lcm.url_where = {"cab.yaml", 12, 15};
  FunctionalElementConfig lamps;
  lamps.id = {FeKind::IndicatorCluster, 1};
  lamps.sources = sources;
  FieldBinding b;
  b.subdevice = "grip";
  lamps.fields.push_back(b);
  c.functional_elements.push_back(lamps);
  return c;
}

TEST(Deployment, WarnsWhenAnLcmUrlReachingBeyondThisHostCarriesCommands) {
  const CommandSources with_lcm = kDefaultCommandSources | static_cast<CommandSources>(CommandSource::Lcm);
  auto w = deployment_warnings(cab_with_lamps(with_lcm, "udpm://239.255.76.67:7667?ttl=1"));
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].str().rfind("cab.yaml:12:15: publish.lcm.url udpm://239.255.76.67:7667?ttl=1 carries commands for "
                             "indicators.1 (sources list lcm), and its ttl 1 makes it a network's group",
                             0),
            0u)
      << w[0].str();
  EXPECT_TRUE(deployment_errors(cab_with_lamps(with_lcm, "udpm://239.255.76.67:7667?ttl=1")).empty());  // a warning

  // The default URL, not written: at the lcm section, "(the default)".
  Config c = cab_with_lamps(with_lcm, "udpm://239.255.76.67:7667?ttl=0");
  c.publish.lcm.url_where = {};
  w = deployment_warnings(c);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].str().rfind("cab.yaml:12:3: publish.lcm.url udpm://239.255.76.67:7667?ttl=0 (the default) carries", 0),
            0u)
      << w[0].str();

  // Host-local URL, or no FE taking LCM, or LCM off: nothing.
  EXPECT_TRUE(deployment_warnings(cab_with_lamps(with_lcm, "udpm://224.0.0.1:7667?ttl=0")).empty());
  EXPECT_TRUE(deployment_warnings(cab_with_lamps(kDefaultCommandSources, "udpm://239.255.76.67:7667?ttl=1")).empty());
  c = cab_with_lamps(with_lcm, "udpm://239.255.76.67:7667?ttl=1");
  c.publish.lcm.enabled = false;
  EXPECT_TRUE(deployment_warnings(c).empty());
}

}  // namespace
}  // namespace oegw::mapping
