#include "subdevices/driver.hpp"

#include <algorithm>
#include <stdexcept>

#include "canopen/state.hpp"

namespace oegw::subdevices {

std::string_view to_string(SignalStatus s) {
  switch (s) {
    case SignalStatus::Valid: return "valid";
    case SignalStatus::Error: return "error";
    case SignalStatus::NotAvailable: return "not available";
    case SignalStatus::Stale: return "stale";
    case SignalStatus::Offline: return "offline";
  }
  return "unknown";
}

SignalStatus get_signal_status(const canopen::StateReader& r, std::string_view key) {
  const auto status = r.get<std::uint8_t>(key);
  if (status > static_cast<std::uint8_t>(SignalStatus::Offline)) r.fail(key, "is no signal status");
  return static_cast<SignalStatus>(status);
}

std::string_view to_string(SignalKind k) {
  switch (k) {
    case SignalKind::Axis: return "axis";
    case SignalKind::Button: return "button";
    case SignalKind::Position: return "position";
    case SignalKind::Speed: return "speed";
    case SignalKind::Digital: return "digital";
    case SignalKind::Analog: return "analog";
    case SignalKind::Output: return "output";
  }
  return "unknown";
}

std::optional<std::size_t> Driver::find_signal(std::string_view name) const {
  const auto& s = signals();
  for (std::size_t i = 0; i < s.size(); ++i)
    if (s[i].name == name) return i;
  return std::nullopt;
}

void Driver::init(NodeId node, FrameSink sink, std::size_t signal_count) {
  node_ = node;
  sink_ = std::move(sink);
  values_.assign(signal_count, SignalValue{});
  faults_.assign(signal_count, false);
  fault_count_ = 0;
  rebuild_deadlines();
}

void Driver::set_fault(std::size_t index, std::optional<TimePoint> now) {
  if (index >= faults_.size()) return;
  if (!faults_[index]) {
    faults_[index] = true;
    ++fault_count_;
  }
  if (!now) return;
  const SignalValue& v = values_[index];
  update(index, v.value, v.status == SignalStatus::Offline ? SignalStatus::Offline : SignalStatus::Error, *now);
}

void Driver::clear_fault(std::size_t index) {
  if (index >= faults_.size() || !faults_[index]) return;
  faults_[index] = false;
  --fault_count_;
}

void Driver::clear_all_faults() {
  faults_.assign(faults_.size(), false);
  fault_count_ = 0;
}

void Driver::on_application_reset(TimePoint /*now*/) { clear_all_faults(); }

void Driver::update_checked(std::size_t index, std::int64_t value, SignalStatus status, TimePoint now) {
  // A value whose carrier PDO is overdue stays Stale, whatever frame republishes it; so does a
  // signal that loses its value (an error reset) while the node is alive and its PDO overdue.
  if ((status == SignalStatus::Valid || (status == SignalStatus::Offline && alive_since_)) && earliest_due_ &&
      now >= *earliest_due_ && overdue(index, now))
    status = SignalStatus::Stale;
  // A faulted signal is Error (an input at its neutral value) while the node is alive.
  if (index < faults_.size() && faults_[index] && status != SignalStatus::Offline) {
    status = SignalStatus::Error;
    const auto& info = signals();
    if (index < info.size() && !info[index].output()) value = info[index].neutral;
  }
  SignalValue& v = values_.at(index);
  if (v.value == value && v.status == status) {
    v.timestamp = now;
    return;
  }
  if (v.status != status) next_due_known_ = false;  // watched(index) may have changed
  v = SignalValue{value, status, now};
  if (on_change) on_change(index, v);
}

void Driver::on_online(TimePoint /*now*/) {}

void Driver::on_offline(TimePoint now) {
  const auto& s = signals();
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i].output()) continue;
    update(i, s[i].neutral, SignalStatus::Offline, now);
  }
}

