// Time on the wire: the simulators' SDO latency on the timed virtual bus, and
// the simulated cab (rig/cab_rig.hpp) booting on timed buses - every frame taking its real
// length at the bit rate, never two on the wire at once. All on a simulated clock: no sleeps.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include "canopen/301/sdo_pacer.hpp"
#include "canopen/frame_bits.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "gateway/control/status_report.hpp"
#include "mapping/config.hpp"
#include "rig/cab_rig.hpp"
#include "subdevices/device_spec.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "tests/fixtures/fixtures.hpp"

using namespace oegw;
using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;

namespace {

const TimePoint kStart{std::chrono::seconds(10)};

// One Novotechnik encoder (node 7Fh) simulated on a timed bus, and a bare port asking it.
struct OneDevice {
  SimulatedClock clock{kStart};
  EventLoop loop{clock};
  VirtualBus bus;
  std::unique_ptr<VirtualPort> sims = (bus.run_timed_on(loop, 250'000), bus.attach("sims"));
  std::unique_ptr<VirtualPort> tester = bus.attach("tester");
  subdevices::sim::SimBench bench{sims->sink()};
  std::unique_ptr<ServiceDriver> driver;
  std::vector<std::pair<CanFrame, TimePoint>> got;
  OneDevice() {
    std::string error;
    auto spec = subdevices::parse_device_spec("novotechnik-406:0x7F:name=knob", error);
    EXPECT_TRUE(spec && bench.add(*spec, error)) << error;
    driver = std::make_unique<ServiceDriver>(loop, bench);
    driver->bind_receiver(*sims, bench);
    tester->set_receiver([this](const CanFrame& f, TimePoint t) { got.emplace_back(f, t); });
  }
  ~OneDevice() {
    sims->set_receiver({});
    tester->set_receiver({});
  }
  // The answer to an SDO upload of 1000h, and when it arrived.
  std::pair<CanFrame, TimePoint> ask_device_type() {
    got.clear();
    const CanFrame request{0x67F, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}};
    EXPECT_TRUE(tester->send(request).ok());
    loop.advance_by(50ms);
    for (const auto& g : got)
      if (g.first.id == 0x5FF) return g;
    ADD_FAILURE() << "no SDO answer";
    return {};
  }
};

TEST(SimulatorLatency, TheDefaultIsOneMillisecondAndTheInstantBusKeepsNone) {
  EXPECT_EQ(subdevices::sim::kTypicalSdoLatency, 1ms);
  OneDevice d;
  EXPECT_EQ(d.bench.device("knob")->sdo_latency(), 0us) << "a simulator answers at once unless told";
}

TEST(SimulatorLatency, AnSdoAnswerLeavesTheLatencyAfterTheRequestArrived) {
  for (const Duration latency : {Duration{0}, Duration{1ms}, Duration{3500us}}) {
    OneDevice d;
    d.bench.set_sdo_latency(latency);
    d.bench.start(d.loop.now());
    d.driver->rearm();
    d.loop.advance_by(20ms);  // the boot-up goes by
    const TimePoint asked = d.loop.now();
    const auto [answer, at] = d.ask_device_type();
    // 67Fh 40 00 10 00 00 00 00 00 on the wire, received 3 bits before its end; the answer is
    // sent `latency` later and (the bus being idle by then, or after the request's
    // intermission when there is no latency) takes its own length.
    const CanFrame request{0x67F, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}};
    const Duration request_on_wire = 4us * (frame_bits(request) - 3);
    const Duration answer_on_wire = 4us * (frame_bits(answer) - 3);
    const Duration start_of_answer = latency.count() == 0 ? request_on_wire + 12us : request_on_wire + latency;
    EXPECT_EQ(answer.data[0], 0x43) << "an expedited upload answer of 4 bytes";
    EXPECT_EQ(at - asked, start_of_answer + answer_on_wire) << "latency " << latency.count() << " us";
  }
}

TEST(SimulatorLatency, OtherFramesAreNotDelayedAndARebootLosesThePendingAnswer) {
  OneDevice d;
  d.bench.set_sdo_latency(5ms);
  d.bench.start(d.loop.now());
  d.driver->rearm();
  d.loop.advance_by(20ms);
  d.got.clear();
  ASSERT_TRUE(d.tester->send(CanFrame{0x67F, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}}).ok());
  d.loop.advance_by(1ms);  // the request arrived; its answer is 4.5 ms away
  EXPECT_EQ(d.bench.command("knob reboot", d.loop.now()).rfind("ok", 0), 0u);
  d.driver->rearm();
  d.loop.advance_by(20ms);
  ASSERT_FALSE(d.got.empty());
  EXPECT_EQ(d.got.front().first.to_string(), "77F#00") << "the boot-up is not an SDO answer: not delayed";
  for (const auto& g : d.got) EXPECT_NE(g.first.id, 0x5FFu) << "the answer died with the device's application";
}

