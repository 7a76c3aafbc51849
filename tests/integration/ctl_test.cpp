// `oegw ctl` against a Gateway with simulators on the virtual buses: the CiA 309-3
// session (cli/ctl_command.hpp) asks the control protocol with the ctl commands
// (ctl_service.hpp) in process — the same JSON lines the socket carries — and the downstream
// frames each command causes are judged frame by frame. Expected values come from the
// simulators' dictionaries (written from the manufacturers' documents), never from the gateway.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "canopen/305/lss.hpp"
#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "cli/ctl_command.hpp"
#include "gateway/control/control_protocol.hpp"
#include "gateway/control/ctl_service.hpp"
#include "gateway/gateway.hpp"
#include "rig/cab_rig.hpp"
#include "subdevices/sim/novotechnik_406_sim.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "tests/fixtures/fixtures.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
namespace gw = oegw::gateway;
namespace sd = oegw::subdevices;

namespace {

using Frames = std::vector<std::pair<std::uint32_t, std::vector<std::uint8_t>>>;
constexpr std::uint8_t kPedal = 0x30, kKnob = 0x7F;

class Ctl : public ::testing::Test {
 protected:
  void SetUp() override {
    auto loaded = oegw::mapping::load_config_text(oegw::fixtures::mapping_file("demo_cab.yaml"), "ctl.yaml",
                                                  gw::driver_catalogue());
    ASSERT_TRUE(loaded.ok()) << loaded.error_text();
    config_ = std::move(*loaded.config);
    store_ = std::filesystem::path(::testing::TempDir()) / fmt::format("ctl_{}.store", ::getpid());
    std::filesystem::remove(store_);
    rig_ = std::make_unique<oegw::rig::CabRig>(config_, loop_, oegw::rig::CabRigOptions{.store = store_});
    rig_->down().set_tap([this](const BusRecord& r) { down_.push_back(r.frame); });
    rig_->to_devices = [this](const CanFrame& f) { return drop_to_devices_ && drop_to_devices_(f); };
    rig_->to_gateway_down = [this](const CanFrame& f) { return drop_to_gateway_ && drop_to_gateway_(f); };
    rig_->on_gateway = [this](gw::Gateway& g) { g.on_log = [this](const std::string& l) { log_ += l + "\n"; }; };
    rig_->build();
    rig_->power_on();
    rig_->run_for(3s);
    for (const auto& n : rig_->gw().downstream().names())
      ASSERT_EQ(rig_->gw().downstream().state(n), sd::NodeState::Operational) << n << "\n" << log_;
    service_ =
        std::make_unique<gw::control::CtlService>(loop_, rig_->gw(), config_, protocol_, [this] { rig_->rearm(); });
    // The session asks the protocol as the socket would, and the loop runs until the answer.
    session_ = std::make_unique<oegw::cli::CtlSession>(
        [this](const std::string& line, std::chrono::milliseconds timeout) {
          std::optional<std::string> answer;
          protocol_.answer(line, [&answer](std::string a) { answer = std::move(a); });
          for (std::int64_t i = 0; i < timeout.count() && !answer; ++i) rig_->run_for(1ms);
          return answer ? oegw::cli::AskResult{oegw::cli::AskStatus::Ok, *answer}
                        : oegw::cli::AskResult{oegw::cli::AskStatus::Timeout, "no answer"};
        },
        "0.1.0", 10s);
    ASSERT_EQ(session_->poll_events().lines, std::vector<std::string>{});
  }
  void TearDown() override {
    session_.reset();
    service_.reset();
    rig_.reset();
    std::filesystem::remove(store_);
  }

  // One command's answer line; the downstream frames it caused are in frames_since().
  std::string run(const std::string& line) {
    mark_ = down_.size();
    const auto o = session_->execute(line);
    EXPECT_EQ(o.fatal, 0) << o.why;
    EXPECT_EQ(o.lines.size(), 1u) << line;
    rig_->run_for(5ms);  // the frames a command sent without waiting for an answer (NMT) reach the bus
    return o.lines.empty() ? "" : o.lines[0];
  }
  // Runs until the network manager holds `name` in `state` (at most 3 s).
  void until(const char* name, sd::NodeState state) {
    for (int i = 0; i < 3000 && rig_->gw().downstream().state(name) != state; ++i) rig_->run_for(1ms);
    ASSERT_EQ(rig_->gw().downstream().state(name), state) << name << "\n" << log_;
  }
  // The frames with these COB-IDs since the last command (all SDO traffic of one node).
  Frames frames_since(std::initializer_list<std::uint32_t> ids) const {
    Frames out;
    for (std::size_t i = mark_; i < down_.size(); ++i)
      if (std::find(ids.begin(), ids.end(), down_[i].id) != ids.end())
        out.emplace_back(down_[i].id,
                         std::vector<std::uint8_t>(down_[i].data.begin(), down_[i].data.begin() + down_[i].dlc));
    return out;
  }
  std::uint32_t sim_u32(const char* device, std::uint16_t index, std::uint8_t sub) {
    return rig_->devices().device(device)->od().get<std::uint32_t>(index, sub);
  }
  static std::vector<std::uint8_t> le32(std::uint32_t v) {
    return {static_cast<std::uint8_t>(v), static_cast<std::uint8_t>(v >> 8), static_cast<std::uint8_t>(v >> 16),
            static_cast<std::uint8_t>(v >> 24)};
  }

