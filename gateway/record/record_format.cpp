#include "gateway/record/record_format.hpp"

#include <array>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <stdexcept>

#include <zlib.h>

namespace oegw::gateway::record {

namespace {

constexpr char kHex[] = "0123456789ABCDEF";

// The writer formats every record it writes: the helpers below fill a line on the stack and
// append it to the buffer once (a push_back per character cost more than the digits).
char* put_hex(char* p, std::uint32_t v, int digits) {
  for (int i = digits - 1; i >= 0; --i) *p++ = kHex[(v >> (4 * i)) & 0xF];
  return p;
}

char* put_decimal(char* p, std::uint64_t v, int min_digits) {
  char buf[20];  // 2^64 has 20 digits
  int n = 0;
  do {
    buf[n++] = static_cast<char>('0' + v % 10);
    v /= 10;
  } while (v != 0 || n < min_digits);
  while (n > 0) *p++ = buf[--n];
  return p;
}

// "(seconds.micros)": at most 1 + 20 + 1 + 6 + 1 characters.
constexpr std::size_t kWallTimeMax = 29;

// "00" .. "99": the microseconds two digits at a time.
constexpr auto kDigitPairs = [] {
  std::array<char, 200> t{};
  for (int i = 0; i < 100; ++i) {
    t[2 * i] = static_cast<char>('0' + i / 10);
    t[2 * i + 1] = static_cast<char>('0' + i % 10);
  }
  return t;
}();

char* put_wall_time(char* p, std::int64_t wall_us) {
  const std::uint64_t us = wall_us < 0 ? 0 : static_cast<std::uint64_t>(wall_us);
  const std::uint64_t sec = us / 1000000;
  auto frac = static_cast<std::uint32_t>(us % 1000000);
  // The lines of one second share its digits: the writer formats them once a second.
  thread_local std::uint64_t cached_sec = ~std::uint64_t{0};
  thread_local char cached[20];
  thread_local std::size_t cached_n = 0;
  if (sec != cached_sec) {
    cached_n = static_cast<std::size_t>(put_decimal(cached, sec, 10) - cached);  // candump pads to 10 digits
    cached_sec = sec;
  }
  *p++ = '(';
  std::memcpy(p, cached, cached_n);
  p += cached_n;
  *p++ = '.';
  for (int i = 4; i >= 0; i -= 2) {
    const std::uint32_t pair = frac % 100;
    frac /= 100;
    p[i] = kDigitPairs[2 * pair];
    p[i + 1] = kDigitPairs[2 * pair + 1];
  }
  p += 6;
  *p++ = ')';
  return p;
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

std::string_view trim_newline(std::string_view s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

}  // namespace

void append_wall_time(std::string& out, std::int64_t wall_us) {
  char line[kWallTimeMax];
  out.append(line, put_wall_time(line, wall_us));
}

void append_frame_line(std::string& out, std::int64_t wall_us, std::string_view iface, const canopen::CanFrame& f,
                       Direction d) {
  // The time, the frame ("1FFFFFFF#" and 16 digits at most) and the mark; the interface apart.
  char head[kWallTimeMax + 1];
  out.append(head, put_wall_time(head, wall_us));
  out.push_back(' ');
  out.append(iface);
  char tail[1 + 9 + 16 + 3];
  char* p = tail;
  *p++ = ' ';
  p = f.extended ? put_hex(p, f.id & 0x1FFFFFFF, 8) : put_hex(p, f.id & 0x7FF, 3);
  *p++ = '#';
  if (f.rtr) {
    *p++ = 'R';
    if (f.dlc != 0) *p++ = static_cast<char>('0' + f.dlc);
  } else {
    for (std::uint8_t i = 0; i < f.dlc && i < 8; ++i) p = put_hex(p, f.data[i], 2);
  }
  *p++ = ' ';
  *p++ = d == Direction::Rx ? 'R' : 'T';
  *p++ = '\n';
  out.append(tail, p);
}

void append_event_prefix(std::string& out, std::int64_t wall_us, std::uint64_t pos) {
  char line[kWallTimeMax + 2 + 20 + 1];
  char* p = put_wall_time(line, wall_us);
  *p++ = ' ';
  *p++ = '@';
  p = put_decimal(p, pos, 1);
  *p++ = ' ';
  out.append(line, p);
}

std::string segment_name(std::string_view file_name) {
  std::string_view stem;
  for (const std::string_view ext : {".events", ".log"})
    if (file_name.size() > ext.size() && file_name.substr(file_name.size() - ext.size()) == ext)
      stem = file_name.substr(0, file_name.size() - ext.size());
  const auto dash = stem.rfind('-');
  if (stem.empty() || dash == std::string_view::npos || dash == 0 || stem.size() - dash != 7) return {};
  for (std::size_t i = dash + 1; i < stem.size(); ++i)
    if (stem[i] < '0' || stem[i] > '9') return {};
  return std::string(stem);
}

std::string wall_text(std::int64_t wall_us, const char* format, bool utc) {
  const std::time_t s = static_cast<std::time_t>(wall_us / 1000000);
  std::tm tm{};
  if (utc) ::gmtime_r(&s, &tm);
  else ::localtime_r(&s, &tm);
  char buf[64];
  return std::string(buf, std::strftime(buf, sizeof buf, format, &tm));
}

std::optional<std::int64_t> parse_wall_time(std::string_view t) {
  if (t.size() < 4 || t.front() != '(' || t.back() != ')') return std::nullopt;
  t = t.substr(1, t.size() - 2);
  const auto dot = t.find('.');
  if (dot == std::string_view::npos || dot == 0) return std::nullopt;
  std::int64_t sec = 0, frac = 0;
  const auto s = t.substr(0, dot), f = t.substr(dot + 1);
  if (f.empty() || f.size() > 9) return std::nullopt;
  if (auto r = std::from_chars(s.data(), s.data() + s.size(), sec); r.ec != std::errc{} || r.ptr != s.data() + s.size())
    return std::nullopt;
  if (auto r = std::from_chars(f.data(), f.data() + f.size(), frac);
      r.ec != std::errc{} || r.ptr != f.data() + f.size())
    return std::nullopt;
  // Microseconds from however many fraction digits were written.
  std::size_t digits = f.size();
  while (digits < 6) {
    frac *= 10;
    ++digits;
  }
  while (digits > 6) {
    frac /= 10;
    --digits;
  }
  return sec * 1000000 + frac;
}

std::optional<canopen::CanFrame> parse_frame(std::string_view t) {
  const auto hash = t.find('#');
  if (hash != 3 && hash != 8) return std::nullopt;
  canopen::CanFrame f;
  f.extended = hash == 8;
  std::uint32_t id = 0;
  for (std::size_t i = 0; i < hash; ++i) {
    const int v = hex_value(t[i]);
    if (v < 0) return std::nullopt;
    id = id << 4 | static_cast<std::uint32_t>(v);
  }
  if ((f.extended && id > 0x1FFFFFFF) || (!f.extended && id > 0x7FF)) return std::nullopt;
  f.id = id;
  auto data = t.substr(hash + 1);
  if (!data.empty() && (data[0] == 'R' || data[0] == 'r')) {
    f.rtr = true;
    if (data.size() == 2 && data[1] >= '0' && data[1] <= '8') {
      f.dlc = static_cast<std::uint8_t>(data[1] - '0');
    } else if (data.size() != 1) {
      return std::nullopt;
    }
    return f;
  }
  if (data.size() % 2 != 0 || data.size() > 16) return std::nullopt;
  for (std::size_t i = 0; i < data.size(); i += 2) {
    const int hi = hex_value(data[i]), lo = hex_value(data[i + 1]);
    if (hi < 0 || lo < 0) return std::nullopt;
    f.data[i / 2] = static_cast<std::uint8_t>(hi << 4 | lo);
  }
  f.dlc = static_cast<std::uint8_t>(data.size() / 2);
  return f;
}

std::optional<FrameLine> parse_frame_line(std::string_view line, std::string& error) {
  line = trim_newline(line);
  // (time) iface frame [R|T]
  const auto sp1 = line.find(' ');
  if (sp1 == std::string_view::npos) {
    error = "expected (seconds.micros) IFACE ID#DATA";
    return std::nullopt;
  }
  FrameLine out;
  const auto t = parse_wall_time(line.substr(0, sp1));
  if (!t) {
    error = "expected a time (seconds.micros) first";
    return std::nullopt;
  }
  out.wall_us = *t;
  auto rest = line.substr(sp1 + 1);
  const auto sp2 = rest.find(' ');
  if (sp2 == std::string_view::npos || sp2 == 0) {
    error = "expected an interface and a frame after the time";
    return std::nullopt;
  }
  out.iface = std::string(rest.substr(0, sp2));
  rest = rest.substr(sp2 + 1);
  const auto sp3 = rest.find(' ');
  const auto frame_text = rest.substr(0, sp3);
  const auto f = parse_frame(frame_text);
  if (!f) {
    error = "'" + std::string(frame_text) + "' is no frame; expected ID#DATA (3 or 8 hex digits, up to 8 bytes)";
    return std::nullopt;
  }
  out.frame = *f;
  if (sp3 != std::string_view::npos) {
    const auto mark = rest.substr(sp3 + 1);
    if (mark == "R") out.direction = Direction::Rx;
    else if (mark == "T") out.direction = Direction::Tx;
    else {
      error = "'" + std::string(mark) + "' after the frame; expected R, T or nothing";
      return std::nullopt;
    }
  }
  return out;
}

std::optional<EventLine> parse_event_line(std::string_view line, std::string& error) {
  line = trim_newline(line);
  const auto sp1 = line.find(' ');
  const auto t = sp1 == std::string_view::npos ? std::nullopt : parse_wall_time(line.substr(0, sp1));
  if (!t) {
    error = "expected (seconds.micros) @N TEXT";
    return std::nullopt;
  }
  auto rest = line.substr(sp1 + 1);
  const auto sp2 = rest.find(' ');
  if (rest.empty() || rest[0] != '@' || sp2 == std::string_view::npos) {
    error = "expected @N (the frame lines before it) after the time";
    return std::nullopt;
  }
  EventLine out;
  out.wall_us = *t;
  const auto n = rest.substr(1, sp2 - 1);
  if (auto r = std::from_chars(n.data(), n.data() + n.size(), out.pos);
      r.ec != std::errc{} || r.ptr != n.data() + n.size()) {
    error = "'" + std::string(n) + "' after @ is no count";
    return std::nullopt;
  }
  out.text = std::string(rest.substr(sp2 + 1));
  if (out.text.empty()) {
    error = "no text after @N";
    return std::nullopt;
  }
  return out;
}

namespace {

std::uint32_t crc32_of(std::string_view s) {
  // zlib takes its length as uInt: a state is far below 4 GiB.
  return static_cast<std::uint32_t>(::crc32(0L, reinterpret_cast<const Bytef*>(s.data()), static_cast<uInt>(s.size())));
}

}  // namespace

std::string state_event(std::string_view state_text) {
  std::string joined(state_text);
  while (!joined.empty() && joined.back() == '\n') joined.pop_back();
  for (char& c : joined) {
    if (c == ';') throw std::logic_error("state_event: a state line holds ';'");
    if (c == '\n') c = ';';
  }
  char head[48];
  const int n = std::snprintf(head, sizeof head, "state crc32=%08X bytes=%zu ", crc32_of(joined), joined.size());
  return std::string(head, static_cast<std::size_t>(n)) + joined;
}

std::string no_state_event(std::string_view why) { return "state none (" + std::string(why) + ")"; }

std::optional<std::string> parse_state_event(std::string_view text, std::string& error) {
  constexpr std::string_view kNone = "state none ";
  if (text.substr(0, kNone.size()) == kNone) {
    error = "none " + std::string(text.substr(kNone.size()));
    return std::nullopt;
  }
  constexpr std::string_view kHead = "state crc32=";
  unsigned crc = 0;
  std::size_t bytes = 0;
  int used = 0;
  if (text.substr(0, kHead.size()) != kHead ||
      std::sscanf(std::string(text.substr(0, 64)).c_str(), "state crc32=%8X bytes=%zu %n", &crc, &bytes, &used) != 2 ||
      used == 0) {
    error = "no state line: expected state crc32=XXXXXXXX bytes=N TEXT or state none (WHY)";
    return std::nullopt;
  }
  const std::string_view joined = text.substr(static_cast<std::size_t>(used));
  if (joined.size() != bytes) {
    error = "the state holds " + std::to_string(joined.size()) + " bytes, its line says " + std::to_string(bytes);
    return std::nullopt;
  }
  if (crc32_of(joined) != crc) {
    error = "the state's CRC-32 differs from its line's: the line is damaged";
    return std::nullopt;
  }
  std::string out(joined);
  for (char& c : out)
    if (c == ';') c = '\n';
  out += '\n';
  return out;
}

}  // namespace oegw::gateway::record
