// The black box's writer (docs/guides/black-box.md): a ring of segment files in one
// folder, written by a thread of its own, so that the event loop never waits for a disk.
//
//  * The loop hands over records (frames with their time and direction, event lines) into a
//    bounded in-memory queue: a lock, a copy, no system call. A full queue (the disk is slower
//    than the buses, or stalled) drops the record and counts it; the next record that fits is
//    preceded by a `gap` line saying how many were lost and why. Memory is bounded: the queue
//    being filled and the one being written, each at most `queue_bytes`.
//  * The writer wakes every `write_period` (or when the queue is half full), turns the records
//    into text (record_format.hpp) and appends them to the current segment; both files are
//    flushed to the disk (fdatasync) every `sync_period` and when a segment closes: after a
//    crash or a power cut at most write_period + sync_period of recording is lost, and the last
//    line may be torn (the reader reports it).
//  * Segments close at max_bytes / segments bytes or span / segments of time; the oldest go once
//    the ring holds more than max_bytes, or ends longer than `span` ago (the current one stays).
//    Segments of earlier runs in the folder count too: a restart does not grow the ring. Each
//    segment's events begin with a `state` line (record_format.hpp): with settings.states, a
//    segment that has reached its size or time is due, and the loop ends it with the gateway's
//    state at its next quiet moment (state()), which begins the next; the writer only says
//    `state none (WHY)` (the run's first segment, after a kept window, no quiet moment in time).
//  * A write that fails (ENOSPC on a full disk, EIO) loses that batch — both files are cut back
//    to the last whole batch, so every file still reads back — is counted and reported
//    (status().last_error), and the next batch tries again: the buses never wait for it.
//  * keep(): the window now (every segment in the ring, the current one closed first) is
//    hard-linked into kept/<time>/, out of the ring's reach, for later collection.
#pragma once

#include <sys/types.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "canopen/can_frame.hpp"
#include "canopen/io/nice.hpp"
#include "canopen/types.hpp"
#include "gateway/record/record_format.hpp"

namespace oegw::gateway::record {

// The folder cannot be used (not made, not writable); what() names it and why.
class RecordError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct RecorderSettings {
  std::filesystem::path dir;
  std::uint64_t max_bytes = 256ull << 20;
  canopen::Duration span = std::chrono::minutes(10);
  unsigned segments = 10;  // the ring's parts: a segment closes at max_bytes/segments or span/segments
  std::size_t queue_bytes = 4u << 20;
  canopen::Duration write_period = std::chrono::milliseconds(100);
  canopen::Duration sync_period = std::chrono::milliseconds(500);
  std::string up_iface = "up", down_iface = "down";  // the interfaces' names in the .log files
  // Lines every segment's .events file starts with after its `segment` line ("version …").
  std::vector<std::string> header;
  // The loop gives the gateway's state (state()) when segment_due(): each segment then begins
  // with it. false: segments close on their own, each with `state none`.
  bool states = false;
  // The files copied into the folder once, at the start of the run (the mapping file, the
  // upstream store): name in the folder (after "<run>.") -> source. A missing source is skipped.
  std::vector<std::pair<std::string, std::filesystem::path>> run_files;
  // Tests: the write(2) the writer uses (to make a disk full or slow); CLOCK_REALTIME − the
  // loop clock in µs, taken at each segment's start.
  std::function<ssize_t(int fd, const void* data, std::size_t n)> write_fn;
  std::function<std::int64_t()> wall_offset_us;
  // Tests: the run's name (default: the UTC start time, 20261205T140312Z).
  std::string run;
};

struct KeptWindow {
  std::filesystem::path path;
  std::size_t segments = 0;
  std::uint64_t bytes = 0;
};

struct RecorderStatus {
  std::filesystem::path dir;
  std::string run;
  std::size_t segments = 0;                              // in the ring, the current one included
  std::uint64_t bytes = 0;                               // their size
  std::int64_t span_us = 0;                              // from the oldest segment's first line to the newest line
  std::uint64_t frames = 0, events = 0;                  // written since the start
  std::uint64_t dropped_frames = 0, dropped_events = 0;  // the queue was full
  std::uint64_t lost_frames = 0, lost_events = 0;        // a write failed
  std::size_t queued_bytes = 0;
  std::string last_error;  // empty: none
  std::vector<KeptWindow> kept;
};

class Recorder final : public RecordSink {
 public:
  // How much nicer than the daemon the writer thread runs (run_writer()).
  static constexpr int kWriterNiceAbove = canopen::io::kNiceBesideTheLoop;