  SimulatedClock clock_;
  EventLoop loop_{clock_};
  oegw::mapping::Config config_;
  std::filesystem::path store_;
  std::unique_ptr<oegw::rig::CabRig> rig_;
  gw::control::ControlProtocol protocol_;
  std::unique_ptr<gw::control::CtlService> service_;
  std::unique_ptr<oegw::cli::CtlSession> session_;
  std::function<bool(const CanFrame&)> drop_to_devices_, drop_to_gateway_;
  std::vector<CanFrame> down_;
  std::size_t mark_ = 0;
  std::string log_;
};

TEST_F(Ctl, ReadsASubDevicesIdentityFrameByFrame) {
  const std::uint32_t vendor = sim_u32("right_grip", 0x1018, 1);
  // lely coctl.md's session, on the mapping file's downstream network 2.
  EXPECT_EQ(run("[1] set network 2"), "[1] OK");
  EXPECT_EQ(run("[2] set node 17"), "[2] OK");
  EXPECT_EQ(run("[3] r 0x1018 0x01 u32"), fmt::format("[3] 0x{:08X}", vendor));
  // One expedited upload on the node's default SDO channel (CiA 301 §7.2.4.3.6): request
  // 40h 1018h:01 on 600h + 11h, answer 43h with the four bytes on 580h + 11h. Nothing else.
  std::vector<std::uint8_t> answer{0x43, 0x18, 0x10, 0x01};
  for (const auto b : le32(vendor)) answer.push_back(b);
  EXPECT_EQ(frames_since({0x611, 0x591}), (Frames{{0x611, {0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0}}, {0x591, answer}}));
  // Net and node on the line, and a string (1008h, segmented upload) of the Novotechnik sensor.
  const auto name = rig_->devices().device("seat_knob")->od().find(0x1008)->find(0)->value;
  EXPECT_EQ(run("[4] 2 127 r 0x1008 0 vs"), "[4] \"" + std::string(name.begin(), name.end()) + "\"");
  // A type whose size does not fit the object: lely's 0607 0010h.
  EXPECT_EQ(run("[5] 2 17 r 0x1018 1 u16"),
            "[5] ERROR: 06070010 (" + std::string(to_string(SdoAbortCode::LengthMismatch)) + ")");
}

TEST_F(Ctl, WritesAnAllowedObjectAndIsRefusedAProtectedOne) {
  // elobau 5001h (a parameter the gateway does not configure): carried out.
  EXPECT_EQ(run("[1] 2 17 w 0x5001 0 u16 30"), "[1] OK");
  EXPECT_EQ(rig_->devices().device("right_grip")->od().get<std::uint16_t>(0x5001, 0), 30);
  EXPECT_EQ(frames_since({0x611, 0x591}),
            (Frames{{0x611, {0x2B, 0x01, 0x50, 0x00, 30, 0, 0, 0}}, {0x591, {0x60, 0x01, 0x50, 0x00, 0, 0, 0, 0}}}));
  EXPECT_EQ(run("[2] 2 17 r 0x5001 0 u16"), "[2] 0x001E");
  // TPDO 1's COB-ID: the gateway configured it and its FEs use the grip (gateway/remote_sdo.hpp):
  // refused with 0800 0021h, and not a frame goes to the node.
  const std::uint32_t cob = sim_u32("right_grip", 0x1800, 1);
  EXPECT_EQ(run("[3] 2 17 w 0x1800 1 u32 0x80000191"),
            "[3] ERROR: 08000021 (" + std::string(to_string(SdoAbortCode::CannotTransferLocalControl)) + ")");
  EXPECT_EQ(frames_since({0x611, 0x591}), Frames{});
  EXPECT_EQ(sim_u32("right_grip", 0x1800, 1), cob);
  EXPECT_EQ(run("[4] 2 17 w 0x1017 0 u16 0"),
            "[4] ERROR: 08000021 (" + std::string(to_string(SdoAbortCode::CannotTransferLocalControl)) + ")");
  // The same mechanism as the host's remote SDO: counted as refused for that sub-device.
  EXPECT_EQ(rig_->gw().subdevice_refused_commands("right_grip"), 2u);
}

TEST_F(Ctl, NodesTheGatewayDoesNotServe) {
  // A node-ID no sub-device has: RemoteSdo's 0609 0011h, nothing on the bus.
  EXPECT_EQ(run("[1] 2 5 r 0x1000 0 u32"),
            "[1] ERROR: 06090011 (" + std::string(to_string(SdoAbortCode::SubIndexDoesNotExist)) + ")");
  EXPECT_EQ(frames_since({0x605, 0x585}), Frames{});
  // A network the mapping file does not have.
  EXPECT_EQ(run("[2] 9 17 r 0x1000 0 u32"),
            "[2] ERROR: 106 (Unsupported net: network 9: this gateway has 1 (upstream, its own dictionary) and 2 "
            "(downstream, the sub-devices))");
  // The host's bus holds only the gateway itself.
  EXPECT_EQ(
      run("[3] 1 5 r 0x1000 0 u32"),
      "[3] ERROR: 107 (Unsupported node: network 1 is the host's bus: only the gateway itself, node 32, is reached "
      "there)");
  // A sub-device whose heartbeat is lost: 0606 0000h, no request sent to it.
  drop_to_gateway_ = [](const CanFrame& f) { return (f.id & 0x7F) == kKnob; };
  until("seat_knob", sd::NodeState::Missing);
  EXPECT_EQ(run("[4] 2 127 r 0x1000 0 u32"),
            "[4] ERROR: 06060000 (" + std::string(to_string(SdoAbortCode::HardwareError)) + ")");
  EXPECT_EQ(frames_since({0x67F}), Frames{});
  // Then the gateway boots it again: its own boot comes first, 0800 0022h.
  until("seat_knob", sd::NodeState::WaitingBootUp);
  EXPECT_EQ(run("[5] 2 127 w 0x2100 0 u8 1"),
            "[5] ERROR: 08000022 (" + std::string(to_string(SdoAbortCode::CannotTransferDeviceState)) + ")");
  EXPECT_EQ(frames_since({0x67F}), Frames{});
}

TEST_F(Ctl, TheGatewaysOwnDictionaryUpstream) {
  auto& od = rig_->gw().upstream().od();
  EXPECT_EQ(run("[1] 1 32 r 0x1018 1 u32"), fmt::format("[1] 0x{:08X}", od.get<std::uint32_t>(0x1018, 1)));
  EXPECT_EQ(run("[2] 1 32 r 0x1000 0 u32"), fmt::format("[2] 0x{:08X}", od.get<std::uint32_t>(0x1000, 0)));
  // As its SDO server: a read-only object, an object it has not, a wrong length.
  EXPECT_EQ(run("[3] 1 32 w 0x1000 0 u32 1"),
            "[3] ERROR: 06010002 (" + std::string(to_string(SdoAbortCode::WriteOfReadOnly)) + ")");
  EXPECT_EQ(run("[4] 1 32 r 0x5FFF 0 u8"),
            "[4] ERROR: 06020000 (" + std::string(to_string(SdoAbortCode::ObjectDoesNotExist)) + ")");
  EXPECT_EQ(run("[5] 1 32 w 0x1017 0 u16 250"), "[5] OK");
  EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 250);
  EXPECT_EQ(run("[6] 1 32 w 0x1017 0 u32 250"),
            "[6] ERROR: 06070012 (" + std::string(to_string(SdoAbortCode::LengthTooHigh)) + ")");
  // Nothing of this reached the sub-devices' bus.
  EXPECT_EQ(frames_since({0x600 + 0x20, 0x580 + 0x20}), Frames{});
  const std::string info = run("[7] info version");
  // The 1018h values as `r` prints a u32: the same text for the same object either way.
  EXPECT_EQ(info, fmt::format("[7] 0x{:08X} 0x{:08X} 0x{:08X} 0x{:08X} 3 3.0 0.1", od.get<std::uint32_t>(0x1018, 1),
                              od.get<std::uint32_t>(0x1018, 2), od.get<std::uint32_t>(0x1018, 3),
                              od.get<std::uint32_t>(0x1018, 4)));
  for (std::uint8_t sub = 1; sub <= 4; ++sub)
    EXPECT_NE(info.find(run(fmt::format("[8] 1 32 r 0x1018 {} u32", sub)).substr(4)), std::string::npos) << +sub;
}

