// NodeBoot: one sub-device's boot steps (identity, diagnostics, the driver's reads, the writes)
// and what each SDO answer means, without a bus: each answer is given by hand.
#include "subdevices/node_boot.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <utility>
#include <vector>

using namespace oegw::subdevices;
using oegw::canopen::encode;
using oegw::canopen::SdoAbortCode;
using testing::HasSubstr;

namespace {

constexpr NodeId kNode{0x11};
using Kind = NodeBoot::Step::Kind;

// A driver whose boot reads, configuration and refusals a test sets.
class ScriptedDriver final : public Driver {
 public:
  ScriptedDriver() { init(kNode, {}, 0); }
  std::string_view family() const override { return "test-scripted"; }
  const std::vector<SignalInfo>& signals() const override { return signals_; }
  ExpectedIdentity expected_identity() const override { return {.device_type = 0x000F0191, .vendor_id = 0x15A}; }
  std::vector<SdoWrite> configuration() const override { return config; }
  void begin_boot() override {
    ++boots;
    rounds_left = rounds;
  }
  std::vector<std::pair<std::uint16_t, std::uint8_t>> boot_reads() const override {
    if (rounds_left == 0) return {};
    return {{0x1A00, 0}};
  }
  bool on_boot_read(std::uint16_t index, std::uint8_t, std::span<const std::uint8_t> data,
                    std::string& error) override {
    read.push_back(index);
    if (index == 0x1A00) --rounds_left;
    if (index == 0x1001 && !data.empty() && data[0] != 0) {
      error = "an error is active";
      return false;
    }
    return true;
  }
  bool on_boot_read_abort(std::uint16_t index, std::uint8_t, SdoAbortCode) override {
    if (index == 0x1A00) rounds_left = 0;
    return index == 0x1A00;
  }
  std::optional<SdoWrite> instead_of_refused(const SdoWrite& write, SdoAbortCode) override {
    if (write.index != 0x1800) return std::nullopt;
    return SdoWrite{0x1800, 5, encode<std::uint16_t>(0), "TPDO1 event timer off instead"};
  }
  bool on_frame(const CanFrame&, TimePoint) override { return false; }
  DecodedEmcy on_emcy(const EmcyMessage& e, TimePoint) override { return {e.code, "test", false, {}}; }
  std::vector<std::uint32_t> consumed_cob_ids() const override { return {}; }
  bool set_output(std::size_t, std::int64_t, TimePoint) override { return false; }

  std::vector<SdoWrite> config;
  int rounds = 0;  // boot-read rounds of 1A00h:00
  int boots = 0;
  std::vector<std::uint16_t> read;

 private:
  std::vector<SignalInfo> signals_;
  int rounds_left = 0;
};

std::vector<std::uint8_t> u32(std::uint32_t v) { return encode<std::uint32_t>(v); }

class NodeBootTest : public ::testing::Test {
 protected:
  ScriptedDriver driver;
  NodeSettings settings{.name = "grip", .node = kNode, .heartbeat_ms = 100};
  NodeBoot boot;

