// Reading an MCB-402's button wiring off the board (the commissioning choice `button_bits`,
// mcb402.hpp): document 003's table ("Bit of cc 7 6 5 4 3 2 1 0 / N° BP 6 7 5 4 3 2 1", [MCB §4])
// has seven entries under eight columns and permits two readings, so the order is found on the
// board itself. ButtonBitsFinder watches the board's TPDO1 (180h + node-ID, byte 2 = 6000h:03,
// "when pressed, the corresponding bit is set to 1"), asks the user to press and hold BP1..BP7 in
// turn, takes the one bit of byte 2 each press sets and, when all seven are known, gives the
// `button_bits` line for the mapping file. Sans I/O (frames and time in, frames and prompts out):
// `oegw signals mcb402 --find-button-bits` runs it on a CAN interface (cli/button_bits_command.hpp).
//
// The board: if no TPDO1 is heard within `start_after` (a board alone on the bench stays
// pre-operational), the finder sends NMT start node ([MCB §4] "Write on bus: 000 01 03") once. A
// running gateway has started it already and its TPDO1 flows (on change, and on its event timer).
// "Released" is byte 2 of the first TPDO1 heard before the first prompt, or 00h ([MCB §4] "183 00 00
// cc": the bits are set only while pressed) when none comes; a press is a change of exactly one bit
// against it. Two bits at once, or a bit another button already set, is said and that button asked
// again; no press within `step_timeout` ends the search.
#pragma once

#include <chrono>
#include <functional>
#include <optional>
#include <string>

#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"
#include "subdevices/mcb402.hpp"

namespace oegw::subdevices {

class ButtonBitsFinder {
 public:
  struct Options {
    canopen::NodeId node{0x03};
    canopen::Duration start_after = std::chrono::seconds(1);    // no TPDO1 by then: NMT start (0: never)
    canopen::Duration step_timeout = std::chrono::seconds(60);  // per button
  };
  // `send`: frames for the bus (the NMT start); `say`: one line for the user.
  ButtonBitsFinder(Options options, canopen::FrameSink send, std::function<void(const std::string&)> say);

  void start(canopen::TimePoint now);
  bool on_frame(const canopen::CanFrame& frame, canopen::TimePoint now);
  void advance(canopen::TimePoint now);
  [[nodiscard]] std::optional<canopen::TimePoint> next_deadline() const;

  [[nodiscard]] bool done() const { return state_ == State::Done || state_ == State::Failed; }
  [[nodiscard]] const std::optional<mcb402::ButtonBits>& result() const { return result_; }
  [[nodiscard]] const std::string& error() const { return error_; }
  // Which button is asked for now (1..7), 0 when none.
  [[nodiscard]] std::size_t asking() const {
    return state_ == State::Pressing || state_ == State::Releasing ? button_ : 0;
  }

  // "button_bits: [1, 2, 3, 4, 5, 7, 6]" and "button_bits=1/2/3/4/5/7/6".
  [[nodiscard]] static std::string yaml_line(const mcb402::ButtonBits& bits);
  [[nodiscard]] static std::string command_line_option(const mcb402::ButtonBits& bits);

 private:
  enum class State : std::uint8_t { Idle, Listening, Started, Pressing, Releasing, Done, Failed };
  void ask(canopen::TimePoint now);
  void fail(const std::string& why);

  Options options_;
  canopen::FrameSink send_;
  std::function<void(const std::string&)> say_;
  State state_ = State::Idle;
  std::size_t button_ = 0;  // 1..7
  std::uint8_t released_ = 0x00;
  unsigned used_ = 0;  // bits taken by earlier buttons
  mcb402::ButtonBits bits_{};
  std::optional<mcb402::ButtonBits> result_;
  std::string error_;
  std::optional<canopen::TimePoint> deadline_;
};

}  // namespace oegw::subdevices
