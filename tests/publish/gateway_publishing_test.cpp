// The gateway's publishing (GatewayPublishing) over LCM, in-process: a simulated elobau grip
// booted by the Gateway (virtual bus, simulated clock) -> joystick.1 on OEGW_JOYSTICK_1 as a
// second LCM instance (the machine application) receives it; its indicator command on
// OEGW_INDICATORS_1 -> the gateway -> the grip's LEDs; a DDS writer likewise. Each indicator FE
// takes only the sources its `sources` list (LCM for indicators.1; the host and DDS for
// indicators.2): the others are refused and counted. Runs in a private network namespace.
#include <gtest/gtest.h>
#include <lcm/lcm.h>
#include <poll.h>

#include <chrono>
#include <functional>
#include <optional>
#include <set>
#include <vector>

#include "../integration/virtual_network.hpp"
#include "dds_command_writer.hpp"
#include "gateway/gateway.hpp"
#include "gateway/publishing.hpp"
#include "oegw/gateway_status_t.hpp"
#include "oegw/indicator_command_t.hpp"
#include "oegw/joystick_t.hpp"
#include "private_network.hpp"
#include "subdevices/sim/elobau_mfg_sim.hpp"
#include "subdevices/sim/sim_bench.hpp"
#include "tests/fixtures/fixtures.hpp"

using namespace oegw;
using namespace oegw::canopen;
using namespace std::chrono_literals;

namespace {

struct App {  // the machine application: its own LCM instance
  lcm_t* lcm = lcm_create("udpm://224.0.0.1:7667?ttl=0");
  std::optional<oegw::joystick_t> last;
  std::optional<oegw::gateway_status_t> status;
  ~App() {
    if (lcm) lcm_destroy(lcm);
  }
  static void on_joystick(const lcm_recv_buf_t* rbuf, const char*, void* user) {
    oegw::joystick_t m;
    if (m.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) >= 0) static_cast<App*>(user)->last = m;
  }
  static void on_status(const lcm_recv_buf_t* rbuf, const char*, void* user) {
    oegw::gateway_status_t m;
    if (m.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) >= 0) static_cast<App*>(user)->status = m;
  }
};

// Waits (bounded) until `fd` is readable, then runs `work`.
bool wait_readable(int fd, int ms) {
  pollfd p{fd, POLLIN, 0};
  return ::poll(&p, 1, ms) > 0;
}

// publishing_grip.yaml's gateway between two virtual networks, the elobau grip simulated on
// the downstream one (each test attaches the gateway's sides itself).
struct GripCab {
  mapping::LoadResult loaded = mapping::load_config_text(fixtures::mapping_file("publishing_grip.yaml"), "test.yaml",
                                                         gateway::driver_catalogue());
  oegw::testing::VirtualNetwork down, up;
  subdevices::sim::SimBench bench{down.sink("sims")};
  std::unique_ptr<gateway::Gateway> gw;
  // Empty when set up; else what failed.
  std::string error = set_up();

 private:
  std::string set_up() {
    if (!loaded.ok()) return loaded.error_text();
    std::string e;
    auto spec = subdevices::parse_device_spec("elobau-mfg:0x11:name=grip", e);
    if (!spec || !bench.add(*spec, e)) return e;
    gateway::GatewayOptions opt;
    opt.store_path = "";
    gw = std::make_unique<gateway::Gateway>(*loaded.config, up.sink("gateway"), down.sink("gateway"), opt);
    down.attach("sims", bench);
    return {};
  }
};

