// elobau MFG 34xG / 36xG driver; the rules and sources are in elobau_mfg.hpp.
#include "subdevices/elobau_mfg.hpp"

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <stdexcept>

#include "canopen/state.hpp"
#include "subdevices/driver_options.hpp"
#include "subdevices/families.hpp"

namespace oegw::subdevices {

namespace {

constexpr std::uint32_t kTpdo0 = 0x180;       // §14.1
constexpr std::uint32_t kTpdo1 = 0x280;       // §14.2
constexpr std::uint32_t kRpdo0 = 0x200;       // §14.3
constexpr std::uint16_t kAxisIndex = 0x2000;  // 2000h X .. 2004h wheel C (Table 14)

constexpr std::array<const char*, ElobauMfgDriver::kAxes> kAxisNames = {"x", "y", "wheel_a", "wheel_b", "wheel_c"};

// leds[i] -> (RPDO #0 byte, bit shift): Table 9 positions, in the order of the mask bits of
// 2200h:0Ah (Table 14), bit i-1 = leds[i].
struct LedPos {
  std::uint8_t byte;
  std::uint8_t shift;
};
constexpr std::array<LedPos, ElobauMfgDriver::kLeds> kLedPos = {{
    {0, 0},
    {0, 2},
    {0, 4},
    {0, 6},  // button 1 LED 1/2, button 2 LED 1/2
    {1, 0},
    {1, 2},
    {1, 4},
    {1, 6},  // button 3 LED 1/2, button 4 LED 1/2
    {2, 0},
    {2, 2},  // button 5 LED 1/2
    {5, 0},
    {5, 2},  // wheel A LED 2-2 / 2-1 (alt. button 8 LED 1/2)
    {6, 0},
    {6, 2},  // wheel B LED 2-2 / 2-1 (alt. button 9 LED 1/2)
    {5, 4},  // wheel A LED 1+3 (alt. button 10 LED 1)
    {6, 4},  // wheel B LED 1+3 (alt. button 10 LED 2)
}};
constexpr std::uint8_t kNoChange = 0b11;  // Table 13

struct ManufacturerError {
  std::uint16_t code;
  const char* name;
};
// §12.5 Table 6 (0003h/0004h are "not used" and therefore unknown here).
constexpr ManufacturerError kManufacturerErrors[] = {
    {0x0000, "No Manufacturer Specific Error Code"},
    {0x0001, "Application Program Checksum Error"},
    {0x0002, "Parameter Checksum Error"},
    {0x0005, "RAM Test Error"},
    {0x0010, "X Axis, Signal 1, Out Of Range"},
    {0x0011, "X Axis, Signal 2, Out Of Range"},
    {0x0012, "X Axis, Signal Difference Too High"},
    {0x0020, "Y Axis, Signal 1, Out Of Range"},
    {0x0021, "Y Axis, Signal 2, Out Of Range"},
    {0x0022, "Y Axis, Signal Difference Too High"},
    {0x0030, "Thumb Wheel A, Signal 1, Out Of Range"},
    {0x0031, "Thumb Wheel A, Signal 2, Out Of Range"},
    {0x0032, "Thumb Wheel A, Signal Difference Too High"},
    {0x0040, "Thumb Wheel B, Signal 1, Out Of Range"},
    {0x0041, "Thumb Wheel B, Signal 2, Out Of Range"},
    {0x0042, "Thumb Wheel B, Signal Difference Too High"},
    {0x0050, "Thumb Wheel C, Signal 1, Out Of Range"},
    {0x0051, "Thumb Wheel C, Signal 2, Out Of Range"},
    {0x0052, "Thumb Wheel C, Signal Difference Too High"},
    {0x0061, "Button 1 Timeout"},
    {0x0062, "Button 2 Timeout"},
    {0x0063, "Button 3 Timeout"},
    {0x0064, "Button 4 Timeout"},
    {0x0065, "Button 5 Timeout"},
    {0x0066, "Button 6 Timeout"},
    {0x0067, "Button 7 Timeout"},
    {0x0068, "Button 8 Timeout"},
    {0x0069, "Button 9 Timeout"},
    {0x006A, "Button 10 Timeout"},
    {0x006B, "Button 11 Timeout"},
    {0x0070, "LED Message Timeout"},
};

std::string hex4(std::uint16_t v) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "%04Xh", v);
  return buf;
}

SdoWrite write_u8(std::uint16_t index, std::uint8_t sub, std::uint8_t v, std::string what) {
  return SdoWrite{index, sub, {v}, std::move(what)};
}
SdoWrite write_u16(std::uint16_t index, std::uint8_t sub, std::uint16_t v, std::string what) {
  return SdoWrite{index, sub, {static_cast<std::uint8_t>(v), static_cast<std::uint8_t>(v >> 8)}, std::move(what)};
}

}  // namespace

