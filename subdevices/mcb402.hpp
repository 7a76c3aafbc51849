// MCB-402 joystick controller (frenzel + berg CO4013A CANopen controller, operation mode 4).
// Source: reference/003_44a28fc862638d35.txt ("MCB-402 CANOPEN Controller for joystick", v1.0),
// quoted below as [MCB §n] for the board's own chapters 1-4 and [CO4013 <object/section>] for the
// controller's chapter 5.
//
// Signals (index = position in signals()):
//   0  x            Axis    raw16  -32768..32767, neutral 0   6401h:01, TPDO2 bytes 0-1 (X, CN5)
//   1  y            Axis    raw16  -32768..32767, neutral 0   6401h:02, TPDO2 bytes 2-3 (Y, CN9)
//   2  z            Axis    raw16  -32768..32767, neutral 0   6401h:03, TPDO2 bytes 4-5 (Z, CN7)
//   3  t            Axis    raw16  -32768..32767, neutral 0   6401h:04, TPDO2 bytes 6-7 ("T axis",
//                                                             CN8 [MCB §2]; the CO4013 chapter
//                                                             calls it the W axis)
//   4..10  buttons[1]..buttons[7]   Button  bool 0..1, neutral 0, 1 = pressed   BP1..BP7 (CN6),
//                                   TPDO1 byte 2 (6000h:03) — bit table below
//   11..14 leds[1]..leds[4]         Output  bool 0..1, 1 = LED on   OUT0..OUT3 (CN10),
//                                   RPDO1 byte 0 (6200h:01) bits 0..3
//
// Wire layouts:
//   TPDO1 0x180+id, 4 bytes [CO4013 "Operation mode 4", default PDO mapping]: 6000h:01 memory
//     flags (forced to 0), 6000h:02 direction inputs, 6000h:03 general-purpose IN7..IN0 = the push
//     buttons, 6000h:04 IN11..IN8. [MCB §4]: "183 00 00 cc 0(0)", "when pressed the corresponding
//     bit is set to 1". The pins are active low (short to GND), and the controller already inverts
//     them into 6000h ("inverted level because active low", [CO4013 6000h sub 3]), so on the wire
//     1 = pressed: the driver does not invert again, and pins the polarity object 6002h:03 to 0 at
//     boot so that nobody's stored inversion changes that meaning.
//   Button bits of byte cc, [MCB §4] "Bit of cc 7 6 5 4 3 2 1 0 / N° BP 6 7 5 4 3 2 1": the
//     extracted table is damaged (7 entries under 8 columns, BP6/BP7 in unexpected order; read
//     as written: bit 7 = BP6, bit 6 = BP7, bits 5..1 = BP5..BP1, bit 0 unused). The driver
//     therefore has no bit order of its own: the option `button_bits` is required, a
//     commissioning choice the integrator reads off the board
//     (docs/design/device-documents.md#mcb-402-button-bits-a-required-commissioning-choice: press
//     BP1..BP7 one at a time, note the bit of byte 2 of TPDO1 that is set).
//   TPDO2 0x280+id, 8 bytes: X, Y, Z, T as INTEGER16 little endian ("the word for X axis is
//     0xbbaa"); 2.5 V = 0x0000, 5 V = 0x7FFF, 0 V = 0x8000 [MCB §4].
//   RPDO1 0x200+id, 1 byte: 6200h:01, bits 0..3 = OUT0..OUT3 ([CO4013 "Operation mode 4"]); the
//     output pins are active low and the controller inverts 6200h onto them (a 1 lights the LED
//     wired from +5 V), 6202h:01 pinned to 0 at boot. set_output() always sends the whole
//     remembered byte; on_online() re-sends it (a rebooted board starts with 6200h = 0).
//   EMCY 0x80+id, cable break [CO4013 "Emergency Messages"]: "20 31 81 00 8x 00 00 00" = code
//     3120h, 1001h = 81h, byte 4 = 80h | axis bits (bit 0 X, bit 1 Y, bit 2 Z, bit 3 W/T); the
//     active errors are ORed, so byte 4 is the set of broken axes. Those axes are faulted
//     (Driver::faulted: Error, value 0, whatever TPDO2 carries) until an EMCY 3120h without their
//     bit, the error-reset EMCY 0000h, or a read-back of 1001h without bit 7 "Device Error" at the
//     node's next (re)start (boot_reads(): a board repaired and rebooted sends no 0000h); the next
//     TPDO2 then makes them Valid. Going offline keeps the fault (a heartbeat loss does not
//     repeat the EMCY); a read-back with bit 7 set keeps it too (all four axes if none was
//     latched: which one is unknown). A 3120h whose byte 4 is not 8xh with x != 0 is counted
//     (unknown_emcy) and faults all four axes.
//   Warnings, faulting nothing (error = false): every 81xxh, CiA 301 Table 26 "communication" —
//     the document's 8100h CAN error warning (also sent at every power-on, [MCB §4] "083 00 81 11
//     0"), 8130h life guarding ("30 81 11"), 8140h return from bus off ("40 81 11"), and any
//     other 81xxh a CO4013 may send (8110h overrun, 8120h error passive): as the elobau and CiA 401
//     drivers treat them (docs/design/device-documents.md#faults-what-sets-them-what-clears-them).
//   Any other code: counted (unknown_emcy) and, being an error the document does not explain,
//     faults every input until 0000h or a 1001h read-back showing no error but communication.
//
// A board that never sends the 0000h (the document lists none, [CO4013 "Emergency Messages"]):
//   while a cable break or an undocumented error is latched, fault_poll() has the network manager
//   read 1001h every kErrorRegisterPoll while the node is operational. [CO4013 Index 1001]: bit 7
//   "Device Error" — the cable break's 81h — clear ends the cable break; no bit but bit 0 "generic"
//   and bit 4 "communication" (the power-on warning's 11h, which a board may keep) ends an
//   undocumented error. An answer to a request sent before a fault latched since is ignored (the
//   EMCY may overtake the answer). So a mended cable clears within one poll period plus an SDO
//   round trip, whether or not the board sends 0000h.
//
// Boot configuration (configuration()), in this order:
//   1800h:02 = FFh, 1800h:05 = button_timer_ms  TPDO1 event driven + periodic refresh
//   1801h:02 = FFh, 1801h:05 = event_timer_ms   TPDO2: the [MCB §4] example
//                                               "603 22 01 18 05 aa bb 00 00" (axes each 0xbbaa ms;
//                                               without it the axes are sent once, at start, as
//                                               6423h is FALSE by default)
//   2180h = can_restart_ms                      CAN restart time after bus off ([CO4013 Index
//                                               2180]: default 0 = "automatic restart ...
//                                               prohibited", the board would stay off the bus)
//   6002h:03 = 00h, 6202h:01 = 00h              input / output polarity as described above
//   6431h:01..04 = 0                            analogue offset 0: 6401h stays signed
// Options (the table mcb402_options() in mcb402.cpp is what the factory parses and `oegw
// signals` lists): event_timer_ms (1..65535, default 20 — the document gives no value, its default 0
// would mean no periodic axes), button_timer_ms (0..65535, default 100, 0 = on change only),
// can_restart_ms (1..65535, default 1000: the document gives none, 0 is refused),
// button_bits (required, no default: seven distinct bit numbers 0..7 of 6000h:03 for BP1..BP7,
// separated by ',' — a YAML list in the mapping file — or '/' on a command line).
//
// Identity [CO4013 1000h, 1018h]: device type 0107 0191h (CO4013A4), vendor 58h, product code
// 0104 0131h; revision is "revision of the device" and not checked.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "subdevices/driver.hpp"
#include "subdevices/driver_options.hpp"

