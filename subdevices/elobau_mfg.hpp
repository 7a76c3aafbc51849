// elobau MFG 34xG / 36xG multifunction joystick grips (family "elobau-mfg").
// Source: "CANopen Protocol for MFG 34xG and 36xG" v01.21 (elobau, 2014-03-10); section
// numbers below are that document's.
//
// Frames (default node-ID 0x11, 250 kbit/s, §7):
//   TPDO #0  180h+id  8 bytes (§14.1, Table 7): X, Y, wheel A, B, C channel 1 (S8 %), buttons 1..8,
//                     buttons 9..16 (bit n-1 = button n, 1 = pressed, Table 12), FFh (4002h).
//   TPDO #1  280h+id  8 bytes (§14.2, Table 8): the five channel-2 values (S8 %), FFh FFh FFh.
//   RPDO #0  200h+id  8 bytes (§14.3, Table 9): LED commands, 2 bits per LED (Table 13:
//                     00 off, 01 on, 10 blink, 11 no change).
//   EMCY     80h+id   (§12.3, Table 5): code, 1001h (always 0), 4001h manufacturer code in bytes
//                     3..4 (the device uses only byte 3), FFh.
//
// Signals (index order):
//   x, y, wheel_a, wheel_b, wheel_c   Axis, percent, -110..110 (detent "pass") or -100..100
//                                     ("clamp"), neutral 0. ±110 is the detent (§15.1.2).
//   buttons[1]..buttons[16]           Button, 0/1, neutral 0 (TPDO #0 bytes 5, 6).
//   presence                          Button, 0/1: button 12 is the presence sensor (§15.2.1),
//                                     the same bit as buttons[12] under an explicit name.
//   leds[1]..leds[16]                 Output, 0 off / 1 on / 2 blink. leds[i] is bit i-1 of the
//                                     LED mask 2200h:0Ah (Table 14): 1..10 = buttons 1..5 LED 1/2,
//                                     11/12 = wheel A LED 2-2 / 2-1 (alt. button 8 LED 1/2),
//                                     13/14 = wheel B LED 2-2 / 2-1 (alt. button 9 LED 1/2),
//                                     15 = wheel A LED 1+3 (alt. button 10 LED 1),
//                                     16 = wheel B LED 1+3 (alt. button 10 LED 2).
//
// Axis rules (channel 1 = TPDO #0 is the value; channel 2 = TPDO #1 is the cross-check):
//   * channel 1 = 126 (error value 20xxh:1Bh) -> Error; 127 (not-available value 1Ch) ->
//     NotAvailable; any other value outside -110..110 -> Error (stats().out_of_range).
//   * channel 2 = 126 -> Error (the redundant sensor failed); 127 -> no cross-check (a
//     single-channel axis, 20xxh:01h = 1).
//   * |ch1 - ch2| > channel_tolerance (both limited to ±100 first: the detent is a jump from 100
//     to 110 at the same mechanical end, §15.1.2) -> Error, counters().mismatches++. The pair is
//     compared when TPDO #1 arrives, against the last TPDO #0. The two TPDOs have their own event
//     timers and only TPDO #0 an inhibit time (2 ms, Table 14): after a movement TPDO #1 can
//     carry the new channel 2 before TPDO #0 may carry the new channel 1. So a TPDO #1 that
//     disagrees is only a suspicion, decided by the next TPDO #0: if its channel 1 still
//     disagrees with that channel 2, the axis is Error (mismatches++), else the pair was just
//     out of step. A real disagreement is thus reported one TPDO #0 later (within its inhibit
//     time when the stick moves, at most one cycle when it rests); the verdict then holds until a
//     TPDO #1 agrees. Comparing every TPDO #0 with the last TPDO #1 would flag every fast
//     movement for the instant between the two frames.
//   * No TPDO #1 at all is not an error by default (a grip may have TPDO #1 disabled): the axis
//     stays Valid on channel 1, unchecked. Option channel2_timeout_ms > 0 makes it one: every
//     axis is Error while the last TPDO #1 (or, before the first, the first TPDO #0 after
//     on_online) is older than that when a TPDO #0 arrives (stats().channel2_missing).
//   * After power-on and bus-off the device sends 0 for a deflected axis until it has been at
//     zero (§4): a value of 0 that the driver cannot tell from neutral, hence nothing to do.
//
// EMCY (§12.4, §12.5 Table 6): 1000h carries the 4001h code; the driver names it and faults
// (Driver::faulted):
//   0010h..0012h -> x, 0020h.. -> y, 0030h.. -> wheel_a, 0040h.. -> wheel_b, 0050h.. -> wheel_c
//     until a good channel pair follows (with 4000h = 1 the device keeps sending the error value
//     126 while the fault lasts, §12.2) or the error reset;
//   0061h..006Bh (button 1..11 timeout) -> that button until the error reset 0000h (the button
//     error value 2100h:09h is 0, which a PDO cannot tell from "released");
//   0000h (no manufacturer code), 0001h, 0005h -> every input until the error reset;
//   0070h (LED message timeout) -> leds[*] (status Error) until the error reset;
//   0002h (parameter checksum, "also set until first parameter saving process") -> every input
//     until the read-back at the next boot decides (below): at run time it can only mean corrupt
//     parameters;
//   0003h/0004h ("not used") and other codes -> counters().unknown_emcy, ignored.
//   8110h/8120h/8140h (CAN overrun / error passive / recovered from bus-off, byte 3 = bus-off
//   count): warnings (error = false), they invalidate no value the device sends.
// Read-back at every (re)start (boot_reads()): 4001h "Error Code" (Table 14, 0: no error). 0
// clears every fault latched before (a grip that rebooted or recovered unseen); a Table 6 code
// faults what its EMCY would. Going offline and coming back keep the faults meanwhile.
//
// A never-saved grip (4001h = 0002h at boot, Table 6 "also set until first parameter saving
// process"): 4001h holds one code and the document sends no 0000h while an error lasts (§12.4),
// so while 0002h stands no other error could be seen to end: a latch the grip cannot clear, or
// (ignoring it) a grip whose errors pass unseen. Neither is taken: with `parameter_checksum:
// refuse` (the default) the node is refused at boot with the commissioning step in the reason;
// with `parameter_checksum: save` the driver writes 1010h:01 "save" (65766173h, §8) at the end of
// its configuration and asks for the restart §8 requires ("Restart the joystick after saving
// procedure", restart_after_configuration()); if 4001h still reads 0002h after that, the grip's
// parameter memory is corrupt and it is refused.
//
// Buttons the grip has: 2100h:01h / 02h "Configuration 8_1 / 16_9" (Table 14, 0: button not
// available; default 63 = buttons 1..6), read at every boot (or as the mapping file's `sdo` list
// writes them): a button the grip does not have is NotAvailable, never "valid, released" (its bit
// in TPDO #0 is the not-available value 2100h:0Ah, 0 as written here, §15.2).
//
// TPDOs (Table 14 18xxh:02 = 254, "transmission event is manufacturer specific, i.e. event
// timer"): a grip may send them on change and on its timer, or on its timer only. Both work; on
// the timer alone a change reaches the gateway up to cycle_ms late and a press shorter than
// cycle_ms may not be seen: such a grip wants a short cycle_ms
// (docs/design/device-documents.md#elobau-mfg-elobau-mfg-document-000-12).
//
// Outputs: set_output(leds[i]) sends RPDO #0 carrying the whole remembered LED state (LEDs never
// commanded as 11 "no change", spare positions 11). The device applies the last command it got
// and refreshes its LEDs only every 100 ms (§14.3): a frame per LED with "no change" elsewhere
// could be overwritten in 2200h before the device acted on it, a full frame cannot. An
// unchanged value sends nothing; on_online() sends the state again (the grip forgot it when it
// rebooted). §14.3 asks for at most one RPDO per 100 ms: callers should not toggle faster.
//
// Boot: expected_identity() checks 1000h = 0 and vendor-ID 1018h:01 = B4h (Table 14); the product
// code (00010003h in Table 14) depends on the grip variant and is not checked. configuration()
// writes 1800h:05/1801h:05 = cycle_ms, 4000h = 1 (§12.2: stay operational, send error values),
// 20xxh:1Bh/1Ch = 126/127 and 2100h:09h/0Ah = 0 (the codes decoded here). Heartbeat (1017h) is
// the network manager's; transmission types are ro (254) and not written.
//
// Options (the table elobau_mfg_options() in elobau_mfg.cpp is what the factory parses and
// `oegw signals` lists): channel_tolerance (percent, 0..100, default 5); detent = "pass" (default: ±110 is
// reported as is, a deliberate detent press the mapping layer may use) | "clamp" (±110 -> ±100);
// channel2_timeout_ms (0 = off, default); cycle_ms (TPDO event timers written at boot, 5..65535,
// default 100, §14.2 Notice: not below 5 ms).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "subdevices/driver.hpp"

