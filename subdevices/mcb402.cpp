#include "subdevices/mcb402.hpp"

#include <array>
#include <charconv>
#include <cstdio>
#include <string_view>

#include "canopen/state.hpp"
#include "subdevices/driver_options.hpp"
#include "subdevices/families.hpp"

namespace oegw::subdevices {

namespace {

using namespace mcb402;

constexpr std::uint32_t kTpdo1 = 0x180;
constexpr std::uint32_t kTpdo2 = 0x280;
constexpr std::uint32_t kRpdo1 = 0x200;
constexpr std::uint8_t kTpdo1Length = 4;  // 6000h:01..04
constexpr std::uint8_t kTpdo2Length = 8;  // 6401h:01..04

std::vector<SignalInfo> make_signals() {
  std::vector<SignalInfo> s;
  for (const char* axis : {"x", "y", "z", "t"})
    s.push_back(
        SignalInfo{.name = axis, .kind = SignalKind::Axis, .min = -32768, .max = 32767, .neutral = 0, .unit = "raw16"});
  for (std::size_t i = 1; i <= kButtons; ++i)
    s.push_back(SignalInfo{.name = "buttons[" + std::to_string(i) + "]",
                           .kind = SignalKind::Button,
                           .min = 0,
                           .max = 1,
                           .neutral = 0,
                           .unit = "bool"});
  for (std::size_t i = 1; i <= kLeds; ++i)
    s.push_back(SignalInfo{.name = "leds[" + std::to_string(i) + "]",
                           .kind = SignalKind::Output,
                           .min = 0,
                           .max = 1,
                           .neutral = 0,
                           .unit = "bool"});
  return s;
}

std::string hex4(std::uint16_t v) {
  char b[8];
  std::snprintf(b, sizeof b, "%04X", v);
  return b;
}

std::vector<std::uint8_t> le(std::uint32_t v, std::size_t n) {
  std::vector<std::uint8_t> out(n);
  for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<std::uint8_t>(v >> (8 * i));
  return out;
}

std::optional<unsigned long> parse_number(std::string_view text, unsigned long max) {
  unsigned long v = 0;
  const char* end = text.data() + text.size();
  auto [p, ec] = std::from_chars(text.data(), end, v);
  if (ec != std::errc{} || p != end || text.empty() || v > max) return std::nullopt;
  return v;
}

}  // namespace

std::optional<ButtonBits> parse_button_bits(std::string_view text, std::string& why) {
  ButtonBits bits{};
  std::size_t n = 0;
  // Where each bit was given (1-based, 0: not yet): a repeated bit names both positions.
  std::array<std::size_t, 8> at{};
  const char separator = text.find('/') != std::string_view::npos ? '/' : ',';
  while (true) {
    const auto end = text.find(separator);
    std::string_view item = text.substr(0, end);
    while (!item.empty() && item.front() == ' ') item.remove_prefix(1);
    while (!item.empty() && item.back() == ' ') item.remove_suffix(1);
    ++n;
    const auto v = parse_number(item, 7);
    if (!v) {
      why = "'" + std::string(item) + "' at position " + std::to_string(n) +
            (n <= kButtons ? " (BP" + std::to_string(n) + ")" : std::string()) + " is not a bit number 0..7";
      return std::nullopt;
    }
    if (n <= kButtons) {  // beyond the seventh only counted: the count is what is wrong then
      if (at[*v] != 0) {
        why = "bit " + std::to_string(*v) + " is given twice, at positions " + std::to_string(at[*v]) + " and " +
              std::to_string(n) + " (BP" + std::to_string(at[*v]) + " and BP" + std::to_string(n) + ")";
        return std::nullopt;
      }
      at[*v] = n;
      bits[n - 1] = static_cast<std::uint8_t>(*v);
    }
    if (end == std::string_view::npos) break;
    text.remove_prefix(end + 1);
  }
  if (n != kButtons) {
    why = std::to_string(n) + " number" + (n == 1 ? "" : "s") + " for " + std::to_string(kButtons) + " push buttons";
    return std::nullopt;
  }
  return bits;
}

std::optional<ButtonBits> parse_button_bits(std::string_view text) {
  std::string why;
  return parse_button_bits(text, why);
}

const std::vector<OptionSpec>& mcb402_options() {
  using T = OptionSpec::Type;
  static const std::vector<OptionSpec> table = {
      {.name = "event_timer_ms",
       .type = T::Integer,
       .ranges = {{1, 65535}},
       .unit = "ms",
       .default_value = "20",
       .note = "(1801h:05; 0 would leave the axes unsent)",
       .description = "TPDO2 (axes) event timer written at boot (1801h:05); the document gives no value and its "
                      "default 0 would send no periodic axes; axes missing for 3 periods are Stale"},
      {.name = "button_timer_ms",
       .type = T::Integer,
       .ranges = {{0, 65535}},
       .unit = "ms",
       .default_value = "100",
       .note = "(1800h:05)",
       .description = "TPDO1 (buttons) event timer written at boot (1800h:05); 0: sent on change only (then no "
                      "deadline for the buttons)"},
      {.name = "can_restart_ms",
       .type = T::Integer,
       .ranges = {{1, 65535}},
       .unit = "ms",
       .default_value = "1000",
       .note = "(2180h; 0 would keep the board off the bus after a bus off)",
       .description = "CAN restart time after bus off written at boot (2180h); 0 is refused: the board would "
                      "stay off the bus"},
      {.name = "button_bits",
       .type = T::Text,
       .syntax = "7 distinct bit numbers 0..7",
       .required = true,
       .missing = kButtonBitsMissing,
       .listing_value = "0/1/2/3/4/5/6",
       .description = "the bit of 6000h:03 (byte 2 of TPDO1) that each push button BP1..BP7 sets, seven numbers "
                      "(',' in a YAML list, '/' on a command line); no default: the document's bit table is damaged "
                      "and permits two readings, so a wrong order would report the wrong button; "
                      "`oegw signals mcb402 --find-button-bits` reads it off the board"},
      freshness_floor_option("200"),
  };
  return table;
}

std::optional<Mcb402Options> parse_mcb402_options(const DriverOptions& options, OptionRefusals& refusals) {
  Mcb402Options o;
  const bool ok = parse_options(
      "mcb402", mcb402_options(), options,
      [&o](const OptionValue& v, std::string& err) {
        const std::string_view name = v.spec->name;
        if (name == "event_timer_ms") o.event_timer_ms = static_cast<std::uint16_t>(v.number);
        if (name == "button_timer_ms") o.button_timer_ms = static_cast<std::uint16_t>(v.number);
        if (name == "can_restart_ms") o.can_restart_ms = static_cast<std::uint16_t>(v.number);
        if (name == "button_bits") {
          std::string why;
          const auto bits = parse_button_bits(v.text, why);
          if (!bits) {
            err = "mcb402: button_bits '" + v.text + "': " + why +
                  "; expected 7 distinct bit numbers 0..7 of 6000h:03 for BP1..BP7, "
                  "separated by ',' or '/' (as `oegw signals mcb402 --find-button-bits` "
                  "prints them)";
            return false;
          }
          o.button_bits = *bits;
        }
        if (name == kFreshnessFloorOption) o.freshness_floor_ms = static_cast<std::uint32_t>(v.number);
        return true;
      },
      refusals);
  if (!ok) return std::nullopt;
  return o;
}

std::unique_ptr<Driver> make_mcb402_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                           OptionRefusals& refusals) {
  if (!node.valid()) {
    refusals.push_back({"", "mcb402: node-ID must be 1..127 (jumpers CN3)"});
    return nullptr;
  }
  auto o = parse_mcb402_options(options, refusals);
  if (!o) return nullptr;
  auto d = std::make_unique<Mcb402Driver>(node, std::move(sink), *o);
  apply_freshness_floor(*d, o->freshness_floor_ms);
  return d;
}

