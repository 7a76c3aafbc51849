#include "programs/core_demo.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <deque>
#include <functional>
#include <numbers>
#include <string>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "canopen/io/event_loop.hpp"
#include "canopen/io/socketcan_transport.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "canopen/master.hpp"
#include "gateway/publishing.hpp"
#include "publish/dds_publisher.hpp"
#include "publish/lcm_publisher.hpp"
#include "publish/publish_schedule.hpp"

namespace oegw::programs {

using namespace gateway;  // the programs compose the daemon's library

using namespace canopen;
using namespace canopen::io;
using namespace std::chrono_literals;

namespace {

constexpr std::uint32_t kDeviceType = 0x000F0191;  // CiA 401 profile, digital+analogue in/out

std::int16_t full_scale(double v) { return static_cast<std::int16_t>(std::lround(v * 32767.0)); }

}  // namespace

DemoDevice::DemoDevice(NodeId id, FrameSink sink, std::filesystem::path store_path, std::uint16_t heartbeat_ms) {
  od_.add_array(0x6000, "Read input 8-bit", DataType::Unsigned8, Access::ReadOnly, 2, {0}, true);
  od_.add_array(0x6401, "Read analogue input 16-bit", DataType::Integer16, Access::ReadOnly, 2, encode<std::int16_t>(0),
                true);
  od_.add_array(0x6200, "Write output 8-bit", DataType::Unsigned8, Access::ReadWrite, 1, {0}, true);
  install_tpdo(od_, 1,
               PdoParameters{.cob_id = cob::kTpdo1 + id.value(),
                             .transmission_type = 0xFF,
                             .inhibit_time = 100,  // 10 ms
                             .event_timer = 500,
                             .mapping = {pdo_map(0x6401, 1, 16), pdo_map(0x6401, 2, 16), pdo_map(0x6000, 1, 8)}});
  install_rpdo(od_, 1,
               PdoParameters{.cob_id = cob::kRpdo1 + id.value(),
                             .transmission_type = 0xFF,
                             .mapping = {pdo_map(0x6200, 1, 8)}});
  NodeConfig cfg;
  cfg.node_id = id;
  cfg.device_type = kDeviceType;
  cfg.device_name = "oegw demo device";
  cfg.software_version = "oegw 0.1.0";
  cfg.identity = {.vendor = 0x00000000, .product = 0x00000852, .revision = 0x00010000, .serial = 1};
  cfg.heartbeat_ms = heartbeat_ms;
  cfg.heartbeat_consumers = 1;
  cfg.store_path = std::move(store_path);
  node_ = std::make_unique<Node>(od_, cfg, std::move(sink));
}

void DemoDevice::move_inputs(TimePoint now) {
  const double t = std::chrono::duration<double>(now.time_since_epoch()).count();
  const double phase = 2.0 * std::numbers::pi * t / 4.0;
  (void)od_.set<std::int16_t>(0x6401, 1, full_scale(std::sin(phase)));
  (void)od_.set<std::int16_t>(0x6401, 2, full_scale(std::cos(phase)));
  (void)od_.set<std::uint8_t>(0x6000, 1, static_cast<std::uint8_t>(static_cast<long long>(t) % 2));
}

// ---- oegw demo ------------------------------------------------------------------------------

namespace {

// A chain of asynchronous steps: each step gets a `next` to call when it is done.
class Script {
 public:
  using Next = std::function<void()>;
  using Step = std::function<void(Next)>;
  void then(Step s) { steps_.push_back(std::move(s)); }
  void run() {
    if (steps_.empty()) {
      if (on_end) on_end();
      return;
    }
    Step s = std::move(steps_.front());
    steps_.pop_front();
    s([this] { run(); });
  }
  std::function<void()> on_end;

 private:
  std::deque<Step> steps_;
};

// `oegw demo`: the state its steps share, one method per step in the order run() takes them,
// each adding to the script what happens then. Members in the order they are made, so they go in
// reverse.
class CoreDemo {
 public:
  CoreDemo(const DemoOptions& o, EventLoop& l, VirtualBus& b) : options(o), loop(l), bus(b) {
    bus.set_tap([this](const BusRecord& r) {
      ++frames;
      if (r.frame.id == 0x720) last_heartbeat = r.time;
      if (options.frames) std::printf("            %-7s %s\n", r.sender.c_str(), r.frame.to_string().c_str());
    });
    dev_driver.bind_receiver(*dev_port, device.node());
    host_driver.bind_receiver(*host_port, host);
  }

