#include "canopen/305/lss_store.hpp"

#include <sstream>

#include "canopen/301/storage.hpp"
#include "canopen/305/lss.hpp"

namespace oegw::canopen {

std::filesystem::path lss_store_path(const std::filesystem::path& store) {
  std::filesystem::path p = store;
  p += ".lss";
  return p;
}

std::optional<LssStored> read_lss_store(const std::filesystem::path& store) {
  if (store.empty()) return std::nullopt;
  const PlainFile file = read_plain_file(lss_store_path(store));  // a link there is not followed
  if (file.state != PlainFile::State::Read) return std::nullopt;
  std::istringstream in(file.text);
  int node = -1;
  int bt = -1;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string key;
    int value = -1;
    if (std::getline(ls, key, '=') && (ls >> value)) {
      if (key == "node_id") node = value;
      if (key == "bit_timing") bt = value;
    }
  }
  if (node < 1 || node > 127 || bt < 0 || !lss::has_bit_timing(lss::kStorableBitTimings, static_cast<unsigned>(bt))) {
    return std::nullopt;
  }
  return LssStored{NodeId{static_cast<std::uint8_t>(node)}, static_cast<std::uint8_t>(bt)};
}

bool write_lss_store(const std::filesystem::path& store, const LssStored& stored, std::string& error) {
  std::ostringstream out;
  out << "node_id=" << static_cast<int>(stored.node_id.value())
      << "\nbit_timing=" << static_cast<int>(stored.bit_timing) << "\n";
  return write_file_atomically(lss_store_path(store), out.str(), error);
}

}  // namespace oegw::canopen