ElobauMfgDriver::ElobauMfgDriver(NodeId node, FrameSink sink, ElobauMfgOptions options) : opt_(options) {
  const std::int64_t lim = opt_.clamp_detent ? 100 : 110;
  for (const char* n : kAxisNames)
    signals_.push_back(
        SignalInfo{.name = n, .kind = SignalKind::Axis, .min = -lim, .max = lim, .neutral = 0, .unit = "percent"});
  for (std::size_t b = 1; b <= kButtons; ++b)
    signals_.push_back(SignalInfo{.name = "buttons[" + std::to_string(b) + "]",
                                  .kind = SignalKind::Button,
                                  .min = 0,
                                  .max = 1,
                                  .neutral = 0,
                                  .unit = "bits"});
  signals_.push_back(
      SignalInfo{.name = "presence", .kind = SignalKind::Button, .min = 0, .max = 1, .neutral = 0, .unit = "bits"});
  for (std::size_t l = 1; l <= kLeds; ++l)
    signals_.push_back(SignalInfo{.name = "leds[" + std::to_string(l) + "]",
                                  .kind = SignalKind::Output,
                                  .min = 0,
                                  .max = 2,
                                  .neutral = 0,
                                  .unit = "led"});
  init(node, std::move(sink), signals_.size());
  // TPDO #0 carries every axis's channel 1 and the buttons (§14.1), sent every cycle_ms (written
  // to 1800h:05 at boot) and on change; TPDO #1 only cross-checks (channel2_timeout_ms).
  // Both 8 bytes (§14.1, §14.2); TPDO #0 with the 2 ms inhibit time of Table 14.
  Carrier tpdo0{.cob_id = kTpdo0 + node.value(),
                .required = true,
                .comm_index = 0x1800,
                .event_timer_ms = opt_.cycle_ms,
                .transmission_type = 254,
                .signals = {},
                .length = 8,
                .inhibit_100us = 20};
  for (std::size_t i = 0; i < kFirstLed; ++i) tpdo0.signals.push_back(i);
  // TPDO #1 (channel 2 of the axes, same cycle, 1801h:05): once seen, its loss leaves the axes
  // unchecked, a doubt like any overdue PDO; a grip with TPDO #1 disabled never sends it.
  Carrier tpdo1{.cob_id = kTpdo1 + node.value(),
                .required = false,
                .comm_index = 0x1801,
                .event_timer_ms = opt_.cycle_ms,
                .transmission_type = 254,
                .signals = {},
                .length = 8};
  for (std::size_t a = 0; a < kAxes; ++a) tpdo1.signals.push_back(kX + a);
  set_carriers({tpdo0, tpdo1});
}

const char* ElobauMfgDriver::manufacturer_error_name(std::uint16_t code) {
  for (const auto& e : kManufacturerErrors)
    if (e.code == code) return e.name;
  return nullptr;
}

ExpectedIdentity ElobauMfgDriver::expected_identity() const {
  // Table 14: 1000h = 0 (no standard profile), 1018h:01 = 000000B4h (elobau). The product code
  // (00010003h in the table) depends on the grip variant ("refer to the product overview"):
  // not checked.
  ExpectedIdentity id;
  id.device_type = 0x00000000;
  id.vendor_id = 0x000000B4;
  return id;
}

std::vector<SdoWrite> ElobauMfgDriver::configuration() const {
  std::vector<SdoWrite> w;
  // §14.1/14.2: both TPDOs cyclic with the same period, so every channel-1 frame has its
  // channel-2 partner (a stored configuration may have disabled the timers).
  w.push_back(
      write_u16(0x1800, 5, opt_.cycle_ms, "TPDO #0 (channel 1) event timer " + std::to_string(opt_.cycle_ms) + " ms"));
  w.push_back(
      write_u16(0x1801, 5, opt_.cycle_ms, "TPDO #1 (channel 2) event timer " + std::to_string(opt_.cycle_ms) + " ms"));
  // §12.2: 4000h = 1 keeps the grip operational and sends the error value of the failed signal
  // (per-signal errors instead of the whole node going pre-operational/stopped).
  w.push_back(write_u8(0x4000, 0, 1, "error behaviour: no state change, error values in the PDOs"));
  // The codes this driver decodes (defaults of 20xxh:1Bh/1Ch and 2100h:09h/0Ah, which are PARA).
  for (std::size_t a = 0; a < kAxes; ++a) {
    const auto idx = static_cast<std::uint16_t>(kAxisIndex + a);
    w.push_back(
        write_u8(idx, 0x1B, static_cast<std::uint8_t>(kErrorValue), std::string(kAxisNames[a]) + " error value 126"));
    w.push_back(write_u8(idx, 0x1C, static_cast<std::uint8_t>(kNotAvailableValue),
                         std::string(kAxisNames[a]) + " not-available value 127"));
  }
  w.push_back(write_u8(0x2100, 0x09, 0, "buttons error value 0 (released)"));
  w.push_back(write_u8(0x2100, 0x0A, 0, "buttons not-available value 0 (released)"));
  // A never-saved grip with `parameter_checksum: save`: §8 "write "save" (0x65766173) into the
  // object 0x1010.1", last, so that what is saved is this configuration; the restart follows
  // (restart_after_configuration()).
  if (saving_) {
    SdoWrite save{0x1010, 1, {0x73, 0x61, 0x76, 0x65}, "store parameters \"save\" (4001h read 0002h: never saved)"};
    w.push_back(std::move(save));
  }
  return w;
}