std::unique_ptr<Driver> make_mcb402_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                           std::string& error) {
  return with_error_text(error, [&](OptionRefusals& refusals) {
    return make_mcb402_driver(node, std::move(sink), options, refusals);
  });
}

Mcb402Driver::Mcb402Driver(NodeId node, FrameSink sink, Mcb402Options options)
    : options_(options), signals_(make_signals()) {
  init(node, std::move(sink), signals_.size());
  // TPDO1 (buttons) and TPDO2 (axes), type FFh with the event timers configuration() writes.
  Carrier tpdo1{.cob_id = canopen::cob::kTpdo1 + node.value(),
                .comm_index = 0x1800,
                .event_timer_ms = options_.button_timer_ms,
                .transmission_type = 0xFF,
                .signals = {},
                .length = 4};  // 6000h:01..04 ("Operation mode 4" mapping)
  for (std::size_t i = 0; i < kButtons; ++i) tpdo1.signals.push_back(kFirstButton + i);
  Carrier tpdo2{.cob_id = canopen::cob::kTpdo2 + node.value(),
                .comm_index = 0x1801,
                .event_timer_ms = options_.event_timer_ms,
                .transmission_type = 0xFF,
                .signals = {},
                .length = 8};  // 6401h:01..04, INTEGER16 each
  for (std::size_t a = 0; a < kAxes; ++a) tpdo2.signals.push_back(a);
  set_carriers({tpdo1, tpdo2});
}

