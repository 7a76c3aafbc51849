#include "subdevices/family_identity.hpp"

#include <cstdio>

namespace oegw::subdevices {

namespace {

// elobau "CANopen Protocol for MFG 34xG and 36xG", object table: 1018h:01 vendor ID 000000B4h
// ("elobau Vendor ID"), 1000h device type 00000000h ("no standardized device profile used");
// the product code (00010003h by default) varies by grip ("refer to elobau Product Overview").
constexpr std::uint32_t kElobauVendor = 0x000000B4;
// CO4013A (MCB-402 controller), "Index 1018h": vendor ID 58h (frenzel + berg elektronik),
// product code 01040131h (CO4013A); "Index 1000": device type 01070191h in operation mode A4
// (the one the mcb402 driver serves), 01050191h in modes A0/A1.
constexpr std::uint32_t kFrenzelBergVendor = 0x58;
constexpr std::uint32_t kCo4013Product = 0x01040131;
constexpr std::uint32_t kCo4013A4DeviceType = 0x01070191;
// Novotechnik CANopen protocol, object table: 1018h/1 vendor ID 00000182h ("386 = 0x0182
// (Novotechnik)"), 1000h device type 00020196h ("Device profile DS406 multi-sensor encoder");
// product codes 0BD5h (MZ1-2200), 0BB9h (MC1-2800), 0BBCh (MB1-3600).
constexpr std::uint32_t kNovotechnikVendor = 0x00000182;
constexpr std::uint16_t kEncoderProfile = 406;  // CiA 406
constexpr std::uint16_t kIoProfile = 401;       // CiA 401 (0191h)

std::string hex8(std::uint32_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "%08Xh", v);
  return b;
}

}  // namespace

FamilyMatch name_family(const NodeIdentity& id) {
  const auto& vendor = id.vendor_id;
  const auto& type = id.device_type;
  if (vendor == kElobauVendor) {
    FamilyMatch m{"elobau-mfg", "vendor " + hex8(*vendor) + " (elobau)"};
    if (type && *type != 0) m.reason += "; device type " + hex8(*type) + ", the MFG 34xG/36xG document says 00000000h";
    return m;
  }
  if (vendor == kFrenzelBergVendor && id.product_code == kCo4013Product) {
    FamilyMatch m{"mcb402", "vendor " + hex8(*vendor) + " (frenzel + berg), product " + hex8(*id.product_code) +
                                " (CO4013A, the MCB-402 controller)"};
    if (type && *type != kCo4013A4DeviceType)
      m.reason += "; device type " + hex8(*type) + " is not operation mode A4 (" + hex8(kCo4013A4DeviceType) +
                  "): the mcb402 driver reads mode A4's PDOs";
    return m;
  }
  if (vendor == kNovotechnikVendor && type && device_profile(*type) == kEncoderProfile)
    return {"novotechnik-406",
            "vendor " + hex8(*vendor) + " (Novotechnik), device type " + hex8(*type) + " (CiA 406 encoder)"};
  if (type && device_profile(*type) == kIoProfile)
    return {"cia401", "device type " + hex8(*type) + " (CiA 401 I/O profile)"};
  std::string why = "no driver fits";
  if (type) why += ": device type " + hex8(*type);
  if (vendor) why += std::string(type ? "," : ":") + " vendor " + hex8(*vendor);
  if (!type && !vendor) why += ": 1000h and 1018h not read";
  return {"", why};
}

}  // namespace oegw::subdevices
