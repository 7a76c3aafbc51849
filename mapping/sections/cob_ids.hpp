// The COB-IDs the sub-devices occupy on the downstream bus, in the mapping file's words: each
// node's predefined connection set (canopen::cob::predefined_connection_set), an `sdo` write of a
// PDO/EMCY COB-ID in place of that default, and every clash between them.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "mapping/config.hpp"
#include "mapping/yaml_reader.hpp"

namespace oegw::mapping::sections {

// A COB-ID in use on the downstream bus.
struct CobUse {
  std::uint32_t cob = 0;   // the CAN-ID, | CobId::kExtendedBit for a 29-bit one
  std::string owner;       // "right_grip TPDO1 (default)", "right_grip TPDO 1800h:01"
  bool explicit_ = false;  // written in the sdo list
  Location where;
};

// Adds the COB-IDs of `s` (node-ID set) to `cobs`: its predefined connection set minus what its
// sdo list re-assigns, plus that. A re-assigned COB-ID that is not valid (bit 31) occupies
// nothing; one that CiA 301 reserves, or SYNC 080h or TIME 100h, is an error.
void add_cob_uses(YamlReader& r, const SubdeviceConfig& s, std::vector<CobUse>& cobs);

// Every explicit COB-ID that another use shares is an error; two explicit ones are reported once,
// at the later.
void check_cob_clashes(YamlReader& r, const std::vector<CobUse>& cobs);

}  // namespace oegw::mapping::sections
