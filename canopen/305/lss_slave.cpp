#include "canopen/305/lss_slave.hpp"

#include "canopen/state.hpp"

namespace oegw::canopen {

using namespace lss::cs;

LssSlave::LssSlave(lss::Address address, NodeId active_node_id, std::uint8_t bit_timing_index, FrameSink sink,
                   Callbacks callbacks, lss::BitTimings supported_bit_timings)
    : address_(address),
      active_node_id_(active_node_id),
      pending_node_id_(active_node_id),
      pending_bit_timing_(bit_timing_index),
      sink_(std::move(sink)),
      cb_(std::move(callbacks)),
      supported_bit_timings_(supported_bit_timings) {}

void LssSlave::reply(std::uint8_t cs, std::uint8_t b1, std::uint8_t b2) {
  if (sink_) sink_(CanFrame(cob::kLssSlave, {cs, b1, b2, 0, 0, 0, 0, 0}));
}

void LssSlave::reply_u32(std::uint8_t cs, std::uint32_t v) {
  CanFrame f(cob::kLssSlave, {cs, 0, 0, 0, 0, 0, 0, 0});
  put_u32(&f.data[1], v);
  if (sink_) sink_(f);
}

void LssSlave::switch_mode(lss::Mode m) {
  const lss::Mode before = mode_;
  mode_ = m;
  selective_next_ = 0;
  if (before == lss::Mode::Configuration && m == lss::Mode::Waiting && active_node_id_.unconfigured() &&
      pending_node_id_.valid() && cb_.on_start_nmt) {
    cb_.on_start_nmt();
  }
}

bool LssSlave::on_frame(const CanFrame& frame, TimePoint /*now*/) {
  if (frame.id != cob::kLssMaster || frame.extended) return false;
  if (frame.rtr || frame.dlc != 8) {
    ++stats_.malformed;
    return true;
  }
  const std::uint8_t cmd = frame.data[0];
  const std::uint32_t u32 = get_u32(&frame.data[1]);
  const bool config = mode_ == lss::Mode::Configuration;

  switch (cmd) {
    case kSwitchStateGlobal: on_switch_state_global(frame.data[1]); return true;
    case kSwitchSelectiveVendor:
    case kSwitchSelectiveProduct:
    case kSwitchSelectiveRevision:
    case kSwitchSelectiveSerial:
      if (!config) on_switch_selective(cmd, u32);  // only a waiting slave takes part
      return true;
    // The configuration and inquire services: in Configuration only, else unknown (CiA 305).
    case kConfigureNodeId:
      if (!config) break;
      on_configure_node_id(frame.data[1]);
      return true;
    case kConfigureBitTiming:
      if (!config) break;
      on_configure_bit_timing(frame.data[1], frame.data[2]);
      return true;
    case kActivateBitTiming:
      if (!config) break;
      if (cb_.on_activate_bit_timing)
        cb_.on_activate_bit_timing(pending_bit_timing_, std::chrono::milliseconds(get_u16(&frame.data[1])));
      return true;
    case kStoreConfiguration:
      if (!config) break;
      reply(kStoreConfiguration, cb_.on_store ? cb_.on_store(pending_node_id_, pending_bit_timing_) : 1);
      return true;
    case kInquireVendor:
    case kInquireProduct:
    case kInquireRevision:
    case kInquireSerial:
    case kInquireNodeId:
      if (!config) break;
      on_inquire(cmd);
      return true;
    case kIdentifyVendor:
    case kIdentifyProduct:
    case kIdentifyRevisionLow:
    case kIdentifyRevisionHigh:
    case kIdentifySerialLow:
    case kIdentifySerialHigh: on_identify(cmd, u32); return true;
    case kFastscan: on_fastscan(frame); return true;
    case kIdentifyNonConfigured:
      if (active_node_id_.unconfigured() && pending_node_id_.unconfigured()) reply(kIdentifyNonConfiguredResponse);
      return true;
    default: break;
  }
  ++stats_.unknown;
  return true;
}

void LssSlave::on_switch_state_global(std::uint8_t mode) {
  if (mode == 0) switch_mode(lss::Mode::Waiting);
  else if (mode == 1) switch_mode(lss::Mode::Configuration);
  else ++stats_.unknown;
}

void LssSlave::on_switch_selective(std::uint8_t cmd, std::uint32_t value) {
  const std::uint32_t expect[4] = {address_.vendor, address_.product, address_.revision, address_.serial};
  const int step = cmd - kSwitchSelectiveVendor;
  // A vendor frame always (re)starts the sequence; the others must come in order.
  const bool in_order = cmd == kSwitchSelectiveVendor || selective_next_ == cmd;
  if (!in_order || value != expect[step]) {
    selective_next_ = 0;
    return;
  }
  if (cmd == kSwitchSelectiveSerial) {
    switch_mode(lss::Mode::Configuration);
    reply(kSwitchSelectiveResponse);
  } else {
    selective_next_ = static_cast<std::uint8_t>(cmd + 1);
  }
}

void LssSlave::on_configure_node_id(std::uint8_t value) {
  const NodeId id{value};
  if (!id.valid() && !id.unconfigured()) {
    reply(kConfigureNodeId, 1);
    return;
  }
  pending_node_id_ = id;
  reply(kConfigureNodeId, 0);
  if (cb_.on_pending_node_id) cb_.on_pending_node_id(id);
}

void LssSlave::on_configure_bit_timing(std::uint8_t table, std::uint8_t index) {
  const bool ok = table == 0 && lss::standard_bit_rate_kbit(index).has_value() &&
                  lss::has_bit_timing(supported_bit_timings_, index);
  if (!ok) {
    reply(kConfigureBitTiming, 1);
    return;
  }
  pending_bit_timing_ = index;
  reply(kConfigureBitTiming, 0);
  if (cb_.on_pending_bit_timing) cb_.on_pending_bit_timing(index);
}

void LssSlave::on_inquire(std::uint8_t cmd) {
  if (cmd == kInquireNodeId) {
    reply(kInquireNodeId, active_node_id_.value());
    return;
  }
  const std::uint32_t v[4] = {address_.vendor, address_.product, address_.revision, address_.serial};
  reply_u32(cmd, v[cmd - kInquireVendor]);
}

void LssSlave::on_identify(std::uint8_t cmd, std::uint32_t value) {
  if (cmd != kIdentifyVendor && identify_next_ != cmd) {
    identify_next_ = 0;
    return;
  }
  switch (cmd) {
    case kIdentifyVendor: identify_.vendor = value; break;
    case kIdentifyProduct: identify_.product = value; break;
    case kIdentifyRevisionLow: identify_.revision_low = value; break;
    case kIdentifyRevisionHigh: identify_.revision_high = value; break;
    case kIdentifySerialLow: identify_.serial_low = value; break;
    default: identify_.serial_high = value; break;
  }
  if (cmd != kIdentifySerialHigh) {
    identify_next_ = static_cast<std::uint8_t>(cmd + 1);
    return;
  }
  identify_next_ = 0;
  const lss::AddressRange& r = identify_;
  if (address_.vendor == r.vendor && address_.product == r.product && address_.revision >= r.revision_low &&
      address_.revision <= r.revision_high && address_.serial >= r.serial_low && address_.serial <= r.serial_high) {
    reply(kIdentifySlaveResponse);
  }
}

void LssSlave::on_fastscan(const CanFrame& frame) {
  // CiA 305 §8.4.4: only a waiting slave without node-ID takes part. BitChecked 80h restarts
  // at the vendor-ID and is answered; otherwise the slave answers when it is at LSSSub and the
  // bits BitChecked..31 of that part of its address equal IDNumber's, and then goes on at
  // LSSNext. A complete match (bit 0) whose LSSNext goes back (LSSNext < LSSSub) ends the
  // scan: the slave is selected, i.e. in configuration mode.
  if (mode_ == lss::Mode::Configuration || !active_node_id_.unconfigured() || !pending_node_id_.unconfigured()) return;
  const std::uint8_t bit = frame.data[5], sub = frame.data[6], next = frame.data[7];
  if (sub > 3 || next > 3 || (bit > 31 && bit != kFastscanReset)) {
    ++stats_.malformed;
    return;
  }
  if (bit == kFastscanReset) {
    fastscan_pos_ = 0;
    reply(kIdentifySlaveResponse);
    return;
  }
  if (fastscan_pos_ != sub) return;
  const std::uint32_t part[4] = {address_.vendor, address_.product, address_.revision, address_.serial};
  const std::uint32_t mask = 0xFFFFFFFFu << bit;
  if (((part[sub] ^ get_u32(&frame.data[1])) & mask) != 0) return;
  fastscan_pos_ = next;
  reply(kIdentifySlaveResponse);
  if (bit == 0 && next < sub) switch_mode(lss::Mode::Configuration);
}

void LssSlave::export_state(StateWriter& w) const {
  w.put("active_node_id", active_node_id_.value());
  w.put("pending_node_id", pending_node_id_.value());
  w.put("pending_bit_timing", pending_bit_timing_);
  w.put("mode", mode_);
  w.put("selective_next", selective_next_);
  w.put("identify_next", identify_next_);
  w.put("identify.vendor", identify_.vendor);
  w.put("identify.product", identify_.product);
  w.put("identify.revision_low", identify_.revision_low);
  w.put("identify.revision_high", identify_.revision_high);
  w.put("identify.serial_low", identify_.serial_low);
  w.put("identify.serial_high", identify_.serial_high);
  w.put("fastscan_pos", fastscan_pos_);
  w.put("stats.malformed", stats_.malformed);
  w.put("stats.unknown", stats_.unknown);
}

void LssSlave::import_state(const StateReader& r) {
  const NodeId active = r.node_id("active_node_id");
  const NodeId pending = r.node_id("pending_node_id");
  const auto bit_timing = r.get<std::uint8_t>("pending_bit_timing");
  // A supported index is configured (on_configure_bit_timing); the store may have given any
  // it can carry (read_lss_store).
  if (!lss::has_bit_timing(supported_bit_timings_ | lss::kStorableBitTimings, bit_timing)) {
    r.fail("pending_bit_timing", "is no bit timing this node supports or a store gives");
  }
  const auto mode = r.get<std::uint8_t>("mode");
  if (mode > static_cast<std::uint8_t>(lss::Mode::Configuration)) r.fail("mode", "is no LSS mode");
  // Each is 0 (none under way) or the command specifier the next step expects (CiA 305).
  const auto selective_next = r.get<std::uint8_t>("selective_next");
  if (selective_next != 0 && (selective_next <= kSwitchSelectiveVendor || selective_next > kSwitchSelectiveSerial)) {
    r.fail("selective_next", "is no step of switch state selective");
  }
  const auto identify_next = r.get<std::uint8_t>("identify_next");
  if (identify_next != 0 && (identify_next <= kIdentifyVendor || identify_next > kIdentifySerialHigh)) {
    r.fail("identify_next", "is no step of identify remote slave");
  }
  const auto fastscan_pos = r.get<std::uint8_t>("fastscan_pos");
  if (fastscan_pos > 3) r.fail("fastscan_pos", "is no part of the LSS address (0..3)");
  const StateReader id = r.in("identify");
  const lss::AddressRange identify{id.get<std::uint32_t>("vendor"),       id.get<std::uint32_t>("product"),
                                   id.get<std::uint32_t>("revision_low"), id.get<std::uint32_t>("revision_high"),
                                   id.get<std::uint32_t>("serial_low"),   id.get<std::uint32_t>("serial_high")};
  const StateReader st = r.in("stats");
  const Stats stats{st.get<std::uint64_t>("malformed"), st.get<std::uint64_t>("unknown")};
  active_node_id_ = active;
  pending_node_id_ = pending;
  pending_bit_timing_ = bit_timing;
  mode_ = static_cast<lss::Mode>(mode);
  selective_next_ = selective_next;
  identify_next_ = identify_next;
  identify_ = identify;
  fastscan_pos_ = fastscan_pos;
  stats_ = stats;
}

}  // namespace oegw::canopen
