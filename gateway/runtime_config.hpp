// The one translation of a mapping file (mapping::Config) into the run-time configuration of the
// upstream CiA 852 device. `oegw run` (through Gateway), `oegw check`, `oegw eds` and the demo
// all use it, so the EDS describes exactly the dictionary the running gateway has (1000h of a
// joystick without buttons, the entries the host may not write, 1010h/1011h).
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "canopen/306/eds_writer.hpp"
#include "gateway/oe_device.hpp"
#include "mapping/config.hpp"

namespace oegw::gateway {

// `store` replaces upstream.store (demo, tests, `oegw eds`); the store is only touched at start().
[[nodiscard]] OeDeviceConfig device_config(const mapping::Config& config,
                                           std::optional<std::filesystem::path> store = std::nullopt);

// The upstream bit rates, one list for the LSS slave and the EDS (device_config's
// supported_bit_timings): CiA 852 §6.2's mandatory 125, 250, 500 and 1000 kbit/s, and
// upstream.bitrate when it is another CiA 301 rate.
[[nodiscard]] canopen::lss::BitTimings upstream_bit_timings(const mapping::Config& config);

// The rate the upstream interface is set to at start. An LSS-stored bit timing (CiA 305 store
// configuration, <upstream.store>.lss) wins over upstream.bitrate: it is what the host configured
// last, and the host's other nodes were switched with it (docs/guides/commission.md#bit-rate).
struct UpstreamBitRate {
  std::uint32_t bitrate = 0;  // bit/s
  bool lss_stored = false;    // from the LSS store
  std::string note;           // which one wins and why, for the log (empty: upstream.bitrate alone)
};
[[nodiscard]] UpstreamBitRate upstream_bit_rate(const mapping::Config& config);

// The EDS of the device `config` describes: identity, node-ID, the bit rates (BaudRate_xxx =
// upstream_bit_timings) and the CiA 306 [Comments] naming each output FE the host may not
// command (mapping-file `sources` without canopen).
[[nodiscard]] canopen::EdsInfo eds_info(const mapping::Config& config, std::string file_name);
// The device itself, never started (its dictionary holds the defaults the EDS describes).
[[nodiscard]] std::unique_ptr<OeDevice> eds_device(const mapping::Config& config);
// The text `oegw eds` writes: eds_text() of the dictionary device_config() builds.
[[nodiscard]] std::string upstream_eds(const mapping::Config& config, std::string file_name);

}  // namespace oegw::gateway