  // Makes the folder (and kept/) if missing, copies the run files, starts the writer thread.
  // Throws RecordError when the folder cannot be made or written.
  explicit Recorder(RecorderSettings settings);
  ~Recorder();  // writes what is queued, flushes, stops the thread
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  // The loop's side: never blocks on the disk, never throws.
  void frame(Side side, Direction d, const canopen::CanFrame& f, canopen::TimePoint t) override;
  void event(canopen::TimePoint t, std::string_view text) override;
  // With RecorderSettings::states: the current segment has reached its size or time, and the
  // next waits for the gateway's state. state() ends the segment there and begins the next with
  // `text` (Gateway::export_state), or no_state() with `state none (WHY)`; either ends the due.
  // state() false: no room in the queue now, nothing dropped or counted, the segment stays due
  // (room(): the longest text a state may have now, the queue's free space less a quarter of the
  // queue kept for the records that follow it); no_state() false: dropped and counted as any
  // record.
  [[nodiscard]] bool segment_due() const { return due_.load(std::memory_order_relaxed); }
  bool state(canopen::TimePoint t, std::string_view text);
  bool no_state(canopen::TimePoint t, std::string_view why);
  [[nodiscard]] std::size_t room() const;

  // Keeps the window now; `done` runs on the loop's thread in dispatch() once the links exist
  // (or with an error). Signalled through event_fd() (an eventfd: readable when a keep is done).
  using KeepDone = std::function<void(std::optional<KeptWindow> kept, std::string error)>;
  void keep(KeepDone done);
  [[nodiscard]] int event_fd() const { return event_fd_; }
  void dispatch();

  // Waits until everything handed over so far is written and flushed (tests, shutdown).
  void flush();
  [[nodiscard]] RecorderStatus status() const;
  [[nodiscard]] const RecorderSettings& settings() const { return settings_; }

 private:
  struct Segment {
    std::string name;  // "<run>-<seq>" (both files: name.log, name.events)
    std::string run;
    std::uint64_t bytes = 0;
    std::int64_t first_wall = 0, last_wall = 0;
  };
  struct Open {  // the current segment
    int log_fd = -1, events_fd = -1;
    std::uint64_t log_size = 0, events_size = 0;  // written and whole
    std::uint64_t frames = 0;                     // frame lines in it (the @N of the next event)
    std::int64_t offset_us = 0;                   // wall = loop time + offset
    std::int64_t first_t = 0;                     // loop time of its first record
    bool due_told = false;                        // segment_due() raised for it
    std::uint64_t state_bytes = 0;                // its state line: not counted towards its size
  };

  // counted false: a record that does not fit is not dropped (no gap): the caller tries again.
  bool push(const void* head, std::size_t head_n, const void* body, std::size_t body_n, bool frame,
            bool counted = true);
  void append_gap(std::int64_t wall);
  [[nodiscard]] std::size_t state_room() const;  // room(), with m_ held
  void run_writer();
  void write_batch(const std::vector<char>& batch);
  void open_segment(std::int64_t t_us, std::string_view state_line);
  void close_segment();
  bool commit();  // the text buffers to the files; false (batch lost, files cut back) on an error
  void sync();
  void trim();
  void do_keep();
  void scan_existing();
  void fail(const std::string& what, int err);
  [[nodiscard]] std::int64_t wall_offset() const;
  ssize_t write_some(int fd, const void* p, std::size_t n);

  RecorderSettings settings_;
  std::uint64_t segment_bytes_;
  std::int64_t segment_span_us_;

  // Shared between the loop and the writer.
  mutable std::mutex m_;
  std::condition_variable cv_, flushed_cv_;
  std::vector<char> front_;
  bool wake_ = false, stop_ = false;
  std::uint64_t flush_asked_ = 0, flush_done_ = 0;
  std::uint64_t pending_dropped_frames_ = 0, pending_dropped_events_ = 0;  // not yet told by a gap record
  std::size_t keeps_asked_ = 0;
  std::deque<KeepDone> keep_waiting_;  // loop side, in request order
  std::deque<std::pair<std::optional<KeptWindow>, std::string>> keep_results_;
  RecorderStatus status_;

  // The writer's own.
  std::vector<char> back_;
  std::deque<Segment> ring_;
  std::optional<Open> open_;
  std::uint64_t next_seq_ = 0;
  std::string log_buf_, events_buf_;
  std::uint64_t buf_frames_ = 0, buf_events_ = 0;  // records in the text buffers
  std::uint64_t gap_frames_ = 0, gap_events_ = 0;  // lost by the writer, told by the next gap line
  std::string gap_why_;
  std::string none_why_ = "the run starts here";  // the next segment's `state none` when no state opens it
  std::int64_t last_sync_us_ = 0;
  bool dirty_ = false;

  // A due segment closes without a state at 4 x its size or 2 x its span + this.
  static constexpr std::int64_t kStateGraceUs = 5'000'000;
  std::atomic<bool> due_{false};

  int event_fd_ = -1;
  std::thread writer_;
};

}  // namespace oegw::gateway::record
