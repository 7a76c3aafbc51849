#include "gateway/record/recording_reader.hpp"

#include <algorithm>
#include <fstream>
#include <functional>
#include <limits>
#include <map>

#include <fmt/format.h>

namespace oegw::gateway::record {

namespace fs = std::filesystem;

namespace {

std::string segment_of(const fs::path& p) { return segment_name(p.filename().string()); }

void add_run_files(Run& r, const fs::path& dir) {
  std::error_code ec;
  const auto at = [&](const char* suffix) {
    const fs::path p = dir / (r.name + suffix);
    return fs::exists(p, ec) ? p : fs::path{};
  };
  r.mapping_copy = at(".mapping.yaml");
  r.store_copy = at(".store");
  r.lss_copy = at(".store.lss");
}

// A line that did not parse, or the last one without its newline (cut mid-write), as a problem:
// true when the line is to be skipped.
bool unreadable(std::vector<std::string>& problems, const std::function<std::string()>& where, bool parsed, bool last,
                bool unterminated, const std::string& error) {
  if (parsed && !(last && unterminated)) return false;
  problems.push_back(
      where() + (last ? ": torn last line, skipped (the recording was cut mid-write): " : ": bad line, skipped: ") +
      (parsed ? std::string("no newline at its end") : error));
  return true;
}

// Calls `fn(line, number, last, unterminated)` for each line of `p` as it is read (a replay reads
// millions of lines: none is kept once parsed); false when the file cannot be opened. `last`: no
// line follows; `unterminated`: the line ends the file without its newline (cut mid-write).
bool for_each_line(const fs::path& p, const std::function<void(const std::string&, std::size_t, bool, bool)>& fn) {
  std::ifstream in(p, std::ios::binary);
  if (!in) return false;
  std::string line;
  std::size_t n = 0;
  while (std::getline(in, line)) {
    const bool unterminated = in.eof();  // getline stopped at the end of the file, not at a '\n'
    const bool last = unterminated || in.peek() == std::ifstream::traits_type::eof();
    fn(line, ++n, last, unterminated);
  }
  return true;
}

}  // namespace

std::string Entry::where() const {
  return file == nullptr ? std::string("?") : fmt::format("{}:{}", file->string(), line);
}

std::string Entry::text_line() const {
  if (kind == Kind::Event) return text;
  return fmt::format("{} {} {}", direction.value_or(Direction::Rx) == Direction::Rx ? 'R' : 'T', iface,
                     frame.to_string());
}

std::optional<std::vector<Run>> find_runs(const fs::path& where, std::string& error) {
  std::error_code ec;
  if (!fs::exists(where, ec)) {
    error = where.string() + ": no such file or folder";
    return std::nullopt;
  }
  std::vector<Run> runs;
  if (fs::is_directory(where, ec)) {
    std::map<std::string, std::map<std::string, Segment>> by_run;
    for (const auto& e : fs::directory_iterator(where, ec)) {
      const std::string seg = segment_of(e.path());
      if (seg.empty()) continue;
      Segment& s = by_run[seg.substr(0, seg.rfind('-'))][seg];
      s.name = seg;
      (e.path().extension() == ".log" ? s.log : s.events) = e.path();
    }
    for (auto& [name, segs] : by_run) {
      Run r;
      r.name = name;
      for (auto& [n, s] : segs)
        if (!s.events.empty()) r.segments.push_back(s);  // a .log without its .events is not ours
      if (r.segments.empty()) continue;
      add_run_files(r, where);
      runs.push_back(std::move(r));
    }
    if (runs.empty()) {
      error = where.string() +
              ": no recording in it (expected <run>-<seq>.events and .log files, docs/guides/black-box.md#the-files"
              ")";
      return std::nullopt;
    }
    return runs;
  }
  // One file: a segment (with its sibling) or a plain candump log.
  const std::string seg = segment_of(where);
  const fs::path events = fs::path(where).replace_extension(".events"), log = fs::path(where).replace_extension(".log");
  if (!seg.empty() && fs::exists(events, ec)) {
    Run r;
    r.name = seg.substr(0, seg.rfind('-'));
    r.segments.push_back(Segment{fs::exists(log, ec) ? log : fs::path{}, events, seg});
    add_run_files(r, where.parent_path());
    runs.push_back(std::move(r));
    return runs;
  }
  Run r;
  r.name = where.filename().string();
  r.segments.push_back(Segment{where, {}, r.name});
  runs.push_back(std::move(r));
  return runs;
}

SegmentReader::SegmentReader(const Segment& s) : s_(&s) {
  SegmentRead& out = head_;
  std::vector<Entry>& events = events_;
  // The events first: the segment line gives the offset and the interfaces.
  if (!s.events.empty()) {
    const bool read = for_each_line(s.events, [&](const std::string& l, std::size_t n, bool last, bool unterminated) {
      if (l.empty() || l[0] == '#') return;
      std::string error;
      auto e = parse_event_line(l, error);
      const auto where = [&] { return fmt::format("{}:{}", s.events.string(), n); };
      if (unreadable(out.problems, where, e.has_value(), last, unterminated, error)) return;
      if (e->text.rfind("segment ", 0) == 0) {
        const auto field = [&](std::string_view key) -> std::string {
          const std::string k = " " + std::string(key) + "=";
          const auto p = e->text.find(k);
          if (p == std::string::npos) return {};
          const auto end = e->text.find(' ', p + k.size());
          return e->text.substr(p + k.size(), end == std::string::npos ? std::string::npos : end - p - k.size());
        };
        out.up_iface = field("up");
        out.down_iface = field("down");
        try {
          out.offset_us = std::stoll(field("offset_us"));
        } catch (const std::exception&) {
          out.problems.push_back(where() + ": segment line without offset_us");
        }
      }
      Entry en;
      en.kind = Entry::Kind::Event;
      en.wall_us = e->wall_us;
      en.text = std::move(e->text);
      en.file = &s.events;
      en.line = n;
      // The pos rides in frame.id until the merge below.
      en.frame.id = static_cast<std::uint32_t>(std::min<std::uint64_t>(e->pos, 0xFFFFFFFFu));
      events.push_back(std::move(en));
    });
    if (!read) out.problems.push_back(s.events.string() + ": cannot be read");
  }
}

std::optional<std::int64_t> SegmentReader::first_wall_us() const {
  if (!events_.empty() && events_.front().frame.id == 0) return events_.front().wall_us;  // an event @0
  std::ifstream in(s_->log, std::ios::binary);
  std::string line;
  std::string error;
  while (std::getline(in, line)) {
    // As each() reads them: comments are skipped, and a plain log's other text is not a frame.
    if (line.empty() || line[0] == '#' || (s_->events.empty() && line[0] != '(')) continue;
    if (const auto f = parse_frame_line(line, error)) return f->wall_us;
  }
  if (!events_.empty()) return events_.front().wall_us;
  return std::nullopt;
}

void SegmentReader::each(const std::function<void(Entry&)>& fn) {
  const Segment& s = *s_;
  SegmentRead& out = head_;
  std::vector<Entry>& events = events_;
  const auto at = [&](std::int64_t wall_us) { return canopen::TimePoint{canopen::Duration{wall_us - out.offset_us}}; };
  // Merged as the frames are read: an event @N comes before frame line N (0-based) of the segment.
  std::size_t ei = 0;
  std::size_t frames = 0;
  const auto events_before = [&](std::size_t k) {
    for (; ei < events.size() && events[ei].frame.id <= k; ++ei) {
      Entry& e = events[ei];
      e.t = at(e.wall_us);
      e.frame = canopen::CanFrame{};
      fn(e);
    }
  };
  if (!s.log.empty()) {
    std::size_t others = 0;
    std::string first_other;
    const bool read = for_each_line(s.log, [&](const std::string& l, std::size_t n, bool last, bool unterminated) {
      if (l.empty() || l[0] == '#') return;
      const auto where = [&] { return fmt::format("{}:{}", s.log.string(), n); };
      // A plain log may hold other text (`oegw demo --frames` prints its steps between the
      // frames): only lines that start as candump's do are frames.
      if (s.events.empty() && l[0] != '(') {
        if (others++ == 0) first_other = where();
        return;
      }
      std::string error;
      auto f = parse_frame_line(l, error);
      if (unreadable(out.problems, where, f.has_value(), last, unterminated, error)) return;
      events_before(frames++);
      Entry en;
      en.kind = Entry::Kind::Frame;
      en.wall_us = f->wall_us;
      en.t = at(f->wall_us);
      en.iface = std::move(f->iface);
      en.direction = f->direction;
      en.frame = f->frame;
      en.file = &s.log;
      en.line = n;
      fn(en);
    });
    if (!read) out.problems.push_back(s.log.string() + ": cannot be read");
    if (others != 0)
      out.problems.push_back(
          fmt::format("{} line(s) that are no candump frames skipped (the first: {})", others, first_other));
  }
  events_before(std::numeric_limits<std::size_t>::max());
  events_.clear();
}

SegmentRead read_segment(const Segment& s) {
  SegmentReader reader(s);
  std::vector<Entry> entries;
  reader.each([&](Entry& e) { entries.push_back(std::move(e)); });
  SegmentRead out = reader.head();
  out.entries = std::move(entries);
  return out;
}

}  // namespace oegw::gateway::record