void ElobauMfgDriver::boot_writes_made(const std::vector<SdoWrite>& writes) {
  // The mapping file's `sdo` list may configure the buttons the grip has (2100h:01h/02h, PARA).
  for (const SdoWrite& w : writes) {
    if (w.index != 0x2100 || w.data.size() != 1) continue;
    if (w.sub == 0x01) fitted_ = static_cast<std::uint16_t>((fitted_ & 0xFF00) | w.data[0]);
    if (w.sub == 0x02) fitted_ = static_cast<std::uint16_t>((fitted_ & 0x00FF) | (w.data[0] << 8));
  }
}

std::vector<std::uint32_t> ElobauMfgDriver::consumed_cob_ids() const {
  return {kTpdo0 + node().value(), kTpdo1 + node().value()};
}

bool ElobauMfgDriver::valid_value(std::int8_t v) const { return v >= -110 && v <= 110; }

std::int8_t ElobauMfgDriver::limit100(std::int8_t v) {
  if (v > 100) return 100;
  if (v < -100) return -100;
  return v;
}

bool ElobauMfgDriver::on_frame(const CanFrame& frame, TimePoint now) {
  const bool ours = !frame.rtr && !frame.extended;
  if (ours && frame.id == kTpdo0 + node().value()) {
    if (frame.dlc != 8) {
      ++counters_.wrong_length;
      return false;
    }
    on_tpdo0(frame, now);
    return true;
  }
  if (ours && frame.id == kTpdo1 + node().value()) {
    if (frame.dlc != 8) {
      ++counters_.wrong_length;
      return false;
    }
    on_tpdo1(frame, now);
    return true;
  }
  ++counters_.unknown_cob;
  return false;
}

bool ElobauMfgDriver::channels_disagree(std::int8_t ch1, std::int8_t ch2) const {
  return std::abs(limit100(ch1) - limit100(ch2)) > opt_.channel_tolerance;
}

void ElobauMfgDriver::on_tpdo0(const CanFrame& frame, TimePoint now) {
  for (std::size_t a = 0; a < kAxes; ++a) {
    const auto v = static_cast<std::int8_t>(frame.data[a]);
    if (!valid_value(v) && v != kErrorValue && v != kNotAvailableValue) ++stats_.out_of_range;
    Axis& ax = axes_[a];
    ax.ch1 = v;
    if (ax.suspect) {  // the channel 2 that disagreed against this newer channel 1
      ax.suspect = false;
      ax.mismatch = valid_value(v) && ax.ch2 && valid_value(*ax.ch2) && channels_disagree(v, *ax.ch2);
      if (ax.mismatch) ++counters_.mismatches;
    }
  }
  buttons_ = static_cast<std::uint16_t>(frame.data[5] | (frame.data[6] << 8));
  if (opt_.channel2_timeout_ms > 0) {
    if (!ch2_reference_) ch2_reference_ = now;
    channel2_late_ = now - *ch2_reference_ > std::chrono::milliseconds(opt_.channel2_timeout_ms);
    if (channel2_late_) ++stats_.channel2_missing;
  }
  publish_all(now);
}

void ElobauMfgDriver::on_tpdo1(const CanFrame& frame, TimePoint now) {
  for (std::size_t a = 0; a < kAxes; ++a) {
    Axis& ax = axes_[a];
    const auto v2 = static_cast<std::int8_t>(frame.data[a]);
    if (!valid_value(v2) && v2 != kErrorValue && v2 != kNotAvailableValue) ++stats_.out_of_range;
    ax.ch2 = v2;
    const bool ch1_ok = ax.ch1 && valid_value(*ax.ch1);
    const bool disagree = ch1_ok && valid_value(v2) && channels_disagree(*ax.ch1, v2);
    // A verdict already given holds while they disagree; a new disagreement waits for TPDO #0.
    ax.suspect = disagree && !ax.mismatch;
    ax.mismatch = disagree && ax.mismatch;
    // A good pair after an axis EMCY: the fault is over (the device sends 126 while it lasts).
    if (ch1_ok && (valid_value(v2) || v2 == kNotAvailableValue) && !disagree && ax.emcy) {
      ax.emcy = false;
      sync_faults(std::nullopt);
    }
  }
  ch2_reference_ = now;
  channel2_late_ = false;
  for (std::size_t a = 0; a < kAxes; ++a) publish_axis(a, now);
}

