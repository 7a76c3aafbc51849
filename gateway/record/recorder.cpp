#include "gateway/record/recorder.hpp"

#include <pthread.h>

#include <fcntl.h>
#include <sys/eventfd.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <map>
#include <set>

#include <fmt/format.h>

#include "canopen/io/nice.hpp"

namespace oegw::gateway::record {

namespace fs = std::filesystem;

namespace {

// State: the body is the gateway's state text (side_dir 0) or why there is none (side_dir 1).
enum class Kind : std::uint8_t { Frame = 1, Event = 2, Gap = 3, State = 4 };

struct Head {
  Kind kind;
  std::uint8_t side_dir;  // bit 0: down, bit 1: sent
  std::uint16_t pad;
  std::uint32_t len;  // body bytes
  std::int64_t t_us;
};
static_assert(sizeof(Head) == 16);

struct FrameBody {
  std::uint32_t id;
  std::uint8_t dlc;
  std::uint8_t flags;  // bit 0 extended, bit 1 rtr
  std::uint8_t data[8];
  std::uint8_t pad[2];
};
static_assert(sizeof(FrameBody) == 16);

struct GapBody {
  std::uint64_t frames, events;
};

constexpr std::size_t kCommitBytes = 1u << 20;  // text buffered before it is written

std::int64_t steady_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::int64_t timespec_us(const timespec& t) { return static_cast<std::int64_t>(t.tv_sec) * 1000000 + t.tv_nsec / 1000; }

// "20261205T140312Z" for a wall time in µs.
std::string utc_stamp(std::int64_t wall_us) { return wall_text(wall_us, "%Y%m%dT%H%M%SZ", true); }

std::int64_t wall_now_us() {
  timespec t{};
  ::clock_gettime(CLOCK_REALTIME, &t);
  return timespec_us(t);
}

void fsync_dir(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  (void)::fsync(fd);
  ::close(fd);
}

std::string segment_of(const fs::path& p) { return segment_name(p.filename().string()); }

std::uint64_t size_of(const fs::path& p) {
  std::error_code ec;
  const auto n = fs::file_size(p, ec);
  return ec ? 0 : n;
}

}  // namespace

Recorder::Recorder(RecorderSettings settings) : settings_(std::move(settings)) {
  if (settings_.segments == 0) settings_.segments = 1;
  segment_bytes_ = std::max<std::uint64_t>(settings_.max_bytes / settings_.segments, 4096);
  segment_span_us_ =
      std::max<std::int64_t>(std::chrono::duration_cast<std::chrono::microseconds>(settings_.span).count() /
                                 settings_.segments,
                             1000);
  std::error_code ec;
  fs::create_directories(settings_.dir / "kept", ec);
  if (ec) throw RecordError(fmt::format("cannot make {}: {}", (settings_.dir / "kept").string(), ec.message()));
  if (::access(settings_.dir.c_str(), W_OK) != 0)
    throw RecordError(fmt::format("cannot write in {}: {}", settings_.dir.string(), std::strerror(errno)));
  scan_existing();
  if (settings_.run.empty()) settings_.run = utc_stamp(wall_now_us());
  // A run started within the same second as an earlier one gets a letter.
  {
    const std::string base = settings_.run;
    for (char c = 'b';
         std::any_of(ring_.begin(), ring_.end(), [&](const Segment& s) { return s.run == settings_.run; }); ++c)
      settings_.run = base + c;
  }
  for (const auto& [name, source] : settings_.run_files) {
    if (source.empty() || !fs::exists(source, ec)) continue;
    fs::copy_file(source, settings_.dir / (settings_.run + "." + name), fs::copy_options::overwrite_existing, ec);
  }
  fsync_dir(settings_.dir);
  event_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (event_fd_ < 0) throw RecordError(fmt::format("eventfd: {}", std::strerror(errno)));
  front_.reserve(settings_.queue_bytes + sizeof(Head) + sizeof(GapBody));
  back_.reserve(settings_.queue_bytes + sizeof(Head) + sizeof(GapBody));
  status_.dir = settings_.dir;
  status_.run = settings_.run;
  writer_ = std::thread([this] { run_writer(); });
  // Named, so that `top -H` and a profiler tell the black box's writer from the event loop.
  (void)::pthread_setname_np(writer_.native_handle(), "oegw-record");
}

Recorder::~Recorder() {
  {
    std::lock_guard lk(m_);
    stop_ = true;
  }
  cv_.notify_one();
  if (writer_.joinable()) writer_.join();
  if (event_fd_ >= 0) ::close(event_fd_);
}

void Recorder::scan_existing() {
  std::map<std::string, Segment> found;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(settings_.dir, ec)) {
    const std::string seg = segment_of(e.path());
    if (seg.empty()) continue;
    Segment& s = found[seg];
    s.name = seg;
    s.run = seg.substr(0, seg.rfind('-'));
    s.bytes += size_of(e.path());
    const auto mtime = fs::last_write_time(e.path(), ec);
    if (!ec) {
      const auto wall = std::chrono::duration_cast<std::chrono::microseconds>(
                            std::chrono::file_clock::to_sys(mtime).time_since_epoch())
                            .count();
      s.last_wall = std::max(s.last_wall, wall);
      s.first_wall = s.last_wall;
    }
  }
  for (auto& [name, s] : found) ring_.push_back(s);  // by name: runs are start times, seq padded
  for (const auto& e : fs::directory_iterator(settings_.dir / "kept", ec)) {
    if (!e.is_directory()) continue;
    KeptWindow k{e.path(), 0, 0};
    for (const auto& f : fs::directory_iterator(e.path(), ec)) {
      if (segment_of(f.path()).empty()) continue;
      if (f.path().extension() == ".events") ++k.segments;
      k.bytes += size_of(f.path());
    }
    status_.kept.push_back(k);
  }
  std::sort(status_.kept.begin(), status_.kept.end(),
            [](const KeptWindow& a, const KeptWindow& b) { return a.path < b.path; });
}

