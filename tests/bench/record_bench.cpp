// The black box's costs (docs/guides/black-box.md, figures in docs/developer/performance.md):
//  * BM_RecordingCpu: CPU per translated frame at 8,000 frames/s (a 1 Mbit/s bus at its most),
//    recording off and on: the process's CPU time (every thread: the writer's too, getrusage)
//    over the frames fed, paced in bursts of 8 each millisecond, as the event loop sees a busy
//    bus. Each frame moves joystick.1's x: a TPDO and an FE line per frame.
//  * BM_RecordingThroughput: the same unpaced (how far recording lowers the ceiling).
//  * BM_RecordingStalledDisk: the writer held in write(2) (a stalled disk) while 200,000 frames
//    come: the queue stays at its bound, the rest is dropped and counted; resident memory grows
//    by at most the bound.
//  * BM_ReplayFullCab10Min: 10 minutes of the full FE set (tests/fixtures/full_fe_set.yaml, 48
//    sub-devices moving) recorded on the timed virtual buses, then replayed exactly: wall time.
// Figures only: nothing here is asserted against time.
#include <benchmark/benchmark.h>
#include <sys/resource.h>
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <fstream>
#include <mutex>
#include <thread>

#include "gateway/record/gateway_recorder.hpp"
#include "gateway/record/recorder.hpp"
#include "gateway/record/replay.hpp"
#include "tests/bench/gateway_rig.hpp"
#include "tests/fixtures/temp_dir.hpp"

namespace oegw {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
using gateway::record::GatewayRecorder;
using gateway::record::Recorder;
using gateway::record::RecorderSettings;

struct TempDir : fixtures::TempDir {
  TempDir() : fixtures::TempDir("oegw-record-bench") {}
};

double cpu_seconds() {
  rusage u{};
  ::getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + (u.ru_utime.tv_usec + u.ru_stime.tv_usec) / 1e6;
}

long rss_kb() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::strtol(line.c_str() + 6, nullptr, 10);
  return 0;
}

// The grip's TPDO #0 (181h + 10h) with x at `percent`.
canopen::CanFrame grip_frame(int percent) {
  return canopen::CanFrame(0x191, {static_cast<std::uint8_t>(percent), 0, 0, 0, 0, 0, 0, 0});
}

// One grip booted with the host's set-up, then detached: the benchmark feeds its frames.
struct Rigged {
  std::unique_ptr<bench::GatewayRig> rig;
  TempDir dir;
  std::unique_ptr<Recorder> recorder;
  std::unique_ptr<GatewayRecorder> tap;
  explicit Rigged(bool recording, const std::function<void(RecorderSettings&)>& adjust = {}) {
    rig = std::make_unique<bench::GatewayRig>(bench::load_or_throw(bench::yaml_one_grip(), "one_grip.yaml"));
    rig->build_gateway();
    rig->build_rest();
    rig->boot();
    rig->detach();
    if (!recording) return;
    RecorderSettings s;
    s.dir = dir.path;
    if (adjust) adjust(s);
    recorder = std::make_unique<Recorder>(s);
    tap = std::make_unique<GatewayRecorder>(*recorder);
    rig->gw().set_tap(tap.get());
  }
  ~Rigged() {
    rig->gw().set_tap(nullptr);
    tap.reset();
    recorder.reset();
  }
};

void BM_RecordingCpu(benchmark::State& state) {
  Rigged r(state.range(0) != 0);
  auto& gw = r.rig->gw();
  canopen::TimePoint t = r.rig->now();
  std::uint64_t frames = 0;
  double cpu = 0;
  for (auto _ : state) {
    // 100 ms of a full 1 Mbit/s bus: 800 frames, 8 each millisecond.
    const double c0 = cpu_seconds();
    auto next = std::chrono::steady_clock::now();
    for (int ms = 0; ms < 100; ++ms) {
      for (int k = 0; k < 8; ++k) {
        t += 125us;
        benchmark::DoNotOptimize(gw.on_downstream_frame(grip_frame(static_cast<int>(frames++ % 100)), t));
      }
      next += 1ms;
      std::this_thread::sleep_until(next);
    }
    cpu += cpu_seconds() - c0;
  }
  if (r.recorder) r.recorder->flush();
  state.counters["cpu_us/frame"] = cpu * 1e6 / static_cast<double>(frames);
  state.counters["frames/s"] = 8000;
  if (r.recorder) {
    const auto st = r.recorder->status();
    state.counters["recorded"] = static_cast<double>(st.frames);
    state.counters["dropped"] = static_cast<double>(st.dropped_frames + st.dropped_events);
  }
}
BENCHMARK(BM_RecordingCpu)
    ->ArgName("recording")
    ->Arg(0)
    ->Arg(1)
    ->Iterations(30)
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

