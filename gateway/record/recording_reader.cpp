#include "gateway/record/recording_reader.hpp"

#include <algorithm>
#include <fstream>
#include <functional>
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
  problems.push_back(where() + (last ? ": torn last line, skipped (the recording was cut mid-write): "
                                   : ": bad line, skipped: ") +
                     (parsed ? std::string("no newline at its end") : error));
  return true;
}

struct Lines {
  std::vector<std::string> lines;
  bool last_unterminated = false;
};

std::optional<Lines> read_lines(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) return std::nullopt;
  Lines out;
  std::string line;
  while (std::getline(in, line)) out.lines.push_back(line);
  // getline drops the last newline: a file not ending in one has a line cut short.
  in.clear();
  in.seekg(0, std::ios::end);
  const auto size = static_cast<std::streamoff>(in.tellg());
  if (size > 0) {
    in.seekg(size - 1);
    char c = 0;
    in.get(c);
    out.last_unterminated = c != '\n';
  }
  return out;
}

}  // namespace

std::string Entry::where() const { return file == nullptr ? std::string("?") : fmt::format("{}:{}", file->string(), line); }

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
      error = where.string() + ": no recording in it (expected <run>-<seq>.events and .log files, docs/guides/black-box.md#the-files"
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

SegmentRead read_segment(const Segment& s) {
  SegmentRead out;
  std::vector<Entry> frames, events;
  // The events first: the segment line gives the offset and the interfaces.
  if (!s.events.empty()) {
    const auto lines = read_lines(s.events);
    if (!lines) {
      out.problems.push_back(s.events.string() + ": cannot be read");
    } else {
      for (std::size_t i = 0; i < lines->lines.size(); ++i) {
        const std::string& l = lines->lines[i];
        if (l.empty() || l[0] == '#') continue;
        std::string error;
        auto e = parse_event_line(l, error);
        const auto where = [&] { return fmt::format("{}:{}", s.events.string(), i + 1); };
        if (unreadable(out.problems, where, e.has_value(), i + 1 == lines->lines.size(), lines->last_unterminated,
                       error))
          continue;
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
        en.frame.dlc = 0;
        en.text = std::move(e->text);
        en.file = &s.events;
        en.line = i + 1;
        // The pos rides in frame.id until the merge below.
        en.frame.id = static_cast<std::uint32_t>(std::min<std::uint64_t>(e->pos, 0xFFFFFFFFu));
        events.push_back(std::move(en));
      }
    }
  }
  if (!s.log.empty()) {
    const auto lines = read_lines(s.log);
    if (!lines) {
      out.problems.push_back(s.log.string() + ": cannot be read");
    } else {
      std::size_t others = 0;
      std::string first_other;
      for (std::size_t i = 0; i < lines->lines.size(); ++i) {
        const std::string& l = lines->lines[i];
        if (l.empty() || l[0] == '#') continue;
        const auto where = [&] { return fmt::format("{}:{}", s.log.string(), i + 1); };
        // A plain log may hold other text (`oegw demo --frames` prints its steps between the
        // frames): only lines that start as candump's do are frames.
        if (s.events.empty() && l[0] != '(') {
          if (others++ == 0) first_other = where();
          continue;
        }
        std::string error;
        auto f = parse_frame_line(l, error);
        if (unreadable(out.problems, where, f.has_value(), i + 1 == lines->lines.size(), lines->last_unterminated,
                       error))
          continue;
        Entry en;
        en.kind = Entry::Kind::Frame;
        en.wall_us = f->wall_us;
        en.iface = std::move(f->iface);
        en.direction = f->direction;
        en.frame = f->frame;
        en.file = &s.log;
        en.line = i + 1;
        frames.push_back(std::move(en));
      }
      if (others != 0)
        out.problems.push_back(fmt::format("{} line(s) that are no candump frames skipped (the first: {})", others,
                                           first_other));
    }
  }
  for (auto& e : frames) e.t = canopen::TimePoint{canopen::Duration{e.wall_us - out.offset_us}};
  for (auto& e : events) e.t = canopen::TimePoint{canopen::Duration{e.wall_us - out.offset_us}};
  // Merge: an event @N comes before frame line N (0-based) of the segment.
  out.entries.reserve(frames.size() + events.size());
  std::size_t ei = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    while (ei < events.size() && events[ei].frame.id <= k) out.entries.push_back(std::move(events[ei++]));
    out.entries.push_back(std::move(frames[k]));
  }
  while (ei < events.size()) out.entries.push_back(std::move(events[ei++]));
  for (auto& e : out.entries)
    if (e.kind == Entry::Kind::Event) e.frame = canopen::CanFrame{};
  return out;
}

}  // namespace oegw::gateway::record