// The demo cab (tests/fixtures/demo_cab.yaml: config/demo.yaml's devices) at 250 kbit/s.
mapping::Config demo_config() {
  const auto r =
      mapping::load_config_text(fixtures::mapping_file("demo_cab.yaml"), "demo_cab.yaml", gateway::driver_catalogue());
  if (!r.ok()) throw std::runtime_error(r.error_text());
  mapping::Config c = *r.config;
  c.upstream.bitrate = 250'000;
  c.downstream.bitrate = 250'000;
  return c;
}

TEST(TimedCab, TheDemoCabBootsOnTimedBusesAndNoTwoFramesOverlap) {
  SimulatedClock clock{kStart};
  EventLoop loop{clock};
  oegw::rig::CabRig rig(demo_config(), loop,
                        oegw::rig::CabRigOptions{.store = "/nonexistent-oegw-test/upstream.store",
                                                 .timed_buses = true});
  rig.build();
  ASSERT_TRUE(rig.down().timed());
  EXPECT_EQ(rig.devices().device("right_grip")->sdo_latency(), subdevices::sim::kTypicalSdoLatency);
  std::vector<BusRecord> down;
  rig.down().set_tap([&](const BusRecord& r) { down.push_back(r); });
  rig.power_on();
  rig.run_for(3s);
  for (const auto& n : rig.gw().downstream().names())
    EXPECT_EQ(rig.gw().downstream().state(n), subdevices::NodeState::Operational) << n;
  ASSERT_GT(down.size(), 100u);
  // Each frame is received at the end of its EOF; the next one cannot be received before its
  // own length after the previous one's intermission: t[i+1] - t[i] >= bits(i+1) x 4 us.
  for (std::size_t i = 1; i < down.size(); ++i) {
    const Duration gap = down[i].time - down[i - 1].time;
    ASSERT_GE(gap, 4us * frame_bits(down[i].frame)) << "frame " << i << ": " << down[i].to_string();
  }
  // The bus time counted is the frames' lengths.
  std::uint64_t bits = 0;
  for (const auto& r : down) bits += frame_bits(r.frame);
  EXPECT_GE(rig.down().stats().bits, bits);  // >=: a frame may be on the wire at the end
  rig.down().set_tap({});
}

TEST(TimedCab, APowerOnBootUpCrossingTheResetDoesNotCostARefusal) {
  // Gateway and devices power on together: each device's power-on boot-up and the boot-up
  // answering the gateway's NMT reset communication both reach the gateway, the second while
  // the first configuration's 1000h read is waiting for the device's 1 ms latency. Starting over
  // used to abort that read and send it again: the late answer to the aborted read was taken
  // for the new one, and the new one's for the 1018h:01 read after it - 08000000h, node
  // refused, a second boot one back-off (1 s) later. Now the read in flight is let finish.
  SimulatedClock clock{kStart};
  EventLoop loop{clock};
  oegw::rig::CabRig rig(demo_config(), loop,
                        oegw::rig::CabRigOptions{.store = "/nonexistent-oegw-test/upstream.store",
                                                 .timed_buses = true});
  std::vector<std::string> log;
  rig.on_gateway = [&log](gateway::Gateway& gw) { gw.on_log = [&log](const std::string& l) { log.push_back(l); }; };
  rig.build();
  rig.power_on();
  rig.run_for(400ms);
  std::string all;
  for (const auto& l : log) all += l + "\n";
  for (const auto& n : rig.gw().downstream().names())
    EXPECT_EQ(rig.gw().downstream().state(n), subdevices::NodeState::Operational) << n << "\n" << all;
  EXPECT_EQ(all.find("refused"), std::string::npos) << all;
  EXPECT_NE(all.find("boot-up again during its configuration"), std::string::npos)
      << "the crossing this test is about did not happen:\n"
      << all;
}