  int run() {
    std::printf(
        "oegw demo: the CANopen protocol core (CiA 301 + CiA 305) on an in-process virtual bus.\n"
        "  device: node 0x20, a CiA 401-style I/O node whose two analogue inputs sweep like a joystick\n"
        "  host:   a built-in CANopen master (NMT, SDO client, heartbeat and EMCY consumer)\n"
        "  (the CiA 852 gateway itself is not built yet; run with --frames to see every CAN frame)\n\n");
    open_publishers();
    watch_the_device();
    the_device_powers_on();
    read_the_device();
    remap_tpdo1();
    write_a_read_only_object();
    take_indicator_commands();
    the_inputs_move();
    show_the_joystick();
    write_the_output();
    pull_the_cable();
    plug_it_back();
    script.then(wait(10ms));
    script.on_end = [this] {
      loop.cancel(motion);
      if (publish_tick != 0) loop.cancel(publish_tick);
      for (auto w : publisher_watches) loop.unwatch(w);
      loop.stop();
    };
    loop.post([this] { script.run(); });
    loop.handle_signals({SIGINT, SIGTERM});
    loop.run();
    std::filesystem::remove(store);
    std::filesystem::remove(std::filesystem::path(store.string() + ".lss"));
    return report();
  }

 private:
  double stamp() const { return std::chrono::duration<double>(loop.now() - t0).count(); }
  void say(const std::string& what) const { std::printf("[%7.3f s] %s\n", stamp(), what.c_str()); }
  void fail(const std::string& what) {
    ++failures;
    say("FAILED: " + what);
  }
  std::int64_t now_us() const { return std::chrono::duration_cast<Duration>(loop.now().time_since_epoch()).count(); }

  // DDS / LCM (--publish): joystick.1 from TPDO1, on change and every 100 ms.
  void open_publishers() {
    if (!options.publish) return;
    try {
      // A demo's own names: never mixed with a real gateway's (partition oegw, OEGW_*).
      publish::DdsSettings ds;
      ds.partition = "oegw-demo";
      dds = std::make_unique<publish::DdsPublisher>(ds);
      fan.add(dds.get());
      say("publishing joystick.1 on DDS: topic oegw/joystick, domain 0, partition oegw-demo, loopback only");
    } catch (const publish::PublishError& e) {  // a bad setting, or the machine's state (no route for LCM)
      fail(e.what());
    }
    try {
      publish::LcmSettings ls;
      ls.channel_prefix = "OEGW_DEMO_";
      lcm = std::make_unique<publish::LcmPublisher>(ls);
      fan.add(lcm.get());
      say("publishing joystick.1 on LCM: channel OEGW_DEMO_JOYSTICK_1, udpm://224.0.0.1:7667?ttl=0");
    } catch (const publish::PublishError& e) {  // a bad setting, or the machine's state (no route for LCM)
      fail(e.what());
    }
  }

  void publish_status(const char* device_state) {
    if (fan.empty()) return;
    gateway::GatewayStatus st;
    st.timestamp_us = now_us();
    st.seq = ++status_seq;
    st.upstream_state = "demo";
    st.subdevices.push_back({"device", dev_id.value(), device_state});
    fan.publish(st);
  }

  // The host's view of the device: its boot-up, EMCYs, heartbeat and TPDO1.
  void watch_the_device() {
    host.on_boot = [this](NodeId n) {
      booted = true;
      publish_status("booted");
      say(fmt::format("host: node 0x{:02X} booted (boot-up message {:03X}#00)", n.value(), 0x700 + n.value()));
    };
    host.on_emcy = [this](const EmcyMessage& m, TimePoint) {
      ++emcys;
      say(fmt::format("host: EMCY from node 0x{:02X}: code {:04X}h, error register {:02X}h", m.node.value(), m.code,
                      m.error_register));
    };
    host.on_heartbeat_timeout = [this](NodeId) {
      if (silent_since && last_heartbeat)
        loss_detected_after = std::chrono::duration_cast<Duration>(loop.now() - *last_heartbeat);
      joystick.h.status = FeStatus::Offline;  // a lost input never keeps the machine moving: neutral
      joystick.h.timestamp_us = now_us();
      joystick.x = joystick.y = 0;
      joystick.buttons = 0;
      if (!fan.empty()) schedule.update(joystick, now_us());
      publish_status("missing");
      say(
          fmt::format("host: heartbeat of node 0x20 LOST ({:.0f} ms after its last heartbeat; consumer time 250 ms)\n"
                      "            -> the gateway will drive every input fed by such a node to neutral",
                      std::chrono::duration<double, std::milli>(loss_detected_after).count()));
    };
    host.on_other_frame = [this](const CanFrame& f, TimePoint) {
      if (f.id == 0x1A0 && f.dlc == 5) {
        ++tpdos;
        x = static_cast<std::int16_t>(get_u16(&f.data[0]));
        y = static_cast<std::int16_t>(get_u16(&f.data[2]));
        buttons = f.data[4];
        joystick.h.status = FeStatus::Valid;
        joystick.h.timestamp_us = now_us();
        joystick.x = x;
        joystick.y = y;
        joystick.buttons = buttons;
        if (!fan.empty()) schedule.update(joystick, now_us());
      }
    };
  }