namespace oegw::subdevices {

struct ElobauMfgOptions {
  int channel_tolerance = 5;
  bool clamp_detent = false;
  std::uint32_t channel2_timeout_ms = 0;
  std::uint16_t cycle_ms = 100;
  // Table 6 0002h "Parameter Checksum Error CRC32. This error is also set until first parameter
  // saving process", read back at boot: false (`parameter_checksum: refuse`, the default) refuses
  // the node; true (`parameter_checksum: save`) saves the grip's parameters once and restarts it.
  bool save_unsaved = false;
  std::uint32_t freshness_floor_ms = 200;  // Driver::set_freshness_floor
};

class ElobauMfgDriver final : public Driver {
 public:
  static constexpr std::size_t kAxes = 5;
  static constexpr std::size_t kButtons = 16;
  static constexpr std::size_t kLeds = 16;
  // Signal indices.
  static constexpr std::size_t kX = 0;
  static constexpr std::size_t kFirstButton = kAxes;                 // buttons[1]
  static constexpr std::size_t kPresence = kFirstButton + kButtons;  // 21
  static constexpr std::size_t kFirstLed = kPresence + 1;            // leds[1] = 22
  static constexpr std::size_t kSignalCount = kFirstLed + kLeds;     // 38

  static constexpr std::int8_t kErrorValue = 126;         // 20xxh:1Bh default
  static constexpr std::int8_t kNotAvailableValue = 127;  // 20xxh:1Ch default