void ElobauMfgDriver::publish_axis(std::size_t a, TimePoint now) {
  const Axis& ax = axes_[a];
  const std::size_t index = kX + a;
  if (latched(index)) {  // an EMCY error shows at once, PDO or not
    update(index, signals_[index].neutral, SignalStatus::Error, now);
    return;
  }
  if (!ax.ch1) {  // Offline until channel 1 arrives (back to Offline when a latch clears)
    if (value(index).status == SignalStatus::Error) update(index, signals_[index].neutral, SignalStatus::Offline, now);
    return;
  }
  const std::int8_t v = *ax.ch1;
  SignalStatus status = SignalStatus::Valid;
  if (v == kNotAvailableValue) {
    status = SignalStatus::NotAvailable;
  } else if (!valid_value(v)) {
    status = SignalStatus::Error;  // 126, or a value the document does not define
  } else if (ax.ch2 && *ax.ch2 != kNotAvailableValue && !valid_value(*ax.ch2)) {
    status = SignalStatus::Error;  // channel 2 reports an error (or nonsense)
  } else if (ax.mismatch || channel2_late_) {
    status = SignalStatus::Error;
  }
  if (status != SignalStatus::Valid) {
    update(index, signals_[index].neutral, status, now);
    return;
  }
  update(index, opt_.clamp_detent ? limit100(v) : v, status, now);
}

void ElobauMfgDriver::publish_buttons(TimePoint now) {
  // An EMCY error shows at once; otherwise a button stays Offline until TPDO #0 arrives.
  auto one = [&](std::size_t index, std::size_t bit) {
    if (latched(index)) {
      update(index, 0, SignalStatus::Error, now);
    } else if (buttons_ && ((fitted_ >> bit) & 1u) == 0) {
      update(index, 0, SignalStatus::NotAvailable, now);  // 2100h:01h/02h: the grip has no such button
    } else if (buttons_) {
      update(index, (*buttons_ >> bit) & 1u, SignalStatus::Valid, now);
    } else if (value(index).status == SignalStatus::Error) {
      update(index, 0, SignalStatus::Offline, now);
    }
  };
  for (std::size_t b = 0; b < kButtons; ++b) one(kFirstButton + b, b);
  one(kPresence, 11);  // button 12 = presence sensor (§15.2.1)
}

void ElobauMfgDriver::publish_all(TimePoint now) {
  // Not online (booting, lost): the inputs stay Offline, whatever an EMCY latched meanwhile; the
  // latches show as Error with the first PDO after on_online().
  if (!online_) return;
  for (std::size_t a = 0; a < kAxes; ++a) publish_axis(a, now);
  publish_buttons(now);
}

DecodedEmcy ElobauMfgDriver::on_emcy(const EmcyMessage& emcy, TimePoint now) {
  DecodedEmcy d;
  d.code = emcy.code;
  switch (emcy.code) {
    case 0x0000: {  // §12.4: error reset or no error
      d.error = false;
      d.text = "elobau EMCY 0000h: error reset";
      clear_faults();
      publish_all(now);
      for (std::size_t l = 0; l < kLeds; ++l)
        if (leds_[l]) update(kFirstLed + l, value(kFirstLed + l).value, SignalStatus::Valid, now);
      return d;
    }
    case 0x8110:
    case 0x8120:
    case 0x8140: {  // §12.4: communication warnings; the values the device sends stay valid
      d.error = false;
      d.text = emcy.code == 0x8110 ? "elobau EMCY 8110h: CAN overrun (object lost)"
               : emcy.code == 0x8120
                   ? "elobau EMCY 8120h: CAN in error passive mode"
                   : "elobau EMCY 8140h: recovered from bus off (count " + std::to_string(emcy.msef[0]) + ")";
      return d;
    }
    case 0x1000: break;  // §12.4: generic error = manufacturer specific (4001h)
    default:
      if ((emcy.code & 0xFF00) == 0x8100) {  // §12.4 "0x81xx: Communication": a warning as the three above
        d.error = false;
        d.text = "elobau EMCY " + hex4(emcy.code) + ": CAN communication (warning)";
        return d;
      }
      ++counters_.unknown_emcy;
      d.error = false;
      d.text = "elobau EMCY " + hex4(emcy.code) + ": unknown code (ignored)";
      return d;
  }
  // Table 5: 4001h in bytes 3..4; the device uses only byte 3 (byte 4 is 00h, or FFh "not used").
  const std::uint16_t m =
      emcy.msef[1] == 0xFF ? emcy.msef[0] : static_cast<std::uint16_t>(emcy.msef[0] | (emcy.msef[1] << 8));
  const char* name = manufacturer_error_name(m);
  if (name == nullptr) {
    ++counters_.unknown_emcy;
    d.error = false;
    d.text = "elobau EMCY 1000h, 4001h " + hex4(m) + ": unknown manufacturer code (ignored)";
    return d;
  }
  d.text = "elobau 4001h " + hex4(m) + ": " + name;
  // Table 6: 0002h at power-on is the never-saved grip; 4001h holds one code, so a later error at
  // boot hides it from the read-back: its EMCY counts as the read-back would.
  if (m == 0x0002 && !online_) unsaved_at_boot_ = true;
  d.affected = apply_manufacturer_code(m, now);
  d.error = !d.affected.empty();
  if (m == 0x0002)
    d.text += " (never saved, or corrupt: every input faulted until 4001h is read back at the next boot)";
  return d;
}