TEST_F(Ctl, NmtAndTheBootUpEvent) {
  EXPECT_EQ(run("[1] 2 48 reset node"), "[1] OK");
  // The reset node frame (CiA 301 §7.2.8.3.1.1: 81h, node-ID); what follows within the 5 ms
  // run() waits is the gateway's own boot of the pedal answering its boot-up.
  const Frames nmt = frames_since({0x000});
  ASSERT_FALSE(nmt.empty());
  EXPECT_EQ(nmt[0], (std::pair<std::uint32_t, std::vector<std::uint8_t>>{0x000, {0x81, kPedal}}));
  rig_->run_for(2s);
  const auto events = session_->poll_events();
  EXPECT_NE(std::find(events.lines.begin(), events.lines.end(), "2 48 BOOT_UP"), events.lines.end())
      << ::testing::PrintToString(events.lines);
  // The gateway boots it again (its reboot seen) and it is operational once more.
  EXPECT_EQ(rig_->gw().downstream().state("pedal"), sd::NodeState::Operational) << log_;
  // Stop of a sub-device in use is carried out, and the gateway sees it lost: its FEs at their
  // fault values (docs/design/fault-policy.md), as with any NMT master's stop.
  EXPECT_EQ(run("[5] 2 17 stop"), "[5] OK");
  const Frames stop = frames_since({0x000});
  ASSERT_FALSE(stop.empty());
  EXPECT_EQ(stop[0], (std::pair<std::uint32_t, std::vector<std::uint8_t>>{0x000, {0x02, 0x11}}));
  rig_->run_for(500ms);
  EXPECT_NE(rig_->gw().downstream().state("right_grip"), sd::NodeState::Operational) << log_;
  EXPECT_EQ(rig_->gw().faults().count("right_grip"), 1u) << log_;
  // NMT to the gateway's own bus is the host's business.
  EXPECT_EQ(
      run("[2] 1 32 stop"),
      "[2] ERROR: 100 (Request not supported: network 1 is the host's bus: the gateway's own NMT state is its NMT "
      "master's)");
  EXPECT_EQ(frames_since({0x000}), Frames{});
  // Start of a node the gateway holds as missing: refused, it starts only what it booted.
  drop_to_gateway_ = [](const CanFrame& f) { return (f.id & 0x7F) == kKnob; };
  until("seat_knob", sd::NodeState::Missing);
  EXPECT_EQ(run("[3] 2 127 start"),
            "[3] ERROR: 102 (Request not processed due to internal state: seat_knob is missing: the gateway starts it "
            "itself once its boot succeeds (reset node boots it again))");
  EXPECT_EQ(frames_since({0x000}), Frames{});
  // While the gateway boots it again, no NMT of the tool may cut in.
  until("seat_knob", sd::NodeState::WaitingBootUp);
  EXPECT_EQ(run("[4] 2 127 stop"),
            "[4] ERROR: 102 (Request not processed due to internal state: seat_knob is being booted by the gateway "
            "(waiting for boot-up); try again when it is operational)");
  EXPECT_EQ(frames_since({0x000}), Frames{});
}

