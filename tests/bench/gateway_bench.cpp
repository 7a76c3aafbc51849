// The gateway's hot path (targets: docs/developer/benchmarks.md): a downstream PDO received → the
// upstream TPDO queued. The Gateway is built from YAML text, booted for real against the
// simulators on a virtual bus under a simulated clock and configured by a host controller
// (gateway_rig.hpp); then it is cut from the buses and fed elobau TPDO #0 frames (181h-based,
// node 11h → 191h) with a changing x, each of which must produce TPDO 1 (1A0h, joystick.1).
//
//  * BM_Latency/<variant>: per frame, steady_clock before on_downstream_frame() → steady_clock
//    taken in the upstream FrameSink when TPDO 1 is queued. 20,000 samples after 2,000 warm-up
//    frames; p50/p90/p99/p99.9/max in ns ("clock_ns": the cost of one clock pair).
//  * BM_Throughput/<variant>: on_downstream_frame() on a stream of changing frames; items/s =
//    downstream frames translated per second, "tpdo/frame" must be 1.
//  * Both report "allocs/frame": heap allocations per frame on the hot path.
//  * BM_FrameAndDeadline/<variant>/cold:<0|1>: a frame and then next_deadline(), what `oegw run`
//    does per frame; cold:1 with the caches evicted before each (the eviction not timed).
// Variants: 0 = one grip feeding joystick.1; 1 = the full FE set (48 sub-devices, gateway_rss.cpp).
//  * BM_ThroughputPublishing: variant 0 with GatewayPublishing on (DDS loopback, LCM ttl=0): every
//    frame also builds the joystick sample from the FE model and publishes it on both transports;
//    "allocs/frame" then counts the whole input path including publishing (liblcm and Cyclone DDS
//    included).
//  * BM_StatusReport/<variant>: one `oegw status` answer built and serialised, the event loop's
//    work per status request between two bus frames; "bytes": the answer's size.
//  * BM_ReloadRead/<variant> and BM_ReloadHandOver/<variant>: a SIGHUP reload's two parts
//    (gateway/programs.cpp reload): what runs beside the buses in a thread of its own, and what
//    runs in the event loop.
// Figures only; nothing asserts on time.
#include "tests/bench/bench_support.hpp"
#include "tests/bench/gateway_rig.hpp"

#include "canopen/state.hpp"
#include "gateway/control/status_report.hpp"
#include "gateway/publishing.hpp"
#include "gateway/reload.hpp"
#include "mapping/deployment.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <vector>

namespace {

using namespace oegw;
using clock_type = std::chrono::steady_clock;

std::unique_ptr<bench::GatewayRig> make_rig(int variant) {
  const std::string yaml = variant == 0 ? bench::yaml_one_grip() : bench::yaml_full_set();
  auto rig =
      std::make_unique<bench::GatewayRig>(bench::load_or_throw(yaml, variant == 0 ? "one_grip.yaml" : "full_set.yaml"));
  rig->build_gateway();
  rig->build_rest();
  rig->boot();
  rig->detach();
  return rig;
}

// Elobau TPDO #0 of node 11h: X, Y, wheel A, B, C (S8 %), buttons 1..8, 9..16, FFh.
canopen::CanFrame grip_frame(std::int8_t x) {
  return canopen::CanFrame(0x191, {static_cast<std::uint8_t>(x), 0, 0, 0, 0, 0, 0, 0xFF});
}

// x alternates between two values outside the deadband: every frame changes joystick.1 x.
std::int8_t x_for(std::uint64_t i) { return (i & 1u) ? std::int8_t{40} : std::int8_t{-40}; }

void check_one_tpdo(bench::GatewayRig& rig, std::uint64_t before, const char* where) {
  if (rig.upstream().frames != before + 1 || rig.upstream().last.id != 0x1A0)
    throw std::runtime_error(std::string(where) + ": a changed grip frame did not queue exactly one TPDO 1 (1A0h)");
}

void BM_Latency(benchmark::State& state) {
  auto rig = make_rig(static_cast<int>(state.range(0)));
  auto& gw = rig->gw();
  auto& up = rig->upstream();
  const auto now = rig->now();
  constexpr std::size_t kWarmup = 2'000, kSamples = 20'000;
  std::vector<std::int64_t> ns(kSamples);
  std::vector<canopen::CanFrame> frames;
  frames.reserve(kWarmup + kSamples);
  for (std::size_t i = 0; i < kWarmup + kSamples; ++i) frames.push_back(grip_frame(x_for(i)));
  std::uint64_t allocs = 0;
  for (auto _ : state) {
    for (std::size_t i = 0; i < kWarmup; ++i) (void)gw.on_downstream_frame(frames[i], now);
    const auto a0 = bench::g_allocations;
    for (std::size_t i = 0; i < kSamples; ++i) {
      const auto before = up.frames;
      const auto t0 = clock_type::now();
      (void)gw.on_downstream_frame(frames[kWarmup + i], now);
      ns[i] = std::chrono::duration_cast<std::chrono::nanoseconds>(up.at - t0).count();
      if (up.frames != before + 1) {
        state.SkipWithError("a frame did not queue exactly one upstream TPDO");
        return;
      }
    }
    allocs = bench::g_allocations - a0;
    state.SetIterationTime(bench::report_samples(state, ns));
  }
  if (up.last.id != 0x1A0) state.SkipWithError("the upstream frame is not TPDO 1 (1A0h)");
  state.counters["clock_ns"] = bench::clock_pair_ns(kSamples);
  state.counters["allocs/frame"] = static_cast<double>(allocs) / static_cast<double>(kSamples);
  state.counters["downstream_sent"] = static_cast<double>(rig->downstream_while_detached());
}
BENCHMARK(BM_Latency)
    ->Arg(0)
    ->Arg(1)
    ->ArgName("full_set")
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond);

