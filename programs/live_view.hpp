// What `oegw demo` and `oegw sim` show: the live table of the FEs and sub-devices at the bottom
// of the terminal with the log above it, and the frames in candump's log format.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"
#include "gateway/gateway.hpp"
#include "rig/cab_rig.hpp"

namespace oegw::programs {

// One line per FE: "joystick.1  valid     x=+12000 y=-300 buttons=10000000"; "held" where an
// axis is valid but held at neutral until it has been seen at zero (the elobau zero-position rule).
[[nodiscard]] std::string fe_line(const gateway::Gateway& gw, mapping::FeId fe);

// "  sub-devices: a=operational b=starting ..." wrapped at `width` columns, continuation rows
// indented under the first name.
[[nodiscard]] std::vector<std::string> wrapped(const std::string& head, const std::vector<std::string>& items,
                                               std::size_t width);

// The table rows of `gw`: one per FE, then its sub-devices' states wrapped at `width`.
[[nodiscard]] std::vector<std::string> gateway_rows(const gateway::Gateway& gw, std::size_t width);

// `line` cut into rows of at most `width` columns at spaces, each row after the first indented
// under the text after the line's "[ 12.34 s] " stamp (or by two columns without one); a word
// longer than a row is cut. A terminal wraps a long log line mid-word, which reads as garbage.
[[nodiscard]] std::vector<std::string> wrap_words(const std::string& line, std::size_t width);

// The live table at the bottom of the terminal with the log above it (no curses). Every table row
// is cut to the terminal's width, so each takes exactly one row of the screen and "cursor up by
// the rows drawn" finds the table's top again at any size; a log line erases the table (cursor
// up, CSI J), is printed — wrapping as it likes, scrolling the screen — and the table is drawn
// again below it. So the screen holds one table, never copies of it. Without a terminal (a pipe,
// --fast, --frames) log lines and tables are printed one after the other.
class LiveScreen {
 public:
  explicit LiveScreen(bool tty) : tty_(tty) {}

  // The terminal's columns and rows (80x24 if it does not say).
  [[nodiscard]] std::pair<std::size_t, std::size_t> size() const;
  void log(const std::string& line);
  // Replaces the table; `keep`: leave it on the screen as it is, later output below it.
  void draw(std::vector<std::string> rows, bool keep);

 private:
  void erase();
  void paint();

  bool tty_;
  std::vector<std::string> rows_;
  std::size_t drawn_ = 0;
};

// A log line as the demo and the sim print it: "[ 12.34 s] text", the time since their start.
[[nodiscard]] std::string stamped(canopen::Duration since_start, const std::string& text);

// --frames: every frame of the rig's two buses printed as it passes, in candump_line()'s format
// ("up", "down"), timed from `t0`.
void print_frames_of(rig::CabRig& rig, canopen::TimePoint t0);

// candump's log format (candump -L), "(seconds.micros) interface id#data", which canplayer
// replays: `canplayer -I FILE vcan0=up vcan1=down`. The time counts from the program's start.
[[nodiscard]] std::string candump_line(canopen::Duration since_start, const char* interface,
                                       const canopen::CanFrame& f);

}  // namespace oegw::programs
