// Simulated Novotechnik CANopen sensor, CiA 406 encoder profile.
// Source: the Novotechnik "CANopen" sensor protocol document (CiA 301 v4.2, CiA 406 v3.2, CiA 305
// LSS; sections cited as §n).
//
// A real canopen::Node (CiA 301 + CiA 305 LSS) with the §4 object library:
//   1000h 00020196h; 1001h (UNSIGNED8 as CiA 301, or UNSIGNED16 as §4.1 lists it: corner
//   error_register_size); 1002h manufacturer status (bits of §10.1); 1008h/1009h/100Ah the §4.1
//   examples; 100Ch/100Dh (objects only: node guarding is not simulated); 1010h subs 1..5 and
//   1011h subs 1..4 with the §11 groups (below); 1014h/1017h; 1018h vendor 0182h and the §6 LSS
//   example identity (product 0BE0h, revision 00010003h, serial 12345678h) unless configured;
//   1029h:01/02; TPDO1 1800h (40000180h + node, type FEh, event timer 0) and TPDO2 1801h
//   (40000280h + node, type 1), both mapped 60200120h + 60300110h, 5 entries each; 1F80h (bit 3:
//   start operational).
//   6000h..6003h (6001h/6002h writable only with scaling on, 6000h bit 2 = 0, else 08000022h;
//   each updates the other and 6501h), 6004h, 600Ch, 6020h:01 (the position object the default
//   mapping 60200120h names; mirrors 6004h; absent in the corner has_6020h=no, where the default
//   mapping is 60040020h: §4.2 lists no 6020h and §8.2 names 6004h mappable), 6030h:01, 6031h (6031h:02 limited to 1,
//   2, 3, 6, 12, 25 ms, coupled to 2010h:02 by the §5.2 table), 6300h..6333h CAMs, 6400h..6402h work area,
//   6500h..650Eh; 2000h node-ID (active at the next reset communication), 2001h bit rate, 2002h temperature, 2003h
//   supply voltage, 2010h filters, 2100h position error reset, 2104h EMCY behaviour. Condition monitoring 2300h..236Bh
//   is not simulated.
//
// Timing: in type 254 TPDO1 goes out on its event timer only (§3.3 "Event Timer"; values are
// updated without "change" events); in type 255 each set_position/set_speed is a measurement
// cycle and sends TPDO1 at once (subject to the inhibit time); 1..240 at SYNC.
//
// EMCYs are sent with the exact §9.1 bytes (byte 2 as the table gives it, byte 3, bytes 4..7),
// on the COB-ID of 1014h, in pre-operational and operational, filtered by 2104h (1: info
// suppressed, 2: info and warnings, 3: also errors; Hard always; its power-on value is the
// corner emcy_behaviour, "stored by 1010h"). CAM states (6300h, without hysteresis) and the
// work-area state (6400h, §5.7.1) are recomputed by set_position and reported by EMCY 9080h /
// 9090h on change; 9090h's byte 7 is "coded according to 0x6400" (the 6400h bits) or the row's
// own list "0: Valid, 1: underflow, 2: overflow" (corner work_area_emcy=bits|enum).
//
// Store (§11): 1010h "save" (65766173h) on sub 1 all, 2 communication, 3 application, 4 user data
// (node-ID 2000h, bit rate 2001h: kept like an LSS store, active at the next reset communication
// or power-up, §7.1), by the §11 table's columns (1005h in none; sub 1 stores the TPDO COB-IDs as
// their defaults, "D"); "kill" (6C6C696Bh) on sub 1..4 deletes that group's stored data and puts
// its objects back to their defaults; 1011h "load" (64616F6Ch) on sub 1..4: §4.1 "restoring of
// default parameters" (CiA 301: the defaults after the next reset) or §11 "will upload data from
// the non-volatile memory" (the stored values now) — corner load=defaults|stored. Another value
// is aborted 0800 0020h, a failed write of the store (no store file given) 0606 0000h "access
// error" (§7.3); sub 5 takes "save" and stores nothing (no manufacturer-defined parameters here).
// Only in pre-operational (§11, refuse_download).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>

#include "subdevices/sim/simulated_device.hpp"

