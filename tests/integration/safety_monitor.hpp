// An invariant monitor for the gateway's safety behaviour (docs/design/fault-policy.md), for
// tier-2 tests on the virtual buses with a simulated clock.
//
// It keeps its own account of every sub-device's proof of life from the downstream frames the
// gateway's interface carries (the gateway's NMT commands, the node's boot-up and heartbeats, the
// arrival of each TPDO), and its own account of what went upstream (every TPDO of the watched FEs,
// every EMCY 7000h/0000h naming a sub-device) and of what the gateway would publish on DDS/LCM
// (Gateway::status()/fields(), the values GatewayPublishing::publish_fe() builds its samples from,
// read on every on_fe_change and on every tick). It never asks the gateway's own lookup code what
// feeds what: the tables (which TPDO byte carries which FE field, which downstream TPDO carries
// the signal, the COB-IDs, the deadlines) are written by the test from the mapping file it wrote
// and the CiA 852 / device-document layouts (Knowledge below).
//
// Invariants (each violation is an ADD_FAILURE with the simulated time and a reason):
//  (1) LIVE WITHOUT PROOF. An upstream TPDO, a published sample or the gateway's current field
//      shows an input FE field at a non-fault value while its sub-device lacks current proof of
//      life and has lacked it for longer than `grace`: proof = the gateway sent NMT start to the
//      node, a heartbeat reporting operational (05h) arrived after it, within the consumer time,
//      and no later heartbeat/boot-up reported another state; and the TPDO carrying that signal
//      arrived after the NMT start and within its freshness deadline (3 x event timer; none for
//      an on-change-only TPDO). The same for the FE status: not `valid` past the grace.
//  (2) LOST AND SILENT. A contract deadline passed (no 05h heartbeat within the consumer time of
//      NMT start; the consumer time since the last 05h heartbeat; a heartbeat in another state
//      once operational; the PDO freshness deadline, counted from NMT start when no PDO came;
//      a boot-up (reboot / NMT reset) not followed by proof of life within `reboot_report`) and,
//      `grace` later, no EMCY 7000h naming the node is active upstream. Also: an EMCY clearing
//      the node's fault (0000h naming it) while the node has no heartbeat proof of life.
//  A sub-device's own EMCY the gateway passes upstream (remote EMCY, gateway/oe_device.hpp: its
//  code, then its node-ID, register and manufacturer bytes 0..2) names no fault of the gateway's:
//  the monitor recognises it from the sub-device's frame it saw downstream and leaves it out.
//  (3) UNCOMMANDED OUTPUT. An RPDO the gateway sends to a sub-device carries, for the bits bound
//      to an indicator FE, a state nobody commanded: allowed are the current and the previous
//      commanded state (the test reports each command as it issues it) and their CiA 401 error
//      states (6206h/6207h as the test configured them). After a host heartbeat loss (EMCY 8130h
//      upstream) the error state must reach an operational node within `grace`.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "canopen/io/virtual_bus.hpp"
#include "gateway/gateway.hpp"