void BM_RecordingThroughput(benchmark::State& state) {
  Rigged r(state.range(0) != 0);
  auto& gw = r.rig->gw();
  canopen::TimePoint t = r.rig->now();
  std::uint64_t frames = 0;
  for (auto _ : state) {
    t += 20us;
    benchmark::DoNotOptimize(gw.on_downstream_frame(grip_frame(static_cast<int>(frames++ % 100)), t));
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(frames));
  if (r.recorder) {
    r.recorder->flush();
    const auto st = r.recorder->status();
    state.counters["dropped"] = static_cast<double>(st.dropped_frames + st.dropped_events);
  }
}
BENCHMARK(BM_RecordingThroughput)->ArgName("recording")->Arg(0)->Arg(1)->MeasureProcessCPUTime();

void BM_RecordingStalledDisk(benchmark::State& state) {
  std::mutex m;
  std::condition_variable cv;
  bool release = false;
  Rigged r(true, [&](RecorderSettings& s) {
    s.write_fn = [&](int fd, const void* p, std::size_t n) -> ssize_t {
      std::unique_lock lk(m);
      cv.wait(lk, [&] { return release; });
      return ::write(fd, p, n);
    };
  });
  auto& gw = r.rig->gw();
  canopen::TimePoint t = r.rig->now();
  const long before = rss_kb();
  std::size_t most_queued = 0;
  std::uint64_t frames = 0;
  for (auto _ : state) {
    for (int i = 0; i < 200000; ++i) {
      t += 125us;
      benchmark::DoNotOptimize(gw.on_downstream_frame(grip_frame(static_cast<int>(frames++ % 100)), t));
      if (i % 1000 == 0) most_queued = std::max(most_queued, r.recorder->status().queued_bytes);
    }
  }
  const long after = rss_kb();
  const auto st = r.recorder->status();
  {
    std::lock_guard lk(m);
    release = true;
  }
  cv.notify_all();
  r.recorder->flush();
  state.counters["frames"] = static_cast<double>(frames);
  state.counters["dropped"] = static_cast<double>(st.dropped_frames + st.dropped_events);
  state.counters["queue_max_kB"] = static_cast<double>(most_queued) / 1024;
  state.counters["queue_bound_kB"] = static_cast<double>(r.recorder->settings().queue_bytes) / 1024;
  state.counters["rss_growth_kB"] = static_cast<double>(after - before);
}
BENCHMARK(BM_RecordingStalledDisk)->Iterations(1)->Unit(benchmark::kMillisecond);

void BM_ReplayFullCab10Min(benchmark::State& state) {
  const mapping::Config cfg = bench::load_or_throw(bench::yaml_full_set(), "full_fe_set.yaml");
  TempDir dir;
  std::uint64_t recorded = 0;
  {
    canopen::io::SimulatedClock clock;
    canopen::io::EventLoop loop(clock);
    RecorderSettings s;
    s.dir = dir.path;
    s.max_bytes = 4ull << 30;
    s.span = 24h;
    s.queue_bytes = 64u << 20;
    s.header = {"meta gateway sdo_bus_share=0.85"};
    Recorder recorder(s);
    GatewayRecorder tap(recorder);
    oegw::rig::CabRig rig(cfg, loop,
                          oegw::rig::CabRigOptions{.store = dir.path / "upstream.store", .timed_buses = true});
    rig.on_gateway = [&](gateway::Gateway& g) { g.set_tap(&tap); };
    rig.build();
    rig.power_on();
    rig.run_for(3s);
    rig.host().nmt().start(canopen::NodeId{0x20});
    for (auto end = loop.now() + 600s; loop.now() < end;) {
      rig.devices().move(loop.now());
      rig.run_for(20ms);
    }
    rig.gw().set_tap(nullptr);
    recorder.flush();
    recorded = recorder.status().frames;
    state.counters["dropped"] = static_cast<double>(recorder.status().dropped_frames);
  }
  std::string error;
  const auto runs = gateway::record::find_runs(dir.path, error);
  if (!runs) {
    state.SkipWithError(error.c_str());
    return;
  }
  std::uint64_t bytes = 0;
  for (const auto& e : fs::directory_iterator(dir.path))
    if (e.is_regular_file()) bytes += e.file_size();
  std::vector<gateway::record::RunReport> reports;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    reports = gateway::record::replay(*runs, cfg, {});
    state.SetIterationTime(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  const bool exact = reports.size() == 1 && reports[0].mode == gateway::record::ReplayMode::Exact &&
                     !reports[0].divergence && reports[0].stopped.empty();
  if (!exact) state.SkipWithError("the replay was not exact");
  state.counters["recorded_frames"] = static_cast<double>(recorded);
  state.counters["compared"] = reports.empty() ? 0 : static_cast<double>(reports[0].compared);
  state.counters["MiB"] = static_cast<double>(bytes) / (1 << 20);
}
BENCHMARK(BM_ReplayFullCab10Min)->Iterations(1)->UseManualTime()->Unit(benchmark::kSecond);

}  // namespace
}  // namespace oegw
