// What a reload of the mapping file may not change (gateway/reload.hpp reload_refusals): every
// setting that defines the upstream device or that the daemon opens at start, each refused at its
// place in the new file (its section, or the file's first line when the file does not write
// it); what a reload applies is not refused. Configs built here from a loaded file.
#include "gateway/reload.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <stdlib.h>

#include <filesystem>
#include <string>
#include <vector>

#include "tests/fixtures/fixtures.hpp"

namespace oegw::gateway {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using ::testing::StartsWith;

mapping::Config load(const std::string& yaml) {
  auto r = mapping::load_config_text(yaml, "next.yaml", driver_catalogue());
  EXPECT_TRUE(r.ok()) << r.error_text();
  return r.ok() ? *r.config : mapping::Config{};
}

class ReloadRefusals : public ::testing::Test {
 protected:
  std::string base_ = fixtures::mapping_file("demo_cab.yaml");
  mapping::Config running_ = load(base_);
  std::vector<std::string> refusals(const std::string& from, const std::string& to, const std::string& append = "") {
    std::vector<std::string> out;
    for (const auto& d : reload_refusals(running_, load(fixtures::replace_all(base_, from, to) + append)))
      out.push_back(d.str());
    return out;
  }
};

TEST_F(ReloadRefusals, WhatAStartWouldApplyIsNotRefused) {
  EXPECT_THAT(refusals("deadband: 300, invert: true", "deadband: 100"), IsEmpty());
  EXPECT_THAT(refusals("seat_knob:\n    driver: novotechnik-406\n    node_id: 0x7F",
                       "seat_knob:\n    driver: novotechnik-406\n    node_id: 0x7E"),
              IsEmpty());
  EXPECT_THAT(
      refusals("downstream: { interface: virtual, bitrate: 250000 }",
               "downstream: { interface: virtual, bitrate: 250000, sdo_timeout_ms: 500, emcy_forwarding: faults }"),
      IsEmpty());
}

TEST_F(ReloadRefusals, TheUpstreamDeviceIsRefusedAtItsSection) {
  EXPECT_THAT(refusals("heartbeat_ms: 100\ndownstream", "heartbeat_ms: 200\ndownstream"),
              ElementsAre(StartsWith("next.yaml:1:1: upstream.heartbeat_ms changed from 100 to 200: 1017h")));
  EXPECT_THAT(refusals("serial: 1 }", "serial: 2 }"),
              ElementsAre(AllOf(StartsWith("next.yaml:1:1: upstream.identity changed from vendor 00000000h product "
                                           "00000852h revision 00010000h serial 00000001h to "),
                                HasSubstr("serial 00000002h: 1018h is the LSS address"))));
  EXPECT_THAT(refusals("bitrate: 250000\n  identity", "bitrate: 500000\n  identity"),
              ElementsAre(HasSubstr("upstream.bitrate changed from 250000 to 500000")));
  const auto store =
      refusals("  heartbeat_ms: 100\ndownstream", "  heartbeat_ms: 100\n  store: /var/lib/other.store\ndownstream");
  ASSERT_EQ(store.size(), 1u);
  EXPECT_THAT(store[0], StartsWith("next.yaml:7:10: upstream.store changed from /var/lib/oegw/upstream.store to "
                                   "/var/lib/other.store"));
  EXPECT_THAT(store[0], HasSubstr("a reload cannot apply it, a restart can (systemctl restart oegw)"));
}

TEST_F(ReloadRefusals, TheFeSetAndTheDeviceTypeAreTheDictionarys) {
  // A joystick losing its buttons: 1000h (CiA 852 Table 8) changes.
  EXPECT_THAT(refusals("    buttons: right_grip.buttons[1..6]\n", ""),
              ElementsAre(HasSubstr("joystick.1 loses its buttons: 1000h, the device type, changes")));
  EXPECT_THAT(refusals("  encoder.1: { position: seat_knob.position }\n", ""),
              ElementsAre(HasSubstr("encoder.1 is no longer in the file: it leaves the upstream device's dictionary")));
}

TEST_F(ReloadRefusals, WhatTheDaemonOpensAtStart) {
  const auto r = refusals("downstream: { interface: virtual, bitrate: 250000 }",
                          "downstream: { interface: can7, bitrate: 250000 }\npublish: { period_ms: 50 }\n"
                          "control: { socket: /run/other.sock }");
  ASSERT_EQ(r.size(), 3u) << ::testing::PrintToString(r);
  EXPECT_THAT(r[0], StartsWith("next.yaml:1:1: publish changed (period_ms): the DDS participant"));
  EXPECT_THAT(r[1], StartsWith("next.yaml:7:26: downstream.interface changed from virtual to can7"));
  EXPECT_THAT(r[2], StartsWith("next.yaml:9:20: control changed (socket /run/oegw/oegw.sock group '' before, "
                               "/run/other.sock group '' now)"));
}

// A cia401 node's EDS that vanishes after the file was loaded: the reload is refused at the
// sub-device's place before the hand-over, not thrown out of the gateway's construction after it.
TEST_F(ReloadRefusals, AnEdsGoneSinceTheFileWasReadRefusesBeforeTheHandOver) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "oegw-reload-eds-XXXXXX";
  std::string templ = dir.string();
  ASSERT_NE(::mkdtemp(templ.data()), nullptr);
  const std::filesystem::path eds = std::filesystem::path(templ) / "pedal.eds";
  std::filesystem::copy_file(std::string(OEGW_SOURCE_DIR) + "/subdevices/eds/generic_pedal.eds", eds);
  const mapping::Config next = load(
      fixtures::replace_all(base_, std::string(OEGW_SOURCE_DIR) + "/subdevices/eds/generic_pedal.eds", eds.string()));
  EXPECT_THAT(build_reload_drivers(next).refusals, IsEmpty());
  std::filesystem::remove(eds);
  std::vector<std::string> r;
  const ReloadDrivers built = build_reload_drivers(next);
  EXPECT_THAT(built.drivers, IsEmpty()) << "no driver of a file refused";
  for (const auto& d : built.refusals) r.push_back(d.str());
  std::filesystem::remove_all(templ);
  ASSERT_EQ(r.size(), 1u) << ::testing::PrintToString(r);
  EXPECT_THAT(r[0], StartsWith("next.yaml:"));
  EXPECT_THAT(r[0], HasSubstr("cia401: "));
  EXPECT_THAT(r[0], HasSubstr("nothing of it is applied"));
}

}  // namespace
}  // namespace oegw::gateway