// The SDO pacing (canopen/301/sdo_pacer.hpp) judged exactly, on simulated time: the demo cab on
// timed buses at 250 kbit/s, devices answering SDO at once (the worst case: without pacing the
// next request follows each answer), boots, then two devices reboot and are configured again.
// Every SDO initiate request the gateway sends downstream (ccs 1 and 2, block 5/6 with cs 0: a
// transfer's segments follow their answers and are not paced) is stamped as it leaves the
// gateway; consecutive ones are at least SdoPacer::gap_for(250 kbit/s, 0.85) = 1,271 us apart
// (two 8-byte frames at their worst-case stuffing, 135 bits each, on 85 % of the bus), and the
// pacing is what holds them: the shortest gap is that gap exactly. Without pacing
// (sdo_bus_share 0) the same cab sends requests microseconds apart. `oegw status --json` shows the
// gap and the requests that waited for it (downstream.sdo_pacing). (The VM tier checks only what
// timing cannot break: tests/vm/guest/gateway.sh.)
struct PacedRun {
  std::vector<TimePoint> starts;
  nlohmann::json pacing;  // the status report's downstream.sdo_pacing
};

PacedRun sdo_request_starts(double sdo_bus_share) {
  SimulatedClock clock{kStart};
  EventLoop loop{clock};
  gateway::GatewayOptions gw;
  gw.sdo_bus_share = sdo_bus_share;
  oegw::rig::CabRig rig(demo_config(), loop,
                        oegw::rig::CabRigOptions{.store = "/nonexistent-oegw-test/upstream.store",
                                                 .gateway = gw,
                                                 .timed_buses = true,
                                                 .device_sdo_latency = Duration{0}});
  PacedRun run;
  auto& starts = run.starts;
  const TimePoint began = loop.now();
  rig.from_gateway_down = [&](const CanFrame& f) {
    if (f.id < 0x600 || f.id > 0x67F || f.dlc < 1) return false;
    const std::uint8_t b = f.data[0], ccs = b >> 5;
    if (ccs == 1 || ccs == 2 || (ccs == 5 && (b & 0x03) == 0) || (ccs == 6 && (b & 0x01) == 0))
      starts.push_back(loop.now());
    return false;  // the frame goes on
  };
  rig.build();
  rig.power_on();
  rig.run_for(3s);
  for (const char* rebooted : {"right_grip", "seat_knob"}) {
    EXPECT_EQ(rig.command(std::string(rebooted) + " reboot").rfind("ok", 0), 0u);
    rig.run_for(3s);
  }
  for (const auto& n : rig.gw().downstream().names())
    EXPECT_EQ(rig.gw().downstream().state(n), subdevices::NodeState::Operational) << n;
  run.pacing = gateway::control::status_report(rig.gw(), rig.config(), {loop.now(), began})["downstream"]["sdo_pacing"];
  return run;
}

