// Small, named types for the numbers CANopen passes around, so that a node-ID is never confused
// with a COB-ID, a sub-index or an abort code.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string_view>

namespace oegw::canopen {

// Time. Every service is "sans I/O": it is handed the current time with each frame and each
// advance() call, and never reads a clock itself. Tests drive a simulated clock.
using Duration = std::chrono::microseconds;
using TimePoint = std::chrono::time_point<std::chrono::steady_clock, Duration>;

// CiA 301 §7.3.2 / CiA 305: a node-ID is 1..127; 255 means "unconfigured" in LSS.
class NodeId {
 public:
  constexpr NodeId() = default;
  constexpr explicit NodeId(std::uint8_t v) : v_(v) {}
  [[nodiscard]] constexpr std::uint8_t value() const { return v_; }
  [[nodiscard]] constexpr bool valid() const { return v_ >= 1 && v_ <= 127; }
  [[nodiscard]] constexpr bool unconfigured() const { return v_ == 0xFF; }
  static constexpr NodeId unconfigured_id() { return NodeId{0xFF}; }
  friend constexpr bool operator==(NodeId, NodeId) = default;
  friend constexpr auto operator<=>(NodeId, NodeId) = default;

 private:
  std::uint8_t v_ = 0xFF;
};

// CiA 301 §7.5.2.35: the COB-ID entries (1014h, 1200h, 1400h..., 1800h...) carry, besides the
// 11- or 29-bit identifier, the "valid" bit 31 (1 = not valid), bit 30 (RTR allowed / SYNC
// producer) and bit 29 (frame: 1 = 29-bit).
class CobId {
 public:
  static constexpr std::uint32_t kInvalidBit = 0x80000000u;
  static constexpr std::uint32_t kBit30 = 0x40000000u;
  static constexpr std::uint32_t kExtendedBit = 0x20000000u;

  constexpr CobId() = default;
  constexpr explicit CobId(std::uint32_t raw) : raw_(raw) {}
  [[nodiscard]] constexpr std::uint32_t raw() const { return raw_; }
  [[nodiscard]] constexpr bool valid() const { return (raw_ & kInvalidBit) == 0; }
  [[nodiscard]] constexpr bool bit30() const { return (raw_ & kBit30) != 0; }
  [[nodiscard]] constexpr bool extended() const { return (raw_ & kExtendedBit) != 0; }
  [[nodiscard]] constexpr std::uint32_t can_id() const { return extended() ? (raw_ & 0x1FFFFFFFu) : (raw_ & 0x7FFu); }
  // CiA 301 §7.5.2.35 (and every COB-ID entry: 1005h, 1012h, 1014h, 1028h, 1200h.., 1400h..,
  // 1800h..): with bit 29 = 0 (an 11-bit CAN-ID) bits 11..28 are 0. A value with any of them set
  // names no frame; a write of one is refused with 0609 0030h (value range exceeded), never cut
  // to its 11 bits.
  [[nodiscard]] constexpr bool well_formed() const { return extended() || (raw_ & 0x1FFFF800u) == 0; }
  friend constexpr bool operator==(CobId, CobId) = default;

