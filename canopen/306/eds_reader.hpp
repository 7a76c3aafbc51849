// An EDS (electronic data sheet, CiA 306) reader: the INI file a CANopen device's vendor ships
// to describe its object dictionary. A driver learns from it which objects a node has; a
// simulator builds a dictionary from it (build_dictionary, pdo_defaults).
//
// What is read (CiA 306 §4.5/§4.6):
//   [DeviceInfo]                     kept as key -> value (VendorNumber, ProductNumber, ...)
//   [MandatoryObjects] [OptionalObjects] [ManufacturerObjects]
//                                    SupportedObjects=n, then 1=0x1000 .. n=0x....; every listed
//                                    object must have its section
//   [1000]                           ParameterName (required), ObjectType (CiA 306 Table 2: 7
//                                    VAR, 8 ARRAY, 9 RECORD, 2 DOMAIN, 5 DEFTYPE, 6 DEFSTRUCT;
//                                    default 7), and for a VAR: DataType, AccessType
//                                    (required), DefaultValue, PDOMapping, LowLimit, HighLimit;
//                                    for an ARRAY/RECORD: SubNumber (required) and one
//                                    [1000subN] section per sub-object (N in hex), with the VAR
//                                    keys. Index and sub-index section names are hexadecimal,
//                                    case-insensitive. A DOMAIN is a VAR whose DataType may be
//                                    left out (0x000F); a DEFTYPE is a VAR (its value is the
//                                    type's size in bits), a DEFSTRUCT a RECORD.
//   CompactSubObj=n (CiA 306 §4.5.2.2) an ARRAY written in one section: sub 0 is UNSIGNED8 ro
//                                    with default n; subs 1..n take DataType, AccessType,
//                                    PDOMapping, DefaultValue, LowLimit and HighLimit of the
//                                    object's section, their names from [1000Name] (k=name;
//                                    NrOfEntries=) or else "<ParameterName><k>", and defaults
//                                    from [1000Value] (k=value) where given.
// Numbers are decimal, 0x-hexadecimal or 0-octal (CiA 306 §4.5.3); a value may be written
// "$NODEID+0x180" or "0x180+$NODEID" (the node-ID is added when the dictionary is built).
// Comments start with ';' at the beginning of a line. Keys are case-insensitive, as INI keys.
// A UTF-8 byte-order mark at the start of the file is skipped.
// Accepted with a warning (File::warnings, "file:line: warning: ..."), as real vendors' tools
// write them although CiA 306 does not allow them:
//   - a key written twice in one section: the FIRST value counts (as Windows' profile API, with
//     which most EDS tools read and write the files, returns it); the later one is ignored;
//   - a DefaultValue outside LowLimit..HighLimit: kept as written;
//   - a LowLimit/HighLimit on a string or DOMAIN entry: ignored (an empty one silently).
// Other keys (Denotation,
// ParameterValue, ObjectFlags, UploadFile, ...) and other sections ([FileInfo], [DummyUsage],
// [Comments], [xxxxObjectLinks], sections of unlisted objects) are ignored.
// A signed value written in hexadecimal is the type's two's complement (0x8000 = -32768 for
// INTEGER16).
//
// Errors: parse() never throws and never crashes on any input; a malformed file yields
// "file:line: what was expected" (line = the offending line, or the section header).
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "canopen/301/object_dictionary.hpp"
#include "canopen/301/pdo.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen::eds {

// A source line, carried for error messages and ignored by ==, so that a file written by
// write() and parsed back compares equal to the original.
struct Line {
  int number = 0;
  friend bool operator==(const Line&, const Line&) { return true; }
};

// A value as written, possibly node-relative: value + (node_relative ? node-ID : 0).
struct Value {
  std::string text;            // as written after trimming ("$NODEID+0x180", "0x10", "abc")
  bool node_relative = false;  // $NODEID appears
  std::uint64_t number = 0;    // the numeric part (two's complement for negative integers)
  bool numeric = false;        // false for strings and empty values
  friend bool operator==(const Value& a, const Value& b) {
    return a.node_relative == b.node_relative && a.numeric == b.numeric &&
           (a.numeric ? a.number == b.number : a.text == b.text);
  }
};

