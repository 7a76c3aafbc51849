// `oegw replay` (docs/guides/black-box.md): the gateway re-run on the simulated clock from a
// recording's inputs.
//
//  * Exact (a recording that holds its run's `start`): every input is fed to a new Gateway of the
//    mapping file in the recorded order with the recorded times — frames received, timer calls
//    (tick), bus events, commands — and every frame it sends and every decision it makes is
//    compared with the recording's, in order. The first difference ends the comparison: both
//    sides are printed. A `gap` (records lost by the recorder), and a control-socket session
//    that reached into the gateway (`oegw ctl` SDO, NMT and LSS, `oegw scan`: not replayed) end
//    it too, with the reason; `oegw status` requests do not.
//    A recording whose start has left the ring (a kept window of a gateway that ran longer than
//    the ring holds) is replayed exactly from its first segment's state (the `state` line the
//    recorder begins each segment with): the new Gateway is put in it (Gateway::import_state)
//    in place of its start, with the parameter store the run began with.
//  * Recorded (a recording whose start has left the ring and whose first segment begins with no
//    state it can be put in: `state none`, a damaged line, another mapping file's): the
//    timeline is the recording's own, the frames and the decisions the gateway made, as they
//    were. Nothing is re-run.
//  * Fresh (a plain candump log — `oegw demo --frames`, `candump -l` of the downstream bus — or
//    any recording with `--fresh`): a new gateway is started at the first frame and given the
//    frames the gateway did not send (the direction marks, or for a plain log the CiA 301
//    predefined connection set: see own_frame()), its own timers run at its own deadlines; its
//    decisions are printed, nothing is compared: "what would this mapping file have done with
//    these frames?".
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "gateway/gateway.hpp"
#include "gateway/record/recording_reader.hpp"
#include "mapping/config.hpp"

namespace oegw::gateway::record {

class PlotData;

enum class ReplayMode : std::uint8_t {
  Exact,     // re-run from the run's start or a segment's state and compared
  Recorded,  // shown as recorded: the run's start has left the ring, no state to begin in
  Fresh,     // re-run on a fresh gateway, nothing compared
};

struct ReplayOptions {
  // Re-run every run on a fresh gateway, also a recording that could be replayed exactly or
  // shown as recorded: what this mapping file would have made of the recorded frames.
  bool fresh = false;
  // The timeline printed (nullptr: none): the inputs that are no frames and every decision.
  std::ostream* timeline = nullptr;
  bool frames = false;  // the frames too
  bool logs = false;    // the gateway's log lines too
  // Only lines from/to these wall times (µs since the epoch), about this FE or sub-device.
  std::optional<std::int64_t> from_us, to_us;
  std::string fe, subdevice;
  // The gateway's options as the recording ran it (its `meta gateway` line overrides
  // sdo_bus_share); store_path is replaced by a copy of the recorded store.
  GatewayOptions gateway{};
  PlotData* plot = nullptr;  // collects the series of the plot
};

struct Divergence {
  std::string when;      // "14:03:12.123456 (12.345678 s into the run)"
  std::string after;     // the last input fed: "tick" or "R can1 191#0102 (…:17)"
  std::string recorded;  // "T can0 1A0#… (…log:18)" or "(nothing: …)"
  std::string replayed;
};

struct RunReport {
  std::string run;
  ReplayMode mode = ReplayMode::Fresh;
  std::uint64_t inputs = 0, frames_in = 0, frames_out = 0, decisions = 0, compared = 0;
  std::uint64_t states = 0;  // segments' states the replayed gateway was found in (exact)
  // Exact from a segment's state: its time and line ("14:03:12.123456 (…events:3)"); empty: from
  // the run's start.
  std::string from_state;
  std::optional<Divergence> divergence;
  std::string stopped;             // why the comparison ended before the recording did (empty: it did not)
  std::vector<std::string> notes;  // torn lines, a different mapping file, the end mid-call…
};

// Replays every run of `runs` (oldest first, a new gateway each). Throws std::runtime_error for
// a recording that names neither of the mapping file's interfaces.
[[nodiscard]] std::vector<RunReport> replay(const std::vector<Run>& runs, const mapping::Config& config,
                                            const ReplayOptions& options);

// Plain logs: true for a frame the gateway would have sent itself on that side (its own COB-IDs
// upstream: heartbeat 700h+ID, EMCY 80h+ID, SDO responses, its TPDOs, LSS 7E4h; downstream as
// the NMT master: NMT 000h, SYNC 080h, SDO requests 600h..67Fh, RPDOs 200h/300h/400h/500h+ID,
// LSS 7E5h).
[[nodiscard]] bool own_frame(Gateway& gw, Side side, const canopen::CanFrame& f);

// "14:03:12.123456" (local time) for a wall time in µs.
[[nodiscard]] std::string time_of_day(std::int64_t wall_us);

}  // namespace oegw::gateway::record