TEST_F(Ctl, EmcyEventLine) {
  auto& knob = dynamic_cast<sd::sim::Novotechnik406Sim&>(*rig_->devices().device("seat_knob"));
  knob.inject_fault(sd::sim::Novotechnik406Sim::Fault::Overflow, loop_.now());
  rig_->run_for(100ms);
  const auto events = session_->poll_events();
  ASSERT_EQ(events.lines.size(), 1u) << ::testing::PrintToString(events.lines);
  // lely's layout: net node EMCY code register and the five manufacturer bytes (decimal); the
  // Novotechnik document's overflow EMCY 5051h/1/1.
  EXPECT_EQ(events.lines[0].substr(0, 16), "2 127 EMCY 5051 ");
  EXPECT_EQ(session_->poll_events().lines, std::vector<std::string>{});  // each event once
}

TEST_F(Ctl, TheSdoTimeoutEndsATransferTheNodeDoesNotAnswer) {
  EXPECT_EQ(run("[1] 2 set sdo_timeout 50"), "[1] OK");
  drop_to_devices_ = [](const CanFrame& f) { return f.id == 0x611; };
  const TimePoint before = loop_.now();
  EXPECT_EQ(run("[2] 2 17 r 0x1018 1 u32"),
            "[2] ERROR: 05040000 (" + std::string(to_string(SdoAbortCode::Timeout)) + ")");
  EXPECT_LT(loop_.now() - before, 100ms);
  // The transfer was aborted on the bus (the node may have seen part of it) and the next one works.
  drop_to_devices_ = nullptr;
  EXPECT_EQ(run("[3] 2 17 r 0x1018 1 u32"), fmt::format("[3] 0x{:08X}", sim_u32("right_grip", 0x1018, 1)));
}

