#include "subdevices/network_manager.hpp"

#include <algorithm>
#include <cstdio>
#include <memory>
#include <stdexcept>

#include "canopen/state.hpp"

namespace oegw::subdevices {

using canopen::SdoAbortCode;

std::string_view to_string(NodeState s) {
  switch (s) {
    case NodeState::Idle: return "idle";
    case NodeState::WaitingBootUp: return "waiting for boot-up";
    case NodeState::Configuring: return "configuring";
    case NodeState::Starting: return "starting";
    case NodeState::Operational: return "operational";
    case NodeState::Missing: return "missing";
    case NodeState::Refused: return "refused";
  }
  return "unknown";
}

NetworkManager::NetworkManager(canopen::Master& master, Timing timing)
    : master_(master), timing_(timing), lss_(master.sink()) {
  master_.on_boot = [this](NodeId n) {
    Managed* m = find(n);
    if (m == nullptr || m->state == NodeState::Idle) return;  // start() has not run yet
    // WaitingBootUp: the gateway sent NMT reset communication / reset node (begin_boot) and
    // this is its answer (CiA 301 §7.2.8.3.2.1: a node in reset sends its boot-up). Any other
    // boot-up the device did of itself (or another master did to it): a reboot seen.
    // Configuring or later with the boot-up still owed: the reset's boot-up, queued behind the
    // node's answer to the probe (Managed::boot_up_owed).
    const bool late_answer = m->state != NodeState::WaitingBootUp && m->boot_up_owed;
    const bool answers_reset = m->state == NodeState::WaitingBootUp || late_answer;
    m->boot_up_owed = false;
    if (answers_reset) {
      ++counters_.gateway_resets;
      ++m->counted.gateway_resets;
    } else if (m->started_once) {
      ++counters_.reboots_seen;
      ++m->counted.reboots_seen;
    }
    const bool was_live = m->state == NodeState::Operational;
    const bool application_reset = !answers_reset || m->reset_node_sent;
    if (application_reset && on_application_reset) on_application_reset(m->settings.name);
    // It just booted: its dictionary is at power-on values. The reason says which boot-up this
    // is, so a second one (e.g. the power-on boot-up crossing the gateway's reset on the bus,
    // then the reset's own) reads as what it is, not as the same step twice.
    m->reset_node_sent = false;
    configure(*m, now_,
              late_answer
                  ? "boot-up answering the reset after the node's SDO answer (or a reboot meanwhile, which looks "
                    "the same): configuring from the start"
              : answers_reset ? "boot-up seen: checking identity and configuring"
              : was_live      ? "boot-up while operational (the node rebooted): configuring again"
              : m->state == NodeState::Configuring || m->state == NodeState::Starting
                  ? "boot-up again during its configuration (the node reset): "
                    "configuring from the start"
                  : "boot-up seen: checking identity and configuring");
    // The inputs go offline after the state says why (see fail()).
    if (was_live) m->driver->on_offline(now_);
  };
  master_.on_heartbeat_timeout = [this](NodeId n) {
    Managed* m = find(n);
    if (m != nullptr && m->state == NodeState::Operational) lost(*m, "heartbeat lost", now_);
  };
  master_.on_heartbeat = [this](NodeId n, canopen::NmtState s) {
    Managed* m = find(n);
    if (m != nullptr) {
      m->last_heartbeat = now_;
      release_held_steps();
    }
    // Only a heartbeat in operational proves the start took effect; one in another state may
    // have been on its way before the node saw the NMT start: the deadline decides.
    if (m != nullptr && m->state == NodeState::Starting && s == canopen::NmtState::Operational)
      go_live(*m, "first heartbeat in operational after NMT start", now_);
  };
  master_.on_state = [this](NodeId n, canopen::NmtState s) {
    Managed* m = find(n);
    if (m == nullptr || m->state != NodeState::Operational) return;
    if (s != canopen::NmtState::Operational && s != canopen::NmtState::Initialisation)
      lost(*m, "the node left operational (now " + std::string(canopen::to_string(s)) + ")", now_);
  };
  master_.on_emcy = [this](const EmcyMessage& e, TimePoint t) {
    Managed* m = find(e.node);
    if (m == nullptr) {
      if (counters_.unknown_emcy++ == 0 && on_bad_input)
        on_bad_input("EMCY from node " + std::to_string(e.node.value()) + ", not in the configuration, ignored");
      return;
    }
    const DecodedEmcy d = m->driver->on_emcy(e, t);
    report_bad_input(*m);
    if (on_emcy) on_emcy(m->settings.name, e, d);
  };
}

bool NetworkManager::add(NodeSettings settings, std::unique_ptr<Driver> driver) {
  if (!driver || driver->node() != settings.node) return false;
  for (const auto& m : nodes_)
    if (m->settings.node == settings.node || m->settings.name == settings.name) return false;
  auto m = std::make_unique<Managed>();
  m->settings = std::move(settings);
  m->driver = std::move(driver);
  m->driver->set_pdo_timeout(std::chrono::milliseconds(m->settings.pdo_timeout_ms));
  m->driver->set_sync_period(master_.sync_period());
  route(*m);
  nodes_.push_back(std::move(m));
  return true;
}

void NetworkManager::route(Managed& m) {
  std::erase_if(by_cob_, [&m](const auto& e) { return e.second == &m; });
  // A COB-ID another node routes already stays its: the one added (or booted) first keeps it,
  // the other is refused when its boot ends (cob_refusal).
  for (const std::uint32_t cob : m.driver->consumed_cob_ids()) (void)by_cob_.try_emplace(cob, &m);
}

void NetworkManager::start(TimePoint now) {
  now_ = now;
  for (auto& m : nodes_) begin_boot(*m, now);
}

NetworkManager::Managed* NetworkManager::find(NodeId node) {
  return const_cast<Managed*>(std::as_const(*this).find(node));
}

const NetworkManager::Managed* NetworkManager::find(NodeId node) const {
  for (const auto& m : nodes_)
    if (m->settings.node == node) return m.get();
  return nullptr;
}

const NetworkManager::Managed* NetworkManager::find(std::string_view name) const {
  for (const auto& m : nodes_)
    if (m->settings.name == name) return m.get();
  return nullptr;
}

NodeState NetworkManager::state(std::string_view name) const {
  const Managed* m = find(name);
  return m ? m->state : NodeState::Idle;
}

Driver* NetworkManager::driver(std::string_view name) {
  const Managed* m = find(name);
  return m ? m->driver.get() : nullptr;
}

const Driver* NetworkManager::driver(std::string_view name) const {
  const Managed* m = find(name);
  return m ? m->driver.get() : nullptr;
}

NodeCounters NetworkManager::node_counters(std::string_view name) const {
  const Managed* m = find(name);
  return m ? m->counted : NodeCounters{};
}

void NetworkManager::count_frame(const CanFrame& frame) {
  if (frame.extended || frame.rtr) return;
  if (auto it = by_cob_.find(frame.id); it != by_cob_.end()) {
    ++it->second->counted.frames;
    return;
  }
  // The predefined connection set's node-bound COB-IDs (CiA 301 §7.3.5): EMCY, SDO answer,
  // heartbeat / boot-up; 080h itself is SYNC.
  const std::uint32_t function = frame.id & 0x780;
  const auto node = static_cast<std::uint8_t>(frame.id & 0x7F);
  if (node == 0 || (function != 0x080 && function != 0x580 && function != 0x700)) return;
  if (Managed* m = find(NodeId{node})) ++m->counted.frames;
}

std::vector<std::string> NetworkManager::names() const {
  std::vector<std::string> out;
  for (const auto& m : nodes_) out.push_back(m->settings.name);
  return out;
}

bool NetworkManager::fault() const {
  return std::any_of(nodes_.begin(), nodes_.end(),
                     [](const auto& m) { return m->settings.mandatory && m->state != NodeState::Operational; });
}

void NetworkManager::set_state(Managed& m, NodeState s, const std::string& why, TimePoint /*now*/) {
  m.state = s;
  if (on_node_state) on_node_state(m.settings.name, s, why);
}

std::uint16_t NetworkManager::consumer_ms(const Managed& m) const {
  if (m.settings.heartbeat_timeout_ms != 0) return m.settings.heartbeat_timeout_ms;
  return static_cast<std::uint16_t>(std::min<unsigned>(0xFFFF, m.settings.heartbeat_ms * 3u / 2u));
}

void NetworkManager::reset_application_next(std::string_view name) {
  for (auto& m : nodes_)
    if (m->settings.name == name) m->reset_node_next = true;
}

void NetworkManager::begin_boot(Managed& m, TimePoint now) {
  ++m.generation;
  m.step_held = false;
  m.last_heartbeat.reset();
  // A transfer in flight runs to its end on the wire (its requester is answered at once; the
  // network manager's own callback is ignored: generation): aborting it
  // would let the node's late answer pass for the answer to the next boot's first request
  // (SdoClient::cancel_queued).
  master_.sdo(m.settings.node).cancel_queued(SdoAbortCode::CannotTransferDeviceState);
  m.reset_node_sent = m.reset_node_next;
  m.reset_node_next = false;
  if (m.reset_node_sent) {
    master_.nmt().reset_node(m.settings.node);
  } else {
    master_.nmt().reset_communication(m.settings.node);
  }
  m.boot_up_owed = true;
  m.held_since.reset();
  m.deadline = now + timing_.boot_wait;
  m.probe_gap = timing_.boot_probe_first;
  m.probe_at.reset();
  if (probes_on()) m.probe_at = now + timing_.boot_probe_first;
  set_state(m, NodeState::WaitingBootUp,
            m.reset_node_sent ? "NMT reset node sent (to clear the error it reported)" : "NMT reset communication sent",
            now);
}

void NetworkManager::probe(Managed& m) {
  m.probe_at.reset();
  const std::uint64_t gen = m.generation;
  Managed* mp = &m;
  canopen::SdoClient& sdo = master_.sdo(m.settings.node);
  const Duration timeout = std::min(timing_.boot_probe_timeout, sdo.config().timeout);
  (void)sdo.upload_within(0x1000, 0, timeout, [this, mp, gen](SdoAbortCode code, std::vector<std::uint8_t>) {
    if (mp->generation != gen || mp->state != NodeState::WaitingBootUp) return;  // the boot-up came
    if (code == SdoAbortCode::Timeout) {
      // Not answered (still resetting, or absent): the next probe after twice the gap, while
      // the wait runs; a late answer to this one is read by the next read of 1000h as its own.
      mp->probe_gap *= 2;
      if (mp->deadline && now_ + mp->probe_gap < *mp->deadline) mp->probe_at = now_ + mp->probe_gap;
      return;
    }
    // An answer, even an abort: its SDO server runs, so it has left its reset (CiA 301
    // §7.3.2.2.1). The identity check decides the rest.
    configure(*mp, now_,
              "no boot-up seen, but the node answered 1000h (it is past its reset): checking identity and configuring");
  });
}

void NetworkManager::configure(Managed& m, TimePoint now, const std::string& why) {
  ++m.generation;
  m.step_held = false;
  m.probe_at.reset();
  m.held_since.reset();
  m.deadline.reset();
  m.held.clear();
  m.driver->set_alive_since(std::nullopt);
  // As in begin_boot(): a request in flight (e.g. the previous configuration's, when a second
  // boot-up - the power-on one crossing the gateway's reset - restarts it) is answered before
  // this configuration's first request goes out, and its answer is ignored.
  master_.sdo(m.settings.node).cancel_queued(SdoAbortCode::CannotTransferDeviceState);
  // Pre-operational before any SDO (step 2 of the header). The NMT command is unconfirmed; the
  // node handles it before the SDO request queued behind it on the bus.
  master_.nmt().enter_pre_operational(m.settings.node);
  m.boot.plan(m.settings, *m.driver);
  set_state(m, NodeState::Configuring, why, now);
  run_step(m);
}

const NodeDiagnostics* NetworkManager::diagnostics(std::string_view name) const {
  const Managed* m = find(name);
  return m ? &m->boot.diagnostics() : nullptr;
}

std::string NetworkManager::sync_refusal(const Managed& m) const {
  if (master_.sync_period().count() != 0) return {};
  const auto comm = m.driver->synchronous_carrier();
  if (!comm) return {};
  char b[200];
  std::snprintf(b, sizeof b,
                "the TPDO of %04Xh has a synchronous transmission type (0..240: sent only at a SYNC) and no SYNC "
                "is produced downstream (downstream.sync_period_ms not set)",
                static_cast<unsigned>(*comm));
  return b;
}

std::string NetworkManager::cob_refusal(const Managed& m) const {
  // CiA 301 §7.2.2: a PDO has one producer. Two nodes sending on one COB-ID (a device whose PDO
  // was configured elsewhere, read back at boot) cannot be told apart: neither one's inputs
  // could be trusted, and the node found so is refused (its FEs at their fault values) until
  // it is configured otherwise.
  for (const std::uint32_t cob : m.driver->consumed_cob_ids()) {
    const auto it = by_cob_.find(cob);
    if (it == by_cob_.end() || it->second == &m) continue;
    char b[200];
    std::snprintf(b, sizeof b, "its PDO COB-ID %03Xh is also %s's: the frames on it cannot be told apart",
                  static_cast<unsigned>(canopen::CobId{cob}.can_id()), it->second->settings.name.c_str());
    return b;
  }
  return {};
}

void NetworkManager::run_step(Managed& m) {
  for (;;) {
    const NodeBoot::Next next = m.boot.advance();
    if (next == NodeBoot::Next::Done) {
      finish(m, now_);
      return;
    }
    if (next == NodeBoot::Next::Request) break;
    const std::uint64_t gen = m.generation;
    if (on_diagnostics) on_diagnostics(m.settings.name, m.boot.diagnostics());
    if (m.generation != gen || m.state != NodeState::Configuring) return;  // the observer rebooted it
    if (const std::string error = m.boot.check_error_register(); !error.empty()) {
      fail(m, NodeState::Refused, error, now_);
      return;
    }
  }
  if (late_heartbeat()) {
    m.step_held = true;  // released by the heartbeat, or by advance() when its consumer time ran out
    return;
  }
  const NodeBoot::Step& step = m.boot.current();
  const std::uint64_t gen = m.generation;
  Managed* mp = &m;
  auto done = [this, mp, gen](SdoAbortCode code, std::vector<std::uint8_t> data) {
    if (mp->generation != gen || mp->state != NodeState::Configuring) return;  // overtaken
    const NodeBoot::Verdict v = mp->boot.on_answer(code, data);
    switch (v.kind) {
      case NodeBoot::Verdict::Kind::Continue: run_step(*mp); return;
      case NodeBoot::Verdict::Kind::NoAnswer: fail(*mp, NodeState::Missing, v.why, now_); return;
      case NodeBoot::Verdict::Kind::Refused: fail(*mp, NodeState::Refused, v.why, now_); return;
    }
  };
  if (step.kind == NodeBoot::Step::Kind::Read) {
    master_.sdo(m.settings.node).upload(step.index, step.sub, done);
  } else {
    master_.sdo(m.settings.node).download(step.index, step.sub, step.data, done);
  }
}

Duration NetworkManager::proof_deadline(const Managed& m) const {
  if (m.settings.heartbeat_ms != 0) return std::chrono::milliseconds(consumer_ms(m));
  // No heartbeat (the mapping file then requires pdo_timeout_ms): the first PDO is the proof.
  const Duration d = m.driver->longest_freshness();
  return d.count() != 0 ? d : timing_.boot_wait;
}

void NetworkManager::finish(Managed& m, TimePoint now) {
  m.state = NodeState::Idle;  // not among the nodes configuring_any() counts while it decides
  if (const std::string why = cob_refusal(m); !why.empty()) {
    fail(m, NodeState::Refused, why, now);
    return;
  }
  route(m);  // what the driver consumes may depend on what it read at boot
  // The event timers actually written decide the PDOs' freshness deadlines.
  m.driver->apply_boot_writes(m.boot.writes());
  if (const std::string why = sync_refusal(m); !why.empty()) {
    fail(m, NodeState::Refused, why, now);
    return;
  }
  if (m.driver->restart_after_configuration()) {
    // Header, step 5: written, the node restarts (NMT reset node) and is booted again.
    m.reset_node_next = true;
    begin_boot(m, now);
    return;
  }
  if (booting_any()) {
    // Held (header, step 7): the other nodes' configuration keeps the bus busy with SDO frames,
    // which win arbitration over every heartbeat; started now, this node's heartbeats could
    // miss its consumer time behind them. A node still waiting for its boot-up is about to be
    // configured (its boot-up may be late behind those very frames).
    if (!m.held_since) m.held_since = now;
    m.deadline = *m.held_since + timing_.start_hold_max;
    set_state(m, NodeState::Configuring,
              "configured; NMT start held while other nodes are being configured (their SDO frames would delay its "
              "heartbeat)",
              now);
    return;
  }
  start_node(m, now);
}

void NetworkManager::start_node(Managed& m, TimePoint now) {
  m.held_since.reset();
  if (m.settings.heartbeat_ms != 0) (void)master_.monitor_heartbeat(m.settings.node, consumer_ms(m));
  master_.nmt().start(m.settings.node);
  m.started_once = true;
  const Duration wait = proof_deadline(m);
  m.deadline = now + wait;
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(wait).count();
  set_state(m, NodeState::Starting,
            std::string("configured, NMT start sent: waiting ") + std::to_string(ms) + " ms for " +
                (m.settings.heartbeat_ms != 0 ? "a heartbeat in operational" : "a first PDO"),
            now);
}

void NetworkManager::go_live(Managed& m, const std::string& evidence, TimePoint now) {
  m.deadline.reset();
  // Proof of life: a heartbeat goes out on the boot-up's COB-ID after it, so no boot-up of the
  // last reset is still queued in the node (with heartbeat_ms 0 the first PDO, after its whole
  // configuration: long past).
  m.boot_up_owed = false;
  m.backoff = Duration{0};
  // One output batch for what the driver re-sends (a rebooted device forgot its outputs) and
  // what the state's observers set: the device gets the current state once.
  m.driver->begin_outputs();
  m.driver->on_online(now);
  m.driver->set_alive_since(now);  // from now on a PDO that never comes is overdue too
  m.poll_at.reset();
  m.poll_pending = false;
  // PDOs the node sent after the NMT start, before its proof of life: the last of each, as
  // received (a node sending on change only may send nothing else for a long time).
  std::vector<std::pair<CanFrame, TimePoint>> held;
  held.swap(m.held);
  set_state(m, NodeState::Operational, evidence, now);
  for (const auto& [frame, at] : held) {
    if (m.state != NodeState::Operational) break;
    m.driver->pdo_received(frame.id, at);  // fresh as of its reception...
    (void)m.driver->on_frame(frame, now);  // ...judged now: past its deadline it is Stale at once
  }
  m.driver->end_outputs(now);
}

void NetworkManager::fail(Managed& m, NodeState s, const std::string& why, TimePoint now) {
  ++m.generation;
  m.step_held = false;
  m.last_heartbeat.reset();
  m.probe_at.reset();
  m.held_since.reset();
  m.held.clear();
  m.driver->set_alive_since(std::nullopt);
  m.backoff = m.backoff == Duration{0} ? timing_.retry_first : std::min(m.backoff * 2, timing_.retry_max);
  m.deadline = now + m.backoff;
  // The state first, then the inputs: whoever watches both sees the inputs go offline because
  // the node failed, never as a moment where the node still counts as live with no bad input.
  set_state(m, s, why, now);
  m.driver->on_offline(now);
}

void NetworkManager::lost(Managed& m, const std::string& why, TimePoint now) { fail(m, NodeState::Missing, why, now); }

void NetworkManager::commission(std::optional<canopen::lss::Address> address, NodeId new_id,
                                std::optional<std::uint8_t> bit_timing, TimePoint now,
                                std::function<void(bool, const std::string&)> done) {
  using canopen::LssMaster;
  now_ = now;
  // The gateway's own LSS work comes first: a client's fastscan ends here (its answer says why).
  // A client's scan it interrupts may have selected its slave with the step already on the wire:
  // everyone back to waiting first, so that only the gateway's own target is configured.
  const bool interrupted = client_scan_running();
  fastscan_.cancel("interrupted: the gateway is commissioning a device by LSS itself");
  slowscan_.cancel("interrupted: the gateway is commissioning a device by LSS itself");
  if (interrupted) lss_.switch_state_global(canopen::lss::Mode::Waiting, now);
  ++own_lss_;
  auto failed = std::make_shared<bool>(false);
  auto step = [failed, done](const char* what) {
    return [failed, done, what](const LssMaster::Result& r) {
      if (*failed) return;
      if (r.status == LssMaster::Status::Ok) return;
      *failed = true;
      std::string why = std::string("LSS ") + what + ": ";
      if (r.status == LssMaster::Status::Timeout) why += "no answer";
      else why += "refused with error " + std::to_string(r.error);
      done(false, why);
    };
  };
  if (address) {
    lss_.switch_state_selective(*address, now, step("switch state selective"));
  } else {
    lss_.switch_state_global(canopen::lss::Mode::Configuration, now, step("switch state global"));
  }
  lss_.configure_node_id(new_id, now, step("configure node-ID"));
  if (bit_timing) lss_.configure_bit_timing(*bit_timing, now, step("configure bit timing"));
  lss_.store_configuration(now, step("store configuration"));
  lss_.switch_state_global(canopen::lss::Mode::Waiting, now, [this, failed, done](const LssMaster::Result&) {
    --own_lss_;
    if (!*failed) done(true, "node-ID configured and stored; active after reset communication");
  });
}

bool NetworkManager::on_frame(const CanFrame& frame, TimePoint now) {
  now_ = now;
  count_frame(frame);
  if (lss_.on_frame(frame, now)) return true;
  if (master_.on_frame(frame, now)) return true;
  if (frame.extended || frame.rtr) return false;
  if (auto it = by_cob_.find(frame.id); it != by_cob_.end()) {
    Managed& m = *it->second;
    // Without a heartbeat, the first PDO after the NMT start is the node's proof of life; with
    // one, PDOs before the proof are kept (the last per COB-ID) for go_live().
    if (m.state == NodeState::Starting && m.settings.heartbeat_ms == 0) go_live(m, "first PDO after NMT start", now);
    if (m.state == NodeState::Starting) {
      auto same = std::find_if(m.held.begin(), m.held.end(), [&](const auto& h) { return h.first.id == frame.id; });
      if (same != m.held.end()) {
        *same = {frame, now};
      } else {
        m.held.emplace_back(frame, now);
      }
      return true;
    }
    // PDOs count only from a node we configured, started and saw alive (CiA 301: none outside
    // operational); anything else is ignored, never passed through.
    if (m.state != NodeState::Operational) return false;
    m.driver->pdo_received(frame.id, now);
    const bool used = m.driver->on_frame(frame, now);
    report_bad_input(m);
    return used;
  }
  if (frame.id >= canopen::cob::kTpdo1 && frame.id < canopen::cob::kSdoTx) {
    if (counters_.unknown_pdo++ == 0 && on_bad_input) {
      char b[96];
      std::snprintf(b, sizeof b, "PDO %03Xh from a node not in the configuration ignored (counted from now on)",
                    static_cast<unsigned>(frame.id));
      on_bad_input(b);
    }
  }
  return false;
}

void NetworkManager::report_once(std::uint64_t& seen, std::uint64_t now_count, const std::string& name,
                                 const char* what) {
  // The line is built only when it is reported: this runs for every PDO (no allocation).
  if (seen == 0 && now_count > 0 && on_bad_input) on_bad_input(name + what);
  seen = now_count;
}

void NetworkManager::report_bad_input(Managed& m) {
  const InputCounters& c = m.driver->counters();
  // This runs for every PDO: the usual case, nothing counted since the last frame, in one
  // comparison of the counters.
  if (c == m.reported) return;
  const std::string& n = m.settings.name;
  report_once(m.reported.wrong_length, c.wrong_length, n, ": PDO of the wrong length ignored (counted from now on)");
  report_once(m.reported.unknown_cob, c.unknown_cob, n, ": frame on a COB-ID the driver does not use ignored");
  report_once(m.reported.unknown_emcy, c.unknown_emcy, n, ": EMCY with an unknown code ignored");
  report_once(m.reported.mismatches, c.mismatches, n, ": redundant channels disagree (signal set to error)");
}

void NetworkManager::advance(TimePoint now) {
  now_ = now;
  master_.advance(now);
  lss_.advance(now);
  release_held_steps();
  for (auto& mp : nodes_) {
    Managed& m = *mp;
    if (m.state == NodeState::Operational) {
      m.driver->advance(now);  // overdue PDOs: Stale
      poll_faults(m, now);
      // Without a heartbeat the PDOs are the only proof of life: all of them overdue, the node
      // is lost (stopped by another master, unplugged) and booted again like any lost node.
      if (m.settings.heartbeat_ms == 0 && m.driver->all_stale()) {
        lost(m, "no PDO within its deadline (no heartbeat watched)", now);
        continue;
      }
    }
    if (m.state == NodeState::WaitingBootUp && m.probe_at && *m.probe_at <= now && !configuring_any()) probe(m);
    if (m.state == NodeState::Configuring && m.held_since && !booting_any()) {
      start_node(m, now);
      continue;
    }
    if (!m.deadline || *m.deadline > now) continue;
    m.deadline.reset();
    switch (m.state) {
      case NodeState::WaitingBootUp:
        // No boot-up: the node may not have reset (or be absent). Asking its identity tells.
        configure(m, now, "no boot-up within the wait: checking identity and configuring");
        break;
      case NodeState::Starting: {
        const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(proof_deadline(m)).count();
        lost(m,
             std::string("no ") + (m.settings.heartbeat_ms != 0 ? "heartbeat in operational" : "PDO") + " within " +
                 std::to_string(ms) + " ms of NMT start",
             now);
        break;
      }
      case NodeState::Configuring:
        if (m.held_since) start_node(m, now);  // held long enough (NetworkTiming::start_hold_max)
        break;
      case NodeState::Missing:
      case NodeState::Refused: begin_boot(m, now); break;
      default: break;
    }
  }
}

std::optional<TimePoint> NetworkManager::late_heartbeat() const {
  std::optional<TimePoint> until;
  for (const auto& m : nodes_) {
    if (m->state != NodeState::Operational || m->settings.heartbeat_ms == 0 || !m->last_heartbeat) continue;
    const Duration period = std::chrono::milliseconds(m->settings.heartbeat_ms);
    const Duration consumer = std::chrono::milliseconds(consumer_ms(*m));
    if (consumer <= period) continue;
    const TimePoint late = *m->last_heartbeat + period + (consumer - period) / 3;
    const TimePoint lost_at = *m->last_heartbeat + consumer;
    if (now_ > late && now_ < lost_at && (!until || lost_at < *until)) until = lost_at;
  }
  return until;
}

void NetworkManager::release_held_steps() {
  if (late_heartbeat()) return;
  for (auto& m : nodes_) {
    if (!m->step_held) continue;
    m->step_held = false;
    if (m->state == NodeState::Configuring && !m->held_since) run_step(*m);
  }
}

void NetworkManager::poll_faults(Managed& m, TimePoint now) {
  const auto poll = m.driver->fault_poll();
  if (!poll) {
    m.poll_at.reset();  // the next fault starts a full period after it
    return;
  }
  if (m.poll_pending) return;
  if (!m.poll_at) m.poll_at = now + poll->period;
  if (now < *m.poll_at) return;
  m.poll_pending = true;
  const std::uint64_t gen = m.generation;
  Managed* mp = &m;
  m.driver->on_fault_poll_sent();
  master_.sdo(m.settings.node)
      .upload(poll->index, poll->sub,
              [this, mp, gen, period = poll->period](SdoAbortCode code, std::vector<std::uint8_t> data) {
                if (mp->generation != gen) return;  // rebooted meanwhile: a new life, a new poll
                mp->poll_pending = false;
                mp->poll_at = now_ + period;
                if (mp->state != NodeState::Operational || code != SdoAbortCode::None) return;  // no evidence
                const std::string what = mp->driver->on_fault_poll(data, now_);
                if (!what.empty() && on_fault_evidence) on_fault_evidence(mp->settings.name, what);
              });
}

bool NetworkManager::configuring_any() const {
  return std::any_of(nodes_.begin(), nodes_.end(), [](const auto& m) { return is_configuring(*m); });
}

bool NetworkManager::booting_any() const {
  // A node whose probe went unanswered is likely absent: it holds no one; nor, with no probes
  // (NetworkTiming), one that would be waited out for boot_wait.
  return configuring_any() || (probes_on() && std::any_of(nodes_.begin(), nodes_.end(),
                                                          [this](const auto& m) { return awaiting_boot_up(*m); }));
}

std::optional<TimePoint> NetworkManager::next_deadline() const {
  std::optional<TimePoint> best = master_.next_deadline();
  const auto sooner = [&best](const std::optional<TimePoint>& t) {
    if (t && (!best || *t < *best)) best = t;
  };
  // One pass over the nodes, as this runs after every frame. Two of its answers depend on the
  // others: a probe waits while any node is configuring (configuring_any()), a held start while
  // any node is booting (booting_any()), so they are gathered and decided after the pass.
  bool step_held = false;
  bool configuring = false;
  bool probing = false;
  bool start_held = false;  // a configured node held before its start
  std::optional<TimePoint> probe;
  for (const auto& m : nodes_) {
    step_held = step_held || m->step_held;
    configuring = configuring || is_configuring(*m);
    probing = probing || awaiting_boot_up(*m);
    sooner(m->deadline);
    if (m->probe_at && (!probe || *m->probe_at < *probe)) probe = m->probe_at;
    if (m->state == NodeState::Configuring && m->held_since) start_held = true;
    if (m->state != NodeState::Operational) continue;
    sooner(m->driver->next_deadline());
    if (m->driver->fault_poll() && !m->poll_pending) sooner(m->poll_at.value_or(now_));
  }
  if (!configuring) sooner(probe);
  const bool booting = configuring || (probing && probes_on());
  if (start_held && !booting) sooner(now_);  // its start is due
  if (step_held) sooner(late_heartbeat());
  sooner(lss_.next_deadline());
  return best;
}

std::string NetworkManager::busy() const {
  if (own_lss_ != 0) return "commissioning a device by LSS";
  if (client_scan_running()) return "an LSS scan runs";
  if (!lss_.idle()) return "an LSS request is under way";
  for (const auto& m : nodes_) {
    if (is_configuring(*m)) return m->settings.name + ": configuring (an SDO request on the wire or held)";
    if (m->poll_pending) return m->settings.name + ": its fault poll is on the wire";
  }
  // A boot-up probe, or a transfer a reboot overtook that still runs to its end on the wire.
  if (const auto server = master_.busy_sdo_server()) {
    const Managed* m = find(*server);
    return (m != nullptr ? m->settings.name : "node " + std::to_string(server->value())) +
           ": an SDO request on the wire";
  }
  return {};
}

namespace {

void put_text(canopen::StateWriter& w, std::string_view key, const std::optional<std::string>& text) {
  if (text) w.put_text(key, *text);
}

std::optional<std::string> text(const canopen::StateReader& r, std::string_view key) {
  if (!r.has(key)) return std::nullopt;
  return r.text(key, NodeDiagnostics::kMaxText);
}

}  // namespace

void NetworkManager::export_state(canopen::StateWriter& w) const {
  if (const std::string why = busy(); !why.empty()) throw std::logic_error("NetworkManager::export_state: " + why);
  w.put("now", now_);
  w.put("counters.unknown_pdo", counters_.unknown_pdo);
  w.put("counters.unknown_emcy", counters_.unknown_emcy);
  w.put("counters.reboots_seen", counters_.reboots_seen);
  w.put("counters.gateway_resets", counters_.gateway_resets);
  // The routes in force: the node that routed a COB-ID first keeps it (route()).
  std::vector<std::pair<std::uint32_t, NodeId>> routes;
  for (const auto& [cob, m] : by_cob_) routes.emplace_back(cob, m->settings.node);
  w.put_list("routes", routes.size(), [&](std::size_t i) {
    w.put("cob", routes[i].first);
    w.put("node", routes[i].second.value());
  });
  w.put_list("nodes", nodes_.size(), [&](std::size_t i) {
    const Managed& m = *nodes_[i];
    w.put("node", m.settings.node.value());
    w.put("state", m.state);
    w.put("generation", m.generation);
    w.put("deadline", m.deadline);
    w.put("backoff", m.backoff);
    w.put("started_once", m.started_once);
    w.put("reset_node_next", m.reset_node_next);
    w.put("reset_node_sent", m.reset_node_sent);
    w.put("boot_up_owed", m.boot_up_owed);
    w.put("probe_at", m.probe_at);
    w.put("probe_gap", m.probe_gap);
    w.put("held_since", m.held_since);
    w.put_list("held", m.held.size(), [&](std::size_t k) {
      w.put("frame", m.held[k].first);
      w.put("at", m.held[k].second);
    });
    w.put("reported.wrong_length", m.reported.wrong_length);
    w.put("reported.unknown_cob", m.reported.unknown_cob);
    w.put("reported.unknown_emcy", m.reported.unknown_emcy);
    w.put("reported.mismatches", m.reported.mismatches);
    w.put("counted.frames", m.counted.frames);
    w.put("counted.reboots_seen", m.counted.reboots_seen);
    w.put("counted.gateway_resets", m.counted.gateway_resets);
    w.put("poll_at", m.poll_at);
    w.put("last_heartbeat", m.last_heartbeat);
    const NodeDiagnostics& d = m.boot.diagnostics();
    {
      const canopen::StateWriter::Scope diag(w, "diagnostics");
      w.put("device_type", d.device_type);
      w.put("vendor_id", d.vendor_id);
      w.put("product_code", d.product_code);
      w.put("revision", d.revision);
      w.put("serial", d.serial);
      put_text(w, "device_name", d.device_name);
      put_text(w, "hardware_version", d.hardware_version);
      put_text(w, "software_version", d.software_version);
      w.put("error_register", d.error_register);
    }
    w.put_state("driver", *m.driver);
  });
}

void NetworkManager::import_state(const canopen::StateReader& r) {
  if (own_lss_ != 0 || client_scan_running() || !lss_.idle()) {
    throw std::logic_error("NetworkManager::import_state while LSS work is under way");
  }
  const canopen::StateReader c = r.in("counters");
  const NetworkCounters counters{c.get<std::uint64_t>("unknown_pdo"), c.get<std::uint64_t>("unknown_emcy"),
                                 c.get<std::uint64_t>("reboots_seen"), c.get<std::uint64_t>("gateway_resets")};
  std::size_t k = 0;
  r.read_list("nodes", nodes_.size(), [&](const canopen::StateReader& item) {
    Managed& m = *nodes_[k++];
    if (item.node_id("node") != m.settings.node) item.fail("node", "differs: the state is of another configuration");
    const auto state = item.get<std::uint8_t>("state");
    if (state > static_cast<std::uint8_t>(NodeState::Refused)) item.fail("state", "is no node state");
    // A node under configuration has a request on the wire or held: busy(), never exported.
    if (static_cast<NodeState>(state) == NodeState::Configuring && !item.has("held_since")) {
      item.fail("state", "is configuring with no start held: a boot under way is no state");
    }
    m.driver->import_state(item.in("driver"));
    m.state = static_cast<NodeState>(state);
    m.generation = item.get<std::uint64_t>("generation");
    m.deadline = item.optional_time("deadline");
    m.backoff = item.duration("backoff");
    m.started_once = item.get<bool>("started_once");
    m.reset_node_next = item.get<bool>("reset_node_next");
    m.reset_node_sent = item.get<bool>("reset_node_sent");
    m.boot_up_owed = item.get<bool>("boot_up_owed");
    m.probe_at = item.optional_time("probe_at");
    m.probe_gap = item.duration("probe_gap");
    m.held_since = item.optional_time("held_since");
    m.held.clear();
    // The last PDO per COB-ID the driver consumes (on_frame, Starting).
    item.read_list("held", m.driver->consumed_cob_ids().size(),
                   [&](const canopen::StateReader& h) { m.held.emplace_back(h.frame("frame"), h.time("at")); });
    const canopen::StateReader rep = item.in("reported");
    m.reported = InputCounters{rep.get<std::uint64_t>("wrong_length"), rep.get<std::uint64_t>("unknown_cob"),
                               rep.get<std::uint64_t>("unknown_emcy"), rep.get<std::uint64_t>("mismatches")};
    const canopen::StateReader cnt = item.in("counted");
    m.counted = NodeCounters{cnt.get<std::uint64_t>("frames"), cnt.get<std::uint64_t>("reboots_seen"),
                             cnt.get<std::uint64_t>("gateway_resets")};
    // Each of these states is judged or retried at its deadline (advance()); PDOs are held only
    // for a proof of life.
    const bool judged = m.state == NodeState::WaitingBootUp || m.state == NodeState::Configuring ||
                        m.state == NodeState::Starting || m.state == NodeState::Missing ||
                        m.state == NodeState::Refused;
    if (judged && !m.deadline)
      item.fail("deadline", "is missing: a " + std::string(to_string(m.state)) + " node waits for it");
    if (!m.held.empty() && m.state != NodeState::Starting)
      item.fail("held.count", "is not 0: PDOs are held only while starting");
    m.poll_at = item.optional_time("poll_at");
    m.poll_pending = false;
    m.step_held = false;
    m.last_heartbeat = item.optional_time("last_heartbeat");
    const canopen::StateReader d = item.in("diagnostics");
    m.boot.restore_diagnostics(NodeDiagnostics{
        .device_type = d.optional<std::uint32_t>("device_type"),
        .vendor_id = d.optional<std::uint32_t>("vendor_id"),
        .product_code = d.optional<std::uint32_t>("product_code"),
        .revision = d.optional<std::uint32_t>("revision"),
        .serial = d.optional<std::uint32_t>("serial"),
        .device_name = text(d, "device_name"),
        .hardware_version = text(d, "hardware_version"),
        .software_version = text(d, "software_version"),
        .error_register = d.optional<std::uint8_t>("error_register"),
    });
  });
  if (k != nodes_.size()) r.fail("nodes.count", "differs: the state is of another configuration");
  by_cob_.clear();
  r.read_list("routes", 4096, [&](const canopen::StateReader& item) {
    const auto cob = item.get<std::uint32_t>("cob");
    Managed* m = find(item.node_id("node"));
    if (m == nullptr) item.fail("node", "is no node of this configuration");
    const std::vector<std::uint32_t> consumed = m->driver->consumed_cob_ids();
    if (std::find(consumed.begin(), consumed.end(), cob) == consumed.end()) {
      item.fail("cob", "is no COB-ID that node's driver consumes");
    }
    if (!by_cob_.try_emplace(cob, m).second) item.fail("cob", "is routed twice");
  });
  counters_ = counters;
  now_ = r.time("now");
}

}  // namespace oegw::subdevices
