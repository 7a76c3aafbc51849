// Which driver family a node is, from its identity (1000h device type, 1018h vendor and product):
// what `oegw scan` writes into the draft mapping file. The values are the manufacturers'
// documents' (/work/shared/reference, cited in family_identity.cpp), not the drivers' constants.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace oegw::subdevices {

// What a node told about itself; each value absent when it was not read (no answer, an abort:
// the MCB-402 has no 1018h:04).
struct NodeIdentity {
  std::optional<std::uint32_t> device_type;   // 1000h
  std::optional<std::uint32_t> vendor_id;     // 1018h:01
  std::optional<std::uint32_t> product_code;  // 1018h:02
  std::optional<std::uint32_t> revision;      // 1018h:03
  std::optional<std::uint32_t> serial;        // 1018h:04
};

struct FamilyMatch {
  // "elobau-mfg", "mcb402", "novotechnik-406", "cia401"; empty: unknown (no driver fits).
  std::string family;
  // Why, in words for the draft's comment: "vendor 000000B4h (elobau)", "device type
  // 00050191h: CiA 401 profile"; and a doubt where the identity is close but not exact.
  std::string reason;
};

// The CiA 301 profile number of a device type (its lower 16 bits, CiA 301 §7.5.2.1).
[[nodiscard]] constexpr std::uint16_t device_profile(std::uint32_t device_type) {
  return static_cast<std::uint16_t>(device_type & 0xFFFFu);
}

[[nodiscard]] FamilyMatch name_family(const NodeIdentity& identity);

}  // namespace oegw::subdevices