namespace oegw::testing::safety {

using canopen::CanFrame;
using canopen::Duration;
using canopen::TimePoint;
using canopen::io::BusRecord;
using mapping::FeId;
using namespace std::chrono_literals;

// ---- What the test knows (written from the mapping file and the documents, never looked up) ----

struct DownTpdo {
  std::uint32_t cob = 0;
  Duration deadline{0};  // 0: on change only, no freshness deadline
};

struct NodeKnowledge {
  std::string name;
  std::uint8_t id = 0;
  Duration consumer{150ms};  // heartbeat consumer time (1.5 x heartbeat_ms)
  std::vector<DownTpdo> tpdos;
};

// One input field of an FE in its upstream TPDO: `bytes` little-endian bytes at `byte` (signed),
// or one bit when `bit` >= 0. `source` = the downstream TPDO that carries its signal.
struct UpField {
  std::string name;  // the FE field ("x", "buttons[1]", "position", "switch[3]")
  std::size_t byte = 0;
  std::size_t bytes = 2;
  int bit = -1;
  std::int64_t fault = 0;
  std::uint8_t node = 0;
  std::uint32_t source = 0;
};

struct UpFe {
  FeId fe;
  std::uint32_t cob = 0;  // the upstream TPDO the host enabled for it
  std::vector<UpField> fields;
};

// An indicator FE driving a sub-device's outputs through one RPDO. `bits[k]` = where FE bit k
// (indicator[k+1]) lands in the RPDO: byte, bit position and width (1: a plain bit, 2: the elobau
// 2-bit LED code 00 off / 01 on / 11 no change).
struct OutBit {
  std::size_t byte = 0;
  unsigned shift = 0;
  unsigned width = 1;
};
struct OutFe {
  FeId fe;
  std::uint8_t node = 0;
  std::uint32_t rpdo = 0;
  std::vector<OutBit> bits;  // FE bit k -> frame position
};

struct Knowledge {
  std::uint8_t gateway_node = 0x20;
  std::vector<NodeKnowledge> nodes;
  std::vector<UpFe> inputs;
  std::vector<OutFe> outputs;
};

// ---- The monitor ----------------------------------------------------------------------------

class Monitor {
 public:
  struct Options {
    Duration grace{2ms};             // processing grace: 1 ms + the 1 ms tick of the harness
    Duration reboot_report{1000ms};  // a boot-up not followed by proof of life within this: EMCY due
    std::size_t max_reports = 8;     // ADD_FAILUREs per test; later violations are only counted
    bool inputs = true;              // invariants (1) and (2); false: outputs only (3)
  };

  Monitor(Knowledge k, Options o) : k_(std::move(k)), o_(o) {
    for (const auto& n : k_.nodes) nodes_[n.id] = NodeState{&n};
    for (const auto& f : k_.outputs) outs_[f.rpdo] = OutState{&f};
  }

  // Context printed with each violation (the cell, the seed and step ...).
  std::function<std::string()> context;
  // Called once per violation (the random test records the step).
  std::function<void(const std::string&)> on_violation;

  [[nodiscard]] std::size_t violations() const { return violations_; }
  [[nodiscard]] const std::vector<std::string>& reports() const { return reports_; }
  void enable(bool on) { enabled_ = on; }

  // ---- Feeds ----
  // A frame the gateway's downstream interface carried (sent or received). `from_gateway` = the
  // gateway sent it.
  void on_downstream(const BusRecord& r, bool from_gateway) {
    const TimePoint t = r.time;
    refresh(t);  // what was alive up to this instant stays recorded as alive
    const CanFrame& f = r.frame;
    if (f.id == 0 && f.dlc >= 2 && from_gateway) {
      const std::uint8_t cs = f.data[0], target = f.data[1];
      for (auto& [id, n] : nodes_) {
        if (target != 0 && target != id) continue;
        if (cs == 0x01) {
          n.start = t;
          n.lapsed = false;
          n.op_hb.reset();
          n.first_op.reset();
          n.bad_state.reset();
          n.pdo.clear();
          n.lost_reported = false;
        } else if (cs == 0x81 || cs == 0x82 || cs == 0x02 || cs == 0x80) {
          n.start.reset();  // the gateway itself took it out of operational
        }
      }
    }
    if (f.id >= 0x701 && f.id <= 0x77F && f.dlc == 1) {
      auto it = nodes_.find(static_cast<std::uint8_t>(f.id - 0x700));
      if (it != nodes_.end()) {
        NodeState& n = it->second;
        const std::uint8_t s = f.data[0];
        if (s == 0x00) {
          n.bootup = t;
          n.start.reset();
          n.op_hb.reset();
          n.pdo.clear();
        } else if (n.start) {
          if (s == 0x05) {
            if (!n.bad_state) n.op_hb = t;
            if (!n.first_op) n.first_op = t;
          } else if (n.op_hb && !n.bad_state) {
            n.bad_state = t;  // once operational, another state is a loss
          }
          // While `starting` another state is ignored (contract point 1, finding 2).
        }
      }
    }
    for (auto& [id, n] : nodes_)
      for (const auto& p : n.k->tpdos)
        if (p.cob == f.id && n.start && !from_gateway) n.pdo[p.cob] = t;
    // A sub-device's EMCY: the frame the gateway forwards for it, byte 2 (the gateway's 1001h)
    // aside.
    if (!from_gateway && f.id > 0x80 && f.id < 0x100 && f.dlc == 8 &&
        nodes_.count(static_cast<std::uint8_t>(f.id - 0x80)))
      forwards_.push_back({f.data[0], f.data[1], 0, static_cast<std::uint8_t>(f.id - 0x80), f.data[2], f.data[3],
                           f.data[4], f.data[5]});
    if (from_gateway) check_output(f, t);
    refresh(t);
  }

