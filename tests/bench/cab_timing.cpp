// `oegw_bench_cab_timing`: the cab on the timed virtual bus (canopen/io/virtual_bus.hpp
// run_timed_on: every frame its real length at the bit rate, arbitration by CAN-ID, the
// simulators answering SDO after their device latency). Not a Google Benchmark: the figures
// are simulated time, printed, never asserted; it fails (exit 1) only when a cab does not boot.
//
//   boot   from power-on (gateway start, every simulator's power-on) to every sub-device
//          operational and the upstream device ready (its boot-up received by the host), at
//          250 kbit/s, for the demo cab (config/demo.yaml) and the full FE set (48 sub-devices,
//          tests/fixtures/full_fe_set.yaml, its encoders at 50 ms to fit 250 kbit/s; as it is at
//          1 Mbit/s too); next to the bound the bus and the devices allow,
//          computed from the boot conversation itself:
//            bus bound   every frame of the boot (NMT, boot-ups, SDO requests and answers, the
//                        proof-of-life heartbeats) back to back: one bus carries them all;
//            node bound  per node, its own frames back to back (a node's conversation is
//                        sequential), plus the device latency of each of its SDO answers, plus
//                        the time from the NMT start reaching it to its first heartbeat in
//                        operational being sent (the device's heartbeat phase: proof of life,
//                        which no master may skip); nodes in parallel: the largest;
//            bound = max(bus bound, node bound).
//          Once more for the demo cab with one sub-device's boot-ups lost: the boot-up probe
//          (subdevices/network_manager.hpp, step 1) instead of the 2 s boot-up wait.
//   load   the steady-state bus load `oegw check` predicts (gateway/bus_load.hpp: heartbeats and
//          SYNC at their exact length, PDOs at worst-case stuffing) next to what the timed bus measures over 10 s of
//          steady state after the boot (inputs held still), for both buses of both cabs at their files' bit rates.
//
// --sdo-latency-us N sets the simulators' SDO latency (default 1000, sim::kTypicalSdoLatency);
// --sdo-share S the share of the bus the gateway's SDO requests are paced to
// (GatewayOptions::sdo_bus_share, default 0.85; 0: not paced);
// --trace prints the gateway's log lines of each boot with their simulated times.
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "canopen/frame_bits.hpp"
#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "gateway/bus_load.hpp"
#include "rig/cab_rig.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "tests/bench/gateway_rig.hpp"
#include "tests/fixtures/fixtures.hpp"