void Driver::end_outputs(TimePoint now) {
  if (output_batch_ > 0 && --output_batch_ == 0) flush_outputs(now);
}

void Driver::set_carriers(std::vector<Carrier> carriers) {
  carriers_ = std::move(carriers);
  rebuild_deadlines();
}

void Driver::apply_boot_writes(const std::vector<SdoWrite>& writes) {
  if (&writes != &boot_writes_) boot_writes_ = writes;
  refresh_carriers();
  boot_writes_made(writes);
  for (const SdoWrite& w : writes) {
    for (Carrier& c : carriers_) {
      if (w.index != c.comm_index || w.data.empty()) continue;
      if (w.sub == 5 && w.data.size() >= 2) c.event_timer_ms = static_cast<std::uint16_t>(w.data[0] | (w.data[1] << 8));
      if (w.sub == 2) c.transmission_type = w.data[0];
    }
  }
  rebuild_deadlines();
}

void Driver::apply_tpdo_writes(TpdoTraffic& t, std::uint16_t comm_index, const std::vector<SdoWrite>& writes) {
  for (const SdoWrite& w : writes) {
    if (w.index != comm_index || w.data.empty()) continue;
    const auto u16 = static_cast<std::uint16_t>(w.data[0] | (w.data.size() >= 2 ? w.data[1] << 8 : 0));
    if (w.sub == 2) t.transmission_type = w.data[0];
    if (w.sub == 3) t.inhibit_100us = u16;
    if (w.sub == 5) t.event_timer_ms = u16;
  }
}

std::vector<Driver::TpdoTraffic> Driver::expected_tpdos(const std::vector<SdoWrite>& writes) const {
  std::vector<TpdoTraffic> out;
  for (const Carrier& c : carriers_) {
    TpdoTraffic t{c.cob_id, c.length, c.event_timer_ms, c.transmission_type, c.inhibit_100us};
    apply_tpdo_writes(t, c.comm_index, writes);
    out.push_back(t);
  }
  return out;
}

void Driver::set_pdo_timeout(Duration timeout) {
  pdo_timeout_ = timeout;
  rebuild_deadlines();
}

void Driver::set_freshness_floor(Duration floor) {
  freshness_floor_ = floor;
  rebuild_deadlines();
}

void Driver::set_sync_period(Duration period) {
  sync_period_ = period;
  rebuild_deadlines();
}

std::optional<std::uint16_t> Driver::synchronous_carrier() const {
  for (const Carrier& c : carriers_)
    if (c.transmission_type <= 240) return c.comm_index;
  return std::nullopt;
}

void Driver::set_alive_since(std::optional<TimePoint> since) {
  alive_since_ = since;
  for (Watch& w : watches_) {
    w.last.reset();  // PDOs of an earlier life prove nothing now
    w.due = compute_due(w);
  }
  refresh_earliest_due();
}

void Driver::refresh_earliest_due() {
  next_due_known_ = false;
  earliest_due_.reset();
  for (const Watch& w : watches_)
    if (w.due && (!earliest_due_ || *w.due < *earliest_due_)) earliest_due_ = w.due;
}

std::optional<TimePoint> Driver::compute_due(const Watch& w) const {
  if (w.last) return *w.last + w.deadline;
  // Never seen since the proof of life: a required PDO is due one deadline after it.
  if (w.required && alive_since_) return *alive_since_ + w.deadline;
  return std::nullopt;
}

bool Driver::overdue(std::size_t index, TimePoint now) const {
  if (index >= watch_mask_.size()) return false;
  for (std::uint32_t m = watch_mask_[index], k = 0; m != 0; m >>= 1, ++k)
    if ((m & 1u) != 0 && watches_[k].due && now >= *watches_[k].due) return true;
  return false;
}

bool Driver::watched(std::size_t index) const {
  const SignalStatus st = values_[index].status;
  return st == SignalStatus::Valid || (st == SignalStatus::Offline && alive_since_);
}

