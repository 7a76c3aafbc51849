#include "subdevices/bus_scan.hpp"

#include <algorithm>

namespace oegw::subdevices {

namespace {

using canopen::SdoAbortCode;

struct Read {
  std::uint16_t index;
  std::uint8_t sub;
};
// 1000h first: its answer (or time-out) decides whether anyone is there.
constexpr Read kReads[] = {{0x1000, 0}, {0x1018, 1}, {0x1018, 2}, {0x1018, 3}, {0x1018, 4}, {0x1017, 0}};
constexpr std::size_t kReadCount = sizeof kReads / sizeof kReads[0];

std::uint32_t le_value(const std::vector<std::uint8_t>& data) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < data.size() && i < 4; ++i) v |= static_cast<std::uint32_t>(data[i]) << (8 * i);
  return v;
}

bool is_heartbeat(const CanFrame& f) { return !f.extended && !f.rtr && f.dlc == 1 && f.id >= 0x701 && f.id <= 0x77F; }

std::optional<canopen::NmtState> nmt_state(std::uint8_t byte) {
  switch (byte & 0x7F) {  // bit 7: the node-guarding toggle, 0 in a heartbeat
    case 0x00: return canopen::NmtState::Initialisation;
    case 0x04: return canopen::NmtState::Stopped;
    case 0x05: return canopen::NmtState::Operational;
    case 0x7F: return canopen::NmtState::PreOperational;
    default: return std::nullopt;
  }
}

// A shared master's callback after the scanner ended (or while its destructor cancels).
bool gone(const std::weak_ptr<bool>& alive) {
  const auto a = alive.lock();
  return !a || !*a;
}

}  // namespace

BusScanner::BusScanner(FrameSink sink, ScanConfig config)
    : sink_(std::move(sink)), cfg_(config), own_lss_(sink_, config.lss_timeout) {
  cfg_.first = std::clamp<std::uint8_t>(cfg_.first, 1, 127);
  cfg_.last = std::clamp<std::uint8_t>(cfg_.last, cfg_.first, 127);
  cfg_.parallel = std::clamp<std::size_t>(cfg_.parallel, 1, 127);
}

BusScanner::BusScanner(FrameSink sink, ScanConfig config, std::function<SharedLss()> shared_lss)
    : BusScanner(std::move(sink), std::move(config)) {
  shared_lss_ = std::move(shared_lss);
}

BusScanner::~BusScanner() {
  *alive_ = false;
  if (fastscan_mine_ && fastscan_->running()) fastscan_->cancel("the scan ended");
}

ScannedNode& BusScanner::node(std::uint8_t id) {
  auto [it, fresh] = nodes_.try_emplace(id);
  if (fresh) it->second.node = NodeId{id};
  return it->second;
}

void BusScanner::start(TimePoint now) {
  start_ = now_ = now;
  phase_ = Phase::Probing;
  for (unsigned id = cfg_.first; id <= cfg_.last; ++id)
    if (!cfg_.skip.count(static_cast<std::uint8_t>(id))) pending_.push_back(static_cast<std::uint8_t>(id));
  total_ = pending_.size();
  while (active_.size() < cfg_.parallel && !pending_.empty()) {
    const std::uint8_t id = pending_.front();
    pending_.pop_front();
    launch(id, now);
  }
}

void BusScanner::launch(std::uint8_t id, TimePoint now) {
  auto cfg = canopen::SdoClientConfig::for_node(NodeId{id});
  cfg.timeout = cfg_.sdo_timeout;
  Probe& p = active_[id];
  p.sdo = std::make_unique<canopen::SdoClient>(sink_, cfg);
  read_next(id);
  p.sdo->advance(now);  // starts the queued upload
}

void BusScanner::read_next(std::uint8_t id) {
  Probe& p = active_.at(id);
  const Read r = kReads[p.step];
  p.sdo->upload(r.index, r.sub, [this, id, r](SdoAbortCode code, std::vector<std::uint8_t> data) {
    Probe& probe = active_.at(id);
    ScannedNode& n = node(id);
    if (code == SdoAbortCode::Timeout && probe.step == 0) {
      probe_ended(id);  // nobody at 1000h: absent (unless heard)
      return;
    }
    // A later time-out (a slow or busy node) leaves that value unknown; the reads go on.
    if (code != SdoAbortCode::Timeout) n.answered_sdo = true;
    if (code == SdoAbortCode::None && !data.empty()) {
      const std::uint32_t v = le_value(data);
      switch (r.index) {
        case 0x1000: n.identity.device_type = v; break;
        case 0x1017: n.producer_heartbeat_ms = static_cast<std::uint16_t>(v); break;
        default:
          switch (r.sub) {
            case 1: n.identity.vendor_id = v; break;
            case 2: n.identity.product_code = v; break;
            case 3: n.identity.revision = v; break;
            default: n.identity.serial = v; break;
          }
      }
    }
    if (++probe.step == kReadCount) {
      probe_ended(id);
      return;
    }
    read_next(id);
  });
}

// Called from an SDO callback: the client is still on the stack, so it is released later.
void BusScanner::probe_ended(std::uint8_t id) {
  active_.at(id).step = kReadCount + 1;  // marks it finished
  ended_ = true;
}

ScanProgress BusScanner::progress() const {
  ScanProgress p;
  p.probed = probed_;
  p.total = total_;
  for (const auto& [id, n] : nodes_) p.found += (n.answered_sdo || n.heard) ? 1 : 0;
  p.lss = lss_began_;
  return p;
}

void BusScanner::report() {
  if (on_progress) on_progress(progress());
}

