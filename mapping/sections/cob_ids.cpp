#include "mapping/sections/cob_ids.hpp"

#include <cstdio>
#include <map>
#include <utility>

#include "canopen/types.hpp"

namespace oegw::mapping::sections {

namespace cob = canopen::cob;

namespace {

// What the mapping file refuses as a PDO/EMCY COB-ID: CiA 301's restricted CAN-IDs, the default
// SYNC (080h) and TIME (100h) identifiers, and any 11-bit value above 7FFh. 29-bit ones pass.
bool refused_cob(std::uint32_t cob_id, bool extended) {
  return !extended && (cob::restricted(cob_id) || cob_id == cob::kSync || cob_id == cob::kTime || cob_id > 0x7FF);
}

// "TPDO 1800h:01", "RPDO 1400h:01", "EMCY 1014h:00".
std::string entry_name(std::uint16_t index, std::uint8_t sub) {
  char what[64];
  std::snprintf(what, sizeof what, "%s %04Xh:%02X",
                index == 0x1014  ? "EMCY"
                : index < 0x1800 ? "RPDO"
                                 : "TPDO",
                static_cast<unsigned>(index), static_cast<unsigned>(sub));
  return what;
}

using ExplicitCobs = std::map<std::pair<int, int>, const SdoWriteConfig*>;  // (index, sub)

ExplicitCobs explicit_cobs(const SubdeviceConfig& s) {
  ExplicitCobs out;
  for (const auto& w : s.sdo)
    if (cob::is_pdo_or_emcy_cob_entry(w.index, w.sub_index)) out[{w.index, w.sub_index}] = &w;
  return out;
}

void add_defaults(const SubdeviceConfig& s, const ExplicitCobs& explicit_ones, std::vector<CobUse>& cobs) {
  for (const auto& d : cob::predefined_connection_set(s.node())) {
    if (d.index != 0 && explicit_ones.count({d.index, d.sub})) continue;
    cobs.push_back({d.cob_id, s.name + " " + std::string(d.service) + " (default)", false, s.where});
  }
}

void add_explicit(YamlReader& r, const SubdeviceConfig& s, const ExplicitCobs& explicit_ones,
                  std::vector<CobUse>& cobs) {
  for (const auto& [key, w] : explicit_ones) {
    const canopen::CobId entry{static_cast<std::uint32_t>(w->value)};
    if (!entry.valid()) continue;  // the PDO/EMCY is off
    const std::uint32_t cob_id = entry.raw() & 0x1FFFFFFFu;
    const auto what = entry_name(static_cast<std::uint16_t>(key.first), static_cast<std::uint8_t>(key.second));
    if (refused_cob(cob_id, entry.extended())) {
      r.error(w->where,
              "COB-ID " + hex(cob_id, 3) + " of " + s.name + " " + what +
                  " is reserved by CiA 301 (NMT, SYNC, TIME, SDO, heartbeat or LSS); expected a PDO/EMCY COB-ID");
      continue;
    }
    cobs.push_back(
        {cob_id | (entry.extended() ? canopen::CobId::kExtendedBit : 0u), s.name + " " + what, true, w->where});
  }
}

}  // namespace

void add_cob_uses(YamlReader& r, const SubdeviceConfig& s, std::vector<CobUse>& cobs) {
  const auto explicit_ones = explicit_cobs(s);
  add_defaults(s, explicit_ones, cobs);
  add_explicit(r, s, explicit_ones, cobs);
}

void check_cob_clashes(YamlReader& r, const std::vector<CobUse>& cobs) {
  for (std::size_t i = 0; i < cobs.size(); ++i) {
    if (!cobs[i].explicit_) continue;
    for (std::size_t j = 0; j < cobs.size(); ++j) {
      if (i == j || cobs[i].cob != cobs[j].cob) continue;
      if (cobs[j].explicit_ && j > i) continue;  // a pair of explicit ones: reported once, at the later
      r.error(cobs[i].where, "COB-ID " + hex(cobs[i].cob, 3) + " of " + cobs[i].owner + " clashes with " +
                                 cobs[j].owner + "; expected a COB-ID no other node uses");
      break;
    }
  }
}

}  // namespace oegw::mapping::sections
