// Tier 2, safety: seeded random scenarios for every family, with the invariant monitor on
// (safety_monitor.hpp). Each step is one action — operator motion, a fault injected or removed
// (the matrix's faults, some armed to hit an exact protocol moment: the NMT start, the 2nd SDO of
// the configuration), an output command by SDO or RPDO, the host's heartbeat lost or back —
// followed by 1..40 ms of simulated time. At the end every fault is removed and the device must
// come back (valid, alive) within the gateway's longest back-off.
//
// CI runs kStepsCi steps per seed, kSeedsCi seeds per family natively (the cross tier under
// qemu-user the first seed only: scripts/cross-build.sh). A failing run prints the family,
// seed and step; replay it with
//   OEGW_SAFETY_SEED=<seed> [OEGW_SAFETY_FAMILY=<Elobau|Mcb402|Novotechnik406|Cia401Pedal|
//   Cia401Cluster>] [OEGW_SAFETY_CORNER=<Doc|Opposite|...>] [OEGW_SAFETY_STEPS=<n>] [OEGW_SAFETY_TRACE=1]
//   ./safety_random_test
// (OEGW_SAFETY_TRACE adds the last frames of both buses to each report).
#include <gtest/gtest.h>

#include <cstdlib>
#include <deque>
#include <random>
#include <string>
#include <vector>

#include "safety_harness.hpp"

namespace oegw::testing::safety {
namespace {

constexpr std::size_t kStepsCi = 10'000;
constexpr std::uint64_t kSeedsCi[] = {1, 2, 3};

enum class Act {
  Motion,
  HbStop,
  HbNeverAfterReboot,
  PdosStop,
  Reboot,
  ErrorEmcy,
  ErrorValue,
  NotAvailable,
  Mismatch,
  NmtStop,
  NmtPreOp,
  NmtReset,
  LinkDown,
  BusOff,
  AtNmtStart,   // arms: a fault at the next NMT start
  AtConfig,     // arms: a fault at the 2nd SDO request of the next configuration
  StaleReport,  // a pre-operational heartbeat overtaken by the NMT start (armed)
  Output,
  HostLost,
  HostBack,
  Remove,
};

struct Runner {
  Bench& b;
  std::mt19937_64 rng;
  std::uint64_t seed;
  std::size_t step = 0;
  std::deque<std::string> recent;
  // Active lasting faults.
  bool hb_stopped = false, pdos = false, emcy = false, value = false, na = false, mism = false;
  std::optional<TimePoint> outage_end;

  Runner(Bench& bench, std::uint64_t s) : b(bench), rng(s), seed(s) {}

  int uniform(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); }
  bool chance(double p) { return std::bernoulli_distribution(p)(rng); }
  void note(const std::string& what) {
    recent.push_back(fmt::format("step {} t={} ms: {}", step, b.ms(), what));
    if (recent.size() > 60) recent.pop_front();
  }
  std::string context() const {
    std::string s = fmt::format(
        "family {} corner {} seed {} step {}; replay: OEGW_SAFETY_SEED={} OEGW_SAFETY_FAMILY={} OEGW_SAFETY_CORNER={}\n"
        "last actions:\n",
        name(b.fam().id), b.corner().name, seed, step, seed, name(b.fam().id), b.corner().name);
    for (const auto& r : recent) s += "  " + r + "\n";
    return s + "gateway log:\n" + b.tail(20);
  }

