#include "profiles/cia852/dictionary.hpp"

#include <algorithm>
#include <functional>
#include <map>

#include "canopen/301/heartbeat.hpp"
#include "canopen/301/pdo.hpp"
#include "profiles/cia401/objects.hpp"
#include "profiles/cia852/device_type.hpp"
#include "profiles/cia852/pdo_defaults.hpp"

namespace oegw::cia852 {

using canopen::Access;
using canopen::DataType;
using canopen::ObjectDictionary;

namespace {

bool has_kind(const std::vector<FeId>& fes, FeKind k) {
  return std::any_of(fes.begin(), fes.end(), [k](const FeId& f) { return f.kind == k; });
}

// An ARRAY holding only the given sub-indexes; sub 0 = the highest one (CiA 301 §7.4.3).
void add_sparse_array(ObjectDictionary& od, std::uint16_t index, DataType type, Access access,
                      const std::set<std::uint8_t>& subs, std::vector<std::uint8_t> dflt, bool mappable,
                      const std::function<std::string(std::uint8_t)>& sub_name) {
  if (subs.empty()) return;
  const std::uint8_t highest = *subs.rbegin();
  canopen::Object& obj =
      od.add_array(index, std::string(cia401::object_name(index)), type, access, highest, std::move(dflt), mappable);
  for (std::uint8_t s = 1; s <= highest; ++s) {
    if (subs.count(s) == 0) {
      obj.subs().erase(s);
    } else {
      obj.find(s)->name = sub_name(s);
    }
    if (s == 255) break;
  }
}

// The name of each entry after the FE field(s) it holds, by index << 8 | sub: "joystick 1 x",
// "joystick 1 memory", "joystick 1 buttons 1-8", "buttons 2 switch 9-16", "display 1 parameter
// 3"; an instance that is not configured adds " (not configured)".
std::map<std::uint32_t, std::string> entry_names(const std::vector<FeId>& instances,
                                                 const std::vector<FeId>& configured) {
  std::map<std::uint32_t, std::string> out;
  for (const FeId& fe : instances) {
    // The fields of one entry are listed together (fe_table.hpp).
    std::map<std::uint32_t, std::vector<std::string>> by_entry;
    for (const auto& f : fe_fields(fe)) by_entry[std::uint32_t{f.index} << 8 | f.sub].push_back(f.name);
    const std::string n = std::string(to_string(fe.kind)) + " " + std::to_string(fe.instance) + " ";
    const std::string tail =
        std::find(configured.begin(), configured.end(), fe) == configured.end() ? " (not configured)" : "";
    for (const auto& [key, names] : by_entry) {
      const std::string& first = names.front();
      const auto br = first.find('[');
      const std::string& last = names.back();
      const auto lbr = last.find('[');
      std::string name;
      if (names.size() == 1) {
        name =
            br == std::string::npos ? first : first.substr(0, br) + " " + first.substr(br + 1, first.size() - br - 2);
      } else if (first.rfind("memory", 0) == 0) {
        name = "memory";
      } else if (br == std::string::npos || lbr == std::string::npos) {
        name = first;
      } else {
        name = first.substr(0, br) + " " + first.substr(br + 1, first.size() - br - 2) + "-" +
               last.substr(lbr + 1, last.size() - lbr - 2);
      }
      out.emplace(key, n + name + tail);
    }
  }
  return out;
}

}  // namespace

canopen::NodeConfig build_dictionary(const DeviceConfig& cfg, ObjectDictionary& od) {
  using namespace cia401;
  const auto& fes = cfg.fes;
  // The entries of the configured instances, and those of every instance the default PDOs map
  // (each instance of a supported kind, pdo_defaults.hpp): an instance that is not configured
  // reads the default below, 0 — CiA 852 and CiA 401 name no not-available value for these
  // objects; 0 is the neutral one (memory off, buttons and switches released, axis centred,
  // pedal/wheel/encoder position 0 as Tables 2 and 7 default, indicators off). Nothing writes
  // them: the inputs are ro and only configured FEs are fed; host writes of the outputs are
  // refused (OeDevice), so they never change.
  const std::vector<FeId> mapped_fes = pdo_instances(fes);
  std::map<std::uint16_t, std::set<std::uint8_t>> subs, mapped;
  for (const FeId& fe : fes)
    for (const auto& f : fe_fields(fe)) subs[f.index].insert(f.sub);
  for (const FeId& fe : mapped_fes)
    for (const auto& f : fe_fields(fe)) mapped[f.index].insert(f.sub);
  const auto names = entry_names(mapped_fes, fes);
  auto namer = [&names](std::uint16_t index) {
    return [&names, index](std::uint8_t s) {
      const auto it = names.find(std::uint32_t{index} << 8 | s);
      return it != names.end() ? it->second : "entry " + std::to_string(s);
    };
  };
  auto subs_of = [&](std::uint16_t index) { return subs.count(index) ? subs[index] : std::set<std::uint8_t>{}; };
  auto mapped_of = [&](std::uint16_t index) { return mapped.count(index) ? mapped[index] : std::set<std::uint8_t>{}; };

  add_sparse_array(od, kReadInput8, DataType::Unsigned8, Access::ReadOnly, mapped_of(kReadInput8), {0}, true,
                   namer(kReadInput8));
  // 6120h: UNSIGNED32 (CiA 852 §9.4 "an unsigned 32-bit value", CiA 401 "read input 32-bit").
  add_sparse_array(od, kReadInput32, DataType::Unsigned32, Access::ReadOnly, mapped_of(kReadInput32),
                   canopen::encode<std::uint32_t>(0), true, namer(kReadInput32));
  add_sparse_array(od, kReadAnalogueInput16, DataType::Integer16, Access::ReadOnly, mapped_of(kReadAnalogueInput16),
                   canopen::encode<std::int16_t>(0), true, namer(kReadAnalogueInput16));
  if (cfg.subdevice_commands)  // the last command accepted reads back; the gateway checks each write
    od.add_var(kSubdeviceCommand, "Sub-device command", DataType::Unsigned32, Access::ReadWrite,
               canopen::encode<std::uint32_t>(0));
  if (has_kind(fes, FeKind::Joystick) || has_kind(fes, FeKind::FootPedal) || has_kind(fes, FeKind::Wheel))
    od.add_var(kAnalogueInputGlobalInterruptEnable, std::string(object_name(kAnalogueInputGlobalInterruptEnable)),
               DataType::Boolean, Access::ReadWrite, {0});
  // 6206h/6207h: one mode/value byte per 6200h byte of a configured cluster, named after it.
  const auto ind = subs_of(kWriteOutput8);
  add_sparse_array(od, kWriteOutput8, DataType::Unsigned8, Access::ReadWrite, mapped_of(kWriteOutput8), {0}, true,
                   namer(kWriteOutput8));
  // 6206h default FFh, not Table 6's 01h: CiA 401 6206h is a mask, bit n = output line n of the
  // 6200h byte takes its 6207h value on a device error (the MCB-402's CiA 401 implementation
  // documents the same, default FFh). Table 6 gives one mode per entry ("error mode 1-to-8"), and
  // 01h as a mask would leave indicators 2..8 of each byte lit when the host is lost; FFh is
  // "error mode on" for all eight (docs/design/cia852-decisions.md).
  add_sparse_array(od, kErrorModeOutput8, DataType::Unsigned8, Access::ReadWrite, ind, {0xFF}, false,
                   namer(kWriteOutput8));
  add_sparse_array(od, kErrorValueOutput8, DataType::Unsigned8, Access::ReadWrite, ind, {0x00}, false,
                   namer(kWriteOutput8));
  // 6443h/6444h: one mode/value per 6411h channel of a configured display, named after it.
  const auto disp = subs_of(kWriteAnalogueOutput16);
  add_sparse_array(od, kWriteAnalogueOutput16, DataType::Integer16, Access::ReadWrite,
                   mapped_of(kWriteAnalogueOutput16), canopen::encode<std::int16_t>(0), true,
                   namer(kWriteAnalogueOutput16));
  add_sparse_array(od, kAnalogueOutputErrorMode, DataType::Unsigned8, Access::ReadWrite, disp, {0x01}, false,
                   namer(kWriteAnalogueOutput16));
  add_sparse_array(od, kAnalogueOutputErrorValueInteger, DataType::Integer32, Access::ReadWrite, disp,
                   canopen::encode<std::int32_t>(0), false, namer(kWriteAnalogueOutput16));
  // 6206h/6443h: CiA 401 error modes are 0 or 1 per bit/channel; 6443h channels hold 0 or 1.
  if (auto* o = od.find(kAnalogueOutputErrorMode))
    for (auto& [s, sub] : o->subs())
      if (s != 0) sub.high = std::uint64_t{1};

  for (const DefaultPdo& p : default_pdos(fes, cfg.node_id)) {
    if (p.transmit) {
      canopen::install_tpdo(od, p.number, p.params);
    } else {
      canopen::install_rpdo(od, p.number, p.params);
    }
    // Tables 10, 14, 18, 22, 26, 30, 34: "highest sub-index supported" is const.
    const auto comm = static_cast<std::uint16_t>((p.transmit ? 0x1800 : 0x1400) + p.number - 1);
    od.find(comm, 0)->access = Access::Const;
  }

  canopen::NodeConfig nc;
  nc.node_id = cfg.node_id;
  nc.device_type = device_type_for(fes, cfg.joysticks_without_buttons);
  nc.device_name = cfg.device_name;
  nc.hardware_version = cfg.hardware_version;
  nc.software_version = cfg.software_version;
  nc.identity.vendor = cfg.identity.vendor;
  nc.identity.product = cfg.identity.product;
  nc.identity.revision = cfg.identity.revision;
  nc.identity.serial = cfg.identity.serial;
  nc.heartbeat_ms = cfg.heartbeat_ms;
  nc.store_path = cfg.store_path;
  nc.bit_timing_index = cfg.bit_timing_index;
  nc.supported_bit_timings = cfg.supported_bit_timings;
  nc.sdo_servers = cfg.sdo_servers;
  const bool outputs = has_kind(fes, FeKind::IndicatorCluster) || has_kind(fes, FeKind::Display);
  if (outputs) {
    // §8.3 / Annex A: heartbeat consumer mandatory with outputs; one entry, the host's.
    nc.heartbeat_consumers = 1;
    canopen::Object& hb = canopen::install_heartbeat_consumer_objects(od, 1);
    const auto v = canopen::encode<std::uint32_t>(
        canopen::heartbeat_consumer_entry(canopen::NodeId{static_cast<std::uint8_t>(cfg.host_node)},
                                          cfg.host_heartbeat_ms));
    hb.find(1)->default_value = v;
    hb.find(1)->value = v;
  }
  return nc;
}

}  // namespace oegw::cia852