void Driver::mark_stale(const Watch& w, TimePoint now) {
  for (const std::size_t i : w.signals)
    if (watched(i)) update(i, values_[i].value, SignalStatus::Stale, now);
}

void Driver::pdo_received(std::uint32_t can_id, TimePoint now) {
  for (Watch& w : watches_) {
    if (w.cob != can_id && w.cob != kAnyCob) continue;
    // Read after its deadline (the loop reached it late): the deadline was missed all the same.
    if (w.due && now >= *w.due) mark_stale(w, now);
    w.last = now;
    w.due = now + w.deadline;
  }
  refresh_earliest_due();
}

void Driver::rebuild_deadlines() {
  deadline_.assign(values_.size(), Duration{0});
  watch_mask_.assign(values_.size(), 0);
  watches_.clear();
  auto add = [this](std::uint32_t cob, Duration d, bool required, const std::vector<std::size_t>& signals) {
    if (d.count() == 0 || watches_.size() >= 32) return;
    const auto k = static_cast<std::uint32_t>(watches_.size());
    watches_.push_back(Watch{cob, d, required, {}, std::nullopt, std::nullopt});
    for (const std::size_t i : signals) {
      if (i >= deadline_.size()) continue;
      watches_.back().signals.push_back(i);
      watch_mask_[i] |= 1u << k;
      if (deadline_[i].count() == 0 || d < deadline_[i]) deadline_[i] = d;
    }
  };
  for (const Carrier& c : carriers_) {
    Duration d = pdo_timeout_;
    if (d.count() == 0 && c.event_timer_ms != 0 && c.transmission_type >= 254)
      d = std::chrono::milliseconds(c.event_timer_ms) * kMissedPeriods;
    if (d.count() == 0 && c.transmission_type >= 1 && c.transmission_type <= 240)
      d = sync_period_ * c.transmission_type * kMissedPeriods;
    if (pdo_timeout_.count() == 0 && d.count() != 0) d = std::max(d, freshness_floor_);
    add(c.cob_id, d, c.required, c.signals);
  }
  // A driver that declares no carriers: pdo_timeout_ms covers every input, refreshed by any PDO.
  if (carriers_.empty() && pdo_timeout_.count() != 0) {
    const auto& info = signals();
    std::vector<std::size_t> inputs;
    for (std::size_t i = 0; i < deadline_.size() && i < info.size(); ++i)
      if (!info[i].output()) inputs.push_back(i);
    add(kAnyCob, pdo_timeout_, true, inputs);
  }
  for (Watch& w : watches_) w.due = compute_due(w);
  refresh_earliest_due();
  with_deadline_.clear();
  for (std::size_t i = 0; i < deadline_.size(); ++i)
    if (deadline_[i].count() != 0) with_deadline_.push_back(i);
}

Duration Driver::freshness(std::size_t index) const {
  return index < deadline_.size() ? deadline_[index] : Duration{0};
}

Duration Driver::longest_freshness() const {
  Duration d{0};
  for (const std::size_t i : with_deadline_) d = std::max(d, deadline_[i]);
  return d;
}

void Driver::advance(TimePoint now) {
  for (const Watch& w : watches_)
    if (w.due && now >= *w.due) mark_stale(w, now);
}

bool Driver::all_stale() const {
  if (with_deadline_.empty()) return false;
  return std::all_of(with_deadline_.begin(), with_deadline_.end(),
                     [this](std::size_t i) { return values_[i].status == SignalStatus::Stale; });
}

std::optional<TimePoint> Driver::find_next_deadline() const {
  std::optional<TimePoint> best;
  for (const Watch& w : watches_) {
    const auto& at = w.due;
    if (!at || (best && *at >= *best)) continue;
    // Only while it still has a signal to mark: an overdue PDO whose signals are all stale
    // already is no reason to wake up.
    if (std::any_of(w.signals.begin(), w.signals.end(), [this](std::size_t i) { return watched(i); })) best = at;
    if (best == earliest_due_) break;  // none is sooner
  }
  next_due_ = best;
  next_due_known_ = true;
  return best;
}

