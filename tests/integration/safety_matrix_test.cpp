// Tier 2, the safety fault matrix: for every device family, each fault in each phase of the
// sub-device's life, on the virtual buses with a simulated clock, with the invariant monitor on
// (safety_monitor.hpp). Each cell asserts the FE's value and status, the EMCY 7000h naming the
// node upstream, and WHEN (a bound in simulated time from the injection), then the recovery: the
// fault cleared by evidence (EMCY 0000h naming the node), the neutral interlock, live values again.
//
// Phases (where the fault is injected):
//   Waiting      the gateway has sent reset communication and waits; the device is still off.
//                The fault is applied to the unpowered device (or the wiring); it is powered
//                200 ms later.
//   Configuring  at the gateway's 2nd SDO request of the configuration (before anyone gets it).
//   JustStarted  at the gateway's NMT start to the node (before the device gets it, so before
//                its first heartbeat in operational).
//   Operational  1 s into steady operation, the input deflected (and a button held).
//   Recovering   after a previous fault (heartbeat stopped 400 ms, then resumed), at the NMT
//                start of the gateway's recovery boot.
//
// Cells NOT generated (the fault cannot happen in that phase or would be another cell):
//   | fault                        | phases left out        | why                                         |
//   |------------------------------|------------------------|---------------------------------------------|
//   | BootUpDuringConfig           | W, S, O, R             | by definition a Configuring event; a boot-up|
//   |                              |                        | elsewhere is RebootDeflected                |
//   | StaleStateReport (boot race) | W, C, O                | a pre-operational report overtaken by the   |
//   |                              |                        | NMT start exists only at an NMT start       |
//   | ErrorEmcy                    | W                      | the device is off: its EMCY cannot be sent  |
//   | NmtStop / NmtPreOp / NmtReset| W                      | the device is off: the command is lost, the |
//   |                              |                        | cell would be the fault-free boot           |
//   | ErrorValue                   | all, for MCB-402,      | the family has no error value in its PDOs   |
//   |                              | CiA 401 pedal/cluster  | (MCB-402 cable break is its ErrorEmcy)      |
//   | NotAvailable, ChannelMismatch| all, except elobau     | only the elobau grip has 127 and 2 channels |
//
// Decisions where the contract is silent (what a safety-minded integrator expects):
//   * No PDO at all after NMT start is a stale signal from NMT start + deadline (not "never
//     stale" because no PDO ever started the clock).
//   * A reboot / NMT reset (boot-up seen) of an operational node takes its FEs to fault values at
//     once; an EMCY is not required when the node is proven alive again within 1 s (the gateway
//     restarts it), and is required after that (Monitor::Options::reboot_report).
//   * A pre-operational or stopped heartbeat right after NMT start is ignored while `starting`
//     (contract point 1), so a foreign NMT stop / pre-op at NMT start is detected as "no heartbeat
//     in operational within the consumer time".
//   * A fault found while the node is starting (error EMCY, error value) may be reported when the
//     node would have become operational: within the consumer time of NMT start.
//   * A node that sends on change only (the CiA 401 cluster, event timer 0) may stay `offline`
//     without a fault after a fault that cost it its last PDO (or after its error reset, whose
//     inputs are unknown until the next PDO): the cell's recovery then lets the operator touch
//     the input.
//   * The matrix commands the outputs one bit at a time (the outputs' own multi-bit atomicity is
//     safety_outputs_test.cpp), so that an input cell fails for its input fault only.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <set>
#include <string>
#include <vector>

#include "safety_harness.hpp"