// ---- The loop's side ----

bool Recorder::push(const void* head, std::size_t head_n, const void* body, std::size_t body_n, bool frame,
                    bool counted) {
  std::lock_guard lk(m_);
  const bool gap = pending_dropped_frames_ != 0 || pending_dropped_events_ != 0;
  const std::size_t need = head_n + body_n + (gap ? sizeof(Head) + sizeof(GapBody) : 0);
  if (!counted && need > state_room()) return false;
  if (front_.size() + need > settings_.queue_bytes) {
    ++(frame ? pending_dropped_frames_ : pending_dropped_events_);
    ++(frame ? status_.dropped_frames : status_.dropped_events);
    return false;
  }
  if (gap) {
    Head h{};
    std::memcpy(&h, head, sizeof h);
    h.kind = Kind::Gap;
    h.len = sizeof(GapBody);
    const GapBody g{pending_dropped_frames_, pending_dropped_events_};
    const auto* hp = reinterpret_cast<const char*>(&h);
    const auto* gp = reinterpret_cast<const char*>(&g);
    front_.insert(front_.end(), hp, hp + sizeof h);
    front_.insert(front_.end(), gp, gp + sizeof g);
    pending_dropped_frames_ = pending_dropped_events_ = 0;
  }
  const auto* hp = static_cast<const char*>(head);
  front_.insert(front_.end(), hp, hp + head_n);
  if (body_n != 0) {
    const auto* bp = static_cast<const char*>(body);
    front_.insert(front_.end(), bp, bp + body_n);
  }
  if (!wake_ && front_.size() > settings_.queue_bytes / 2) {
    wake_ = true;
    cv_.notify_one();
  }
  return true;
}