std::optional<std::string> DriverOptions::get(std::string_view key) const {
  for (const auto& [k, v] : values)
    if (k == key) return v;
  return std::nullopt;
}

void Driver::export_state(canopen::StateWriter& w) const {
  if (output_batch_ != 0) throw std::logic_error("Driver::export_state inside an output batch");
  w.put_list("boot_writes", boot_writes_.size(), [&](std::size_t i) {
    w.put("index", boot_writes_[i].index);
    w.put("sub", boot_writes_[i].sub);
    w.put_bytes("data", boot_writes_[i].data);
  });
  w.put_list("signals", values_.size(), [&](std::size_t i) {
    w.put("value", values_[i].value);
    w.put("status", values_[i].status);
    w.put("at", values_[i].timestamp);
    if (faults_[i]) w.put("fault", true);
  });
  // Each watch's due follows from its last PDO, the proof of life and its deadline (compute_due).
  w.put_list("watches", watches_.size(), [&](std::size_t k) {
    w.put("cob", watches_[k].cob);
    w.put("last", watches_[k].last);
  });
  w.put("alive_since", alive_since_);
  w.put("counters.wrong_length", counters_.wrong_length);
  w.put("counters.unknown_cob", counters_.unknown_cob);
  w.put("counters.unknown_emcy", counters_.unknown_emcy);
  w.put("counters.mismatches", counters_.mismatches);
  const canopen::StateWriter::Scope family(w, "family");
  export_family_state(w);
}

void Driver::import_state(const canopen::StateReader& r) {
  std::vector<SdoWrite> writes;
  r.read_list("boot_writes", 4096, [&](const canopen::StateReader& item) {
    writes.push_back(SdoWrite{item.get<std::uint16_t>("index"), item.get<std::uint8_t>("sub"), item.bytes("data"),
                              "restored from a state"});
  });
  import_boot_learned(r.in("family"));
  boot_writes_ = std::move(writes);
  apply_boot_writes(boot_writes_);
  std::vector<SignalValue> values;
  std::vector<bool> faults;
  r.read_list("signals", values_.size(), [&](const canopen::StateReader& s) {
    values.push_back(SignalValue{s.integer("value"), get_signal_status(s, "status"), s.time("at")});
    faults.push_back(s.get_or("fault", false));
  });
  if (values.size() != values_.size()) {
    r.fail("signals.count", "differs from this driver's " + std::to_string(values_.size()) + " signals");
  }
  std::vector<std::optional<TimePoint>> last;
  r.read_list("watches", watches_.size(), [&](const canopen::StateReader& item) {
    if (item.get<std::uint32_t>("cob") != watches_[last.size()].cob) {
      item.fail("cob", "differs: the state is of another boot's PDOs");
    }
    last.push_back(item.optional_time("last"));
  });
  if (last.size() != watches_.size()) r.fail("watches.count", "differs: the state is of another boot's PDOs");
  const canopen::StateReader c = r.in("counters");
  const InputCounters counters{c.get<std::uint64_t>("wrong_length"), c.get<std::uint64_t>("unknown_cob"),
                               c.get<std::uint64_t>("unknown_emcy"), c.get<std::uint64_t>("mismatches")};
  alive_since_ = r.optional_time("alive_since");
  values_ = std::move(values);
  faults_ = std::move(faults);
  fault_count_ = static_cast<std::size_t>(std::count(faults_.begin(), faults_.end(), true));
  // After the faults: the family checks them against the latches that set them.
  import_family_state(r.in("family"));
  for (std::size_t k = 0; k < watches_.size(); ++k) {
    watches_[k].last = last[k];
    watches_[k].due = compute_due(watches_[k]);
  }
  counters_ = counters;
  refresh_earliest_due();
}

}  // namespace oegw::subdevices
