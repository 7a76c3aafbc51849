// Simulated MCB-402 joystick controller (CO4013A, operation mode 4), after
// reference/003_44a28fc862638d35.txt. A canopen::Node with the controller's dictionary:
//
//   1000h device type 0107 0191h (CO4013A4)   1002h status register (bit 31 = operational)
//   1008h "CO4013A"  1009h "1.0"  100Ch/100Dh guard time / life time factor (stored only: node
//   guarding is not simulated)  100Eh COB-ID guard 700h+id  1014h/1015h EMCY  1017h heartbeat 0
//   1018h vendor 58h, product 0104 0131h, revision (sub 0 = 3, no serial)
//   2000h "Frenzel + Berg"  2101h system configuration = 4 (inverted CFG3..0 = 1011b)  2180h 0
//   1400h/1600h RPDO1 200h+id, type FFh: 6200h:01
//   1800h/1A00h TPDO1 180h+id, type FFh, event timer 0: 6000h:01..04 (4 bytes)
//   1801h/1A01h TPDO2 280h+id, type FFh, event timer 0: 6401h:01..04 (8 bytes)
//   5003h debounce (stored, not applied)  5401h zero point enlargement 1000h (applied by
//   convert_axis(); move_axis() sets the value after it)
//   6000h:01..04 inputs: 01 memory flags (0 in mode 4), 02 direction inputs, 03 IN7..IN0 = the
//   buttons, 04 IN11..IN8; each = NOT(pin level) XOR 6002h (the pins are pulled up and shorted to
//   GND when pressed: "inverted level because active low")
//   6002h polarity, 6005h global interrupt enable TRUE, 6006h any-change mask FFh, 6007h/6008h 0:
//   a change of 6000h sends TPDO1 only when these enable it
//   6200h:01 outputs (wo), 6202h polarity, 6206h error mode FFh, 6207h error value 0
//   6401h:01..04 axes INTEGER16 = move_axis() value + 6431h offset (16-bit wrap)
//   6421h trigger 7, 6423h global analogue interrupt FALSE, 6424h..6428h limits 0, 6431h offset 0:
//   while 6423h is FALSE an axis movement sends nothing — TPDO2 goes out at NMT start and by its
//   event timer 1801h:05 only ([MCB §4]: "we now set the timer events so that the MCB402 sends at
//   regular intervals the value of the axis")
//
// Faults: cable_break(axis) sends EMCY 3120h "20 31 81 00 8x 00 00 00" (x = the OR of the broken
// axes, [CO4013 "Emergency Messages"] "the bitmap ... combined with a logical or"; the broken
// axis reads -32768, a floating wiper pulled to 0 V — the document does not say) and sets 1001h
// bit 7 "device error" and bit 0 "generic" ([CO4013 Index 1001]). A change of the broken set
// while one is active sends 3120h with the new set. Mending the last one clears bit 7 and, as the
// corner `clear_after_break` says, sends the error reset 0000h (ErrorReset) or nothing (None: the
// document's EMCY list has no reset, only 1001h shows it). device_error() forces the outputs as
// 6206h/6207h say (bus off, life guarding in the document). A power cycle keeps what is broken
// (the board detects it again: 1001h bit 7 stays set, no EMCY is repeated); a cable mended while
// the board is off (silent) shows as bit 7 clear after it.
// Power-on: EMCY 8100h after the boot-up (start(), reboot()), "00 81 11 ..." as the [MCB §4]
// trace, byte 2 = 1001h with bits 0 and 4 ("generic", "CAN bus or communication error"); whether
// 1001h keeps those bits afterwards the document does not say (corner `power_on_1001h`: 11h
// held, or 00h). life_guarding() and bus_off_recovered() send the document's "30 81 11 ..." and
// "40 81 11 ..." the same way.
//
// Corners (Mcb402SimConfig, oegw-sim options): wiring=, clear_after_break=0000h|none,
// power_on_1001h=11h|00h
// (docs/design/device-documents.md#corners-every-reading-a-document-permits).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string_view>

#include "canopen/301/subscription.hpp"
#include "subdevices/sim/simulated_device.hpp"