void Recorder::frame(Side side, Direction d, const canopen::CanFrame& f, canopen::TimePoint t) {
  Head h{Kind::Frame, static_cast<std::uint8_t>((side == Side::Down ? 1 : 0) | (d == Direction::Tx ? 2 : 0)), 0,
         sizeof(FrameBody), t.time_since_epoch().count()};
  FrameBody b{};
  b.id = f.id;
  b.dlc = f.dlc;
  b.flags = static_cast<std::uint8_t>((f.extended ? 1 : 0) | (f.rtr ? 2 : 0));
  std::memcpy(b.data, f.data.data(), 8);
  char buf[sizeof h + sizeof b];
  std::memcpy(buf, &h, sizeof h);
  std::memcpy(buf + sizeof h, &b, sizeof b);
  (void)push(buf, sizeof buf, nullptr, 0, true);
}

void Recorder::event(canopen::TimePoint t, std::string_view text) {
  const std::size_t n = std::min<std::size_t>(text.size(), 0xFFFF);
  const Head h{Kind::Event, 0, 0, static_cast<std::uint32_t>(n), t.time_since_epoch().count()};
  (void)push(&h, sizeof h, text.data(), n, false);
}

bool Recorder::state(canopen::TimePoint t, std::string_view text) {
  const Head h{Kind::State, 0, 0, static_cast<std::uint32_t>(text.size()), t.time_since_epoch().count()};
  if (!push(&h, sizeof h, text.data(), text.size(), false, false)) return false;
  due_.store(false, std::memory_order_relaxed);
  return true;
}

bool Recorder::no_state(canopen::TimePoint t, std::string_view why) {
  const Head h{Kind::State, 1, 0, static_cast<std::uint32_t>(why.size()), t.time_since_epoch().count()};
  if (!push(&h, sizeof h, why.data(), why.size(), false)) return false;
  due_.store(false, std::memory_order_relaxed);
  return true;
}

std::size_t Recorder::room() const {
  // The state's text: its record's head, and a gap record that may have to go first.
  constexpr std::size_t kAround = sizeof(Head) + sizeof(Head) + sizeof(GapBody);
  std::lock_guard lk(m_);
  const std::size_t r = state_room();
  return r - std::min(r, kAround);
}

std::size_t Recorder::state_room() const {
  const std::size_t kept = settings_.queue_bytes / 4;  // for the records that follow the state
  const std::size_t used = front_.size() + kept;
  return settings_.queue_bytes - std::min(settings_.queue_bytes, used);
}

void Recorder::keep(KeepDone done) {
  {
    std::lock_guard lk(m_);
    keep_waiting_.push_back(std::move(done));
    ++keeps_asked_;
  }
  cv_.notify_one();
}

void Recorder::dispatch() {
  std::uint64_t n = 0;
  (void)::read(event_fd_, &n, sizeof n);
  std::vector<std::pair<KeepDone, std::pair<std::optional<KeptWindow>, std::string>>> ready;
  {
    std::lock_guard lk(m_);
    while (!keep_results_.empty() && !keep_waiting_.empty()) {
      ready.emplace_back(std::move(keep_waiting_.front()), std::move(keep_results_.front()));
      keep_waiting_.pop_front();
      keep_results_.pop_front();
    }
  }
  for (auto& [done, r] : ready)
    if (done) done(std::move(r.first), std::move(r.second));
}

void Recorder::flush() {
  std::unique_lock lk(m_);
  const std::uint64_t target = ++flush_asked_;
  cv_.notify_one();
  flushed_cv_.wait(lk, [&] { return flush_done_ >= target || !writer_.joinable(); });
}

RecorderStatus Recorder::status() const {
  std::lock_guard lk(m_);
  RecorderStatus s = status_;
  s.queued_bytes = front_.size();
  return s;
}

// ---- The writer ----

std::int64_t Recorder::wall_offset() const {
  if (settings_.wall_offset_us) return settings_.wall_offset_us();
  timespec real{}, mono{};
  ::clock_gettime(CLOCK_REALTIME, &real);
  ::clock_gettime(CLOCK_MONOTONIC, &mono);
  return timespec_us(real) - timespec_us(mono);
}

