#include "canopen/state.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

using namespace oegw::canopen;
using namespace std::chrono_literals;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;

namespace {

enum class Colour : std::uint8_t { Red = 1, Green = 7 };

TEST(State, WhatIsWrittenReadsBackUnderItsScopes) {
  StateWriter w;
  w.put("count", 42);
  {
    const StateWriter::Scope a(w, "hb");
    w.put("last", TimePoint{1250ms});
    w.put("gap", Duration{-5us});
    {
      const StateWriter::Scope b(w, "consumer");
      w.put("colour", Colour::Green);
      w.put("on", true);
    }
    w.put("none", std::optional<TimePoint>{});
    w.put("some", std::optional<TimePoint>{TimePoint{3s}});
  }
  w.put_bytes("od.1017.00", std::vector<std::uint8_t>{0xE8, 0x03});
  w.put("big", std::uint64_t{0xFFFF'FFFF'FFFF'FFFFu});
  w.put("frame", CanFrame{0x081, {0x00, 0x81, 0x11}});
  EXPECT_EQ(w.text().substr(0, 38), "count 42\nhb.last 1250000\nhb.gap -5\nhb.");

  const StateReader r = StateReader::parse(w.text());
  EXPECT_EQ(r.integer("count"), 42);
  const StateReader hb = r.in("hb");
  EXPECT_EQ(hb.time("last"), TimePoint{1250ms});
  EXPECT_EQ(hb.duration("gap"), Duration{-5us});
  EXPECT_EQ(hb.in("consumer").get<Colour>("colour"), Colour::Green);
  EXPECT_TRUE(hb.in("consumer").get<bool>("on"));
  EXPECT_EQ(hb.optional_time("none"), std::nullopt);
  EXPECT_FALSE(hb.has("none"));
  EXPECT_EQ(hb.optional_time("some"), TimePoint{3s});
  EXPECT_THAT(r.bytes("od.1017.00"), ElementsAre(0xE8, 0x03));
  EXPECT_EQ(r.get<std::uint64_t>("big"), 0xFFFF'FFFF'FFFF'FFFFu);
  EXPECT_EQ(r.frame("frame"), (CanFrame{0x081, {0x00, 0x81, 0x11}}));
  EXPECT_THAT(r.unread(), IsEmpty());
}

TEST(State, RemoteAndExtendedFramesReadBack) {
  StateWriter w;
  CanFrame ext{0x1ABCDEF0, {0x01}};
  ext.extended = true;
  w.put("a", CanFrame::remote(0x701, 1));
  w.put("b", ext);
  const StateReader r = StateReader::parse(w.text());
  EXPECT_EQ(r.frame("a"), CanFrame::remote(0x701, 1));
  EXPECT_EQ(r.frame("b"), ext);
}

TEST(State, KeysNeverReadAreListed) {
  const StateReader r = StateReader::parse("a 1\nb.c 2\nb.d 3\n");
  (void)r.in("b").integer("c");
  EXPECT_THAT(r.unread(), ElementsAre("a", "b.d"));
}

std::string error_of(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const StateError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(State, BadTextAndBadValuesAreRefusedNamingTheLineOrKey) {
  EXPECT_EQ(error_of([] { (void)StateReader::parse("a 1\nb\n"); }), "state line 2: 'b' has no value");
  EXPECT_EQ(error_of([] { (void)StateReader::parse("A 1\n"); }), "state line 1: bad key 'A'");
  EXPECT_EQ(error_of([] { (void)StateReader::parse("a 1\nb 2\na 2\n"); }), "state line 3: key 'a' appears twice");
  EXPECT_EQ(error_of([] { (void)StateReader::parse("a..b 1\n"); }), "state line 1: bad key 'a..b'");
  const StateReader r = StateReader::parse("n 300\nx 1x\nb #0g\nodd #123\nneg -1\nf.id 2048\nf.extended 0\n");
  EXPECT_EQ(error_of([&] { (void)r.get<std::uint8_t>("n"); }), "state: 'n' = 300 is outside 0..255");
  EXPECT_EQ(error_of([&] { (void)r.integer("x"); }), "state: 'x' is not an integer: '1x'");
  EXPECT_THAT(error_of([&] { (void)r.bytes("b"); }), HasSubstr("'b' is not '#' and hex bytes"));
  EXPECT_THAT(error_of([&] { (void)r.bytes("odd"); }), HasSubstr("'odd' is not '#' and hex bytes"));
  EXPECT_EQ(error_of([&] { (void)r.get<bool>("neg"); }), "state: 'neg' = -1 is outside 0..1");
  EXPECT_EQ(error_of([&] { (void)r.in("hb").integer("last"); }), "state: 'hb.last' is missing");
  EXPECT_EQ(error_of([&] { (void)r.frame("f"); }), "state: 'f.id' is too large");
  const StateReader ids = StateReader::parse("none 0\nbig 128\nunset 255\n");
  EXPECT_EQ(error_of([&] { (void)ids.node_id("none"); }), "state: 'none' is no node-ID");
  EXPECT_EQ(error_of([&] { (void)ids.node_id("big"); }), "state: 'big' is no node-ID");
  EXPECT_TRUE(ids.node_id("unset").unconfigured()) << "CiA 305: FFh, not configured";
  const StateReader frames = StateReader::parse(
      "d.id 1\nd.rtr 0\nd.extended 0\nd.dlc 2\nd.data #01\n"
      "r.id 1\nr.rtr 1\nr.extended 0\nr.dlc 2\nr.data #0102\n");
  EXPECT_EQ(error_of([&] { (void)frames.frame("d"); }), "state: 'd.data' is not dlc bytes long");
  EXPECT_EQ(error_of([&] { (void)frames.frame("r"); }), "state: 'r.data' is not empty in a remote frame");
}

TEST(State, ChildrenAreTheDistinctNamesBelowAScope) {
  const StateReader r = StateReader::parse("tpdo.1.a 1\ntpdo.1.b 2\ntpdo.12.a 3\ntpdox 4\nrpdo.2.a 5\n");
  EXPECT_THAT(r.in("tpdo").children(), ElementsAre("1", "12"));
  EXPECT_THAT(r.in("none").children(), IsEmpty());
  EXPECT_THROW((void)r.in(""), std::invalid_argument);
}

TEST(State, AListReadsBackInOrderAndACountAboveItsBoundIsRefused) {
  StateWriter w;
  const std::vector<int> items{5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
  w.put_list("q", items.size(), [&](std::size_t i) { w.put("v", items[i]); });
  const StateReader r = StateReader::parse(w.text());
  std::vector<int> back;
  r.read_list("q", 16, [&](const StateReader& item) { back.push_back(item.get<int>("v")); });
  EXPECT_EQ(back, items) << "item 10 comes after item 9, not after item 1";
  EXPECT_EQ(error_of([&] { r.read_list("q", 4, [](const StateReader&) {}); }), "state: 'q.count' = 11 is above 4");
}

TEST(State, AWriterRefusesAKeyTheReaderCouldNotRead) {
  StateWriter w;
  EXPECT_THROW(w.put("Bad Key", 1), std::invalid_argument);
  EXPECT_THROW(StateWriter::Scope(w, ""), std::invalid_argument);
}

}  // namespace
