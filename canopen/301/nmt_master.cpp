#include "canopen/301/nmt_master.hpp"

namespace oegw::canopen {

bool NmtMaster::send(NmtCommand cs, NodeId node) {
  if (node.value() > 127) return false;
  if (sink_) sink_(CanFrame(cob::kNmt, {static_cast<std::uint8_t>(cs), node.value()}));
  return true;
}

}  // namespace oegw::canopen
