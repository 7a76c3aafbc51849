// libFuzzer target for the EDS reader (canopen/306) as a cia401 node's file is read: parse, the
// default-mapping check, the dictionary a simulator builds from it, the default PDOs. Invariants
// (trap on breach): parse() gives a file or a "name:line: ..." error, never both; a file that
// parses is written by write() into text that parses back equal (eds_reader.hpp promises it);
// every default mapping that passes check_pdo_mappings() names an object of the dictionary.
// Seeds: subdevices/eds/*.eds; dictionary: eds.dict.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "canopen/306/eds_check.hpp"
#include "canopen/306/eds_reader.hpp"
#include "tests/fuzz/fuzz_support.hpp"

using namespace oegw::canopen;
using oegw::fuzz::check;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  std::string error;
  const auto file = eds::parse(text, "f.eds", error);
  check(file.has_value() == error.empty());
  if (!file) {
    check(error.rfind("f.eds:", 0) == 0);
    return 0;
  }
  std::string again_error;
  const auto again = eds::parse(eds::write(*file), "w.eds", again_error);
  check(again.has_value() && *again == *file);

  const bool consistent = eds::check_pdo_mappings(*file).empty();
  const auto od = eds::build_dictionary(*file, NodeId{5});
  check(od != nullptr);
  for (const bool transmit : {false, true})
    for (std::uint16_t n = 1; n <= 8; ++n) {
      const auto p = eds::pdo_defaults(*file, transmit, n, NodeId{5});
      if (!p || !consistent) continue;
      for (const std::uint32_t m : p->mapping) {
        const auto index = static_cast<std::uint16_t>(m >> 16);
        if (index >= 0x0001 && index <= 0x0007) continue;  // dummy entry
        check(od->find(index, static_cast<std::uint8_t>(m >> 8)) != nullptr);
      }
    }
  return 0;
}