namespace oegw::subdevices::sim {

// The controller as the document describes it, independent of the driver's reading of it.
namespace co4013 {
inline constexpr std::uint32_t kDeviceType = 0x01070191;   // [CO4013 1000h] CO4013A4
inline constexpr std::uint32_t kVendorId = 0x58;           // [CO4013 1018h]
inline constexpr std::uint32_t kProductCode = 0x01040131;  // [CO4013 1018h]
inline constexpr std::uint16_t kEmcyCableBreak = 0x3120;   // [CO4013 "Emergency Messages"]
inline constexpr std::size_t kAxes = 4;                    // X, Y, Z, T [MCB §2]
inline constexpr std::size_t kButtons = 7;                 // BP1..BP7 [MCB §4]
// BP1..BP7 -> bit of 6000h:03: how a board is wired. [MCB §4] "Bit of cc 7 6 5 4 3 2 1 0 / N° BP
// 6 7 5 4 3 2 1", read as printed, is the simulated board's wiring unless its configuration
// says otherwise (the table is damaged: a real board may differ, which is why the driver
// takes the order from the mapping file only).
using ButtonBits = std::array<std::uint8_t, kButtons>;
// The table's two readings: its seven entries under the eight columns' left end (bit 7 = BP6,
// bit 6 = BP7, bits 5..1 = BP5..BP1, bit 0 unused) or right end (bit 6 = BP6, bit 5 = BP7, bits
// 4..0 = BP5..BP1, bit 7 unused). The simulated board is wired by the right-end reading unless
// told otherwise: every example file carries the left-end one, so a test that pairs the two
// without saying how its board is wired reports the wrong buttons.
inline constexpr ButtonBits kPrintedTableBits{1, 2, 3, 4, 5, 7, 6};
inline constexpr ButtonBits kRightAlignedBits{0, 1, 2, 3, 4, 6, 5};
inline constexpr std::uint16_t kEmcyCanWarning = 0x8100;      // "00 81 11"
inline constexpr std::uint16_t kEmcyLifeGuarding = 0x8130;    // "30 81 11"
inline constexpr std::uint16_t kEmcyBusOffReturn = 0x8140;    // "40 81 11"
inline constexpr std::uint8_t kRegisterDeviceError = 0x81;    // the cable break's byte 2
inline constexpr std::uint8_t kRegisterCommunication = 0x11;  // the CAN frames' byte 2
// "1/2/3/4/5/7/6" or "1,2,3,4,5,7,6" -> the wiring of BP1..BP7; nullopt unless 7 distinct bits 0..7.
std::optional<ButtonBits> parse_wiring(std::string_view text);
}  // namespace co4013

struct Mcb402SimConfig {
  NodeId node_id{0x03};
  std::uint16_t kbaud = 250;  // 20, 50, 125, 250 or 500 [MCB §1]
  std::uint32_t revision = 1;
  std::uint16_t heartbeat_ms = 0;                              // 1017h default (document: 0)
  co4013::ButtonBits button_bits = co4013::kRightAlignedBits;  // oegw-sim option wiring=
  std::filesystem::path store_path;                            // empty: no 1010h/1011h
  // Mending the last broken cable sends 0000h (true) or nothing, 1001h alone showing it (false;
  // oegw-sim clear_after_break=none).
  bool clear_with_error_reset = true;
  // 1001h after the power-on warning (and the other CAN warnings): 11h kept, as the frame's byte 2
  // (true; oegw-sim power_on_1001h=11h) or back to 00h (false).
  bool keep_communication_bits = false;

  // [MCB §3] CN3 jumpers. Address pins 14,12,10,8,6,4,2 (bit 6 .. bit 0 of `address_pins`) and
  // bit-rate pins 20,18,16 (bit 2 .. bit 0 of `baud_pins`), 1 = open (pulled up), 0 = jumper:
  // address = NOT pins (1111110b -> 1, 0000000b -> 7Fh); 101b 500, 100b 250, 011b 125, 010b 50,
  // 001b 20 kbit/s. nullopt for address 0 or an undocumented bit-rate code.
  static std::optional<Mcb402SimConfig> from_jumpers(std::uint8_t address_pins, std::uint8_t baud_pins);
};

class Mcb402Sim final : public SimulatedDevice {
 public:
  Mcb402Sim(FrameSink sink, Mcb402SimConfig config = {});

