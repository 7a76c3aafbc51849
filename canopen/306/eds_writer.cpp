#include "canopen/306/eds_writer.hpp"

#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <vector>

namespace oegw::canopen {

namespace {

std::string hex(std::uint64_t v, int width = 0) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "0x%0*llX", width, static_cast<unsigned long long>(v));
  return buf;
}
std::string hex_plain(std::uint64_t v, int width) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%0*llX", width, static_cast<unsigned long long>(v));
  return buf;
}

bool node_relative_cob(std::uint16_t index, std::uint8_t sub) {
  if (index == 0x1014 && sub == 0) return true;
  if (index == 0x1200 && (sub == 1 || sub == 2)) return true;
  if (index >= 0x1400 && index <= 0x15FF && sub == 1) return true;
  if (index >= 0x1800 && index <= 0x19FF && sub == 1) return true;
  return false;
}

// CiA 301 §7.3.3 Table 37: function codes of the pre-defined connection set.
bool function_code(std::uint32_t base) {
  switch (base) {
    case 0x080:
    case 0x180:
    case 0x200:
    case 0x280:
    case 0x300:
    case 0x380:
    case 0x400:
    case 0x480:
    case 0x500:
    case 0x580:
    case 0x600: return true;
    default: return false;
  }
}

std::string scalar_text(const canopen::Scalar& s) {
  if (const auto* i = std::get_if<std::int64_t>(&s)) return std::to_string(*i);
  if (const auto* u = std::get_if<std::uint64_t>(&s)) return hex(*u);
  std::ostringstream o;
  o.precision(9);
  o << std::get<double>(s);
  return o.str();
}

std::string value_text(const SubObject& s, std::uint16_t index, canopen::NodeId node) {
  const auto& v = s.default_value;
  if (s.type == DataType::VisibleString) return std::string(v.begin(), v.end());
  if (s.type == DataType::OctetString || s.type == DataType::UnicodeString) {
    std::string out;
    for (auto b : v) out += hex_plain(b, 2);
    return out;
  }
  if (s.type == DataType::Domain || v.empty()) return {};
  if (s.type == DataType::Real32 && v.size() == 4) {
    float f;
    std::memcpy(&f, v.data(), 4);
    return scalar_text(canopen::Scalar{static_cast<double>(f)});
  }
  if (s.type == DataType::Real64 && v.size() == 8) {
    double d;
    std::memcpy(&d, v.data(), 8);
    return scalar_text(canopen::Scalar{d});
  }
  if (canopen::is_signed_integer(s.type)) return std::to_string(canopen::decode_signed(v));
  const std::uint64_t u = canopen::decode_unsigned(v);
  if (s.type == DataType::Boolean) return u ? "1" : "0";
  if (v.size() == 4 && node_relative_cob(index, s.sub_index) && (u & (1u << 29)) == 0) {
    const std::uint32_t id = static_cast<std::uint32_t>(u) & 0x7FF;
    if (id >= node.value() && function_code(id - node.value()))
      return "$NODEID+" + hex((u & ~std::uint64_t{0x7FF}) | (id - node.value()));
  }
  return hex(u);
}

void write_entry(std::ostream& o, const Object& obj, const SubObject& s, canopen::NodeId node, bool var) {
  o << "ParameterName=" << (var ? obj.name() : s.name) << "\n";
  o << "ObjectType=0x7\n";
  o << "DataType=" << hex(static_cast<std::uint16_t>(s.type), 4) << "\n";
  o << "AccessType=" << canopen::to_string(s.access) << "\n";
  const std::string dv = value_text(s, obj.index(), node);
  if (s.type != DataType::Domain) o << "DefaultValue=" << dv << "\n";
  o << "PDOMapping=" << (s.pdo_mappable ? 1 : 0) << "\n";
  if (s.low) o << "LowLimit=" << scalar_text(*s.low) << "\n";
  if (s.high) o << "HighLimit=" << scalar_text(*s.high) << "\n";
}

void object_list(std::ostream& o, const char* section, const std::vector<std::uint16_t>& idx) {
  o << "[" << section << "]\nSupportedObjects=" << idx.size() << "\n";
  for (std::size_t i = 0; i < idx.size(); ++i) o << (i + 1) << "=" << hex(idx[i], 4) << "\n";
  o << "\n";
}

}  // namespace