// The CiA 309-3 LSS commands on the downstream bus, frame by frame against CiA 305's command
// specifiers (canopen/305/lss.hpp) and the simulated pedal's LSS slave (canopen/305/lss_slave.*):
// its node-ID taken away with oegw ctl itself (tests/vm/guest/scan.sh does it with cansend), then
// found by fastscan, given its node-ID again, and booted by the gateway.
TEST_F(Ctl, LssGivesANodeWithoutNodeIdItsNodeIdFrameByFrame) {
  const std::uint32_t a[4] = {sim_u32("pedal", 0x1018, 1), sim_u32("pedal", 0x1018, 2), sim_u32("pedal", 0x1018, 3),
                              sim_u32("pedal", 0x1018, 4)};
  const auto lss_frames = [this] { return frames_since({0x7E5, 0x7E4}); };
  using F = std::vector<std::uint8_t>;
  const auto u32 = [](std::uint8_t cs, std::uint32_t v) {
    F f{cs};
    for (const auto b : le32(v)) f.push_back(b);
    f.resize(8, 0);
    return f;
  };
  EXPECT_EQ(run("[1] set network 2"), "[1] OK");
  // Switch state selective (40h..43h, CiA 305 §8.3.2), answered 44h by the pedal alone.
  EXPECT_EQ(run(fmt::format("[2] lss_switch_sel {} {} {} {}", a[0], a[1], a[2], a[3])), "[2] OK");
  EXPECT_EQ(lss_frames(), (Frames{{0x7E5, u32(0x40, a[0])},
                                  {0x7E5, u32(0x41, a[1])},
                                  {0x7E5, u32(0x42, a[2])},
                                  {0x7E5, u32(0x43, a[3])},
                                  {0x7E4, u32(0x44, 0)}}));
  // Inquire node-ID (5Eh): lely prints it in decimal.
  EXPECT_EQ(run("[3] lss_get_node"), "[3] 48");
  EXPECT_EQ(lss_frames(), (Frames{{0x7E5, u32(0x5E, 0)}, {0x7E4, u32(0x5E, kPedal)}}));
  // Inquire the LSS address (5Ah..5Dh), all four parts, and one.
  EXPECT_EQ(run("[4] lss_inquire_addr"),
            fmt::format("[4] 0x{:08X} 0x{:08X} 0x{:08X} 0x{:08X}", a[0], a[1], a[2], a[3]));
  EXPECT_EQ(lss_frames(), (Frames{{0x7E5, u32(0x5A, 0)},
                                  {0x7E4, u32(0x5A, a[0])},
                                  {0x7E5, u32(0x5B, 0)},
                                  {0x7E4, u32(0x5B, a[1])},
                                  {0x7E5, u32(0x5C, 0)},
                                  {0x7E4, u32(0x5C, a[2])},
                                  {0x7E5, u32(0x5D, 0)},
                                  {0x7E4, u32(0x5D, a[3])}}));
  EXPECT_EQ(run("[5] lss_inquire_addr 0x5B"), fmt::format("[5] 0x{:08X}", a[1]));
  // Its node-ID taken away: configure node-ID FFh (11h, answered 11h error 0), waiting (04h 00h,
  // no answer), and reset communication, after which it has none.
  EXPECT_EQ(run("[6] lss_set_node 255"), "[6] OK");
  EXPECT_EQ(lss_frames(), (Frames{{0x7E5, F{0x11, 0xFF, 0, 0, 0, 0, 0, 0}}, {0x7E4, F{0x11, 0, 0, 0, 0, 0, 0, 0}}}));
  EXPECT_EQ(run("[7] lss_switch_glob 0"), "[7] OK");
  EXPECT_EQ(lss_frames(), (Frames{{0x7E5, F{0x04, 0, 0, 0, 0, 0, 0, 0}}}));
  EXPECT_EQ(run("[8] 2 48 reset comm"), "[8] OK");
  until("pedal", sd::NodeState::Missing);
  // Identify non-configured remote slave (4Ch), answered 50h.
  EXPECT_EQ(run("[9] lss_ident_nonconf"), "[9] OK");
  EXPECT_EQ(lss_frames(), (Frames{{0x7E5, F{0x4C, 0, 0, 0, 0, 0, 0, 0}}, {0x7E4, F{0x50, 0, 0, 0, 0, 0, 0, 0}}}));
  // Fastscan (51h, CiA 305 §8.4.4) with 10 ms steps finds its address and leaves it selected.
  EXPECT_EQ(run("[10] _lss_fastscan 10"),
            fmt::format("[10] 0x{:08X} 0x{:08X} 0x{:08X} 0x{:08X}", a[0], a[1], a[2], a[3]));
  const Frames fs = lss_frames();
  ASSERT_GE(fs.size(), 2u);
  EXPECT_EQ(fs.front(), (Frames::value_type{0x7E5, F{0x51, 0, 0, 0, 0, 0x80, 0, 0}}));  // the reset step
  EXPECT_EQ(fs[1], (Frames::value_type{0x7E4, F{0x4F, 0, 0, 0, 0, 0, 0, 0}}));
  F last{0x51};
  for (const auto b : le32(a[3])) last.push_back(b);
  last.insert(last.end(), {0, 3, 0});  // bit 0 of the serial confirmed, LSSNext back to the vendor
  const auto final_request = std::find_if(fs.rbegin(), fs.rend(), [](const auto& f) { return f.first == 0x7E5; });
  EXPECT_EQ(final_request->second, last);
  for (const auto& [id, data] : fs) EXPECT_TRUE(data[0] == 0x51 || data[0] == 0x4F) << fmt::format("{:02X}", data[0]);
  EXPECT_EQ(run("[11] lss_get_node"), "[11] 255");  // selected, and without node-ID
  // lely's fastscan with values and masks: vendor and product known, so only the revision's and the
  // serial's bits are asked (1 reset + 4 confirmations + 2 × 31 bits + a retry per part ending in 1).
  EXPECT_EQ(run("[31] lss_switch_glob 0"), "[31] OK");
  EXPECT_EQ(run(fmt::format("[32] _lss_fastscan {} 0xFFFFFFFF {} 0xFFFFFFFF 0 0 0 0", a[0], a[1])),
            fmt::format("[32] 0x{:08X} 0x{:08X} 0x{:08X} 0x{:08X}", a[0], a[1], a[2], a[3]));
  std::size_t steps = 0;
  for (const auto& [id, data] : lss_frames()) steps += id == 0x7E5 && data[0] == 0x51 ? 1 : 0;
  EXPECT_EQ(steps, 1u + 4 + 2 * 31 + (a[2] & 1u) + (a[3] & 1u));
  EXPECT_EQ(run("[33] lss_get_node"), "[33] 255");  // selected again
  // Its node-ID again: the gateway holds the pedal missing, so the mapping file's 30h may be given,
  // also while it retries it (configuring: asking its identity, unanswered).
  for (int i = 0; i < 10000 && rig_->gw().downstream().state("pedal") != sd::NodeState::Configuring; ++i)
    rig_->run_for(1ms);
  ASSERT_EQ(rig_->gw().downstream().state("pedal"), sd::NodeState::Configuring) << log_;
  EXPECT_EQ(run("[12] lss_set_node 48"), "[12] OK");
  EXPECT_EQ(lss_frames(), (Frames{{0x7E5, F{0x11, kPedal, 0, 0, 0, 0, 0, 0}}, {0x7E4, F{0x11, 0, 0, 0, 0, 0, 0, 0}}}));
  // Store configuration (17h): this simulated pedal has no LSS store and answers error 1.
  EXPECT_EQ(run("[13] lss_store"),
            "[13] ERROR: 504 (LSS parameter storing failed: store configuration refused with LSS error code 1)");
  EXPECT_EQ(lss_frames(), (Frames{{0x7E5, F{0x17, 0, 0, 0, 0, 0, 0, 0}}, {0x7E4, F{0x17, 1, 0, 0, 0, 0, 0, 0}}}));
  // Bit timing: table 0 index 3 (250 kbit/s) configured (13h), a missing index refused before
  // any frame.
  EXPECT_EQ(run("[14] lss_conf_bitrate 0 3"), "[14] OK");
  EXPECT_EQ(lss_frames(), (Frames{{0x7E5, F{0x13, 0, 3, 0, 0, 0, 0, 0}}, {0x7E4, F{0x13, 0, 0, 0, 0, 0, 0, 0}}}));
  // Back to waiting: a slave without active node-ID and with a pending one starts NMT (CiA 305),
  // boots up as 30h, and the gateway boots it as its pedal.
  EXPECT_EQ(run("[15] lss_switch_glob 0"), "[15] OK");
  until("pedal", sd::NodeState::Operational);
  // Nobody without node-ID is left: identify non-configured and fastscan answer time-outs.
  EXPECT_EQ(run("[16] lss_ident_nonconf"),
            "[16] ERROR: 103 (Time-out: no LSS slave without node-ID answered identify non-configured remote slave)");
  EXPECT_EQ(
      run("[17] _lss_fastscan 10"),
      "[17] ERROR: 103 (Time-out: no answer to LSS fastscan (CiA 305 §8.4.4): no node without node-ID, or it does "
      "not support fastscan)");
  EXPECT_EQ(lss_frames(), (Frames{{0x7E5, F{0x51, 0, 0, 0, 0, 0x80, 0, 0}}}));
}