TEST(GatewayPublishing, JoystickGoesOutOnLcmAndCommandsOverLcmAndDdsLightOnlyTheLedsOfFesListingThem) {
  GripCab cab;
  ASSERT_EQ(cab.error, "");
  auto& loaded = cab.loaded;
  auto& down = cab.down;
  auto& up = cab.up;
  auto& bench = cab.bench;
  gateway::Gateway& gw = *cab.gw;
  // The gateway sits on two buses: one driver per side is enough for frames; its timers run
  // from the downstream network's loop.
  struct Up {
    gateway::Gateway& gw;
    bool on_frame(const CanFrame& f, TimePoint t) { return gw.on_upstream_frame(f, t); }
    void advance(TimePoint) {}
    std::optional<TimePoint> next_deadline() const { return std::nullopt; }
  } up_side{gw};
  // The reception time of every frame the grip sends, as the bus delivered it (µs): what a
  // sample's timestamp_us must be (docs/guides/dds-lcm.md: the source time, not the publish time).
  std::set<std::int64_t> grip_frames_us;
  struct Down {
    gateway::Gateway& gw;
    std::set<std::int64_t>& grip_frames_us;
    bool on_frame(const CanFrame& f, TimePoint t) {
      if ((f.id & 0x7F) == 0x11 && f.id >= 0x180 && f.id < 0x580)
        grip_frames_us.insert(std::chrono::duration_cast<std::chrono::microseconds>(t.time_since_epoch()).count());
      return gw.on_downstream_frame(f, t);
    }
    void advance(TimePoint t) { gw.advance(t); }
    std::optional<TimePoint> next_deadline() const { return gw.next_deadline(); }
  } down_side{gw, grip_frames_us};
  down.attach("gateway", down_side);
  up.attach("gateway", up_side);

  App app;
  ASSERT_NE(app.lcm, nullptr);
  lcm_subscribe(app.lcm, "OEGW_JOYSTICK_1", &App::on_joystick, &app);
  lcm_subscribe(app.lcm, "OEGW_STATUS", &App::on_status, &app);
  // The publisher's clock runs 7 ms behind the bus, as a loop that reads a frame later than the
  // kernel received it: a sample stamped with the publish time would show it.
  gateway::GatewayPublishing pub(gw, loaded.config->publish, [&down] { return down.now() + 7ms; });
  ASSERT_TRUE(pub.active());

  (void)gw.start(down.now());
  bench.start(down.now());
  down.run_for(2s);
  ASSERT_EQ(gw.downstream().state("grip"), subdevices::NodeState::Operational);
  (void)bench.command("grip x 0", down.now());
  down.run_for(100ms);
  (void)bench.command("grip x 50", down.now());
  down.run_for(100ms);
  // The app receives joystick.1 valid with x = 50 % of full scale.
  for (int i = 0; i < 40 && !(app.last && app.last->x == 16384); ++i) {
    if (wait_readable(lcm_get_fileno(app.lcm), 50)) lcm_handle(app.lcm);
    pub.tick();
  }
  ASSERT_TRUE(app.last.has_value()) << "no joystick sample on OEGW_JOYSTICK_1";
  EXPECT_EQ(app.last->instance, 1);
  EXPECT_EQ(app.last->status, 0) << "valid";
  EXPECT_EQ(app.last->x, 16384) << "50 % -> 32767 * 0.5, rounded";
  // Its timestamp is the reception time of the grip's PDO that carried x = 50 %, and the
  // periodic republishes of the unchanged value (new seq, later publish time) keep it.
  const std::int64_t carried_at = app.last->timestamp_us;
  EXPECT_EQ(grip_frames_us.count(carried_at), 1u) << carried_at << " is not the reception time of a grip frame";
  const std::int32_t first_seq = app.last->seq;
  for (int i = 0; i < 40 && app.last->seq < first_seq + 2; ++i) {
    down.run_for(60ms);  // more than period_ms: the next tick republishes
    pub.tick();
    if (wait_readable(lcm_get_fileno(app.lcm), 50)) lcm_handle(app.lcm);
  }
  ASSERT_GE(app.last->seq, first_seq + 2) << "no periodic republish";
  EXPECT_EQ(app.last->x, 16384);
  EXPECT_EQ(app.last->timestamp_us, carried_at) << "a republish carries the source time, not the publish time";
  EXPECT_LT(app.last->timestamp_us,
            std::chrono::duration_cast<std::chrono::microseconds>(down.now().time_since_epoch()).count() - 100000);

  // The app tries indicators.2 (sources: [canopen]), then lights indicators 1 and 2 of
  // indicators.1: the grip's LEDs 1 and 2 go on, 3 and 4 stay off.
  auto command = [&](std::uint8_t instance, std::int64_t bits) {
    oegw::indicator_command_t cmd;
    cmd.instance = instance;
    cmd.indicators = bits;
    std::vector<std::uint8_t> buf(static_cast<std::size_t>(cmd.getEncodedSize()));
    cmd.encode(buf.data(), 0, static_cast<int>(buf.size()));
    lcm_publish(app.lcm, ("OEGW_INDICATORS_" + std::to_string(instance)).c_str(), buf.data(),
                static_cast<unsigned>(buf.size()));
  };
  command(2, 0x3);
  command(1, 0x3);
  auto* grip = bench.device("grip");
  // The gateway's loop: wait on the transports' fds, poll(), let the bus carry the RPDO.
  auto serve_until = [&](const std::function<bool()>& done) {
    for (int i = 0; i < 200 && !done(); ++i) {
      for (auto* p : pub.publishers())
        if (p->fd() >= 0 && wait_readable(p->fd(), 10)) p->poll();
      down.run_for(10ms);
    }
  };
  serve_until([&] { return grip->output("leds[2]") == 1; });
  EXPECT_EQ(grip->output("leds[1]"), 1);
  EXPECT_EQ(grip->output("leds[2]"), 1);
  EXPECT_EQ(grip->output("leds[3]"), 0) << "indicators.2 takes no LCM commands";
  EXPECT_EQ(grip->output("leds[4]"), 0);
  EXPECT_EQ(gw.refused_commands(), 1u);

  // Over DDS: indicators.1 (LCM only) is refused, indicators.2 (canopen, dds) lights LEDs 3, 4.
  const oegw::test::DdsIndicatorWriter dds(0, "oegw-gateway-publishing");
  ASSERT_TRUE(dds.ready()) << "the gateway's DDS reader never matched";
  ASSERT_TRUE(dds.write(1, 0x0));  // refused
  ASSERT_TRUE(dds.write(2, 0x3));  // taken
  serve_until([&] { return grip->output("leds[4]") == 1; });
  EXPECT_EQ(grip->output("leds[3]"), 1);
  EXPECT_EQ(grip->output("leds[4]"), 1);
  EXPECT_EQ(grip->output("leds[1]"), 1) << "DDS may not clear indicators.1";
  EXPECT_EQ(grip->output("leds[2]"), 1);
  EXPECT_EQ(gw.refused_commands(), 2u);
  // The machine application sees the refusals in the gateway status.
  for (int i = 0; i < 40 && !(app.status && app.status->refused_commands == 2); ++i) {
    pub.tick();
    if (wait_readable(lcm_get_fileno(app.lcm), 50)) lcm_handle(app.lcm);
  }
  ASSERT_TRUE(app.status.has_value()) << "no gateway status on OEGW_STATUS";
  EXPECT_EQ(app.status->refused_commands, 2);
  ASSERT_EQ(app.status->n_subdevices, 1);
  EXPECT_EQ(app.status->n_upstream_emcys, 0) << "no upstream EMCY yet";

  // The grip's EMCY (elobau Table 5: 1000h, 4001h = 0021h "Y Axis, Signal 2, Out Of Range") and
  // one of upstream node 05h, which the gateway consumes (1028h: it has output FEs): the status
  // carries the grip's last EMCY with its reception time and count, and node 05h's.
  const std::int64_t before_us =
      std::chrono::duration_cast<std::chrono::microseconds>(down.now().time_since_epoch()).count();
  dynamic_cast<subdevices::sim::ElobauMfgSim&>(*grip).raise_error(0x0021, down.now());
  down.run_for(50ms);
  auto host = up.sink("host");
  host(CanFrame(0x085, {0x30, 0x81, 0x11, 0x01, 0x02, 0x03, 0x04, 0x05}));
  up.run_for(10ms);
  auto has_both = [&] {
    return app.status && app.status->n_upstream_emcys == 1 && app.status->subdevices[0].last_emcy.code == 0x1000;
  };
  for (int i = 0; i < 40 && !has_both(); ++i) {
    pub.tick();
    if (wait_readable(lcm_get_fileno(app.lcm), 50)) lcm_handle(app.lcm);
  }
  ASSERT_TRUE(has_both()) << "the status never carried both EMCYs";
  const auto& sub = app.status->subdevices[0];
  EXPECT_EQ(sub.name, "grip");
  // The boot diagnostics the grip answered (elobau Table 14: 1008h "JST", 1009h/100Ah "0.00",
  // vendor B4h, product 00010003h; 1001h 00h): every one present.
  EXPECT_EQ(static_cast<std::uint32_t>(sub.identity.vendor_id), 0xB4u);
  EXPECT_EQ(static_cast<std::uint32_t>(sub.identity.product_code), 0x00010003u);
  EXPECT_EQ(sub.identity.device_name, "JST");
  EXPECT_EQ(sub.identity.hardware_version, "0.00");
  EXPECT_EQ(sub.identity.software_version, "0.00");
  EXPECT_EQ(static_cast<std::uint8_t>(sub.identity.present), 0xFF);
  EXPECT_EQ(sub.last_emcy.error_register, 0x00);
  EXPECT_EQ(std::vector<std::uint8_t>(sub.last_emcy.msef, sub.last_emcy.msef + 5),
            (std::vector<std::uint8_t>{0x21, 0x00, 0xFF, 0xFF, 0xFF}));
  EXPECT_GE(sub.last_emcy.timestamp_us, before_us);
  EXPECT_LE(sub.last_emcy.timestamp_us,
            std::chrono::duration_cast<std::chrono::microseconds>(down.now().time_since_epoch()).count());
  EXPECT_GE(sub.emcy_count, 1);
  EXPECT_EQ(sub.emcy_count, static_cast<std::int64_t>(gw.subdevice_emcy("grip").count));
  const auto& u = app.status->upstream_emcys[0];
  EXPECT_EQ(u.node_id, 0x05);
  EXPECT_EQ(static_cast<std::uint16_t>(u.last.code), 0x8130);
  EXPECT_EQ(u.last.error_register, 0x11);
  EXPECT_EQ(std::vector<std::uint8_t>(u.last.msef, u.last.msef + 5), (std::vector<std::uint8_t>{1, 2, 3, 4, 5}));
  EXPECT_EQ(u.count, 1);
}

