// The black box's line formats (gateway/record/record_format.hpp,
// docs/guides/black-box.md#the-files): candump's log format for the frames, "(seconds.micros) @N
// TEXT" for the rest.
#include "gateway/record/record_format.hpp"

#include <gtest/gtest.h>

#include <limits>

namespace oegw::gateway::record {
namespace {

TEST(RecordFormat, FrameLinesAreCandumpLogLinesWithTheirDirection) {
  std::string out;
  append_frame_line(out, 1733407392123456, "can1", canopen::CanFrame(0x191, {0x01, 0x02}), Direction::Rx);
  append_frame_line(out, 5, "can0", canopen::CanFrame(0x705, {0x05}), Direction::Tx);
  canopen::CanFrame ext(0x1ABCDEF0, {});
  ext.extended = true;
  append_frame_line(out, 1000000, "down", ext, Direction::Tx);
  append_frame_line(out, 1000000, "up", canopen::CanFrame::remote(0x181, 4), Direction::Rx);
  EXPECT_EQ(out,
            "(1733407392.123456) can1 191#0102 R\n"
            "(0000000000.000005) can0 705#05 T\n"
            "(0000000001.000000) down 1ABCDEF0# T\n"
            "(0000000001.000000) up 181#R4 R\n");
}

// The time field at its edges: before the epoch (written as 0), past 10 digits of seconds (not
// padded further, not cut), and the digits of one second kept by the writer reused only for that
// second, also when time goes back.
TEST(RecordFormat, TheTimeFieldAtItsEdges) {
  std::string out;
  append_wall_time(out, -1);
  out += ' ';
  append_wall_time(out, std::numeric_limits<std::int64_t>::max());
  out += ' ';
  append_wall_time(out, 1733407392999999);
  out += ' ';
  append_wall_time(out, 1733407392000001);
  out += ' ';
  append_wall_time(out, 1733407391500000);
  out += ' ';
  append_event_prefix(out, 1733407392000000, 0);
  EXPECT_EQ(out,
            "(0000000000.000000) (9223372036854.775807) (1733407392.999999) (1733407392.000001) "
            "(1733407391.500000) (1733407392.000000) @0 ");
  for (const std::int64_t t : {std::int64_t{0}, std::int64_t{59}, std::int64_t{1733407392000001}}) {
    std::string line;
    append_wall_time(line, t);
    EXPECT_EQ(parse_wall_time(line), t) << line;
  }
}

TEST(RecordFormat, EveryFrameReadsBackAsWritten) {
  std::vector<canopen::CanFrame> frames{canopen::CanFrame(0x000, {0x01, 0x11}), canopen::CanFrame(0x7FF, {}),
                                        canopen::CanFrame(0x581, {1, 2, 3, 4, 5, 6, 7, 8}),
                                        canopen::CanFrame::remote(0x701, 0)};
  canopen::CanFrame ext(0x18FF0011, {0xAA});
  ext.extended = true;
  frames.push_back(ext);
  for (const auto& f : frames)
    for (const auto d : {Direction::Rx, Direction::Tx}) {
      std::string line;
      append_frame_line(line, 1733407392000001, "can1", f, d);
      std::string error;
      const auto back = parse_frame_line(line, error);
      ASSERT_TRUE(back) << line << ": " << error;
      EXPECT_EQ(back->wall_us, 1733407392000001);
      EXPECT_EQ(back->iface, "can1");
      EXPECT_EQ(back->frame, f) << line;
      EXPECT_EQ(back->frame.rtr, f.rtr);
      EXPECT_EQ(back->frame.extended, f.extended);
      EXPECT_EQ(back->direction, d);
    }
}

TEST(RecordFormat, APlainCandumpLogLineHasNoDirection) {
  std::string error;
  const auto f = parse_frame_line("(1436509052.249713) vcan0 044#2A366C2BBA", error);
  ASSERT_TRUE(f) << error;
  EXPECT_EQ(f->iface, "vcan0");
  EXPECT_EQ(f->frame, canopen::CanFrame(0x044, {0x2A, 0x36, 0x6C, 0x2B, 0xBA}));
  EXPECT_FALSE(f->direction);
}

TEST(RecordFormat, BrokenFrameLinesSayWhatIsWrong) {
  std::string error;
  EXPECT_FALSE(parse_frame_line("(1436509052.24971 vcan0 044#2A", error));
  EXPECT_FALSE(parse_frame_line("(1436509052.249713) vcan0 44#2A", error));
  EXPECT_NE(error.find("'44#2A' is no frame"), std::string::npos) << error;
  EXPECT_FALSE(parse_frame_line("(1436509052.249713) vcan0 044#2A3", error));
  EXPECT_FALSE(parse_frame_line("(1436509052.249713) vcan0 044#2A X", error));
  EXPECT_NE(error.find("expected R, T or nothing"), std::string::npos) << error;
  EXPECT_FALSE(parse_frame_line("(1436509052.249713) vcan0 044#112233445566778899", error));
  // A line cut short by a power failure.
  EXPECT_FALSE(parse_frame_line("(1436509052.249713) vca", error));
}

TEST(RecordFormat, EventLinesCarryTheFramesBeforeThem) {
  std::string out;
  append_event_prefix(out, 1733407392123456, 17);
  out += "fe joystick.1 valid x=12";
  std::string error;
  const auto e = parse_event_line(out, error);
  ASSERT_TRUE(e) << error;
  EXPECT_EQ(out, "(1733407392.123456) @17 fe joystick.1 valid x=12");
  EXPECT_EQ(e->wall_us, 1733407392123456);
  EXPECT_EQ(e->pos, 17u);
  EXPECT_EQ(e->text, "fe joystick.1 valid x=12");
  EXPECT_FALSE(parse_event_line("(1733407392.123456) 17 tick", error));
  EXPECT_FALSE(parse_event_line("(1733407392.123456) @x tick", error));
  EXPECT_FALSE(parse_event_line("(1733407392.123456) @3 ", error));
}

// A segment's state: its lines on one event line, with its length and CRC-32, so that a torn or
// damaged line is told from a state (the CRC as python3's zlib.crc32 gives it for that text).
TEST(RecordFormat, AStateLineReadsBackAndADamagedOneIsRefused) {
  const std::string state = "now 1500000\nsubdevices.0.why #6f6b\n";
  const std::string line = state_event(state);
  EXPECT_EQ(line, "state crc32=032EC1BC bytes=34 now 1500000;subdevices.0.why #6f6b");
  std::string error;
  EXPECT_EQ(parse_state_event(line, error), state) << error;
  std::string damaged = line;
  damaged[damaged.size() - 2] = 'c';
  EXPECT_FALSE(parse_state_event(damaged, error));
  EXPECT_EQ(error, "the state's CRC-32 differs from its line's: the line is damaged");
  EXPECT_FALSE(parse_state_event(line.substr(0, line.size() - 5), error));
  EXPECT_EQ(error, "the state holds 29 bytes, its line says 34");
  EXPECT_FALSE(parse_state_event(no_state_event("the run starts here"), error));
  EXPECT_EQ(error, "none (the run starts here)");
  EXPECT_FALSE(parse_state_event("state of mind", error));
  EXPECT_THROW((void)state_event("a 1;2\n"), std::logic_error);
}

}  // namespace
}  // namespace oegw::gateway::record