bool BusScanner::on_frame(const CanFrame& f, TimePoint now) {
  now_ = now;
  if (phase_ == Phase::Idle || phase_ == Phase::Done) return false;
  if (is_heartbeat(f)) {
    const auto id = static_cast<std::uint8_t>(f.id - 0x700);
    ScannedNode& n = node(id);
    n.heard = true;
    if (f.data[0] == 0) {
      n.booted = true;  // a boot-up is not a heartbeat (CiA 301 §7.2.8.3.2.3): no period from it
      last_heartbeat_.erase(id);
    } else {
      if (auto s = nmt_state(f.data[0])) n.state = s;
      if (auto it = last_heartbeat_.find(id); it != last_heartbeat_.end()) {
        const Duration gap = now - it->second;
        if (!n.heartbeat_period || gap < *n.heartbeat_period) n.heartbeat_period = gap;
      }
      last_heartbeat_[id] = now;
    }
    return true;
  }
  if (!f.extended && f.id >= 0x581 && f.id <= 0x5FF) {
    const auto id = static_cast<std::uint8_t>(f.id - 0x580);
    auto it = active_.find(id);
    if (it == active_.end()) return false;
    it->second.sdo->on_frame(f, now);
    if (it->second.step < kReadCount) it->second.sdo->advance(now);  // starts the next read
    advance(now);
    return true;
  }
  // (a shared master has its frames from its owner, before this)
  if (phase_ == Phase::Lss && !lss_shared_ && lss_->on_frame(f, now)) {
    advance(now);
    return true;
  }
  return false;
}

void BusScanner::advance(TimePoint now) {
  now_ = now;
  if (phase_ == Phase::Probing) {
    for (auto& [id, p] : active_)
      if (p.step < kReadCount) p.sdo->advance(now);
    // Release the ended probes, start the next node-IDs.
    while (ended_) {
      ended_ = false;
      for (auto it = active_.begin(); it != active_.end();) {
        if (it->second.step <= kReadCount) {
          ++it;
          continue;
        }
        it = active_.erase(it);
        ++probed_;
        report();
      }
      while (active_.size() < cfg_.parallel && !pending_.empty()) {
        const std::uint8_t id = pending_.front();
        pending_.pop_front();
        launch(id, now);
      }
    }
    if (active_.empty() && pending_.empty()) after_probing(now);
  }
  if (phase_ == Phase::Lss) lss_->advance(now);
  if (phase_ == Phase::Listening && now >= start_ + cfg_.listen) phase_ = Phase::Done;
}

std::optional<TimePoint> BusScanner::next_deadline() const {
  switch (phase_) {
    case Phase::Probing: {
      std::optional<TimePoint> d;
      for (const auto& [id, p] : active_) {
        if (p.step >= kReadCount) return now_;  // ended: release it now
        if (auto t = p.sdo->next_deadline(); t && (!d || *t < *d)) d = t;
      }
      return d;
    }
    case Phase::Lss: return lss_->next_deadline();
    case Phase::Listening: return std::max(start_ + cfg_.listen, now_);
    default: return std::nullopt;
  }
}

void BusScanner::after_probing(TimePoint now) {
  if (!cfg_.lss) {
    phase_ = Phase::Listening;
    return;
  }
  std::optional<Duration> step_timeout;
  if (shared_lss_) {
    const SharedLss shared = shared_lss_();
    std::string why_not = shared.why_not;
    if ((shared.master == nullptr || shared.fastscan == nullptr) && why_not.empty()) why_not = "no LSS master";
    if (why_not.empty() && shared.fastscan->running()) why_not = "another client's fastscan is running";
    if (!why_not.empty()) {
      lss_result_.lss_note = "LSS skipped: " + why_not;
      phase_ = Phase::Listening;
      return;
    }
    lss_ = shared.master;
    fastscan_ = shared.fastscan;
    lss_shared_ = true;
    step_timeout = cfg_.lss_timeout;  // the shared master's own time-out is its owner's
  }
  phase_ = Phase::Lss;
  lss_began_ = true;
  report();
  // Callbacks of a shared master may come after this scanner is gone; they take the master's time
  // (its owner fed it the answer, before this scanner saw the frame).
  const std::weak_ptr<bool> alive = alive_;
  lss_->identify_non_configured(now, [this, alive, step_timeout](const canopen::LssMaster::Result& r) {
    if (gone(alive)) return;
    if (r.status != canopen::LssMaster::Status::Ok) {
      lss_ended(lss_->now());
      return;
    }
    lss_result_.unconfigured = true;
    fastscan_mine_ = true;
    fastscan_->start(
        lss_->now(),
        [this, alive](const canopen::LssFastscan::Result& f) {
          if (gone(alive)) return;
          fastscan_mine_ = false;
          if (!f.address) {
            lss_result_.lss_note = f.note;
            lss_ended(lss_->now());
            return;
          }
          lss_result_.unconfigured_address = f.address;
          // The last step selected it (LSS configuration mode): back to waiting, node-ID unchanged.
          lss_->switch_state_global(canopen::lss::Mode::Waiting, lss_->now(),
                                    [this, alive](const canopen::LssMaster::Result&) {
                                      if (!gone(alive)) lss_ended(lss_->now());
                                    });
        },
        step_timeout);
  });
}

void BusScanner::lss_ended(TimePoint now) {
  phase_ = Phase::Listening;
  if (now >= start_ + cfg_.listen) phase_ = Phase::Done;
  if (lss_shared_ && on_wake) on_wake();
}

ScanResult BusScanner::result() const {
  ScanResult r = lss_result_;
  for (const auto& [id, n] : nodes_) {
    if (!n.answered_sdo && !n.heard) continue;
    ScannedNode out = n;
    out.family = name_family(n.identity);
    r.nodes.push_back(std::move(out));
  }
  return r;
}

}  // namespace oegw::subdevices
