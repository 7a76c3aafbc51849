// Writes the electronic data sheet (CiA 306 v1.3, INI format) of any object dictionary.
//
// Sections: [FileInfo], [DeviceInfo] (vendor/product numbers, supported bit rates, NrOfRXPDO /
// NrOfTXPDO counted from 1400h–15FFh / 1800h–19FFh, LSS_Supported), [DummyUsage] (the core
// accepts dummy entries 0001h–0007h in RPDOs), [MandatoryObjects] (1000h, 1001h, 1018h when
// present), [OptionalObjects] (the other 1000h–1FFFh and 6000h–FFFFh objects),
// [ManufacturerObjects] (2000h–5FFFh), then one section per object ([6000]) and, for ARRAY and
// RECORD objects, one per sub-object ([6000sub1F], sub-index in upper-case hex). Sparse arrays
// list only the sub-objects present; SubNumber counts them.
// Values: unsigned integers in hex (0x...), signed in decimal, BOOLEAN 0/1, REAL decimal,
// VISIBLE_STRING as text, OCTET_STRING as hex digits; DOMAIN has no DefaultValue. A COB-ID whose
// default is "function code + node-ID" (1014h, 1200h:01/02, 1400h–15FFh:01, 1800h–19FFh:01)
// is written node-relative: "$NODEID+0x80000180".
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "canopen/301/object_dictionary.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

struct EdsInfo {
  std::string file_name = "oegw.eds";
  std::string description = "oegw CiA 852 OE interface module";
  std::string created_by = "oegw";
  std::string creation_date = "01-01-2026";  // mm-dd-yyyy (CiA 306)
  std::string creation_time = "12:00AM";     // hh:mm(AM|PM)
  std::string vendor_name = "oegw";
  std::string product_name = "oegw";
  std::uint32_t vendor = 0;
  std::uint32_t product = 0;
  std::uint32_t revision = 0;
  std::string order_code;
  canopen::NodeId node_id{0x20};  // the node-ID the defaults were built for ($NODEID)
  // CiA 852 §6.2: 125, 250, 500 and 1000 kbit/s are mandatory.
  bool baud_10 = false, baud_20 = false, baud_50 = false, baud_125 = true, baud_250 = true, baud_500 = true,
       baud_800 = false, baud_1000 = true;
  bool lss_supported = true;
  // CiA 306 [Comments] lines (e.g. which entries the host may not write: mapping-file `sources`).
  std::vector<std::string> comments;
};

[[nodiscard]] std::string eds_text(const canopen::ObjectDictionary& od, const EdsInfo& info);
// Writes the text to `path`; false with `error` set when the file cannot be written.
bool write_eds(const std::filesystem::path& path, const canopen::ObjectDictionary& od, const EdsInfo& info,
               std::string& error);

}  // namespace oegw::canopen