namespace oegw::subdevices::sim {

struct Novotechnik406SimConfig {
  NodeId node_id{0x7F};                 // §3.1 standard models
  std::uint32_t product_code = 0x0BE0;  // §6 switch-mode-selective example (41h E0 0B ..)
  std::uint32_t revision = 0x00010003;  // §4.1 1018h:03 "e.g. 0x10003", §6 example 42h 03 00 01 00
  std::uint32_t serial = 0x12345678;    // §6 example 43h 78 56 34 12
  std::uint16_t bit_rate_kbit = 250;    // 2001h; CiA 305 table index 3
  std::uint16_t heartbeat_ms = 0;       // 1017h default: disabled
  std::filesystem::path store_path;     // empty: 1010h/1011h refuse, LSS store answers error 2
  // Corners (docs/design/device-documents.md#corners-every-reading-a-document-permits; oegw-sim
  // options in parentheses):
  std::uint8_t error_register_bytes = 1;  // 1001h 1 byte, CiA 301 (error_register_size=1), or 2, §4.1
  std::uint8_t emcy_behaviour = 0;        // 2104h at power-on, as stored (emcy_behaviour=0..3)
  bool has_6020h = true;                  // 6020h:01 present (has_6020h=yes|no)
  bool work_area_bits = true;             // 9090h byte 7: 6400h bits, or 0/1/2 (work_area_emcy=bits|enum)
  bool load_restores_defaults =
      true;  // 1011h "load": defaults at the next reset, or the stored values now (load=defaults|stored)
};

class Novotechnik406Sim : public SimulatedDevice {
 public:
  // §9.1 position faults: the marker the position takes and the EMCY that announces it.
  enum class Fault : std::uint8_t {
    Measurement,       // 5051h/1/0, 7FFFFFFCh, alarm bit 0
    Overflow,          // 5051h/1/1, 7FFFFFF8h, alarm bit 13; cleared by 2100h only
    Underflow,         // 5051h/1/2, 80000008h, alarm bit 12; cleared by 2100h only
    OverflowWarning,   // 5051h/2/1, 7FFFFFF8h, warning bit 13
    UnderflowWarning,  // 5051h/2/2, 80000008h, warning bit 12
    HardwareFault,     // 5000h/1/0, 7FFFFFFCh, alarm bit 1
    SoftwareFault,     // 6000h/1/0, 7FFFFFFCh, alarm bit 1
  };

  explicit Novotechnik406Sim(FrameSink sink, Novotechnik406SimConfig config = {});
  [[nodiscard]] std::string_view family() const override { return "novotechnik-406"; }

  void start(TimePoint now) override;
  void reboot(TimePoint now) override;

  // Driver signal names: position (counts), speed (0.1 deg/s). No outputs.
  bool set_input(std::string_view signal, std::int64_t value, TimePoint now) override;
  [[nodiscard]] std::optional<std::int64_t> output(std::string_view) const override { return std::nullopt; }

  // The measured position (what 6004h shows once preset and scaling are applied) and speed.
  void set_position(std::int32_t position, TimePoint now);
  void set_speed(std::int16_t speed, TimePoint now);
  // Puts a raw value (e.g. 7FFFFFFCh) into the position objects without any EMCY.
  void inject_error_position(std::uint32_t raw, TimePoint now);
  // A §9.1 fault: marker position, speed 0, status/alarm/warning bits and its EMCY.
  void inject_fault(Fault fault, TimePoint now);
  // The internal error bit goes back to 0: EMCY 0000h, the real position again. Refused (false)
  // for Overflow/Underflow, which §9.1 resets only through 2100h.
  bool clear_fault(TimePoint now);
  [[nodiscard]] std::optional<Fault> fault() const { return fault_; }
  // Any EMCY, with the §9.1 byte layout (honours 2104h with `level` "Info"/"Warn"/"Error"/"Hard").
  void send_emcy(std::uint16_t code, std::uint8_t error_register, std::uint8_t byte3,
                 std::array<std::uint8_t, 4> bytes4to7, TimePoint now, std::string_view level = "Hard");

  [[nodiscard]] std::int32_t position() const { return position_; }

 private:
  [[nodiscard]] canopen::SdoAbortCode refuse_download(std::uint16_t index, std::uint8_t sub,
                                                      canopen::NmtState state) const override;
  [[nodiscard]] std::optional<canopen::SdoAbortCode> handle_download(std::uint16_t index, std::uint8_t sub,
                                                                     std::span<const std::uint8_t> data) override;
  // §11 store groups (sub-index of 1010h/1011h: 1 all, 2 communication, 3 application, 4 user data).
  canopen::SdoAbortCode save_group(std::uint8_t group);
  canopen::SdoAbortCode forget_group(std::uint8_t group, bool defaults_now);
  canopen::SdoAbortCode load_group(std::uint8_t group);
  void build_od(canopen::ObjectDictionary& od);
  void install_hooks();
  void publish(TimePoint now);
  void update_cams_and_work_area(TimePoint now);
  void apply_startup(TimePoint now);
  void install_startup_rule();
  void set_bits(std::uint16_t index, std::uint32_t mask, bool on);

  Novotechnik406SimConfig cfg_;
  std::int32_t position_ = 0;
  std::int16_t speed_ = 0;
  std::optional<Fault> fault_;
  std::optional<std::uint32_t> forced_raw_;
  TimePoint now_{};
  canopen::NmtState last_state_ = canopen::NmtState::Initialisation;
  canopen::Subscriptions subs_;
};

}  // namespace oegw::subdevices::sim
