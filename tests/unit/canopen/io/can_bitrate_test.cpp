// What the gateway does with a configured bit rate (canopen/io/can_bitrate.hpp), against a fake
// of the netlink calls: same rate, another rate (up or down), no bit timing (vcan), no such
// interface, and each step failing.
#include "canopen/io/can_bitrate.hpp"

#include <gtest/gtest.h>

#include <cerrno>
#include <map>
#include <string>
#include <vector>

using namespace oegw::canopen;
using namespace oegw::canopen::io;
namespace {

// A kernel with interfaces and their link state; records every change asked for and refuses,
// as the kernel does, a new rate on an interface that is up (EBUSY).
class FakeLink final : public CanLink {
 public:
  std::map<std::string, CanLinkState> links;
  std::vector<std::string> calls;
  int query_error = 0, stop_error = 0, set_error = 0, start_error = 0;

  int query(const std::string& name, CanLinkState& state) override {
    calls.push_back("query " + name);
    if (query_error != 0) return query_error;
    const auto it = links.find(name);
    state = it == links.end() ? CanLinkState{} : it->second;
    return 0;
  }
  int stop(const std::string& name) override {
    calls.push_back("stop " + name);
    if (stop_error != 0) return stop_error;
    links[name].up = false;
    return 0;
  }
  int set_bitrate(const std::string& name, std::uint32_t rate) override {
    calls.push_back("set " + name + " " + std::to_string(rate));
    if (set_error != 0) return set_error;
    if (links[name].up) return EBUSY;
    links[name].bitrate = rate;
    return 0;
  }
  int start(const std::string& name) override {
    calls.push_back("start " + name);
    if (start_error != 0) return start_error;
    links[name].up = true;
    return 0;
  }
};

CanLinkState controller(std::uint32_t rate, bool up) {
  return {.exists = true, .up = up, .has_bit_timing = true, .bitrate = rate};
}
CanLinkState vcan() { return {.exists = true, .up = true, .has_bit_timing = false, .bitrate = 0}; }

using Calls = std::vector<std::string>;

TEST(CanBitRate, SameRateChangesNothing) {
  FakeLink k;
  k.links["can0"] = controller(250000, true);
  const auto r = apply_bit_rate(k, "can0", 250000);
  EXPECT_TRUE(r.ok());
  EXPECT_EQ(r.action, BitRateAction::Keep);
  EXPECT_EQ(k.calls, (Calls{"query can0"}));
}

TEST(CanBitRate, OtherRateOnAnInterfaceThatIsUpIsSetBetweenDownAndUp) {
  FakeLink k;
  k.links["can0"] = controller(125000, true);
  const auto r = apply_bit_rate(k, "can0", 250000);
  EXPECT_TRUE(r.ok()) << r.message;
  EXPECT_EQ(r.action, BitRateAction::Set);
  EXPECT_EQ(r.before, 125000u);
  EXPECT_TRUE(r.was_up);
  EXPECT_EQ(k.calls, (Calls{"query can0", "stop can0", "set can0 250000", "start can0"}));
  EXPECT_EQ(k.links["can0"].bitrate, 250000u);
  EXPECT_TRUE(k.links["can0"].up);
}

TEST(CanBitRate, AnInterfaceThatIsDownIsSetAndBroughtUp) {
  FakeLink k;
  k.links["can0"] = controller(0, false);  // never configured
  const auto r = apply_bit_rate(k, "can0", 500000);
  EXPECT_TRUE(r.ok()) << r.message;
  EXPECT_EQ(r.action, BitRateAction::Set);
  EXPECT_EQ(k.calls, (Calls{"query can0", "set can0 500000", "start can0"}));
  EXPECT_TRUE(k.links["can0"].up);
}

TEST(CanBitRate, VirtualCanHasNoBitTimingAndIsLeftAlone) {
  FakeLink k;
  k.links["vcan0"] = vcan();
  const auto r = apply_bit_rate(k, "vcan0", 250000);
  EXPECT_TRUE(r.ok());
  EXPECT_EQ(r.action, BitRateAction::NoBitTiming);
  EXPECT_EQ(k.calls, (Calls{"query vcan0"}));
}

TEST(CanBitRate, AMissingInterfaceIsLeftToOpeningIt) {
  FakeLink k;
  const auto r = apply_bit_rate(k, "can7", 250000);
  EXPECT_TRUE(r.ok());
  EXPECT_EQ(r.action, BitRateAction::Missing);
  EXPECT_EQ(k.calls, (Calls{"query can7"}));
}

TEST(CanBitRate, NoPermissionIsAnErrorNamingInterfaceAndRate) {
  FakeLink k;
  k.links["can0"] = controller(125000, true);
  k.stop_error = EPERM;
  const auto r = apply_bit_rate(k, "can0", 250000);
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.error, EPERM);
  EXPECT_EQ(r.message, "cannot set can0 to 250000 bit/s: Operation not permitted");
  EXPECT_EQ(k.calls, (Calls{"query can0", "stop can0"}));
  EXPECT_EQ(k.links["can0"].bitrate, 125000u);
}

