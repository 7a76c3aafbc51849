#include "profiles/cia852/pdo_defaults.hpp"

#include <algorithm>
#include <array>

namespace oegw::cia852 {

namespace {

// One FE field whose dictionary entry a PDO maps. A one-bit field stands for its whole byte
// ("memory_x": the joystick's memory byte; "switch[9]": the cluster's second byte).
struct Slot {
  FeId fe;
  std::string field;
};

// One PDO of clause 12 with every slot its table prints, in the table's mapping order.
struct Layout {
  bool transmit = true;
  unsigned number = 0;
  std::vector<Slot> slots;
};

constexpr std::array<FeKind, 7> kKinds{FeKind::Joystick,      FeKind::FootPedal,        FeKind::Encoder, FeKind::Wheel,
                                       FeKind::ButtonCluster, FeKind::IndicatorCluster, FeKind::Display};

std::uint8_t u8(unsigned v) { return static_cast<std::uint8_t>(v); }
std::string indexed(const char* base, unsigned i) { return std::string(base) + "[" + std::to_string(i) + "]"; }

bool has_kind(const std::vector<FeId>& fes, FeKind k) {
  return std::any_of(fes.begin(), fes.end(), [k](const FeId& f) { return f.kind == k; });
}

// Clause 12, every PDO of kind `k`, in PDO number order within the kind.
std::vector<Layout> clause12_layouts(FeKind k) {
  std::vector<Layout> out;
  switch (k) {
    case FeKind::Joystick:
      // §12.2.1/§12.2.2, Table 12: TPDO 1 joystick 1, TPDO 5..19 joysticks 2..16 (Table 1).
      for (unsigned n = 1; n <= 16; ++n) {
        const FeId j{FeKind::Joystick, u8(n)};
        out.push_back({true, n == 1 ? 1 : 3 + n, {{j, "x"}, {j, "y"}, {j, "z"}, {j, "memory_x"}, {j, "buttons[1]"}}});
      }
      break;
    case FeKind::FootPedal:
      // §12.2.3/§12.2.4, Table 16: TPDO 20 + k carries pedals 2k+1 (subs 1, 2) and 2k+2 (3, 4).
      for (unsigned k2 = 0; k2 < 8; ++k2) {
        Layout l{true, 20 + k2, {}};
        for (unsigned p = 2 * k2 + 1; p <= 2 * k2 + 2; ++p) {
          const FeId pedal{FeKind::FootPedal, u8(p)};
          l.slots.push_back({pedal, "memory_x"});
          l.slots.push_back({pedal, "position"});
        }
        out.push_back(std::move(l));
      }
      break;
    case FeKind::Encoder:
      // §12.2.5/§12.2.6, Table 20: TPDO 28 + k carries encoders 2k+1, 2k+2.
      for (unsigned k2 = 0; k2 < 4; ++k2) {
        Layout l{true, 28 + k2, {}};
        for (unsigned e = 2 * k2 + 1; e <= 2 * k2 + 2; ++e) l.slots.push_back({{FeKind::Encoder, u8(e)}, "position"});
        out.push_back(std::move(l));
      }
      break;
    case FeKind::Wheel:
      // §12.2.7/§12.2.8, Table 24: TPDO 32 wheels 1..4, TPDO 33 wheels 5..8.
      for (unsigned k2 = 0; k2 < 2; ++k2) {
        Layout l{true, 32 + k2, {}};
        for (unsigned w = 4 * k2 + 1; w <= 4 * k2 + 4; ++w) l.slots.push_back({{FeKind::Wheel, u8(w)}, "position"});
        out.push_back(std::move(l));
      }
      break;
    case FeKind::ButtonCluster:
      // §12.2.9/§12.2.10, Table 28: TPDO 34 + (n−1) push-button cluster n, eight bytes.
      for (unsigned n = 1; n <= 8; ++n) {
        Layout l{true, 33 + n, {}};
        for (unsigned b = 0; b < 8; ++b)
          l.slots.push_back({{FeKind::ButtonCluster, u8(n)}, indexed("switch", 8 * b + 1)});
        out.push_back(std::move(l));
      }
      break;
    case FeKind::IndicatorCluster:
      // §12.2.11/§12.2.12, Table 32: RPDO 1 indicator cluster 1, RPDO 5..11 clusters 2..8.
      for (unsigned n = 1; n <= 8; ++n) {
        Layout l{false, n == 1 ? 1 : 3 + n, {}};
        for (unsigned b = 0; b < 8; ++b)
          l.slots.push_back({{FeKind::IndicatorCluster, u8(n)}, indexed("indicator", 8 * b + 1)});
        out.push_back(std::move(l));
      }
      break;
    case FeKind::Display:
      // §12.2.13/§12.2.14, Table 36: display 1 on RPDO 2, 4, 12; display d on RPDO 13+3(d−2) …
      // 15+3(d−2); RPDO 34 does not exist (docs/design/cia852-decisions.md).
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
      break;
  }
  return out;
}

// "1, 3..16": the instance numbers, runs as ranges.
std::string instance_list(const std::vector<unsigned>& n) {
  std::string s;
  for (std::size_t i = 0; i < n.size();) {
    std::size_t j = i;
    while (j + 1 < n.size() && n[j + 1] == n[j] + 1) ++j;
    if (!s.empty()) s += ", ";
    s += std::to_string(n[i]);
    if (j > i) s += (j == i + 1 ? ", " : "..") + std::to_string(n[j]);
    i = j + 1;
  }
  return s;
}

// The objects an unconfigured instance of `k` occupies, for the EDS comment.
const char* objects_of(FeKind k) {
  switch (k) {
    case FeKind::Joystick: return "6000h memory off, buttons released; 6401h x, y, z centred";
    case FeKind::FootPedal: return "6000h memory off; 6401h position";
    case FeKind::Encoder: return "6120h position";
    case FeKind::Wheel: return "6401h position";
    case FeKind::ButtonCluster: return "6000h switches released";
    case FeKind::IndicatorCluster:
      return "6200h indicators off; an SDO download is aborted with 08000020h, RPDO bytes are ignored";
    case FeKind::Display: return "6411h parameters; an SDO download is aborted with 08000020h, RPDO bytes are ignored";
  }
  return "";
}

}  // namespace

std::vector<FeId> pdo_instances(const std::vector<FeId>& fes) {
  std::vector<FeId> out;
  for (const FeKind k : kKinds)
    if (has_kind(fes, k))
      for (unsigned n = 1; n <= max_instances(k); ++n) out.push_back({k, u8(n)});
  return out;
}

std::vector<DefaultPdo> default_pdos(const std::vector<FeId>& fes, canopen::NodeId node_id) {
  constexpr std::uint32_t kDisabled = 0x80000000u;
  std::vector<DefaultPdo> out;
  for (const FeKind k : kKinds) {
    if (!has_kind(fes, k)) continue;
    for (const Layout& l : clause12_layouts(k)) {
      canopen::PdoParameters p;
      for (const Slot& s : l.slots) {
        const auto f = find_fe_field(s.fe, s.field);
        if (f) p.mapping.push_back(canopen::pdo_map(f->index, f->sub, u8(8 * canopen::fixed_size(f->type))));
      }
      // Table 10: (8000 0180h or C000 0180h) + node-ID for TPDO 1; 8000 0000h for every other PDO.
      p.cob_id = l.transmit && l.number == 1 ? kDisabled + 0x180 + node_id.value() : kDisabled;
      p.transmission_type = 0xFF;  // §12.1
      p.mapping_capacity = 8;
      out.push_back({l.transmit, static_cast<std::uint16_t>(l.number), std::move(p)});
    }
  }
  std::sort(out.begin(), out.end(), [](const DefaultPdo& a, const DefaultPdo& b) {
    return a.transmit != b.transmit ? a.transmit : a.number < b.number;
  });
  return out;
}

std::vector<std::string> pdo_eds_comments(const std::vector<FeId>& fes) {
  std::vector<std::string> out;
  if (has_kind(fes, FeKind::Joystick))
    out.push_back(
        "CiA 852 Table 12: TPDO 1 and 5..19 always map z at sub 3 (6401h sub 3n), never FFFFh; a joystick "
        "with fewer axes reads z = 0");
  if (has_kind(fes, FeKind::FootPedal))
    out.push_back(
        "CiA 852 Tables 13/15: TPDO 20..27 are at 1813h..181Ah / 1A13h..1A1Ah (CiA 301 numbering, "
        "TPDO n = 1800h + n - 1), not at 1814h/1A14h as printed");
  if (has_kind(fes, FeKind::Encoder)) {
    out.push_back(
        "CiA 852 Tables 17/19: TPDO 28..31 are at 181Bh..181Eh / 1A1Bh..1A1Eh, not at 181Ch/1A1Ch as printed");
    out.push_back("CiA 852 Table 20: encoder entries are mapped 32 bits long (6120h sub 8nh length 20h)");
  }
  if (has_kind(fes, FeKind::Wheel))
    out.push_back(
        "CiA 852 Tables 21/23: TPDO 32, 33 are at 181Fh, 1820h / 1A1Fh, 1A20h, not at 1820h/1A20h as printed");
  if (has_kind(fes, FeKind::ButtonCluster)) {
    out.push_back(
        "CiA 852 Tables 25/27: TPDO 34..41 are at 1821h..1828h / 1A21h..1A28h, not at 1822h/1A22h as printed");
    out.push_back(
        "CiA 852 Table 5: push-button cluster n is 6000h sub 31h+8(n-1)..38h+8(n-1); cluster 8 is 69h..70h "
        "(printed: 61h to 70h)");
  }
  if (has_kind(fes, FeKind::IndicatorCluster))
    out.push_back(
        "CiA 852 Table 6: indicator cluster n is 6200h sub 01h+8(n-1)..08h+8(n-1); cluster 8 is 39h..40h "
        "(printed: 31h to 40h)");
  if (has_kind(fes, FeKind::Display)) {
    out.push_back(
        "CiA 852 Table 7: display n parameter p is 6411h sub 12(n-1)+p; display 8 is 55h..60h (printed: "
        "ABh to C0h)");
    out.push_back("CiA 852 12.2.14: displays 2..8 use RPDO 13..33, three each; RPDO 34 (1421h/1621h) does not exist");
  }
  if (has_kind(fes, FeKind::IndicatorCluster) || has_kind(fes, FeKind::Display))
    out.push_back("CiA 852 Tables 32/36: RPDO mapping sub 0 is rw (variable mapping, 8.5), not const as printed");
  for (const FeKind k : kKinds) {
    if (!has_kind(fes, k)) continue;
    std::vector<unsigned> missing;
    for (unsigned n = 1; n <= max_instances(k); ++n)
      if (std::find(fes.begin(), fes.end(), FeId{k, u8(n)}) == fes.end()) missing.push_back(n);
    if (missing.empty()) continue;
    out.push_back(std::string(to_string(k)) + " " + instance_list(missing) +
                  " not configured: their entries in the default PDOs read 0 and never change (" + objects_of(k) + ")");
  }
  return out;
}

}  // namespace oegw::cia852