  Script::Step sdo_read(std::uint16_t index, std::uint8_t sub,
                        std::function<void(const std::vector<std::uint8_t>&)> show,
                        SdoTransfer mode = SdoTransfer::Auto) {
    return [this, index, sub, show, mode](Script::Next next) {
      host.sdo(dev_id).upload(
          index, sub,
          [this, index, sub, show, next](SdoAbortCode c, std::vector<std::uint8_t> d) {
            if (c != SdoAbortCode::None) {
              fail(fmt::format("SDO upload {:04X}h:{:02X}: {}", index, sub, to_string(c)));
            } else {
              show(d);
            }
            next();
          },
          mode);
      host_driver.rearm();
    };
  }

  Script::Step sdo_write(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data, const char* what) {
    return [this, index, sub, data, what](Script::Next next) {
      host.sdo(dev_id).download(index, sub, data,
                                [this, index, sub, data, what, next](SdoAbortCode c, std::vector<std::uint8_t>) {
                                  const std::string line =
                                      fmt::format("SDO download {:04X}h:{:02X} = {:<9} {}", index, sub,
                                                  fmt::format("{:X}h", decode_unsigned(data)), what);
                                  if (c != SdoAbortCode::None) {
                                    fail(line + ": " + std::string(to_string(c)));
                                  } else {
                                    say(line);
                                  }
                                  next();
                                });
      host_driver.rearm();
    };
  }

  Script::Step wait(Duration d) {
    return [this, d](Script::Next next) { loop.call_after(d, next); };
  }

  void the_device_powers_on() {
    script.then([this](Script::Next next) {
      (void)host.monitor_heartbeat(dev_id, 250);
      say("device: power on");
      (void)device.node().start(loop.now());
      dev_driver.rearm();
      loop.call_after(20ms, next);
    });
    script.then([this](Script::Next next) {
      if (!booted) fail("no boot-up seen");
      next();
    });
  }

  void read_the_device() {
    script.then(sdo_read(0x1000, 0, [this](const auto& d) {
      say(fmt::format("SDO upload 1000h    device type = {:08X}h (expedited)", get_u32(d.data())));
    }));
    script.then(sdo_read(0x1008, 0, [this](const auto& d) {
      say("SDO upload 1008h    device name = \"" + std::string(d.begin(), d.end()) + "\" (segmented)");
    }));
    script.then(sdo_read(
        0x100A, 0,
        [this](const auto& d) {
          say("SDO upload 100Ah    software version = \"" + std::string(d.begin(), d.end()) + "\" (block, CRC)");
        },
        SdoTransfer::Block));
    script.then(sdo_write(0x1017, 0, encode<std::uint16_t>(100), "heartbeat every 100 ms"));
  }

  void remap_tpdo1() {
    script.then([this](Script::Next next) {
      say("host: remap TPDO1 by SDO (CiA 301 dynamic mapping: invalidate, clear, map, count, validate)");
      next();
    });
    script.then(sdo_write(0x1800, 1, encode<std::uint32_t>(0x800001A0), "TPDO1 COB-ID invalid"));
    script.then(sdo_write(0x1A00, 0, {0}, "mapping cleared"));
    script.then(sdo_write(0x1A00, 1, encode<std::uint32_t>(pdo_map(0x6401, 1, 16)), "6401h:01 x axis, 16 bit"));
    script.then(sdo_write(0x1A00, 2, encode<std::uint32_t>(pdo_map(0x6401, 2, 16)), "6401h:02 y axis, 16 bit"));
    script.then(sdo_write(0x1A00, 3, encode<std::uint32_t>(pdo_map(0x6000, 1, 8)), "6000h:01 buttons, 8 bit"));
    script.then(sdo_write(0x1A00, 0, {3}, "3 entries"));
    script.then(sdo_write(0x1800, 1, encode<std::uint32_t>(0x1A0), "TPDO1 valid on 1A0h"));
  }

