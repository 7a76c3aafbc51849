// The black box's writer (gateway/record/recorder.hpp) and reader (recording_reader.hpp): the
// ring of segments, what a stalled or full disk costs (the recording, counted and told, never
// the caller), keeping a window, and reading back what a crash left.
#include "gateway/record/recorder.hpp"

#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <fstream>
#include <functional>
#include <mutex>
#include <optional>
#include <sstream>

#include <gtest/gtest.h>

#include "canopen/io/nice.hpp"
#include "gateway/record/recording_reader.hpp"
#include "tests/fixtures/temp_dir.hpp"
#include "tests/fixtures/thread_nice.hpp"

namespace oegw::gateway::record {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

constexpr std::int64_t kOffset = 1'700'000'000'000'000;  // wall = loop time + this

canopen::TimePoint at_ms(std::int64_t ms) { return canopen::TimePoint{std::chrono::milliseconds(ms)}; }

struct TempDir : fixtures::TempDir {
  TempDir() : fixtures::TempDir("oegw-recorder-test") {}
};

RecorderSettings settings(const fs::path& dir, std::string run = "R1") {
  RecorderSettings s;
  s.dir = dir;
  s.run = std::move(run);
  s.up_iface = "can0";
  s.down_iface = "can1";
  s.write_period = 1ms;
  s.wall_offset_us = [] { return kOffset; };
  return s;
}

std::vector<Entry> read_run(const fs::path& dir, std::vector<std::string>* problems = nullptr) {
  std::string error;
  const auto runs = find_runs(dir, error);
  EXPECT_TRUE(runs) << error;
  std::vector<Entry> out;
  if (!runs) return out;
  for (const auto& r : *runs)
    for (const auto& s : r.segments) {
      auto read = read_segment(s);
      if (problems) problems->insert(problems->end(), read.problems.begin(), read.problems.end());
      else EXPECT_TRUE(read.problems.empty()) << read.problems.front();
      for (auto& e : read.entries) out.push_back(std::move(e));
    }
  return out;
}

std::size_t count_files(const fs::path& dir, const std::string& ext) {
  std::size_t n = 0;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ext) ++n;
  return n;
}

TEST(Recorder, FramesAndEventsReadBackInOneOrderWithTheLoopTimes) {
  TempDir tmp;
  {
    Recorder r(settings(tmp.path));
    r.event(at_ms(1000), "start");
    r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1, 2}), at_ms(1001));
    r.event(at_ms(1001), "fe joystick.1 valid x=3");
    r.frame(Side::Up, Direction::Tx, canopen::CanFrame(0x1A0, {3}), at_ms(1001));
    r.event(at_ms(1050), "tick");
    r.flush();
    EXPECT_EQ(r.status().frames, 2u);
  }
  const auto e = read_run(tmp.path);
  std::vector<std::string> seen;
  for (const auto& x : e) {
    if (x.kind == Entry::Kind::Frame)
      seen.push_back(std::string(x.direction == Direction::Rx ? "R " : "T ") + x.iface + " " + x.frame.to_string() +
                     " @" + std::to_string(x.t.time_since_epoch().count()));
    else if (x.text.rfind("segment", 0) != 0)
      seen.push_back(x.text + " @" + std::to_string(x.t.time_since_epoch().count()));
  }
  EXPECT_EQ(seen, (std::vector<std::string>{"state none (the recorder is given no states) @1000000", "start @1000000",
                                            "R can1 191#0102 @1001000", "fe joystick.1 valid x=3 @1001000",
                                            "T can0 1A0#03 @1001000", "tick @1050000"}));
  // The .log file is candump's log, wall time = loop time + the segment's offset.
  std::ifstream log(tmp.path / "R1-000000.log");
  std::string first;
  std::getline(log, first);
  EXPECT_EQ(first, "(1700000001.001000) can1 191#0102 R");
}

// The texts of a folder's segments' `state` lines, in order, each parsed back (or "none (WHY)").
std::vector<std::string> segment_states(const fs::path& dir) {
  std::vector<std::string> out;
  std::string error;
  const auto runs = find_runs(dir, error);
  if (!runs) return out;
  for (const auto& r : *runs)
    for (const auto& s : r.segments) {
      const auto read = read_segment(s);
      const auto it = std::find_if(read.entries.begin(), read.entries.end(),
                                   [](const Entry& e) { return e.text.rfind("state ", 0) == 0; });
      if (it == read.entries.end()) {
        out.push_back("(no state line)");
        continue;
      }
      const auto text = parse_state_event(it->text, error);
      out.push_back(text ? *text : error);
    }
  return out;
}

