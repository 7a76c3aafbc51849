#include "gateway/record/gateway_recorder.hpp"

#include <charconv>
#include <iterator>

#include <fmt/format.h>

namespace oegw::gateway::record {

namespace {

Side side_of(Bus b) { return b == Bus::Up ? Side::Up : Side::Down; }

// One word for a state name ("not available" -> "not-available").
void append_word(std::string& out, std::string_view s) {
  for (const char c : s) out.push_back(c == ' ' ? '-' : c);
}

void append_bytes(std::string& out, std::span<const std::uint8_t> b) {
  for (const auto v : b) fmt::format_to(std::back_inserter(out), "{:02X}", v);
}

}  // namespace

void GatewayRecorder::emit() { sink_.event(now_, line_); }

void GatewayRecorder::input(canopen::TimePoint t, std::string_view text) {
  now_ = t;
  sink_.event(t, text);
}

void GatewayRecorder::started(canopen::TimePoint now) { input(now, "start"); }

void GatewayRecorder::received(Bus bus, const canopen::CanFrame& f, canopen::TimePoint t) {
  now_ = t;
  sink_.frame(side_of(bus), Direction::Rx, f, t);
}

void GatewayRecorder::bus_event(Bus bus, canopen::BusEvent e, canopen::TimePoint now) {
  now_ = now;
  line_ = bus == Bus::Up ? "bus up " : "bus down ";
  append_word(line_, canopen::to_string(e));
  emit();
}

void GatewayRecorder::advanced(canopen::TimePoint now) { input(now, "tick"); }

void GatewayRecorder::indicators(std::uint8_t instance, std::uint64_t bits, mapping::CommandSource source,
                                 canopen::TimePoint now) {
  now_ = now;
  line_.clear();
  fmt::format_to(std::back_inserter(line_), "indicators {} {:016X} {}", instance, bits, mapping::to_string(source));
  emit();
}

void GatewayRecorder::display(std::uint8_t instance, const std::array<std::int16_t, 12>& p,
                              mapping::CommandSource source, canopen::TimePoint now) {
  now_ = now;
  line_.clear();
  fmt::format_to(std::back_inserter(line_), "display {} {},{},{},{},{},{},{},{},{},{},{},{} {}", instance, p[0], p[1],
                 p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10], p[11], mapping::to_string(source));
  emit();
}

void GatewayRecorder::subdevice_command(const std::string& name, std::string_view command, canopen::TimePoint now) {
  now_ = now;
  line_ = "subdevice_command " + name + " ";
  line_ += command;
  emit();
}

void GatewayRecorder::downstream_nmt(canopen::NodeId node, canopen::NmtCommand cs, canopen::TimePoint now) {
  now_ = now;
  line_.clear();
  fmt::format_to(std::back_inserter(line_), "nmt {:02X} {:02X}", node.value(), static_cast<unsigned>(cs));
  emit();
}

void GatewayRecorder::control(std::string_view what, canopen::TimePoint now) {
  now_ = now;
  line_ = "control ";
  // One line whatever the request held.
  for (const char c : what) line_.push_back(c == '\n' || c == '\r' ? ' ' : c);
  emit();
}

void GatewayRecorder::sent(const Gateway& gw, Bus bus, const canopen::CanFrame& f) {
  sink_.frame(side_of(bus), Direction::Tx, f, now_);
  // The gateway's own EMCYs (CiA 301 §7.2.7: 80h + node-ID, 8 bytes), for the timeline.
  if (bus != Bus::Up || f.rtr || f.extended || f.dlc != 8) return;
  if (f.id != 0x80u + gw.upstream().node().node_id().value()) return;
  line_.clear();
  fmt::format_to(std::back_inserter(line_), "emcy_sent {:02X}{:02X} {:02X} ", f.data[1], f.data[0], f.data[2]);
  append_bytes(line_, std::span<const std::uint8_t>(f.data.data() + 3, 5));
  emit();
}

void GatewayRecorder::command_outcome(bool taken, std::string_view why) {
  line_ = taken ? "outcome accepted" : "outcome refused";
  if (!why.empty()) {
    line_ += ' ';
    line_ += why;
  }
  emit();
}

void GatewayRecorder::node_state(const std::string& name, subdevices::NodeState state, const std::string& why) {
  line_ = "node " + name + " ";
  append_word(line_, subdevices::to_string(state));
  line_ += " (" + why + ")";
  emit();
}

void GatewayRecorder::fault(const std::string& name, bool raised, std::string_view text) {
  line_ = "fault " + name + (raised ? " raised " : " cleared ");
  line_ += text;
  emit();
}

void GatewayRecorder::subdevice_emcy(const std::string& name, const canopen::EmcyMessage& e) {
  line_.clear();
  fmt::format_to(std::back_inserter(line_), "emcy {} {:04X} {:02X} ", name, e.code, e.error_register);
  append_bytes(line_, e.msef);
  emit();
}

void GatewayRecorder::fe_changed(const Gateway& gw, mapping::FeId fe) {
  // Called for every changed FE value on the loop's thread: the line is built by appends and
  // to_chars, the FE's name and field names kept from its first line.
  FeCache& c = fes_[fe];
  gw.field_samples(fe, samples_);
  if (!c.seen || c.names.size() != samples_.size()) {  // a reload may bind other fields
    c = FeCache{};
    c.prefix = "fe " + mapping::fe_name(fe) + " ";
    for (const auto& f : gw.fields(fe)) c.names.push_back(" " + f.name + "=");
    c.last.assign(samples_.size(), Gateway::FieldSample{});
  }
  line_ = c.prefix;
  append_word(line_, subdevices::to_string(static_cast<subdevices::SignalStatus>(gw.status(fe))));
  for (std::size_t k = 0; k < samples_.size() && k < c.names.size(); ++k) {
    const Gateway::FieldSample& s = samples_[k];
    if (c.seen && s == c.last[k]) continue;
    line_ += c.names[k];
    char digits[24];  // an int64_t: 19 digits and a sign
    line_.append(digits, std::to_chars(digits, digits + sizeof digits, s.value).ptr);
    if (s.status != subdevices::SignalStatus::Valid) {
      line_ += '[';
      append_word(line_, subdevices::to_string(s.status));
      line_ += ']';
    }
    if (s.interlocked) line_ += "(held)";
    c.last[k] = s;
  }
  c.seen = true;
  emit();
}

void GatewayRecorder::logged(const std::string& line) {
  line_ = "log ";
  for (const char c : line) line_.push_back(c == '\n' ? ' ' : c);
  emit();
}

}  // namespace oegw::gateway::record