namespace oegw::testing::safety {
namespace {

enum class Fault {
  HbStops,
  HbNeverAfterReboot,
  PdosStop,
  RebootDeflected,
  BootUpDuringConfig,
  StaleStateReport,
  ErrorEmcy,
  ErrorValue,
  NotAvailable,
  ChannelMismatch,
  NmtStop,
  NmtPreOp,
  NmtReset,
  InterfaceDown,
  BusOff,
};
enum class Phase { Waiting, Configuring, JustStarted, Operational, Recovering };

const char* fault_name(Fault f) {
  switch (f) {
    case Fault::HbStops: return "HeartbeatStops";
    case Fault::HbNeverAfterReboot: return "HeartbeatNeverStartsAfterReboot";
    case Fault::PdosStop: return "PdosStopHeartbeatGoesOn";
    case Fault::RebootDeflected: return "RebootDeflected";
    case Fault::BootUpDuringConfig: return "BootUpDuringConfiguration";
    case Fault::StaleStateReport: return "PreOpHeartbeatOvertakenByNmtStart";
    case Fault::ErrorEmcy: return "ErrorEmcy";
    case Fault::ErrorValue: return "ErrorValue";
    case Fault::NotAvailable: return "NotAvailableValue";
    case Fault::ChannelMismatch: return "ChannelMismatch";
    case Fault::NmtStop: return "ForeignNmtStop";
    case Fault::NmtPreOp: return "ForeignNmtPreOp";
    case Fault::NmtReset: return "ForeignNmtResetNode";
    case Fault::InterfaceDown: return "InterfaceDownUp";
    case Fault::BusOff: return "BusOff";
  }
  return "?";
}
const char* phase_name(Phase p) {
  switch (p) {
    case Phase::Waiting: return "WaitingForBootUp";
    case Phase::Configuring: return "Configuring";
    case Phase::JustStarted: return "JustStarted";
    case Phase::Operational: return "Operational";
    case Phase::Recovering: return "Recovering";
  }
  return "?";
}

struct Cell {
  FamilyId family;
  std::size_t corner;  // corners(family)[corner]
  Fault fault;
  Phase phase;
};

bool applies(FamilyId fam, Fault f, Phase p) {
  const bool elobau = fam == FamilyId::Elobau;
  switch (f) {
    case Fault::BootUpDuringConfig: return p == Phase::Configuring;
    case Fault::StaleStateReport: return p == Phase::JustStarted || p == Phase::Recovering;
    case Fault::ErrorEmcy:
    case Fault::NmtStop:
    case Fault::NmtPreOp:
    case Fault::NmtReset: return p != Phase::Waiting;
    case Fault::ErrorValue: return elobau || fam == FamilyId::Novotechnik;
    case Fault::NotAvailable:
    case Fault::ChannelMismatch: return elobau;
    default: return true;
  }
}

// Every family at each of its corners (safety_harness.hpp corners()).
std::vector<Cell> all_cells() {
  std::vector<Cell> out;
  for (FamilyId fam : kFamilies)
    for (std::size_t c = 0; c < corners(fam).size(); ++c)
      for (int f = 0; f <= static_cast<int>(Fault::BusOff); ++f)
        for (int p = 0; p <= static_cast<int>(Phase::Recovering); ++p)
          if (applies(fam, static_cast<Fault>(f), static_cast<Phase>(p)))
            out.push_back({fam, c, static_cast<Fault>(f), static_cast<Phase>(p)});
  return out;
}

std::string cell_name(const ::testing::TestParamInfo<Cell>& i) {
  return std::string(name(i.param.family)) + "_" + corners(i.param.family)[i.param.corner].name + "_" +
         fault_name(i.param.fault) + "_" + phase_name(i.param.phase);
}

// What a cell expects.
struct Expect {
  bool fault = true;                   // EMCY 7000h naming the node, FE at fault values, by `by`
  bool false_fault_forbidden = false;  // no EMCY 7000h naming the node at all after the injection
  Duration by{0};                      // from the injection
  std::set<FeStatus> status;           // the FE status at `by`
  bool primary_only = false;           // only the primary field is affected (an axis error value)
};

constexpr Duration kGrace = 5ms;  // the monitor's 2 ms plus the 1 ms steps of the cell
constexpr Duration kConsumer = 150ms;
constexpr Duration kHbPeriod = 100ms;
constexpr Duration kPowerDelay = 200ms;   // Waiting: the device is powered this long after the fault
constexpr Duration kSdoTimeout = 1000ms;  // GatewayOptions::sdo_timeout (default)
constexpr Duration kBootWait = 2000ms;    // NetworkTiming::boot_wait (default)
constexpr Duration kOutage = 500ms;       // interface down / bus-off

Expect expect(const Family& fam, const Corner& corner, Fault f, Phase p) {
  Expect e;
  const Duration w = p == Phase::Waiting ? kPowerDelay : Duration{0};
  const std::set<FeStatus> lost{FeStatus::Offline, FeStatus::Stale};
  const bool before_op = p != Phase::Operational;
  switch (f) {
    case Fault::HbStops:
    case Fault::HbNeverAfterReboot:
      e.by = w + kConsumer + kGrace;
      e.status = lost;
      break;
    case Fault::PdosStop:
      if (fam.pdo_deadline == Duration{0}) {  // on change only: nothing to miss
        e.fault = false;
        e.false_fault_forbidden = true;
        break;
      }
      // Every field's PDO overdue (the monitor checks each signal's own deadline); before the
      // node is operational the deadline runs from its first heartbeat in operational.
      e.by = w + (p == Phase::Operational ? Duration{0} : kHbPeriod) + fam.pdo_deadline_max + kGrace;
      e.status = p == Phase::Operational ? std::set<FeStatus>{FeStatus::Stale} : lost;
      break;
    case Fault::RebootDeflected:
    case Fault::NmtReset:
      e.fault = false;  // a reboot is neither reported nor forbidden to report (see above)
      break;
    case Fault::BootUpDuringConfig:
    case Fault::StaleStateReport:
      e.fault = false;
      e.false_fault_forbidden = p != Phase::Recovering;  // R: the previous fault is still up
      break;
    case Fault::ErrorEmcy:
      e.by = p == Phase::Operational || p == Phase::Recovering ? kGrace : kConsumer + kGrace;
      e.status =
          before_op ? std::set<FeStatus>{FeStatus::Error, FeStatus::Offline} : std::set<FeStatus>{FeStatus::Error};
      break;
    case Fault::ErrorValue:
    case Fault::NotAvailable:
    case Fault::ChannelMismatch: {
      const FeStatus s = f == Fault::NotAvailable ? FeStatus::NotAvailable : FeStatus::Error;
      const int periods = f == Fault::ChannelMismatch ? corner.mismatch_periods : 1;
      e.by = p == Phase::Operational ? periods * fam.pdo_period + kGrace : w + kConsumer + kGrace;
      e.status = before_op ? std::set<FeStatus>{s, FeStatus::Offline} : std::set<FeStatus>{s};
      e.primary_only = fam.id == FamilyId::Elobau;
      break;
    }
    case Fault::NmtStop:
    case Fault::NmtPreOp:
      if (p == Phase::Configuring && f == Fault::NmtPreOp) {  // it is pre-operational already
        e.fault = false;
        e.false_fault_forbidden = true;
        break;
      }
      e.by = p == Phase::Operational   ? kHbPeriod + kGrace
             : p == Phase::Configuring ? kSdoTimeout + 100ms + kGrace  // a stopped node answers no SDO
                                       : kConsumer + kGrace;
      e.status = lost;
      break;
    case Fault::InterfaceDown:
    case Fault::BusOff:
      if (p == Phase::Waiting) {
        // The boot-up is lost; when the boot wait expires the gateway asks the node's identity,
        // finds it and boots it: a first boot that took longer, not a failure (the FE stays at
        // its fault value meanwhile, which the monitor checks).
        e.fault = false;
        break;
      }
      e.by = p == Phase::Configuring ? kSdoTimeout + 100ms + kGrace : kConsumer + kGrace;
      e.status = lost;
      break;
  }
  return e;
}

std::string statuses(const std::set<FeStatus>& s) {
  std::string out;
  for (auto x : s) out += std::to_string(static_cast<int>(x)) + " ";
  return out;
}

class SafetyMatrix : public ::testing::TestWithParam<Cell> {
 protected:
  void SetUp() override {
    b_ = std::make_unique<Bench>(GetParam().family, Monitor::Options{}, corners(GetParam().family)[GetParam().corner]);
    b_->build();
    b_->set_context([this] {
      return std::string("cell ") + name(GetParam().family) + "/" + b_->corner().name + "/" +
             fault_name(GetParam().fault) + "/" + phase_name(GetParam().phase) + "\n" + b_->tail(25);
    });
  }
  // OEGW_SAFETY_LOG=1: every cell prints its gateway log (what a passing cell went through).
  void TearDown() override {
    if (std::getenv("OEGW_SAFETY_LOG") != nullptr && b_) std::printf("%s", b_->log().c_str());
  }
  Bench& b() { return *b_; }
  // The gateway log (and with OEGW_SAFETY_TRACE=<lines>, the last frames of both buses).
  std::string dump() {
    const char* tr = std::getenv("OEGW_SAFETY_TRACE");
    return "gateway log:\n" + b_->tail(60) +
           (tr ? "frames:\n" + b_->trace_tail(std::max<std::size_t>(60, std::strtoul(tr, nullptr, 10)))
               : std::string());
  }