// As oegw run records: the loop gives states; a segment is due at max_bytes / segments.
RecorderSettings with_states(const fs::path& dir, std::uint64_t max_bytes, unsigned segments) {
  RecorderSettings s = settings(dir);
  s.states = true;
  s.max_bytes = max_bytes;
  s.segments = segments;
  return s;
}

// `n` grip frames of 4 bytes, 1 ms apart, then the writer waited for.
struct Frames {
  Recorder& r;
  int t = 0;
  void operator()(int n) {
    for (int i = 0; i < n; ++i) r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1, 2, 3, 4}), at_ms(t++));
    r.flush();
  }
};

// With states (oegw run): a segment that has reached its size is due and goes on until the loop
// gives the gateway's state, which begins the next segment (a replay can start there); the
// run's first begins with `state none`.
TEST(Recorder, ASegmentDueWaitsForTheStateThatBeginsTheNext) {
  TempDir tmp;
  Recorder r(with_states(tmp.path, 64 * 1024, 4));  // due at 16 KiB
  Frames frames{r};
  frames(100);
  EXPECT_FALSE(r.segment_due());
  frames(500);  // ~22 KiB: past its size, and not closed
  EXPECT_TRUE(r.segment_due());
  EXPECT_EQ(r.status().segments, 1u);
  EXPECT_TRUE(r.state(at_ms(frames.t), "a 1\nb #00ff\n"));
  frames(10);
  EXPECT_FALSE(r.segment_due());
  EXPECT_EQ(r.status().segments, 2u);
  frames(600);
  ASSERT_TRUE(r.segment_due());
  EXPECT_TRUE(r.no_state(at_ms(frames.t), "the gateway was busy for 2 s: grip: booting"));
  frames(10);
  EXPECT_EQ(segment_states(tmp.path), (std::vector<std::string>{"none (the run starts here)", "a 1\nb #00ff\n",
                                                                "none (the gateway was busy for 2 s: grip: booting)"}));
  // The state line comes after the segment's header, before any frame of it.
  const auto e = read_run(tmp.path);
  const auto state =
      std::find_if(e.begin(), e.end(), [](const Entry& x) { return x.text.rfind("state crc32=", 0) == 0; });
  ASSERT_NE(state, e.end());
  EXPECT_EQ(state->t, at_ms(600));
  EXPECT_EQ(std::prev(state)->text.rfind("segment run=R1 seq=1 ", 0), 0u);
}

// A state that does not come does not let a due segment grow on: at 4 times its size it closes
// with `state none`, and so does the one a kept window closed.
TEST(Recorder, ADueSegmentThatGetsNoStateClosesAtFourTimesItsSize) {
  TempDir tmp;
  Recorder r(with_states(tmp.path, 1024 * 1024, 64));  // due at 16 KiB
  for (int i = 0; i < 3000; ++i)                       // ~110 KiB
    r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1, 2, 3, 4}), at_ms(i));
  r.flush();
  const auto states = segment_states(tmp.path);
  ASSERT_EQ(states.size(), 2u);
  EXPECT_EQ(states[1], "none (no quiet moment of the gateway came in time)");
  const auto first = fs::file_size(tmp.path / "R1-000000.log") + fs::file_size(tmp.path / "R1-000000.events");
  EXPECT_GE(first, 4u * 16 * 1024);
  EXPECT_LT(first, 4u * 16 * 1024 + 64 + 128);  // its state line is not counted
  ASSERT_TRUE(r.state(at_ms(3000), "a 1\n"));   // the loop's state ends the due at once
  EXPECT_FALSE(r.segment_due());
  r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1}), at_ms(3001));
  r.flush();
  EXPECT_FALSE(r.segment_due());
  r.keep([](std::optional<KeptWindow>, std::string) {});
  r.flush();
  r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1}), at_ms(5000));
  r.flush();
  EXPECT_EQ(segment_states(tmp.path),
            (std::vector<std::string>{"none (the run starts here)",
                                      "none (no quiet moment of the gateway came in time)", "a 1\n",
                                      "none (a window was kept: the segment before it closed there)"}));
  EXPECT_TRUE(r.segment_due()) << "after a kept window the loop is asked for a state at once";
}

