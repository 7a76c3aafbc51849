// Novotechnik CANopen sensors (series MZ1-2200, MC1-2800, MB1-3600), CiA 406 encoder profile.
// Source: the Novotechnik "CANopen" sensor protocol document ("the document"; CiA 301 v4.2,
// CiA 406 v3.2, CiA 305 LSS; sections cited as §n).
//
// TPDO1 (COB-ID 180h + node-ID, §3.1), as configuration() maps it with the §8.2 procedure
// (disable COB-ID, sub 0 = 0, entries, sub 0 = 4, enable), 8 bytes, little endian:
//   bytes 0..3  position value, INTEGER32: 6020h:01 (the §4.1 default mapping 60200120h) when the
//               sensor has it, else 6004h (§4.2 "Position value channel 1", §8.2's mappable list;
//               §4.2 lists no 6020h): a sensor that refuses the 60200120h entry gets 60040020h in its
//               stead (instead_of_refused(); position_object())
//   bytes 4..5  speed value channel 1, INTEGER16 (60300110h, 6030h:01)
//   byte  6     CAM state channel 1 (63000108h, 6300h:01, §8.2 mappable)
//   byte  7     work area state channel 1 (64000108h, 6400h:01, §8.2 mappable, §5.7.1 bits)
// so that a custom mapping saved in the sensor cannot be misread, and the CAM and work-area
// states come as the objects themselves: the EMCYs 9080h/9090h that also report them are
// suppressed by a stored 2104h >= 2 (§4.3) and 9090h's byte 7 has two codings in §9.1 ("coded
// according to 0x6400" and "0: Valid, 1: underflow, 2: overflow"); they are decoded to text only.
//
// Signals (index: name, kind, unit, range, neutral):
//   0 position   Position  counts (steps, 6001h per revolution; 6002h total)  INT32 range, neutral 0
//   1 speed      Speed     0.1 deg/s (§3.4 "Resolution speed 0,1°/s")        INT16 range, neutral 0
//   2 cams       Digital   bits  CAM state channel 1 (6300h:01, bit n-1 = CAM n), 0..15, neutral 0
//   3 work_area  Digital   bits  work area state channel 1 (6400h:01: bit 0 out of range, bit 1
//                               overflow, bit 2 underflow), 0..7, neutral 0
// "Neutral" of an absolute encoder: there is no "not operated" position. 0 is the fault value the
// driver reports with Error/Offline: the encoder zero point after the preset (6003h), NOT a safe
// state — a consumer must act on the status, never on the value 0. Speed 0 = standstill, the value
// the sensor itself sends on a process error (§9). The CAM and work-area states are computed from
// the position: while the position is an error, they are Error too.
//
// Error positions (§9.1 EMCY table, §10.1 bits 12/13/20/21, §10.2):
//   7FFFFFFCh  measurement error, unknown error, device hardware / ASIC / software fault
//   7FFFFFF8h  position overflow "Out of range (+)" (error 5051h/1/1 or warning 5051h/2/1)
//   80000008h  position underflow "Out of range (-)" (error 5051h/1/2 or warning 5051h/2/2)
//   any other value in 7FFFFFF0h..7FFFFFFFh or 80000000h..8000000Fh: reserved marker band, Error
//   (a 44-turn 16-bit encoder, 650Ah:03 = 2BFFFFh, cannot reach it).
// Each puts position, speed, cams and work_area into Error with the neutral value (the sensor
// sets speed to 0 on a process error, §9, so its speed is not a measurement either; the CAM and
// work-area states derive from the position). The next ordinary position
// clears it. last_error_position() tells which marker was seen. Not treated as a marker: the
// "0x7FF0" of §9's prose, which lies inside the measuring range (0..2BFFFFh) and contradicts the
// §9.1 table; flagging it would fault a valid position of 32752 counts.
//
// EMCYs (§9.1): decoded by (error code, byte 2 error register, byte 3) into the table's text.
// The Error/Hard-level entries whose position value is a marker, and the sensor faults (supply
// voltage fault, memory lost: scaling/preset may be gone) fault position and speed
// (Driver::faulted; DecodedEmcy::error = true, affected = {position, speed}) until the clear
// code of that fault. Each latch has its cause (Latch): a position error (5051h/1/x) ends with
// 5051h/0/0 "valid position" ("if the internal error bit is reset to 0, an EMCY with 0x0000
// (valid position) is sent") — for "Out of range (+/-)" (5051h/1/1, 5051h/1/2) only after the
// position error reset 2100h (command "position_error_reset"); a device fault (1000h, 5000h/1/x,
// 5000h/2/0 memory lost, 6000h/1/0) and the supply voltage fault (3100h/1/0) only with 0000h
// "sensor error resetted, no error" (5000h: "an EMCY with 0x0000 is sent"), which ends every
// latch. A "valid position" does not end a memory loss: the sensor's scaling may still be gone.
// At the next (re)start the read-backs decide what they show: 6503h "Alarms" (§10.2) bits 0, 12,
// 13 the position errors and bit 1 the device faults, 6505h "Warnings" (§10.3) bit 4 the supply
// voltage fault; a refused read or one of the wrong length is no evidence (the latch stays). The
// warnings 5051h/2/1 and 5051h/2/2 put the signals in Error without a latch (the marker comes
// in TPDO1 while they last); 9080h, 9090h, other warnings, info and CAN-controller EMCYs (81xxh,
// CiA 301 "communication", warnings as in every family) are decoded to text only (error =
// false). A code the table lacks is counted (counters().unknown_emcy) and ignored.
//
// Boot: configuration() also writes 2104h "EMCY behaviour" = 0 "all events active" (§4.3: 1..3
// suppress info, warnings, errors and the value is stored by 1010h, §11: a sensor may come with
// the error EMCYs this driver latches on, and the "valid position" that ends them, silenced),
// 1029h:01 = 0 and 1029h:02 = 1 (see there: a measurement error keeps the sensor operational).
// The error register 1001h is UNSIGNED16 in §4.1 (CiA 301: UNSIGNED8): the network manager reads
// either; this driver decides nothing by it.
//
// Options (the table novotechnik_406_options() in novotechnik_406.cpp is what the factory parses
// and `oegw signals` lists):
//   event_timer_ms     TPDO1 event timer 1800h:05, 1..65535 (default 10). 0 is refused: §8.2 says
//                      TPDO1 is then never sent in the default type 254.
//   transmission_type  1800h:02: 254 (event timer, default), 255 (measurement cycle, 1 ms) or
//                      1..240 (every n-th SYNC).
//   product_code       1018h:02 to check at boot: 0x0BD5 (MZ1-2200), 0x0BB9 (MC1-2800), 0x0BBC
//                      (MB1-3600) from §4.1; 0x0BC5 and 0x0BE0 (only in the §6 LSS example) are
//                      accepted too. Unset: only the vendor-ID 0182h is checked (the document
//                      lists several products and ExpectedIdentity holds one).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "subdevices/driver.hpp"