ExpectedIdentity Mcb402Driver::expected_identity() const {
  return ExpectedIdentity{.device_type = kDeviceType,
                          .vendor_id = kVendorId,
                          .product_code = kProductCode,
                          .revision = std::nullopt,
                          .serial = std::nullopt};
}

std::vector<SdoWrite> Mcb402Driver::configuration() const {
  std::vector<SdoWrite> w;
  w.push_back({0x1800, 2, {0xFF}, "TPDO1 (buttons) transmission type 255, event driven"});
  w.push_back({0x1800, 5, le(options_.button_timer_ms, 2),
               "TPDO1 (buttons) event timer " + std::to_string(options_.button_timer_ms) + " ms"});
  w.push_back({0x1801, 2, {0xFF}, "TPDO2 (axes) transmission type 255, event driven"});
  w.push_back({0x1801, 5, le(options_.event_timer_ms, 2),
               "TPDO2 (axes) event timer " + std::to_string(options_.event_timer_ms) + " ms"});
  w.push_back({0x2180, 0, le(options_.can_restart_ms, 2),
               "CAN restart time " + std::to_string(options_.can_restart_ms) + " ms after bus off"});
  w.push_back({0x6002, 3, {0x00}, "input polarity IN7..IN0 not inverted (1 = button pressed)"});
  w.push_back({0x6202, 1, {0x00}, "output polarity OUT3..OUT0 not inverted (1 = LED on)"});
  for (std::uint8_t i = 1; i <= kAxes; ++i)
    w.push_back({0x6431, i, le(0, 4), "analogue input " + std::to_string(i) + " offset 0 (signed axis values)"});
  return w;
}

std::vector<std::uint32_t> Mcb402Driver::consumed_cob_ids() const {
  return {kTpdo1 + node().value(), kTpdo2 + node().value()};
}

bool Mcb402Driver::on_frame(const CanFrame& frame, TimePoint now) {
  const std::uint32_t id = node().value();
  if (frame.extended || frame.rtr || (frame.id != kTpdo1 + id && frame.id != kTpdo2 + id)) {
    ++counters_.unknown_cob;
    return false;
  }
  if (frame.id == kTpdo1 + id) {
    if (frame.dlc != kTpdo1Length) {
      ++counters_.wrong_length;
      return true;
    }
    on_tpdo1(frame, now);
  } else {
    if (frame.dlc != kTpdo2Length) {
      ++counters_.wrong_length;
      return true;
    }
    on_tpdo2(frame, now);
  }
  return true;
}

void Mcb402Driver::on_tpdo1(const CanFrame& frame, TimePoint now) {
  const std::uint8_t cc = frame.data[kButtonByte];
  for (std::size_t i = 0; i < kButtons; ++i)
    update(kFirstButton + i, (cc >> options_.button_bits[i]) & 1u, SignalStatus::Valid, now);
}

void Mcb402Driver::on_tpdo2(const CanFrame& frame, TimePoint now) {
  // A faulted axis (cable break) stays Error whatever TPDO2 carries (Driver::update).
  for (std::size_t a = 0; a < kAxes; ++a) {
    const auto raw = static_cast<std::int16_t>(canopen::get_u16(&frame.data[2 * a]));
    update(a, raw, SignalStatus::Valid, now);
  }
}

void Mcb402Driver::set_broken(std::uint8_t axes, std::optional<TimePoint> now) {
  broken_ = static_cast<std::uint8_t>(axes & 0x0F);
  for (std::size_t a = 0; a < kAxes; ++a) {
    if (!latched(a)) {
      clear_fault(a);  // its next TPDO2 value is good
    } else if ((broken_ & (1u << a)) != 0) {
      set_fault(a, now);
    }
  }
}

bool Mcb402Driver::latched(std::size_t i) const {
  return !signals_[i].output() && (unknown_fault_ || (i < kAxes && ((broken_ >> i) & 1u) != 0));
}

