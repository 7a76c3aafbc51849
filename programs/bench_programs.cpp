#include "programs/bench_programs.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <memory>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "canopen/io/event_loop.hpp"
#include "canopen/io/socketcan_transport.hpp"
#include "canopen/master.hpp"
#include "subdevices/device_spec.hpp"
#include "subdevices/network_manager.hpp"
#include "subdevices/sim/sim_bench.hpp"

namespace oegw::programs {

using namespace canopen;
using namespace canopen::io;
using namespace std::chrono_literals;
namespace sd = oegw::subdevices;

namespace {

std::unique_ptr<SocketCanTransport> open_bus(const std::string& interface) {
  try {
    return SocketCanTransport::open(interface, SocketCanOptions{});
  } catch (const CanOpenError& e) {
    spdlog::error("interface: {}", e.what());
    return nullptr;
  }
}

}  // namespace

int run_sim(const SimOptions& options) {
  // The devices are checked before the bus is opened: a bad command line changes nothing.
  std::unique_ptr<SocketCanTransport> port;
  sd::sim::SimBench bench([&port](const CanFrame& f) {
    if (port) (void)port->send(f);
  });
  for (const auto& text : options.devices) {
    std::string error;
    auto spec = sd::parse_device_spec(text, error);
    if (!spec || !bench.add(*spec, error)) {
      spdlog::error("{}", error);
      return 2;
    }
  }
  port = open_bus(options.interface);
  if (!port) return 2;
  // The port's acceptance filter, as a real device's controller has one: the data frames on the
  // devices' own TPDO COB-IDs are dropped by the kernel (one producer per COB-ID: such a frame is
  // never for them). So a test that sends a device's PDOs in its stead (vm_latency's probe, the
  // grip's TPDO #0 while `grip pdo off`) does not wake this process for each of them, a cost a
  // real device would not put on the gateway's CPU. Set again whenever a frame that can change a
  // TPDO's COB-ID was taken (NMT, an SDO request, LSS) and after every command (reboot); a
  // refusal is reported once.
  std::vector<CobId> filtered;
  const auto refilter = [&] {
    auto ids = bench.tpdo_cob_ids();
    if (ids == filtered) return;
    try {
      port->set_filters(all_but_data_frames_on(ids), true);
    } catch (const CanOpenError& e) {
      spdlog::warn("interface: {} (no acceptance filter: frames on the devices' own TPDO COB-IDs are read too)",
                   e.what());
    }
    filtered = std::move(ids);
  };
  // NMT (000h), an SDO request (600h..67Fh, CiA 301 §7.3.5) or LSS (7E5h).
  const auto may_change_cob_ids = [](const CanFrame& f) {
    return !f.extended && (f.id == 0x000 || f.id == 0x7E5 || (f.id >= 0x600 && f.id <= 0x67F));
  };
  EventLoop loop;
  ServiceDriver driver(loop, bench);
  port->set_receiver([&](const CanFrame& f, TimePoint t) {
    if (bench.on_frame(f, t) && may_change_cob_ids(f)) refilter();
    driver.rearm();
  });
  watch_transport(loop, *port);
  if (options.motion) {
    loop.call_every(loop.now(), 20ms, [&] {
      bench.move(loop.now());
      driver.rearm();
    });
  }
  std::string pending;
  if (options.commands) {
    loop.watch(STDIN_FILENO, 0x001 /* EPOLLIN */, [&](std::uint32_t) {
      char buf[256];
      const ssize_t n = ::read(STDIN_FILENO, buf, sizeof buf);
      if (n <= 0) {
        loop.stop();  // end of the command stream ends the bench
        return;
      }
      pending.append(buf, static_cast<std::size_t>(n));
      for (auto nl = pending.find('\n'); nl != std::string::npos; nl = pending.find('\n')) {
        const std::string line = pending.substr(0, nl);
        pending.erase(0, nl + 1);
        if (!line.empty()) std::printf("%s\n", bench.command(line, loop.now()).c_str());
        std::fflush(stdout);
      }
      refilter();
      driver.rearm();
    });
  }
  loop.handle_signals({SIGINT, SIGTERM});
  bench.start(loop.now());
  refilter();
  driver.rearm();
  std::string names;
  for (const auto& n : bench.names()) names += " " + n;
  spdlog::info("oegw-sim on {}:{}", options.interface, names);
  loop.run();
  return 0;
}

int run_master(const MasterOptions& options) {
  std::unique_ptr<SocketCanTransport> port;
  const FrameSink sink = [&port](const CanFrame& f) {
    if (port) (void)port->send(f);
  };
  EventLoop loop;
  ObjectDictionary od;
  // One 1016h entry per device (at least the default 16): with fewer, the later devices' heartbeats
  // would go unwatched.
  Master master(od, sink,
                MasterConfig{.heartbeat_entries =
                                 static_cast<std::uint8_t>(std::clamp<std::size_t>(options.devices.size(), 16, 127))});
  sd::NetworkManager network(master);
  for (const auto& text : options.devices) {
    std::string error;
    auto spec = sd::parse_device_spec(text, error);
    std::unique_ptr<sd::Driver> driver;
    if (spec) driver = sd::make_driver(spec->family, spec->node, sink, spec->options, error);
    if (!driver) {
      spdlog::error("{}", error);
      return 2;
    }
    const std::string name = spec->name();
    sd::Driver* d = driver.get();
    if (options.signals) {
      d->on_change = [d, name](std::size_t i, const sd::SignalValue& v) {
        std::printf("signal %s.%s = %lld (%s)\n", name.c_str(), d->signals()[i].name.c_str(),
                    static_cast<long long>(v.value), std::string(sd::to_string(v.status)).c_str());
        std::fflush(stdout);  // a line as it happens, as the node lines: a watcher reads it at once
      };
    }
    sd::NodeSettings settings;
    settings.name = name;
    settings.node = spec->node;
    settings.heartbeat_ms = static_cast<std::uint16_t>(options.heartbeat_ms);
    settings.mandatory = true;
    if (!network.add(settings, std::move(driver))) {
      spdlog::error("{}: node-ID used twice", name);
      return 2;
    }
  }
  port = open_bus(options.interface);
  if (!port) return 2;
  int rc = 0;
  network.on_node_state = [&](const std::string& name, sd::NodeState s, const std::string& why) {
    std::printf("node %s: %s (%s)\n", name.c_str(), std::string(sd::to_string(s)).c_str(), why.c_str());
    std::fflush(stdout);
    if (options.until_operational > 0 && !network.fault()) loop.stop();
  };
  network.on_bad_input = [](const std::string& what) { spdlog::warn("{}", what); };
  network.on_emcy = [](const std::string& name, const EmcyMessage& e, const sd::DecodedEmcy& d) {
    std::printf("emcy %s: %04Xh %s\n", name.c_str(), e.code, d.text.c_str());
  };
  ServiceDriver driver(loop, network);
  port->set_receiver([&](const CanFrame& f, TimePoint t) {
    network.on_frame(f, t);
    driver.rearm();
  });
  watch_transport(loop, *port);
  loop.handle_signals({SIGINT, SIGTERM});
  if (options.until_operational > 0) {
    loop.call_after(std::chrono::duration_cast<Duration>(std::chrono::duration<double>(options.until_operational)),
                    [&] {
                      spdlog::error("not every node operational after {} s", options.until_operational);
                      rc = 1;
                      loop.stop();
                    });
  }
  network.start(loop.now());
  driver.rearm();
  loop.run();
  return rc;
}

}  // namespace oegw::programs