namespace oegw::subdevices {

namespace mcb402 {
inline constexpr std::uint32_t kDeviceType = 0x01070191;  // CO4013A4
inline constexpr std::uint32_t kVendorId = 0x58;
inline constexpr std::uint32_t kProductCode = 0x01040131;
inline constexpr std::uint16_t kEmcyCableBreak = 0x3120;
inline constexpr std::uint16_t kEmcyCanWarning = 0x8100;
inline constexpr std::uint16_t kEmcyLifeGuarding = 0x8130;
inline constexpr std::uint16_t kEmcyBusOffRecovered = 0x8140;
inline constexpr std::size_t kAxes = 4;
inline constexpr std::size_t kButtons = 7;
inline constexpr std::size_t kLeds = 4;
inline constexpr std::size_t kButtonByte = 2;  // 6000h:03 in TPDO1
// BP1..BP7 -> bit of 6000h:03 (the option `button_bits`, see above).
using ButtonBits = std::array<std::uint8_t, kButtons>;
// What parse_mcb402_options() says when `button_bits` is missing: the setting and the
// commissioning step that fills it.
inline constexpr std::string_view kButtonBitsMissing =
    "mcb402: option button_bits is required (no default: the document's bit table is damaged and permits two "
    "readings): the bit of 6000h:03 - byte 2 of TPDO1, COB-ID 180h + node-ID - that each push button BP1..BP7 "
    "sets, as options: { button_bits: [b1, b2, b3, b4, b5, b6, b7] }; read it off the board: `oegw signals mcb402 "
    "--find-button-bits -i IF --node N` asks you to press BP1..BP7 one at a time and prints the line "
    "(docs/design/device-documents.md#mcb-402-button-bits-a-required-commissioning-choice)";
// How often 1001h is read while a fault waits for it (fault_poll()).
inline constexpr std::chrono::milliseconds kErrorRegisterPoll{250};
// [CO4013 Index 1001]: bit 7 device error; bits 0 (generic) and 4 (communication) alone are the
// CAN warnings' register (11h in "083 00 81 11").
inline constexpr std::uint8_t kDeviceErrorBit = 0x80;
inline constexpr std::uint8_t kCommunicationOnly = 0x11;
// Signal indices.
inline constexpr std::size_t kFirstButton = kAxes;
inline constexpr std::size_t kFirstLed = kAxes + kButtons;
}  // namespace mcb402

struct Mcb402Options {
  std::uint16_t event_timer_ms = 20;
  std::uint16_t button_timer_ms = 100;
  std::uint16_t can_restart_ms = 1000;
  mcb402::ButtonBits button_bits{};        // required: parse_mcb402_options() refuses options without it
  std::uint32_t freshness_floor_ms = 200;  // Driver::set_freshness_floor
};

class Mcb402Driver final : public Driver {
 public:
  Mcb402Driver(NodeId node, FrameSink sink, Mcb402Options options);

