// `oegw_bench_rss`: the resident memory of the gateway with the full FE set (16 joysticks,
// 16 pedals, 8 encoders, 8 wheels, 8 clusters; 48 sub-devices,
// tests/fixtures/full_fe_set.yaml). Not a Google Benchmark: it prints figures and fails (exit 1)
// only when the set cannot be brought up (a sub-device not operational, no TPDO at the host).
//
// The simulators run in this process too, so the figures are taken in phases:
//   baseline         the program before anything (libraries loaded, nothing built)
//   gateway_only     + mapping file loaded (EDS files parsed) + Gateway constructed; no
//                    simulator exists yet (the gateway is not started: starting it needs the bus)
//   with_simulators  + the 48 simulators and a host, the real boot and the host's configuration
//                    and 5 s of simulated running time (heartbeats, cyclic PDOs)
//   gateway_after    the simulators and the host destroyed again and malloc_trim(0): the gateway
//                    after a full boot, as near as one process allows (freed heap may stay mapped)
//   hwm              VmHWM, the peak over the whole run (includes the simulators); the kernel
//                    updates it lazily, so the largest VmRSS sampled above if that is higher
// Heap in use (mallinfo2 uordblks) is printed for the same phases.
#include <malloc.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <exception>
#include <fstream>
#include <string>

#include "tests/bench/gateway_rig.hpp"

namespace {

long status_kib(const char* key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::size_t n = std::strlen(key);
  while (std::getline(in, line))
    if (line.compare(0, n, key) == 0 && line.size() > n && line[n] == ':') return std::stol(line.substr(n + 1));
  return -1;
}
long heap_kib() { return static_cast<long>(mallinfo2().uordblks / 1024); }

}  // namespace

int main() {
  using namespace oegw;
  using namespace std::chrono_literals;
  try {
    const long base_rss = status_kib("VmRSS"), base_heap = heap_kib();
    const std::string yaml = bench::yaml_full_set();
    bench::GatewayRig rig(bench::load_or_throw(yaml, "full_set.yaml"));
    rig.build_gateway();
    const long gw_rss = status_kib("VmRSS"), gw_heap = heap_kib();

    rig.build_rest();
    rig.boot(5s);
    const long all_rss = status_kib("VmRSS"), all_heap = heap_kib();
    std::size_t operational = 0;
    for (const auto& n : rig.gw().downstream().names())
      operational += rig.gw().downstream().state(n) == subdevices::NodeState::Operational ? 1 : 0;

    // Heartbeat watch of the last node configured: silenced, the gateway must call it missing.
    (void)rig.command("cluster8 silent on");
    rig.run_for(1s);
    const auto last_state = rig.gw().downstream().state("cluster8");
    (void)rig.command("cluster8 silent off");

    rig.detach();
    rig.drop_simulators();
    malloc_trim(0);
    const long after_rss = status_kib("VmRSS"), after_heap = heap_kib();
    // VmHWM is the kernel's high-water mark, updated lazily: never below a VmRSS we saw.
    const long hwm = std::max({status_kib("VmHWM"), gw_rss, all_rss, after_rss});

    std::printf(
        "full FE set: %d joysticks, %d pedals, %d encoders, %d wheels, %d clusters on %d sub-devices "
        "(%zu operational), %zu FEs\n",
        bench::FullSetCounts::grips, bench::FullSetCounts::pedals, bench::FullSetCounts::encoders,
        bench::FullSetCounts::wheels, bench::FullSetCounts::clusters, bench::FullSetCounts::nodes, operational,
        rig.gw().fes().size());
    std::printf("heartbeat watch: cluster8 (node 57h, the 48th) silenced for 1 s -> %s\n",
                std::string(subdevices::to_string(last_state)).c_str());
    std::printf("measured: VmRSS/VmHWM of this process (/proc/self/status); the simulators share it, see the phases\n");
    std::printf("rss_kib baseline=%ld gateway_only=%ld with_simulators=%ld gateway_after_boot=%ld hwm=%ld\n", base_rss,
                gw_rss, all_rss, after_rss, hwm);
    std::printf("heap_kib baseline=%ld gateway_only=%ld with_simulators=%ld gateway_after_boot=%ld\n", base_heap,
                gw_heap, all_heap, after_heap);
    std::printf(
        "gateway share: rss %ld KiB over baseline before the simulators, %ld KiB after the boot; "
        "heap %ld KiB / %ld KiB\n",
        gw_rss - base_rss, after_rss - base_rss, gw_heap - base_heap, after_heap - base_heap);
    return operational == static_cast<std::size_t>(bench::FullSetCounts::nodes) ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "oegw_bench_rss: %s\n", e.what());
    return 1;
  }
}