// The state line a segment begins with does not count towards its size: a state larger than a
// segment does not make the next one due at once (the loop would take a state every 100 ms).
TEST(Recorder, AStateLargerThanASegmentDoesNotMakeTheNextDueAtOnce) {
  TempDir tmp;
  Recorder r(with_states(tmp.path, 64 * 1024, 4));  // due at 16 KiB
  Frames frames{r};
  frames(600);
  ASSERT_TRUE(r.segment_due());
  ASSERT_TRUE(r.state(at_ms(frames.t), "big " + std::string(20000, 'x') + "\n"));
  frames(10);
  EXPECT_FALSE(r.segment_due());
  EXPECT_EQ(r.status().segments, 2u);
  frames(600);
  EXPECT_TRUE(r.segment_due()) << "due again at its own 16 KiB";
}

// A segment reopened after a close at four times its size is due; a state that comes in the same
// batch answers that due too: no second state is asked for.
TEST(Recorder, AStateInTheBatchThatReopensASegmentEndsItsDue) {
  TempDir tmp;
  RecorderSettings s = with_states(tmp.path, 1024 * 1024, 64);  // due at 16 KiB
  s.write_period = std::chrono::hours(1);                       // one batch: flush()
  Recorder r(s);
  for (int i = 0; i < 3000; ++i)  // ~110 KiB: closed at 64 KiB, reopened
    r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1, 2, 3, 4}), at_ms(i));
  ASSERT_TRUE(r.state(at_ms(3000), "a 1\n"));
  r.flush();
  EXPECT_EQ(segment_states(tmp.path),
            (std::vector<std::string>{"none (the run starts here)",
                                      "none (no quiet moment of the gateway came in time)", "a 1\n"}));
  EXPECT_FALSE(r.segment_due());
}

// The writes of a disk that is full (ENOSPC, nothing written) while `full` is set.
std::function<ssize_t(int, const void*, std::size_t)> full_while(const std::atomic<bool>& full) {
  return [&full](int fd, const void* p, std::size_t n) -> ssize_t {
    if (!full) return ::write(fd, p, n);
    errno = ENOSPC;
    return -1;
  };
}

// A state that does not fit the queue is not dropped (no gap: the loop tries again), and
// records a failed write lost are told before the next segment's state, where a replay stops.
TEST(Recorder, AStateWithoutRoomIsNotDroppedAndALossIsToldBeforeTheState) {
  TempDir tmp;
  RecorderSettings s = with_states(tmp.path, 64 * 1024, 4);
  s.queue_bytes = 1024;
  std::atomic<bool> full{false};
  s.write_fn = full_while(full);
  Recorder r(s);
  r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1}), at_ms(0));
  r.flush();
  EXPECT_FALSE(r.state(at_ms(1), std::string(2000, 'x')));
  // The queue less a quarter kept for the records that follow the state, less its record's head
  // and a gap record's (16 + 16 + 16 bytes): one that fits the queue but not that is not taken.
  EXPECT_EQ(r.room(), 768u - 48u);
  EXPECT_FALSE(r.state(at_ms(1), std::string(760, 'x')));
  EXPECT_EQ(r.status().dropped_events, 0u);
  full = true;
  r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {2}), at_ms(2));
  r.flush();
  full = false;
  ASSERT_TRUE(r.state(at_ms(3), "a 1\n"));
  r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {3}), at_ms(4));
  r.flush();
  std::vector<std::string> lines;
  for (const auto& x : read_run(tmp.path))
    if (x.kind == Entry::Kind::Event && x.text.rfind("segment", 0) != 0) lines.push_back(x.text.substr(0, 20));
  EXPECT_EQ(lines, (std::vector<std::string>{"state none (the run ", "gap frames=1 events=", "state crc32=720E5C9D"}));
}

// A segment whose first batch (its header and state line) a failed write lost is not taken for
// one past its size: it goes on, and the next batch tells the loss.
TEST(Recorder, ASegmentWhoseFirstWriteFailedGoesOn) {
  TempDir tmp;
  RecorderSettings s = with_states(tmp.path, 64 * 1024, 4);  // due at 16 KiB
  std::atomic<bool> full{true};
  s.write_fn = full_while(full);
  Recorder r(s);
  r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1}), at_ms(0));
  r.flush();
  full = false;
  Frames frames{r, 1};
  frames(10);
  EXPECT_FALSE(r.segment_due());
  EXPECT_EQ(r.status().segments, 1u);
  frames(10);
  EXPECT_EQ(r.status().segments, 1u);
}