namespace oegw::subdevices {

namespace novotechnik {
inline constexpr std::uint32_t kVendorId = 0x00000182;      // §4.1 1018h:01
inline constexpr std::uint32_t kDeviceType = 0x00020196;    // §4.1 1000h: DS406 multi-sensor
inline constexpr std::int32_t kErrorFault = 0x7FFFFFFC;     // §9.1
inline constexpr std::int32_t kErrorOverflow = 0x7FFFFFF8;  // §9.1 "Out of range (+)"
inline constexpr std::int32_t kErrorUnderflow = static_cast<std::int32_t>(0x80000008u);  // "(-)"
inline constexpr std::uint32_t kProductCodes[] = {0x0BD5, 0x0BB9, 0x0BBC, 0x0BC5, 0x0BE0};

enum class EmcyEffect : std::uint8_t {
  None,             // text only: warning, info, communication
  PositionError,    // position and speed faulted until the clear code of its cause (or the read-back)
  PositionWarning,  // position and speed Error now (the PDO carries the marker), not latched
  Clear,            // 0000h error reset: every latch ends
  ClearPosition,    // 5051h/0/0 valid position: the position errors (5051h/1/x) end
  Cams,             // 9080h
  WorkArea,         // 9090h
};
struct EmcyEntry {
  std::uint16_t code;
  std::uint8_t error_register;  // byte 2 as the table gives it
  std::uint8_t byte3;
  const char* level;  // "Hard", "Error", "Warn", "Info", ""
  const char* text;
  EmcyEffect effect;
};
// The §9.1 table; nullptr for a combination it does not list.
[[nodiscard]] const EmcyEntry* find_emcy(std::uint16_t code, std::uint8_t error_register, std::uint8_t byte3);
}  // namespace novotechnik

struct Novotechnik406Options {
  std::uint16_t event_timer_ms = 10;
  std::uint8_t transmission_type = 254;
  std::optional<std::uint32_t> product_code;
  std::uint32_t freshness_floor_ms = 200;  // Driver::set_freshness_floor
};

class Novotechnik406Driver final : public Driver {
 public:
  static constexpr std::size_t kPosition = 0;
  static constexpr std::size_t kSpeed = 1;
  static constexpr std::size_t kCams = 2;
  static constexpr std::size_t kWorkArea = 3;
  // Any latch faults the position and what follows from it, nothing else.
  static constexpr std::array<std::size_t, 4> kLatchFollowers{kPosition, kSpeed, kCams, kWorkArea};
  static constexpr std::uint8_t kTpdo1Length = 8;

  Novotechnik406Driver(NodeId node, FrameSink sink, Novotechnik406Options options);