// lely's `lss_identity` and `_lss_slowscan` (its gateway test session's [15] and [11]), frame by
// frame: identify remote slave 46h..4Bh answered 4Fh by the slaves in the range; slowscan halves
// the revision, then the serial range, and selects what it found (40h..43h, answered 44h).
TEST_F(Ctl, LelysIdentityAndSlowscan) {
  const std::uint32_t a[4] = {sim_u32("pedal", 0x1018, 1), sim_u32("pedal", 0x1018, 2), sim_u32("pedal", 0x1018, 3),
                              sim_u32("pedal", 0x1018, 4)};
  EXPECT_EQ(run("[1] set network 2"), "[1] OK");
  EXPECT_EQ(run(fmt::format("[2] lss_identity {} {} 0 0xFFFFFFFF 0 0xFFFFFFFF", a[0], a[1])), "[2] OK");
  const Frames id = frames_since({0x7E5, 0x7E4});
  ASSERT_EQ(id.size(), 7u);
  EXPECT_EQ(id[0].second[0], 0x46);
  EXPECT_EQ(id[5].second[0], 0x4B);
  EXPECT_EQ(id[6], (Frames::value_type{0x7E4, {0x4F, 0, 0, 0, 0, 0, 0, 0}}));
  EXPECT_EQ(run("[3] lss_identity 0x360 0 0 0 0 0"),
            "[3] ERROR: 103 (Time-out: no LSS slave in the range answered identify remote slave)");
  EXPECT_EQ(run(fmt::format("[4] _lss_slowscan {} {} 0 0xFFFFFFFF 0 0xFFFFFFFF", a[0], a[1])),
            fmt::format("[4] 0x{:08X} 0x{:08X} 0x{:08X} 0x{:08X}", a[0], a[1], a[2], a[3]));
  std::size_t identify = 0, selective = 0;
  for (const auto& [cob, data] : frames_since({0x7E5})) {
    identify += data[0] == 0x46 ? 1 : 0;
    selective += data[0] == 0x40 ? 1 : 0;
  }
  EXPECT_EQ(identify, 1u + 32 + 32);
  EXPECT_EQ(selective, 1u);
  EXPECT_EQ(run("[5] lss_get_node"), "[5] 48");  // the pedal, selected (its node-ID kept)
  EXPECT_EQ(run("[6] lss_switch_glob 0"), "[6] OK");
  EXPECT_EQ(run("[7] _lss_slowscan 0x360 0 0 0 0 0"),
            "[7] ERROR: 103 (Time-out: no LSS slave in the range answered identify remote slave (CiA 305 §8.4.3.6))");
}