  struct Stats {
    std::uint64_t out_of_range = 0;      // channel values outside -110..110 besides 126/127
    std::uint64_t channel2_missing = 0;  // TPDO #0 received while TPDO #1 overdue (option set)
  };

  ElobauMfgDriver(NodeId node, FrameSink sink, ElobauMfgOptions options);

  [[nodiscard]] std::string_view family() const override { return "elobau-mfg"; }
  [[nodiscard]] const std::vector<SignalInfo>& signals() const override { return signals_; }
  [[nodiscard]] ExpectedIdentity expected_identity() const override;
  [[nodiscard]] std::vector<SdoWrite> configuration() const override;
  // 5999h "LSS": bit rate (sub 1), node-ID (sub 2) and their store (sub 3) by SDO (document §7);
  // 5000h "Auto NMT Start" (Annex A: the grip's own NMT startup, as 1F80h); 2200h the LEDs the
  // gateway drives (its output signals).
  [[nodiscard]] bool protects(std::uint16_t index, std::uint8_t /*sub*/) const override {
    return index == 0x5999 || index == 0x5000 || index == 0x2200;
  }
  // 4001h "Error Code" (Table 14), read back at every (re)start: it decides the faults; 2100h:01h
  // and 02h: the buttons the grip has.
  void begin_boot() override {
    error_code_read_ = false;
    fitted_read_ = 0;
    saving_ = false;
    unsaved_at_boot_ = false;
  }
  [[nodiscard]] std::vector<std::pair<std::uint16_t, std::uint8_t>> boot_reads() const override;
  bool on_boot_read(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                    std::string& error) override;
  bool on_boot_read_abort(std::uint16_t index, std::uint8_t sub, canopen::SdoAbortCode code) override;
  void on_application_reset(TimePoint /*now*/) override {}  // the 4001h read-back decides
  [[nodiscard]] bool restart_after_configuration() const override { return saving_; }
  // The buttons the grip has (bit n-1 = button n), as read or written at the last boot.
  [[nodiscard]] std::uint16_t fitted_buttons() const { return fitted_; }
  bool on_frame(const CanFrame& frame, TimePoint now) override;
  DecodedEmcy on_emcy(const EmcyMessage& emcy, TimePoint now) override;
  [[nodiscard]] std::vector<std::uint32_t> consumed_cob_ids() const override;
  void on_online(TimePoint now) override;
  void on_offline(TimePoint now) override;
  bool set_output(std::size_t index, std::int64_t value, TimePoint now) override;