  // A frame on the upstream bus.
  void on_upstream(const BusRecord& r, const gateway::Gateway& gw) {
    const TimePoint t = r.time;
    refresh(t);
    const CanFrame& f = r.frame;
    if (f.id == 0x700u + k_.gateway_node && f.dlc == 1) gw_operational_ = f.data[0] == 0x05;
    if (f.id == 0 && f.dlc >= 2 && (f.data[1] == k_.gateway_node || f.data[1] == 0))
      gw_operational_ = f.data[0] == 0x01;
    const auto forward = std::find_if(forwards_.begin(), forwards_.end(), [&](const std::array<std::uint8_t, 8>& b) {
      for (std::size_t i = 0; i < 8; ++i)
        if (i != 2 && b[i] != f.data[i]) return false;
      return true;
    });
    const bool forwarded = f.id == 0x80u + k_.gateway_node && f.dlc == 8 && forward != forwards_.end();
    if (forwarded) forwards_.erase(forward);
    if (f.id == 0x80u + k_.gateway_node && f.dlc == 8 && !forwarded) {
      const std::uint16_t code = static_cast<std::uint16_t>(f.data[0] | (f.data[1] << 8));
      const std::uint8_t named = f.data[3];
      if (code == 0x8130) {
        host_lost(t);
        gw_operational_ = false;  // 1029h:01 = 0 (default): pre-operational on the loss
      }
      auto it = nodes_.find(named);
      auto note = [&](NodeState& n, bool raise) {
        // Evidence: the heartbeat proof, and no deadline of the contract overdue (a PDO).
        const auto due = emcy_due(n, t);
        if (!raise && n.emcy && (!hb_alive(n, t) || due))
          violation(t, fmt::format("EMCY {} clears {} (node {:02X}h) without proof of life: {}{}", f.to_string(),
                                   n.k->name, n.k->id, life_text(n, t), due ? "; overdue: " + *due : std::string()));
        n.emcy = raise;
        n.emcy_log.push_back({t, raise});
      };
      if ((code == 0x7000 || code == 0x0000) && it != nodes_.end()) {
        note(it->second, code == 0x7000);
      } else if (code == 0x0000 && (f.data[2] & 0x01) == 0) {
        // The error reset of the last active error (the EMCY producer's own 0000h, no name):
        // every sub-device fault is cleared. If only 7000h was active, this frame IS the clear
        // of the (last) sub-device fault: evidence needed as for a named one. If another error
        // (e.g. 8130h) was active too, the sub-device fault may have ended silently before (the
        // producer says nothing while errors remain): then it is wrong only for a node that is
        // past a deadline of the contract now.
        const bool only_7000 =
            std::all_of(active_codes_.begin(), active_codes_.end(), [](std::uint16_t c) { return c == 0x7000; });
        for (auto& [id, n] : nodes_) {
          if (!n.emcy) continue;
          if (only_7000) {
            note(n, false);
            continue;
          }
          if (const auto due = emcy_due(n, t))
            violation(t, fmt::format("EMCY {} (no error left) while {} (node {:02X}h) is lost: {}", f.to_string(),
                                     n.k->name, n.k->id, *due));
          n.emcy = false;
          n.emcy_log.push_back({t, false});
        }
        active_codes_.clear();
      }
      if (code != 0x0000) active_codes_.insert(code);
    }
    for (const auto& fe : k_.inputs) {
      if (f.id != fe.cob) continue;
      for (const auto& fld : fe.fields) {
        const std::int64_t v = decode(f, fld);
        up_last_[{fe.cob, fld.name}] = v;
        if (v != fld.fault && !proven(fld, t))
          violation(t, fmt::format("upstream TPDO {} shows {} {} = {} (fault value {}) without proof of life of "
                                   "node {:02X}h: {}",
                                   f.to_string(), mapping::fe_name(fe.fe), fld.name, v, fld.fault, fld.node,
                                   field_life_text(fld, t)));
      }
    }
    (void)gw;
  }

