// Shared by the *_bench.cpp executables (each is its own program: include this from exactly one
// translation unit per executable, since it replaces the global operator new).
//
//  * Allocation counting: every benchmark reports "allocs/iter", the heap allocations made inside
//    its timed loop divided by the iterations, so that a per-frame allocation shows up as >= 1.
//  * Percentiles: sample a callable N times with steady_clock and report p50/p90/p99/p99.9/max
//    (ns) as counters, together with the cost of the clock reads themselves ("clock_ns").
#pragma once

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <new>
#include <vector>

namespace oegw::bench {
// Single-threaded benchmarks: a plain counter is enough (and costs nothing measurable).
inline std::uint64_t g_allocations = 0;
}  // namespace oegw::bench

// Replacement allocation functions ([replacement.functions]; must not be inline). The array and
// nothrow forms of libstdc++ forward to these. Not inlined: GCC would otherwise see free() applied
// to the result of operator new and warn (-Wmismatched-new-delete) about the pair it inlined.
[[gnu::noinline]] void* operator new(std::size_t n) {
  ++oegw::bench::g_allocations;
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
[[gnu::noinline]] void operator delete(void* p) noexcept { std::free(p); }
[[gnu::noinline]] void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace oegw::bench {

// Counts the allocations between construction and report(); report() sets "allocs/iter".
class AllocCounter {
 public:
  AllocCounter() : start_(g_allocations) {}
  void report(benchmark::State& state) const {
    const auto n = static_cast<double>(g_allocations - start_);
    state.counters["allocs/iter"] =
        benchmark::Counter(state.iterations() == 0 ? 0.0 : n / static_cast<double>(state.iterations()));
  }

 private:
  std::uint64_t start_;
};

// Reports a distribution of samples in ns (sorted in place) as p50/p90/p99/p99.9/max counters
// and "samples". Returns the mean in seconds, for State::SetIterationTime.
inline double report_samples(benchmark::State& state, std::vector<std::int64_t>& ns) {
  const std::size_t samples = ns.size();
  if (samples == 0) return 0.0;
  std::sort(ns.begin(), ns.end());
  auto pct = [&](double p) {
    const auto idx = static_cast<std::size_t>(p * static_cast<double>(samples - 1) + 0.5);
    return static_cast<double>(ns[std::min(idx, samples - 1)]);
  };
  state.counters["p50_ns"] = pct(0.50);
  state.counters["p90_ns"] = pct(0.90);
  state.counters["p99_ns"] = pct(0.99);
  state.counters["p99.9_ns"] = pct(0.999);
  state.counters["max_ns"] = static_cast<double>(ns.back());
  state.counters["samples"] = static_cast<double>(samples);
  double sum = 0;
  for (const auto v : ns) sum += static_cast<double>(v);
  return sum / static_cast<double>(samples) * 1e-9;
}

// The cost of two consecutive steady_clock reads (median of `samples`), in ns.
inline double clock_pair_ns(std::size_t samples) {
  using clock = std::chrono::steady_clock;
  std::vector<std::int64_t> overhead(samples);
  for (std::size_t i = 0; i < samples; ++i) {
    const auto a = clock::now();
    const auto b = clock::now();
    overhead[i] = std::chrono::duration_cast<std::chrono::nanoseconds>(b - a).count();
  }
  std::sort(overhead.begin(), overhead.end());
  return static_cast<double>(overhead[samples / 2]);
}

// Runs `op` `samples` times (after as many untimed warm-up calls), timing each call, and reports
// the distribution in ns. Returns the mean in seconds, for State::SetIterationTime: a percentile
// benchmark runs with Iterations(1) and UseManualTime(), so that its Time column is the mean.
template <class Op>
double report_percentiles(benchmark::State& state, std::size_t samples, Op&& op) {
  using clock = std::chrono::steady_clock;
  for (std::size_t i = 0; i < samples; ++i) op();
  std::vector<std::int64_t> ns(samples);
  const double overhead = clock_pair_ns(samples);
  for (std::size_t i = 0; i < samples; ++i) {
    const auto a = clock::now();
    op();
    const auto b = clock::now();
    ns[i] = std::chrono::duration_cast<std::chrono::nanoseconds>(b - a).count();
  }
  state.counters["clock_ns"] = overhead;
  return report_samples(state, ns);
}

}  // namespace oegw::bench
