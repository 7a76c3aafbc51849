// The CiA 852 functional elements (FE) and where each of their fields lives in the upstream
// object dictionary (CiA 852 clause 9, Tables 1–7): the one table of the CiA 852 layout. The
// dictionary (dictionary.hpp) and the default PDOs (pdo_defaults.hpp) take their sub-indices
// from it; the mapping file names FE fields by it. Pure data, no I/O.
//
// Where clause 9's tables do not add up (Tables 5, 6, 7: push-button cluster 8, indicator cluster
// 8, display sub-indices), one rule per kind is used: docs/design/cia852-decisions.md.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "canopen/301/object_dictionary.hpp"
#include "profiles/cia401/objects.hpp"

namespace oegw::cia852 {

enum class FeKind : std::uint8_t { Joystick, FootPedal, Encoder, Wheel, ButtonCluster, IndicatorCluster, Display };

// "joystick", "pedal", "encoder", "wheel", "buttons", "indicators", "display" — the names used
// in mapping files ("joystick.1", "indicators.2").
[[nodiscard]] std::string_view to_string(FeKind k);
[[nodiscard]] std::optional<FeKind> fe_kind_from_string(std::string_view s);
// Highest instance number (CiA 852 §9.1): 16 joysticks/pedals, 8 of everything else.
[[nodiscard]] std::uint8_t max_instances(FeKind k);
// True for the FEs whose values flow from the operator to the host (inputs).
[[nodiscard]] bool is_input(FeKind k);

struct FeId {
  FeKind kind = FeKind::Joystick;
  std::uint8_t instance = 1;  // 1-based
  friend bool operator==(const FeId&, const FeId&) = default;
  friend auto operator<=>(const FeId&, const FeId&) = default;
};
// "joystick.1", "indicators.2": how mapping files, logs and `oegw check` name an FE.
[[nodiscard]] std::string fe_name(FeId fe);

// One FE field as the mapping file names it, and its place in the dictionary.
struct FeField {
  std::string name;         // "x", "buttons[3]", "memory_x", "switch[17]", "indicator[5]", "parameter[2]"
  std::uint16_t index = 0;  // 6000h, 6401h, 6120h, 6200h, 6411h
  std::uint8_t sub = 0;
  std::uint8_t bit = 0xFF;  // bit within the UNSIGNED8 for one-bit fields, 0xFF = whole value
  canopen::DataType type = canopen::DataType::Unsigned8;  // of the whole OD entry
};

// Every field of one FE instance, in dictionary order:
//  joystick n:  memory_x, memory_y, memory_z (6000h sub 2n−1, bits 0..2), buttons[1..8] (6000h
//               sub 2n, bits 0..7), x, y, z (6401h sub 3n−2 … 3n, INTEGER16)
//  pedal n:     memory_x (6000h sub 20h+n, bit 0), position (6401h sub 30h+n, INTEGER16)
//  encoder n:   position (6120h sub 80h+n, UNSIGNED32 as CiA 852 §9.4 and CiA 401 define 6120h)
//  wheel n:     position (6401h sub 40h+n, INTEGER16)
//  buttons n:   switch[1..64] (6000h sub 31h+8(n−1)+⌊(i−1)/8⌋, bit (i−1) mod 8)
//  indicators n: indicator[1..64] (6200h sub 01h+8(n−1)+⌊(i−1)/8⌋, bit (i−1) mod 8)
//  display n:   parameter[1..12] (6411h sub 12(n−1)+p, INTEGER16)
[[nodiscard]] const std::vector<FeField>& fe_fields(FeId fe);
[[nodiscard]] std::optional<FeField> find_fe_field(FeId fe, std::string_view name);

}  // namespace oegw::cia852