// CAN first: the writer thread is nicer than the thread that made it (the event loop), so a
// bus frame that wakes the loop takes the CPU from a writer busy with its batch.
TEST(Recorder, TheWriterRunsNicerThanTheLoop) {
  TempDir tmp;
  errno = 0;
  const int loop_nice = ::getpriority(PRIO_PROCESS, 0);
  ASSERT_EQ(errno, 0);
  if (loop_nice >= canopen::io::kMaxNice)
    GTEST_SKIP() << "this test runs at nice 19: no nicer value to tell the writer by";
  Recorder r(settings(tmp.path));
  r.flush();  // returns once the writer has written a batch: it runs, its nice set first
  const std::optional<int> nice = fixtures::thread_nice("oegw-record");
  ASSERT_TRUE(nice) << "no thread named oegw-record";
  EXPECT_EQ(*nice, std::min(loop_nice + Recorder::kWriterNiceAbove, canopen::io::kMaxNice));
  EXPECT_EQ(::getpriority(PRIO_PROCESS, 0), loop_nice) << "the loop's own thread unchanged";
}

TEST(Recorder, TheRingKeepsItsSizeCapClosingSegmentsAndDroppingTheOldest) {
  TempDir tmp;
  RecorderSettings s = settings(tmp.path);
  s.max_bytes = 64 * 1024;
  s.segments = 4;  // a segment closes at 16 KiB
  Recorder r(s);
  for (int i = 0; i < 5000; ++i)  // ~37 bytes a line: ~180 KiB in all
    r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1, 2, 3, 4}), at_ms(i));
  r.flush();
  const RecorderStatus st = r.status();
  EXPECT_LE(st.bytes, s.max_bytes);
  EXPECT_GE(st.segments, 3u);
  EXPECT_FALSE(fs::exists(tmp.path / "R1-000000.log")) << "the oldest segment stays";
  EXPECT_EQ(count_files(tmp.path, ".log"), st.segments);
  // What is left is the newest part, whole and in order.
  const auto e = read_run(tmp.path);
  std::int64_t last = -1;
  std::size_t frames = 0;
  for (const auto& x : e) {
    if (x.kind != Entry::Kind::Frame) continue;
    EXPECT_GT(x.t.time_since_epoch().count(), last);
    last = x.t.time_since_epoch().count();
    ++frames;
  }
  EXPECT_EQ(last, 4999 * 1000);
  EXPECT_GT(frames, 1000u);
  EXPECT_LT(frames, 5000u);
}

TEST(Recorder, TheRingKeepsItsTimeSpan) {
  TempDir tmp;
  RecorderSettings s = settings(tmp.path);
  s.span = 10s;
  s.segments = 10;  // a segment closes after 1 s
  Recorder r(s);
  for (int i = 0; i <= 300; ++i) r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x711, {5}), at_ms(i * 100));
  r.flush();
  const auto e = read_run(tmp.path);
  ASSERT_FALSE(e.empty());
  std::int64_t first = -1;
  for (const auto& x : e)
    if (x.kind == Entry::Kind::Frame) {
      first = x.t.time_since_epoch().count();
      break;
    }
  // The newest line is at 30 s: what stays reaches back at most the span and one segment more.
  EXPECT_GE(first, (30'000 - 11'000) * 1000);
  EXPECT_LE(first, (30'000 - 9'000) * 1000);
}

TEST(Recorder, AStalledDiskCostsRecordsNotTheCallerAndTheGapIsTold) {
  TempDir tmp;
  RecorderSettings s = settings(tmp.path);
  s.queue_bytes = 4096;  // 128 frame records
  std::mutex m;
  std::condition_variable cv;
  bool stalled = false, release = false;
  s.write_fn = [&](int fd, const void* p, std::size_t n) -> ssize_t {
    std::unique_lock lk(m);
    if (!release) {
      stalled = true;
      cv.notify_all();
      cv.wait(lk, [&] { return release; });
    }
    return ::write(fd, p, n);
  };
  Recorder r(s);
  r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {0}), at_ms(0));
  {
    std::unique_lock lk(m);
    cv.wait(lk, [&] { return stalled; });  // the writer is inside write(), held
  }
  for (int i = 1; i <= 1000; ++i) r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1}), at_ms(i));
  const RecorderStatus held = r.status();
  EXPECT_LE(held.queued_bytes, s.queue_bytes) << "memory stays bounded while the disk is stalled";
  EXPECT_GT(held.dropped_frames, 800u);
  {
    std::lock_guard lk(m);
    release = true;
  }
  cv.notify_all();
  r.flush();  // the queue drained: the next record fits, and the gap is told before it
  r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {2}), at_ms(2000));
  r.flush();
  const RecorderStatus after = r.status();
  EXPECT_EQ(after.frames + after.dropped_frames, 1002u);
  bool gap = false;
  for (const auto& x : read_run(tmp.path))
    if (x.kind == Entry::Kind::Event && x.text.rfind("gap frames=", 0) == 0) {
      gap = true;
      EXPECT_NE(x.text.find("gap frames=" + std::to_string(after.dropped_frames) + " events=0"), std::string::npos)
          << x.text;
    }
  EXPECT_TRUE(gap) << [&] {
    std::ifstream in(tmp.path / "R1-000000.events");
    std::stringstream t;
    t << in.rdbuf();
    return t.str();
  }();
}

