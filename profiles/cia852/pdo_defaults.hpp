// The default PDOs of CiA 852 clause 12 for a configured FE set: all disabled, transmission type
// FFh, inhibit time 0, event timer 0.
//
//   TPDO 1, 5..19   joystick 1, 2..16: 6401 x,y,z (10h), 6000 memory, buttons (08h)
//   TPDO 20..27     pedals 2k+1, 2k+2 (k = 0..7): 6000 memory, 6401 position per pedal
//   TPDO 28..31     encoders 2k+1, 2k+2: 6120 position (20h)
//   TPDO 32, 33     wheels 1..4, 5..8: 6401 position
//   TPDO 34..41     push-button cluster 1..8: its eight 6000h bytes
//   RPDO 1, 5..11   indicator cluster 1, 2..8: its eight 6200h bytes
//   RPDO 2, 4, 12   display 1 parameters 1–4, 5–8, 9–12
//   RPDO 13..33     display d (2..8): RPDOs 13+3(d−2) … 15+3(d−2), 4 parameters each
// Each mapping entry is the dictionary entry (fe_table.hpp) holding an FE field the clause names;
// its length is the entry's type. A PDO exists when one of its FEs is configured; it maps only the
// configured FEs' entries (in the clause 12 order). COB-IDs: TPDO 1 = 8000 0180h + node-ID
// (Table 10), every other PDO 8000 0000h (Tables 14, 18, 22, 26, 30, 34; §12.2.2) — the host
// assigns them.
//
// Decisions where the clause is open or inconsistent:
//  * The joystick layout is fixed (3 axes, memory and buttons bytes always exist): TPDO 1 sub 4/5
//    (6000h) are mandatory and fixed byte positions help the host.
//  * Table 12 sub 3 ("FFFFh if 3-axis joystick not supported") is not applied: z always exists
//    (0 when not fed), so the PDO layout does not depend on the axis count.
//  * RPDO 13–34 for displays 2–8 (22 PDOs for 21 needed): three each, RPDO 34 unused.
//  * Encoder mapping entries are printed without length (6120 81h): 20h (INTEGER32) is used.
//  * TPDO numbers follow CiA 301 (TPDO n = 1800h/1A00h + n − 1), as Table 9 (TPDO 1 = 1800h)
//    and the RPDO tables (RPDO 1/2 = 1400h/1401h) do; Tables 13, 17, 21, 25 print 1814h, 181Ch,
//    1820h, 1822h for TPDO 20, 28, 32, 34 (1800h + n), which contradicts both. The clause
//    headings, the text and the PDO numbers win: pedal 1 is TPDO 20 at 1813h.
//  * Pedal pairs (Table 16 maps pedal 2's entries into TPDO 20): a PDO maps only the configured
//    pedals of its pair, encoders and wheels likewise.
//  * TPDO COB-IDs use the "8000 …h" form (RTR allowed: the core serves RTR for types 252/253).
#pragma once

#include <cstdint>
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

}  // namespace oegw::cia852