  [[nodiscard]] std::string_view family() const override { return "novotechnik-406"; }
  [[nodiscard]] const std::vector<SignalInfo>& signals() const override { return signals_; }
  [[nodiscard]] ExpectedIdentity expected_identity() const override;
  [[nodiscard]] std::vector<SdoWrite> configuration() const override;
  // 2000h node-ID and 2001h bit rate by SDO (document §4.3, §7.1); CiA 406 6000h..6003h
  // (operating parameters, measuring units, preset) and 6200h (cyclic timer): what the position
  // means and when it comes.
  [[nodiscard]] bool protects(std::uint16_t index, std::uint8_t /*sub*/) const override {
    return index == 0x2000 || index == 0x2001 || (index >= 0x6000 && index <= 0x6003) || index == 0x6200;
  }
  // 6503h "Alarms" (§10.2) and 6505h "Warnings" (§10.3), read back at every (re)start: they
  // decide the faults they show.
  void begin_boot() override { reads_done_ = 0; }
  // 1A00h:01 = 60200120h refused (no 6020h): 60040020h, 6004h "Position value", in its stead.
  [[nodiscard]] std::optional<SdoWrite> instead_of_refused(const SdoWrite& write, canopen::SdoAbortCode code) override;
  [[nodiscard]] std::vector<std::pair<std::uint16_t, std::uint8_t>> boot_reads() const override;
  bool on_boot_read(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                    std::string& error) override;
  bool on_boot_read_abort(std::uint16_t index, std::uint8_t sub, canopen::SdoAbortCode code) override;
  void on_application_reset(TimePoint /*now*/) override {}  // the read-backs decide
  bool on_frame(const CanFrame& frame, TimePoint now) override;
  DecodedEmcy on_emcy(const EmcyMessage& emcy, TimePoint now) override;
  // §4.3 2100h "Position Error Reset": the SDO write that resets a latched "Out of range (+/-)"
  // once the sensor is back in the measuring range (Gateway::subdevice_command
  // "position_error_reset"). The fault clears only on the sensor's answer, its EMCY "valid
  // position" (§9.1), never on the write itself.
  [[nodiscard]] std::vector<SdoWrite> command(std::string_view name) const override;
  [[nodiscard]] std::vector<std::string> commands() const override { return {"position_error_reset"}; }
  [[nodiscard]] std::vector<std::uint32_t> consumed_cob_ids() const override;
  bool set_output(std::size_t, std::int64_t, TimePoint) override { return false; }  // no outputs

  // The error marker of the most recent TPDO1 that carried one (nullopt after a good position).
  [[nodiscard]] std::optional<std::uint32_t> last_error_position() const { return last_marker_; }
  [[nodiscard]] const Novotechnik406Options& options() const { return options_; }
  // The position object TPDO1 maps: 6020h (sub 1) unless the sensor refused it, then 6004h.
  [[nodiscard]] std::uint16_t position_object() const { return has_6020h_ ? 0x6020 : 0x6004; }

  // True if `position` is one of the document's error markers (or in the reserved band).
  [[nodiscard]] static bool is_error_position(std::int32_t position);

 private:
  // What keeps position and speed faulted, by what ends it (see the class comment).
  enum Latch : std::uint8_t {
    kLatchPosition = 1u << 0,  // 5051h/1/x; 6503h bits 0, 12, 13
    kLatchDevice = 1u << 1,    // 1000h, 5000h/1/x, 5000h/2/0, 6000h/1/0; 6503h bit 1
    kLatchSupply = 1u << 2,    // 3100h/1/0; 6505h bit 4
  };
  static constexpr std::uint8_t kReadAlarms = 1u << 0;    // 6503h answered or refused
  static constexpr std::uint8_t kReadWarnings = 1u << 1;  // 6505h answered or refused
  [[nodiscard]] static std::uint8_t latch_of(std::uint16_t code);

  void fault_position(TimePoint now);
  // Sets or ends the latches in `mask` to `set`, then faults position and speed while any
  // latch is held (Error at once when `now` is given, also before the first TPDO1).
  void set_latches(std::uint8_t mask, std::uint8_t set, std::optional<TimePoint> now);
  // Whether the latches fault signal `i` (set_latches; the state import checks the same rule).
  [[nodiscard]] bool latched(std::size_t i) const;

  void export_family_state(canopen::StateWriter& w) const override;
  void import_family_state(const canopen::StateReader& r) override;

  Novotechnik406Options options_;
  std::vector<SignalInfo> signals_;
  std::optional<std::uint32_t> last_marker_;
  std::uint8_t reads_done_ = 0;  // kReadAlarms | kReadWarnings of this boot
  std::uint8_t latches_ = 0;     // Latch bits
  bool has_6020h_ = true;        // false once the sensor refused 1A00h:01 = 60200120h
};

}  // namespace oegw::subdevices