TEST_F(Ctl, LssRefusals) {
  EXPECT_EQ(run("[1] 2 lss_conf_bitrate 0 5"),
            "[1] ERROR: 503 (LSS bit-rate not supported: table index 5 is not in the CiA 305 table (0 1000, 1 800, 2 "
            "500, 3 250, 4 125, 6 50, 7 20, 8 10 kbit/s))");
  // The host's bus: the gateway is no LSS master there; an unknown network: 106.
  EXPECT_EQ(
      run("[2] 1 lss_switch_glob 1"),
      "[2] ERROR: 100 (Request not supported: network 1 is the host's bus: LSS is served on the downstream network "
      "2 only (the gateway is no LSS master upstream))");
  EXPECT_EQ(run("[3] 9 lss_store"),
            "[3] ERROR: 106 (Unsupported net: network 9: this gateway has 1 (upstream, its own dictionary) and 2 "
            "(downstream, the sub-devices))");
  EXPECT_EQ(frames_since({0x7E5, 0x7E4}), Frames{});
  // Nobody in LSS configuration mode: configure node-ID gets no answer (the LSS time-out).
  EXPECT_EQ(run("[4] 2 lss_set_node 5"),
            "[4] ERROR: 103 (Time-out: no LSS slave answered configure node-ID (none in LSS configuration mode?))");
  // The node-ID of a sub-device the gateway runs: refused, nothing sent.
  EXPECT_EQ(run("[5] 2 lss_set_node 17"),
            "[5] ERROR: 102 (Request not processed due to internal state: node-ID 17 is right_grip's, which is on the "
            "bus (operational); only a sub-device the gateway holds missing gives its node-ID away)");
  EXPECT_EQ(frames_since({0x7E5, 0x7E4}), Frames{});
  // The gateway's own LSS work comes first: while it commissions a device, an lss_* is refused.
  std::optional<bool> commissioned;
  // (a selective switch to an address nobody has: it ends at the LSS time-out, changing nothing)
  rig_->gw().downstream().commission(lss::Address{1, 2, 3, 4}, NodeId{0x40}, std::nullopt, loop_.now(),
                                     [&](bool ok, const std::string&) { commissioned = ok; });
  rig_->rearm();
  EXPECT_TRUE(rig_->gw().downstream().own_lss_busy());
  EXPECT_EQ(run("[6] 2 lss_get_node"),
            "[6] ERROR: 102 (Request not processed due to internal state: the gateway is commissioning a device by LSS "
            "itself; try again when it is done)");
  // (its requests queued behind the failed switch still end at their time-outs, then it is done)
  for (int i = 0; i < 2000 && rig_->gw().downstream().own_lss_busy(); ++i) rig_->run_for(1ms);
  ASSERT_TRUE(commissioned);
  EXPECT_FALSE(*commissioned);
  EXPECT_FALSE(rig_->gw().downstream().own_lss_busy());
  EXPECT_EQ(run("[7] 2 lss_switch_glob 0"), "[7] OK");
}

