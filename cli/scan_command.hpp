// `oegw scan -i IF`: finds every node on the downstream bus — before the gateway
// runs, or through the running gateway's control socket (gateway/control/scan_service.hpp), which
// probes only what is no sub-device of its own and reports those from what it read at their boot —
// (subdevices/bus_scan.hpp: boot-ups, heartbeats, SDO reads of 1000h/1018h/1017h, LSS) and writes a draft mapping file:
// one `subdevices` entry per node whose driver it can name, each driver's required options as marked placeholders, and
// commented-out functional-element lines for the node's signals (from the drivers themselves, as `oegw signals` lists
// them). The draft passes `oegw check` as it is written; docs/reference/mapping-file.md#drafting-the-file-oegw-scan.
// The draft itself is written by mapping/draft.hpp; this is the command around it.
#pragma once

#include <cstdint>
#include <string>

#include "subdevices/bus_scan.hpp"

namespace oegw::cli {

struct ScanOptions {
  // Where the scan runs: Auto asks the control socket first and scans through the gateway when
  // one runs on `interface` (or `interface` is empty), else on `interface` itself.
  enum class Via : std::uint8_t { Auto, Daemon, Direct };
  Via via = Via::Auto;
  std::string socket;     // the control socket; empty: `config`'s, else the default
  std::string config;     // a mapping file whose control.socket to ask
  std::string interface;  // the downstream bus (empty: the running gateway's)
  // Given on the command line: through the gateway its own values are the draft's otherwise.
  bool upstream_given = false, bitrate_given = false;
  std::string output = "-";        // the draft; "-" standard output
  std::string upstream = "can0";   // the draft's upstream.interface
  std::uint32_t bitrate = 250000;  // the draft's downstream/upstream bitrate (not measured)
  std::string store;               // the draft's upstream.store; empty: the default (not written)
  double timeout_ms = 100;         // per SDO read
  double listen_ms = 1000;         // the scan lasts at least this long (heartbeats)
  double lss_timeout_ms = 25;      // per LSS step
  unsigned parallel = 8;           // node-IDs probed at once
  bool lss = true;
  bool progress = true;  // progress lines on standard error
};

// A human summary of the scan, one line per node (for standard error).
[[nodiscard]] std::string scan_summary(const subdevices::ScanResult& scan);

// 0 at least one node found and the draft written; 1 no node found (the draft, without
// sub-devices, is still written); 2 the interface cannot be opened or the output not written,
// or the gateway's control socket refuses this user (scanning beside it could collide with its
// own SDO clients); the control socket's codes of `oegw status` (3 no gateway, with --daemon;
// 5 no answer) when asking it failed.
int run_scan(const ScanOptions& options);

}  // namespace oegw::cli