namespace {

using namespace std::chrono_literals;
using oegw::canopen::CanFrame;
using oegw::canopen::Duration;
using oegw::canopen::TimePoint;

double ms(Duration d) { return static_cast<double>(d.count()) / 1000.0; }

bool g_trace = false;
double g_sdo_share = oegw::gateway::GatewayOptions::kDefaultSdoBusShare;

oegw::mapping::Config load_file(const std::string& path) {
  auto r = oegw::mapping::load_config(path, oegw::gateway::driver_catalogue());
  if (!r.ok()) throw std::runtime_error(path + ":\n" + r.error_text());
  return std::move(*r.config);
}

struct BootFigures {
  Duration boot{0}, upstream_ready{0}, all_operational{0};
  Duration bus_bound{0}, node_bound{0};
  std::string slowest_node;
  std::size_t frames = 0, sdo_round_trips = 0;
};

// Which node a downstream boot frame belongs to (0: every node, e.g. NMT to all), or nullopt
// for a frame that is not part of the boot conversation (PDOs, EMCY, SYNC).
std::optional<unsigned> boot_node(const CanFrame& f) {
  if (f.id == 0x000 && f.dlc == 2) return f.data[1];
  const unsigned fn = f.id & 0x780, node = f.id & 0x7F;
  if (fn == 0x580 || fn == 0x600 || fn == 0x700) return node;
  return std::nullopt;
}

// `lose_boot_ups_of`: that node's boot-ups never reach the bus (its power-on one and the one
// answering the gateway's reset), as when a device's boot-up is lost.
BootFigures boot(oegw::mapping::Config cfg, std::uint32_t bit_rate, Duration latency,
                 std::optional<unsigned> lose_boot_ups_of = std::nullopt) {
  cfg.upstream.bitrate = bit_rate;
  cfg.downstream.bitrate = bit_rate;
  oegw::canopen::io::SimulatedClock clock{TimePoint{std::chrono::seconds(1)}};
  oegw::canopen::io::EventLoop loop{clock};
  oegw::rig::CabRig rig(cfg, loop,
                        oegw::rig::CabRigOptions{.store = "/nonexistent-oegw-bench/upstream.store",
                                                 .gateway = {.sdo_bus_share = g_sdo_share},
                                                 .timed_buses = true,
                                                 .device_sdo_latency = latency});
  if (g_trace)
    rig.on_gateway = [&loop](oegw::gateway::Gateway& gw) {
      const TimePoint start = loop.now();
      gw.on_log = [&loop, start](const std::string& line) {
        std::printf("  %9.3f ms  %s\n", ms(loop.now() - start), line.c_str());
      };
    };
  rig.build();
  const TimePoint t0 = loop.now();
  struct Seen {
    TimePoint at;
    CanFrame frame;
  };
  std::vector<Seen> down;
  std::map<unsigned, TimePoint> started, proof_sent;  // NMT start received / first op heartbeat sent
  std::optional<TimePoint> upstream_ready;
  const std::uint32_t gw_boot = 0x700u + cfg.upstream.node_id;
  rig.down().set_tap([&](const oegw::canopen::io::BusRecord& r) {
    down.push_back({r.time, r.frame});
    if (r.frame.id == 0 && r.frame.dlc == 2 && r.frame.data[0] == 0x01) {
      for (const auto& s : cfg.subdevices)
        if (r.frame.data[1] == 0 || r.frame.data[1] == s.node_id) started[s.node_id] = r.time;
    }
  });
  rig.up().set_tap([&](const oegw::canopen::io::BusRecord& r) {
    if (!upstream_ready && r.frame.id == gw_boot && r.frame.dlc == 1 && r.frame.data[0] == 0) upstream_ready = r.time;
  });
  rig.from_devices = [&](const CanFrame& f) {
    const unsigned node = f.id & 0x7F;
    if ((f.id & 0x780) == 0x700 && f.dlc == 1 && f.data[0] == 0x05 && started.contains(node) &&
        !proof_sent.contains(node))
      proof_sent[node] = loop.now();
    return false;
  };
  if (lose_boot_ups_of)
    rig.down().drop_next(2, [id = 0x700u + *lose_boot_ups_of](const CanFrame& f) {
      return f.id == id && f.dlc == 1 && f.data[0] == 0x00;
    });
  rig.power_on();
  std::optional<TimePoint> all_op;
  for (int step = 0; step < 100'000 && !(all_op && upstream_ready); ++step) {  // 10 s at most
    rig.run_for(100us);
    if (!all_op) {
      bool all = true;
      for (const auto& n : rig.gw().downstream().names())
        all = all && rig.gw().downstream().state(n) == oegw::subdevices::NodeState::Operational;
      if (all) all_op = loop.now();
    }
  }
  rig.down().set_tap({});
  rig.up().set_tap({});
  rig.from_devices = {};
  if (!all_op || !upstream_ready) throw std::runtime_error("the cab did not boot within 10 s of simulated time");

  BootFigures b;
  b.all_operational = *all_op - t0;
  b.upstream_ready = *upstream_ready - t0;
  b.boot = std::max(b.all_operational, b.upstream_ready);
  // The boot conversation: the boot frames up to the last node's proof of life.
  std::map<unsigned, std::uint64_t> node_bits;
  std::map<unsigned, std::size_t> node_sdos;
  std::uint64_t bus_bits = 0;
  for (const auto& s : down) {
    if (s.at > *all_op) break;
    const auto node = boot_node(s.frame);
    if (!node) continue;
    const unsigned fn = s.frame.id & 0x780;
    // Heartbeats count up to the node's proof of life; later ones are not the boot's.
    if (fn == 0x700 && s.frame.data[0] == 0x05 && proof_sent.contains(*node) && s.at > proof_sent[*node] + 1ms)
      continue;
    const std::uint32_t bits = oegw::canopen::frame_bits(s.frame);
    ++b.frames;
    bus_bits += bits;
    if (*node == 0) {
      for (const auto& sd : cfg.subdevices) node_bits[sd.node_id] += bits;
    } else {
      node_bits[*node] += bits;
      if (fn == 0x580) ++node_sdos[*node];
    }
  }
  b.bus_bound = rig.down().bit_time(bus_bits);
  for (const auto& s : cfg.subdevices) {
    const unsigned n = s.node_id;
    b.sdo_round_trips += node_sdos[n];
    Duration d = rig.down().bit_time(node_bits[n]) + latency * static_cast<int>(node_sdos[n]);
    if (started.contains(n) && proof_sent.contains(n)) d += proof_sent[n] - started[n];
    if (d > b.node_bound) {
      b.node_bound = d;
      b.slowest_node = s.name;
    }
  }
  return b;
}

struct LoadFigures {
  oegw::gateway::BusLoadPrediction predicted;
  double measured_up = 0, measured_down = 0;  // % of the bit rate
};

LoadFigures load(const oegw::mapping::Config& cfg) {
  LoadFigures f;
  f.predicted = oegw::gateway::predict_bus_load(cfg);
  oegw::canopen::io::SimulatedClock clock{TimePoint{std::chrono::seconds(1)}};
  oegw::canopen::io::EventLoop loop{clock};
  oegw::rig::CabRig rig(cfg, loop,
                        oegw::rig::CabRigOptions{.store = "/nonexistent-oegw-bench/upstream.store",
                                                 .timed_buses = true});
  rig.build();
  rig.power_on();
  rig.run_for(5s);  // booted, and the boot's SDO traffic long over
  for (const auto& n : rig.gw().downstream().names())
    if (rig.gw().downstream().state(n) != oegw::subdevices::NodeState::Operational)
      throw std::runtime_error("sub-device " + n + " not operational");
  const auto up0 = rig.up().stats().busy, down0 = rig.down().stats().busy;
  const Duration window = 10s;
  rig.run_for(window);
  f.measured_up =
      100.0 * static_cast<double>((rig.up().stats().busy - up0).count()) / static_cast<double>(window.count());
  f.measured_down =
      100.0 * static_cast<double>((rig.down().stats().busy - down0).count()) / static_cast<double>(window.count());
  return f;
}

void print_boot(const char* name, const BootFigures& b, std::size_t nodes) {
  const Duration bound = std::max(b.bus_bound, b.node_bound);
  std::printf(
      "boot %-10s %2zu sub-devices: %8.1f ms (all operational %.1f ms, upstream ready %.1f ms); bound %.1f ms "
      "(bus %.1f ms: %zu frames, %zu SDO round trips; node %.1f ms: %s) -> %.2fx the bound\n",
      name, nodes, ms(b.boot), ms(b.all_operational), ms(b.upstream_ready), ms(bound), ms(b.bus_bound), b.frames,
      b.sdo_round_trips, ms(b.node_bound), b.slowest_node.c_str(), ms(b.boot) / ms(bound));
}

void print_load(const char* name, const oegw::mapping::Config& cfg, const LoadFigures& f) {
  const auto row = [name](const char* bus, std::uint32_t rate, double predicted, double measured) {
    std::printf(
        "load %-10s %-10s %7u bit/s: predicted %6.2f %% (PDOs at worst-case stuffing), measured %6.2f %% -> "
        "prediction %+.1f %% of the measured\n",
        name, bus, rate, predicted, measured, measured > 0 ? 100.0 * (predicted - measured) / measured : 0.0);
  };
  row("upstream", cfg.upstream.bitrate, f.predicted.upstream.percent(), f.measured_up);
  row("downstream", cfg.downstream.bitrate, f.predicted.downstream.percent(), f.measured_down);
}

}  // namespace

