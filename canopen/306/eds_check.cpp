#include "canopen/306/eds_check.hpp"

#include <algorithm>
#include <cstdio>

namespace oegw::canopen::eds {

namespace {

std::string hex4(unsigned v) {
  char b[16];
  std::snprintf(b, sizeof b, "%04Xh", v & 0xFFFFu);
  return b;
}
std::string hex2(unsigned v) {
  char b[8];
  std::snprintf(b, sizeof b, "%02X", v & 0xFFu);
  return b;
}
std::string hex8(std::uint64_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "%08llXh", static_cast<unsigned long long>(v & 0xFFFFFFFFu));
  return b;
}

// The length in bits a mapping entry of this type has; 0 for a type of no fixed length.
unsigned bits_of(DataType t) {
  if (t == DataType::Boolean) return 1;  // CiA 301 §7.4.7.1: BOOLEAN is mapped as one bit
  return static_cast<unsigned>(fixed_size(t) * 8);
}

}  // namespace

std::vector<std::string> check_pdo_mappings(const File& file) {
  std::vector<std::string> out;
  const canopen::NodeId any{1};  // mapping entries are never node-relative
  for (const auto& [index, obj] : file.objects) {
    if (!((index >= 0x1600 && index <= 0x17FF) || (index >= 0x1A00 && index <= 0x1BFF))) continue;
    const std::string where = file.path + ":";
    const std::string what = hex4(index);
    const SubEntry* count_entry = obj.find(0);
    const auto count = file.default_number(index, 0, any);
    if (count_entry == nullptr || !count) continue;  // no default mapping: nothing to check
    // A PDO disabled by default (its COB-ID's bit 31, CiA 301 §7.5.2.35) is not used unless
    // configured, and then the node's actual mapping is read at boot: its defaults may be sloppy.
    const auto cob = file.default_number(static_cast<std::uint16_t>(index - 0x200), 1, any);
    if (cob && (*cob & 0x80000000u) != 0) continue;
    std::uint8_t highest = 0;
    for (const auto& [si, e] : obj.subs) highest = std::max(highest, si);
    if (*count > 64 || *count > highest) {
      out.push_back(where + std::to_string(count_entry->line.number) + ": " + what + " sub 0 default " +
                    std::to_string(*count) + " counts more entries than the object has (" + std::to_string(highest) +
                    "); expected at most " + std::to_string(std::min<unsigned>(highest, 64)));
      continue;
    }
    unsigned total = 0;
    for (std::uint8_t i = 1; i <= *count; ++i) {
      const SubEntry* e = obj.find(i);
      const auto v = file.default_number(index, i, any);
      const std::string at = where + std::to_string(e != nullptr ? e->line.number : obj.line.number) + ": " + what +
                             " sub " + std::to_string(i);
      if (e == nullptr || !v) {
        out.push_back(at + " has no numeric DefaultValue; expected a mapping entry (sub 0 counts " +
                      std::to_string(*count) + ")");
        continue;
      }
      const auto target = static_cast<std::uint16_t>(*v >> 16);
      const auto tsub = static_cast<std::uint8_t>(*v >> 8);
      const auto bits = static_cast<unsigned>(*v & 0xFF);
      const std::string maps = at + " default " + hex8(*v) + " maps " + hex4(target) + ":" + hex2(tsub);
      total += bits;
      if (bits == 0) {
        out.push_back(maps + " with length 0; expected the object's length in bits");
        continue;
      }
      if (target >= 0x0001 && target <= 0x0007) {  // dummy mapping: a gap of that type's length
        const unsigned want = bits_of(static_cast<DataType>(target));
        if (bits != want)
          out.push_back(maps + " with " + std::to_string(bits) + " bits; expected " + std::to_string(want) +
                        " (a dummy entry of " + std::string(to_string(static_cast<DataType>(target))) + ")");
        continue;
      }
      const SubEntry* t = file.find(target, tsub);
      if (t == nullptr) {
        out.push_back(maps + ", which the file does not describe; expected an object of this EDS");
        continue;
      }
      if (!t->pdo_mapping) {
        out.push_back(maps + ", which is not PDO-mappable (PDOMapping=0, line " + std::to_string(t->line.number) +
                      "); expected a mappable object");
        continue;
      }
      const unsigned want = bits_of(t->type);
      if (want != 0 ? bits != want : bits % 8 != 0)
        out.push_back(maps + " with " + std::to_string(bits) + " bits; expected " +
                      (want != 0 ? std::to_string(want) : std::string("whole bytes")) + " (" +
                      std::string(to_string(t->type)) + ", line " + std::to_string(t->line.number) + ")");
    }
    if (total > 64)
      out.push_back(where + std::to_string(obj.line.number) + ": " + what + " maps " + std::to_string(total) +
                    " bits; expected at most 64 (one CAN frame)");
  }
  return out;
}

}  // namespace oegw::canopen::eds