  // A sample the publishers would build now (on_fe_change).
  void on_sample(FeId fe, const gateway::Gateway& gw, TimePoint t) {
    refresh(t);
    for (const auto& ufe : k_.inputs)
      if (ufe.fe == fe) check_fe(ufe, gw, t, "published sample");
  }

  // The harness's tick (every 1 ms): time-based checks.
  void tick(const gateway::Gateway& gw, TimePoint t) {
    refresh(t);
    for (const auto& ufe : k_.inputs) {
      // While every field is proven nothing the gateway shows can be wrong: skip the queries.
      if (std::any_of(ufe.fields.begin(), ufe.fields.end(), [&](const UpField& f) { return !proven(f, t); }))
        check_fe(ufe, gw, t, "gateway state (the next DDS/LCM sample)");
      for (const auto& fld : ufe.fields) {
        // While the gateway is not operational upstream it sends no PDO (CiA 301) and the host
        // knows it from its heartbeat; when it is operational again it must send the values.
        auto it = up_last_.find({ufe.cob, fld.name});
        if (gw_operational_ && it != up_last_.end() && it->second != fld.fault && !proven(fld, t))
          violation(t,
                    fmt::format("the last upstream TPDO still shows {} {} = {} without proof of life of node "
                                "{:02X}h: {}",
                                mapping::fe_name(ufe.fe), fld.name, it->second, fld.node, field_life_text(fld, t)),
                    /*once_key=*/"stuck " + mapping::fe_name(ufe.fe) + fld.name);
      }
    }
    for (auto& [id, n] : nodes_) {
      const auto due = emcy_due(n, t);
      if (due && !n.emcy && !n.lost_reported) {
        n.lost_reported = true;
        violation(t, fmt::format("no EMCY 7000h naming {} (node {:02X}h) {} ms after the deadline: {}", n.k->name, id,
                                 ms(o_.grace), *due));
      }
      if (!due) n.lost_reported = false;
    }
    for (auto& [cob, o] : outs_) {
      if (o.expect && o.expect_after_restart) {
        const NodeState& n = nodes_.at(o.k->node);
        if (!(n.start && *n.start >= o.lost_at && n.first_op)) continue;
        o.expect_by = *n.first_op + o_.grace;
        o.expect_after_restart = false;
      }
      // Sent in the same call that noticed the loss, before the EMCY reached the bus, but into
      // a dead interface: the gateway did what it could.
      if (o.expect && o.last_attempt == *o.expect && o.last_attempt_time >= o.lost_at) o.expect.reset();
      if (o.expect && t > o.expect_by && o.last_sent != *o.expect && node_driven(o.k->node, t)) {
        violation(t,
                  fmt::format("host heartbeat lost: {} should show its error state {:02X}h on RPDO {:03X}h "
                              "by {}, the device got {}",
                              mapping::fe_name(o.k->fe), *o.expect, cob, at(o.expect_by),
                              o.last_sent ? fmt::format("{:02X}h", *o.last_sent) : std::string("nothing")),
                  {}, /*input=*/false);
        o.expect.reset();
      }
    }
  }

  // A frame the gateway sent while its downstream interface was down (lost before the bus): it
  // did what it could — an error state it carried counts as applied (the node, restarted when
  // the interface is back, gets the current outputs again).
  void sent_into_dead_interface(const CanFrame& f, TimePoint t) {
    auto it = outs_.find(f.id);
    if (it == outs_.end()) return;
    OutState& o = it->second;
    o.last_attempt = decode_state(o, f, o.last_sent.value_or(0));
    o.last_attempt_time = t;
    if (o.expect && *o.last_attempt == *o.expect) o.expect.reset();
  }