// The measured loop: the two frames alternately into the gateway, heap allocations counted.
void feed_frames(benchmark::State& state, gateway::Gateway& gw, const canopen::CanFrame (&frames)[2],
                 canopen::TimePoint now) {
  std::uint64_t i = 0;
  bench::AllocCounter allocs;
  for (auto _ : state) {
    benchmark::DoNotOptimize(gw.on_downstream_frame(frames[i & 1u], now));
    ++i;
  }
  allocs.report(state);
  state.counters["allocs/frame"] = state.counters["allocs/iter"];
  state.counters.erase("allocs/iter");
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}

void BM_Throughput(benchmark::State& state) {
  auto rig = make_rig(static_cast<int>(state.range(0)));
  auto& gw = rig->gw();
  auto& up = rig->upstream();
  const auto now = rig->now();
  const canopen::CanFrame frames[2] = {grip_frame(x_for(0)), grip_frame(x_for(1))};
  {
    const auto before = up.frames;
    (void)gw.on_downstream_frame(frames[0], now);
    (void)gw.on_downstream_frame(frames[1], now);
    check_one_tpdo(*rig, before + 1, "throughput warm-up");
  }
  const auto up0 = up.frames;
  feed_frames(state, gw, frames, now);
  state.counters["frames/s"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["tpdo/frame"] =
      state.iterations() == 0 ? 0.0 : static_cast<double>(up.frames - up0) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_Throughput)->Arg(0)->Arg(1)->ArgName("full_set");

// What `oegw run` does per frame (gateway/programs.cpp Daemon::take_frames): the frame, then the
// gateway's next deadline for the loop's timer. cold:1 evicts the caches between frames (a
// 4 MiB buffer written over, not timed), as a gateway woken from its wait finds them after the
// other threads and the kernel ran: the work's memory footprint, not only its instructions.
void BM_FrameAndDeadline(benchmark::State& state) {
  auto rig = make_rig(static_cast<int>(state.range(0)));
  const bool cold = state.range(1) != 0;
  auto& gw = rig->gw();
  const auto now = rig->now();
  const canopen::CanFrame frames[2] = {grip_frame(x_for(0)), grip_frame(x_for(1))};
  std::vector<std::uint8_t> evict(cold ? 4u << 20 : 0u);
  std::uint64_t i = 0;
  std::uint8_t fill = 0;
  for (auto _ : state) {
    if (cold) {
      state.PauseTiming();
      std::fill(evict.begin(), evict.end(), ++fill);
      benchmark::ClobberMemory();
      state.ResumeTiming();
    }
    benchmark::DoNotOptimize(gw.on_downstream_frame(frames[i & 1u], now));
    benchmark::DoNotOptimize(gw.next_deadline());
    ++i;
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}
BENCHMARK(BM_FrameAndDeadline)->ArgsProduct({{0, 1}, {0}})->ArgNames({"full_set", "cold"});
// Cold: a fixed number of frames, the untimed eviction would otherwise run for seconds.
BENCHMARK(BM_FrameAndDeadline)->ArgsProduct({{0, 1}, {1}})->ArgNames({"full_set", "cold"})->Iterations(5000);

void BM_ThroughputPublishing(benchmark::State& state) {
  const std::string yaml = bench::yaml_one_grip() +
                           "publish:\n"
                           "  period_ms: 1000\n"
                           "  lcm: { url: \"udpm://224.0.0.1:7667?ttl=0\", channel_prefix: OEGW_BENCH_ }\n"
                           "  dds: { domain: 0, partition: oegw-bench, network: loopback }\n";
  const mapping::Config cfg = bench::load_or_throw(yaml, "one_grip_publishing.yaml");
  bench::GatewayRig rig(cfg);
  rig.build_gateway();
  rig.build_rest();
  rig.boot();
  rig.detach();
  auto& gw = rig.gw();
  const auto now = rig.now();
  gateway::GatewayPublishing pub(gw, cfg.publish, [now] { return now; });
  const canopen::CanFrame frames[2] = {grip_frame(x_for(0)), grip_frame(x_for(1))};
  for (int w = 0; w < 100; ++w) (void)gw.on_downstream_frame(frames[w & 1], now);  // first samples, DDS matching
  const auto published0 = pub.published();
  feed_frames(state, gw, frames, now);
  state.counters["samples/frame"] = state.iterations() == 0 ? 0.0
                                                            : static_cast<double>(pub.published() - published0) /
                                                                  static_cast<double>(state.iterations());
}
BENCHMARK(BM_ThroughputPublishing);

// `oegw status`'s answer (gateway/control/status_report.hpp), built and serialised as the control
// socket sends it: the event loop does this work between two bus frames, once per status request
// (docs/reference/limits.md#can-first-what-the-event-loop-does-beside-the-buses). Variants as above.
void BM_StatusReport(benchmark::State& state) {
  const int variant = static_cast<int>(state.range(0));
  const mapping::Config cfg = bench::load_or_throw(variant == 0 ? bench::yaml_one_grip() : bench::yaml_full_set(),
                                                   variant == 0 ? "one_grip.yaml" : "full_set.yaml");
  auto rig = make_rig(variant);
  const gateway::control::StatusContext at{rig->now(), {}};
  std::size_t bytes = 0;
  for (auto _ : state) {
    const std::string text = gateway::control::status_report(rig->gw(), cfg, at).dump();
    bytes = text.size();
    benchmark::DoNotOptimize(text.data());
  }
  state.counters["bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_StatusReport)->Arg(0)->Arg(1)->ArgName("full_set")->Unit(benchmark::kMicrosecond);

// The gateway's run-time state as the black box takes it at the head of each segment
// (record::StateGiver: Gateway::export_state on the loop, between two bus frames, once a segment)
// and the text the recorder's writer then puts on one line. Variants as above.
void BM_ExportState(benchmark::State& state) {
  auto rig = make_rig(static_cast<int>(state.range(0)));
  if (!rig->gw().busy().empty()) throw std::runtime_error("the bench's gateway is busy: " + rig->gw().busy());
  std::size_t bytes = 0;
  for (auto _ : state) {
    canopen::StateWriter w;
    rig->gw().export_state(w);
    bytes = w.text().size();
    benchmark::DoNotOptimize(w.text().data());
  }
  state.counters["bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_ExportState)->Arg(0)->Arg(1)->ArgName("full_set")->Unit(benchmark::kMicrosecond);

const char* variant_name(int variant) { return variant == 0 ? "one_grip.yaml" : "full_set.yaml"; }
const std::string& variant_yaml(int variant) {
  static const std::string grip = bench::yaml_one_grip();
  static const std::string full = bench::yaml_full_set();
  return variant == 0 ? grip : full;
}

// A reload's reading beside the buses: the file parsed and checked as `oegw run` takes it (the
// loader's and the cab settings' checks; from memory here, no disk) and the drivers it names built
// once (build_reload_drivers).
void BM_ReloadRead(benchmark::State& state) {
  const int variant = static_cast<int>(state.range(0));
  for (auto _ : state) {
    auto r = mapping::load_config_text(variant_yaml(variant), variant_name(variant), gateway::driver_catalogue());
    if (!r.ok()) throw std::runtime_error(r.error_text());
    const auto errors = mapping::deployment_errors(*r.config);
    const auto built = gateway::build_reload_drivers(*r.config);
    benchmark::DoNotOptimize(errors.size() + built.drivers.size());
  }
}
BENCHMARK(BM_ReloadRead)->Arg(0)->Arg(1)->ArgName("full_set")->Unit(benchmark::kMillisecond);

// A reload's part in the event loop: the new file compared with the running one (reload_refusals)
// and the gateway handed over (reload_gateway: the old one's outputs at their error values, a new
// one built around the same upstream device with the drivers built beforehand, and resumed). Each
// iteration hands the last one over.
void BM_ReloadHandOver(benchmark::State& state) {
  const int variant = static_cast<int>(state.range(0));
  const std::filesystem::path store =
      std::filesystem::temp_directory_path() / ("oegw-bench-reload-" + std::to_string(::getpid()) + ".store");
  mapping::Config cfg = bench::load_or_throw(variant_yaml(variant), variant_name(variant));
  cfg.upstream.store = store.string();
  const mapping::Config next = cfg;
  const canopen::FrameSink nowhere = [](const canopen::CanFrame&) {};
  auto gw = std::make_unique<gateway::Gateway>(cfg, nowhere, nowhere);
  canopen::TimePoint now{};
  (void)gw->start(now);
  for (auto _ : state) {
    state.PauseTiming();  // the drivers are built beside the buses, with the file's reading
    gateway::ReloadDrivers built = gateway::build_reload_drivers(next);
    state.ResumeTiming();
    now += std::chrono::milliseconds(100);
    if (!gateway::reload_refusals(cfg, next).empty()) throw std::runtime_error("the same file refused");
    gw = gateway::reload_gateway(std::move(gw), next, nowhere, {}, now, std::move(built.drivers));
  }
  gw.reset();
  std::filesystem::remove(store);
}
BENCHMARK(BM_ReloadHandOver)->Arg(0)->Arg(1)->ArgName("full_set")->Unit(benchmark::kMillisecond);

}  // namespace
