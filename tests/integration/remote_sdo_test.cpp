// Remote SDO through the gateway on the virtual buses: the simulated cab of
// rig/cab_rig.hpp on tests/fixtures/demo_cab.yaml plus two additional SDO server channels
// (1201h on 690h/6B0h bound to left_grip, 1202h on 691h/6B1h unbound). The host's SDO clients
// (the rig's on the default channel 620h/5A0h, a second host's on the extra channels) reach every
// sub-device; each expected value is read from the simulator's own dictionary (written from the
// manufacturers' documents), never from the gateway. Frames are judged on both buses' taps.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "canopen/301/sdo_client.hpp"
#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "cli/status_command.hpp"
#include "gateway/control/status_report.hpp"
#include "gateway/gateway.hpp"
#include "rig/cab_rig.hpp"
#include "subdevices/sim/mcb402_sim.hpp"
#include "subdevices/sim/novotechnik_406_sim.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "tests/fixtures/fixtures.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
namespace gw = oegw::gateway;
namespace sd = oegw::subdevices;

namespace {

using Bytes = std::vector<std::uint8_t>;

constexpr NodeId kGw{0x20};
constexpr std::uint8_t kUp = 1, kDown = 2;  // the mapping file's default network IDs
constexpr std::uint8_t kGrip = 0x11, kLeft = 0x03, kPedal = 0x30, kKnob = 0x7F, kCluster = 0x31;
constexpr std::uint32_t kDefaultRx = 0x620, kDefaultTx = 0x5A0;
constexpr std::uint32_t kBoundRx = 0x690, kBoundTx = 0x6B0;  // 1201h, bound to left_grip
constexpr std::uint32_t kFreeRx = 0x691, kFreeTx = 0x6B1;    // 1202h, unbound

std::string mapping_yaml() {
  std::string yaml = oegw::fixtures::mapping_file("demo_cab.yaml");
  const std::string after = "  heartbeat_ms: 100\n";  // upstream's, the first of the file
  yaml.insert(yaml.find(after) + after.size(),
              "  sdo_servers:\n"
              "    - { subdevice: left_grip, request: 0x690, response: 0x6B0 }\n"
              "    - { request: 0x691, response: 0x6B1 }\n");
  return yaml;
}

struct Result {
  bool done = false;
  SdoAbortCode code = SdoAbortCode::GeneralError;
  Bytes data;
};

class RemoteSdo : public ::testing::Test {
 protected:
  void SetUp() override { build(); }

  // `downstream_extra` goes into the downstream flow map (", sdo_timeout_ms: 100").
  void build(gw::GatewayOptions options = {}, Duration host_timeout = 3s, const std::string& downstream_extra = "") {
    std::string yaml = mapping_yaml();
    const std::string down = "downstream: { interface: virtual, bitrate: 250000";
    yaml.insert(yaml.find(down) + down.size(), downstream_extra);
    auto loaded = oegw::mapping::load_config_text(yaml, "remote.yaml", gw::driver_catalogue());
    ASSERT_TRUE(loaded.ok()) << loaded.error_text();
    config_ = std::move(*loaded.config);
    store_ = std::filesystem::path(::testing::TempDir()) / fmt::format("remote_sdo_{}.store", ::getpid());
    std::filesystem::remove(store_);
    rig_ = std::make_unique<oegw::rig::CabRig>(config_, loop_,
                                               oegw::rig::CabRigOptions{.store = store_,
                                                                        .host_sdo_timeout = host_timeout,
                                                                        .gateway = options});
    rig_->up().set_tap([this](const BusRecord& r) { up_.push_back(r.frame); });
    rig_->down().set_tap([this](const BusRecord& r) { down_.push_back(r.frame); });
    rig_->to_devices = [this](const CanFrame& f) { return drop_to_devices_ && drop_to_devices_(f); };
    rig_->to_gateway_down = [this](const CanFrame& f) { return drop_to_gateway_ && drop_to_gateway_(f); };
    rig_->on_gateway = [this](gw::Gateway& g) { g.on_log = [this](const std::string& l) { log_ += l + "\n"; }; };
    rig_->build();
    // A second host tool on the extra channels: plain SDO clients, no network indication needed.
    port2_ = rig_->up().attach("host2");
    bound_ = std::make_unique<SdoClient>([this](const CanFrame& f) { (void)port2_->send(f); },
                                         SdoClientConfig{.request_cob = CobId(kBoundRx),
                                                         .response_cob = CobId(kBoundTx),
                                                         .timeout = host_timeout});
    free_ = std::make_unique<SdoClient>([this](const CanFrame& f) { (void)port2_->send(f); },
                                        SdoClientConfig{.request_cob = CobId(kFreeRx),
                                                        .response_cob = CobId(kFreeTx),
                                                        .timeout = host_timeout});
    port2_->set_receiver([this](const CanFrame& f, TimePoint t) {
      (void)bound_->on_frame(f, t);
      (void)free_->on_frame(f, t);
    });
    rig_->power_on();
    run_for(3s);
    for (const auto& n : rig_->gw().downstream().names())
      ASSERT_EQ(rig_->gw().downstream().state(n), sd::NodeState::Operational) << n << "\n" << log_;
  }
  void TearDown() override {
    port2_.reset();
    rig_.reset();
    std::filesystem::remove(store_);
  }