ssize_t Recorder::write_some(int fd, const void* p, std::size_t n) {
  return settings_.write_fn ? settings_.write_fn(fd, p, n) : ::write(fd, p, n);
}

void Recorder::fail(const std::string& what, int err) {
  std::lock_guard lk(m_);
  status_.last_error = what + ": " + std::strerror(err);
}

void Recorder::run_writer() {
  // CAN first: the writer's batches (text for 100 ms of frames, a write, an fdatasync) must not
  // hold the event loop off the CPU when a bus frame wakes it. A nice value kWriterNiceAbove the
  // daemon's lets the loop preempt the writer sooner (canopen/io/nice.hpp run_nicer);
  // what it cannot write in time is dropped and counted, never waited for.
  canopen::io::run_nicer(kWriterNiceAbove);
  last_sync_us_ = steady_us();
  for (;;) {
    std::unique_lock lk(m_);
    cv_.wait_for(lk, settings_.write_period,
                 [&] { return wake_ || stop_ || flush_asked_ != flush_done_ || keeps_asked_ > 0; });
    wake_ = false;
    back_.swap(front_);
    front_.clear();
    const bool stopping = stop_;
    const std::uint64_t flush_target = flush_asked_;
    const std::size_t keeps = keeps_asked_;
    keeps_asked_ = 0;
    lk.unlock();

    write_batch(back_);
    back_.clear();
    for (std::size_t k = 0; k < keeps; ++k) do_keep();
    if (stopping || flush_target != 0 ||
        steady_us() - last_sync_us_ >=
            std::chrono::duration_cast<std::chrono::microseconds>(settings_.sync_period).count())
      sync();
    trim();

    lk.lock();
    status_.segments = ring_.size();
    status_.bytes = 0;
    for (const Segment& s : ring_) status_.bytes += s.bytes;
    status_.span_us = ring_.empty() ? 0 : ring_.back().last_wall - ring_.front().first_wall;
    if (flush_target > flush_done_) {
      flush_done_ = flush_target;
      flushed_cv_.notify_all();
    }
    if (stopping) break;
  }
  close_segment();
  std::lock_guard lk(m_);
  flush_done_ = flush_asked_;
  flushed_cv_.notify_all();
}

void Recorder::open_segment(std::int64_t t_us, std::string_view state_line) {
  Open o;
  o.offset_us = wall_offset();
  o.first_t = t_us;
  const std::string name = fmt::format("{}-{:06}", settings_.run, next_seq_);
  const fs::path log = settings_.dir / (name + ".log"), events = settings_.dir / (name + ".events");
  o.log_fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0640);
  if (o.log_fd < 0) return fail("recording: cannot open " + log.string(), errno);
  o.events_fd = ::open(events.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0640);
  if (o.events_fd < 0) {
    const int err = errno;
    ::close(o.log_fd);
    ::unlink(log.c_str());
    return fail("recording: cannot open " + events.string(), err);
  }
  ++next_seq_;
  fsync_dir(settings_.dir);
  const std::int64_t wall = t_us + o.offset_us;
  ring_.push_back(Segment{name, settings_.run, 0, wall, wall});
  open_ = o;
  events_buf_ += fmt::format(
      "# oegw recording, format {}: {}.log holds the frames (candump log), this file the other "
      "inputs and the decisions as (seconds.micros) @frames-before TEXT; docs/guides/black-box.md#the-files"
      "\n",
      kFormatVersion, name);
  append_event_prefix(events_buf_, wall, 0);
  events_buf_ += fmt::format("segment run={} seq={} offset_us={} up={} down={}\n", settings_.run, next_seq_ - 1,
                             o.offset_us, settings_.up_iface, settings_.down_iface);
  ++buf_events_;
  for (const std::string& h : settings_.header) {
    append_event_prefix(events_buf_, wall, 0);
    events_buf_ += h;
    events_buf_ += '\n';
    ++buf_events_;
  }
  // Records lost before (a failed write) are told before the state: a replay stops there
  // rather than hold the state against a gateway that missed them.
  if (gap_frames_ != 0 || gap_events_ != 0) append_gap(wall);
  const std::size_t before = events_buf_.size();
  append_event_prefix(events_buf_, wall, 0);
  events_buf_ += state_line;
  events_buf_ += '\n';
  ++buf_events_;
  open_->state_bytes = events_buf_.size() - before;
  none_why_ = "the segment before it ended without a state";
}