// An axis EMCY: the channel values received before it say nothing about the fault, so only a
// good pair of TPDO #0 and #1 both received after it clears it (on_tpdo1).
void ElobauMfgDriver::latch_axis(std::size_t a) {
  Axis& ax = axes_[a];
  ax.emcy = true;
  ax.ch1.reset();
  ax.ch2.reset();
  ax.suspect = false;
  ax.mismatch = false;
}

std::vector<std::size_t> ElobauMfgDriver::apply_manufacturer_code(std::uint16_t m, TimePoint now) {
  std::vector<std::size_t> affected;
  if (m >= 0x0010 && m <= 0x0052 && (m & 0x0F) <= 2) {
    const std::size_t a = (m >> 4) - 1;
    latch_axis(a);
    affected = {kX + a};
  } else if (m >= 0x0061 && m <= 0x006B) {
    const std::size_t b = m - 0x0061;
    button_emcy_[b] = true;
    affected = {kFirstButton + b};
  } else if (m == 0x0070) {
    led_emcy_ = true;
    for (std::size_t l = 0; l < kLeds; ++l) affected.push_back(kFirstLed + l);
  } else if (m == 0x0000 || m == 0x0001 || m == 0x0002 || m == 0x0005) {
    // The whole device is in doubt. 0002h: at power-on a grip never saved (the read-back at boot
    // decides, on_boot_read), at run time corrupt parameters.
    global_emcy_ = true;
    for (std::size_t i = 0; i < kFirstLed; ++i) affected.push_back(i);
  }
  sync_faults(now);
  publish_all(now);  // an EMCY error shows at once, PDO or not
  if (led_emcy_)
    for (std::size_t l = 0; l < kLeds; ++l) update(kFirstLed + l, value(kFirstLed + l).value, SignalStatus::Error, now);
  return affected;
}

void ElobauMfgDriver::sync_faults(std::optional<TimePoint> now) {
  for (std::size_t i = 0; i < signals_.size(); ++i) {
    if (latched(i)) {
      set_fault(i, now);
    } else {
      clear_fault(i);
    }
  }
}

bool ElobauMfgDriver::latched(std::size_t i) const {
  if (i >= kFirstLed) return led_emcy_;
  if (i == kPresence) return global_emcy_ || button_emcy_[11];  // button 12 = presence sensor (§15.2.1)
  if (i >= kFirstButton) return global_emcy_ || button_emcy_[i - kFirstButton];
  return global_emcy_ || axes_[i - kX].emcy;
}

std::string ElobauMfgDriver::latch_key(std::size_t i) const {
  if (i >= kFirstLed) return "led_emcy";
  if (global_emcy_) return "global_emcy";
  if (i >= kFirstButton) return "button_emcy";
  return "axis." + std::to_string(i - kX) + ".emcy";
}

void ElobauMfgDriver::clear_faults() {
  global_emcy_ = false;
  led_emcy_ = false;
  button_emcy_.fill(false);
  for (auto& ax : axes_) ax.emcy = false;
  sync_faults(std::nullopt);
}

std::vector<std::pair<std::uint16_t, std::uint8_t>> ElobauMfgDriver::boot_reads() const {
  std::vector<std::pair<std::uint16_t, std::uint8_t>> reads;
  if (!error_code_read_) reads.emplace_back(0x4001, 0);
  if ((fitted_read_ & 0x01) == 0) reads.emplace_back(0x2100, 0x01);
  if ((fitted_read_ & 0x02) == 0) reads.emplace_back(0x2100, 0x02);
  return reads;
}

