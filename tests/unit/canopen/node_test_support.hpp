// Test support for the Node tests: an application's part of a dictionary.
#pragma once

#include "canopen/301/object_dictionary.hpp"
#include "canopen/301/pdo.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen::test_support {

// Inputs, an output, a setting (2000h = 7), two TPDOs (TPDO1 on change, TPDO2 every SYNC) and
// an RPDO whose COB-ID defaults follow `id`.
inline void build_application_od(ObjectDictionary& d, NodeId id) {
  d.add_array(0x6000, "Read input 8-bit", DataType::Unsigned8, Access::ReadOnly, 2, {0}, true);
  d.add_array(0x6200, "Write output 8-bit", DataType::Unsigned8, Access::ReadWrite, 1, {0}, true);
  d.add_var(0x2000, "Setting", DataType::Unsigned16, Access::ReadWrite, encode<std::uint16_t>(7));
  install_tpdo(d, 1,
               PdoParameters{.cob_id = cob::kTpdo1 + id.value(),
                             .transmission_type = 0xFF,
                             .mapping = {pdo_map(0x6000, 1, 8), pdo_map(0x6000, 2, 8)}});
  install_tpdo(d, 2,
               PdoParameters{.cob_id = cob::kTpdo2 + id.value(),
                             .transmission_type = 1,
                             .mapping = {pdo_map(0x6000, 1, 8)}});
  install_rpdo(d, 1,
               PdoParameters{.cob_id = cob::kRpdo1 + id.value(),
                             .transmission_type = 0xFF,
                             .mapping = {pdo_map(0x6200, 1, 8)}});
}

}  // namespace oegw::canopen::test_support
