#include "gateway/runtime_config.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "canopen/305/lss_store.hpp"
#include "profiles/cia852/pdo_defaults.hpp"

namespace oegw::gateway {

canopen::lss::BitTimings upstream_bit_timings(const mapping::Config& c) {
  canopen::lss::BitTimings rates = cia852::kMandatoryBitTimings;
  if (const auto index = canopen::lss::standard_bit_timing_index(c.upstream.bitrate)) rates |= 1u << *index;
  return rates;
}

UpstreamBitRate upstream_bit_rate(const mapping::Config& c) {
  UpstreamBitRate r{c.upstream.bitrate, false, {}};
  if (c.upstream.store.empty()) return r;
  const auto stored = canopen::read_lss_store(c.upstream.store);
  if (!stored) return r;
  const std::string file = canopen::lss_store_path(c.upstream.store).string();
  const auto kbit = canopen::lss::standard_bit_rate_kbit(stored->bit_timing);
  if (!kbit) {
    r.note =
        fmt::format("the LSS-stored bit timing index {} ({}) is no CiA 305 table-0 rate: upstream.bitrate {} applies",
                    stored->bit_timing, file, c.upstream.bitrate);
    return r;
  }
  r.bitrate = std::uint32_t{*kbit} * 1000u;
  r.lss_stored = true;
  r.note = r.bitrate == c.upstream.bitrate
               ? fmt::format("the LSS-stored bit rate {} bit/s ({}) is upstream.bitrate's", r.bitrate, file)
               : fmt::format(
                     "the LSS-stored bit rate {} bit/s ({}) overrides upstream.bitrate {}: CiA 305 store "
                     "configuration keeps the rate the host configured last",
                     r.bitrate, file, c.upstream.bitrate);
  return r;
}

OeDeviceConfig device_config(const mapping::Config& c, std::optional<std::filesystem::path> store) {
  OeDeviceConfig oe;
  oe.node_id = canopen::NodeId{c.upstream.node_id};
  oe.identity = {c.upstream.identity.vendor_id, c.upstream.identity.product_code, c.upstream.identity.revision,
                 c.upstream.identity.serial};
  oe.heartbeat_ms = c.upstream.heartbeat_ms;
  oe.subdevice_commands = !c.subdevices.empty();
  for (const auto& fe : c.functional_elements) {
    oe.fes.push_back(fe.id);
    // CiA 852 Table 8 distinguishes joysticks with buttons.
    if (fe.id.kind == mapping::FeKind::Joystick && std::none_of(fe.fields.begin(), fe.fields.end(), [](const auto& f) {
          return f.field.name.rfind("buttons", 0) == 0;
        }))
      oe.joysticks_without_buttons.insert(fe.id);
    if (!fe.input() && !fe.accepts(mapping::CommandSource::Canopen)) oe.host_may_not_command.insert(fe.id);
  }
  oe.store_path = store ? *store : std::filesystem::path(c.upstream.store);
  oe.bit_timing_index = canopen::lss::standard_bit_timing_index(c.upstream.bitrate).value_or(3);
  oe.supported_bit_timings = upstream_bit_timings(c);
  // 1201h..: a channel without COB-IDs in the file is disabled until the host writes them.
  for (const auto& s : c.upstream.sdo_servers)
    oe.sdo_servers.push_back(s.enabled() ? canopen::SdoServerChannel{*s.request, *s.response}
                                         : canopen::SdoServerChannel{});
  return oe;
}

canopen::EdsInfo eds_info(const mapping::Config& c, std::string file_name) {
  canopen::EdsInfo info;
  info.file_name = std::move(file_name);
  info.vendor = c.upstream.identity.vendor_id;
  info.product = c.upstream.identity.product_code;
  info.revision = c.upstream.identity.revision;
  info.node_id = canopen::NodeId{c.upstream.node_id};
  // CiA 306 BaudRate_xxx: the rates LSS configure bit timing accepts (one list).
  const canopen::lss::BitTimings rates = upstream_bit_timings(c);
  auto has = [rates](std::uint8_t index) { return ((rates >> index) & 1u) != 0; };
  info.baud_1000 = has(0);
  info.baud_800 = has(1);
  info.baud_500 = has(2);
  info.baud_250 = has(3);
  info.baud_125 = has(4);
  info.baud_50 = has(6);
  info.baud_20 = has(7);
  info.baud_10 = has(8);
  for (const auto& fe : c.functional_elements) {
    if (fe.input() || fe.accepts(mapping::CommandSource::Canopen)) continue;
    const auto fields = mapping::fe_fields(fe.id);
    info.comments.push_back(fmt::format(
        "{} ({:04X}h sub {:02X}h..{:02X}h) takes commands from {} only: an SDO download is aborted with 08000021h "
        "(local control), its bytes in an RPDO are ignored",
        mapping::fe_name(fe.id), fields.front().index, fields.front().sub, fields.back().sub,
        mapping::describe_sources(fe.sources)));
  }
  // 1201h..: where each additional SDO server channel leads (upstream.sdo_servers).
  for (std::size_t k = 1; k <= c.upstream.sdo_servers.size(); ++k) {
    const auto& s = c.upstream.sdo_servers[k - 1];
    const mapping::SubdeviceConfig* d = s.subdevice.empty() ? nullptr : c.find_subdevice(s.subdevice);
    info.comments.push_back(fmt::format("SDO server {:04X}h ({}): {}", 0x1200 + k,
                                        s.enabled() ? fmt::format("COB-IDs {:03X}h/{:03X}h", *s.request, *s.response)
                                                    : std::string("disabled until the host sets its COB-IDs"),
                                        d ? fmt::format("bound to sub-device {} (node {:02X}h on network {})", d->name,
                                                        d->node_id, c.downstream.network_id)
                                          : std::string("the gateway's own dictionary")));
  }
  // Where a host built from CiA 852's printed PDO tables would differ
  // (docs/design/cia852-decisions.md).
  std::vector<mapping::FeId> fes;
  for (const auto& fe : c.functional_elements) fes.push_back(fe.id);
  for (auto& line : cia852::pdo_eds_comments(fes)) info.comments.push_back(std::move(line));
  // CiA 302-7 network IDs, as the host names the two buses in remote SDO/EMCY.
  info.comments.push_back(fmt::format("network IDs: upstream (this device's bus) {}, downstream (its sub-devices) {}",
                                      c.upstream.network_id, c.downstream.network_id));
  return info;
}

std::unique_ptr<OeDevice> eds_device(const mapping::Config& c) {
  // 1010h/1011h exist as in the running device; the store itself is never opened (start()).
  std::optional<std::filesystem::path> store;
  if (!c.upstream.store.empty()) store = "/nonexistent/eds-only";
  return std::make_unique<OeDevice>(device_config(c, store), canopen::FrameSink{});
}

std::string upstream_eds(const mapping::Config& c, std::string file_name) {
  return canopen::eds_text(eds_device(c)->od(), eds_info(c, std::move(file_name)));
}

}  // namespace oegw::gateway