  [[nodiscard]] std::string_view family() const override { return "mcb402"; }
  [[nodiscard]] const std::vector<SignalInfo>& signals() const override { return signals_; }
  [[nodiscard]] ExpectedIdentity expected_identity() const override;
  [[nodiscard]] std::vector<SdoWrite> configuration() const override;
  // 6200h the LEDs the gateway drives; 5401h the zero point enlargement its axis values depend on.
  [[nodiscard]] bool protects(std::uint16_t index, std::uint8_t /*sub*/) const override {
    return index == 0x6200 || index == 0x5401;
  }
  // The error register 1001h, read back at every (re)start: it decides the faults.
  void begin_boot() override { error_register_read_ = false; }
  [[nodiscard]] std::vector<std::pair<std::uint16_t, std::uint8_t>> boot_reads() const override;
  bool on_boot_read(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                    std::string& error) override;
  bool on_boot_read_abort(std::uint16_t index, std::uint8_t sub, canopen::SdoAbortCode code) override;
  void on_application_reset(TimePoint /*now*/) override {}  // the 1001h read-back decides
  // 1001h every mcb402::kErrorRegisterPoll while a cable break or an undocumented error is latched.
  [[nodiscard]] std::optional<FaultPoll> fault_poll() const override;
  void on_fault_poll_sent() override { poll_epoch_sent_ = latch_epoch_; }
  std::string on_fault_poll(std::span<const std::uint8_t> data, TimePoint now) override;
  bool on_frame(const CanFrame& frame, TimePoint now) override;
  DecodedEmcy on_emcy(const EmcyMessage& emcy, TimePoint now) override;
  [[nodiscard]] std::vector<std::uint32_t> consumed_cob_ids() const override;
  void on_online(TimePoint now) override;
  bool set_output(std::size_t index, std::int64_t value, TimePoint now) override;

  [[nodiscard]] const Mcb402Options& options() const { return options_; }
  // Axes (bit 0 = X .. bit 3 = T) latched broken by the cable-break EMCY.
  [[nodiscard]] std::uint8_t broken_axes() const { return broken_; }
  [[nodiscard]] std::uint8_t output_byte() const { return outputs_; }

 private:
  void on_tpdo1(const CanFrame& frame, TimePoint now);
  void on_tpdo2(const CanFrame& frame, TimePoint now);
  void set_broken(std::uint8_t axes, std::optional<TimePoint> now);
  // Whether the latches fault signal `i`: an axis while broken, every input while an
  // undocumented error lasts, an LED never (set_broken, on_emcy; the state import checks it).
  [[nodiscard]] bool latched(std::size_t i) const;
  void clear_faults();
  void send_outputs();
  void flush_outputs(TimePoint now) override;
  void export_family_state(canopen::StateWriter& w) const override;
  void import_family_state(const canopen::StateReader& r) override;

  Mcb402Options options_;
  std::vector<SignalInfo> signals_;
  std::uint8_t broken_ = 0;
  bool unknown_fault_ = false;  // an undocumented error EMCY faults every input
  // Counts every latch an EMCY sets; a poll answer counts only when nothing latched since its
  // request went out.
  std::uint64_t latch_epoch_ = 0;
  std::uint64_t poll_epoch_sent_ = ~std::uint64_t{0};
  bool error_register_read_ = false;  // 1001h read in this boot
  std::uint8_t outputs_ = 0;          // 6200h:01 as last commanded
  bool outputs_pending_ = false;      // set_output() inside an output batch: RPDO1 not sent yet
};

// Parses `options` (event_timer_ms, button_timer_ms, can_restart_ms, button_bits); nullopt and
// every refusal if one is bad or button_bits is missing.
std::optional<Mcb402Options> parse_mcb402_options(const DriverOptions& options, OptionRefusals& refusals);
// "1,2,3,4,5,7,6" or "1/2/3/4/5/7/6" (spaces around the numbers allowed) -> the bits of BP1..BP7;
// nullopt unless 7 distinct bit numbers 0..7, and then `why` names what is wrong: the number that
// is no bit 0..7, a bit given twice with both positions (BP3 and BP4), or how many there are.
std::optional<mcb402::ButtonBits> parse_button_bits(std::string_view text, std::string& why);
std::optional<mcb402::ButtonBits> parse_button_bits(std::string_view text);

}  // namespace oegw::subdevices
