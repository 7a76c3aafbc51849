#include "canopen/can_frame.hpp"

#include <algorithm>
#include <cstdio>

namespace oegw::canopen {

CanFrame::CanFrame(std::uint32_t can_id, std::initializer_list<std::uint8_t> bytes)
    : CanFrame(can_id, std::span<const std::uint8_t>(bytes.begin(), bytes.size())) {}

CanFrame::CanFrame(std::uint32_t can_id, std::span<const std::uint8_t> bytes)
    : id(can_id), dlc(static_cast<std::uint8_t>(std::min<std::size_t>(bytes.size(), 8))), extended(can_id > 0x7FF) {
  std::copy_n(bytes.begin(), dlc, data.begin());
}

CanFrame CanFrame::remote(std::uint32_t can_id, std::uint8_t dlc) {
  CanFrame f;
  f.id = can_id;
  f.dlc = std::min<std::uint8_t>(dlc, 8);
  f.rtr = true;
  f.extended = can_id > 0x7FF;
  return f;
}

bool operator==(const CanFrame& a, const CanFrame& b) {
  if (a.id != b.id || a.dlc != b.dlc || a.rtr != b.rtr || a.extended != b.extended) return false;
  return a.rtr || std::equal(a.data.begin(), a.data.begin() + a.dlc, b.data.begin());
}

std::string CanFrame::to_string() const {
  char buf[64];
  int n = extended ? std::snprintf(buf, sizeof buf, "%08X#", id) : std::snprintf(buf, sizeof buf, "%03X#", id);
  std::string s(buf, static_cast<std::size_t>(n));
  if (rtr) {
    s += 'R';
    if (dlc) s += static_cast<char>('0' + dlc);
    return s;
  }
  for (std::uint8_t i = 0; i < dlc; ++i) {
    std::snprintf(buf, sizeof buf, "%02X", data[i]);
    s += buf;
  }
  return s;
}

std::string_view to_string(SdoAbortCode code) {
  switch (code) {
    case SdoAbortCode::None: return "no error";
    case SdoAbortCode::ToggleBitNotAlternated: return "toggle bit not alternated";
    case SdoAbortCode::Timeout: return "SDO protocol timed out";
    case SdoAbortCode::UnknownCommandSpecifier: return "client/server command specifier not valid or unknown";
    case SdoAbortCode::InvalidBlockSize: return "invalid block size";
    case SdoAbortCode::InvalidSequenceNumber: return "invalid sequence number";
    case SdoAbortCode::CrcError: return "CRC error";
    case SdoAbortCode::OutOfMemory: return "out of memory";
    case SdoAbortCode::UnsupportedAccess: return "unsupported access to an object";
    case SdoAbortCode::ReadOfWriteOnly: return "attempt to read a write only object";
    case SdoAbortCode::WriteOfReadOnly: return "attempt to write a read only object";
    case SdoAbortCode::ObjectDoesNotExist: return "object does not exist in the object dictionary";
    case SdoAbortCode::CannotBeMapped: return "object cannot be mapped to the PDO";
    case SdoAbortCode::MappingExceedsPdoLength:
      return "number and length of objects to be mapped would exceed PDO length";
    case SdoAbortCode::ParameterIncompatibility: return "general parameter incompatibility";
    case SdoAbortCode::InternalIncompatibility: return "general internal incompatibility in the device";
    case SdoAbortCode::HardwareError: return "access failed due to a hardware error";
    case SdoAbortCode::LengthMismatch: return "data type does not match, length of service parameter does not match";
    case SdoAbortCode::LengthTooHigh: return "data type does not match, length of service parameter too high";
    case SdoAbortCode::LengthTooLow: return "data type does not match, length of service parameter too low";
    case SdoAbortCode::SubIndexDoesNotExist: return "sub-index does not exist";
    case SdoAbortCode::InvalidValue: return "invalid value for parameter";
    case SdoAbortCode::ValueTooHigh: return "value of parameter written too high";
    case SdoAbortCode::ValueTooLow: return "value of parameter written too low";
    case SdoAbortCode::MaxLessThanMin: return "maximum value is less than minimum value";
    case SdoAbortCode::ResourceNotAvailable: return "resource not available: SDO connection";
    case SdoAbortCode::GeneralError: return "general error";
    case SdoAbortCode::CannotTransfer: return "data cannot be transferred or stored to the application";
    case SdoAbortCode::CannotTransferLocalControl:
      return "data cannot be transferred or stored because of local control";
    case SdoAbortCode::CannotTransferDeviceState:
      return "data cannot be transferred or stored because of the present device state";
    case SdoAbortCode::NoObjectDictionary:
      return "object dictionary dynamic generation fails or no object dictionary is present";
    case SdoAbortCode::NoDataAvailable: return "no data available";
  }
  return "unknown abort code";
}

std::string_view to_string(NmtState state) {
  switch (state) {
    case NmtState::Initialisation: return "initialisation";
    case NmtState::Stopped: return "stopped";
    case NmtState::Operational: return "operational";
    case NmtState::PreOperational: return "pre-operational";
  }
  return "unknown";
}

}  // namespace oegw::canopen