void Mcb402Driver::clear_faults() {
  broken_ = 0;
  unknown_fault_ = false;
  clear_all_faults();
}

std::vector<std::pair<std::uint16_t, std::uint8_t>> Mcb402Driver::boot_reads() const {
  if (error_register_read_) return {};
  return {{0x1001, 0}};
}

bool Mcb402Driver::on_boot_read(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                                std::string& /*error*/) {
  if (index != 0x1001 || sub != 0) return true;
  error_register_read_ = true;
  if (data.size() != 1) return true;  // 1001h is UNSIGNED8: another length is no evidence, the faults stay
  const std::uint8_t reg = data[0];
  // [CO4013 Index 1001]: bit 7 "Device Error" — the cable break's 81h ([CO4013 "Emergency
  // Messages"] "20 31 81 ..."). Clear: no device error, whatever cable break was latched before
  // (a board repaired and rebooted); an undocumented error ends only when no bit but the
  // communication warning's (11h) is left. Set: the latched axes stay broken; none latched (the
  // EMCY went before the gateway listened): which axis is unknown, so all four.
  if ((reg & kDeviceErrorBit) == 0) {
    if ((reg & ~kCommunicationOnly) == 0) unknown_fault_ = false;
    set_broken(0, std::nullopt);
    if (!unknown_fault_) clear_faults();
    return true;
  }
  if (!any_fault()) set_broken(0x0F, std::nullopt);
  return true;
}

std::optional<Driver::FaultPoll> Mcb402Driver::fault_poll() const {
  if (broken_ == 0 && !unknown_fault_) return std::nullopt;
  return FaultPoll{0x1001, 0, kErrorRegisterPoll};
}

std::string Mcb402Driver::on_fault_poll(std::span<const std::uint8_t> data, TimePoint /*now*/) {
  // A request sent before the last latch may be answered with the register of before it; 1001h
  // is UNSIGNED8, another length is no evidence.
  if (poll_epoch_sent_ != latch_epoch_ || data.size() != 1) return {};
  const std::uint8_t reg = data[0];
  const bool break_over = broken_ != 0 && (reg & kDeviceErrorBit) == 0;
  const bool unknown_over = unknown_fault_ && (reg & ~kCommunicationOnly) == 0;
  if (!break_over && !unknown_over) return {};
  if (unknown_over) unknown_fault_ = false;
  if (break_over) set_broken(0, std::nullopt);
  if (!unknown_fault_ && broken_ == 0) clear_faults();
  // As after 0000h: the inputs stay at neutral until their next PDO brings a fresh value.
  char b[96];
  std::snprintf(b, sizeof b, "1001h read %02Xh: %s", reg,
                break_over ? "no device error, the cable break is over" : "no error but communication left");
  return b;
}

bool Mcb402Driver::on_boot_read_abort(std::uint16_t index, std::uint8_t /*sub*/, canopen::SdoAbortCode /*code*/) {
  // No evidence either way: the faults stay as they are.
  if (index == 0x1001) error_register_read_ = true;
  return index == 0x1001;
}