  // ---- What the test did (for invariant 3) ----
  // `by_rpdo`: the host's RPDO, which the gateway applies only while operational (its heartbeat,
  // the host's NMT commands and 1029h on a host heartbeat loss tell the monitor its state).
  void commanded(FeId fe, std::uint64_t bits, TimePoint, bool by_rpdo = false) {
    if (by_rpdo && !gw_operational_) return;  // not a command: CiA 301 processes no PDO then
    for (auto& [cob, o] : outs_)
      if (o.k->fe == fe) {
        o.previous = o.current;
        o.current = bits & mask(*o.k);
        o.expect.reset();
      }
  }
  void error_config(FeId fe, std::uint64_t mode, std::uint64_t value) {
    for (auto& [cob, o] : outs_)
      if (o.k->fe == fe) {
        o.mode = mode;
        o.value = value;
      }
  }

  // ---- Queries for the cells ----
  [[nodiscard]] bool alive(std::uint8_t node, TimePoint t) const { return node_hb_alive(node, t); }
  // A 7000h naming `node` active upstream at `t` (from the frames seen).
  [[nodiscard]] bool emcy_active_at(std::uint8_t node, TimePoint t) const {
    auto it = nodes_.find(node);
    if (it == nodes_.end()) return false;
    bool active = false;
    for (const auto& e : it->second.emcy_log)
      if (e.time <= t) active = e.raise;
    return active;
  }
  [[nodiscard]] std::optional<TimePoint> first_emcy(std::uint8_t node, bool raise, TimePoint from) const {
    auto it = nodes_.find(node);
    if (it == nodes_.end()) return std::nullopt;
    for (const auto& e : it->second.emcy_log)
      if (e.time >= from && e.raise == raise) return e.time;
    return std::nullopt;
  }
  [[nodiscard]] std::size_t emcy_count(std::uint8_t node, bool raise, TimePoint from) const {
    auto it = nodes_.find(node);
    if (it == nodes_.end()) return 0;
    return static_cast<std::size_t>(std::count_if(it->second.emcy_log.begin(), it->second.emcy_log.end(),
                                                  [&](const auto& e) { return e.time >= from && e.raise == raise; }));
  }
  [[nodiscard]] std::optional<TimePoint> last_start(std::uint8_t node) const { return nodes_.at(node).start; }
  [[nodiscard]] std::string life(std::uint8_t node, TimePoint t) const { return life_text(nodes_.at(node), t); }
  void set_epoch(TimePoint t0) { t0_ = t0; }
  [[nodiscard]] std::string at(TimePoint t) const { return fmt::format("t={} ms", ms(t - t0_)); }

 private:
  struct EmcyEvent {
    TimePoint time;
    bool raise;
  };
  struct NodeState {
    const NodeKnowledge* k = nullptr;
    std::optional<TimePoint> start;          // the gateway's last NMT start to it (reset: none)
    std::optional<TimePoint> op_hb;          // last 05h heartbeat after `start`
    std::optional<TimePoint> first_op;       // first 05h heartbeat after `start` (the proof: live from here)
    std::optional<TimePoint> bad_state;      // a heartbeat in another state after being operational
    std::optional<TimePoint> bootup;         // its last boot-up
    std::map<std::uint32_t, TimePoint> pdo;  // arrival of each TPDO after `start`
    bool emcy = false;                       // 7000h naming it active upstream
    std::vector<EmcyEvent> emcy_log;
    bool lost_reported = false;
    bool lapsed = false;  // its proof lapsed since `start`: the gateway must restart it first
    std::map<std::uint32_t, TimePoint> fresh_until;  // per TPDO: last time it was seen proven
    std::optional<TimePoint> hb_proven_at;           // last time the heartbeat proof held
  };
  struct OutState {
    const OutFe* k = nullptr;
    std::uint64_t current = 0, previous = 0;
    std::uint64_t mode = 0, value = 0;
    std::optional<std::uint64_t> last_sent;
    std::optional<std::uint64_t> expect;
    TimePoint expect_by{};
    bool expect_after_restart = false;
    TimePoint lost_at{};
    std::optional<std::uint64_t> last_attempt;  // sent into a dead interface
    TimePoint last_attempt_time{};
  };