TEST(TimedCab, TheGatewayStartsItsDownstreamSdoRequestsAtLeastThePacingGapApart) {
  const Duration gap = SdoPacer::gap_for(250'000, gateway::GatewayOptions::kDefaultSdoBusShare);
  ASSERT_EQ(gap, 1271us) << "270 bits / (250,000 bit/s x 0.85)";
  const PacedRun paced_run = sdo_request_starts(gateway::GatewayOptions::kDefaultSdoBusShare);
  const std::vector<TimePoint>& paced = paced_run.starts;
  ASSERT_GE(paced.size(), 50u) << "the boot and the two reboots configure five devices";
  Duration shortest = Duration::max();
  for (std::size_t i = 1; i < paced.size(); ++i) {
    EXPECT_GE(paced[i] - paced[i - 1], gap) << "request " << i;
    shortest = std::min(shortest, paced[i] - paced[i - 1]);
  }
  EXPECT_EQ(shortest, gap) << "the pacing, not the devices, set the pace";
  // The status report: the gap, and how many requests waited for it (some: the devices answer at
  // once; not the first).
  EXPECT_EQ(paced_run.pacing["gap_us"], 1271);
  EXPECT_GT(paced_run.pacing["delayed_starts"].get<std::size_t>(), 0u);
  EXPECT_LT(paced_run.pacing["delayed_starts"].get<std::size_t>(), paced.size());

  const PacedRun unpaced_run = sdo_request_starts(0.0);
  const std::vector<TimePoint>& unpaced = unpaced_run.starts;
  EXPECT_EQ(unpaced_run.pacing["gap_us"], 0);
  EXPECT_EQ(unpaced_run.pacing["delayed_starts"], 0);
  ASSERT_GE(unpaced.size(), 50u);
  std::size_t close = 0;
  for (std::size_t i = 1; i < unpaced.size(); ++i) close += unpaced[i] - unpaced[i - 1] < gap ? 1 : 0;
  EXPECT_GT(close, unpaced.size() / 2) << "without pacing most requests follow each other sooner than the gap";
}

// Invariant: the gateway's SDO traffic — whose COB-IDs (580h/600h + node) win arbitration over
// every heartbeat and boot-up (700h + node) — never costs a node its heartbeat, however fast the
// devices answer: the full FE set at 250 kbit/s (about half the bus in steady state) boots, and
// a sub-device rebooting alone is configured again while the rest of the cab runs without
// another node lost. One node of each family is rebooted in turn, the highest node-ID among
// them (cluster8, 757h: the heartbeat that loses every arbitration) last; the devices answer
// SDO after 1 ms, 250 us and at once (back-to-back SDO, the worst case for the others). A
// monitor checks every other node every millisecond and fails at the first one not
// operational. Without the SDO pacing (GatewayOptions::sdo_bus_share 0) the cab did not boot
// with devices answering within 750 us: the configurations' SDO starved the boot-ups, probes
// went unanswered, nodes were started while others were still being configured, and their
// first heartbeats came too late — a cascade of losses.
class TimedFullSet : public ::testing::TestWithParam<Duration> {};

TEST_P(TimedFullSet, TheCabBootsAndALoneRebootAtHalfLoadCostsNoOtherNodeItsHeartbeat) {
  const auto r = mapping::load_config_text(fixtures::full_fe_set_at_250k(), "full_fe_set.yaml at 250 kbit/s",
                                           gateway::driver_catalogue());
  ASSERT_TRUE(r.ok()) << r.error_text();
  SimulatedClock clock{kStart};
  EventLoop loop{clock};
  oegw::rig::CabRig rig(*r.config, loop,
                        oegw::rig::CabRigOptions{.store = "/nonexistent-oegw-test/upstream.store",
                                                 .timed_buses = true,
                                                 .device_sdo_latency = GetParam()});
  rig.build();
  rig.power_on();
  rig.run_for(4s);
  auto& down = rig.gw().downstream();
  const auto names = down.names();
  ASSERT_EQ(names.size(), 48u);
  for (const auto& n : names) ASSERT_EQ(down.state(n), subdevices::NodeState::Operational) << n << " did not boot";
  for (const std::string rebooted : {"grip1", "pedal1", "enc1", "cluster8"}) {
    ASSERT_EQ(rig.command(rebooted + " reboot").rfind("ok", 0), 0u);
    const TimePoint at = loop.now();
    bool went = false, back = false;           // the gateway saw the reboot, and configured the node again
    for (int step = 0; step < 2000; ++step) {  // 2 s, a monitor every millisecond
      rig.run_for(1ms);
      for (const auto& n : names) {
        if (n == rebooted) continue;
        ASSERT_EQ(down.state(n), subdevices::NodeState::Operational)
            << n << " left operational "
            << std::chrono::duration_cast<std::chrono::milliseconds>(loop.now() - at).count() << " ms after "
            << rebooted << " rebooted";
      }
      const bool op = down.state(rebooted) == subdevices::NodeState::Operational;
      went = went || !op;
      back = back || (went && op);
    }
    EXPECT_TRUE(went) << "the gateway did not notice " << rebooted << "'s reboot";
    EXPECT_TRUE(back) << rebooted << " was not operational again within 2 s";
    ASSERT_EQ(down.state(rebooted), subdevices::NodeState::Operational) << rebooted;
  }
}

INSTANTIATE_TEST_SUITE_P(DeviceLatency, TimedFullSet,
                         ::testing::Values(subdevices::sim::kTypicalSdoLatency, Duration{250}, Duration{0}),
                         [](const ::testing::TestParamInfo<Duration>& p) {
                           return p.param == Duration{0} ? std::string("AtOnce")
                                                         : "After" + std::to_string(p.param.count()) + "us";
                         });

}  // namespace
