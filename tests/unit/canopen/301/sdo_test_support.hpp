// Shared helpers for the SDO tests (not a test executable itself: no _test suffix).
#pragma once

#include <cstdint>
#include <initializer_list>
#include <ostream>
#include <string>
#include <vector>

#include "canopen/301/object_dictionary.hpp"
#include "canopen/can_frame.hpp"

namespace oegw::canopen {

// gtest prints frames in candump notation.
inline void PrintTo(const CanFrame& f, std::ostream* os) { *os << f.to_string(); }
inline void PrintTo(SdoAbortCode c, std::ostream* os) {
  *os << "0x" << std::hex << static_cast<std::uint32_t>(c) << std::dec << " (" << to_string(c) << ")";
}

}  // namespace oegw::canopen

namespace sdo_test {

using namespace oegw::canopen;

inline std::vector<std::uint8_t> bytes_of(const std::string& s) { return {s.begin(), s.end()}; }

inline std::vector<std::uint8_t> pattern(std::size_t n, std::uint8_t seed = 1) {
  std::vector<std::uint8_t> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<std::uint8_t>(seed + i * 7 + (i >> 8));
  return v;
}

inline CanFrame abort_frame(std::uint32_t id, std::uint16_t index, std::uint8_t sub, SdoAbortCode code) {
  const auto c = static_cast<std::uint32_t>(code);
  return CanFrame(id, {0x80, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub,
                       static_cast<std::uint8_t>(c), static_cast<std::uint8_t>(c >> 8),
                       static_cast<std::uint8_t>(c >> 16), static_cast<std::uint8_t>(c >> 24)});
}

inline constexpr std::uint32_t kSaveSignature = 0x65766173;  // "save", CiA 301 §7.5.2.13
inline constexpr std::uint32_t kLoadSignature = 0x64616F6C;  // "load", CiA 301 §7.5.2.14

// The objects the tests (and the reference-document vectors) touch.
struct TestDictionary {
  ObjectDictionary od;
  int stores = 0;    // accepted "save" writes to 1010h
  int restores = 0;  // accepted "load" writes to 1011h
  Subscriptions hooks;

  TestDictionary() {
    od.add_var(0x1000, "Device type", DataType::Unsigned32, Access::Const, encode<std::uint32_t>(0x00080196));
    od.add_var(0x1008, "Manufacturer device name", DataType::VisibleString, Access::Const,
               bytes_of("OEGW test device"));
    Object& store =
        od.add_array(0x1010, "Store parameters", DataType::Unsigned32, Access::ReadWrite, 4, encode<std::uint32_t>(1));
    hooks += store.add_write_hook([this](Object&, std::uint8_t, std::span<const std::uint8_t> b, Origin) {
      if (b.size() != 4 || get_u32(b.data()) != kSaveSignature) return SdoAbortCode::CannotTransfer;
      ++stores;
      return SdoAbortCode::None;
    });
    Object& restore = od.add_array(0x1011, "Restore default parameters", DataType::Unsigned32, Access::ReadWrite, 4,
                                   encode<std::uint32_t>(1));
    hooks += restore.add_write_hook([this](Object&, std::uint8_t, std::span<const std::uint8_t> b, Origin) {
      if (b.size() != 4 || get_u32(b.data()) != kLoadSignature) return SdoAbortCode::CannotTransfer;
      ++restores;
      return SdoAbortCode::None;
    });
    od.add_record(0x1801, "TPDO2 communication parameter");
    od.add_record_member(0x1801, 1, "COB-ID", DataType::Unsigned32, Access::ReadWrite, encode<std::uint32_t>(0x283));
    od.add_record_member(0x1801, 2, "Transmission type", DataType::Unsigned8, Access::ReadWrite, {0xFF});
    od.add_record_member(0x1801, 5, "Event timer", DataType::Unsigned16, Access::ReadWrite, encode<std::uint16_t>(0));
    od.add_var(0x2000, "Node-ID", DataType::Unsigned8, Access::ReadWrite, {0x01});
    od.add_var(0x2001, "Word", DataType::Unsigned16, Access::ReadWrite, encode<std::uint16_t>(0xBEEF));
    od.add_var(0x2002, "Triple", DataType::Unsigned24, Access::ReadWrite, {0x01, 0x02, 0x03});
    od.add_var(0x2003, "Limited", DataType::Unsigned32, Access::ReadWrite, encode<std::uint32_t>(10));
    od.find(0x2003, 0)->high = std::uint64_t{1000};
    od.add_var(0x2004, "Write only", DataType::Unsigned8, Access::WriteOnly, {0});
    od.add_var(0x2100, "Domain", DataType::Domain, Access::ReadWrite, {});
    od.find(0x2100, 0)->max_size = 1000;
    od.add_var(0x2101, "Short string", DataType::OctetString, Access::ReadWrite, bytes_of("abc"));
    od.find(0x2101, 0)->max_size = 10;
    Object& even = od.add_var(0x2102, "Even-length domain", DataType::Domain, Access::ReadWrite, {});
    od.find(0x2102, 0)->max_size = 1000;
    hooks += even.add_write_hook([](Object&, std::uint8_t, std::span<const std::uint8_t> b, Origin) {
      return b.size() % 2 == 0 ? SdoAbortCode::None : SdoAbortCode::InvalidValue;
    });
    od.reset_to_defaults(0x0000, 0xFFFF);
  }

  std::vector<std::uint8_t> value(std::uint16_t index, std::uint8_t sub = 0) const {
    return od.find(index, sub)->value;
  }
};

}  // namespace sdo_test