  static long ms(Duration d) {
    return static_cast<long>(std::chrono::duration_cast<std::chrono::milliseconds>(d).count());
  }

  // The first 05h heartbeat after NMT start came within the consumer time (else the node is
  // `missing` by contract until the gateway starts it again).
  [[nodiscard]] bool started_in_time(const NodeState& n) const {
    return n.start && n.first_op && *n.first_op - *n.start <= n.k->consumer;
  }
  [[nodiscard]] bool hb_alive(const NodeState& n, TimePoint t) const {
    return started_in_time(n) && n.op_hb && !n.bad_state && *n.op_hb >= *n.start && t - *n.op_hb <= n.k->consumer;
  }
  [[nodiscard]] bool node_hb_alive(std::uint8_t node, TimePoint t) const {
    auto it = nodes_.find(node);
    return it != nodes_.end() && hb_alive(it->second, t);
  }
  // Alive and never lapsed since the gateway started it: one the gateway can drive now (a node
  // whose heartbeat came back by itself is restarted by the gateway first).
  [[nodiscard]] bool node_driven(std::uint8_t node, TimePoint t) const {
    auto it = nodes_.find(node);
    return it != nodes_.end() && hb_alive(it->second, t) && !it->second.lapsed;
  }
  [[nodiscard]] bool pdo_fresh(const NodeState& n, std::uint32_t cob, TimePoint t) const {
    for (const auto& p : n.k->tpdos) {
      if (p.cob != cob) continue;
      auto it = n.pdo.find(cob);
      if (it == n.pdo.end()) return false;  // not since NMT start: nothing to vouch for the value
      return p.deadline == Duration{0} || t - it->second <= p.deadline;
    }
    return false;
  }
  [[nodiscard]] bool field_alive(const UpField& f, TimePoint t) const {
    const NodeState& n = nodes_.at(f.node);
    return hb_alive(n, t) && pdo_fresh(n, f.source, t);
  }
  // Alive now, or alive no longer than `grace` ago.
  [[nodiscard]] bool proven(const UpField& f, TimePoint t) const {
    if (field_alive(f, t)) return true;
    const NodeState& n = nodes_.at(f.node);
    auto it = n.fresh_until.find(f.source);
    return it != n.fresh_until.end() && t - it->second <= o_.grace;
  }
  // Records, up to `t`, the last instant each proof held (called before and after every event).
  void refresh(TimePoint t) {
    for (auto& [id, n] : nodes_) {
      if (hb_alive(n, t)) n.hb_proven_at = t;
      if (n.start && (n.first_op || t - *n.start > n.k->consumer) && !hb_alive(n, t)) n.lapsed = true;
      for (const auto& p : n.k->tpdos)
        if (hb_alive(n, t) && pdo_fresh(n, p.cob, t)) n.fresh_until[p.cob] = t;
    }
  }

  // When a contract deadline has passed `grace` ago with the node still lost: the reason.
  [[nodiscard]] std::optional<std::string> emcy_due(const NodeState& n, TimePoint t) const {
    const Duration g = o_.grace;
    if (n.bootup && (!n.start || *n.start < *n.bootup) && t - *n.bootup > o_.reboot_report + g)
      return fmt::format("boot-up at {} and no NMT start since", at(*n.bootup));
    if (!n.start) return std::nullopt;
    if (n.bad_state && t - *n.bad_state > g) return fmt::format("a heartbeat in another state at {}", at(*n.bad_state));
    if (!started_in_time(n) && t - *n.start > n.k->consumer + g)
      return fmt::format("NMT start at {} and no heartbeat in operational within {} ms", at(*n.start),
                         ms(n.k->consumer));
    if (n.op_hb && t - *n.op_hb > n.k->consumer + g)
      return fmt::format("last heartbeat in operational at {} (consumer time {} ms)", at(*n.op_hb), ms(n.k->consumer));
    for (const auto& p : n.k->tpdos) {
      if (p.deadline == Duration{0}) continue;
      auto it = n.pdo.find(p.cob);
      // No PDO yet: the deadline runs from the proof of life (the first 05h heartbeat after NMT
      // start, when the gateway takes the node's inputs as live); before it the heartbeat rule
      // above applies.
      // A PDO already overdue at the proof of life is due from the proof of life.
      if (!n.first_op) continue;
      const TimePoint from = it == n.pdo.end() ? *n.first_op : it->second;
      if (t - std::max(from + p.deadline, *n.first_op) > g)
        return fmt::format("TPDO {:03X}h {} (deadline {} ms)", p.cob,
                           it == n.pdo.end()
                               ? "not received since the first heartbeat in operational at " + at(*n.first_op)
                               : "last received at " + at(it->second),
                           ms(p.deadline));
    }
    return std::nullopt;
  }

