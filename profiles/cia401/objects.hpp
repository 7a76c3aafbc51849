// The objects of CiA 401 (CANopen device profile for generic I/O modules) that the gateway reads
// or builds, named as CiA 401 names them. CiA 852 builds its operator-environment dictionary
// from these objects (clause 9); the generic CiA 401 driver reads them on downstream nodes.
//
// Each digital object is an ARRAY with one sub-index per group of lines (8 lines per UNSIGNED8,
// 32 per UNSIGNED32); each analogue object an ARRAY with one sub-index per channel.
#pragma once

#include <cstdint>
#include <string_view>

namespace oegw::cia401 {

// Digital inputs.
inline constexpr std::uint16_t kReadInput8 = 0x6000;   // Read input 8-bit, UNSIGNED8 per 8 lines
inline constexpr std::uint16_t kReadInput32 = 0x6120;  // Read input 32-bit, UNSIGNED32 per 32 lines
// Digital outputs.
inline constexpr std::uint16_t kWriteOutput8 = 0x6200;       // Write output 8-bit, UNSIGNED8 per 8 lines
inline constexpr std::uint16_t kErrorModeOutput8 = 0x6206;   // per line: 1 = take the error value
inline constexpr std::uint16_t kErrorValueOutput8 = 0x6207;  // per line: the value on a device fault
// Analogue inputs.
inline constexpr std::uint16_t kReadAnalogueInput16 = 0x6401;  // Read analogue input 16-bit, INTEGER16
// BOOLEAN; FALSE: an analogue input change raises no event (no TPDO is triggered by it).
inline constexpr std::uint16_t kAnalogueInputGlobalInterruptEnable = 0x6423;
// Analogue outputs.
inline constexpr std::uint16_t kWriteAnalogueOutput16 = 0x6411;            // Write analogue output 16-bit, INTEGER16
inline constexpr std::uint16_t kAnalogueOutputErrorMode = 0x6443;          // per channel: 1 = take the error value
inline constexpr std::uint16_t kAnalogueOutputErrorValueInteger = 0x6444;  // INTEGER32 per channel

// The object's name as CiA 401 gives it ("Read input 8-bit"); empty for an index not listed above.
[[nodiscard]] constexpr std::string_view object_name(std::uint16_t index) {
  switch (index) {
    case kReadInput8: return "Read input 8-bit";
    case kReadInput32: return "Read input 32-bit";
    case kWriteOutput8: return "Write output 8-bit";
    case kErrorModeOutput8: return "Error mode output 8-bit";
    case kErrorValueOutput8: return "Error value output 8-bit";
    case kReadAnalogueInput16: return "Read analogue input 16-bit";
    case kAnalogueInputGlobalInterruptEnable: return "Analogue input global interrupt enable";
    case kWriteAnalogueOutput16: return "Write analogue output 16-bit";
    case kAnalogueOutputErrorMode: return "Analogue output error mode";
    case kAnalogueOutputErrorValueInteger: return "Analogue output error value integer";
    default: return {};
  }
}

}  // namespace oegw::cia401