  void run_for(Duration d) {
    const TimePoint end = loop_.now() + d;
    while (loop_.now() < end) {
      bound_->advance(loop_.now());
      free_->advance(loop_.now());
      rig_->rearm();
      loop_.advance_by(1ms);
    }
  }
  // Runs until `r` is done (at most 5 s of simulated time).
  void wait(const Result& r) {
    for (int i = 0; i < 5000 && !r.done; ++i) run_for(1ms);
    ASSERT_TRUE(r.done) << "the transfer never finished\n" << log_;
  }
  SdoClient::Callback into(Result& r) {
    return [&r](SdoAbortCode c, Bytes d) {
      r.code = c;
      r.data = std::move(d);
      r.done = true;
    };
  }
  Result read(SdoClient& c, std::uint16_t index, std::uint8_t sub, SdoTransfer mode = SdoTransfer::Auto) {
    Result r;
    c.upload(index, sub, into(r), mode);
    wait(r);
    return r;
  }
  Result write(SdoClient& c, std::uint16_t index, std::uint8_t sub, Bytes data) {
    Result r;
    c.download(index, sub, std::move(data), into(r));
    wait(r);
    return r;
  }
  SdoClient& host() { return rig_->host().sdo(kGw); }

  // The network indication as a raw frame on channel `rx`; returns the gateway's answer on `tx`.
  std::optional<CanFrame> indicate(std::uint8_t network, std::uint8_t node, std::uint32_t rx = kDefaultRx,
                                   std::uint32_t tx = kDefaultTx) {
    const std::size_t from = up_.size();
    (void)rig_->host_port().send(CanFrame(rx, {0xE0, 0, 0, 0, network, node, 0, 0}));
    run_for(5ms);
    for (std::size_t i = from; i < up_.size(); ++i)
      if (up_[i].id == tx) return up_[i];
    return std::nullopt;
  }
  void select(std::uint8_t network, std::uint8_t node) {
    const auto answer = indicate(network, node);
    ASSERT_TRUE(answer.has_value());
    ASSERT_EQ(answer->data, (std::array<std::uint8_t, 8>{0xE0, 0, 0, 0, network, node, 0, 0}));
  }
  std::uint32_t sim_u32(const char* device, std::uint16_t index, std::uint8_t sub) {
    auto* d = rig_->devices().device(device);
    EXPECT_NE(d, nullptr) << device;
    return d == nullptr ? 0 : d->od().get<std::uint32_t>(index, sub);
  }
  std::string sim_string(const char* device, std::uint16_t index) {
    const Bytes v = rig_->devices().device(device)->od().find(index)->find(0)->value;
    return {v.begin(), v.end()};
  }
  bool downstream_has(std::uint32_t id, std::initializer_list<std::uint8_t> head) const {
    for (const auto& f : down_) {
      if (f.id != id || f.dlc < head.size()) continue;
      if (std::equal(head.begin(), head.end(), f.data.begin())) return true;
    }
    return false;
  }