int main(int argc, char** argv) {
  Duration latency = oegw::subdevices::sim::kTypicalSdoLatency;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--trace") == 0) {
      g_trace = true;
    } else if (std::strcmp(argv[i], "--sdo-latency-us") == 0 && i + 1 < argc) {
      latency = Duration{std::atoll(argv[++i])};
    } else if (std::strcmp(argv[i], "--sdo-share") == 0 && i + 1 < argc) {
      g_sdo_share = std::atof(argv[++i]);
    } else {
      std::fprintf(stderr, "usage: %s [--sdo-latency-us N] [--sdo-share S] [--trace]\n", argv[0]);
      return 2;
    }
  }
  try {
    const auto demo = load_file(std::string(OEGW_SOURCE_DIR) + "/config/demo.yaml");
    const auto full = oegw::bench::load_or_throw(oegw::bench::yaml_full_set(), "full_fe_set.yaml");
    std::printf(
        "timed virtual bus, simulated clock; device SDO latency %.3f ms; the gateway's SDO paced to %.0f %% of the "
        "bus\n",
        ms(latency), 100.0 * g_sdo_share);
    print_boot("demo", boot(demo, 250'000, latency), demo.subdevices.size());
    {
      // A lost boot-up is not waited out (NetworkTiming::boot_wait, 2 s): the boot-up probe
      // reads 1000h once no other node is being configured.
      const auto& grip = demo.subdevices.front();
      const BootFigures b = boot(demo, 250'000, latency, grip.node_id);
      std::printf("boot demo, %s's boot-ups lost: %.1f ms (the boot-up wait it no longer waits out: %.0f ms)\n",
                  grip.name.c_str(), ms(b.boot), ms(oegw::subdevices::NetworkTiming{}.boot_wait));
    }
    // full_fe_set.yaml is laid out for 1 Mbit/s: at 250 kbit/s its steady state would be 80 % of
    // the bus (`oegw check` warns above 70 %), its encoders' 10 ms event timers alone 32 %. The
    // same 48 sub-devices laid out for 250 kbit/s: the encoders at 50 ms (54 % predicted).
    const auto full250 = oegw::bench::load_or_throw(oegw::fixtures::full_fe_set_at_250k(),
                                                    "full_fe_set.yaml, encoders at 50 ms, 250 kbit/s");
    print_boot("full-set", boot(full250, 250'000, latency), full250.subdevices.size());
    std::printf("at 1000000 bit/s (full_fe_set.yaml as it is):\n");
    print_boot("full-set", boot(full, 1'000'000, latency), full.subdevices.size());
    print_load("demo", demo, load(demo));
    print_load("full-set", full, load(full));
    print_load("full-250k", full250, load(full250));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "oegw_bench_cab_timing: %s\n", e.what());
    return 1;
  }
  return 0;
}