struct SubEntry {
  std::uint8_t sub = 0;
  std::string name;  // ParameterName
  canopen::DataType type = canopen::DataType::Unsigned8;
  canopen::Access access = canopen::Access::ReadOnly;
  std::optional<Value> default_value;
  bool pdo_mapping = false;
  std::optional<Value> low;
  std::optional<Value> high;
  Line line;
  friend bool operator==(const SubEntry&, const SubEntry&) = default;
};

struct ObjectEntry {
  std::uint16_t index = 0;
  std::string name;  // ParameterName
  canopen::ObjectCode code = canopen::ObjectCode::Var;
  std::uint8_t sub_number = 0;            // SubNumber (ARRAY/RECORD), 0 for a VAR
  std::map<std::uint8_t, SubEntry> subs;  // a VAR has exactly sub 0, with its own fields
  std::string list;                       // "MandatoryObjects", "OptionalObjects", ...
  std::uint8_t object_type = 0;           // ObjectType as written when not 7/8/9 (2, 5, 6); else 0
  Line line;
  friend bool operator==(const ObjectEntry&, const ObjectEntry&) = default;
  [[nodiscard]] const SubEntry* find(std::uint8_t sub) const {
    auto it = subs.find(sub);
    return it == subs.end() ? nullptr : &it->second;
  }
};

struct File {
  std::string path;                                // for messages
  std::map<std::string, std::string> device_info;  // [DeviceInfo], keys as written
  std::map<std::uint16_t, ObjectEntry> objects;
  std::vector<std::string> warnings;  // "file:line: warning: ..." (not compared)
  friend bool operator==(const File& a, const File& b) {
    return a.device_info == b.device_info && a.objects == b.objects;
  }

  [[nodiscard]] const ObjectEntry* find(std::uint16_t index) const {
    auto it = objects.find(index);
    return it == objects.end() ? nullptr : &it->second;
  }
  [[nodiscard]] const SubEntry* find(std::uint16_t index, std::uint8_t sub) const {
    const ObjectEntry* o = find(index);
    return o == nullptr ? nullptr : o->find(sub);
  }
  // A [DeviceInfo] number (VendorNumber, ProductNumber, RevisionNumber), if present and valid.
  [[nodiscard]] std::optional<std::uint32_t> device_number(std::string_view key) const;
  // The default of a numeric entry with $NODEID resolved; nullopt if absent or not numeric.
  [[nodiscard]] std::optional<std::uint64_t> default_number(std::uint16_t index, std::uint8_t sub,
                                                            canopen::NodeId node) const;
};

// Parses EDS text. `name` is used in error messages ("pedal.eds:12: ..."). Returns nullopt
// and sets `error` on malformed input.
std::optional<File> parse(std::string_view text, std::string_view name, std::string& error);
// Reads and parses a file; an unreadable one is "path: cannot open: <reason>; ...", one that is
// not a regular file or is larger than kMaxFileBytes is refused unread (canopen/text_file.hpp).
// The largest EDS files of real devices are a few hundred kilobytes.
inline constexpr std::size_t kMaxFileBytes = 4 * 1024 * 1024;
std::optional<File> load(const std::filesystem::path& path, std::string& error);

// Writes an EDS that parse() reads back equal (==) to `file` (lists, objects, sub sections).
std::string write(const File& file);

// The dictionary described by the EDS, with every $NODEID value resolved for `node`: VARs,
// ARRAYs and RECORDs with their sub-objects, types, access, PDO mappability, defaults, limits.
std::unique_ptr<canopen::ObjectDictionary> build_dictionary(const File& file, canopen::NodeId node);

// The default parameters of PDO n (1-based) as the EDS gives them (1400h/1600h for an RPDO,
// 1800h/1A00h for a TPDO), $NODEID resolved; nullopt if the EDS lacks either object.
std::optional<canopen::PdoParameters> pdo_defaults(const File& file, bool transmit, std::uint16_t n,
                                                   canopen::NodeId node);

}  // namespace oegw::canopen::eds