  void inject(Fault f, Phase p) {
    Bench& x = b();
    const TimePoint now = x.now();
    auto* d = x.dev();
    switch (f) {
      case Fault::HbStops: d->set_heartbeat_stopped(true); break;
      case Fault::HbNeverAfterReboot:
        d->set_heartbeat_stopped(true);
        if (p != Phase::Waiting) d->reboot(now);
        break;
      case Fault::PdosStop: x.dev_drop_tpdos = true; break;
      case Fault::RebootDeflected:
        x.deflect(true);
        if (p != Phase::Waiting) d->reboot(now);
        break;
      case Fault::BootUpDuringConfig: d->reboot(now); break;
      case Fault::StaleStateReport: x.device_frame(CanFrame(0x700 + x.fam().node, {0x7F})); break;
      case Fault::ErrorEmcy: x.error_emcy(true); break;
      case Fault::ErrorValue: x.error_value(true); break;
      case Fault::NotAvailable: x.error_value(true, true); break;
      case Fault::ChannelMismatch: x.mismatch(true); break;
      case Fault::NmtStop: x.foreign_nmt(0x02); break;
      case Fault::NmtPreOp: x.foreign_nmt(0x80); break;
      case Fault::NmtReset: x.foreign_nmt(0x81); break;
      case Fault::InterfaceDown:
        x.gw_link_down = true;
        x.loop().call_after(kOutage, [&x] { x.gw_link_down = false; });
        break;
      case Fault::BusOff:
        x.dev_drop_all = true;
        x.loop().call_after(kOutage, [&x] {
          x.dev_drop_all = false;
          x.bus_off_recovered();
        });
        break;
    }
  }
  void remove(Fault f) {
    Bench& x = b();
    switch (f) {
      case Fault::HbStops:
      case Fault::HbNeverAfterReboot: x.dev()->set_heartbeat_stopped(false); break;
      case Fault::PdosStop: x.dev_drop_tpdos = false; break;
      case Fault::ErrorEmcy: x.error_emcy(false); break;
      case Fault::ErrorValue:
      case Fault::NotAvailable: x.error_value(false); break;
      case Fault::ChannelMismatch: x.mismatch(false); break;
      default: break;
    }
  }

