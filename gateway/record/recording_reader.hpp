// Reading a black-box recording back (docs/guides/black-box.md): a recording folder (the
// ring, or a kept window: segments of one or more runs of `oegw run`), one segment's file, or a
// plain candump log (`oegw demo --frames`, `candump -l`: frames only, no decisions).
//
// Every file reads back after a crash: a torn last line (the power went mid-write) is skipped
// and reported; a malformed line elsewhere is skipped and reported with its file:line.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"
#include "gateway/record/record_format.hpp"

namespace oegw::gateway::record {

// One line of the merged sequence: a frame (its .log line) or an event (its .events line).
struct Entry {
  enum class Kind : std::uint8_t { Frame, Event };
  Kind kind = Kind::Frame;
  canopen::TimePoint t{};    // the gateway's loop time (wall − the segment's offset)
  std::int64_t wall_us = 0;  // as written
  // Frames.
  std::string iface;
  std::optional<Direction> direction;  // absent in a plain log
  canopen::CanFrame frame;
  // Events.
  std::string text;
  // Where it was read: where() is "…/20261205T140312Z-000003.log:17" (made only when asked:
  // a replay reads millions of lines).
  const std::filesystem::path* file = nullptr;  // the Segment's, which outlives the entry's use
  std::size_t line = 0;
  [[nodiscard]] std::string where() const;
  // As the recording's lines show it: "R can1 191#0102" (a frame), or the event's text.
  [[nodiscard]] std::string text_line() const;
};

struct Segment {
  std::filesystem::path log, events;  // events empty: a plain candump log
  std::string name;                   // "<run>-<seq>", or the plain log's file name
};

struct Run {
  std::string name;  // the run (its start, UTC), or the plain log's file name
  std::vector<Segment> segments;
  // The files the recorder copied at the start of the run (empty when absent).
  std::filesystem::path mapping_copy, store_copy, lss_copy;
  [[nodiscard]] bool plain() const { return !segments.empty() && segments.front().events.empty(); }
};

// The runs of a folder or file, oldest first; nullopt and `error` when there is none.
[[nodiscard]] std::optional<std::vector<Run>> find_runs(const std::filesystem::path& where, std::string& error);

struct SegmentRead {
  std::vector<Entry> entries;         // merged: each event before the frame line its @N names
  std::vector<std::string> problems;  // "file:line: torn last line (…)", bad lines
  std::string up_iface, down_iface;   // from the `segment` line (empty in a plain log)
  std::int64_t offset_us = 0;
};
// Reads one segment. A file that cannot be opened is a problem, not an exception.
[[nodiscard]] SegmentRead read_segment(const Segment& s);

// One segment as a replay walks it: the events file at once (the segment's decisions, a small
// part), the frames file line by line as each() hands them over, merged (a 10-minute recording of
// a full cab holds millions of frames: none is kept once handed over). head(): the interfaces, the
// offset and the problems (the frames file's once each() has returned); its `entries` stay empty.
class SegmentReader {
 public:
  explicit SegmentReader(const Segment& s);  // `s` outlives the reader
  [[nodiscard]] const SegmentRead& head() const { return head_; }
  // The events, in order, before each() (their frame.id holds the frame line each precedes).
  [[nodiscard]] const std::vector<Entry>& events() const { return events_; }
  // Each entry once, in order: each event before the frame line its @N names.
  void each(const std::function<void(Entry&)>& fn);
  // The wall time of the entry each() would hand over first, reading the frames file only up to
  // its first frame (a time origin without reading the segment); nullopt for an empty segment.
  [[nodiscard]] std::optional<std::int64_t> first_wall_us() const;

 private:
  const Segment* s_;
  SegmentRead head_;
  std::vector<Entry> events_;
};

}  // namespace oegw::gateway::record
