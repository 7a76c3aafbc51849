// CiA 852 §11.2 Table 8: the device type (1000h) of an OE interface module, from its FE set.
//
// Decisions where Table 8 is open: specific functionality = bits 24–31, M = bit 23, I/O
// functionality = bits 16–19 (bit 16 digital input, 17 digital output, 18 analogue input, 19
// analogue output), profile 0191h = bits 0–15. "0" in a row means "this FE does not set the
// bit". A joystick sets the digital-input bit only when it has buttons ("Joystick with
// buttons"); memory bits alone do not, as for the foot pedal whose row never sets it.
#pragma once

#include <cstdint>
#include <set>
#include <vector>

#include "profiles/cia852/fe_table.hpp"

namespace oegw::cia852 {

inline constexpr std::uint16_t kProfile401 = 0x0191;

// `joysticks_without_buttons`: joysticks whose button byte is fed by nothing (the dictionary
// layout keeps the byte; only 1000h changes).
[[nodiscard]] std::uint32_t device_type_for(const std::vector<FeId>& fes,
                                            const std::set<FeId>& joysticks_without_buttons = {});

}  // namespace oegw::cia852