void Recorder::append_gap(std::int64_t wall) {
  append_event_prefix(events_buf_, wall, open_->frames);
  events_buf_ += fmt::format("gap frames={} events={} ({})\n", gap_frames_, gap_events_, gap_why_);
  ++buf_events_;
  gap_frames_ = gap_events_ = 0;
}

void Recorder::close_segment() {
  if (!open_) return;
  (void)commit();
  if (::fdatasync(open_->log_fd) != 0 || ::fdatasync(open_->events_fd) != 0) fail("recording: fdatasync", errno);
  ::close(open_->log_fd);
  ::close(open_->events_fd);
  open_.reset();
  dirty_ = false;
}

bool Recorder::commit() {
  if (!open_ || (log_buf_.empty() && events_buf_.empty())) return true;
  const auto write_all = [this](int fd, const std::string& buf) -> int {
    std::size_t done = 0;
    while (done < buf.size()) {
      const ssize_t n = write_some(fd, buf.data() + done, buf.size() - done);
      if (n < 0) {
        if (errno == EINTR) continue;
        return errno;
      }
      if (n == 0) return EIO;
      done += static_cast<std::size_t>(n);
    }
    return 0;
  };
  int err = write_all(open_->log_fd, log_buf_);
  const char* which = ".log";
  if (err == 0) {
    err = write_all(open_->events_fd, events_buf_);
    which = ".events";
  }
  Segment& seg = ring_.back();
  if (err == 0) {
    open_->log_size += log_buf_.size();
    open_->events_size += events_buf_.size();
    seg.bytes = open_->log_size + open_->events_size;
    {
      std::lock_guard lk(m_);
      status_.frames += buf_frames_;
      status_.events += buf_events_;
    }
    dirty_ = true;
  } else {
    // Both files back to their last whole batch: every file reads back, the loss is one gap.
    (void)::ftruncate(open_->log_fd, static_cast<off_t>(open_->log_size));
    (void)::ftruncate(open_->events_fd, static_cast<off_t>(open_->events_size));
    if (open_->events_size == 0) open_->state_bytes = 0;  // its first batch, the state line with it
    open_->frames -= buf_frames_;
    gap_frames_ += buf_frames_;
    gap_events_ += buf_events_;
    gap_why_ = std::string("write failed: ") + std::strerror(err);
    {
      std::lock_guard lk(m_);
      status_.lost_frames += buf_frames_;
      status_.lost_events += buf_events_;
    }
    fail("recording: writing " + seg.name + which, err);
  }
  log_buf_.clear();
  events_buf_.clear();
  buf_frames_ = buf_events_ = 0;
  return err == 0;
}

