// Tier 2, findings 3 and 4 (gateway_e2e_test.cpp) for every family with outputs (elobau LEDs,
// MCB-402 OUT0..3, the CiA 401 cluster's output byte), with the invariant monitor on
// (safety_monitor.hpp):
//   * one command that changes several outputs of one sub-device reaches it as ONE frame per RPDO
//     of that device, carrying the commanded state (never 203#01 on the way from 00h to 05h);
//   * the CiA 401 error values (6206h/6207h) at a host heartbeat loss: one frame, in the same
//     call that notices the time-out (EMCY 8130h upstream and the RPDO at the same simulated
//     instant), also when the path that notices it is a downstream frame.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "safety_harness.hpp"

namespace oegw::testing::safety {
namespace {

constexpr FamilyId kOutputFamilies[] = {FamilyId::Elobau, FamilyId::Mcb402, FamilyId::Cia401Cluster};

std::uint32_t device_rpdo(const Family& f) { return f.knowledge.outputs.at(0).rpdo; }

// The FE state an RPDO carries (the test's own decoding of the device's RPDO layout).
std::uint64_t decode(const Family& f, const CanFrame& frame, std::uint64_t previous) {
  std::uint64_t s = previous;
  const auto& bits = f.knowledge.outputs.at(0).bits;
  for (std::size_t k = 0; k < bits.size(); ++k) {
    const unsigned code = (frame.data[bits[k].byte] >> bits[k].shift) & ((1u << bits[k].width) - 1);
    if (bits[k].width == 2 && code == 3) continue;
    s = code ? (s | (1ull << k)) : (s & ~(1ull << k));
  }
  return s;
}

std::string frames_since(const Bench& b, std::size_t from) {
  std::string s;
  for (std::size_t i = from; i < b.rpdos().size(); ++i) s += "  " + b.rpdos()[i].to_string() + "\n";
  return s;
}

class SafetyOutputs : public ::testing::TestWithParam<std::tuple<FamilyId, bool>> {
 protected:
  void SetUp() override {
    Monitor::Options o;
    o.inputs = false;  // this file is about the outputs (the matrix watches the inputs)
    b_ = std::make_unique<Bench>(std::get<0>(GetParam()), o);
    b_->build();
    b_->start_gateway();
    b_->power_device();
    const std::uint8_t node = b_->fam().node;
    ASSERT_TRUE(b_->run_until([&] { return b_->status() == FeStatus::Valid && b_->mon().alive(node, b_->now()); }, 3s))
        << b_->log();
  }
  std::unique_ptr<Bench> b_;
};

TEST_P(SafetyOutputs, OneCommandChangingSeveralOutputsReachesTheDeviceAsOneFrame) {
  Bench& b = *b_;
  const Family& f = b.fam();
  const bool by_rpdo = std::get<1>(GetParam());
  const std::uint32_t cob = device_rpdo(f);
  std::uint64_t state = 0;
  for (std::uint64_t cmd : {0x05ull, 0x0Aull, 0x0Full, 0x00ull, 0x03ull, 0x0Cull, 0xA5ull, 0x5Aull}) {
    cmd &= f.out_mask;
    if (cmd == state) continue;
    const std::size_t from = b.rpdos().size();
    b.command_outputs(static_cast<std::uint8_t>(cmd), by_rpdo);
    b.run_for(50ms);
    std::vector<CanFrame> got;
    for (std::size_t i = from; i < b.rpdos().size(); ++i)
      if (b.rpdos()[i].frame.id == cob) got.push_back(b.rpdos()[i].frame);
    ASSERT_EQ(got.size(), 1u) << fmt::format("{:02X}h -> {:02X}h by {}: exactly one RPDO {:03X}h expected\n", state,
                                             cmd, by_rpdo ? "RPDO" : "SDO", cob)
                              << frames_since(b, from);
    EXPECT_EQ(decode(f, got[0], state), cmd) << got[0].to_string();
    state = cmd;
  }
  EXPECT_EQ(b.mon().violations(), 0u);
}

// Error mode for every bit; error state 0Ah (masked). The host's heartbeat stops: EMCY 8130h and
// the error state in one RPDO frame, at the same instant.
void expect_error_state_with_the_emcy(Bench& b, std::size_t from, std::uint64_t before) {
  const Family& f = b.fam();
  const std::uint32_t cob = device_rpdo(f);
  std::optional<TimePoint> emcy;
  for (const auto& r : b.up_emcys())
    if (r.frame.data[0] == 0x30 && r.frame.data[1] == 0x81) emcy = r.time;
  ASSERT_TRUE(emcy) << "no EMCY 8130h upstream\n" << b.log();
  std::vector<BusRecord> got;
  for (std::size_t i = from; i < b.rpdos().size(); ++i)
    if (b.rpdos()[i].frame.id == cob) got.push_back(b.rpdos()[i]);
  ASSERT_EQ(got.size(), 1u) << "the error values as exactly one frame\n" << frames_since(b, from);
  EXPECT_EQ(decode(f, got[0].frame, before), 0x0Au & f.out_mask) << got[0].to_string();
  EXPECT_LE(got[0].time - *emcy, 1ms)
      << fmt::format("error values {} ms after EMCY 8130h",
                     std::chrono::duration_cast<std::chrono::milliseconds>(got[0].time - *emcy).count());
  EXPECT_GE(got[0].time, *emcy - 1ms) << "error values before the host was lost?";
}

TEST_P(SafetyOutputs, HostHeartbeatLossAppliesTheErrorValuesInOneFrameAtOnce) {
  Bench& b = *b_;
  const Family& f = b.fam();
  b.host_heartbeat();
  b.error_values(0xFF, 0x0A);
  b.command_outputs(static_cast<std::uint8_t>(0x05 & f.out_mask), std::get<1>(GetParam()));
  b.run_for(500ms);
  const std::size_t from = b.rpdos().size();
  b.host_alive = false;
  b.run_for(600ms);
  expect_error_state_with_the_emcy(b, from, 0x05 & f.out_mask);
  EXPECT_EQ(b.mon().violations(), 0u);
}

// Finding 3: the time-out noticed on the path that handles downstream frames. A device frame
// reaches the gateway at every millisecond around the host's consumer deadline, each before the
// gateway's own timer at that instant (armed earlier): whichever call notices the loss must
// apply the error values in that call.
TEST_P(SafetyOutputs, HostHeartbeatLossNoticedWhileHandlingADownstreamFrame) {
  Bench& b = *b_;
  const Family& f = b.fam();
  b.host_heartbeat();
  b.error_values(0xFF, 0x0A);
  b.command_outputs(static_cast<std::uint8_t>(0x05 & f.out_mask), std::get<1>(GetParam()));
  b.run_for(450ms);
  // The host's next heartbeat is its last one: it stops right after it; the gateway's consumer
  // deadline is 250 ms after it.
  const auto periods = (b.now() - b.host_hb_first) / 100ms + 1;
  const TimePoint last = b.host_hb_first + periods * 100ms;
  for (int k = -10; k <= 10; ++k)
    b.loop().call_at(last + 250ms + std::chrono::milliseconds(k),
                     [&b, &f] { b.gateway_receives(CanFrame(0x700 + f.node, {0x05})); });
  b.run_until([&] { return b.now() > last; }, 200ms);
  b.host_alive = false;
  const std::size_t from = b.rpdos().size();
  b.run_for(500ms);
  expect_error_state_with_the_emcy(b, from, 0x05 & f.out_mask);
  EXPECT_EQ(b.mon().violations(), 0u);
}

std::string out_name(const ::testing::TestParamInfo<std::tuple<FamilyId, bool>>& i) {
  return std::string(name(std::get<0>(i.param))) + (std::get<1>(i.param) ? "_ByRpdo" : "_BySdo");
}
INSTANTIATE_TEST_SUITE_P(Families, SafetyOutputs,
                         ::testing::Combine(::testing::ValuesIn(kOutputFamilies), ::testing::Bool()), out_name);

}  // namespace
}  // namespace oegw::testing::safety