  [[nodiscard]] const Stats& stats() const { return stats_; }
  [[nodiscard]] const ElobauMfgOptions& options() const { return opt_; }
  // The RPDO #0 payload for the remembered LED state (what set_output sends).
  [[nodiscard]] std::array<std::uint8_t, 8> led_payload() const;
  // Table 6 name of a 4001h manufacturer code, nullptr for an unknown one.
  [[nodiscard]] static const char* manufacturer_error_name(std::uint16_t code);

 private:
  void flush_outputs(TimePoint now) override;
  void boot_writes_made(const std::vector<SdoWrite>& writes) override;
  void export_family_state(canopen::StateWriter& w) const override;
  void import_family_state(const canopen::StateReader& r) override;
  struct Axis {
    std::optional<std::int8_t> ch1;
    std::optional<std::int8_t> ch2;
    bool mismatch = false;
    bool suspect = false;  // the last TPDO #1 disagreed: the next TPDO #0 decides
    bool emcy = false;     // latched by an axis EMCY, cleared by a good pair or the error reset
  };
  [[nodiscard]] bool channels_disagree(std::int8_t ch1, std::int8_t ch2) const;
  void latch_axis(std::size_t a);
  void on_tpdo0(const CanFrame& frame, TimePoint now);
  void on_tpdo1(const CanFrame& frame, TimePoint now);
  void publish_axis(std::size_t a, TimePoint now);
  void publish_buttons(TimePoint now);
  void publish_all(TimePoint now);
  void reset_state();
  // Latches a Table 6 code's fault; returns the signals it faults.
  std::vector<std::size_t> apply_manufacturer_code(std::uint16_t m, TimePoint now);
  // The latches below -> Driver faults (set_fault/clear_fault); without a time, no status change.
  void sync_faults(std::optional<TimePoint> now);
  // Whether the latches fault signal `i`, and the latch's state key (sync_faults; the import).
  [[nodiscard]] bool latched(std::size_t i) const;
  [[nodiscard]] std::string latch_key(std::size_t i) const;
  void clear_faults();
  [[nodiscard]] bool valid_value(std::int8_t v) const;
  [[nodiscard]] static std::int8_t limit100(std::int8_t v);

  ElobauMfgOptions opt_;
  std::vector<SignalInfo> signals_;
  Stats stats_;
  std::array<Axis, kAxes> axes_{};
  std::optional<std::uint16_t> buttons_;  // bit n-1 = button n
  std::array<bool, kButtons> button_emcy_{};
  bool global_emcy_ = false;
  bool led_emcy_ = false;
  bool online_ = false;            // between on_online() and on_offline()
  bool error_code_read_ = false;   // 4001h read in this boot
  std::uint8_t fitted_read_ = 0;   // bit 0: 2100h:01h answered, bit 1: 2100h:02h
  std::uint16_t fitted_ = 0x003F;  // 2100h:01h/02h; the document's default until read
  bool saving_ = false;            // this boot's configuration saves the parameters (save_unsaved)
  bool unsaved_at_boot_ = false;   // an EMCY 0002h came between boot-up and operational
  bool save_tried_ = false;        // a save was written and the grip restarted since 0002h was read
  bool channel2_late_ = false;
  std::optional<TimePoint> ch2_reference_;                 // last TPDO #1, or the first TPDO #0 before one
  std::array<std::optional<std::uint8_t>, kLeds> leds_{};  // commanded 2-bit codes
  bool leds_sent_ = false;                                 // the state went out since online
  bool leds_dirty_ = false;                                // changed, not sent yet (output batch)
};

// Factory (families.hpp). Options: channel_tolerance, detent, channel2_timeout_ms, cycle_ms,
// parameter_checksum (refuse | save, ElobauMfgOptions::save_unsaved), freshness_floor_ms.
std::unique_ptr<Driver> make_elobau_mfg_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                               std::string& error);

}  // namespace oegw::subdevices
