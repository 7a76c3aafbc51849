// Simulated elobau MFG 34xG / 36xG joystick grip: a canopen::Node with the object dictionary,
// PDOs and EMCYs of "CANopen Protocol for MFG 34xG and 36xG" v01.21
// (section numbers are that document's).
//
// What it models:
//   * OD (Table 14): 1000h = 0, 1008h "JST", 1009h/100Ah "0.00", 1014h ro, 1017h, 1018h (vendor
//     B4h, product 00010003h), 1200h, 1400h/1600h, 1800h/1801h (sub 1..5, 4 = reserved),
//     1A00h/1A01h, 2000h..2004h (all sub-indices: configuration, raw signals, filter, max
//     difference, X1..X10/Y1..Y10, error value 1Bh, not-available value 1Ch, signals 20h/21h),
//     2100h (configuration, raw, debounce, timeout, error/not-available values, 10h/11h),
//     2200h (LED commands 1..7, spare 8, timeout 9, mask 0Ah), 4000h, 4001h, 4002h, 5000h,
//     5001h, 5999h. 1010h/1011h exist when a store path is given. Extra objects the Node adds
//     (1001h, 1003h, 1015h, 1029h, 1010h:02/03) are not in the document.
//   * TPDO #0 (180h+id, Table 7) and TPDO #1 (280h+id, Table 8): transmission type 254, event
//     timer 100 ms, sent when entering Operational and cyclically; Table 14's "transmission event
//     is manufacturer specific, i.e. event timer" leaves open whether a change is an event too:
//     the corner `tpdo` (change: on every change of their data as well, the default; timer: on the
//     event timer only). The 5 ms coding cycle is not modelled: a change is visible at the next
//     advance().
//   * Channel availability 20xxh:01h (0 none, 1 signal 1, 2 signal 2, 3 both): a missing channel
//     carries the not-available value 1Ch. Buttons not enabled in 2100h:01h/02h carry 2100h:0Ah.
//   * RPDO #0 (200h+id, Table 9) -> LED states by Table 13 (11 = no change honoured); a LED is
//     displayed only if its bit in 2200h:0Ah is set (§15.3). LEDs are off at power-on.
//   * EMCY (Table 5): [code][1001h = 0][4001h lo][4001h hi][FF FF FF]; manufacturer errors go
//     with code 1000h; the last error's clearing sends 0000h. Not sent in Stopped (§12.1).
//     With 4000h = 1 the failed signal carries its error value (§12.2): axis codes x0h/x1h set
//     channel 1/2 to 1Bh, button timeouts 61h..6Bh set the button to 2100h:09h; 4000h = 0/2
//     send the node to pre-operational/stopped instead.
//   * Zero position (§4): after power-on (start, reboot) and after a bus-off, an axis not at 0
//     is sent as 0 until it has been at 0 once.
//   * Bus-off (bus_off()): counted; recovering sends EMCY 8140h with the count (§12.4); past
//     the limit 5001h the device goes off-line (silent) until the next power cycle.
//   * 5999h (§7): :01 baud rate (20, 50, 125, 250, 500, 800, 1000 only), :02 node-ID (becomes
//     active at the next reset communication, like LSS), :03 "save" = 1010h:01 "save".
//   * 5000h = 1: operational by itself after power-on.
//   * Parameter checksum error 0002h until the parameters were first saved (config flag; corner
//     `saved`): raised at every power-on and reset node while unsaved; a 1010h:01 / 5999h:03
//     "save" ends it at the next restart (§8 "Restart the joystick after saving procedure").
//     4001h shows the highest active code (Table 14 holds one code; which one, the document does
//     not say) and is kept across resets.
//   Not modelled: the 5 ms coding cycle, filter/debounce, the transformation from raw voltages
//   (axes are moved in percent), button timeout monitoring 2100h:08h (raise_error(61h..6Bh)
//   scripts it), the LED message timeout ("function not implemented"), 599Ah.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <set>
#include <string_view>

#include "subdevices/sim/simulated_device.hpp"

namespace oegw::subdevices::sim {

struct ElobauMfgSimConfig {
  NodeId node_id{0x11};                                       // §7 default
  std::uint32_t product_code = 0x00010003;                    // 1018h:02 default
  std::uint32_t serial = 0;                                   // 1018h:04
  std::uint8_t buttons_1_8 = 63;                              // 2100h:01h default: buttons 1..6 fitted
  std::uint8_t buttons_9_16 = 0;                              // 2100h:02h default: none
  std::array<std::uint8_t, 5> axis_config = {3, 3, 3, 3, 3};  // 20xxh:01h default: both signals
  std::uint16_t heartbeat_ms = 0;                             // 1017h default
  std::filesystem::path store_path;                           // empty: no 1010h/1011h
  // Table 6 0002h "is also set until first parameter saving process": false = a grip whose
  // parameters were never saved raises it at every power-on until 1010h:01 (or 5999h:03) "save".
  bool parameters_saved = true;
  // TPDO #0/#1 also on every change (true), or on the event timer only (false; oegw-sim tpdo=timer).
  bool tpdo_on_change = true;
};

class ElobauMfgSim : public SimulatedDevice {
 public:
  enum class Fault : std::uint8_t { None, Error, NotAvailable };
  static constexpr std::size_t kLeds = 16;

