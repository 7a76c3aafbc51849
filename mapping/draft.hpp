// The draft mapping file `oegw scan` writes for the nodes it found (cli/scan_command.hpp runs the
// scan): one `subdevices` entry per node whose driver it can name, each driver's required options
// as marked placeholders, and commented-out functional-element lines for the node's signals (from
// the drivers themselves, as `oegw signals` lists them). The draft passes `oegw check` as it is
// written (docs/reference/mapping-file.md#drafting-the-file-oegw-scan).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "subdevices/bus_scan.hpp"

namespace oegw::mapping {

// What the draft says about the command line that made it (its header and interface lines).
struct DraftSettings {
  std::string downstream = "can1";
  std::string upstream = "can0";
  std::uint32_t bitrate = 250000;
  std::string store;             // upstream.store; empty: not written (the default /var/lib/oegw/upstream.store)
  bool through_gateway = false;  // scanned through the running gateway (the header says so)
};

// The draft mapping file for what a scan found.
[[nodiscard]] std::string draft_mapping(const subdevices::ScanResult& scan, const DraftSettings& settings);

// One line about a node found: what it is and why ("node 11h: elobau-mfg (vendor ...); ...").
[[nodiscard]] std::string describe_node(const subdevices::ScannedNode& node);

// The words of `text` in lines of at most `width` columns, the first line starting with
// `first_prefix`, the others with `rest_prefix` (a word longer than a line stands alone): the
// draft's comments and `oegw signals`' listing.
[[nodiscard]] std::string wrap_words(const std::string& text, std::size_t width, const std::string& first_prefix,
                                     const std::string& rest_prefix);

}  // namespace oegw::mapping
