// The parsers of the mapping file's top-level sections (docs/reference/mapping-file.md documents
// each key). Each reads its section through a YamlReader, which collects the errors, and fills its
// part of the Config; load_config() (config.cpp) calls them in this order, since the functional
// elements refer to the sub-devices.
#pragma once

#include "mapping/config.hpp"
#include "mapping/yaml_reader.hpp"

namespace oegw::mapping::sections {

void read_upstream(YamlReader& r, const MapEntry& section, UpstreamConfig& out);  // upstream.cpp
// upstream.cpp: upstream.sdo_servers against the sub-devices and the gateway's own COB-IDs.
// `subdevices_read`: false when the subdevices section is missing or no map (reported there):
// then a sub-device name is not reported unknown.
void check_sdo_servers(YamlReader& r, const Config& config, bool subdevices_read = true);
void read_downstream(YamlReader& r, const MapEntry& section, DownstreamConfig& out);  // downstream.cpp
// A sub-device configured with a synchronous transmission type (option transmission_type, or an
// sdo write of 1800h..19FFh:02, 0..240) needs downstream.sync_period_ms (downstream.cpp).
void check_sync(YamlReader& r, const Config& config);
void read_publish(YamlReader& r, const MapEntry& section, PublishConfig& out);  // publish.cpp
void read_control(YamlReader& r, const MapEntry& section, ControlConfig& out);  // control.cpp
void read_record(YamlReader& r, const MapEntry& section, RecordConfig& out);    // record.cpp
// subdevices.cpp; the signals of each come from `catalogue`.
void read_subdevices(YamlReader& r, const MapEntry& section, const SignalCatalogue& catalogue,
                     std::vector<SubdeviceConfig>& out);
// functional_elements.cpp; the fields' signals are looked up in `config.subdevices`. With
// `subdevices_read` false (the subdevices section missing or no map, reported there) a signal's
// sub-device is not reported unknown: one mistake, one error, not one per field.
void read_functional_elements(YamlReader& r, const MapEntry& section, Config& config, bool subdevices_read = true);
// functional_elements.cpp: an output FE whose only sources the publish section leaves off.
void check_command_sources_reachable(YamlReader& r, const Config& config);

}  // namespace oegw::mapping::sections
