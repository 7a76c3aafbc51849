#include "profiles/cia852/fe_table.hpp"

#include <iterator>

namespace oegw::cia852 {

using canopen::DataType;

std::string fe_name(FeId fe) { return std::string(to_string(fe.kind)) + "." + std::to_string(fe.instance); }

std::string_view to_string(FeKind k) {
  switch (k) {
    case FeKind::Joystick: return "joystick";
    case FeKind::FootPedal: return "pedal";
    case FeKind::Encoder: return "encoder";
    case FeKind::Wheel: return "wheel";
    case FeKind::ButtonCluster: return "buttons";
    case FeKind::IndicatorCluster: return "indicators";
    case FeKind::Display: return "display";
  }
  return "unknown";
}

std::optional<FeKind> fe_kind_from_string(std::string_view s) {
  for (auto k : {FeKind::Joystick, FeKind::FootPedal, FeKind::Encoder, FeKind::Wheel, FeKind::ButtonCluster,
                 FeKind::IndicatorCluster, FeKind::Display})
    if (to_string(k) == s) return k;
  return std::nullopt;
}

std::uint8_t max_instances(FeKind k) { return (k == FeKind::Joystick || k == FeKind::FootPedal) ? 16 : 8; }

bool is_input(FeKind k) { return k != FeKind::IndicatorCluster && k != FeKind::Display; }

namespace {
std::string indexed(std::string_view base, unsigned i) { return std::string(base) + "[" + std::to_string(i) + "]"; }
std::uint8_t u8(unsigned v) { return static_cast<std::uint8_t>(v); }
// The CiA 401 objects clause 9 places the FEs in.
constexpr std::uint16_t kIn8 = cia401::kReadInput8;
constexpr std::uint16_t kIn32 = cia401::kReadInput32;
constexpr std::uint16_t kAnalogueIn16 = cia401::kReadAnalogueInput16;
constexpr std::uint16_t kOut8 = cia401::kWriteOutput8;
constexpr std::uint16_t kAnalogueOut16 = cia401::kWriteAnalogueOutput16;
}  // namespace

namespace {

std::vector<FeField> build_fields(FeId fe) {
  const unsigned n = fe.instance;
  std::vector<FeField> out;
  switch (fe.kind) {
    case FeKind::Joystick: {
      // CiA 852 Table 1 / Figure 5: memory function bits m-x, m-y, m-z.
      const char* const mem[3] = {"memory_x", "memory_y", "memory_z"};
      for (unsigned b = 0; b < 3; ++b) out.push_back({mem[b], kIn8, u8(2 * n - 1), u8(b), DataType::Unsigned8});
      for (unsigned b = 0; b < 8; ++b)
        out.push_back({indexed("buttons", b + 1), kIn8, u8(2 * n), u8(b), DataType::Unsigned8});
      const char* const axes[3] = {"x", "y", "z"};
      for (unsigned a = 0; a < 3; ++a)
        out.push_back({axes[a], kAnalogueIn16, u8(3 * n - 2 + a), 0xFF, DataType::Integer16});
      break;
    }
    case FeKind::FootPedal:
      out.push_back({"memory_x", kIn8, u8(0x20 + n), 0, DataType::Unsigned8});  // Table 2 / Figure 6
      out.push_back({"position", kAnalogueIn16, u8(0x30 + n), 0xFF, DataType::Integer16});
      break;
    case FeKind::Encoder: out.push_back({"position", kIn32, u8(0x80 + n), 0xFF, DataType::Unsigned32}); break;
    case FeKind::Wheel: out.push_back({"position", kAnalogueIn16, u8(0x40 + n), 0xFF, DataType::Integer16}); break;
    case FeKind::ButtonCluster:
      for (unsigned i = 1; i <= 64; ++i)
        out.push_back(
            {indexed("switch", i), kIn8, u8(0x31 + 8 * (n - 1) + (i - 1) / 8), u8((i - 1) % 8), DataType::Unsigned8});
      break;
    case FeKind::IndicatorCluster:
      for (unsigned i = 1; i <= 64; ++i)
        out.push_back({indexed("indicator", i), kOut8, u8(0x01 + 8 * (n - 1) + (i - 1) / 8), u8((i - 1) % 8),
                       DataType::Unsigned8});
      break;
    case FeKind::Display:
      for (unsigned p = 1; p <= 12; ++p)
        out.push_back({indexed("parameter", p), kAnalogueOut16, u8(12 * (n - 1) + p), 0xFF, DataType::Integer16});
      break;
  }
  return out;
}

constexpr FeKind kAllKinds[] = {FeKind::Joystick,      FeKind::FootPedal,        FeKind::Encoder, FeKind::Wheel,
                                FeKind::ButtonCluster, FeKind::IndicatorCluster, FeKind::Display};
constexpr unsigned kSlots = 17;  // instances 0..16 per kind (0 stays empty)

}  // namespace

const std::vector<FeField>& fe_fields(FeId fe) {
  // Built once: the device's dictionary, its default PDOs and the mapping loader ask for fields
  // thousands of times while a full cab boots (find_fe_field per PDO entry).
  static const std::vector<std::vector<FeField>> table = [] {
    std::vector<std::vector<FeField>> t(std::size(kAllKinds) * kSlots);
    for (const FeKind k : kAllKinds)
      for (unsigned n = 1; n <= max_instances(k); ++n)
        t[static_cast<unsigned>(k) * kSlots + n] = build_fields({k, static_cast<std::uint8_t>(n)});
    return t;
  }();
  static const std::vector<FeField> none;
  const auto k = static_cast<unsigned>(fe.kind);
  if (k >= std::size(kAllKinds) || fe.instance < 1 || fe.instance > max_instances(fe.kind)) return none;
  return table[k * kSlots + fe.instance];
}

std::optional<FeField> find_fe_field(FeId fe, std::string_view name) {
  for (auto& f : fe_fields(fe))
    if (f.name == name) return f;
  return std::nullopt;
}

}  // namespace oegw::cia852