TEST_F(Ctl, TheGatewaysOwnLssWorkInterruptsAFastscan) {
  // A fastscan of 50 ms steps runs (nobody answers its reset step); the gateway's commissioning
  // starts meanwhile: the fastscan is answered 102 and sends no further step.
  std::optional<std::string> answer;
  protocol_.answer(R"({"protocol": 1, "command": "lss", "network": 2, "service": "fastscan", "timeout_ms": 50})",
                   [&answer](std::string a) { answer = std::move(a); });
  rig_->run_for(10ms);
  EXPECT_FALSE(answer);
  rig_->gw().downstream().commission(lss::Address{1, 2, 3, 4}, NodeId{0x40}, std::nullopt, loop_.now(),
                                     [](bool, const std::string&) {});
  rig_->rearm();
  ASSERT_TRUE(answer);
  EXPECT_NE(answer->find(R"("gateway_error":102)"), std::string::npos) << *answer;
  EXPECT_NE(answer->find("interrupted: the gateway is commissioning a device by LSS itself"), std::string::npos)
      << *answer;
  mark_ = down_.size();
  rig_->run_for(500ms);
  std::size_t fastscans = 0;
  for (const auto& [id, data] : frames_since({0x7E5})) fastscans += data[0] == 0x51;
  EXPECT_EQ(fastscans, 0u);
  // Its first frame sends every slave back to waiting (the fastscan's step on the wire may have
  // selected one, which would take the node-ID too), then it selects its own target.
  const Frames lss = frames_since({0x7E5});
  ASSERT_GE(lss.size(), 2u);
  EXPECT_EQ(lss[0].second, (std::vector<std::uint8_t>{0x04, 0, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(lss[1].second[0], 0x40);  // switch state selective, vendor-ID
}

TEST_F(Ctl, OneClientLssScanAtATime) {
  // A slowscan and a fastscan each end with a slave selected: while one runs the other is refused.
  std::optional<std::string> first;
  protocol_.answer(R"({"protocol": 1, "command": "lss", "network": 2, "service": "fastscan", "timeout_ms": 50})",
                   [&first](std::string a) { first = std::move(a); });
  rig_->run_for(10ms);
  const std::string slow = protocol_.answer(
      R"({"protocol": 1, "command": "lss", "network": 2, "service": "slowscan", "range": [1, 2, 0, 9, 0, 9]})");
  EXPECT_NE(slow.find(R"("gateway_error":102)"), std::string::npos) << slow;
  EXPECT_NE(slow.find("a fastscan or slowscan of another client is running"), std::string::npos) << slow;
  rig_->run_for(200ms);
  ASSERT_TRUE(first);  // nobody without node-ID: the fastscan ends
  std::optional<std::string> second;
  protocol_
      .answer(R"({"protocol": 1, "command": "lss", "network": 2, "service": "slowscan", "range": [1, 2, 0, 9, 0, 9]})",
              [&second](std::string a) { second = std::move(a); });
  rig_->run_for(10ms);
  const std::string fast =
      protocol_.answer(R"({"protocol": 1, "command": "lss", "network": 2, "service": "fastscan", "timeout_ms": 50})");
  EXPECT_NE(fast.find("a fastscan or slowscan of another client is running"), std::string::npos) << fast;
}

}  // namespace

// A reload replaces the gateway whose LSS master would answer an lss_* request (CtlService::detach
// while the old gateway still runs): the request in flight is answered 102 then, once, instead of
// never (its client would wait out its own time-out, and then not know what happened).
TEST_F(Ctl, AReloadAnswersAnLssRequestInFlightOnce) {
  std::vector<std::string> answers;
  // Configure node-ID with nobody in LSS configuration mode: no slave answers before the LSS
  // time-out, so the request is in flight.
  protocol_.answer(R"({"command":"lss","network":2,"service":"set_node","node":5})",
                   [&](std::string a) { answers.push_back(std::move(a)); });
  rig_->run_for(5ms);
  ASSERT_EQ(answers, std::vector<std::string>{});
  service_->detach();
  ASSERT_EQ(answers.size(), 1u);
  EXPECT_NE(answers[0].find("\"gateway_error\":102"), std::string::npos) << answers[0];
  EXPECT_NE(answers[0].find("the gateway reloads its mapping file: the LSS request ended unanswered"),
            std::string::npos)
      << answers[0];
  // The old master's time-out that follows answers nothing a second time.
  service_->attach(rig_->gw(), config_);
  rig_->run_for(2s);
  EXPECT_EQ(answers.size(), 1u);
  // And the service goes on: the next request is answered as usual.
  EXPECT_EQ(run("[1] 2 lss_set_node 5"),
            "[1] ERROR: 103 (Time-out: no LSS slave answered configure node-ID (none in LSS configuration mode?))");
}