TEST(CanBitRate, ARateTheControllerRefusesBringsTheInterfaceBackAtItsOldRate) {
  FakeLink k;
  k.links["can0"] = controller(125000, true);
  k.set_error = EINVAL;
  const auto r = apply_bit_rate(k, "can0", 1000000);
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.message, "cannot set can0 to 1000000 bit/s: Invalid argument");
  EXPECT_EQ(k.calls, (Calls{"query can0", "stop can0", "set can0 1000000", "start can0"}));
  EXPECT_EQ(k.links["can0"].bitrate, 125000u);
  EXPECT_TRUE(k.links["can0"].up);
}

TEST(CanBitRate, ABusyDeviceIsAnError) {
  FakeLink k;
  k.links["can0"] = controller(125000, false);
  k.set_error = EBUSY;
  const auto r = apply_bit_rate(k, "can0", 250000);
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.message, "cannot set can0 to 250000 bit/s: Device or resource busy");
  // It was down: it stays down.
  EXPECT_EQ(k.calls, (Calls{"query can0", "set can0 250000"}));
}

TEST(CanBitRate, StartFailingIsAnError) {
  FakeLink k;
  k.links["can0"] = controller(125000, false);
  k.start_error = ENETDOWN;
  const auto r = apply_bit_rate(k, "can0", 250000);
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.error, ENETDOWN);
}

TEST(CanBitRate, AKernelThatCannotBeAskedIsAnError) {
  FakeLink k;
  k.query_error = EACCES;
  const auto r = apply_bit_rate(k, "can0", 250000);
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.message, "cannot query can0: Permission denied");
}

TEST(CanBitRate, PlanSaysWhatApplyWouldDoAndChangesNothing) {
  FakeLink k;
  k.links["can0"] = controller(125000, true);
  k.links["can1"] = controller(250000, true);
  k.links["vcan0"] = vcan();
  EXPECT_EQ(plan_bit_rate(k, "can0", 250000).action, BitRateAction::Set);
  EXPECT_EQ(plan_bit_rate(k, "can1", 250000).action, BitRateAction::Keep);
  EXPECT_EQ(plan_bit_rate(k, "vcan0", 250000).action, BitRateAction::NoBitTiming);
  EXPECT_EQ(plan_bit_rate(k, "can9", 250000).action, BitRateAction::Missing);
  EXPECT_EQ(k.calls, (Calls{"query can0", "query can1", "query vcan0", "query can9"}));
}

// The real netlink query on this machine's loopback: it exists and has no CAN bit timing.
TEST(CanBitRate, NetlinkQueryOfANonCanInterface) {
  auto link = netlink_can_link();
  CanLinkState s;
  ASSERT_EQ(link->query("lo", s), 0);
  EXPECT_TRUE(s.exists);
  EXPECT_FALSE(s.has_bit_timing);
  EXPECT_EQ(plan_bit_rate(*link, "oegwnope0", 250000).action, BitRateAction::Missing);
}

}  // namespace