void Recorder::write_batch(const std::vector<char>& batch) {
  std::size_t at = 0;
  bool open_failed = false;
  while (at + sizeof(Head) <= batch.size()) {
    Head h;
    std::memcpy(&h, batch.data() + at, sizeof h);
    const char* body = batch.data() + at + sizeof h;
    at += sizeof h + h.len;
    if (open_) {
      // The state line it began with is not counted: a state larger than a segment would make
      // every segment due at once.
      const std::uint64_t all = open_->log_size + open_->events_size + log_buf_.size() + events_buf_.size();
      const std::uint64_t bytes = all - std::min(all, open_->state_bytes);
      const std::int64_t age = h.t_us - open_->first_t;
      if (!settings_.states && (bytes >= segment_bytes_ || age >= segment_span_us_)) {
        close_segment();
      } else if (bytes >= segment_bytes_ || age >= segment_span_us_) {
        // Due: the loop gives the gateway's state at its next quiet moment (state()), which
        // opens the next segment; told once a segment, so that the records still on their
        // way to it do not ask the loop again. One that does not come in time does not let
        // it grow on.
        if (!open_->due_told) due_.store(true, std::memory_order_relaxed);
        open_->due_told = true;
        if (bytes >= 4 * segment_bytes_ || age >= 2 * segment_span_us_ + kStateGraceUs) {
          close_segment();
          none_why_ = "no quiet moment of the gateway came in time";
        }
      }
    }
    if (h.kind == Kind::State) {
      // A new segment begins with it: a replay can start there.
      close_segment();
      if (open_failed) {  // lost as any record the folder refuses
        ++gap_events_;
        std::lock_guard lk(m_);
        ++status_.lost_events;
        continue;
      }
      const std::string_view text(body, h.len);
      std::string line;
      try {
        line = h.side_dir == 0 ? state_event(text) : no_state_event(text);
      } catch (const std::logic_error& e) {
        line = no_state_event(e.what());
      }
      open_segment(h.t_us, line);
      open_failed = !open_;
      if (open_failed) {  // the state with it
        ++gap_events_;
        std::lock_guard lk(m_);
        ++status_.lost_events;
      }
      // A due raised in this batch for a segment before it (a reopened one) is answered.
      due_.store(false, std::memory_order_relaxed);
      continue;
    }
    if (!open_ && !open_failed) {
      open_segment(h.t_us, no_state_event(settings_.states ? none_why_ : "the recorder is given no states"));
      open_failed = !open_;
      // Not the run's first: the loop gives a state soon, and the segment after it has it.
      if (open_ && next_seq_ > 1 && settings_.states) due_.store(true, std::memory_order_relaxed);
    }
    if (!open_) {  // the folder refuses new files: counted as lost, told by the next gap line
      const bool is_frame = h.kind == Kind::Frame;
      ++(is_frame ? gap_frames_ : gap_events_);
      std::lock_guard lk(m_);
      ++(is_frame ? status_.lost_frames : status_.lost_events);
      continue;
    }
    const std::int64_t wall = h.t_us + open_->offset_us;
    if (gap_frames_ != 0 || gap_events_ != 0) append_gap(wall);
    switch (h.kind) {
      case Kind::Frame: {
        FrameBody b;
        std::memcpy(&b, body, sizeof b);
        canopen::CanFrame f;
        f.id = b.id;
        f.dlc = b.dlc;
        f.extended = (b.flags & 1) != 0;
        f.rtr = (b.flags & 2) != 0;
        std::memcpy(f.data.data(), b.data, 8);
        append_frame_line(log_buf_, wall, (h.side_dir & 1) != 0 ? settings_.down_iface : settings_.up_iface, f,
                          (h.side_dir & 2) != 0 ? Direction::Tx : Direction::Rx);
        ++open_->frames;
        ++buf_frames_;
        break;
      }
      case Kind::Event:
        append_event_prefix(events_buf_, wall, open_->frames);
        events_buf_.append(body, h.len);
        events_buf_ += '\n';
        ++buf_events_;
        break;
      case Kind::Gap: {
        GapBody g;
        std::memcpy(&g, body, sizeof g);
        append_event_prefix(events_buf_, wall, open_->frames);
        events_buf_ += fmt::format("gap frames={} events={} (the queue was full: the disk was slower than the buses)\n",
                                   g.frames, g.events);
        ++buf_events_;
        break;
      }
      case Kind::State: break;  // opened its segment above
    }
    ring_.back().last_wall = wall;
    if (log_buf_.size() + events_buf_.size() >= kCommitBytes) (void)commit();
  }
  (void)commit();
}

