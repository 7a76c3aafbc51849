// What LSS "store configuration" (CiA 305, 17h) keeps: the pending node-ID and bit timing, in a
// small file beside the parameter store (<store>.lss), two lines:
//
//   node_id=33
//   bit_timing=3
//
// (decimal; bit_timing is the index of CiA 305 table 0). Read at power-on: the node-ID by the
// Node, the bit timing also by the program before it opens the interface (the rate the bus runs
// at is set before the first frame).
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "canopen/types.hpp"

namespace oegw::canopen {

struct LssStored {
  NodeId node_id;
  std::uint8_t bit_timing = 0;  // CiA 305 table 0 index
};

// <store>.lss for the parameter file `store`.
[[nodiscard]] std::filesystem::path lss_store_path(const std::filesystem::path& store);
// nullopt: no file, a symbolic link (not followed), or a half-written or foreign one (node-ID
// outside 1..127, bit timing outside 0..9): the configured defaults stay.
[[nodiscard]] std::optional<LssStored> read_lss_store(const std::filesystem::path& store);
// Written atomically (write_file_atomically); false with `error` set on failure.
bool write_lss_store(const std::filesystem::path& store, const LssStored& stored, std::string& error);

}  // namespace oegw::canopen
