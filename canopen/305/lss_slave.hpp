// LSS slave (CiA 305): node-ID and bit-rate configuration over 7E5h/7E4h.
//
// Two LSS modes: Waiting (the normal one) and Configuration. Switch state global (04h) moves
// every slave; switch state selective (40h vendor, 41h product, 42h revision, 43h serial, in
// this order, each matching 1018h) moves only the addressed one, which answers 44h.
//
// In Configuration: configure node-ID (11h; 1..127 or FFh = unconfigured; error 1 = out of
// range), configure bit timing (13h; table 0 = CiA table, only the indexes of
// supported_bit_timings, error 1 for any other index or table), activate bit timing (15h, switch
// delay in ms, no answer; the owner does the switch, CiA 305: silent for the delay, switch, silent
// for the delay again), store configuration (17h; via the owner's
// callback, error 1 = not supported, 2 = storage media access error), inquire vendor/product/
// revision/serial/node-ID (5Ah–5Eh). In any mode: identify remote slave (46h–4Bh -> 4Fh) and
// identify non-configured remote slave (4Ch -> 50h).
//
// The configured node-ID is *pending*: it is reported to the owner (on_pending_node_id) and
// becomes active at the next NMT reset communication, when the owner calls set_active_node_id()
// (NmtSlave::set_pending_node_id carries it across). Exception (CiA 305): a slave whose active
// node-ID is FFh (unconfigured) that has a valid pending node-ID asks the owner to start NMT
// (on_start_nmt) when it is switched back to Waiting.
//
// Frames on 7E5h with DLC != 8 or RTR are ignored and counted.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>

#include "canopen/305/lss.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

class StateWriter;  // canopen/state.hpp
class StateReader;

class LssSlave {
 public:
  struct Callbacks {
    std::function<void(NodeId)> on_pending_node_id;
    std::function<void(std::uint8_t table_index)> on_pending_bit_timing;
    // Switch to the pending bit timing: stop sending for `delay`, switch, wait `delay` again.
    std::function<void(std::uint8_t table_index, Duration delay)> on_activate_bit_timing;
    // Persist pending node-ID and bit timing; returns the LSS error code (0 ok, 2 media error).
    // Unset: store is answered with error 1 (not supported).
    std::function<std::uint8_t(NodeId node_id, std::uint8_t table_index)> on_store;
    std::function<void()> on_start_nmt;
  };
  struct Stats {
    std::uint64_t malformed = 0;  // DLC != 8 or RTR on 7E5h; a fastscan with fields out of range
    std::uint64_t unknown = 0;    // unknown command specifier (or not valid in this mode)
  };

  // `bit_timing_index`: the active entry of table 0. `supported_bit_timings`: bit i set =
  // table-0 index i supported (default: every index of the standard table).
  LssSlave(lss::Address address, NodeId active_node_id, std::uint8_t bit_timing_index, FrameSink sink,
           Callbacks callbacks = {}, lss::BitTimings supported_bit_timings = lss::kAllStandardBitTimings);

  bool on_frame(const CanFrame& frame, TimePoint now);
  void advance(TimePoint /*now*/) {}
  [[nodiscard]] std::optional<TimePoint> next_deadline() const { return std::nullopt; }

  [[nodiscard]] lss::Mode mode() const { return mode_; }
  [[nodiscard]] NodeId active_node_id() const { return active_node_id_; }
  [[nodiscard]] NodeId pending_node_id() const { return pending_node_id_; }
  [[nodiscard]] std::uint8_t pending_bit_timing() const { return pending_bit_timing_; }
  [[nodiscard]] const Stats& stats() const { return stats_; }
  // The owner applies the pending node-ID at reset communication.
  void set_active_node_id(NodeId id) { active_node_id_ = id; }
  // The bit timing in use changed outside LSS (a stored one applied at power-on): it is also the
  // pending one, which activate bit timing switches to.
  void set_bit_timing(std::uint8_t index) { pending_bit_timing_ = index; }
  [[nodiscard]] lss::BitTimings supported_bit_timings() const { return supported_bit_timings_; }

  // Run-time state (canopen/state.hpp): the node-IDs and bit timing, the mode, how far a switch
  // state selective, an identify or a fastscan has come, the counts. The address and the
  // supported bit timings are configuration. Throws StateError.
  void export_state(StateWriter& w) const;
  void import_state(const StateReader& r);

 private:
  void reply(std::uint8_t cs, std::uint8_t b1 = 0, std::uint8_t b2 = 0);
  void reply_u32(std::uint8_t cs, std::uint32_t v);
  void switch_mode(lss::Mode m);
  // A handler per command specifier (CiA 305), called by on_frame in the modes that take it.
  void on_switch_state_global(std::uint8_t mode);
  void on_switch_selective(std::uint8_t cmd, std::uint32_t value);
  void on_configure_node_id(std::uint8_t value);
  void on_configure_bit_timing(std::uint8_t table, std::uint8_t index);
  void on_inquire(std::uint8_t cmd);
  void on_identify(std::uint8_t cmd, std::uint32_t value);
  void on_fastscan(const CanFrame& frame);

  lss::Address address_;
  NodeId active_node_id_;
  NodeId pending_node_id_;
  std::uint8_t pending_bit_timing_;
  FrameSink sink_;
  Callbacks cb_;
  lss::BitTimings supported_bit_timings_;
  lss::Mode mode_ = lss::Mode::Waiting;
  Stats stats_;
  // Switch-selective / identify progress: the next command specifier expected (0 = none).
  std::uint8_t selective_next_ = 0;
  std::uint8_t identify_next_ = 0;
  lss::AddressRange identify_;
  // Fastscan: the part of the address (0 vendor .. 3 serial) the next step checks.
  std::uint8_t fastscan_pos_ = 0;
};

}  // namespace oegw::canopen
