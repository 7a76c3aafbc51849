// The control socket's protocol (docs/reference/control-protocol.md): request parsing, the answer's
// envelope, every error code, and the JSON text itself (escaping, numbers, bytes that are not
// UTF-8), read back by nlohmann's parser and checked as text.
#include "gateway/control/control_protocol.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>

using namespace oegw::gateway;
using namespace oegw::gateway::control;
using nlohmann::json;

namespace {

ControlProtocol protocol() {
  ControlProtocol p;
  p.add("status", [](const json&) { return json{{"status", json{{"n", 1}}}}; });
  p.add("echo", [](const json& r) { return json{{"said", r.value("text", "")}}; });
  p.add("broken", [](const json&) -> json { throw std::runtime_error("no dictionary"); });
  return p;
}

json answer(const std::string& line) {
  const std::string a = protocol().answer(line);
  EXPECT_EQ(a.find('\n'), std::string::npos) << "one line";
  return json::parse(a);
}

std::string error_code(const std::string& line) { return answer(line)["error"]["code"].get<std::string>(); }

TEST(ControlProtocol, ACommandIsAnsweredInTheEnvelope) {
  const json a = answer(R"({"command": "status"})");
  EXPECT_EQ(a["protocol"], 1);
  EXPECT_EQ(a["ok"], true);
  EXPECT_EQ(a["command"], "status");
  EXPECT_EQ(a["status"]["n"], 1);
  EXPECT_EQ(answer(R"({"protocol": 1, "command": "echo", "text": "hi"})")["said"], "hi");
}

TEST(ControlProtocol, EveryMalformedRequestGetsItsErrorCode) {
  EXPECT_EQ(error_code("status"), "bad_request") << "not JSON";
  EXPECT_EQ(error_code("[1, 2]"), "bad_request") << "not an object";
  EXPECT_EQ(error_code("{}"), "bad_request") << "no command";
  EXPECT_EQ(error_code(R"({"command": 7})"), "bad_request");
  EXPECT_EQ(error_code(R"({"command": "status", "protocol": "1"})"), "bad_request");
  EXPECT_EQ(error_code(R"({"command": "status", "protocol": 2})"), "unsupported_protocol");
  const json unknown = answer(R"({"command": "sdo_read"})");
  EXPECT_EQ(unknown["ok"], false);
  EXPECT_EQ(unknown["protocol"], 1);
  EXPECT_EQ(unknown["error"]["code"], "unknown_command");
  EXPECT_EQ(unknown["error"]["message"], "no command 'sdo_read'; this gateway has: broken, echo, status");
  const json broken = answer(R"({"command": "broken"})");
  EXPECT_EQ(broken["error"]["code"], "failed");
  EXPECT_EQ(broken["error"]["message"], "broken: no dictionary");
}

TEST(ControlProtocol, TheJsonTextEscapesAndKeepsNumbersExact) {
  const json j{{"name", "a \"quoted\"\\ line\nand\ttab\x01"},
               {"u64", std::numeric_limits<std::uint64_t>::max()},
               {"i64", std::numeric_limits<std::int64_t>::min()},
               {"none", nullptr}};
  const std::string text = json_line(j);
  EXPECT_EQ(text, R"({"i64":-9223372036854775808,"name":"a \"quoted\"\\ line\nand\ttab\u0001","none":null,)"
                  R"("u64":18446744073709551615})");
  const json back = json::parse(text);
  EXPECT_EQ(back["u64"].get<std::uint64_t>(), std::numeric_limits<std::uint64_t>::max());
  EXPECT_EQ(back["name"], j["name"]);
}

TEST(ControlProtocol, BytesThatAreNotUtf8BecomeReplacementCharactersNotAnException) {
  // A device's 1008h is its own bytes: a Latin-1 "é" must not end the gateway's answer.
  const std::string text = json_line(json{{"device_name", std::string("caf\xE9")}});
  EXPECT_EQ(text, "{\"device_name\":\"caf\xEF\xBF\xBD\"}");
  EXPECT_EQ(json::parse(text)["device_name"], "caf\xEF\xBF\xBD");
}

}  // namespace

namespace {

// `oegw ctl`'s SDO commands answer later (ControlProtocol::add_async): the envelope is the same,
// the answer comes once however often the command calls back, and a command that throws after
// answering does not answer twice. The caller that needs the line at once (answer(line)) gets
// `failed`, and the later call-back writes nowhere it should not.
TEST(ControlProtocol, AnAsyncCommandAnswersOnceInTheEnvelope) {
  ControlProtocol p;
  ControlProtocol::Done later;
  p.add_async("slow", [&later](const json&, ControlProtocol::Done done) { later = std::move(done); });
  p.add_async("twice", [](const json&, ControlProtocol::Done done) {
    done(json{{"n", 1}});
    done(json{{"n", 2}});
    throw std::runtime_error("after the answer");
  });
  std::vector<std::string> got;
  p.answer(R"({"command": "slow"})", [&got](std::string a) { got.push_back(std::move(a)); });
  EXPECT_TRUE(got.empty());
  later(json{{"abort", 0}});
  ASSERT_EQ(got.size(), 1u);
  const json a = json::parse(got[0]);
  EXPECT_EQ(a["ok"], true);
  EXPECT_EQ(a["command"], "slow");
  EXPECT_EQ(a["abort"], 0);
  p.answer(R"({"command": "twice"})", [&got](std::string s) { got.push_back(std::move(s)); });
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(json::parse(got[1])["n"], 1);
  const json now = json::parse(p.answer(R"({"command": "slow"})"));
  EXPECT_EQ(now["error"]["code"], "failed");
  later(json{{"abort", 0}});  // after answer(line) returned: harmless
}

}  // namespace