TEST(Recorder, AFullDiskLosesTheBatchKeepsEveryFileReadableAndRecovers) {
  TempDir tmp;
  RecorderSettings s = settings(tmp.path);
  std::atomic<bool> full{false};
  s.write_fn = [&](int fd, const void* p, std::size_t n) -> ssize_t {
    if (full) {
      // Half the batch reaches the disk before it is full: the file is cut back.
      const ssize_t half = ::write(fd, p, n / 2);
      (void)half;
      errno = ENOSPC;
      return -1;
    }
    return ::write(fd, p, n);
  };
  Recorder r(s);
  r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1}), at_ms(0));
  r.flush();
  full = true;
  for (int i = 1; i <= 10; ++i) r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {2}), at_ms(i));
  r.flush();
  RecorderStatus st = r.status();
  EXPECT_EQ(st.lost_frames, 10u);
  EXPECT_NE(st.last_error.find("No space left on device"), std::string::npos) << st.last_error;
  full = false;
  r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {3}), at_ms(20));
  r.flush();
  std::vector<std::string> frames, gaps;
  for (const auto& x : read_run(tmp.path)) {
    if (x.kind == Entry::Kind::Frame) frames.push_back(x.frame.to_string());
    else if (x.text.rfind("gap", 0) == 0) gaps.push_back(x.text);
  }
  EXPECT_EQ(frames, (std::vector<std::string>{"191#01", "191#03"}));
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_NE(gaps[0].find("gap frames=10 events=0 (write failed: No space left on device)"), std::string::npos)
      << gaps[0];
}

TEST(Recorder, KeepLinksTheWindowOutOfTheRingsReach) {
  TempDir tmp;
  RecorderSettings s = settings(tmp.path);
  s.max_bytes = 64 * 1024;
  s.segments = 4;
  Recorder r(s);
  for (int i = 0; i < 300; ++i) r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1}), at_ms(i));
  std::optional<KeptWindow> kept;
  std::string error = "not called";
  r.keep([&](std::optional<KeptWindow> k, std::string e) {
    kept = std::move(k);
    error = std::move(e);
  });
  r.flush();
  r.dispatch();
  ASSERT_TRUE(kept) << error;
  EXPECT_EQ(error, "");
  EXPECT_EQ(kept->path.parent_path(), tmp.path / "kept");
  ASSERT_EQ(kept->segments, 1u);
  struct stat a {
  }, b{};
  ASSERT_EQ(::stat((kept->path / "R1-000000.log").c_str(), &a), 0);
  ASSERT_EQ(::stat((tmp.path / "R1-000000.log").c_str(), &b), 0);
  EXPECT_EQ(a.st_ino, b.st_ino) << "a hard link, not a copy";
  // The ring goes on in a new segment and drops the kept one; the kept window stays whole.
  for (int i = 300; i < 8000; ++i) r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {2}), at_ms(i));
  r.flush();
  EXPECT_FALSE(fs::exists(tmp.path / "R1-000000.log"));
  std::size_t frames = 0;
  for (const auto& x : read_run(kept->path))
    if (x.kind == Entry::Kind::Frame) ++frames;
  EXPECT_EQ(frames, 300u);
  ASSERT_EQ(r.status().kept.size(), 1u);
  EXPECT_EQ(r.status().kept[0].path, kept->path);
}

