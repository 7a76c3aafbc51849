// Consistency checks of an EDS beyond its syntax (CiA 306 reader: eds_reader.hpp), run where a
// file is accepted, so that `oegw check` refuses what would otherwise fail only at boot.
//
// Default PDO mappings (1600h–17FFh receive, 1A00h–1BFFh transmit; CiA 301 §7.5.2.36 and
// §7.5.2.38): sub 0 counts at most 64 entries and no more than the object has; each entry
// 1..n is written (a numeric DefaultValue) as index << 16 | sub << 8 | length in bits; it names
// an object the file describes, whose PDOMapping is 1 and whose data type is exactly that long
// (a dummy entry, index 0001h–0007h, is the length of that type: CiA 301 §7.4.7.1); together
// they fit one CAN frame (64 bits). Only PDOs enabled by default are checked (their COB-ID's
// bit 31 clear in 1400h/1800h sub 1): a disabled one is used only once configured, and then the
// node's actual mapping is read at boot.
#pragma once

#include <string>
#include <vector>

#include "canopen/306/eds_reader.hpp"

namespace oegw::canopen::eds {

// One line per problem: "pedal.eds:120: 1A00h sub 1 maps 6401h:01 ...; expected ...".
[[nodiscard]] std::vector<std::string> check_pdo_mappings(const File& file);

}  // namespace oegw::canopen::eds
