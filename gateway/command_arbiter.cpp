#include "gateway/command_arbiter.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <stdexcept>

namespace oegw::gateway {

using canopen::TimePoint;
using mapping::CommandSource;
using mapping::FeId;

namespace {
bool takes(mapping::CommandSources sources, CommandSource s) {
  return (sources & static_cast<mapping::CommandSources>(s)) != 0;
}

// The ways a refusal is logged once for (refuse()): host_write's and take()'s.
constexpr std::array<std::string_view, 5> kWays{"SDO", "RPDO", "canopen", "dds", "lcm"};
}  // namespace

CommandArbiter::CommandArbiter(const mapping::Config& config, OeDevice& device, FeModel& model)
    : device_(device), model_(model) {
  for (const auto& fe : config.functional_elements) {
    if (fe.input()) continue;
    outputs_.push_back({fe.id, fe.sources, std::chrono::milliseconds(fe.command_timeout_ms)});
  }
  device_.on_host_write([this](FeId fe, canopen::Origin origin, TimePoint now) { return host_write(fe, origin, now); });
  device_.on_output(
      [this](FeId fe, FieldRef ref, std::int64_t value, TimePoint now) { output_changed(fe, ref, value, now); });
}

CommandArbiter::Output* CommandArbiter::find(FeId fe) {
  for (auto& o : outputs_)
    if (o.id == fe) return &o;
  return nullptr;
}

void CommandArbiter::say(const std::string& line) const {
  if (log) log(line);
}

void CommandArbiter::start(TimePoint now) {
  for (auto& o : outputs_) {
    o.last = now;
    o.expired = false;
  }
  started_ = true;
}

void CommandArbiter::seen(Output& o, TimePoint now) {
  o.last = now;
  if (o.expired) say(mapping::fe_name(o.id) + ": commands again");
  o.expired = false;
}

std::uint64_t CommandArbiter::refused(FeId fe) const {
  for (const auto& o : outputs_)
    if (o.id == fe) return o.refused;
  return 0;
}

void CommandArbiter::refuse(FeId fe, std::string_view way, const std::string& why) {
  ++refused_;
  if (Output* o = find(fe)) ++o->refused;
  // Logged once per FE and way (dds, lcm, SDO, RPDO): a commander at 100 Hz must not flood the
  // journal; refused() keeps the count.
  if (refused_logged_.emplace(fe, std::string(way)).second) say(mapping::fe_name(fe) + ": " + why);
}

bool CommandArbiter::host_write(FeId fe, canopen::Origin origin, TimePoint now) {
  Output* o = find(fe);
  if (o == nullptr) return true;  // not an FE of the mapping file: the dictionary decides
  if (takes(o->sources, CommandSource::Canopen)) {
    seen(*o, now);
    return true;
  }
  const bool rpdo = origin == canopen::Origin::Pdo;
  refuse(fe, rpdo ? "RPDO" : "SDO",
         std::string(rpdo ? "the host's RPDO bytes for it ignored"
                          : "the host's SDO write refused (abort 0800 0021h)") +
             ": its sources are " + mapping::describe_sources(o->sources));
  return false;
}

bool CommandArbiter::take(FeId fe, CommandSource source, TimePoint now) {
  Output* o = find(fe);  // none: also an instance outside 1..8
  if (o == nullptr || !takes(o->sources, source)) {
    const auto src = std::string(mapping::to_string(source));
    refuse(fe, src,
           "a command from " + src + " ignored: " +
               (o == nullptr ? "the mapping file does not configure " + mapping::fe_name(fe)
                             : "its sources are " + mapping::describe_sources(o->sources)));
    return false;
  }
  seen(*o, now);
  return true;
}

bool CommandArbiter::command_indicators(std::uint8_t instance, std::uint64_t bits, CommandSource source,
                                        TimePoint now) {
  const FeId fe{mapping::FeKind::IndicatorCluster, instance};
  if (!take(fe, source, now)) return false;
  device_.write_indicators(fe, bits, now);  // the changed bits come back as output_changed()
  return true;
}

bool CommandArbiter::command_display(std::uint8_t instance, const std::array<std::int16_t, 12>& parameters,
                                     CommandSource source, TimePoint now) {
  const FeId fe{mapping::FeKind::Display, instance};
  if (!take(fe, source, now)) return false;
  device_.write_display(fe, parameters, now);
  return true;
}

void CommandArbiter::output_changed(FeId fe, FieldRef ref, std::int64_t value, TimePoint now) {
  (void)model_.write(fe, ref, value, now);
  if (drive) drive(fe, ref, value);
}

void CommandArbiter::hold_error_values(TimePoint now) {
  // Only writes what differs: cheap when nothing changed.
  for (const auto& o : outputs_)
    if (o.expired) device_.apply_error_values(o.id, now);
}

void CommandArbiter::advance(TimePoint now) {
  for (auto& o : outputs_) {
    if (!started_ || o.timeout.count() == 0 || o.expired || now - o.last < o.timeout) continue;
    o.expired = true;
    device_.apply_error_values(o.id, now);
    say(fmt::format("{}: no command for {} ms: outputs set to their error values until the next command",
                    mapping::fe_name(o.id), std::chrono::duration_cast<std::chrono::milliseconds>(o.timeout).count()));
  }
}

std::optional<TimePoint> CommandArbiter::next_deadline() const {
  std::optional<TimePoint> best;
  if (!started_) return best;
  for (const auto& o : outputs_) {
    if (o.timeout.count() == 0 || o.expired) continue;
    const TimePoint t = o.last + o.timeout;
    if (!best || t < *best) best = t;
  }
  return best;
}

void CommandArbiter::export_state(canopen::StateWriter& w) const {
  w.put("started", started_);
  w.put("refused", refused_);
  w.put_list("outputs", outputs_.size(), [&](std::size_t i) {
    const Output& o = outputs_[i];
    put_fe_id(w, o.id);
    w.put("last", o.last);
    w.put("expired", o.expired);
    w.put("refused", o.refused);
  });
  std::vector<std::pair<FeId, std::size_t>> logged;
  for (const auto& [fe, way] : refused_logged_) {
    const auto it = std::find(kWays.begin(), kWays.end(), way);
    if (it == kWays.end()) throw std::logic_error("CommandArbiter: a refusal logged for an unknown way: " + way);
    logged.emplace_back(fe, static_cast<std::size_t>(it - kWays.begin()));
  }
  w.put_list("logged", logged.size(), [&](std::size_t i) {
    put_fe_id(w, logged[i].first);
    w.put("way", logged[i].second);
  });
}

void CommandArbiter::import_state(const canopen::StateReader& r) {
  std::vector<Output> outputs = outputs_;
  std::size_t i = 0;
  r.read_list("outputs", outputs.size(), [&](const canopen::StateReader& item) {
    Output& o = outputs[i++];
    expect_fe_id(item, o.id, "outputs");
    o.last = item.time("last");
    o.expired = item.get<bool>("expired");
    o.refused = item.get<std::uint64_t>("refused");
    // advance(): only a watchdog expires.
    if (o.expired && o.timeout.count() == 0) item.fail("expired", "is set for an output without a watchdog");
  });
  if (i != outputs.size()) r.fail("outputs.count", "differs from the mapping file's output FEs");
  const bool started = r.get<bool>("started");
  if (!started && std::any_of(outputs.begin(), outputs.end(), [](const Output& o) { return o.expired; })) {
    r.fail("started", "is not set, yet a watchdog expired");
  }
  std::set<std::pair<FeId, std::string>> logged;
  r.read_list("logged", 2 * 256 * kWays.size(), [&](const canopen::StateReader& item) {
    const FeId fe = get_fe_id(item);
    if (fe.kind != mapping::FeKind::IndicatorCluster && fe.kind != mapping::FeKind::Display) {
      item.fail("kind", "is no output FE");
    }
    const auto way = item.get<std::uint8_t>("way");
    if (way >= kWays.size()) item.fail("way", "is no way a command comes");
    logged.emplace(fe, std::string(kWays[way]));
  });
  outputs_ = std::move(outputs);
  started_ = started;
  refused_ = r.get<std::uint64_t>("refused");
  refused_logged_ = std::move(logged);
}

}  // namespace oegw::gateway