  void write_a_read_only_object() {
    script.then([this](Script::Next next) {
      // Refused on purpose: the answer is an abort code and nothing changes.
      host.sdo(dev_id)
          .download(0x1000, 0, encode<std::uint32_t>(0), [this, next](SdoAbortCode c, std::vector<std::uint8_t>) {
            const std::string line =
                fmt::format("SDO download 1000h (read-only) refused with abort {:08X}h \"{}\", as it must be",
                            static_cast<unsigned>(c), to_string(c));
            if (c != SdoAbortCode::WriteOfReadOnly) fail(line);
            else say(line);
            next();
          });
      host_driver.rearm();
    });
  }

  void take_indicator_commands() {
    if (fan.empty()) return;
    publish_tick = loop.call_every(loop.now(), 100ms, [this] { schedule.tick(now_us()); });
    // indicators.1 -> the device's output byte 6200h:01 (RPDO1 220h); the last command wins.
    const auto on_indicators = [this](const IndicatorCommand& c) {
      if (c.instance != 1) return;
      const auto byte = static_cast<std::uint8_t>(c.indicators & 0xFF);
      say(fmt::format("indicators.1 command {:02X}h -> RPDO1 220h#{:02X}", byte, byte));
      (void)host_port->send(CanFrame(0x220, {byte}));
    };
    for (gateway::Publisher* p : {static_cast<Publisher*>(dds.get()), static_cast<Publisher*>(lcm.get())}) {
      if (p == nullptr || p->fd() < 0) continue;
      p->on_indicator_command = on_indicators;
      publisher_watches.push_back(loop.watch(p->fd(), events::kReadable, [p](std::uint32_t) { p->poll(); }));
    }
  }

  void the_inputs_move() {
    script.then([this](Script::Next next) {
      say("host: NMT start node 0x20 -> operational; the device's inputs start moving");
      host.nmt().start(dev_id);
      motion = loop.call_every(loop.now(), 20ms, [this] {
        device.move_inputs(loop.now());
        dev_driver.rearm();
      });
      next();
    });
  }

  void show_the_joystick() {
    script.then([this](Script::Next next) {
      const auto end =
          loop.now() + std::chrono::duration_cast<Duration>(std::chrono::duration<double>(options.live_seconds));
      auto view = std::make_shared<std::function<void()>>();
      *view = [this, end, next, view] {
        const std::string b =
            fmt::format("  joystick (TPDO1 1A0h)  x = {:+6.2f}  y = {:+6.2f}  button 1 = {:<8}  TPDOs so far: {}",
                        x / 32767.0, y / 32767.0, (buttons & 1) ? "pressed" : "released", tpdos);
        if (tty) {
          std::printf("\r%s", b.c_str());
          std::fflush(stdout);
        } else {
          std::printf("%s\n", b.c_str());
        }
        if (loop.now() >= end) {
          if (tty) std::printf("\n");
          next();
          return;
        }
        loop.call_after(tty ? 100ms : 500ms, *view);
      };
      (*view)();
    });
  }

  void write_the_output() {
    script.then([this](Script::Next next) {
      if (tpdos == 0) fail("no TPDO received");
      say("host: RPDO1 220h#A5 -> device output 6200h:01");
      (void)host_port->send(CanFrame(0x220, {0xA5}));
      loop.call_after(10ms, next);
    });
    script.then(sdo_read(0x6200, 1, [this](const auto& d) {
      const std::string line = fmt::format("SDO upload 6200h:01 output = {:02X}h (written by the RPDO)", d[0]);
      if (d[0] != 0xA5) fail(line);
      else say(line);
    }));
  }

  void pull_the_cable() {
    script.then([this](Script::Next next) {
      say("cable pulled: the device goes silent");
      dev_port->set_connected(false);
      silent_since = loop.now();
      loop.call_after(600ms, next);
    });
  }

  void plug_it_back() {
    script.then([this](Script::Next next) {
      if (loss_detected_after == Duration{0}) fail("heartbeat loss not detected");
      say("cable back; host: NMT reset node 0x20");
      dev_port->set_connected(true);
      booted = false;
      host.nmt().reset_node(dev_id);
      loop.call_after(50ms, next);
    });
    script.then([this](Script::Next next) {
      if (!booted) fail("no boot-up after reset");
      next();
    });
  }