bool ElobauMfgDriver::on_boot_read(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                                   std::string& error) {
  if (index == 0x2100 && (sub == 0x01 || sub == 0x02)) {
    fitted_read_ |= sub;  // sub 1 -> bit 0, sub 2 -> bit 1
    if (data.size() != 1) {
      error = "2100h sub " + std::to_string(sub) + " (buttons fitted, UNSIGNED8) answered " +
              std::to_string(data.size()) + " bytes: which buttons the grip has is unknown";
      return false;
    }
    fitted_ = sub == 0x01 ? static_cast<std::uint16_t>((fitted_ & 0xFF00) | data[0])
                          : static_cast<std::uint16_t>((fitted_ & 0x00FF) | (data[0] << 8));
    return true;
  }
  if (index != 0x4001 || sub != 0) return true;
  error_code_read_ = true;
  // Table 14 4001h "Error Code", 0: no error. No error: every fault latched before is over (the
  // grip rebooted, or it recovered while the gateway did not see its 0000h). An error code: it
  // faults what its EMCY would, beside what is latched (4001h holds one code only).
  if (data.size() != 2) return true;  // 4001h is UNSIGNED16: another length is no evidence, the faults stay
  const auto m = static_cast<std::uint16_t>(data[0] | (data[1] << 8));
  if (m == 0x0002 || unsaved_at_boot_) {
    // Never saved, or corrupt (Table 6): see the header. Saved once and restarted, still 0002h:
    // corrupt.
    if (opt_.save_unsaved && !save_tried_) {
      saving_ = true;
      save_tried_ = true;
      global_emcy_ = true;
      sync_faults(std::nullopt);
      return true;
    }
    const std::string seen = m == 0x0002 ? "4001h reads 0002h"
                                         : "EMCY 1000h with 4001h 0002h came at boot (4001h now reads " + hex4(m) + ")";
    error = save_tried_
                ? seen +
                      " still, after 1010h:01 \"save\" and a restart (Table 6 parameter checksum error): the "
                      "grip's parameter memory is corrupt; replace the grip"
                : seen +
                      " (Table 6 \"Parameter Checksum Error ... also set until first parameter saving process\"): "
                      "the grip's parameters were never saved (or are corrupt), and while 0002h stands the end of "
                      "any other error cannot be seen (4001h holds one code, no 0000h comes); commission it once: "
                      "with the grip pre-operational write 1010h:01 = 65766173h (\"save\", oegw ctl: w 0x1010 1 "
                      "u32 0x65766173) and power-cycle it, or set option parameter_checksum: save to let the "
                      "gateway do it at boot (docs/design/device-documents.md#elobau-mfg-elobau-mfg-document-000-12)";
    return false;
  }
  save_tried_ = false;
  if (m == 0) {
    clear_faults();
  } else if (manufacturer_error_name(m) != nullptr) {
    // As its EMCY would, without a status change: the signals are Offline during the boot.
    if (m >= 0x0010 && m <= 0x0052 && (m & 0x0F) <= 2) latch_axis((m >> 4) - 1);
    if (m >= 0x0061 && m <= 0x006B) button_emcy_[m - 0x0061] = true;
    if (m == 0x0070) led_emcy_ = true;
    if (m == 0x0000 || m == 0x0001 || m == 0x0005) global_emcy_ = true;
    sync_faults(std::nullopt);
  }
  return true;
}

bool ElobauMfgDriver::on_boot_read_abort(std::uint16_t index, std::uint8_t /*sub*/, canopen::SdoAbortCode /*code*/) {
  if (index == 0x4001) error_code_read_ = true;  // no evidence either way: the faults stay
  // 2100h refused (Table 14 lists it): which buttons the grip has is unknown, the node is refused.
  return index == 0x4001;
}

std::array<std::uint8_t, 8> ElobauMfgDriver::led_payload() const {
  std::array<std::uint8_t, 8> p;
  p.fill(0xFF);  // every position "no change", spares included
  for (std::size_t l = 0; l < kLeds; ++l) {
    if (!leds_[l]) continue;
    const LedPos pos = kLedPos[l];
    p[pos.byte] = static_cast<std::uint8_t>((p[pos.byte] & ~(kNoChange << pos.shift)) | (*leds_[l] << pos.shift));
  }
  return p;
}

bool ElobauMfgDriver::set_output(std::size_t index, std::int64_t v, TimePoint now) {
  if (index < kFirstLed || index >= kFirstLed + kLeds || v < 0 || v > 2) return false;
  const std::size_t l = index - kFirstLed;
  const auto code = static_cast<std::uint8_t>(v);  // 0 off 00, 1 on 01, 2 blink 10 (Table 13)
  const bool unchanged = leds_[l] == code && leds_sent_;
  leds_[l] = code;
  leds_dirty_ = leds_dirty_ || !unchanged;
  if (!outputs_deferred()) flush_outputs(now);
  update(index, v, led_emcy_ ? SignalStatus::Error : SignalStatus::Valid, now);
  return true;
}

void ElobauMfgDriver::flush_outputs(TimePoint /*now*/) {
  if (!leds_dirty_) return;
  leds_dirty_ = false;
  const auto p = led_payload();
  send(CanFrame(kRpdo0 + node().value(), std::span<const std::uint8_t>(p.data(), p.size())));
  leds_sent_ = true;
}

