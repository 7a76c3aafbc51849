#include "gateway/command_arbiter.hpp"

#include <fmt/format.h>

namespace oegw::gateway {

using canopen::TimePoint;
using mapping::CommandSource;
using mapping::FeId;

namespace {
bool takes(mapping::CommandSources sources, CommandSource s) {
  return (sources & static_cast<mapping::CommandSources>(s)) != 0;
}
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

}  // namespace oegw::gateway
