#include "profiles/cia852/pdo_defaults.hpp"

#include <algorithm>
#include <string>

namespace oegw::cia852 {

namespace {

// One FE field whose dictionary entry a PDO maps. A one-bit field stands for its whole byte
// ("memory_x": the joystick's memory byte; "switch[9]": the cluster's second byte).
struct Slot {
  FeId fe;
  std::string field;
};

// One PDO of clause 12 with every slot it may carry, in the clause's mapping order.
struct Layout {
  bool transmit = true;
  unsigned number = 0;
  std::vector<Slot> slots;
};

std::uint8_t u8(unsigned v) { return static_cast<std::uint8_t>(v); }
std::string indexed(const char* base, unsigned i) { return std::string(base) + "[" + std::to_string(i) + "]"; }

// Clause 12, every PDO, in the order default_pdos() lists them.
std::vector<Layout> clause12_layouts() {
  std::vector<Layout> out;
  // §12.2.1/§12.2.2, Table 12: TPDO 1 joystick 1, TPDO 5..19 joysticks 2..16.
  for (unsigned n = 1; n <= 16; ++n) {
    const FeId j{FeKind::Joystick, u8(n)};
    out.push_back({true, n == 1 ? 1 : 3 + n, {{j, "x"}, {j, "y"}, {j, "z"}, {j, "memory_x"}, {j, "buttons[1]"}}});
  }
  // §12.2.3/§12.2.4, Table 16: TPDO 20 + k carries pedals 2k+1 and 2k+2.
  for (unsigned k = 0; k < 8; ++k) {
    Layout l{true, 20 + k, {}};
    for (unsigned p = 2 * k + 1; p <= 2 * k + 2; ++p) {
      const FeId pedal{FeKind::FootPedal, u8(p)};
      l.slots.push_back({pedal, "memory_x"});
      l.slots.push_back({pedal, "position"});
    }
    out.push_back(std::move(l));
  }
  // §12.2.5/§12.2.6, Table 20: TPDO 28 + k carries encoders 2k+1, 2k+2.
  for (unsigned k = 0; k < 4; ++k) {
    Layout l{true, 28 + k, {}};
    for (unsigned e = 2 * k + 1; e <= 2 * k + 2; ++e) l.slots.push_back({{FeKind::Encoder, u8(e)}, "position"});
    out.push_back(std::move(l));
  }
  // §12.2.7/§12.2.8, Table 24: TPDO 32 wheels 1..4, TPDO 33 wheels 5..8.
  for (unsigned k = 0; k < 2; ++k) {
    Layout l{true, 32 + k, {}};
    for (unsigned w = 4 * k + 1; w <= 4 * k + 4; ++w) l.slots.push_back({{FeKind::Wheel, u8(w)}, "position"});
    out.push_back(std::move(l));
  }
  // §12.2.9/§12.2.10, Table 28: TPDO 34 + (n−1) push-button cluster n, eight bytes.
  for (unsigned n = 1; n <= 8; ++n) {
    Layout l{true, 33 + n, {}};
    for (unsigned b = 0; b < 8; ++b) l.slots.push_back({{FeKind::ButtonCluster, u8(n)}, indexed("switch", 8 * b + 1)});
    out.push_back(std::move(l));
  }
  // §12.2.11/§12.2.12, Table 32: RPDO 1 indicator cluster 1, RPDO 5..11 clusters 2..8.
  for (unsigned n = 1; n <= 8; ++n) {
    Layout l{false, n == 1 ? 1 : 3 + n, {}};
    for (unsigned b = 0; b < 8; ++b)
      l.slots.push_back({{FeKind::IndicatorCluster, u8(n)}, indexed("indicator", 8 * b + 1)});
    out.push_back(std::move(l));
  }
  // §12.2.13/§12.2.14, Table 36: display 1 on RPDO 2, 4, 12; display d on RPDO 13+3(d−2) …
  for (unsigned d = 1; d <= 8; ++d) {
    const unsigned numbers[3] = {d == 1 ? 2u : 13 + 3 * (d - 2), d == 1 ? 4u : 14 + 3 * (d - 2),
                                 d == 1 ? 12u : 15 + 3 * (d - 2)};
    for (unsigned r = 0; r < 3; ++r) {
      Layout l{false, numbers[r], {}};
      for (unsigned p = 4 * r + 1; p <= 4 * r + 4; ++p)
        l.slots.push_back({{FeKind::Display, u8(d)}, indexed("parameter", p)});
      out.push_back(std::move(l));
    }
  }
  return out;
}

}  // namespace

std::vector<DefaultPdo> default_pdos(const std::vector<FeId>& fes, canopen::NodeId node_id) {
  constexpr std::uint32_t kDisabled = 0x80000000u;
  std::vector<DefaultPdo> out;
  for (const Layout& l : clause12_layouts()) {
    std::vector<std::uint32_t> mapping;
    for (const Slot& s : l.slots) {
      if (std::find(fes.begin(), fes.end(), s.fe) == fes.end()) continue;
      const auto f = find_fe_field(s.fe, s.field);
      if (!f) continue;
      mapping.push_back(canopen::pdo_map(f->index, f->sub, u8(8 * canopen::fixed_size(f->type))));
    }
    if (mapping.empty()) continue;
    canopen::PdoParameters p;
    // Table 10: (8000 0180h or C000 0180h) + node-ID for TPDO 1; 8000 0000h for every other PDO.
    p.cob_id = l.transmit && l.number == 1 ? kDisabled + 0x180 + node_id.value() : kDisabled;
    p.transmission_type = 0xFF;  // §12.1
    p.mapping = std::move(mapping);
    p.mapping_capacity = 8;
    out.push_back({l.transmit, static_cast<std::uint16_t>(l.number), std::move(p)});
  }
  return out;
}

}  // namespace oegw::cia852