  void check_fe(const UpFe& ufe, const gateway::Gateway& gw, TimePoint t, const char* what) {
    bool any_lost = false;
    const auto fields = gw.fields(ufe.fe);
    for (const auto& fld : ufe.fields) {
      if (!proven(fld, t)) any_lost = true;
      // What the host reads by SDO (the upstream dictionary) is what the FE model holds, and
      // without proof of life it is the fault value too.
      const auto od = gw.upstream().get(ufe.fe, fld.name);
      for (const auto& s : fields)
        if (s.name == fld.name && od && *od != s.value)
          violation(t,
                    fmt::format("{}: {} {} = {} in the FE model but {} in the dictionary", what,
                                mapping::fe_name(ufe.fe), fld.name, s.value, *od),
                    "dictionary " + mapping::fe_name(ufe.fe) + fld.name);
      if (od && *od != fld.fault && !proven(fld, t))
        violation(t,
                  fmt::format("{}: {} {} reads {} in the dictionary (fault value {}) without proof of life of node "
                              "{:02X}h: {}",
                              what, mapping::fe_name(ufe.fe), fld.name, *od, fld.fault, fld.node,
                              field_life_text(fld, t)),
                  "dictionary " + mapping::fe_name(ufe.fe) + fld.name);
      for (const auto& s : fields) {
        if (s.name != fld.name || s.value == fld.fault || proven(fld, t)) continue;
        violation(t,
                  fmt::format("{}: {} {} = {} (fault value {}) without proof of life of node {:02X}h: {}", what,
                              mapping::fe_name(ufe.fe), fld.name, s.value, fld.fault, fld.node,
                              field_life_text(fld, t)),
                  "sample " + mapping::fe_name(ufe.fe) + fld.name);
      }
    }
    if (any_lost && gw.status(ufe.fe) == gateway::FeStatus::Valid) {
      const UpField* lost = nullptr;
      for (const auto& fld : ufe.fields)
        if (!proven(fld, t)) lost = &fld;
      violation(t,
                fmt::format("{}: {} status valid while {} has no proof of life: {}", what, mapping::fe_name(ufe.fe),
                            lost->name, field_life_text(*lost, t)),
                "status " + mapping::fe_name(ufe.fe));
    }
  }

  [[nodiscard]] std::string life_text(const NodeState& n, TimePoint t) const {
    auto opt = [this](const std::optional<TimePoint>& x) { return x ? at(*x) : std::string("none"); };
    return fmt::format("now {}; NMT start {}, last 05h heartbeat {}, other state {}, boot-up {}", at(t), opt(n.start),
                       opt(n.op_hb), opt(n.bad_state), opt(n.bootup));
  }
  [[nodiscard]] std::string field_life_text(const UpField& f, TimePoint t) const {
    const NodeState& n = nodes_.at(f.node);
    auto it = n.pdo.find(f.source);
    return life_text(n, t) + fmt::format(", TPDO {:03X}h {}", f.source,
                                         it == n.pdo.end() ? std::string("not since NMT start") : at(it->second));
  }

  static std::int64_t decode(const CanFrame& f, const UpField& fld) {
    if (fld.byte + fld.bytes > f.dlc) return fld.fault;
    if (fld.bit >= 0) return (f.data[fld.byte] >> fld.bit) & 1;
    std::uint64_t v = 0;
    for (std::size_t i = 0; i < fld.bytes; ++i) v |= std::uint64_t{f.data[fld.byte + i]} << (8 * i);
    const unsigned bits = static_cast<unsigned>(8 * fld.bytes);
    if (bits < 64 && (v >> (bits - 1)) & 1) v |= ~std::uint64_t{0} << bits;  // sign-extend
    return static_cast<std::int64_t>(v);
  }

