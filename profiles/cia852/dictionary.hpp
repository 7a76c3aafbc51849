// The object dictionary of a CiA 852 OE interface module for its configured functional elements
// (FE): the application objects and default PDOs build_dictionary() adds (CiA 852 clauses 9, 11,
// 12; what the configured FE kinds need), and the NodeConfig the CiA 301 objects are built from.
//
//  * 6000h "Read input 8-bit" UNSIGNED8 ro mappable: joystick n memory (sub 2n−1) and buttons
//    (sub 2n), pedal n memory (sub 20h+n), push-button cluster n (subs 31h+8(n−1) … 38h+8(n−1)).
//  * 6401h "Read analogue input 16-bit" INTEGER16 ro mappable: joystick n x/y/z (subs 3n−2 … 3n),
//    pedal n (sub 30h+n), wheel n (sub 40h+n).
//  * 6120h "Read input 32-bit" UNSIGNED32 ro mappable: encoder n (sub 80h+n).
//  * 6423h "Analogue input global interrupt enable" BOOLEAN rw, default FALSE: present when an
//    FE with analogue inputs (joystick, pedal, wheel) is configured (Tables 1, 2, 4).
//  * 6200h "Write output 8-bit" UNSIGNED8 rw mappable, 6206h "Error mode output 8-bit" UNSIGNED8
//    rw default 01h, 6207h "Error value output 8-bit" UNSIGNED8 rw default 0: indicator cluster n
//    (subs 01h+8(n−1) … 08h+8(n−1)).
//  * 6411h "Write analogue output 16-bit" INTEGER16 rw mappable, 6443h "Analogue output error
//    mode" UNSIGNED8 rw default 01h (each channel 0 or 1), 6444h "Analogue output error value
//    integer" INTEGER32 rw default 0 (INTEGER32 as CiA 401 defines 6444h): display n parameter p
//    (sub 12(n−1)+p).
//  Sub-index layout: fe_table.hpp, the one table both this dictionary and the PDOs read.
//  Which instances have entries: every PDO of a supported kind exists with its full default
//  mapping (pdo_defaults.hpp), so 6000h, 6401h, 6120h, 6200h and 6411h hold the entries of every
//  instance of each configured kind (pdo_instances()). An instance that is not configured keeps
//  its entries at 0 — CiA 852 and CiA 401 name no not-available value for them, and 0 is the
//  neutral one (memory off, buttons released, axis centred, position 0, indicators off, display
//  parameter 0) — and they never change: the inputs are ro and fed only for configured FEs, a
//  host write of the outputs is refused (OeDevice: SDO abort 0800 0020h, RPDO bytes ignored).
//  Their entries are named "… (not configured)". 6206h/6207h and 6443h/6444h exist only for the
//  configured instances (no output of another instance ever takes an error value). The ARRAYs
//  may have gaps (a missing sub answers SDO abort 0609 0011h); sub 0 is the highest sub-index
//  present (CiA 301 §7.4.3), so its value is not the number of entries. Each entry is named
//  after the FE field(s) it holds ("joystick 1 x", "joystick 1 memory", "buttons 2 switch 9-16").
//  * 1000h per Table 8 (device_type.hpp), 1016h (host heartbeat consumer, one entry) when an
//    output FE exists (§8.3, Annex A), everything else of CiA 301 from canopen::Node.
//  * PDOs of clause 12 (pdo_defaults.hpp): every mapping sub 0 is rw, every communication
//    record's sub 0 const (Tables 10, 14, ...); docs/design/cia852-decisions.md.
#pragma once

#include <cstdint>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "canopen/301/object_dictionary.hpp"
#include "canopen/node.hpp"
#include "profiles/cia852/fe_table.hpp"

namespace oegw::cia852 {

// 1018h.
struct Identity {
  std::uint32_t vendor = 0;
  std::uint32_t product = 0;
  std::uint32_t revision = 0;
  std::uint32_t serial = 0;
};

// §6.2: "shall support the bit-rates 125 kbit/s, 250 kbit/s, 500 kbit/s and 1000 kbit/s" (CiA 305
// table 0 indexes 4, 3, 2, 0).
inline constexpr canopen::lss::BitTimings kMandatoryBitTimings = (1u << 0) | (1u << 2) | (1u << 3) | (1u << 4);

// The gateway's own manufacturer-specific object (CiA 301 2000h–5FFFh): a host's command to one
// sub-device, UNSIGNED32 = command code << 8 | the sub-device's node-ID (gateway/gateway.hpp,
// docs/guides/remote-sdo.md#commands-to-a-sub-device-3000h). Exists when
// DeviceConfig::subdevice_commands.
inline constexpr std::uint16_t kSubdeviceCommand = 0x3000;

struct DeviceConfig {
  canopen::NodeId node_id{0x20};
  bool subdevice_commands = false;  // 3000h (kSubdeviceCommand)
  Identity identity{};
  std::string device_name = "oegw OE interface module";
  std::string hardware_version = "1";
  std::string software_version = "0.1.0";
  std::uint16_t heartbeat_ms = 1000;    // 1017h default (mandatory, Annex A)
  std::uint16_t host_node = 0;          // 1016h:01 default host node-ID (0: entry unused)
  std::uint16_t host_heartbeat_ms = 0;  // 1016h:01 default consumer time
  std::vector<FeId> fes;
  std::set<FeId> joysticks_without_buttons;  // affects 1000h only (Table 8)
  // Output FEs the host may not command (their mapping-file `sources` leave out canopen): an SDO
  // download of their 6200h/6411h entries is aborted with 0800 0021h ("cannot be transferred
  // because of local control", CiA 301 Table 22) and their bytes in an RPDO are ignored. Writes
  // of the gateway itself (Origin::Local: DDS/LCM commands, 6206h/6443h error values) pass.
  std::set<FeId> host_may_not_command;
  std::filesystem::path store_path;  // empty: no 1010h/1011h
  // CiA 305 table 0: the bit timing at power-on (3 = 250 kbit/s) and the rates the device runs at
  // (bit i = index i): LSS configure bit timing takes those, the EDS lists them (BaudRate_xxx).
  std::uint8_t bit_timing_index = 3;
  canopen::lss::BitTimings supported_bit_timings = kMandatoryBitTimings;
  // Additional SDO server channels 1201h.. (CiA 301 §7.5.2.33; canopen::Node installs them).
  std::vector<canopen::SdoServerChannel> sdo_servers;
};

// Adds the application objects and PDOs to `od` (not the CiA 301 objects the Node adds). Returns
// the NodeConfig to construct the Node with (1000h, identity, 1016h ...).
canopen::NodeConfig build_dictionary(const DeviceConfig& cfg, canopen::ObjectDictionary& od);

}  // namespace oegw::cia852