std::string eds_text(const canopen::ObjectDictionary& od, const EdsInfo& info) {
  std::ostringstream o;
  o << "[FileInfo]\nFileName=" << info.file_name << "\nFileVersion=1\nFileRevision=0\nEDSVersion=4.0\n"
    << "Description=" << info.description << "\nCreationTime=" << info.creation_time
    << "\nCreationDate=" << info.creation_date << "\nCreatedBy=" << info.created_by
    << "\nModificationTime=" << info.creation_time << "\nModificationDate=" << info.creation_date
    << "\nModifiedBy=" << info.created_by << "\n\n";
  if (!info.comments.empty()) {
    o << "[Comments]\nLines=" << info.comments.size() << "\n";
    for (std::size_t i = 0; i < info.comments.size(); ++i) o << "Line" << i + 1 << "=" << info.comments[i] << "\n";
    o << "\n";
  }

  unsigned rx = 0, tx = 0;
  for (const auto& [index, obj] : od.objects()) {
    if (index >= 0x1400 && index <= 0x15FF) ++rx;
    if (index >= 0x1800 && index <= 0x19FF) ++tx;
  }
  o << "[DeviceInfo]\nVendorName=" << info.vendor_name << "\nVendorNumber=" << hex(info.vendor, 8)
    << "\nProductName=" << info.product_name << "\nProductNumber=" << hex(info.product, 8)
    << "\nRevisionNumber=" << hex(info.revision, 8) << "\nOrderCode=" << info.order_code
    << "\nBaudRate_10=" << info.baud_10 << "\nBaudRate_20=" << info.baud_20 << "\nBaudRate_50=" << info.baud_50
    << "\nBaudRate_125=" << info.baud_125 << "\nBaudRate_250=" << info.baud_250 << "\nBaudRate_500=" << info.baud_500
    << "\nBaudRate_800=" << info.baud_800 << "\nBaudRate_1000=" << info.baud_1000
    << "\nSimpleBootUpMaster=0\nSimpleBootUpSlave=1\nGranularity=8\nDynamicChannelsSupported=0"
    << "\nGroupMessaging=0\nNrOfRXPDO=" << rx << "\nNrOfTXPDO=" << tx
    << "\nLSS_Supported=" << (info.lss_supported ? 1 : 0) << "\n\n";

  // CiA 301 §7.4.7.1: the core maps dummy entries 0001h..0007h into RPDOs.
  o << "[DummyUsage]\n";
  for (int i = 1; i <= 7; ++i) o << "Dummy000" << i << "=1\n";
  o << "\n";

  std::vector<std::uint16_t> mandatory, optional, manufacturer;
  for (const auto& [index, obj] : od.objects()) {
    if (index == 0x1000 || index == 0x1001 || index == 0x1018) {
      mandatory.push_back(index);
    } else if (index >= 0x2000 && index <= 0x5FFF) {
      manufacturer.push_back(index);
    } else if (index >= 0x1000) {
      optional.push_back(index);
    }
  }
  object_list(o, "MandatoryObjects", mandatory);
  object_list(o, "OptionalObjects", optional);
  object_list(o, "ManufacturerObjects", manufacturer);

  for (const auto& [index, obj] : od.objects()) {
    if (index < 0x1000) continue;  // data type definitions are not written
    const std::string name = hex_plain(index, 4);
    o << "[" << name << "]\n";
    if (obj.code() == ObjectCode::Var) {
      const SubObject* s = obj.find(0);
      if (s == nullptr) continue;
      write_entry(o, obj, *s, info.node_id, true);
      o << "\n";
      continue;
    }
    o << "ParameterName=" << obj.name() << "\nObjectType=" << hex(static_cast<unsigned>(obj.code()))
      << "\nSubNumber=" << obj.subs().size() << "\n\n";
    for (const auto& [sub, s] : obj.subs()) {
      o << "[" << name << "sub" << hex_plain(sub, 0) << "]\n";
      write_entry(o, obj, s, info.node_id, false);
      o << "\n";
    }
  }
  return o.str();
}

bool write_eds(const std::filesystem::path& path, const canopen::ObjectDictionary& od, const EdsInfo& info,
               std::string& error) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) {
    error = "cannot open " + path.string() + " for writing";
    return false;
  }
  out << eds_text(od, info);
  out.flush();
  if (!out) {
    error = "cannot write " + path.string();
    return false;
  }
  return true;
}

}  // namespace oegw::canopen