void Recorder::sync() {
  last_sync_us_ = steady_us();
  if (!open_ || !dirty_) return;
  if (::fdatasync(open_->log_fd) != 0 || ::fdatasync(open_->events_fd) != 0) fail("recording: fdatasync", errno);
  dirty_ = false;
}

void Recorder::trim() {
  std::uint64_t total = 0;
  for (const Segment& s : ring_) total += s.bytes;
  const std::int64_t span_us = std::chrono::duration_cast<std::chrono::microseconds>(settings_.span).count();
  const std::size_t keep_last = open_ ? 1 : 0;
  std::set<std::string> runs_gone;
  while (ring_.size() > keep_last &&
         (total > settings_.max_bytes || ring_.back().last_wall - ring_.front().last_wall > span_us)) {
    const Segment s = ring_.front();
    ring_.pop_front();
    total -= s.bytes;
    ::unlink((settings_.dir / (s.name + ".log")).c_str());
    ::unlink((settings_.dir / (s.name + ".events")).c_str());
    if (s.run != settings_.run &&
        std::none_of(ring_.begin(), ring_.end(), [&](const Segment& o) { return o.run == s.run; }))
      runs_gone.insert(s.run);
  }
  // The run files (mapping file, store) of a run none of whose segments is left.
  if (runs_gone.empty()) return;
  std::error_code ec;
  std::vector<fs::path> doomed;
  for (const auto& e : fs::directory_iterator(settings_.dir, ec)) {
    const std::string n = e.path().filename().string();
    for (const std::string& r : runs_gone)
      if (n.size() > r.size() && n.compare(0, r.size() + 1, r + ".") == 0) doomed.push_back(e.path());
  }
  for (const auto& p : doomed) fs::remove(p, ec);
}

void Recorder::do_keep() {
  close_segment();  // the window ends now; the next record opens a new segment
  none_why_ = "a window was kept: the segment before it closed there";
  std::string name = utc_stamp(wall_now_us());
  fs::path dir = settings_.dir / "kept" / name;
  for (int n = 2; fs::exists(dir); ++n) dir = settings_.dir / "kept" / (name + "-" + std::to_string(n));
  std::error_code ec;
  std::optional<KeptWindow> result;
  std::string error;
  if (!fs::create_directory(dir, ec)) {
    error = fmt::format("cannot make {}: {}", dir.string(), ec.message());
  } else {
    KeptWindow k{dir, 0, 0};
    std::set<std::string> runs;
    for (const Segment& s : ring_) {
      runs.insert(s.run);
      for (const char* ext : {".log", ".events"}) {
        const fs::path from = settings_.dir / (s.name + ext);
        fs::create_hard_link(from, dir / (s.name + ext), ec);
        if (ec) {
          error = fmt::format("cannot link {} into {}: {}", from.string(), dir.string(), ec.message());
          break;
        }
        k.bytes += size_of(from);
      }
      if (!error.empty()) break;
      ++k.segments;
    }
    for (const auto& e : fs::directory_iterator(settings_.dir, ec)) {
      if (!e.is_regular_file() || !segment_of(e.path()).empty()) continue;
      const std::string n = e.path().filename().string();
      for (const std::string& r : runs)
        if (n.size() > r.size() && n.compare(0, r.size() + 1, r + ".") == 0) {
          std::error_code lec;
          fs::create_hard_link(e.path(), dir / n, lec);
        }
    }
    fsync_dir(dir);
    if (error.empty()) result = k;
  }
  {
    std::lock_guard lk(m_);
    if (result) status_.kept.push_back(*result);
    if (!error.empty()) status_.last_error = "recording: keep: " + error;
    keep_results_.emplace_back(result, error);
  }
  const std::uint64_t one = 1;
  (void)::write(event_fd_, &one, sizeof one);
}

}  // namespace oegw::gateway::record
