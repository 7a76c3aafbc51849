// Run-time state of remote SDO (gateway/remote_sdo.hpp, canopen/state.hpp): the next ticket and
// the counters, the refusals by sub-device among them. A copy given the state counts on from
// there; none is taken while a transfer is in flight.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "canopen/master.hpp"
#include "gateway/remote_sdo.hpp"
#include "subdevices/network_manager.hpp"
#include "tests/unit/canopen/state_twin.hpp"

namespace {

using namespace oegw;
using canopen::SdoAbortCode;
using canopen::SdoTarget;

// Two sub-devices on network 2; neither is added to the network manager, so each transfer to
// them is refused as "not started" (0800 0022h) and counted against it.
mapping::Config config() {
  mapping::Config c;
  c.upstream.node_id = 0x20;
  c.downstream.network_id = 2;
  mapping::SubdeviceConfig grip;
  grip.name = "grip";
  grip.driver = "elobau-mfg";
  grip.node_id = 0x11;
  mapping::SubdeviceConfig knob = grip;
  knob.name = "knob";
  knob.node_id = 0x12;
  c.subdevices = {grip, knob};
  return c;
}

struct Side {
  mapping::Config cfg = config();
  canopen::ObjectDictionary od;
  canopen::Master master{od, [](const canopen::CanFrame&) {}};
  subdevices::NetworkManager network{master};
  gateway::RemoteSdo remote{cfg, master, network, [] { return canopen::NodeId{0x20}; }};
  std::vector<SdoAbortCode> results;

  gateway::RemoteSdo::Ticket upload(std::uint8_t node) {
    return remote.upload(SdoTarget{2, node}, 0x1018, 1, canopen::TimePoint{},
                         [this](SdoAbortCode code, std::vector<std::uint8_t>) { results.push_back(code); });
  }
};

TEST(RemoteSdoState, ACopyGivenTheStateCountsOnAndTicketsFollow) {
  Side a;
  a.upload(0x11);
  a.upload(0x11);
  a.upload(0x12);
  a.upload(0x30);  // no sub-device: only the total counts it
  EXPECT_EQ(a.results,
            (std::vector<SdoAbortCode>{SdoAbortCode::CannotTransferDeviceState, SdoAbortCode::CannotTransferDeviceState,
                                       SdoAbortCode::CannotTransferDeviceState, SdoAbortCode::SubIndexDoesNotExist}));
  Side b;
  canopen::test_support::copy_state(a.remote, b.remote);
  EXPECT_EQ(b.remote.refused("grip"), 2u);
  EXPECT_EQ(b.remote.refused("knob"), 1u);
  EXPECT_EQ(b.remote.counters().refused, 4u);
  EXPECT_EQ(b.upload(0x12), a.upload(0x12));
  Side fresh;
  EXPECT_NE(fresh.upload(0x12), a.upload(0x12));
}

TEST(RemoteSdoState, AStateWithTooFewRefusalsOrOtherSubdevicesIsRefused) {
  Side a;
  a.upload(0x11);
  const std::string text = canopen::test_support::state_text(a.remote);
  using canopen::test_support::refusal;
  using canopen::test_support::with_value;
  Side b;
  EXPECT_EQ(refusal(b.remote, with_value(text, "counters.refused", "0")),
            "state: 'counters.refused' is below the sub-devices' refusals");
  EXPECT_EQ(refusal(b.remote, with_value(text, "next", "0")), "state: 'next' is 0: tickets start at 1");
  EXPECT_EQ(refusal(b.remote, with_value(text, "refused_by.count", "3")), "state: 'refused_by.count' = 3 is above 2");
}

}  // namespace