void ElobauMfgDriver::reset_state() {
  // The values go; the faults stay until the device's evidence (4001h at the next boot).
  for (auto& ax : axes_) ax = Axis{.emcy = ax.emcy};
  buttons_.reset();
  channel2_late_ = false;
  ch2_reference_.reset();
}

void ElobauMfgDriver::on_online(TimePoint now) {
  online_ = true;
  reset_state();
  leds_sent_ = false;
  leds_dirty_ = false;
  bool any = false;
  for (const auto& l : leds_) any = any || l.has_value();
  if (any) {
    leds_dirty_ = true;  // sent now, or at the end of the caller's output batch
    if (!outputs_deferred()) flush_outputs(now);
    for (std::size_t l = 0; l < kLeds; ++l)
      if (leds_[l]) update(kFirstLed + l, value(kFirstLed + l).value, SignalStatus::Valid, now);
  }
}

void ElobauMfgDriver::on_offline(TimePoint now) {
  online_ = false;
  Driver::on_offline(now);
  reset_state();
  leds_sent_ = false;
}

const std::vector<OptionSpec>& elobau_mfg_options() {
  using T = OptionSpec::Type;
  static const std::vector<OptionSpec> table = {
      {.name = "channel_tolerance",
       .type = T::Integer,
       .ranges = {{0, 100}},
       .unit = "percent",
       .default_value = "5",
       .description = "largest difference between an axis's channel 1 (TPDO #0) and its redundant channel 2 "
                      "(TPDO #1), both limited to +-100, before the axis is Error; a larger value lets a "
                      "drifting or miscalibrated sensor pass the cross-check",
       .safety = true},
      {.name = "detent",
       .type = T::Choice,
       .choices = {"pass", "clamp"},
       .default_value = "pass",
       .description = "pass: the end-of-travel detent +-110 (section 15.1.2) is reported as it is, a press the "
                      "mapping may use; clamp: reported as +-100. Sets the axes' range, so what full deflection "
                      "means to the FE",
       .safety = true},
      {.name = "channel2_timeout_ms",
       .type = T::Integer,
       .ranges = {{0, 600000}},
       .unit = "ms",
       .default_value = "0",
       .description = "0: a grip that sends no channel 2 (TPDO #1 disabled) is no error, its axes stay Valid "
                      "unchecked; > 0: every axis is Error while the last channel 2 is older than this when "
                      "channel 1 arrives. Must exceed cycle_ms",
       .safety = true},
      {.name = "cycle_ms",
       .type = T::Integer,
       .ranges = {{5, 65535}},
       .unit = "ms",
       .default_value = "100",
       .note = "(the document's 5 ms coding cycle)",
       .description = "TPDO #0 / #1 event timers written at boot (1800h:05, 1801h:05); a TPDO missing for 3 "
                      "cycles makes its signals Stale"},
      {.name = "parameter_checksum",
       .type = T::Choice,
       .choices = {"refuse", "save"},
       .default_value = "refuse",
       .note = "(refuse: commission the grip by hand; save: the gateway saves it once)",
       .description = "a grip whose 4001h reads 0002h at boot (parameters never saved, Table 6): refuse: the node "
                      "is refused, the reason says how to save it; save: the gateway writes 1010h:01 \"save\" and "
                      "restarts it once (refused if 0002h stays: corrupt). At run time 0002h faults every input"},
      freshness_floor_option("200"),
  };
  return table;
}

std::unique_ptr<Driver> make_elobau_mfg_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                               OptionRefusals& refusals) {
  ElobauMfgOptions o;
  const bool ok = parse_options(
      "elobau-mfg", elobau_mfg_options(), options,
      [&o](const OptionValue& v, std::string& /*error*/) {
        const std::string_view name = v.spec->name;
        if (name == "channel_tolerance") o.channel_tolerance = static_cast<int>(v.number);
        if (name == "detent") o.clamp_detent = v.text == "clamp";
        if (name == "channel2_timeout_ms") o.channel2_timeout_ms = static_cast<std::uint32_t>(v.number);
        if (name == "cycle_ms") o.cycle_ms = static_cast<std::uint16_t>(v.number);
        if (name == "parameter_checksum") o.save_unsaved = v.text == "save";
        if (name == kFreshnessFloorOption) o.freshness_floor_ms = static_cast<std::uint32_t>(v.number);
        return true;
      },
      refusals);
  if (!ok) return nullptr;
  if (o.channel2_timeout_ms != 0 && o.channel2_timeout_ms <= o.cycle_ms) {
    refusals.push_back(
        {options.get("channel2_timeout_ms") ? "channel2_timeout_ms" : "cycle_ms",
         "elobau-mfg: channel2_timeout_ms must exceed cycle_ms (" + std::to_string(o.cycle_ms) + " ms)"});
    return nullptr;
  }
  if (!node.valid()) {
    refusals.push_back({"", "elobau-mfg: node-ID " + std::to_string(node.value()) + " is not 1..127"});
    return nullptr;
  }
  auto d = std::make_unique<ElobauMfgDriver>(node, std::move(sink), o);
  apply_freshness_floor(*d, o.freshness_floor_ms);
  return d;
}

