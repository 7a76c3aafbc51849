// The per-driver option tables (subdevices/driver_options.hpp): the factories parse by them and
// `oegw signals` lists them, so what the listing says must be what a factory does. These tests
// hold every table to its factory: each Integer range's edges and the values just outside, each
// Choice and one value that is none of them, each default, the unknown-option refusal's list.
#include "subdevices/driver_options.hpp"

#include <gtest/gtest.h>

#include <string>

#include "subdevices/elobau_mfg.hpp"
#include "subdevices/mcb402.hpp"
#include "subdevices/novotechnik_406.hpp"

namespace oegw::subdevices {
namespace {

constexpr NodeId kNode{0x11};

// The options that make `info`'s driver buildable besides `extra` (the listing values of its
// required options), as `oegw signals` builds it; the EDS of the demo pedal for cia401.
DriverOptions with_required(const DriverInfo& info, std::vector<std::pair<std::string, std::string>> extra) {
  DriverOptions o;
  for (const OptionSpec& s : info.options) {
    if (!s.required) continue;
    bool given = false;
    for (const auto& [k, v] : extra) given = given || k == s.name;
    if (given) continue;
    const std::string value = s.name == "eds" ? std::string(OEGW_SOURCE_DIR) + "/subdevices/eds/generic_pedal.eds"
                                              : std::string(s.listing_value);
    o.values.emplace_back(std::string(s.name), value);
  }
  for (auto& kv : extra) o.values.push_back(std::move(kv));
  return o;
}

bool builds(const DriverInfo& info, const std::string& key, const std::string& value, std::string& error) {
  error.clear();
  return make_driver(info.family, kNode, {}, with_required(info, {{key, value}}), error) != nullptr;
}

TEST(DriverOptionTables, EveryFamilyHasOneAndMakeDriverKnowsIt) {
  ASSERT_EQ(drivers().size(), 4u);
  EXPECT_EQ(driver_names(), "elobau-mfg, mcb402, novotechnik-406, cia401");
  for (const DriverInfo& info : drivers()) {
    std::string error;
    EXPECT_NE(make_driver(info.family, kNode, {}, with_required(info, {}), error), nullptr) << info.family << error;
  }
  std::string error;
  EXPECT_EQ(make_driver("elobau", kNode, {}, {}, error), nullptr);
  EXPECT_EQ(error, "unknown driver 'elobau' (expected one of: elobau-mfg, mcb402, novotechnik-406, cia401)");
}

TEST(DriverOptionTables, IntegerRangesAreWhatTheFactoryAccepts) {
  for (const DriverInfo& info : drivers())
    for (const OptionSpec& s : info.options) {
      if (s.type != OptionSpec::Type::Integer) continue;
      for (const auto& [lo, hi] : s.ranges) {
        std::string error;
        // channel2_timeout_ms must also exceed cycle_ms: its lowest non-zero edge is refused
        // for that reason, not its range.
        if (!(s.name == "channel2_timeout_ms" && lo == 0)) {
          EXPECT_TRUE(builds(info, std::string(s.name), std::to_string(lo), error)) << s.name << " " << lo << error;
        }
        EXPECT_TRUE(builds(info, std::string(s.name), std::to_string(hi), error)) << s.name << " " << hi << error;
        bool below_in = false, above_in = false;
        for (const auto& [l2, h2] : s.ranges) {
          below_in = below_in || (lo - 1 >= l2 && lo - 1 <= h2);
          above_in = above_in || (hi + 1 >= l2 && hi + 1 <= h2);
        }
        if (!below_in) {
          EXPECT_FALSE(builds(info, std::string(s.name), std::to_string(lo - 1), error)) << s.name << " " << lo - 1;
          EXPECT_EQ(error, std::string(info.family) + ": " + std::string(s.name) + " '" + std::to_string(lo - 1) +
                               "' is not an " + s.type_text() + (s.note.empty() ? "" : " " + std::string(s.note)));
        }
        if (!above_in) {
          EXPECT_FALSE(builds(info, std::string(s.name), std::to_string(hi + 1), error)) << s.name;
        }
      }
      std::string error;
      EXPECT_FALSE(builds(info, std::string(s.name), "12x", error)) << s.name;
    }
}

TEST(DriverOptionTables, ChoicesDefaultsAndRequiredAreWhatTheFactoryDoes) {
  for (const DriverInfo& info : drivers())
    for (const OptionSpec& s : info.options) {
      std::string error;
      if (!s.default_value.empty()) {
        EXPECT_TRUE(builds(info, std::string(s.name), std::string(s.default_value), error)) << s.name << error;
      }
      if (s.type == OptionSpec::Type::Choice) {
        for (const auto c : s.choices) EXPECT_TRUE(builds(info, std::string(s.name), std::string(c), error)) << c;
        EXPECT_FALSE(builds(info, std::string(s.name), "neither", error));
        EXPECT_EQ(error, std::string(info.family) + ": " + std::string(s.name) + " 'neither' must be " + s.type_text() +
                             (s.note.empty() ? "" : " " + std::string(s.note)));
      }
      if (s.required) {
        DriverOptions none;  // every other required option, but not this one
        for (const auto& kv : with_required(info, {}).values)
          if (kv.first != s.name) none.values.push_back(kv);
        EXPECT_EQ(make_driver(info.family, kNode, {}, none, error), nullptr) << s.name;
        EXPECT_EQ(error, s.missing);
      }
      EXPECT_FALSE(s.description.empty()) << s.name;
    }
  std::string error;
  EXPECT_EQ(make_driver("novotechnik-406", kNode, {}, DriverOptions{{{"colour", "red"}}}, error), nullptr);
  EXPECT_EQ(error,
            "novotechnik-406: unknown option 'colour' (expected event_timer_ms, transmission_type, product_code, "
            "freshness_floor_ms)");
}

// The defaults the table lists are the ones a driver built without options has.
TEST(DriverOptionTables, ListedDefaultsAreTheDriversDefaults) {
  std::string error;
  auto m = make_driver("mcb402", kNode, {}, DriverOptions{{{"button_bits", "0/1/2/3/4/5/6"}}}, error);
  ASSERT_NE(m, nullptr) << error;
  const auto& mo = dynamic_cast<const Mcb402Driver&>(*m).options();
  EXPECT_EQ(mo.event_timer_ms, 20);
  EXPECT_EQ(mo.button_timer_ms, 100);
  EXPECT_EQ(mo.can_restart_ms, 1000);
  auto n = make_driver("novotechnik-406", kNode, {}, {}, error);
  ASSERT_NE(n, nullptr) << error;
  const auto& no = dynamic_cast<const Novotechnik406Driver&>(*n).options();
  EXPECT_EQ(no.event_timer_ms, 10);
  EXPECT_EQ(no.transmission_type, 254);
  EXPECT_FALSE(no.product_code.has_value());
  // 0x.. hexadecimal as the listing's product codes are written
  n = make_driver("novotechnik-406", kNode, {}, DriverOptions{{{"product_code", "0x0BB9"}}}, error);
  ASSERT_NE(n, nullptr) << error;
  EXPECT_EQ(dynamic_cast<const Novotechnik406Driver&>(*n).options().product_code, 0x0BB9u);
  auto e = make_driver("elobau-mfg", kNode, {}, {}, error);
  ASSERT_NE(e, nullptr) << error;
  EXPECT_EQ(e->signals()[0].max, 110) << "detent pass by default";
  EXPECT_EQ(e->freshness(0), std::chrono::milliseconds(300)) << "cycle_ms 100 by default: 3 x 100 ms";
}

}  // namespace
}  // namespace oegw::subdevices