  SimulatedClock clock_;
  EventLoop loop_{clock_};
  oegw::mapping::Config config_;
  std::filesystem::path store_;
  std::unique_ptr<oegw::rig::CabRig> rig_;
  std::unique_ptr<VirtualPort> port2_;
  std::unique_ptr<SdoClient> bound_, free_;
  std::function<bool(const CanFrame&)> drop_to_devices_, drop_to_gateway_;
  std::vector<CanFrame> up_, down_;
  std::string log_;
};

TEST_F(RemoteSdo, EveryFamilysIdentityThroughANetworkIndication) {
  const std::pair<const char*, std::uint8_t> nodes[] = {{"right_grip", kGrip},
                                                        {"left_grip", kLeft},
                                                        {"pedal", kPedal},
                                                        {"seat_knob", kKnob},
                                                        {"cluster", kCluster}};
  for (const auto& [name, node] : nodes) {
    select(kDown, node);
    for (std::uint8_t sub = 1; sub <= 2; ++sub) {
      const Result r = read(host(), 0x1018, sub);
      ASSERT_EQ(r.code, SdoAbortCode::None) << name << " 1018h:" << int(sub) << "\n" << log_;
      ASSERT_EQ(r.data.size(), 4u);
      EXPECT_EQ(get_u32(r.data.data()), sim_u32(name, 0x1018, sub)) << name;
    }
    // The request went to that node's default SDO server on the cab's bus.
    EXPECT_TRUE(downstream_has(0x600 + node, {0x40, 0x18, 0x10, 0x01})) << name;
  }
}

TEST_F(RemoteSdo, SegmentedAndBlockUploadsOfAString) {
  select(kDown, kKnob);
  const std::string expected = sim_string("seat_knob", 0x1008);
  ASSERT_EQ(expected, "MC1-2832-A7F-614-511");  // Novotechnik document §4.1
  for (const SdoTransfer mode : {SdoTransfer::Auto, SdoTransfer::Block}) {
    const Result r = read(host(), 0x1008, 0, mode);
    ASSERT_EQ(r.code, SdoAbortCode::None) << log_;
    EXPECT_EQ(std::string(r.data.begin(), r.data.end()), expected);
  }
  select(kDown, kLeft);
  const Result r = read(host(), 0x1008, 0);
  EXPECT_EQ(std::string(r.data.begin(), r.data.end()), sim_string("left_grip", 0x1008));
}

// Novotechnik §9.1 "Out of range (+)", "Reset via Position Error Reset (see 4.3 Index 0x2100)":
// a host may write 2100h through remote SDO (the driver does not protect it), and the driver's
// fault clears on the sensor's evidence, its "valid position" EMCY 5051h/0/0, not on the write.
TEST_F(RemoteSdo, ANovotechnikPositionErrorResetByTheHostClearsOnTheSensorsValidPosition) {
  auto& knob = dynamic_cast<oegw::subdevices::sim::Novotechnik406Sim&>(*rig_->devices().device("seat_knob"));
  oegw::subdevices::Driver& drv = *rig_->gw().downstream().driver("seat_knob");
  knob.set_position(1000, loop_.now());
  run_for(100ms);
  knob.inject_fault(oegw::subdevices::sim::Novotechnik406Sim::Fault::Overflow, loop_.now());
  run_for(100ms);
  ASSERT_TRUE(drv.faulted(0)) << log_;
  // Still out of range: the write succeeds, the sensor resets nothing, the fault stays.
  knob.set_position(-100, loop_.now());
  select(kDown, kKnob);
  ASSERT_EQ(write(host(), 0x2100, 0, {0x01}).code, SdoAbortCode::None) << log_;
  run_for(100ms);
  EXPECT_TRUE(drv.faulted(0)) << "a write is no evidence";
  EXPECT_EQ(log_.find("EMCY 5051h novotechnik 5051h/0/0"), std::string::npos);
  knob.set_position(1000, loop_.now());
  ASSERT_EQ(write(host(), 0x2100, 0, {0x01}).code, SdoAbortCode::None) << log_;
  run_for(100ms);
  EXPECT_NE(log_.find("EMCY 5051h novotechnik 5051h/0/0"), std::string::npos) << log_;
  EXPECT_FALSE(drv.any_fault()) << log_;
  EXPECT_EQ(rig_->gw().faults().count("seat_knob"), 0u) << log_;
}

TEST_F(RemoteSdo, AnElobauParameterIsWrittenAndReadBack) {
  select(kDown, kGrip);
  ASSERT_EQ(write(host(), 0x5001, 0, {30, 0}).code, SdoAbortCode::None) << log_;
  EXPECT_EQ(rig_->devices().device("right_grip")->od().get<std::uint16_t>(0x5001, 0), 30);
  const Result r = read(host(), 0x5001, 0);
  EXPECT_EQ(r.data, (Bytes{30, 0}));
}

TEST_F(RemoteSdo, WritesOfWhatTheGatewayConfiguredAreRefused) {
  select(kDown, kGrip);
  const std::uint32_t cob = sim_u32("right_grip", 0x1800, 1);
  const std::size_t before = down_.size();
  EXPECT_EQ(write(host(), 0x1800, 1, {0x91, 0x01, 0, 0x80}).code, SdoAbortCode::CannotTransferLocalControl);
  EXPECT_EQ(write(host(), 0x1A00, 0, {0}).code, SdoAbortCode::CannotTransferLocalControl);
  EXPECT_EQ(write(host(), 0x1017, 0, {0, 0}).code, SdoAbortCode::CannotTransferLocalControl);
  EXPECT_EQ(write(host(), 0x1010, 1, {'s', 'a', 'v', 'e'}).code, SdoAbortCode::CannotTransferLocalControl);
  EXPECT_EQ(write(host(), 0x2000, 0x1B, {0}).code, SdoAbortCode::CannotTransferLocalControl);  // driver config
  EXPECT_EQ(write(host(), 0x5999, 2, {0x12}).code, SdoAbortCode::CannotTransferLocalControl);  // elobau LSS
  for (std::size_t i = before; i < down_.size(); ++i)
    EXPECT_NE(down_[i].id, 0x600u + kGrip) << "a refused write reached the grip";
  EXPECT_EQ(sim_u32("right_grip", 0x1800, 1), cob);
  // The Novotechnik's 1800h:05 is in the mapping file's sdo list.
  select(kDown, kKnob);
  EXPECT_EQ(write(host(), 0x1800, 5, {50, 0}).code, SdoAbortCode::CannotTransferLocalControl);
  // Reads are always allowed.
  EXPECT_EQ(read(host(), 0x1800, 5).code, SdoAbortCode::None);
  // Each refusal counts for the sub-device it was aimed at (`oegw status`), and in the totals.
  const gw::Gateway& g = rig_->gw();
  EXPECT_EQ(g.subdevice_refused_commands("right_grip"), 6u);
  EXPECT_EQ(g.subdevice_refused_commands("seat_knob"), 1u);
  EXPECT_EQ(g.subdevice_refused_commands("left_grip"), 0u);
  EXPECT_EQ(g.remote_sdo().counters().refused, 7u);
  EXPECT_EQ(g.subdevice_refused_commands(), 7u);
}

TEST_F(RemoteSdo, RefusedNetworkIndicationsKeepTheTarget) {
  select(kDown, kGrip);
  auto a = indicate(9, kGrip);
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(a->data, (std::array<std::uint8_t, 8>{0x80, 0, 0, 0, 0x00, 0x00, 0x02, 0x06}));  // 0602 0000h
  a = indicate(kDown, 0x44);
  EXPECT_EQ(a->data, (std::array<std::uint8_t, 8>{0x80, 0, 0, 0, 0x11, 0x00, 0x09, 0x06}));  // 0609 0011h
  a = indicate(kUp, 0x05);  // another node of the host's own bus
  EXPECT_EQ(a->data, (std::array<std::uint8_t, 8>{0x80, 0, 0, 0, 0x11, 0x00, 0x09, 0x06}));
  // Still the grip.
  EXPECT_EQ(get_u32(read(host(), 0x1018, 1).data.data()), sim_u32("right_grip", 0x1018, 1));
}

TEST_F(RemoteSdo, NamingTheGatewayItselfReturnsToItsDictionary) {
  select(kDown, kGrip);
  select(kUp, kGw.value());
  EXPECT_EQ(get_u32(read(host(), 0x1018, 2).data.data()), 0x852u);  // demo_cab.yaml's product code
  select(kDown, kKnob);
  select(0, 0);
  EXPECT_EQ(get_u32(read(host(), 0x1018, 2).data.data()), 0x852u);
}

TEST_F(RemoteSdo, ThreeHostChannelsAtOnce) {
  select(kDown, kGrip);
  ASSERT_TRUE(indicate(kDown, kKnob, kFreeRx, kFreeTx).has_value());
  Result a, b, c;
  host().upload(0x1018, 1, into(a));
  bound_->upload(0x1018, 1, into(b));
  free_->upload(0x1008, 0, into(c));
  wait(a);
  wait(b);
  wait(c);
  EXPECT_EQ(a.code, SdoAbortCode::None);
  EXPECT_EQ(get_u32(a.data.data()), sim_u32("right_grip", 0x1018, 1));
  EXPECT_EQ(b.code, SdoAbortCode::None);
  EXPECT_EQ(get_u32(b.data.data()), sim_u32("left_grip", 0x1018, 1));
  EXPECT_EQ(std::string(c.data.begin(), c.data.end()), sim_string("seat_knob", 0x1008));
}

TEST_F(RemoteSdo, TheBoundChannelRefusesANetworkIndication) {
  const auto a = indicate(kDown, kGrip, kBoundRx, kBoundTx);
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(a->data, (std::array<std::uint8_t, 8>{0x80, 0, 0, 0, 0x21, 0x00, 0x00, 0x08}));  // 0800 0021h
  EXPECT_EQ(get_u32(read(*bound_, 0x1018, 1).data.data()), sim_u32("left_grip", 0x1018, 1));
}

TEST_F(RemoteSdo, ASecondRequestWhileOneIsInFlight) {
  select(kDown, kGrip);
  drop_to_devices_ = [](const CanFrame& f) { return f.id == 0x600u + kGrip; };  // the grip never hears it
  const std::size_t up0 = up_.size(), down0 = down_.size();
  (void)rig_->host_port().send(CanFrame(kDefaultRx, {0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0}));
  run_for(5ms);
  (void)rig_->host_port().send(CanFrame(kDefaultRx, {0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0}));
  run_for(5ms);
  std::vector<CanFrame> answers;
  for (std::size_t i = up0; i < up_.size(); ++i)
    if (up_[i].id == kDefaultTx) answers.push_back(up_[i]);
  ASSERT_EQ(answers.size(), 1u);
  EXPECT_EQ(answers[0].data,
            (std::array<std::uint8_t, 8>{0x80, 0x08, 0x10, 0x00, 0x23, 0x00, 0x0A, 0x06}));  // 060A 0023h
  // The first transfer was aborted on the cab's bus with the same code.
  bool aborted = false;
  for (std::size_t i = down0; i < down_.size(); ++i)
    aborted |= down_[i].id == 0x600u + kGrip &&
               down_[i].data == std::array<std::uint8_t, 8>{0x80, 0x18, 0x10, 0x01, 0x23, 0x00, 0x0A, 0x06};
  EXPECT_TRUE(aborted);
}

TEST_F(RemoteSdo, ANodeBeingBootedIsRefusedUntilItIsUp) {
  select(kDown, kGrip);
  // The grip reboots; its SDO answers are held back, so the gateway's configuration of it stays
  // in progress (on the virtual bus it would otherwise finish within one step).
  drop_to_gateway_ = [](const CanFrame& f) { return f.id == 0x580u + kGrip; };
  (void)rig_->command("right_grip reboot");
  run_for(50ms);
  ASSERT_EQ(rig_->gw().downstream().state("right_grip"), sd::NodeState::Configuring) << log_;
  const std::size_t down0 = down_.size();
  EXPECT_EQ(read(host(), 0x1018, 1).code, SdoAbortCode::CannotTransferDeviceState);
  std::size_t grip_requests = 0;
  for (std::size_t i = down0; i < down_.size(); ++i) grip_requests += down_[i].id == 0x600u + kGrip ? 1 : 0;
  EXPECT_EQ(grip_requests, 0u) << "the refused read reached the grip";
  drop_to_gateway_ = nullptr;
  run_for(5s);
  ASSERT_EQ(rig_->gw().downstream().state("right_grip"), sd::NodeState::Operational) << log_;
  EXPECT_EQ(read(host(), 0x1018, 1).code, SdoAbortCode::None);
}

TEST_F(RemoteSdo, TheGatewayTakingANodeBackEndsATransferInFlight) {
  select(kDown, kGrip);
  drop_to_devices_ = [](const CanFrame& f) { return f.id == 0x600u + kGrip; };  // it stays in flight
  Result r;
  host().upload(0x1018, 1, into(r));
  run_for(10ms);
  ASSERT_FALSE(r.done);
  drop_to_devices_ = nullptr;
  (void)rig_->command("right_grip reboot");  // its boot-up: the gateway reconfigures it at once
  run_for(10ms);
  ASSERT_TRUE(r.done) << "the host still waits for a node the gateway took back\n" << log_;
  EXPECT_EQ(r.code, SdoAbortCode::CannotTransferDeviceState);
  run_for(3s);
  EXPECT_EQ(rig_->gw().downstream().state("right_grip"), sd::NodeState::Operational) << log_;
}

// A reload replaces the gateway around the same upstream device: the transfers in progress on
// its SDO servers end with the old gateway, each client told at once (0800 0022h) on its own
// channel rather than left to its time-out — a bound channel's and a network indication's.
TEST_F(RemoteSdo, AReloadEndsTheTransfersInFlightWithAnAbortToTheirClients) {
  select(kDown, kGrip);
  drop_to_devices_ = [](const CanFrame& f) { return f.id == 0x600u + kGrip || f.id == 0x600u + kLeft; };
  Result on_default, on_bound;
  host().upload(0x1018, 1, into(on_default));
  bound_->upload(0x1018, 1, into(on_bound));
  run_for(10ms);
  ASSERT_FALSE(on_default.done);
  ASSERT_FALSE(on_bound.done);
  drop_to_devices_ = nullptr;
  ASSERT_TRUE(rig_->reload(config_).empty()) << "the same file: valid";
  run_for(10ms);
  ASSERT_TRUE(on_default.done) << "the host still waits on the default channel\n" << log_;
  EXPECT_EQ(on_default.code, SdoAbortCode::CannotTransferDeviceState);
  ASSERT_TRUE(on_bound.done) << "the host still waits on the bound channel\n" << log_;
  EXPECT_EQ(on_bound.code, SdoAbortCode::CannotTransferDeviceState);
  run_for(3s);
  EXPECT_EQ(read(*bound_, 0x1018, 1).code, SdoAbortCode::None) << "the bound channel serves again\n" << log_;
}

TEST_F(RemoteSdo, NodeIdBitRateAndEmcyCobIdOfSubdevicesInUseAreRefused) {
  select(kDown, kKnob);  // Novotechnik document §4.3, §7.1: 2000h node-ID, 2001h bit rate by SDO
  EXPECT_EQ(write(host(), 0x2000, 0, {0x40}).code, SdoAbortCode::CannotTransferLocalControl);
  EXPECT_EQ(write(host(), 0x2001, 0, {0xF4, 0x01}).code, SdoAbortCode::CannotTransferLocalControl);
  EXPECT_EQ(write(host(), 0x6003, 0, {0, 0, 0, 0}).code, SdoAbortCode::CannotTransferLocalControl);  // preset
  EXPECT_EQ(rig_->devices().device("seat_knob")->od().get<std::uint8_t>(0x2000, 0), kKnob);
  // The MCB-402's 1014h: with bit 31 set its cable-break EMCY would never reach the gateway.
  select(kDown, kLeft);
  EXPECT_EQ(write(host(), 0x1014, 0, {0x83, 0x00, 0x00, 0x80}).code, SdoAbortCode::CannotTransferLocalControl);
  EXPECT_EQ(write(host(), 0x6200, 1, {0x0F}).code, SdoAbortCode::CannotTransferLocalControl);  // its LEDs
  auto& mcb = dynamic_cast<oegw::subdevices::sim::Mcb402Sim&>(*rig_->devices().device("left_grip"));
  mcb.cable_break(2, true, loop_.now());
  run_for(500ms);
  EXPECT_FALSE(rig_->gw().faults().empty()) << "the cable break went unseen\n" << log_;
}

// Each object that re-wires or re-flashes a sub-device whose inputs FEs use, written by the host
// as one expedited download frame through a network indication: answered at once with the abort
// frame 0800 0021h naming that object, and not one SDO request reaches the cab's bus. TIME 1012h,
// the SDO server and client parameters 1200h..12FFh (an SDO answer moved onto another device's
// TPDO COB-ID would be taken for its inputs), the EMCY consumer 1028h, program download and
// control 1F50h..1F57h (CiA 302-3), NMT startup 1F80h; the MCB-402's 100Eh "COB-ID guard" (its
// document's object list: rw); the elobau's 5000h "Auto NMT Start" (document 000, Annex A).
TEST_F(RemoteSdo, EveryObjectThatRewiresOrReflashesASubdeviceInUseIsRefusedAtFrameLevel) {
  struct Write {
    std::uint8_t node;
    std::uint16_t index;
    std::uint8_t sub;
  };
  const std::vector<Write> writes = {{kGrip, 0x1012, 0x00},  {kGrip, 0x1200, 0x01},   {kGrip, 0x1200, 0x02},
                                     {kGrip, 0x1201, 0x01},  {kGrip, 0x1280, 0x01},   {kGrip, 0x1280, 0x02},
                                     {kGrip, 0x12FF, 0x03},  {kGrip, 0x1028, 0x01},   {kGrip, 0x1F50, 0x01},
                                     {kGrip, 0x1F51, 0x01},  {kGrip, 0x1F52, 0x01},   {kGrip, 0x1F53, 0x01},
                                     {kGrip, 0x1F54, 0x01},  {kGrip, 0x1F55, 0x01},   {kGrip, 0x1F56, 0x01},
                                     {kGrip, 0x1F57, 0x01},  {kGrip, 0x1F80, 0x00},   {kGrip, 0x5000, 0x00},
                                     {kLeft, 0x100E, 0x00},  {kLeft, 0x1200, 0x02},   {kKnob, 0x1F51, 0x01},
                                     {kPedal, 0x1280, 0x01}, {kCluster, 0x1012, 0x00}};
  for (const Write& w : writes) {
    select(kDown, w.node);
    const std::size_t up0 = up_.size(), down0 = down_.size();
    const auto lo = static_cast<std::uint8_t>(w.index), hi = static_cast<std::uint8_t>(w.index >> 8);
    // 23h: expedited download of 4 bytes, e.g. an SDO server COB-ID of 191h (the grip's TPDO #0).
    (void)rig_->host_port().send(CanFrame(kDefaultRx, {0x23, lo, hi, w.sub, 0x91, 0x01, 0x00, 0x00}));
    run_for(20ms);
    std::vector<CanFrame> answers;
    for (std::size_t i = up0; i < up_.size(); ++i)
      if (up_[i].id == kDefaultTx) answers.push_back(up_[i]);
    ASSERT_EQ(answers.size(), 1u) << fmt::format("{:02X}h {:04X}h:{:02X}", w.node, w.index, w.sub);
    EXPECT_EQ(answers[0].data, (std::array<std::uint8_t, 8>{0x80, lo, hi, w.sub, 0x21, 0x00, 0x00, 0x08}))
        << fmt::format("{:02X}h {:04X}h:{:02X}: {}", w.node, w.index, w.sub, answers[0].to_string());
    for (std::size_t i = down0; i < down_.size(); ++i)
      EXPECT_FALSE(down_[i].id >= 0x600 && down_[i].id <= 0x67F)
          << fmt::format("{:02X}h {:04X}h:{:02X}: {} reached the cab's bus", w.node, w.index, w.sub,
                         down_[i].to_string());
  }
  EXPECT_EQ(rig_->gw().remote_sdo().counters().refused, writes.size());
  EXPECT_EQ(rig_->gw().remote_sdo().counters().transfers, 0u);
  // Reads of the same objects stay allowed: the grip's SDO server COB-IDs.
  select(kDown, kGrip);
  const Result r = read(host(), 0x1200, 2);
  ASSERT_EQ(r.code, SdoAbortCode::None) << log_;
  EXPECT_EQ(get_u32(r.data.data()), 0x580u + kGrip);
}

// A network indication's redirect is logged when it begins and ends and listed by `oegw status`
// (status_report, and the table) while in force: which SDO server channel, which network and
// node, since when, by which request. It ends when a network indication names the gateway and
// when the gateway is reset (NMT reset communication).
TEST_F(RemoteSdo, ARedirectIsShownInTheLogAndStatusUntilItEnds) {
  const TimePoint started = loop_.now();
  const auto redirects = [&] {
    return gw::control::status_report(rig_->gw(), config_, {loop_.now(), started})["upstream"]["sdo_redirects"];
  };
  EXPECT_TRUE(redirects().empty());
  log_.clear();
  select(kDown, kGrip);
  EXPECT_NE(log_.find(
                "remote SDO: SDO server 1200h (620h/5A0h) redirected to right_grip (network 2, node 11h) by the "
                "network indication E0 00 00 00 02 11 00 00: every client on 620h now reaches right_grip, not the "
                "gateway, until a network indication names the gateway (network 1, node 20h, or network 0, node "
                "0) or the gateway is reset or stopped (NMT)"),
            std::string::npos)
      << log_;
  run_for(1500ms);
  nlohmann::json r = redirects();
  ASSERT_EQ(r.size(), 1u) << r.dump();
  EXPECT_EQ(r[0]["sdo_server"], 0x1200);
  EXPECT_EQ(r[0]["request_cob_id"], kDefaultRx);
  EXPECT_EQ(r[0]["response_cob_id"], kDefaultTx);
  EXPECT_EQ(r[0]["network_id"], kDown);
  EXPECT_EQ(r[0]["node_id"], kGrip);
  EXPECT_EQ(r[0]["subdevice"], "right_grip");
  EXPECT_GE(r[0]["age_ms"].get<std::int64_t>(), 1500);
  EXPECT_LT(r[0]["age_ms"].get<std::int64_t>(), 1510);
  EXPECT_EQ(r[0]["indication"], nlohmann::json::array({0xE0, 0, 0, 0, kDown, kGrip, 0, 0}));
  // The table names it too, wrapped to 100 columns (read here with its wrapped lines joined).
  std::string table = oegw::cli::status_table(gw::control::status_report(rig_->gw(), config_, {loop_.now(), started}));
  for (std::size_t at = 0; (at = table.find("\n    ", at)) != std::string::npos;) table.replace(at, 5, " ");
  const std::string line =
      "remote SDO: SDO server 1200h (620h/5A0h) redirected to right_grip (network 2, node 11h) "
      "for 1.5 s by the network indication E0 00 00 00 02 11 00 00: a client on 620h reaches "
      "right_grip, not the gateway\n";
  EXPECT_NE(table.find(line), std::string::npos) << table;
  // The bound channel is configured, not redirected: not listed. The free one, redirected too.
  ASSERT_TRUE(indicate(kDown, kKnob, kFreeRx, kFreeTx).has_value());
  r = redirects();
  ASSERT_EQ(r.size(), 2u) << r.dump();
  EXPECT_EQ(r[1]["sdo_server"], 0x1202);
  EXPECT_EQ(r[1]["subdevice"], "seat_knob");
  // Naming the gateway ends the first.
  log_.clear();
  select(kUp, kGw.value());
  EXPECT_NE(log_.find("remote SDO: SDO server 1200h (620h/5A0h) reaches the gateway's own dictionary again (a network "
                      "indication named the gateway): its redirect to right_grip (network 2, node 11h) lasted 1.5 s"),
            std::string::npos)
      << log_;
  r = redirects();
  ASSERT_EQ(r.size(), 1u) << r.dump();
  EXPECT_EQ(r[0]["sdo_server"], 0x1202);
  // NMT reset communication of the gateway ends the other.
  log_.clear();
  (void)rig_->host_port().send(CanFrame(0x000, {0x82, kGw.value()}));
  run_for(100ms);
  EXPECT_NE(log_.find("remote SDO: SDO server 1202h (691h/6B1h) reaches the gateway's own dictionary again (NMT reset "
                      "or stop of the gateway): its redirect to seat_knob (network 2, node 7Fh) lasted"),
            std::string::npos)
      << log_;
  EXPECT_TRUE(redirects().empty());
}

TEST_F(RemoteSdo, AnExpeditedDownloadWithoutSizeIsRelayedAsOne) {
  // 100Ch guard time (UNSIGNED16) written as the MCB-402 document writes its SDOs: 22h, no size.
  select(kDown, kLeft);
  const std::size_t up0 = up_.size();
  (void)rig_->host_port().send(CanFrame(kDefaultRx, {0x22, 0x0C, 0x10, 0x00, 0x05, 0x00, 0x00, 0x00}));
  run_for(20ms);
  EXPECT_TRUE(downstream_has(0x600u + kLeft, {0x22, 0x0C, 0x10, 0x00, 0x05, 0x00, 0x00, 0x00}));
  std::optional<CanFrame> answer;
  for (std::size_t i = up0; i < up_.size(); ++i)
    if (up_[i].id == kDefaultTx) answer = up_[i];
  ASSERT_TRUE(answer.has_value());
  EXPECT_EQ(answer->data, (std::array<std::uint8_t, 8>{0x60, 0x0C, 0x10, 0x00, 0, 0, 0, 0}));
  EXPECT_EQ(rig_->devices().device("left_grip")->od().get<std::uint16_t>(0x100C, 0), 5);
}

TEST_F(RemoteSdo, SegmentedAndBlockDownloadsFromTheHost) {
  // The host chooses segmented or block on its bus; the gateway writes the grip as the value's
  // size allows (expedited for two bytes).
  select(kDown, kGrip);
  std::uint8_t v = 40;
  for (const SdoTransfer mode : {SdoTransfer::Segmented, SdoTransfer::Block}) {
    Result r;
    host().download(0x5001, 0, {v, 0}, into(r), mode);
    wait(r);
    ASSERT_EQ(r.code, SdoAbortCode::None) << log_;
    EXPECT_EQ(rig_->devices().device("right_grip")->od().get<std::uint16_t>(0x5001, 0), v);
    v = static_cast<std::uint8_t>(v + 1);
  }
  // A block upload of each family's 1018h:01.
  for (const auto& [name, node] : {std::pair{"right_grip", kGrip}, std::pair{"left_grip", kLeft},
                                   std::pair{"pedal", kPedal}, std::pair{"seat_knob", kKnob}}) {
    select(kDown, node);
    const Result r = read(host(), 0x1018, 1, SdoTransfer::Block);
    ASSERT_EQ(r.code, SdoAbortCode::None) << name;
    EXPECT_EQ(get_u32(r.data.data()), sim_u32(name, 0x1018, 1)) << name;
  }
}

class RemoteSdoTimeout : public RemoteSdo {
 protected:
  // The gateway's downstream SDO time-out (downstream.sdo_timeout_ms: 100) below the encoder's
  // heartbeat consumer time (150 ms): a silent node is first a remote time-out, then missing.
  void SetUp() override { build({}, 3s, ", sdo_timeout_ms: 100"); }
};

TEST_F(RemoteSdoTimeout, APoweredOffNodeTimesOutThenIsMissing) {
  select(kDown, kKnob);
  (void)rig_->command("seat_knob silent on");
  EXPECT_EQ(read(host(), 0x1018, 1).code, SdoAbortCode::Timeout);
  run_for(1s);
  ASSERT_EQ(rig_->gw().downstream().state("seat_knob"), sd::NodeState::Missing) << log_;
  EXPECT_EQ(read(host(), 0x1018, 1).code, SdoAbortCode::HardwareError);
  (void)rig_->command("seat_knob silent off");
}

}  // namespace
