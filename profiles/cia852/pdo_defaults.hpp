// The default PDOs of CiA 852 clause 12 for a configured FE set: all disabled, transmission type
// FFh, inhibit time 0, event timer 0 (§12.1).
//
//   TPDO 1, 5..19   joystick 1, 2..16: 6401 x,y,z (10h), 6000 memory, buttons (08h)  Table 12, Table 1
//   TPDO 20..27     pedals 2k+1, 2k+2 (k = 0..7): 6000 memory, 6401 position, each   Table 16, Table 2
//   TPDO 28..31     encoders 2k+1, 2k+2: 6120 position (20h)                          Table 20, Table 3
//   TPDO 32, 33     wheels 1..4, 5..8: 6401 position                                  Table 24, Table 4
//   TPDO 34..41     push-button cluster 1..8: its eight 6000h bytes                   Table 28, Table 5
//   RPDO 1, 5..11   indicator cluster 1, 2..8: its eight 6200h bytes                  Table 32, Table 6
//   RPDO 2, 4, 12   display 1 parameters 1–4, 5–8, 9–12                               Table 36, Table 7
//   RPDO 13..33     display d (2..8): RPDOs 13+3(d−2) … 15+3(d−2), 4 parameters each  §12.2.14
//
// Existence follows the FE kind: every PDO of a supported kind exists (the categories read
// "Mandatory, if joystick/foot pedal/… supported (see 1000h)", and 1000h names kinds, not
// instances), whichever of its instances are configured. Each PDO maps every entry its table
// prints, in the table's order, so each instance's values sit at the table's sub-index and byte
// position for every combination of configured instances. The entries of an instance that is not
// configured exist in the dictionary and read their neutral value (dictionary.hpp). Each mapping
// entry is the dictionary entry (fe_table.hpp) holding an FE field the clause names; its length
// is the entry's type. COB-IDs: TPDO 1 = 8000 0180h + node-ID (Table 10), every other PDO
// 8000 0000h (Tables 14, 18, 22, 26, 30, 34; §12.2.2) — the host assigns them.
//
// Where clause 12 is open or contradicts itself (PDO numbers and indexes, RPDO 34, the damaged
// tables): docs/design/cia852-decisions.md, one row per decision; pdo_eds_comments() gives the EDS
// its [Comments] line where a host built from the printed tables would differ.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "canopen/301/pdo.hpp"
#include "canopen/types.hpp"
#include "profiles/cia852/fe_table.hpp"

namespace oegw::cia852 {

// One PDO of clause 12 for this FE set.
struct DefaultPdo {
  bool transmit = true;
  std::uint16_t number = 0;
  canopen::PdoParameters params;
};
[[nodiscard]] std::vector<DefaultPdo> default_pdos(const std::vector<FeId>& fes, canopen::NodeId node_id);

// Every FE instance the default PDOs of `fes` map, configured or not: each instance of each
// supported kind, in FeId order. The dictionary holds the entries of all of them.
[[nodiscard]] std::vector<FeId> pdo_instances(const std::vector<FeId>& fes);

// CiA 306 [Comments] lines for the EDS of a device with these FEs: one for each decision of
// docs/design/cia852-decisions.md where a host built from clause 9/12's printed tables would expect
// another index, sub-index or length than this device has, and one per supported kind naming
// its instances that are not configured (their entries read 0 and never change).
[[nodiscard]] std::vector<std::string> pdo_eds_comments(const std::vector<FeId>& fes);

}  // namespace oegw::cia852