namespace oegw::subdevices {
namespace {

// The draft's placeholder of a required commissioning choice (`oegw scan` writes TODO) is refused
// with the option's own text: how to find the value.
TEST(DriverOptionTables, ThePlaceholderOfARequiredOptionIsRefusedWithHowToFindIt) {
  std::string error;
  EXPECT_EQ(make_driver("mcb402", NodeId{3}, {}, DriverOptions{{{"button_bits", "TODO"}}}, error), nullptr);
  EXPECT_NE(error.find("mcb402: option button_bits is still the draft's placeholder TODO"), std::string::npos) << error;
  EXPECT_NE(error.find("press BP1..BP7 one at a time"), std::string::npos) << error;
  EXPECT_NE(error.find("oegw signals mcb402 --find-button-bits"), std::string::npos) << error;
  // An option that is not required takes TODO as any other text (and refuses it as such).
  EXPECT_EQ(make_driver("elobau-mfg", NodeId{0x11}, {}, DriverOptions{{{"detent", "TODO"}}}, error), nullptr);
  EXPECT_EQ(error.find("placeholder"), std::string::npos) << error;
}

// Every refusal of one set of options, each naming its option: a mapping file with three wrong
// options of one grip hears of all three at once (the first only, before).
TEST(DriverOptionTables, EveryRefusalIsCollectedWithItsOption) {
  OptionRefusals refusals;
  EXPECT_EQ(make_driver("elobau-mfg", kNode, {},
                        DriverOptions{{{"channel_tolerance", "200"}, {"detent", "round"}, {"colour", "red"}}},
                        refusals),
            nullptr);
  ASSERT_EQ(refusals.size(), 3u);
  EXPECT_EQ(refusals[0].option, "colour");
  EXPECT_EQ(refusals[1].option, "channel_tolerance");
  EXPECT_EQ(refusals[1].message, "elobau-mfg: channel_tolerance '200' is not an integer 0..100 (percent)");
  EXPECT_EQ(refusals[2].option, "detent");
  EXPECT_EQ(refusals[2].message, "elobau-mfg: detent 'round' must be 'pass' or 'clamp'");
  // The text form: the same messages, one a line.
  std::string error;
  EXPECT_EQ(make_driver("elobau-mfg", kNode, {}, DriverOptions{{{"channel_tolerance", "200"}, {"detent", "round"}}},
                        error),
            nullptr);
  EXPECT_EQ(error,
            "elobau-mfg: channel_tolerance '200' is not an integer 0..100 (percent)\n"
            "elobau-mfg: detent 'round' must be 'pass' or 'clamp'");
  // A missing required option is about no written one; an EDS that cannot be read is about eds.
  refusals.clear();
  EXPECT_EQ(make_driver("mcb402", kNode, {}, DriverOptions{{{"event_timer_ms", "0"}}}, refusals), nullptr);
  ASSERT_EQ(refusals.size(), 2u);
  EXPECT_EQ(refusals[0].option, "");
  EXPECT_EQ(refusals[1].option, "event_timer_ms");
  refusals.clear();
  EXPECT_EQ(make_driver("cia401", kNode, {}, DriverOptions{{{"eds", "/nonexistent/pedal.eds"}}}, refusals), nullptr);
  ASSERT_EQ(refusals.size(), 1u);
  EXPECT_EQ(refusals[0].option, "eds");
  EXPECT_EQ(refusals[0].message, "cia401: EDS file /nonexistent/pedal.eds does not exist");
}

// Every family lists its freshness floor (200 ms), the same option name.
TEST(DriverOptionTables, EveryFamilyHasAFreshnessFloorOption) {
  for (const DriverInfo& info : drivers()) {
    bool found = false;
    for (const OptionSpec& s : info.options)
      if (s.name == kFreshnessFloorOption) {
        found = true;
        EXPECT_EQ(s.default_value, "200") << info.family;
      }
    EXPECT_TRUE(found) << info.family;
  }
}

}  // namespace
}  // namespace oegw::subdevices