// What one wake-up of the loop reads (a backlog, when the gateway has fallen behind)
// is published once per FE, with the latest value, at the end of that wake-up: nine changes of
// x read together make one sample (one per frame before: at 5,000 frames/s the publishing kept
// the gateway so far behind that the grip's PDOs came in stale).
TEST(GatewayPublishing, ChangesReadInOneWakeUpPublishEachFeOnceWithItsLatestValue) {
  GripCab cab;
  ASSERT_EQ(cab.error, "");
  auto& loaded = cab.loaded;
  auto& down = cab.down;
  auto& bench = cab.bench;
  gateway::Gateway& gw = *cab.gw;
  struct Side {
    gateway::Gateway& gw;
    bool on_frame(const CanFrame& f, TimePoint t) { return gw.on_downstream_frame(f, t); }
    void advance(TimePoint t) { gw.advance(t); }
    std::optional<TimePoint> next_deadline() const { return gw.next_deadline(); }
  } side{gw};
  down.attach("gateway", side);
  App app;
  ASSERT_NE(app.lcm, nullptr);
  lcm_subscribe(app.lcm, "OEGW_JOYSTICK_1", &App::on_joystick, &app);
  Duration skew{0};  // the publisher's clock ahead of the bus (for the tick below)
  gateway::GatewayPublishing pub(gw, loaded.config->publish, [&down, &skew] { return down.now() + skew; });
  pub.run_on(down.loop(), [] {});
  (void)gw.start(down.now());
  bench.start(down.now());
  down.run_for(2s);
  ASSERT_EQ(gw.downstream().state("grip"), subdevices::NodeState::Operational);
  // The grip's own TPDOs off: x is what the probe sends (TPDO #0, byte 0: x in %, as can_probe).
  (void)bench.command("grip pdo off", down.now());
  auto probe = down.sink("probe");
  probe(CanFrame(0x191, {0, 0, 0, 0, 0, 0, 0, 0}));
  down.run_for(5ms);
  while (wait_readable(lcm_get_fileno(app.lcm), 20)) lcm_handle(app.lcm);  // the boot's samples, read
  const std::uint64_t before = pub.published();
  for (std::uint8_t v = 10; v <= 90; v = static_cast<std::uint8_t>(v + 10))
    probe(CanFrame(0x191, {v, 0, 0, 0, 0, 0, 0, 0}));
  down.run_for(1ms);  // one delivery of the nine, one wake-up; less than the 50 ms period
  EXPECT_EQ(pub.published() - before, 1u) << "nine changes read in one wake-up: one sample";
  for (int i = 0; i < 40 && !(app.last && app.last->x == 29490); ++i)
    if (wait_readable(lcm_get_fileno(app.lcm), 50)) lcm_handle(app.lcm);
  ASSERT_TRUE(app.last.has_value());
  EXPECT_EQ(app.last->x, 29490) << "the latest value: 90 % of 32767";
  EXPECT_EQ(app.last->status, 0) << "valid";
  // A change in a later wake-up is a sample of its own, as before.
  probe(CanFrame(0x191, {20, 0, 0, 0, 0, 0, 0, 0}));
  down.run_for(1ms);
  EXPECT_EQ(pub.published() - before, 2u);
  // A press and release of button 1 (TPDO #0 byte 5, bit 0) read in one wake-up: both go out,
  // the press first; only axes merge.
  probe(CanFrame(0x191, {20, 0, 0, 0, 0, 0x01, 0, 0}));
  probe(CanFrame(0x191, {20, 0, 0, 0, 0, 0x00, 0, 0}));
  down.run_for(1ms);
  EXPECT_EQ(pub.published() - before, 4u) << "a press and a release: two samples";
  std::vector<int> buttons;
  while (wait_readable(lcm_get_fileno(app.lcm), 50)) {
    lcm_handle(app.lcm);
    if (app.last && (buttons.empty() || buttons.back() != app.last->buttons)) buttons.push_back(app.last->buttons);
  }
  EXPECT_EQ(buttons, (std::vector<int>{0, 1, 0}));
  // The period's tick in the same wake-up as a change (in real time the timers run before the
  // posted flush): the change goes out first, never after a republish of the value it replaced.
  skew = 1s;  // every FE due for its republish
  ASSERT_TRUE(gw.on_downstream_frame(CanFrame(0x191, {40, 0, 0, 0, 0, 0, 0, 0}), down.now()));
  pub.tick();
  app.last.reset();
  ASSERT_TRUE(wait_readable(lcm_get_fileno(app.lcm), 500));
  lcm_handle(app.lcm);
  ASSERT_TRUE(app.last.has_value());
  EXPECT_EQ(app.last->x, 13107) << "the first sample after the tick: the change (40 %), not the old 20 %";
}

}  // namespace

int main(int argc, char** argv) {
  oegw::test::enter_private_network();  // lo only, for this process
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