std::unique_ptr<Driver> make_elobau_mfg_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                               std::string& error) {
  return with_error_text(error, [&](OptionRefusals& refusals) {
    return make_elobau_mfg_driver(node, std::move(sink), options, refusals);
  });
}

// The channels' last values and latches (an axis EMCY holds until a good pair or the error
// reset), the buttons, the EMCY latches, what this boot read (4001h, 2100h), the save's progress
// (§8, Table 6 0002h) and the LEDs as last commanded.
void ElobauMfgDriver::export_family_state(canopen::StateWriter& w) const {
  w.put("stats.out_of_range", stats_.out_of_range);
  w.put("stats.channel2_missing", stats_.channel2_missing);
  for (std::size_t a = 0; a < kAxes; ++a) {
    const Axis& x = axes_[a];
    const canopen::StateWriter::Scope axis(w, "axis." + std::to_string(a));
    w.put("ch1", x.ch1);
    w.put("ch2", x.ch2);
    w.put("mismatch", x.mismatch);
    w.put("suspect", x.suspect);
    w.put("emcy", x.emcy);
  }
  w.put("buttons", buttons_);
  std::uint32_t button_emcy = 0;
  for (std::size_t b = 0; b < kButtons; ++b) button_emcy |= button_emcy_[b] ? 1u << b : 0u;
  w.put("button_emcy", button_emcy);
  w.put("global_emcy", global_emcy_);
  w.put("led_emcy", led_emcy_);
  w.put("online", online_);
  w.put("error_code_read", error_code_read_);
  w.put("fitted_read", fitted_read_);
  w.put("fitted", fitted_);
  w.put("saving", saving_);
  w.put("unsaved_at_boot", unsaved_at_boot_);
  w.put("save_tried", save_tried_);
  w.put("channel2_late", channel2_late_);
  w.put("ch2_reference", ch2_reference_);
  for (std::size_t l = 0; l < kLeds; ++l) {
    if (leds_[l]) w.put("led." + std::to_string(l), *leds_[l]);
  }
  w.put("leds_sent", leds_sent_);
}

void ElobauMfgDriver::import_family_state(const canopen::StateReader& r) {
  stats_ = Stats{r.get<std::uint64_t>("stats.out_of_range"), r.get<std::uint64_t>("stats.channel2_missing")};
  for (std::size_t a = 0; a < kAxes; ++a) {
    const canopen::StateReader x = r.in("axis." + std::to_string(a));
    axes_[a] = Axis{x.optional<std::int8_t>("ch1"), x.optional<std::int8_t>("ch2"), x.get<bool>("mismatch"),
                    x.get<bool>("suspect"), x.get<bool>("emcy")};
  }
  buttons_ = r.optional<std::uint16_t>("buttons");
  const auto button_emcy = r.get<std::uint16_t>("button_emcy");
  for (std::size_t b = 0; b < kButtons; ++b) button_emcy_[b] = ((button_emcy >> b) & 1u) != 0;
  global_emcy_ = r.get<bool>("global_emcy");
  led_emcy_ = r.get<bool>("led_emcy");
  online_ = r.get<bool>("online");
  error_code_read_ = r.get<bool>("error_code_read");
  fitted_read_ = r.get<std::uint8_t>("fitted_read");
  fitted_ = r.get<std::uint16_t>("fitted");
  saving_ = r.get<bool>("saving");
  unsaved_at_boot_ = r.get<bool>("unsaved_at_boot");
  save_tried_ = r.get<bool>("save_tried");
  channel2_late_ = r.get<bool>("channel2_late");
  ch2_reference_ = r.optional_time("ch2_reference");
  for (std::size_t l = 0; l < kLeds; ++l) {
    const std::string key = "led." + std::to_string(l);
    leds_[l] = r.optional<std::uint8_t>(key);
    // set_output() takes 0 off, 1 on, 2 blink (Table 13; 3 is "no change", never commanded).
    if (leds_[l] && *leds_[l] > 2) r.fail(key, "is no LED code the gateway commands");
  }
  leds_sent_ = r.get<bool>("leds_sent");
  // The EMCY latches decide the faults (sync_faults).
  for (std::size_t i = 0; i < signals_.size(); ++i) {
    if (faulted(i) != latched(i)) r.fail(latch_key(i), "differs from signal " + std::to_string(i) + "'s fault");
  }
}

}  // namespace oegw::subdevices