  // The request now due, as "R 1018h:01" or "W 1017h:00"; "" when advance() says otherwise.
  std::string next() {
    if (boot.advance() != NodeBoot::Next::Request) return "";
    char b[16];
    std::snprintf(b, sizeof b, "%c %04Xh:%02X", boot.current().kind == Kind::Read ? 'R' : 'W', boot.current().index,
                  boot.current().sub);
    return b;
  }
  void ok(std::vector<std::uint8_t> data = {}) {
    EXPECT_EQ(boot.on_answer(SdoAbortCode::None, data).kind, NodeBoot::Verdict::Kind::Continue);
  }
  // The identity as the driver expects it; 1018h:02..04 are not present.
  void identity() {
    ASSERT_EQ(next(), "R 1000h:00");
    ok(u32(0x000F0191));
    ASSERT_EQ(next(), "R 1018h:01");
    ok(u32(0x15A));
    for (const char* sub : {"R 1018h:02", "R 1018h:03", "R 1018h:04"}) {
      ASSERT_EQ(next(), sub);
      EXPECT_EQ(boot.on_answer(SdoAbortCode::ObjectDoesNotExist, {}).kind, NodeBoot::Verdict::Kind::Continue);
    }
  }
  // 1008h, 1009h, 100Ah not present, 1001h = `reg`.
  void diagnostics(std::uint8_t reg) {
    for (const char* obj : {"R 1008h:00", "R 1009h:00", "R 100Ah:00"}) {
      ASSERT_EQ(next(), obj);
      (void)boot.on_answer(SdoAbortCode::ObjectDoesNotExist, {});
    }
    ASSERT_EQ(next(), "R 1001h:00");
    ok({reg});
  }
};

TEST_F(NodeBootTest, IdentityDiagnosticsDriverReadsThenTheWritesInTheirOrder) {
  driver.rounds = 2;
  driver.config = {SdoWrite{0x1800, 5, encode<std::uint16_t>(50), "TPDO1 event timer"}};
  settings.sdo = {SdoWrite{0x1800, 2, {0xFE}, "TPDO1 type 254"}};
  boot.plan(settings, driver);
  EXPECT_EQ(driver.boots, 1);
  identity();
  diagnostics(0x00);
  ASSERT_EQ(boot.advance(), NodeBoot::Next::Diagnostics);
  EXPECT_EQ(boot.diagnostics().vendor_id, 0x15Au);
  EXPECT_EQ(boot.diagnostics().error_register, 0x00);
  EXPECT_EQ(boot.check_error_register(), "");
  // The driver asks for a round of reads while it has one; then the heartbeat, the driver's
  // configuration (asked only now: it may depend on the reads), the mapping file's list.
  EXPECT_EQ(next(), "R 1A00h:00");
  ok({2});
  EXPECT_EQ(next(), "R 1A00h:00");
  ok({2});
  EXPECT_EQ(next(), "W 1017h:00");
  EXPECT_EQ(boot.current().data, encode<std::uint16_t>(100));
  ok();
  EXPECT_EQ(next(), "W 1800h:05");
  ok();
  EXPECT_EQ(next(), "W 1800h:02");
  ok();
  EXPECT_EQ(boot.advance(), NodeBoot::Next::Done);
  const std::vector<SdoWrite> writes = boot.writes();
  ASSERT_EQ(writes.size(), 3u);
  EXPECT_EQ(writes[0].index, 0x1017);
  EXPECT_EQ(writes[1].index, 0x1800);
  EXPECT_EQ(writes[2].data, (std::vector<std::uint8_t>{0xFE}));
}

TEST_F(NodeBootTest, AWrongDeviceTypeRefusesTheNodeAndNamesBothValues) {
  boot.plan(settings, driver);
  ASSERT_EQ(next(), "R 1000h:00");
  const NodeBoot::Verdict v = boot.on_answer(SdoAbortCode::None, u32(0x00020192));
  EXPECT_EQ(v.kind, NodeBoot::Verdict::Kind::Refused);
  EXPECT_EQ(v.why, "1000h:00 is 00020192h, the configuration expects 000F0191h");
}

TEST_F(NodeBootTest, NoAnswerIsAMissingNodeAndAnAbortOfAMandatoryReadRefusesIt) {
  boot.plan(settings, driver);
  ASSERT_EQ(next(), "R 1000h:00");
  NodeBoot::Verdict v = boot.on_answer(SdoAbortCode::Timeout, {});
  EXPECT_EQ(v.kind, NodeBoot::Verdict::Kind::NoAnswer);
  EXPECT_EQ(v.why, "reading 1000h:00 (device type): no answer (SDO timeout)");
  boot.plan(settings, driver);
  ASSERT_EQ(next(), "R 1000h:00");
  ok(u32(0x000F0191));
  ASSERT_EQ(next(), "R 1018h:01");
  v = boot.on_answer(SdoAbortCode::ObjectDoesNotExist, {});
  EXPECT_EQ(v.kind, NodeBoot::Verdict::Kind::Refused);
  EXPECT_THAT(v.why, HasSubstr("reading 1018h:01 (vendor-ID): abort 06020000h"));
}

TEST_F(NodeBootTest, TheDriverRefusingTheErrorRegisterRefusesTheNode) {
  boot.plan(settings, driver);
  identity();
  diagnostics(0x81);
  ASSERT_EQ(boot.advance(), NodeBoot::Next::Diagnostics);
  EXPECT_EQ(boot.check_error_register(), "1001h:00: an error is active");
}

TEST_F(NodeBootTest, NoErrorRegisterLeavesItToTheDriver) {
  boot.plan(settings, driver);
  identity();
  for (const char* obj : {"R 1008h:00", "R 1009h:00", "R 100Ah:00", "R 1001h:00"}) {
    ASSERT_EQ(next(), obj);
    (void)boot.on_answer(SdoAbortCode::ObjectDoesNotExist, {});
  }
  ASSERT_EQ(boot.advance(), NodeBoot::Next::Diagnostics);
  EXPECT_EQ(boot.diagnostics().error_register, std::nullopt);
  EXPECT_EQ(boot.check_error_register(), "");
  EXPECT_TRUE(driver.read.empty()) << "the driver was handed no 1001h";
}

TEST_F(NodeBootTest, ADriverReadTheDriverCanDoWithoutAndARefusedWriteWithItsAlternative) {
  driver.rounds = 1;
  driver.config = {SdoWrite{0x1800, 5, encode<std::uint16_t>(50), "TPDO1 event timer"}};
  settings.heartbeat_ms = 0;  // no 1017h write
  boot.plan(settings, driver);
  identity();
  diagnostics(0x00);
  ASSERT_EQ(boot.advance(), NodeBoot::Next::Diagnostics);
  ASSERT_EQ(next(), "R 1A00h:00");
  EXPECT_EQ(boot.on_answer(SdoAbortCode::ObjectDoesNotExist, {}).kind, NodeBoot::Verdict::Kind::Continue);
  ASSERT_EQ(next(), "W 1800h:05");
  EXPECT_EQ(boot.on_answer(SdoAbortCode::InvalidValue, {}).kind, NodeBoot::Verdict::Kind::Continue);
  ASSERT_EQ(next(), "W 1800h:05");
  EXPECT_EQ(boot.current().what, "TPDO1 event timer off instead");
  EXPECT_EQ(boot.current().data, encode<std::uint16_t>(0));
  // The alternative refused too: the node is refused.
  const NodeBoot::Verdict v = boot.on_answer(SdoAbortCode::InvalidValue, {});
  EXPECT_EQ(v.kind, NodeBoot::Verdict::Kind::Refused);
  EXPECT_THAT(v.why, HasSubstr("writing 1800h:05 (TPDO1 event timer off instead): abort"));
}

TEST_F(NodeBootTest, PlanStartsOverFromTheIdentity) {
  boot.plan(settings, driver);
  identity();
  boot.plan(settings, driver);
  EXPECT_EQ(driver.boots, 2);
  EXPECT_EQ(boot.diagnostics().vendor_id, std::nullopt) << "the last boot's values are gone";
  EXPECT_EQ(next(), "R 1000h:00");
}

}  // namespace
