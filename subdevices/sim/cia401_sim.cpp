#include "subdevices/sim/cia401_sim.hpp"

#include <cstdint>

#include "subdevices/sim/signal_names.hpp"

namespace oegw::subdevices::sim {

namespace {

canopen::NodeConfig config_from(const canopen::eds::File& file, NodeId node) {
  canopen::NodeConfig cfg;
  cfg.node_id = node;
  cfg.device_type = static_cast<std::uint32_t>(file.default_number(0x1000, 0, node).value_or(0));
  for (const auto& [k, v] : file.device_info)
    if (k == "ProductName") cfg.device_name = v;
  // 1008h/1009h/100Ah as the EDS gives them (their DefaultValue; CiA 306).
  auto text = [&file](std::uint16_t index, std::string& out) {
    if (const auto* e = file.find(index, 0); e != nullptr && e->default_value) out = e->default_value->text;
  };
  text(0x1008, cfg.device_name);
  text(0x1009, cfg.hardware_version);
  text(0x100A, cfg.software_version);
  cfg.identity.vendor = static_cast<std::uint32_t>(file.default_number(0x1018, 1, node).value_or(0));
  cfg.identity.product = static_cast<std::uint32_t>(file.default_number(0x1018, 2, node).value_or(0));
  cfg.identity.revision = static_cast<std::uint32_t>(file.default_number(0x1018, 3, node).value_or(0));
  cfg.identity.serial = static_cast<std::uint32_t>(file.default_number(0x1018, 4, node).value_or(0));
  cfg.heartbeat_ms = static_cast<std::uint16_t>(file.default_number(0x1017, 0, node).value_or(0));
  return cfg;
}

}  // namespace

Cia401Sim::Cia401Sim(const canopen::eds::File& file, NodeId node, FrameSink sink, const std::filesystem::path& store)
    : SimulatedDevice(std::move(sink)), eds_(file) {
  auto od = canopen::eds::build_dictionary(eds_, node);
  // The PDO objects are re-installed with the EDS defaults in the layout PdoService runs.
  for (std::uint16_t n = 1; n <= 512; ++n) {
    if (auto p = canopen::eds::pdo_defaults(eds_, false, n, node)) canopen::install_rpdo(*od, n, *p);
    if (auto p = canopen::eds::pdo_defaults(eds_, true, n, node)) canopen::install_tpdo(*od, n, *p);
  }
  canopen::NodeConfig cfg = config_from(eds_, node);
  cfg.store_path = store;
  build(std::move(od), cfg);
  // The node has the manufacturer strings its EDS lists, no others (an upload of one it lacks
  // is refused with 0602 0000h).
  for (const std::uint16_t index : {std::uint16_t{0x1008}, std::uint16_t{0x1009}, std::uint16_t{0x100A}})
    if (eds_.find(index) == nullptr) (void)this->od().remove(index);
}

std::unique_ptr<Cia401Sim> Cia401Sim::from_file(const std::filesystem::path& eds_path, NodeId node, FrameSink sink,
                                                std::string& error, const std::filesystem::path& store) {
  auto file = canopen::eds::load(eds_path, error);
  if (!file) return nullptr;
  return std::make_unique<Cia401Sim>(*file, node, std::move(sink), store);
}

canopen::SdoAbortCode Cia401Sim::set_object(std::uint16_t index, std::uint8_t sub, std::int64_t value) {
  return od().set<std::int64_t>(index, sub, value, canopen::Origin::Local);
}

std::optional<std::int64_t> Cia401Sim::object_value(std::uint16_t index, std::uint8_t sub) const {
  const canopen::SubObject* s = od().find(index, sub);
  if (s == nullptr || canopen::fixed_size(s->type) == 0) return std::nullopt;
  if (canopen::is_signed_integer(s->type)) return canopen::decode_signed(s->value);
  return static_cast<std::int64_t>(canopen::decode_unsigned(s->value));
}

}  // namespace oegw::subdevices::sim

namespace oegw::subdevices::sim {

namespace {
struct NamedObject {
  std::string_view base;
  std::uint16_t index;
};
constexpr NamedObject kInputs[] = {{"in", 0x6000}, {"in32", 0x6120}, {"analog", 0x6401}};
constexpr NamedObject kOutputs[] = {{"out", 0x6200}, {"aout", 0x6411}};
}  // namespace

bool Cia401Sim::set_input(std::string_view signal, std::int64_t value, TimePoint /*now*/) {
  // CiA 401 6423h "analogue input global interrupt enable": while FALSE (its default) a new
  // analogue value triggers no event-driven TPDO; it goes out with the next timer or SYNC.
  if (const auto k = indexed_signal(signal, "analog"); k && *k >= 1 && *k <= 0xFE)
    if (const canopen::SubObject* enable = od().find(0x6423, 0);
        enable != nullptr && canopen::decode_unsigned(enable->value) == 0) {
      canopen::SubObject* s = od().find(0x6401, static_cast<std::uint8_t>(*k));
      if (s == nullptr || value < INT16_MIN || value > INT16_MAX) return false;
      s->value = canopen::encode<std::int16_t>(static_cast<std::int16_t>(value));  // no change event
      return true;
    }
  for (const auto& n : kInputs)
    if (const auto k = indexed_signal(signal, n.base); k && *k >= 1 && *k <= 0xFE)
      return set_object(n.index, static_cast<std::uint8_t>(*k), value) == canopen::SdoAbortCode::None;
  return false;
}

std::optional<std::int64_t> Cia401Sim::output(std::string_view signal) const {
  for (const auto& n : kOutputs)
    if (const auto k = indexed_signal(signal, n.base); k && *k >= 1 && *k <= 0xFE)
      return object_value(n.index, static_cast<std::uint8_t>(*k));
  return std::nullopt;
}

}  // namespace oegw::subdevices::sim