  explicit ElobauMfgSim(FrameSink sink, ElobauMfgSimConfig config = {});

  [[nodiscard]] std::string_view family() const override { return "elobau-mfg"; }
  void start(TimePoint now) override;
  void reboot(TimePoint now) override;

  // Driver signal names: x, y, wheel_a..wheel_c (percent), buttons[1..16] (0/1); outputs
  // leds[1..16] (0 off / 1 on / 2 blink, as displayed).
  bool set_input(std::string_view signal, std::int64_t value, TimePoint now) override;
  [[nodiscard]] std::optional<std::int64_t> output(std::string_view signal) const override;

  // Axes by signal name: "x", "y", "wheel_a", "wheel_b", "wheel_c". `percent` is the physical
  // deflection (-110..110); channel 2 reads percent + offset (a mismatch). False for a bad name.
  bool move_axis(std::string_view axis, int percent, int channel2_offset = 0);
  // The axis at an input voltage (0..5000 mV, §15.1 "Input value range (X): 0...5V"), through its
  // transformation function 20xxh:06h..19h (X1..X10 in mV, Y1..Y10 in %, Tables 10/11):
  // linear between neighbouring points, except that the step to a detent (±100 % to ±110 %,
  // §15.1.2 "The detent function is a jump from 100% to 110%"; "X2 and X9 are used for detent
  // detection") jumps at X9 / X2; below X1 or above X10 the signal is out of range ("X1 and X10
  // are also used for error detection"): the error value 1Bh. Both channels. Returns the percent
  // sent (or nullopt for out of range).
  std::optional<int> apply_voltage(std::string_view axis, int millivolts);
  // Forces an axis channel to the error value (126 by default) or the not-available value.
  // channel: 1, 2, or 0 = both.
  bool inject(std::string_view axis, Fault fault, int channel = 0);
  // Buttons 1..16 (12 = presence sensor).
  bool press(int button);
  bool release(int button);

  // A Table 6 manufacturer error (4001h): EMCY 1000h and the error behaviour of 4000h.
  void raise_error(std::uint16_t code, TimePoint now);
  // The error is gone; the last one sends the error reset 0000h.
  void clear_error(std::uint16_t code, TimePoint now);
  // Whether the parameters were ever saved (ElobauMfgSimConfig::parameters_saved): false, the
  // grip raises 0002h at its next power-on until 1010h:01 / 5999h:03 "save".
  void set_parameters_saved(bool saved) { parameters_saved_ = saved; }
  // The controller went bus-off and recovered (§4, §12.4, 5001h).
  void bus_off(TimePoint now);

  // What the simulated device is doing.
  // LED i (1..16, bit i-1 of 2200h:0Ah): last commanded 0 off / 1 on / 2 blink.
  [[nodiscard]] std::uint8_t led(std::size_t i) const { return leds_.at(i - 1); }
  // As led(), but 0 when the LED mask 2200h:0Ah disables it (§15.3).
  [[nodiscard]] std::uint8_t led_displayed(std::size_t i);
  [[nodiscard]] std::int8_t transmitted(std::string_view axis, int channel);
  [[nodiscard]] bool zero_locked(std::string_view axis) const;
  [[nodiscard]] std::uint16_t bus_off_count() const { return bus_off_count_; }
  [[nodiscard]] std::uint16_t baud_rate();  // 5999h:01
  [[nodiscard]] const std::set<std::uint16_t>& active_errors() const { return errors_; }

 protected:
  void on_power_cycle(TimePoint now) override;

 private:
  [[nodiscard]] canopen::SdoAbortCode refuse_download(std::uint16_t index, std::uint8_t sub,
                                                      canopen::NmtState state) const override;
  static std::optional<std::size_t> axis_index(std::string_view name);
  void build_od(canopen::ObjectDictionary& od, const ElobauMfgSimConfig& c);
  void publish();  // physical state -> 20xxh, 2100h
  void apply_led_byte(std::uint8_t sub, std::uint8_t byte);
  void send_emcy(std::uint16_t code, std::uint16_t manufacturer, TimePoint now);
  void arm_zero_rule();
  // Writes a TPDO-mapped value: as an application event (tpdo_on_change) or silently (the event
  // timer sends it).
  void put(std::uint16_t index, std::uint8_t sub, std::uint8_t raw);
  void refresh_error_code();  // 4001h = the highest active code, 0 for none

  std::array<int, 5> physical_{};
  std::array<int, 5> offset2_{};
  std::array<bool, 5> zero_lock_{};
  std::array<std::array<Fault, 2>, 5> faults_{};
  std::uint16_t buttons_ = 0;  // bit n-1 = button n pressed
  std::array<std::uint8_t, kLeds> leds_{};
  std::set<std::uint16_t> errors_;
  std::uint16_t bus_off_count_ = 0;
  bool parameters_saved_ = true;
  bool tpdo_on_change_ = true;
  canopen::NmtState last_state_ = canopen::NmtState::Initialisation;
  canopen::Subscriptions subs_;  // last: released before the dictionary goes
};

}  // namespace oegw::subdevices::sim
