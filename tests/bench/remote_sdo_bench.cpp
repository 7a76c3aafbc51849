// Remote SDO through the gateway (the target: p99 under 20 µs): what the gateway adds to a
// remote expedited upload. The gateway of gateway_rig.hpp (one elobau grip, node 11h) is booted
// for real, the host names the grip with an SDO network indication on the default channel
// (620h), then the gateway is cut from the buses and fed, per sample:
//   1. the host's initiate upload of 1018h:01 (620h 40 18 10 01 ...) → steady_clock taken in the
//      downstream sink when the request to the grip (611h 40 18 10 01 ...) is queued;
//   2. the grip's answer (591h 43 18 10 01 <vendor-ID>) → steady_clock taken in the upstream sink
//      when the answer to the host (5A0h 43 18 10 01 <vendor-ID>) is queued.
// A sample is the sum of both halves: the gateway's processing, no bus time. 20,000 samples
// after 2,000 warm-up transfers; p50/p90/p99/p99.9/max in ns, "allocs/transfer" heap allocations
// per transfer. Figures only; nothing asserts on time.
#include "tests/bench/bench_support.hpp"
#include "tests/bench/gateway_rig.hpp"

#include <chrono>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <vector>

namespace {

using namespace oegw;
using clock_type = std::chrono::steady_clock;

constexpr std::uint32_t kHostRequest = 0x620;  // 600h + the gateway's node-ID 20h
constexpr std::uint32_t kGripRequest = 0x611;  // 600h + the grip's node-ID 11h
constexpr std::uint32_t kGripAnswer = 0x591;   // 580h + 11h

void BM_RemoteExpeditedUpload(benchmark::State& state) {
  bench::GatewayRig rig(bench::load_or_throw(bench::yaml_one_grip(), "one_grip.yaml"));
  rig.build_gateway();
  rig.build_rest();
  rig.boot();
  auto& gw = rig.gw();
  auto& up = rig.upstream();
  clock_type::time_point down_at{};
  std::uint64_t down_frames = 0;
  canopen::CanFrame down_last{};
  rig.on_downstream_detached = [&](const canopen::CanFrame& f) {
    down_at = clock_type::now();
    ++down_frames;
    down_last = f;
  };
  rig.detach();
  const auto now = rig.now();
  constexpr std::uint8_t network = 2;  // downstream.network_id (one_grip.yaml: the default)
  (void)gw.on_upstream_frame(canopen::CanFrame(kHostRequest, {0xE0, 0, 0, 0, network, 0x11, 0, 0}), now);
  if (up.last.data[0] != 0xE0) {
    state.SkipWithError("the network indication was not accepted");
    return;
  }
  const canopen::CanFrame request(kHostRequest, {0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0});
  const canopen::CanFrame answer(kGripAnswer, {0x43, 0x18, 0x10, 0x01, 0x5A, 0x01, 0x00, 0x00});
  constexpr std::size_t kWarmup = 2'000, kSamples = 20'000;
  std::vector<std::int64_t> ns(kSamples);
  std::uint64_t allocs = 0;
  auto one = [&](std::size_t i, bool sample) {
    const auto d0 = down_frames;
    const auto u0 = up.frames;
    const auto t0 = clock_type::now();
    (void)gw.on_upstream_frame(request, now);
    if (down_frames != d0 + 1 || down_last.id != kGripRequest) throw std::runtime_error("no request to the grip");
    const auto t2 = clock_type::now();
    (void)gw.on_downstream_frame(answer, now);
    if (up.frames != u0 + 1 || up.last.data[0] != 0x43) throw std::runtime_error("no answer to the host");
    if (sample) ns[i] = std::chrono::duration_cast<std::chrono::nanoseconds>((down_at - t0) + (up.at - t2)).count();
  };
  for (auto _ : state) {
    try {
      for (std::size_t i = 0; i < kWarmup; ++i) one(i, false);
      const auto a0 = bench::g_allocations;
      for (std::size_t i = 0; i < kSamples; ++i) one(i, true);
      allocs = bench::g_allocations - a0;
    } catch (const std::exception& e) {
      state.SkipWithError(e.what());
      return;
    }
    state.SetIterationTime(bench::report_samples(state, ns));
  }
  state.counters["clock_ns"] = bench::clock_pair_ns(kSamples);
  state.counters["allocs/transfer"] = static_cast<double>(allocs) / static_cast<double>(kSamples);
}
BENCHMARK(BM_RemoteExpeditedUpload)->Iterations(1)->UseManualTime()->Unit(benchmark::kMicrosecond);

}  // namespace