  static std::uint64_t mask(const OutFe& o) { return o.bits.size() >= 64 ? ~0ull : (1ull << o.bits.size()) - 1; }
  [[nodiscard]] static std::uint64_t error_state(const OutState& o, std::uint64_t s) {
    return ((s & ~o.mode) | (o.value & o.mode)) & mask(*o.k);
  }

  void host_lost(TimePoint t) {
    for (auto& [cob, o] : outs_) {
      o.expect = error_state(o, o.current);
      // A node alive now gets it in the same call; a node the gateway must first restart gets
      // it when it is proven alive again (first 05h heartbeat after its next NMT start).
      o.expect_by = t + o_.grace;
      o.expect_after_restart = !node_driven(o.k->node, t);
      o.lost_at = t;
      o.previous = o.current;
      o.current = *o.expect;  // what the outputs hold from now on
    }
  }

  static std::uint64_t decode_state(const OutState& o, const CanFrame& f, std::uint64_t state) {
    for (std::size_t k = 0; k < o.k->bits.size(); ++k) {
      const OutBit& b = o.k->bits[k];
      if (b.byte >= f.dlc) continue;
      const unsigned code = (f.data[b.byte] >> b.shift) & ((1u << b.width) - 1);
      if (b.width == 2 && code == 3) continue;  // elobau "no change"
      state = code != 0 ? (state | (1ull << k)) : (state & ~(1ull << k));
    }
    return state;
  }

  void check_output(const CanFrame& f, TimePoint t) {
    auto it = outs_.find(f.id);
    if (it == outs_.end()) return;
    OutState& o = it->second;
    const std::uint64_t state = decode_state(o, f, o.last_sent.value_or(0));
    o.last_sent = state;
    const std::uint64_t allowed[] = {o.current, o.previous, error_state(o, o.current), error_state(o, o.previous)};
    if (std::find(std::begin(allowed), std::end(allowed), state) == std::end(allowed))
      violation(t,
                fmt::format("RPDO {} to node {:02X}h carries {} = {:02X}h, which nobody commanded (commanded "
                            "{:02X}h, before it {:02X}h; error mode {:02X}h value {:02X}h)",
                            f.to_string(), o.k->node, mapping::fe_name(o.k->fe), state, o.current, o.previous, o.mode,
                            o.value),
                {}, /*input=*/false);
    if (o.expect && state == *o.expect) o.expect.reset();
  }

  void violation(TimePoint t, const std::string& what, const std::string& once_key = {}, bool input = true) {
    if (!enabled_ || (input && !o_.inputs)) return;
    if (!once_key.empty()) {
      // A lasting condition is reported when it starts, not every tick.
      auto& last = once_[once_key];
      const bool continuing = last && t - *last <= 2ms;
      last = t;
      if (continuing) return;
    }
    ++violations_;
    const std::string line = fmt::format("[safety monitor {}] {}", at(t), what);
    if (on_violation) on_violation(line);
    if (reports_.size() < o_.max_reports) {
      reports_.push_back(line);
      ADD_FAILURE() << line << (context ? "\n  " + context() : std::string());
    }
  }

  Knowledge k_;
  Options o_;
  std::map<std::uint8_t, NodeState> nodes_;
  std::map<std::uint32_t, OutState> outs_;
  std::map<std::pair<std::uint32_t, std::string>, std::int64_t> up_last_;
  std::map<std::string, std::optional<TimePoint>> once_;
  std::size_t violations_ = 0;
  std::vector<std::string> reports_;
  bool enabled_ = true;
  bool gw_operational_ = false;
  std::set<std::uint16_t> active_codes_;               // EMCY codes the gateway has raised and not reset
  std::vector<std::array<std::uint8_t, 8>> forwards_;  // sub-device EMCYs the gateway will pass on
  TimePoint t0_{};
};

}  // namespace oegw::testing::safety
