// The requirement "every deadline acts in bounded time, whichever path notices it": the host's
// heartbeat stops while the downstream bus carries a frame load; how late do the outputs take
// their CiA 401 error values (6206h/6207h) after the consumer deadline?
//
// The gateway (one elobau grip on joystick.1, an MCB-402 whose LEDs are indicators.1) is booted
// by gateway_rig.hpp, then cut from the buses and driven here as an event loop would drive it on
// a loaded host, on a simulated clock: downstream grip PDOs every `period` (the argument, in µs:
// 1000 = 1,000 frames/s, 125 = 8,000 frames/s, about a full 1 Mbit/s bus, 20 = 50,000 frames/s),
// the host heartbeat (701h) and the sub-devices' heartbeats every 100 ms (the host's stops), and the gateway's own
// timer served only every `timer_late` (5 ms: a loop busy with frames that reaches its timers late). Per episode:
//  * lag_us: the error-value RPDO (203h) queued − the consumer deadline (last heartbeat + 250 ms);
//  * frames_after: downstream frames handled after the deadline before that RPDO (0: the first
//    frame after the deadline noticed it, as it must: the frame path that notices the time-out
//    applies the error values itself, it does not leave them to the next timer wake-up).
// Figures only; nothing asserts on time.
#include "tests/bench/bench_support.hpp"
#include "tests/bench/gateway_rig.hpp"

#include <algorithm>
#include <optional>
#include <stdexcept>

namespace {

using namespace oegw;
using canopen::CanFrame;
using canopen::TimePoint;

// An elobau grip on joystick.1, an MCB-402's outputs on indicators.1 (tests/fixtures).
std::string yaml() { return fixtures::mapping_file("grip_and_leds.yaml"); }

// An expedited SDO download to the gateway (node 20h), as the host would send it.
CanFrame sdo_download(std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t size) {
  const auto cs = static_cast<std::uint8_t>(0x23 | ((4 - size) << 2));
  return CanFrame(0x620, {cs, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub,
                          static_cast<std::uint8_t>(value), static_cast<std::uint8_t>(value >> 8),
                          static_cast<std::uint8_t>(value >> 16), static_cast<std::uint8_t>(value >> 24)});
}

void BM_HostHeartbeatLossUnderLoad(benchmark::State& state) {
  const auto period = std::chrono::microseconds(state.range(0));
  constexpr auto kTimerLate = std::chrono::milliseconds(5);
  constexpr auto kConsumer = std::chrono::milliseconds(250);
  bench::GatewayRig rig(bench::load_or_throw(yaml(), "deadline.yaml"));
  rig.build_gateway();
  rig.build_rest();
  rig.boot();
  rig.detach();
  auto& gw = rig.gw();
  TimePoint now = rig.now();
  std::optional<TimePoint> rpdo_at;
  std::uint64_t frames = 0, frames_at_rpdo = 0;
  rig.on_downstream_detached = [&](const CanFrame& f) {
    if (f.id == 0x203 && f.dlc == 1 && f.data[0] == 0x00 && !rpdo_at) {
      rpdo_at = now;
      frames_at_rpdo = frames;
    }
  };
  // The host watches nothing of ours; the gateway consumes the host's heartbeat: 1016h:01.
  (void)gw.on_upstream_frame(sdo_download(0x1016, 1, (1u << 16) | kConsumer.count(), 4), now);
  std::vector<std::int64_t> lag_ns;
  std::uint64_t worst_after = 0;
  std::int8_t x = 10;
  for (auto _ : state) {
    // Outputs on (indicator 1: error mode 01h, error value 0), the host alive, operational.
    (void)gw.on_downstream_frame(CanFrame(0x711, {0x05}), now);
    (void)gw.on_downstream_frame(CanFrame(0x703, {0x05}), now);
    (void)gw.on_upstream_frame(CanFrame(0x000, {0x01, 0x20}), now);
    (void)gw.command_indicators(1, 0x01, now, mapping::CommandSource::Canopen);
    rpdo_at.reset();
    TimePoint last_hb = now;
    (void)gw.on_upstream_frame(CanFrame(0x701, {0x05}), now);
    const TimePoint stop = now + std::chrono::milliseconds(300);
    // Frames out of phase with the heartbeats (7 µs + a third of a period), as on a real bus.
    TimePoint next_frame = now + std::chrono::microseconds(7) + period / 3,
              next_hb = now + std::chrono::milliseconds(100),
              next_timer = now + kTimerLate / 2 + std::chrono::microseconds(11);
    std::uint64_t frames_at_deadline = 0;
    bool past_deadline = false;
    while (!rpdo_at) {
      now = std::min({next_frame, next_hb, next_timer});
      if (!past_deadline && now >= last_hb + kConsumer) {
        past_deadline = true;
        frames_at_deadline = frames;
      }
      if (now == next_frame) {
        x = static_cast<std::int8_t>(x == 10 ? 20 : 10);
        (void)gw.on_downstream_frame(CanFrame(0x191, {static_cast<std::uint8_t>(x), 0, 0, 0, 0, 0, 0, 0xFF}), now);
        ++frames;
        next_frame += period;
      } else if (now == next_hb) {
        // The sub-devices stay alive (their heartbeats; the simulators are cut off)...
        (void)gw.on_downstream_frame(CanFrame(0x711, {0x05}), now);
        (void)gw.on_downstream_frame(CanFrame(0x703, {0x05}), now);
        if (now < stop) {  // ...the host's stops
          (void)gw.on_upstream_frame(CanFrame(0x701, {0x05}), now);
          last_hb = now;
        }
        next_hb += std::chrono::milliseconds(100);
      } else {
        const auto due = gw.next_deadline();
        if (due && *due <= now) gw.advance(now);
        next_timer += kTimerLate;
      }
      if (now > last_hb + std::chrono::seconds(2)) {
        state.SkipWithError("the error values never reached the MCB-402");
        return;
      }
    }
    lag_ns.push_back(std::chrono::duration_cast<std::chrono::nanoseconds>(*rpdo_at - (last_hb + kConsumer)).count());
    worst_after =
        std::max(worst_after, frames_at_rpdo - frames_at_deadline - (frames_at_rpdo > frames_at_deadline ? 1 : 0));
    now += std::chrono::milliseconds(50);
  }
  std::sort(lag_ns.begin(), lag_ns.end());
  state.counters["lag_us_p50"] = static_cast<double>(lag_ns[lag_ns.size() / 2]) / 1000.0;
  state.counters["lag_us_max"] = static_cast<double>(lag_ns.back()) / 1000.0;
  state.counters["frames_after_max"] = static_cast<double>(worst_after);
  state.counters["episodes"] = static_cast<double>(lag_ns.size());
}
BENCHMARK(BM_HostHeartbeatLossUnderLoad)->Arg(1000)->Arg(125)->Arg(20)->ArgName("frame_period_us")->Iterations(20);

}  // namespace
