// An integer as ISO C writes a constant (strtoull with base 0): 0x.. hexadecimal, a leading 0
// octal, else decimal, with an optional sign. CiA 306 §4.5.3 (EDS values) and CiA 309-3 (the
// ASCII commands, as lely's coctl documents them: "as specified in [ISO/IEC 9899]") both take it.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace oegw::canopen {

struct CInteger {
  bool negative = false;
  std::uint64_t magnitude = 0;
};

// nullopt for anything else: no digits, a digit the base lacks, trailing characters, > 2^64 − 1.
[[nodiscard]] std::optional<CInteger> parse_c_integer(std::string_view s);

}  // namespace oegw::canopen