  [[nodiscard]] std::string_view family() const override { return "mcb402"; }
  // Power on / power cycle: boot-up, then the EMCY 8100h "CAN bus in error warning state" the
  // [MCB §4] power-on trace shows ("703 00" then "083 00 81 11 0", i.e. 00 81 11 00 00 00 00 00).
  void start(TimePoint now) override;
  void reboot(TimePoint now) override;
  [[nodiscard]] const Mcb402SimConfig& config() const { return cfg_; }
  // CiA 305 bit-timing table index of the jumpered bit rate (500 -> 2, 250 -> 3, 125 -> 4,
  // 50 -> 6, 20 -> 7).
  [[nodiscard]] std::uint8_t bit_timing_index() const;

  // Driver signal names: x, y, z, t (raw16), buttons[1..7] (0/1); outputs leds[1..4].
  bool set_input(std::string_view signal, std::int64_t value, TimePoint now) override;
  [[nodiscard]] std::optional<std::int64_t> output(std::string_view signal) const override;

  // Axis 1..4 (X, Y, Z, T) to `raw` (the signed value after the zero-point processing).
  void move_axis(std::size_t axis, std::int16_t raw, TimePoint now);
  // Axis 1..4 from the 16-bit conversion result before the zero point enlargement: applies
  // 5401h as [CO4013 Index 5401] says (v > z: v - z; v < -z: v + z; else 0), then move_axis().
  void convert_axis(std::size_t axis, std::int16_t converted, TimePoint now);
  // Push button BP1..BP7.
  void press(std::size_t button, TimePoint now) { set_button(button, true, now); }
  void release(std::size_t button, TimePoint now) { set_button(button, false, now); }
  void set_button(std::size_t button, bool pressed, TimePoint now);
  // Axis 1..4 cable broken (true) or mended (false).
  void cable_break(std::size_t axis, bool broken, TimePoint now);
  // A device error (bus off, life guarding) forcing the outputs per 6206h/6207h.
  void device_error(bool active) { device_error_ = active; }
  // The controller's CAN warnings as [CO4013 "Emergency Messages"] lists them: "30 81 11 ..."
  // (the master's guarding stopped) and "40 81 11 ..." (back from bus off).
  void life_guarding(TimePoint now) { send_can_warning(co4013::kEmcyLifeGuarding, now); }
  void bus_off_recovered(TimePoint now) { send_can_warning(co4013::kEmcyBusOffReturn, now); }
  // 1001h as the board holds it now.
  [[nodiscard]] std::uint8_t error_register() const;

  // What the output pins drive: bit i = OUT i LED lit (pin low), after 6202h polarity and the
  // error mode. led(n) for n = 1..4.
  [[nodiscard]] std::uint8_t leds() const;
  [[nodiscard]] bool led(std::size_t n) const { return ((leds() >> (n - 1)) & 1u) != 0; }
  // The GP input pin levels IN7..IN0 (1 = high = released).
  [[nodiscard]] std::uint8_t input_pins() const { return pins_; }
  [[nodiscard]] std::uint8_t broken_axes() const { return broken_; }

 private:
  [[nodiscard]] canopen::SdoAbortCode refuse_download(std::uint16_t index, std::uint8_t sub,
                                                      canopen::NmtState state) const override;
  void refresh_inputs(bool notify);
  void write_input(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> bytes, bool notify);
  [[nodiscard]] bool digital_interrupt(std::uint8_t before, std::uint8_t after, std::uint8_t sub) const;
  [[nodiscard]] bool analogue_interrupt(std::size_t axis, std::int16_t before, std::int16_t after) const;
  void on_power_cycle(TimePoint now) override;
  void send_can_warning(std::uint16_t code, TimePoint now);
  // 1001h from what is active (the broken axes, the kept communication bits).
  void refresh_error_register();
  void send_emcy(std::uint16_t code, std::uint8_t byte4);

  Mcb402SimConfig cfg_;
  std::uint8_t pins_ = 0xFF;  // IN7..IN0 pin levels: pulled up
  std::array<std::int16_t, co4013::kAxes> axes_{};
  std::uint8_t broken_ = 0;
  bool device_error_ = false;
  bool communication_bits_ = false;                  // a CAN warning was sent and keep_communication_bits
  const canopen::ObjectDictionary* dict_ = nullptr;  // od(), for the const accessors
  canopen::Subscriptions subs_;                      // declared last: released before the dictionary goes
};

}  // namespace oegw::subdevices::sim