  std::unique_ptr<Bench> b_;
};

TEST_P(SafetyMatrix, Cell) {
  const Cell c = GetParam();
  Bench& x = b();
  const Family& fam = x.fam();
  const Expect e = expect(fam, x.corner(), c.fault, c.phase);
  x.start_gateway();
  if (fam.out) {
    x.error_values(0x01, 0x01);  // indicator 1 is the error lamp
    x.command_outputs(0x02, /*by_rpdo=*/false);
  }
  const std::uint8_t node = fam.node;
  auto sdo_to_node = [node](const BusRecord& r) { return r.sender == "gateway" && r.frame.id == 0x600u + node; };
  auto nmt_start = [node](const BusRecord& r) {
    return r.sender == "gateway" && r.frame.id == 0 && r.frame.dlc >= 2 && r.frame.data[0] == 0x01 &&
           (r.frame.data[1] == node || r.frame.data[1] == 0);
  };
  TimePoint t_inj{};
  auto injected = [&](TimePoint t) {
    t_inj = t;
    inject(c.fault, c.phase);
  };
  auto became_valid = [&] { return x.status() == FeStatus::Valid && x.mon().alive(node, x.now()); };

  switch (c.phase) {
    case Phase::Waiting:
      x.deflect(true);
      injected(x.now());
      x.run_for(kPowerDelay);
      x.power_device();
      break;
    case Phase::Configuring: {
      x.deflect(true);
      auto count = std::make_shared<int>(0);
      x.on_next([count, sdo_to_node](const BusRecord& r) { return sdo_to_node(r) && ++*count == 2; }, injected);
      x.power_device();
      ASSERT_TRUE(x.run_until([&] { return !x.trigger_pending(); }, 3s)) << dump();
      break;
    }
    case Phase::JustStarted:
      x.deflect(true);
      x.on_next(nmt_start, injected);
      x.power_device();
      ASSERT_TRUE(x.run_until([&] { return !x.trigger_pending(); }, 3s)) << dump();
      break;
    case Phase::Operational:
    case Phase::Recovering:
      x.power_device();
      ASSERT_TRUE(x.run_until(became_valid, 3s)) << "the device never became valid\n" << dump();
      x.deflect(true);
      x.run_for(500ms);
      ASSERT_EQ(x.field(fam.primary), fam.live) << dump();
      if (fam.out) x.command_outputs(0x03, /*by_rpdo=*/true);
      if (c.phase == Phase::Operational) {
        x.run_for(500ms);
        injected(x.now());
        break;
      }
      // The previous fault: the heartbeat stops for 400 ms, then comes back.
      x.dev()->set_heartbeat_stopped(true);
      x.run_for(400ms);
      ASSERT_TRUE(x.mon().emcy_active_at(node, x.now())) << "the previous fault was not reported\n" << dump();
      x.dev()->set_heartbeat_stopped(false);
      x.on_next(nmt_start, injected);
      ASSERT_TRUE(x.run_until([&] { return !x.trigger_pending(); }, 10s)) << "no recovery boot\n" << dump();
      break;
  }
  const TimePoint inj = t_inj;
  const long inj_ms = x.ms_at(inj);

  // ---- The fault: value, status, EMCY and when ----
  if (e.fault) {
    x.run_until([&] { return x.now() >= inj + e.by; }, e.by + 1s);
    EXPECT_TRUE(x.mon().emcy_active_at(node, inj + e.by))
        << "EMCY 7000h naming " << fam.dut << " not active "
        << std::chrono::duration_cast<std::chrono::milliseconds>(e.by).count()
        << " ms after the fault (injected at t=" << inj_ms << " ms); " << x.mon().life(node, x.now()) << "\n"
        << dump();
    if (e.primary_only) {
      EXPECT_EQ(x.field(fam.primary), 0) << dump();
    } else {
      EXPECT_TRUE(x.all_neutral()) << dump();
    }
    EXPECT_TRUE(e.status.count(x.status()))
        << "status " << static_cast<int>(x.status()) << ", expected one of " << statuses(e.status) << "\n"
        << dump();
    const auto first = x.mon().first_emcy(node, true, inj);
    if (c.phase != Phase::Recovering && first) {
      EXPECT_LE(*first, inj + e.by) << "EMCY 7000h late";
    }
    x.run_for(std::max<Duration>(700ms - e.by, 200ms));
    remove(c.fault);
  } else {
    x.run_for(700ms);
    remove(c.fault);
  }

  // ---- Recovery: cleared by evidence, neutral interlock, live again ----
  // The gateway retries a missing node with back-off (1 s, doubling): a few seconds.
  auto is_back = [&] { return became_valid() && !x.mon().emcy_active_at(node, x.now()); };
  bool recovered = x.run_until(is_back, fam.pdo_deadline == Duration{0} ? 5s : 15s);
  if (!recovered && fam.pdo_deadline == Duration{0} && x.mon().alive(node, x.now()) &&
      !x.mon().emcy_active_at(node, x.now())) {
    // A node sending on change only (the cluster) reports its inputs with the next change: after
    // a fault that cost its last PDO (or left its inputs unknown, e.g. after an error reset) the
    // FE is `offline` without a fault until the operator touches it.
    x.deflect(false);
    x.run_for(50ms);
    x.deflect(true);
    recovered = x.run_until(is_back, 10s);
  }
  ASSERT_TRUE(recovered) << "not recovered 15 s after the fault was removed: status " << static_cast<int>(x.status())
                         << ", node " << sd::to_string(x.node_state()) << ", " << x.mon().life(node, x.now()) << "\n"
                         << dump();
  if (e.false_fault_forbidden) {
    EXPECT_EQ(x.mon().emcy_count(node, true, inj), 0u) << "a false fault: EMCY 7000h naming " << fam.dut << "\n"
                                                       << dump();
  }
  if (x.mon().first_emcy(node, true, inj)) {
    EXPECT_TRUE(x.mon().first_emcy(node, false, inj)) << "the fault was never cleared upstream";
  }
  x.run_for(20ms);
  if (fam.interlock) {
    EXPECT_EQ(x.field(fam.primary), 0) << "the input is still deflected: the neutral interlock must hold it\n"
                                       << dump();
  }
  if (fam.out) x.command_outputs(0x01, /*by_rpdo=*/false);
  x.deflect(false);
  // Not a whole number of PDO cycles after the release: an elobau grip whose TPDO #0 was just
  // re-phased by the button release would otherwise send the new channel 2 before the new
  // channel 1 (the false mismatch SafetyFindings.ElobauNoFalseMismatch... reproduces).
  x.run_for(350ms);
  x.deflect(true);
  x.run_for(300ms);
  EXPECT_EQ(x.field(fam.primary), fam.live) << dump();
  EXPECT_EQ(x.status(), FeStatus::Valid);
  EXPECT_EQ(x.mon().violations(), 0u);
}

INSTANTIATE_TEST_SUITE_P(Families, SafetyMatrix, ::testing::ValuesIn(all_cells()), cell_name);

}  // namespace
}  // namespace oegw::testing::safety