  void apply(Act a) {
    auto* d = b.dev();
    const TimePoint now = b.now();
    switch (a) {
      case Act::Motion: {
        const double level = uniform(-4, 4) / 4.0;
        const bool button = chance(0.4);
        b.move(level, button);
        note(fmt::format("operator: input {:+.2f}, button {}", level, button));
        break;
      }
      case Act::HbStop:
        d->set_heartbeat_stopped(true);
        hb_stopped = true;
        note("heartbeat stops");
        break;
      case Act::HbNeverAfterReboot:
        d->set_heartbeat_stopped(true);
        hb_stopped = true;
        d->reboot(now);
        note("reboot, heartbeat never starts");
        break;
      case Act::PdosStop:
        b.dev_drop_tpdos = true;
        pdos = true;
        note("TPDOs stop, heartbeat goes on");
        break;
      case Act::Reboot:
        d->reboot(now);
        note("reboot (input as it is)");
        break;
      case Act::ErrorEmcy:
        b.error_emcy(true);
        emcy = true;
        note("error EMCY");
        break;
      case Act::ErrorValue: {
        const std::uint32_t markers[] = {0x7FFFFFFC, 0x7FFFFFF8, 0x80000008};
        b.error_value(true, false, markers[uniform(0, 2)]);
        value = true;
        note("error value in the PDO");
        break;
      }
      case Act::NotAvailable:
        b.error_value(true, true);
        na = true;
        note("not-available value in the PDO");
        break;
      case Act::Mismatch:
        b.mismatch(true, uniform(-9, 9) * 10);
        mism = true;
        note("channel mismatch");
        break;
      case Act::NmtStop:
        b.foreign_nmt(0x02);
        note("another master: NMT stop");
        break;
      case Act::NmtPreOp:
        b.foreign_nmt(0x80);
        note("another master: NMT pre-operational");
        break;
      case Act::NmtReset:
        b.foreign_nmt(0x81);
        note("another master: NMT reset node");
        break;
      case Act::LinkDown:
      case Act::BusOff: {
        if (outage_end) break;
        const Duration len = std::chrono::milliseconds(uniform(20, 800));
        const bool bus_off = a == Act::BusOff;
        (bus_off ? b.dev_drop_all : b.gw_link_down) = true;
        outage_end = now + len;
        b.loop().call_at(now + len, [this, bus_off] {
          (bus_off ? b.dev_drop_all : b.gw_link_down) = false;
          if (bus_off) b.bus_off_recovered();
          outage_end.reset();
        });
        note(fmt::format("{} for {} ms", bus_off ? "bus-off" : "downstream interface down",
                         std::chrono::duration_cast<std::chrono::milliseconds>(len).count()));
        break;
      }
      case Act::AtNmtStart:
      case Act::AtConfig: {
        const std::uint8_t node = b.fam().node;
        const Act what = pick_fault();
        auto count = std::make_shared<int>(0);
        const bool at_start = a == Act::AtNmtStart;
        b.on_next(
            [node, count, at_start](const BusRecord& r) {
              if (r.sender != "gateway") return false;
              if (at_start)
                return r.frame.id == 0 && r.frame.dlc >= 2 && r.frame.data[0] == 0x01 &&
                       (r.frame.data[1] == node || r.frame.data[1] == 0);
              return r.frame.id == 0x600u + node && ++*count == 2;
            },
            [this, what, at_start](TimePoint) {
              note(std::string("armed fault fires at ") + (at_start ? "NMT start" : "configuration"));
              apply(what);
            });
        note(std::string("armed a fault for the next ") + (at_start ? "NMT start" : "configuration"));
        break;
      }
      case Act::StaleReport: {
        const std::uint8_t node = b.fam().node;
        b.on_next(
            [node](const BusRecord& r) {
              return r.sender == "gateway" && r.frame.id == 0 && r.frame.dlc >= 2 && r.frame.data[0] == 0x01 &&
                     (r.frame.data[1] == node || r.frame.data[1] == 0);
            },
            [this, node](TimePoint) {
              b.device_frame(CanFrame(0x700 + node, {0x7F}));
              note("pre-operational heartbeat overtaken by the NMT start");
            });
        note("armed a stale pre-operational heartbeat");
        break;
      }
      case Act::Output: {
        const auto bits = static_cast<std::uint8_t>(uniform(0, 255) & b.fam().out_mask);
        const bool rpdo = chance(0.5);
        b.command_outputs(bits, rpdo);
        note(fmt::format("host commands outputs {:02X}h by {}", bits, rpdo ? "RPDO" : "SDO"));
        break;
      }
      case Act::HostLost:
        b.host_alive = false;
        note("host heartbeat stops");
        break;
      case Act::HostBack:
        b.host_alive = true;
        note("host heartbeat back");
        break;
      case Act::Remove: remove_one(); break;
    }
  }

  Act pick_fault() {
    std::vector<Act> v{Act::HbStop,  Act::HbNeverAfterReboot, Act::PdosStop, Act::Reboot,   Act::ErrorEmcy,
                       Act::NmtStop, Act::NmtPreOp,           Act::NmtReset, Act::LinkDown, Act::BusOff};
    if (b.has_error_value()) v.push_back(Act::ErrorValue);
    if (b.has_not_available()) v.push_back(Act::NotAvailable);
    if (b.has_mismatch()) v.push_back(Act::Mismatch);
    return v[static_cast<std::size_t>(uniform(0, static_cast<int>(v.size()) - 1))];
  }

  void remove_one() {
    std::vector<int> active;
    if (hb_stopped) active.push_back(0);
    if (pdos) active.push_back(1);
    if (emcy) active.push_back(2);
    if (value || na) active.push_back(3);
    if (mism) active.push_back(4);
    if (active.empty()) return;
    switch (active[static_cast<std::size_t>(uniform(0, static_cast<int>(active.size()) - 1))]) {
      case 0:
        b.dev()->set_heartbeat_stopped(false);
        hb_stopped = false;
        note("heartbeat resumes");
        break;
      case 1:
        b.dev_drop_tpdos = false;
        pdos = false;
        note("TPDOs resume");
        break;
      case 2:
        b.error_emcy(false);
        emcy = false;
        note("error cleared (error reset EMCY)");
        break;
      case 3:
        b.error_value(false);
        value = na = false;
        note("real value again");
        break;
      case 4:
        b.mismatch(false, 0);
        mism = false;
        note("channels agree again");
        break;
    }
  }
  void remove_all() {
    b.cancel_trigger();  // an armed fault that has not fired yet would strike after the end
    while (hb_stopped || pdos || emcy || value || na || mism) remove_one();
    b.host_alive = true;
  }