 private:
  std::uint32_t raw_ = kInvalidBit;
};

// CiA 301 §7.2.4.3.17, Table 22: SDO abort codes. `None` (0) means "accepted" and is what a
// write hook returns when it has no objection.
enum class SdoAbortCode : std::uint32_t {
  None = 0,
  ToggleBitNotAlternated = 0x05030000,
  Timeout = 0x05040000,
  UnknownCommandSpecifier = 0x05040001,
  InvalidBlockSize = 0x05040002,
  InvalidSequenceNumber = 0x05040003,
  CrcError = 0x05040004,
  OutOfMemory = 0x05040005,
  UnsupportedAccess = 0x06010000,
  ReadOfWriteOnly = 0x06010001,
  WriteOfReadOnly = 0x06010002,
  ObjectDoesNotExist = 0x06020000,
  CannotBeMapped = 0x06040041,
  MappingExceedsPdoLength = 0x06040042,
  ParameterIncompatibility = 0x06040043,
  InternalIncompatibility = 0x06040047,
  HardwareError = 0x06060000,
  LengthMismatch = 0x06070010,
  LengthTooHigh = 0x06070012,
  LengthTooLow = 0x06070013,
  SubIndexDoesNotExist = 0x06090011,
  InvalidValue = 0x06090030,
  ValueTooHigh = 0x06090031,
  ValueTooLow = 0x06090032,
  MaxLessThanMin = 0x06090036,
  ResourceNotAvailable = 0x060A0023,
  GeneralError = 0x08000000,
  CannotTransfer = 0x08000020,
  CannotTransferLocalControl = 0x08000021,
  CannotTransferDeviceState = 0x08000022,
  NoObjectDictionary = 0x08000023,
  NoDataAvailable = 0x08000024,
};

[[nodiscard]] std::string_view to_string(SdoAbortCode code);

// CiA 301 §7.3.2.2.1 NMT states; the numeric values are the heartbeat/boot-up state bytes
// (§7.2.8.3.2.1, Table 55).
enum class NmtState : std::uint8_t {
  Initialisation = 0x00,  // boot-up message
  Stopped = 0x04,
  Operational = 0x05,
  PreOperational = 0x7F,
};

[[nodiscard]] std::string_view to_string(NmtState state);
// True for the four state bytes of Table 55 (a heartbeat's byte, a state read back).
[[nodiscard]] constexpr bool is_nmt_state(std::uint8_t b) {
  switch (static_cast<NmtState>(b)) {
    case NmtState::Initialisation:
    case NmtState::Stopped:
    case NmtState::Operational:
    case NmtState::PreOperational: return true;
  }
  return false;
}

// CiA 301 §7.2.8.3.1.1, Table 51: NMT command specifiers.
enum class NmtCommand : std::uint8_t {
  Start = 0x01,
  Stop = 0x02,
  EnterPreOperational = 0x80,
  ResetNode = 0x81,
  ResetCommunication = 0x82,
};

// CiA 301 §7.3.5, Table 36 (the pre-defined connection set): function codes, to be added to
// the node-ID.
namespace cob {
inline constexpr std::uint32_t kNmt = 0x000;
inline constexpr std::uint32_t kSync = 0x080;
inline constexpr std::uint32_t kEmcy = 0x080;  // + node-ID
inline constexpr std::uint32_t kTime = 0x100;
inline constexpr std::uint32_t kTpdo1 = 0x180;
inline constexpr std::uint32_t kRpdo1 = 0x200;
inline constexpr std::uint32_t kTpdo2 = 0x280;
inline constexpr std::uint32_t kRpdo2 = 0x300;
inline constexpr std::uint32_t kTpdo3 = 0x380;
inline constexpr std::uint32_t kRpdo3 = 0x400;
inline constexpr std::uint32_t kTpdo4 = 0x480;
inline constexpr std::uint32_t kRpdo4 = 0x500;
inline constexpr std::uint32_t kSdoTx = 0x580;  // server -> client
inline constexpr std::uint32_t kSdoRx = 0x600;  // client -> server
inline constexpr std::uint32_t kHeartbeat = 0x700;
inline constexpr std::uint32_t kLssMaster = 0x7E5;  // CiA 305 §5: master -> slaves
inline constexpr std::uint32_t kLssSlave = 0x7E4;   // CiA 305 §5: slave -> master

// CiA 301 §7.3.5, Table 36 "restricted CAN-IDs" (11-bit): no PDO or EMCY may use them (NMT,
// the reserved ranges, the default SDO, NMT error control and LSS identifiers).
[[nodiscard]] constexpr bool restricted(std::uint32_t can_id) {
  return can_id == 0x000 || (can_id >= 0x001 && can_id <= 0x07F) || (can_id >= 0x101 && can_id <= 0x180) ||
         (can_id >= 0x581 && can_id <= 0x5FF) || (can_id >= 0x601 && can_id <= 0x67F) ||
         (can_id >= 0x6E0 && can_id <= 0x6FF) || (can_id >= 0x701 && can_id <= 0x77F) ||
         (can_id >= 0x780 && can_id <= 0x7FF);
}

// The object entries that hold the COB-ID of a PDO or of the EMCY: RPDO 1400h..15FFh sub 01h and
// TPDO 1800h..19FFh sub 01h (CiA 301 §7.5.2.35, §7.5.2.37), COB-ID EMCY 1014h sub 00h.
[[nodiscard]] constexpr bool is_pdo_or_emcy_cob_entry(std::uint16_t index, std::uint8_t sub) {
  const bool pdo = (index >= 0x1400 && index <= 0x15FF) || (index >= 0x1800 && index <= 0x19FF);
  return (pdo && sub == 1) || (index == 0x1014 && sub == 0);
}

// One COB-ID of a node's predefined connection set (CiA 301 §7.3.5, Table 36).
struct DefaultCobId {
  std::string_view service;  // "EMCY", "TPDO1" .. "RPDO4", "SDO server->client", ...
  std::uint32_t cob_id = 0;
  std::uint16_t index = 0;  // the entry that re-assigns it (is_pdo_or_emcy_cob_entry); 0: none
  std::uint8_t sub = 0;
};

// The COB-IDs node `node` (1..127) occupies by default: EMCY, TPDO1/RPDO1 .. TPDO4/RPDO4, the
// default SDO (server->client, client->server) and NMT error control, in that order.
[[nodiscard]] constexpr std::array<DefaultCobId, 12> predefined_connection_set(NodeId node) {
  const std::uint32_t n = node.value();
  return {{
      {"EMCY", kEmcy + n, 0x1014, 0},
      {"TPDO1", kTpdo1 + n, 0x1800, 1},
      {"RPDO1", kRpdo1 + n, 0x1400, 1},
      {"TPDO2", kTpdo2 + n, 0x1801, 1},
      {"RPDO2", kRpdo2 + n, 0x1401, 1},
      {"TPDO3", kTpdo3 + n, 0x1802, 1},
      {"RPDO3", kRpdo3 + n, 0x1402, 1},
      {"TPDO4", kTpdo4 + n, 0x1803, 1},
      {"RPDO4", kRpdo4 + n, 0x1403, 1},
      {"SDO server->client", kSdoTx + n, 0, 0},
      {"SDO client->server", kSdoRx + n, 0, 0},
      {"heartbeat", kHeartbeat + n, 0, 0},
  }};
}
}  // namespace cob

}  // namespace oegw::canopen
