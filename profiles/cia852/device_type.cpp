#include "profiles/cia852/device_type.hpp"

namespace oegw::cia852 {

std::uint32_t device_type_for(const std::vector<FeId>& fes, const std::set<FeId>& joysticks_without_buttons) {
  // CiA 852 Table 8: every row sets bit 7 of the specific functionality and M.
  std::uint32_t specific = 0x80;
  std::uint32_t io = 0;
  for (const FeId& fe : fes) {
    switch (fe.kind) {
      case FeKind::Joystick:
        specific |= 0x01;
        io |= 0x4;
        if (joysticks_without_buttons.count(fe) == 0) io |= 0x1;
        break;
      case FeKind::FootPedal:
        specific |= 0x02;
        io |= 0x4;
        break;
      case FeKind::Encoder:
        specific |= 0x04;
        io |= 0x4;
        break;
      case FeKind::Wheel:
        specific |= 0x08;
        io |= 0x4;
        break;
      case FeKind::ButtonCluster:
        specific |= 0x10;
        io |= 0x1;
        break;
      case FeKind::IndicatorCluster:
        specific |= 0x20;
        io |= 0x2;
        break;
      case FeKind::Display:
        specific |= 0x40;
        io |= 0xA;
        break;
    }
  }
  return specific << 24 | 1u << 23 | io << 16 | kProfile401;
}

}  // namespace oegw::cia852