  // One step: an action, then 1..40 ms.
  void run_step() {
    const int r = uniform(0, 999);
    if (r < 400) {
      apply(Act::Motion);
    } else if (r < 440) {
      apply(pick_fault());
    } else if (r < 520) {
      apply(Act::Remove);
    } else if (r < 535) {
      apply(Act::AtNmtStart);
    } else if (r < 545) {
      apply(Act::AtConfig);
    } else if (r < 552) {
      apply(Act::StaleReport);
    } else if (r < 620) {
      if (b.fam().out) apply(Act::Output);
    } else if (r < 624) {
      apply(b.host_alive ? Act::HostLost : Act::HostBack);
    }
    b.run_for(std::chrono::milliseconds(uniform(1, 40)));
  }
};

std::optional<std::uint64_t> env_u64(const char* n) {
  const char* v = std::getenv(n);
  if (v == nullptr || *v == 0) return std::nullopt;
  return std::strtoull(v, nullptr, 0);
}

// A family at one of its corners (safety_harness.hpp corners()).
struct FamilyCorner {
  FamilyId family;
  std::size_t corner;
};
std::vector<FamilyCorner> all_corners() {
  std::vector<FamilyCorner> out;
  for (FamilyId fam : kFamilies)
    for (std::size_t c = 0; c < corners(fam).size(); ++c) out.push_back({fam, c});
  return out;
}

class SafetyRandom : public ::testing::TestWithParam<FamilyCorner> {};

TEST_P(SafetyRandom, SeededFaultSequencesKeepTheInvariants) {
  const FamilyId fam = GetParam().family;
  const Corner corner = corners(fam)[GetParam().corner];
  if (const char* only = std::getenv("OEGW_SAFETY_FAMILY"); only && *only && std::string(only) != name(fam))
    GTEST_SKIP() << "OEGW_SAFETY_FAMILY=" << only;
  if (const char* only = std::getenv("OEGW_SAFETY_CORNER"); only && *only && std::string(only) != corner.name)
    GTEST_SKIP() << "OEGW_SAFETY_CORNER=" << only;
  std::vector<std::uint64_t> seeds(std::begin(kSeedsCi), std::end(kSeedsCi));
  if (auto s = env_u64("OEGW_SAFETY_SEED")) seeds = {*s};
  const std::size_t steps = env_u64("OEGW_SAFETY_STEPS").value_or(kStepsCi);
  for (const std::uint64_t seed : seeds) {
    Monitor::Options mo;
    mo.max_reports = 3;
    Bench b(fam, mo, corner);
    b.build();
    Runner run(b, seed * 1000003u + static_cast<std::uint64_t>(fam));
    run.seed = seed;
    b.set_context([&run] { return run.context(); });
    std::optional<std::size_t> first_bad;
    bool stepping = false;
    std::string first_line;
    b.mon().on_violation = [&](const std::string& line) {
      if (first_bad) return;
      first_bad = stepping ? run.step : steps;  // `steps`: before the first step (the first boot)
      first_line = line;
    };
    b.start_gateway();
    if (b.fam().out) b.error_values(static_cast<std::uint8_t>(0x05 & b.fam().out_mask), 0x01);
    b.host_heartbeat();
    b.power_device();
    b.run_for(500ms);
    stepping = true;
    for (run.step = 0; run.step < steps && !first_bad; ++run.step) run.run_step();
    if (first_bad) {
      ADD_FAILURE() << "family " << name(fam) << " corner " << corner.name << " seed " << seed << ": first violation "
                    << (*first_bad == steps ? std::string("at the first boot, before any step")
                                            : "at step " + std::to_string(*first_bad))
                    << ": " << first_line << "\nreplay with OEGW_SAFETY_SEED=" << seed
                    << " OEGW_SAFETY_FAMILY=" << name(fam) << " OEGW_SAFETY_CORNER=" << corner.name;
      continue;
    }
    // Everything removed: the device must come back (the gateway's back-off is at most 30 s).
    run.remove_all();
    run.note("every fault removed");
    b.move(0, false);
    const std::uint8_t node = b.fam().node;
    const bool back = b.run_until([&] { return b.status() == FeStatus::Valid && b.mon().alive(node, b.now()); }, 40s);
    EXPECT_TRUE(back) << "family " << name(fam) << " seed " << seed << ": the device did not come back within 40 s "
                      << "after every fault was removed; status " << static_cast<int>(b.status()) << ", "
                      << b.mon().life(node, b.now()) << "\n"
                      << run.context();
    RecordProperty(std::string("sim_seconds_seed_") + std::to_string(seed), static_cast<int>(b.ms() / 1000));
  }
}

INSTANTIATE_TEST_SUITE_P(Families, SafetyRandom, ::testing::ValuesIn(all_corners()),
                         [](const ::testing::TestParamInfo<FamilyCorner>& i) {
                           return std::string(name(i.param.family)) + "_" +
                                  corners(i.param.family)[i.param.corner].name;
                         });

}  // namespace
}  // namespace oegw::testing::safety
