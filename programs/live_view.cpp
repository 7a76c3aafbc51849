// live_view.hpp: the table `oegw demo` and `oegw sim` draw, and their frame log.
#include "programs/live_view.hpp"

#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>

#include <fmt/format.h>

namespace oegw::programs {

using namespace gateway;  // the programs compose the daemon's library

using namespace canopen;
using namespace canopen::io;
namespace sd = oegw::subdevices;

std::string fe_line(const Gateway& gw, mapping::FeId fe) {
  static const char* const kStatus[] = {"valid", "ERROR", "n/a", "stale", "OFFLINE"};
  const auto fields = gw.fields(fe);
  const bool held = std::any_of(fields.begin(), fields.end(), [](const auto& f) { return f.interlocked; });
  const FeStatus status = gw.status(fe);
  std::string out = fmt::format("  {:<13} {:<8}", mapping::fe_name(fe),
                                held && status == FeStatus::Valid ? "held" : kStatus[static_cast<int>(status)]);
  std::string bits_name, bits;
  for (const auto& f : fields) {
    const auto bracket = f.name.find('[');
    if (bracket != std::string::npos) {
      const std::string base = f.name.substr(0, bracket);
      if (base != bits_name && !bits_name.empty()) out += fmt::format(" {}={}", bits_name, bits), bits.clear();
      bits_name = base;
      bits += f.value ? '1' : '0';
      continue;
    }
    out += fmt::format(" {}={:+6d}{}", f.name, f.value, f.interlocked ? "(held)" : "");
  }
  if (!bits_name.empty()) out += fmt::format(" {}={}", bits_name, bits);
  return out;
}

std::vector<std::string> wrapped(const std::string& head, const std::vector<std::string>& items, std::size_t width) {
  std::vector<std::string> rows{head};
  const std::string indent(head.size(), ' ');
  for (const auto& item : items) {
    if (rows.back().size() + 1 + item.size() > width && rows.back().size() > indent.size()) rows.push_back(indent);
    rows.back() += " " + item;
  }
  return rows;
}

std::vector<std::string> gateway_rows(const Gateway& gw, std::size_t width) {
  std::vector<std::string> lines;
  for (const auto& fe : gw.fes()) lines.push_back(fe_line(gw, fe));
  std::vector<std::string> nodes;
  for (const auto& n : gw.downstream().names())
    nodes.push_back(fmt::format("{}={}", n, sd::to_string(gw.downstream().state(n))));
  for (auto& r : wrapped("  sub-devices:", nodes, width)) lines.push_back(std::move(r));
  return lines;
}

// The live table (live_view.hpp): a log line erases it, is printed, and it is drawn again below.
std::pair<std::size_t, std::size_t> LiveScreen::size() const {
  winsize ws{};
  if (!tty_ || ::ioctl(STDOUT_FILENO, TIOCGWINSZ, &ws) != 0 || ws.ws_col == 0) return {80, 24};
  return {ws.ws_col, ws.ws_row == 0 ? 24 : ws.ws_row};
}

std::vector<std::string> wrap_words(const std::string& line, std::size_t width) {
  if (width < 8 || line.size() <= width) return {line};
  const auto stamp = line.find("] ");
  const std::size_t indent =
      line.starts_with("[") && stamp != std::string::npos && stamp + 2 <= width / 2 ? stamp + 2 : 2;
  std::vector<std::string> rows;
  std::size_t pos = 0;
  while (pos < line.size()) {
    const std::size_t lead = rows.empty() ? 0 : indent;
    const std::size_t room = width - lead;
    if (line.size() - pos <= room) {
      rows.push_back(std::string(lead, ' ') + line.substr(pos));
      break;
    }
    std::size_t cut = line.rfind(' ', pos + room);
    if (cut == std::string::npos || cut <= pos) cut = pos + room;  // one word longer than a row
    rows.push_back(std::string(lead, ' ') + line.substr(pos, cut - pos));
    pos = cut;
    while (pos < line.size() && line[pos] == ' ') ++pos;
  }
  return rows;
}

void LiveScreen::log(const std::string& line) {
  erase();
  if (tty_) {
    // One column spare, as the table's rows (paint()).
    const auto cols = size().first;
    for (const auto& row : wrap_words(line, cols > 1 ? cols - 1 : 1)) std::printf("%s\n", row.c_str());
  } else {
    std::printf("%s\n", line.c_str());
  }
  paint();
}

void LiveScreen::draw(std::vector<std::string> rows, bool keep) {
  erase();
  rows_ = std::move(rows);
  paint();
  if (keep || !tty_) {
    rows_.clear();
    drawn_ = 0;
  }
}

void LiveScreen::erase() {
  if (tty_ && drawn_ > 0) std::printf("\x1b[%zuA\r\x1b[J", drawn_);
  drawn_ = 0;
}

void LiveScreen::paint() {
  if (rows_.empty()) {
    std::fflush(stdout);
    return;
  }
  const auto [cols, lines] = size();
  // One column spare: a row of exactly `cols` leaves some terminals in their pending-wrap state.
  const std::size_t width = cols > 1 ? cols - 1 : 1;
  // At most the screen's height less one row, so the log keeps a line and the top stays found.
  const std::size_t max_rows = lines > 1 ? lines - 1 : 1;
  std::size_t n = 0;
  for (std::size_t i = 0; i < rows_.size() && n < max_rows; ++i, ++n) {
    std::string r = rows_[i];
    if (n + 1 == max_rows && i + 1 < rows_.size())
      r = fmt::format("  ... {} more rows (a taller terminal shows them)", rows_.size() - i);
    if (tty_ && r.size() > width) r = r.substr(0, width - 1) + "~";
    std::printf("%s\n", r.c_str());
  }
  drawn_ = tty_ ? n : 0;
  std::fflush(stdout);
}

std::string stamped(Duration since_start, const std::string& text) {
  return fmt::format("[{:6.2f} s] {}", std::chrono::duration<double>(since_start).count(), text);
}

void print_frames_of(rig::CabRig& rig, TimePoint t0) {
  for (auto [bus, name] : {std::pair{&rig.up(), "up"}, std::pair{&rig.down(), "down"}})
    bus->set_tap([&rig, t0, name](const BusRecord& r) {
      std::printf("%s\n", candump_line(rig.now() - t0, name, r.frame).c_str());
    });
}

std::string candump_line(Duration since_start, const char* interface, const CanFrame& f) {
  const auto us = since_start.count();
  return fmt::format("({:010}.{:06}) {} {}", us / 1'000'000, us % 1'000'000, interface, f.to_string());
}

}  // namespace oegw::programs
