// The black box's files (docs/guides/black-box.md documents both formats line by line).
//
// A segment is two files written side by side:
//  * `<run>-<seq>.log`: every CAN frame the gateway received or sent, in candump's log format
//    `(seconds.micros) IFACE ID#DATA R|T` — the wall time (CLOCK_REALTIME), the interface the
//    frame was on, the frame in cansend notation, and its direction (R received, T sent by the
//    gateway), which can-utils' log2asc and canplayer read (they ignore or understand the mark);
//  * `<run>-<seq>.events`: one line per input that is no frame (the gateway's timer calls, bus
//    events, commands, control requests) and per decision (FE values and status, node states,
//    faults, EMCYs, command outcomes, log lines), `(seconds.micros) @N TEXT`, where N is the
//    number of frame lines of the segment's .log file written before it: that orders both files
//    into the one sequence the gateway saw and did.
// The wall time of a line is its time on the gateway's loop clock (CLOCK_MONOTONIC, which is
// what the gateway is given) plus the segment's offset (its `segment` line), so the replay gets
// the loop's time back exactly: monotonic = wall − offset.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::gateway::record {

// 2: each segment's events begin with a `state` line (state_event()).
inline constexpr int kFormatVersion = 2;

// R: received by the gateway; T: sent by it.
enum class Direction : std::uint8_t { Rx, Tx };
// The host's bus (upstream) or the sub-devices' (downstream).
enum class Side : std::uint8_t { Up, Down };

// Where the black box's records go: the recorder's files (recorder.hpp) or, in a replay, the
// comparison with the recording (replay.hpp). Called on the gateway's thread.
class RecordSink {
 public:
  virtual ~RecordSink() = default;
  // A frame the gateway received (Rx, at its reception time) or sent (Tx, at the time of the
  // call that sent it).
  virtual void frame(Side side, Direction d, const canopen::CanFrame& f, canopen::TimePoint t) = 0;
  // An input that is no frame, or a decision: one line of text (no newline).
  virtual void event(canopen::TimePoint t, std::string_view text) = 0;
};

// "(1733407392.123456) can1 191#0102 R\n" appended to `out`; `wall_us` microseconds since the
// epoch. No allocation beyond `out`'s growth.
void append_frame_line(std::string& out, std::int64_t wall_us, std::string_view iface, const canopen::CanFrame& f,
                       Direction d);
// "(1733407392.123456) @17 " appended (the text follows).
void append_event_prefix(std::string& out, std::int64_t wall_us, std::uint64_t pos);
// "(1733407392.123456)"
void append_wall_time(std::string& out, std::int64_t wall_us);

struct FrameLine {
  std::int64_t wall_us = 0;
  std::string iface;
  canopen::CanFrame frame;
  std::optional<Direction> direction;  // absent in a plain candump log
};
// One line of a candump log (with or without the R/T mark, the trailing newline ignored);
// nullopt for anything else. `error` says what is wrong.
[[nodiscard]] std::optional<FrameLine> parse_frame_line(std::string_view line, std::string& error);
// "123#0102", "1ABCDEF0#", "123#R", "123#R4" (candump's notation).
[[nodiscard]] std::optional<canopen::CanFrame> parse_frame(std::string_view text);

struct EventLine {
  std::int64_t wall_us = 0;
  std::uint64_t pos = 0;
  std::string text;
};
[[nodiscard]] std::optional<EventLine> parse_event_line(std::string_view line, std::string& error);

// The segment "<run>-<seq>" a file name "<run>-<seq>.log" / ".events" belongs to (seq: 6
// digits), or "" for another file.
[[nodiscard]] std::string segment_name(std::string_view file_name);

// A wall time (µs since the epoch) by strftime's `format`, in UTC or local time.
[[nodiscard]] std::string wall_text(std::int64_t wall_us, const char* format, bool utc);

// "(1733407392.123456)" -> microseconds; nullopt for anything else.
[[nodiscard]] std::optional<std::int64_t> parse_wall_time(std::string_view text);

// A segment's `state` event (format 2), after its header: the gateway's run-time state when the
// segment began (canopen/state.hpp: Gateway::export_state), from which a replay can start there,
// as one line: "state crc32=1A2B3C4D bytes=N KEY VALUE;KEY VALUE;…", the state's lines joined
// by ';' (no state line holds one) and N and zlib's CRC-32 of that joined text, so that a line
// torn or damaged on the disk is told from a state. Or, where the gateway had no quiet moment
// to give one (a request on the wire), "state none (WHY)".
[[nodiscard]] std::string state_event(std::string_view state_text);
[[nodiscard]] std::string no_state_event(std::string_view why);
// A `state` event's state text (its lines again), or nullopt with `error`: "none (WHY)", a
// length or CRC that differs, no state event.
[[nodiscard]] std::optional<std::string> parse_state_event(std::string_view text, std::string& error);

}  // namespace oegw::gateway::record