  int report() const {
    std::printf(
        "\nsummary: %zu frames on the bus, %zu TPDOs and %zu EMCYs received, heartbeat loss detected %.0f ms after "
        "the last heartbeat; %s\n",
        frames, tpdos, emcys, std::chrono::duration<double, std::milli>(loss_detected_after).count(),
        failures == 0 ? "every step as expected" : "SOME STEPS FAILED");
    if (!fan.empty())
      std::printf("published: %llu joystick.1 samples on %s\n", static_cast<unsigned long long>(schedule.published()),
                  dds && lcm ? "DDS and LCM" : (dds ? "DDS" : "LCM"));
    return failures == 0 ? 0 : 1;
  }

  const DemoOptions& options;
  EventLoop& loop;
  VirtualBus& bus;
  const NodeId dev_id{0x20};
  const TimePoint t0 = loop.now();
  const bool tty = ::isatty(STDOUT_FILENO) != 0;
  std::size_t frames = 0;
  std::optional<TimePoint> last_heartbeat;
  std::unique_ptr<VirtualPort> dev_port = bus.attach("device");
  std::unique_ptr<VirtualPort> host_port = bus.attach("host");
  const std::filesystem::path store =
      std::filesystem::temp_directory_path() / ("oegw-demo-" + std::to_string(::getpid()) + ".params");
  DemoDevice device{dev_id, dev_port->sink(), store, 100};
  ObjectDictionary host_od;
  Master host{host_od, host_port->sink(), MasterConfig{.heartbeat_entries = 4, .sdo_timeout = 500ms}};
  ServiceDriver dev_driver{loop, device.node()};
  ServiceDriver host_driver{loop, host};
  int failures = 0;
  std::unique_ptr<publish::DdsPublisher> dds;
  std::unique_ptr<publish::LcmPublisher> lcm;
  FanOut fan;
  std::vector<EventLoop::WatchId> publisher_watches;
  publish::PublishSchedule schedule{fan, 100'000};
  JoystickSample joystick;  // instance 1, offline until the first TPDO
  std::uint32_t status_seq = 0;
  std::size_t tpdos = 0;
  std::size_t emcys = 0;
  std::optional<TimePoint> silent_since;
  Duration loss_detected_after{0};
  bool booted = false;
  std::int16_t x = 0, y = 0;
  std::uint8_t buttons = 0;
  Script script;
  EventLoop::TimerId motion = 0;
  EventLoop::TimerId publish_tick = 0;
};

}  // namespace

int run_demo(const DemoOptions& options) {
  EventLoop loop;
  VirtualBus bus;
  bus.run_on(loop);
  CoreDemo demo(options, loop, bus);
  return demo.run();
}

// ---- oegw device ----------------------------------------------------------------------------

int run_device(const DeviceOptions& options) {
  std::unique_ptr<SocketCanTransport> port;
  try {
    port = SocketCanTransport::open(options.interface, SocketCanOptions{});
  } catch (const CanOpenError& e) {
    spdlog::error("interface: {}", e.what());
    return 2;
  }
  EventLoop loop;
  DemoDevice device(options.node_id, port->sink(), options.store_path, options.heartbeat_ms);
  ServiceDriver driver(loop, device.node());
  port->set_receiver([&](const CanFrame& f, TimePoint t) {
    device.node().on_frame(f, t);
    driver.rearm();
  });
  port->set_event_handler([&](BusEvent e) {
    spdlog::warn("{}: {}", options.interface, to_string(e));
    device.node().on_bus_event(e, loop.now());
    driver.rearm();
  });
  watch_transport(loop, *port);
  if (options.motion) {
    loop.call_every(loop.now(), 20ms, [&] {
      device.move_inputs(loop.now());
      driver.rearm();
    });
  }
  device.node().on_state_change = [&](NmtState s) { spdlog::info("NMT state: {}", to_string(s)); };
  loop.handle_signals({SIGINT, SIGTERM}, [&](int sig) {
    spdlog::info("signal {}: stopping", sig);
    loop.stop();
  });
  const auto loaded = device.node().start(loop.now());
  if (!loaded.ok)
    spdlog::warn("parameter store {} refused ({}); running on defaults", options.store_path.string(), loaded.error);
  driver.rearm();
  spdlog::info("oegw demo device: node 0x{:02X} on {}", device.node().node_id().value(), options.interface);
  loop.run();
  const auto& c = port->counters();
  spdlog::info("stopped: rx {} tx {} tx dropped {}", c.rx_frames, c.tx_frames, c.tx_dropped);
  return 0;
}

}  // namespace oegw::programs