TEST(Recorder, ARestartCountsTheEarlierRunsSegmentsInTheRing) {
  TempDir tmp;
  RecorderSettings s = settings(tmp.path, "A");
  s.max_bytes = 64 * 1024;
  s.segments = 4;
  {
    Recorder r(s);
    for (int i = 0; i < 1500; ++i) r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1, 2, 3, 4}), at_ms(i));
  }
  s.run = "B";
  Recorder r(s);
  for (int i = 0; i < 1500; ++i) r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1, 2, 3, 4}), at_ms(i));
  r.flush();
  std::uint64_t total = 0;
  for (const auto& e : fs::directory_iterator(tmp.path))
    if (e.is_regular_file()) total += e.file_size();
  EXPECT_LE(total, s.max_bytes);
  EXPECT_FALSE(fs::exists(tmp.path / "A-000000.log"));
  EXPECT_TRUE(fs::exists(tmp.path / "B-000000.log"));
}

TEST(RecordingReader, ATornLastLineIsSkippedAndReported) {
  TempDir tmp;
  {
    Recorder r(settings(tmp.path));
    for (int i = 0; i < 3; ++i) r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1}), at_ms(i));
    r.event(at_ms(3), "tick");
  }
  // The power went while a line was being written.
  std::ofstream(tmp.path / "R1-000000.log", std::ios::app) << "(1700000000.004000) can1 19";
  std::ofstream(tmp.path / "R1-000000.events", std::ios::app) << "(1700000000.004000) @3 fe joy";
  std::vector<std::string> problems;
  const auto e = read_run(tmp.path, &problems);
  std::size_t frames = 0, ticks = 0;
  for (const auto& x : e) {
    if (x.kind == Entry::Kind::Frame) ++frames;
    else if (x.text == "tick") ++ticks;
  }
  EXPECT_EQ(frames, 3u);
  EXPECT_EQ(ticks, 1u);
  ASSERT_EQ(problems.size(), 2u);
  for (const auto& p : problems) EXPECT_NE(p.find("torn last line"), std::string::npos) << p;
  EXPECT_NE(problems[0].find("R1-000000.events:"), std::string::npos) << problems[0];
}

// `oegw replay --from 12.5` counts from the first entry's time without reading the segment: the
// same time read_segment's first entry has, for a recording that starts with an event or a frame
// and for a plain log with other text before its frames.
TEST(RecordingReader, TheFirstWallTimeIsTheFirstEntrysWithoutReadingTheSegment) {
  const auto first_of = [](const fs::path& dir) {
    std::string error;
    const auto runs = find_runs(dir, error);
    EXPECT_TRUE(runs) << error;
    const Segment& s = runs->front().segments.front();
    const auto all = read_segment(s).entries;
    EXPECT_FALSE(all.empty());
    EXPECT_EQ(SegmentReader(s).first_wall_us(), all.front().wall_us);
    return SegmentReader(s).first_wall_us();
  };
  TempDir events_first, frame_first, plain, empty;
  {
    Recorder r(settings(events_first.path));
    r.event(at_ms(1000), "start");
    r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1}), at_ms(1001));
  }
  {
    Recorder r(settings(frame_first.path));
    r.frame(Side::Down, Direction::Rx, canopen::CanFrame(0x191, {1}), at_ms(1001));
    r.event(at_ms(1002), "tick");
  }
  EXPECT_NE(first_of(events_first.path), std::nullopt);
  EXPECT_NE(first_of(frame_first.path), std::nullopt);
  std::ofstream(plain.path / "cab.log") << "# oegw demo --frames\nstep 1: boot\n(1700000003.250000) can1 191#01\n";
  EXPECT_EQ(first_of(plain.path / "cab.log"), 1700000003250000);
  std::ofstream(empty.path / "cab.log") << "step 1: boot\n";
  std::string error;
  const auto runs = find_runs(empty.path / "cab.log", error);
  ASSERT_TRUE(runs) << error;
  EXPECT_EQ(SegmentReader(runs->front().segments.front()).first_wall_us(), std::nullopt);
}

TEST(RecordingReader, AFolderWithoutARecordingIsRefusedWithWhatWasExpected) {
  TempDir tmp;
  std::string error;
  EXPECT_FALSE(find_runs(tmp.path, error));
  EXPECT_NE(error.find("no recording in it"), std::string::npos) << error;
  EXPECT_FALSE(find_runs(tmp.path / "nope", error));
  EXPECT_NE(error.find("no such file or folder"), std::string::npos) << error;
}

}  // namespace
}  // namespace oegw::gateway::record
