// The demo's and the sim's log lines on a terminal (programs/live_view.hpp): cut at spaces, never
// mid-word, continuation rows under the text after the time stamp.
#include "programs/live_view.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace oegw::gateway {
namespace {

using ::testing::ElementsAre;
using ::testing::SizeIs;

TEST(WrapWords, AShortLineIsOneRow) {
  EXPECT_THAT(programs::wrap_words("[  1.00 s] ok", 79), ElementsAre("[  1.00 s] ok"));
}

TEST(WrapWords, ALongLineBreaksAtSpacesUnderTheStampsText) {
  const std::string line =
      "[ 10.08 s] gateway: seat_knob: EMCY 9090h novotechnik 9090h/1/0 (Warn): work area state changed, byte 7 = 05h";
  const auto rows = programs::wrap_words(line, 79);
  EXPECT_THAT(rows, ElementsAre("[ 10.08 s] gateway: seat_knob: EMCY 9090h novotechnik 9090h/1/0 (Warn): work",
                                "           area state changed, byte 7 = 05h"));
}

TEST(WrapWords, EveryRowFitsAndNoWordIsCut) {
  std::string line = "[  0.00 s]";
  for (int i = 0; i < 60; ++i) line += " word" + std::to_string(i);
  const auto rows = programs::wrap_words(line, 40);
  std::string joined;
  for (const auto& r : rows) {
    EXPECT_LE(r.size(), 40u) << r;
    joined += (joined.empty() ? "" : " ") + r.substr(r.find_first_not_of(' '));
  }
  EXPECT_EQ(joined, line);  // the same words in the same order: none was cut
}

TEST(WrapWords, AWordLongerThanARowIsCutRatherThanOverflowing) {
  const auto rows = programs::wrap_words("[  0.00 s] " + std::string(50, 'x'), 30);
  std::string word;
  for (const auto& r : rows) {
    EXPECT_LE(r.size(), 30u) << r;
    if (r != rows.front()) word += r.substr(r.find_first_not_of(' '));
  }
  EXPECT_EQ(rows.front(), "[  0.00 s]");  // the word starts on a row of its own, then is cut
  EXPECT_EQ(word, std::string(50, 'x'));
  EXPECT_THAT(rows, SizeIs(4));
}

TEST(WrapWords, WithoutAStampContinuationRowsAreIndentedByTwo) {
  EXPECT_THAT(programs::wrap_words("aaaa bbbb cccc dddd eeee", 10),
              ElementsAre("aaaa bbbb", "  cccc", "  dddd", "  eeee"));
}

}  // namespace
}  // namespace oegw::gateway