DecodedEmcy Mcb402Driver::on_emcy(const EmcyMessage& emcy, TimePoint now) {
  DecodedEmcy d;
  d.code = emcy.code;
  switch (emcy.code) {
    case canopen::EmcyProducer::kErrorReset: {
      d.error = false;
      d.text = "MCB-402 0000h: error reset";
      clear_faults();
      // The affected signals stay at neutral until their next PDO brings a fresh value.
      return d;
    }
    case kEmcyCableBreak: {
      ++latch_epoch_;
      // [CO4013 "Emergency Messages"] "20 31 81 00 8x 00 00 00": byte 4 (msef[1]) = 8xh.
      const std::uint8_t b = emcy.msef[1];
      std::uint8_t axes = static_cast<std::uint8_t>(b & 0x0F);
      if ((b & 0xF0) != 0x80 || axes == 0) {
        ++counters_.unknown_emcy;
        axes = 0x0F;  // which axis is unknown: all of them
        d.text = "MCB-402 3120h: cable break, undecodable axis byte";
      } else {
        d.text = "MCB-402 3120h: cable break on axis";
        static constexpr std::array<const char*, kAxes> kNames{" X", " Y", " Z", " T"};
        for (std::size_t a = 0; a < kAxes; ++a)
          if ((axes & (1u << a)) != 0) d.text += kNames[a];
      }
      // The active errors are ORed into byte 4: axes no longer in the set are mended.
      set_broken(axes, now);
      for (std::size_t a = 0; a < kAxes; ++a)
        if ((axes & (1u << a)) != 0) d.affected.push_back(a);
      return d;
    }
    default: break;
  }
  if ((emcy.code & 0xFF00) == 0x8100) {
    // CiA 301 Table 26 81xxh "communication" warnings ([CO4013 "Emergency Messages"] lists 8100h,
    // 8130h, 8140h): the values the board sends stay good. 8100h also comes at every power-on
    // ([MCB §4] "083 00 81 11 0").
    d.error = false;
    d.text = emcy.code == kEmcyCanWarning     ? "MCB-402 8100h: CAN bus in error warning state (warning)"
             : emcy.code == kEmcyLifeGuarding ? "MCB-402 8130h: life guarding error (warning)"
             : emcy.code == kEmcyBusOffRecovered
                 ? "MCB-402 8140h: return from CAN bus off (warning)"
                 : "MCB-402 " + hex4(emcy.code) + "h: CAN communication (CiA 301 81xxh, warning)";
    return d;
  }
  ++latch_epoch_;
  ++counters_.unknown_emcy;
  // An error code the document does not list: what it affects is unknown, so every input is
  // faulted until the error reset 0000h or 1001h showing no error but communication.
  d.text = "MCB-402 " + hex4(emcy.code) + "h: undocumented EMCY code, every input faulted";
  unknown_fault_ = true;
  for (std::size_t i = 0; i < signals_.size(); ++i) {
    if (!latched(i)) continue;
    set_fault(i, now);
    d.affected.push_back(i);
  }
  return d;
}

void Mcb402Driver::send_outputs() { send(CanFrame(kRpdo1 + node().value(), {outputs_})); }

void Mcb402Driver::on_online(TimePoint now) {
  Driver::on_online(now);
  outputs_pending_ = true;  // sent now, or at the end of the caller's output batch
  if (!outputs_deferred()) flush_outputs(now);
}

bool Mcb402Driver::set_output(std::size_t index, std::int64_t value, TimePoint now) {
  if (index < kFirstLed || index >= kFirstLed + kLeds || value < 0 || value > 1) return false;
  const auto bit = static_cast<std::uint8_t>(1u << (index - kFirstLed));
  outputs_ = static_cast<std::uint8_t>(value != 0 ? (outputs_ | bit) : (outputs_ & ~bit));
  update(index, value, SignalStatus::Valid, now);
  outputs_pending_ = true;
  if (!outputs_deferred()) flush_outputs(now);
  return true;
}

void Mcb402Driver::flush_outputs(TimePoint /*now*/) {
  if (!outputs_pending_) return;
  outputs_pending_ = false;
  send_outputs();
}

// The latches only the evidence clears (a 1001h read-back, the error reset), and the outputs as
// last commanded (sent again when the board comes back: on_online).
void Mcb402Driver::export_family_state(canopen::StateWriter& w) const {
  w.put("broken", broken_);
  w.put("unknown_fault", unknown_fault_);
  w.put("latch_epoch", latch_epoch_);
  w.put("poll_epoch_sent", poll_epoch_sent_);
  w.put("error_register_read", error_register_read_);
  w.put("outputs", outputs_);
}

void Mcb402Driver::import_family_state(const canopen::StateReader& r) {
  const auto broken = r.get<std::uint8_t>("broken");
  if ((broken & ~0x0Fu) != 0) r.fail("broken", "names an axis the board does not have");
  broken_ = broken;
  unknown_fault_ = r.get<bool>("unknown_fault");
  latch_epoch_ = r.get<std::uint64_t>("latch_epoch");
  poll_epoch_sent_ = r.get<std::uint64_t>("poll_epoch_sent");
  error_register_read_ = r.get<bool>("error_register_read");
  const auto outputs = r.get<std::uint8_t>("outputs");
  if ((outputs & ~0x0Fu) != 0) r.fail("outputs", "sets a bit no LED of the board has");
  outputs_ = outputs;
  for (std::size_t i = 0; i < signals_.size(); ++i) {
    if (faulted(i) == latched(i)) continue;
    // The latch that decides: an axis's cable break unless an undocumented error faults it too.
    r.fail(i < kAxes && !unknown_fault_ ? "broken" : "unknown_fault",
           "differs from signal " + std::to_string(i) + "'s fault");
  }
}

}  // namespace oegw::subdevices
