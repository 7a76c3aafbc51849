#include "gateway/programs.hpp"

#include <grp.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <stdexcept>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "canopen/306/eds_reader.hpp"
#include "canopen/306/eds_writer.hpp"
#include "canopen/io/background_work.hpp"
#include "canopen/io/can_bitrate.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/io/socketcan_transport.hpp"
#include "gateway/bus_load.hpp"
#include "gateway/control/gateway_control.hpp"
#include "gateway/control/status_report.hpp"
#include "gateway/daemon_log.hpp"
#include "gateway/gateway.hpp"
#include "gateway/publishing.hpp"
#include "gateway/record/recording_service.hpp"
#include "gateway/reload.hpp"
#include "gateway/runtime_config.hpp"
#include "gateway/serve_gateway.hpp"
#include "gateway/service_notify.hpp"
#include "mapping/deployment.hpp"
#include "profiles/cia852/pdo_defaults.hpp"
#include "publish/dds_publisher.hpp"
#include "publish/lcm_url.hpp"

namespace oegw::gateway {

using namespace canopen;
using namespace canopen::io;

namespace {

// Which commands load the file, and what they ask of it: `eds` the loader's checks only; `oegw
// check` (File) the cab settings of the file too (mapping/deployment.hpp, the demo's `interface:
// virtual` among them), this machine's findings printed apart, not refused: the file may be
// checked on another computer than the one it is for; `oegw check --here`, `oegw run` and its
// reloads (Here) refuse this machine's findings as well.
enum class Use : std::uint8_t { Eds, File, Here };

// What `oegw run` refuses of this machine as it is now (mapping::machine_errors, and
// publish.dds.security's files as this machine has them), in the file's order.
std::vector<mapping::Diagnostic> machine_refusals(const mapping::Config& c) {
  std::vector<mapping::Diagnostic> out = mapping::machine_errors(c);
  for (auto& e : dds_security_errors(c)) out.push_back(std::move(e));
  mapping::sort_by_place(out);
  return out;
}

struct FileRead {
  mapping::LoadResult loaded;  // errors: the loader's, then the file's cab settings' (and, Here, this machine's)
  std::vector<mapping::Diagnostic> on_this_machine;  // File: what Here would refuse of this machine
};

// The file as `use` takes it. The machine is asked only of a file the loader took.
FileRead read_file(const std::string& file, Use use) {
  FileRead f{mapping::load_config(file, driver_catalogue()), {}};
  mapping::LoadResult& r = f.loaded;
  if (!r.ok() || use == Use::Eds) return f;
  r.errors = mapping::deployment_errors(*r.config);
  std::vector<mapping::Diagnostic> machine = machine_refusals(*r.config);
  if (use == Use::Here) {
    for (auto& e : machine) r.errors.push_back(std::move(e));
    mapping::sort_by_place(r.errors);
  } else {
    f.on_this_machine = std::move(machine);
  }
  if (!r.errors.empty()) r.config.reset();
  return f;
}

// `oegw check` without --here: what this machine lacks for the file, each as a warning
// (file:line:column, the setting's name) under a heading saying who refuses it.
void print_on_this_machine(std::FILE* to, const std::vector<mapping::Diagnostic>& refused) {
  if (refused.empty()) return;
  std::fprintf(to, "on this machine (oegw check --here, and oegw run, refuse these):\n");
  for (const auto& d : refused) std::fprintf(to, "warning: %s\n", d.str().c_str());
}

// The file for `use`, or nullopt with every error printed (and, for `oegw check`, this machine's
// findings in their section). `on_this_machine`, when given, receives them of a file taken.
std::optional<mapping::Config> load(const std::string& file, Use use,
                                    std::vector<mapping::Diagnostic>* on_this_machine = nullptr) {
  FileRead f = read_file(file, use);
  const mapping::LoadResult& r = f.loaded;
  if (!r.ok()) {
    std::fprintf(stderr, "%s", r.error_text().c_str());
    if (!r.error_text().empty() && r.error_text().back() != '\n') std::fprintf(stderr, "\n");
    print_on_this_machine(stderr, f.on_this_machine);
    std::fprintf(stderr, "%s: %zu error%s; nothing was started\n", file.c_str(), r.errors.size(),
                 r.errors.size() == 1 ? "" : "s");
    return std::nullopt;
  }
  if (on_this_machine != nullptr) *on_this_machine = std::move(f.on_this_machine);
  return std::move(f.loaded.config);
}

// "125, 250, 500, 1000 kbit/s": the table-0 rates of `rates`, fastest last.
std::string rate_list(lss::BitTimings rates) {
  std::string out;
  for (int i = 8; i >= 0; --i) {
    const auto kbit = lss::standard_bit_rate_kbit(static_cast<std::uint8_t>(i));
    if (!kbit || ((rates >> i) & 1u) == 0) continue;
    out += (out.empty() ? "" : ", ") + std::to_string(*kbit);
  }
  return out + " kbit/s";
}

// What `oegw run` will do with one interface's bit rate (`oegw check`).
std::string bit_rate_plan(CanLink& link, const std::string& interface, std::uint32_t bitrate) {
  const BitRateOutcome p = plan_bit_rate(link, interface, bitrate);
  if (!p.ok()) return p.message;
  switch (p.action) {
    case BitRateAction::Keep: return fmt::format("{} is at {} bit/s already", interface, bitrate);
    case BitRateAction::Set:
      return fmt::format("{} {}: oegw run sets it to {} (interface down, bit rate, up)", interface,
                         p.before == 0 ? std::string("has no bit rate yet") : fmt::format("is at {} bit/s", p.before),
                         bitrate);
    case BitRateAction::NoBitTiming: return interface + " has no bit timing (virtual CAN): not applied";
    case BitRateAction::Missing: break;
  }
  return interface + " is not on this machine (oegw run needs it)";
}

// Sets one interface's bit rate at start (canopen/io/can_bitrate.hpp), logging what was done;
// false, logged with the setting's name, when it cannot be set.
bool set_bit_rate(CanLink& link, const std::string& file, const std::string& setting, const std::string& interface,
                  std::uint32_t bitrate) {
  const BitRateOutcome r = apply_bit_rate(link, interface, bitrate);
  if (!r.ok()) {
    spdlog::error("{}: {}: {}; nothing was started", file, setting, r.message);
    return false;
  }
  switch (r.action) {
    case BitRateAction::Set:
      spdlog::info("{}: {} set from {} to {} bit/s (interface down, bit rate, up)", setting, interface,
                   r.before == 0 ? std::string("none") : std::to_string(r.before), bitrate);
      break;
    case BitRateAction::Keep: spdlog::info("{}: {} is at {} bit/s", setting, interface, bitrate); break;
    case BitRateAction::NoBitTiming:
      spdlog::info("{} has no bit timing (virtual CAN): {} {} not applied", interface, setting, bitrate);
      break;
    case BitRateAction::Missing: break;  // opening it reports that
  }
  return true;
}

// Where an FE field travels in the PDOs of clause 12: "TPDO 1 (180h+ID) byte 2 bit 3".
std::string pdo_place(const std::vector<cia852::DefaultPdo>& pdos, const mapping::FeField& f) {
  for (const auto& p : pdos) {
    unsigned bit_pos = 0;
    for (const std::uint32_t entry : p.params.mapping) {
      const auto index = static_cast<std::uint16_t>(entry >> 16);
      const auto sub = static_cast<std::uint8_t>(entry >> 8);
      const unsigned bits = entry & 0xFF;
      if (index == f.index && sub == f.sub) {
        const unsigned at = bit_pos + (f.bit == 0xFF ? 0 : f.bit);
        const CobId cob{p.params.cob_id};
        std::string where = fmt::format("{} {:>2} (COB-ID {:08X}h{})", p.transmit ? "TPDO" : "RPDO", p.number,
                                        p.params.cob_id, cob.valid() ? "" : ", disabled by default");
        if (f.bit == 0xFF) return where + fmt::format(" bytes {}-{}", at / 8, (at + bits) / 8 - 1);
        return where + fmt::format(" byte {} bit {}", at / 8, at % 8);
      }
      bit_pos += bits;
    }
  }
  return "not in a default PDO";
}

// What the EDS reader accepted of a sub-device's EDS with a warning (CiA 306 does not allow it,
// vendors' tools write it): "io: file.eds:174: warning: ..." each.
std::vector<std::string> eds_warnings(const mapping::SubdeviceConfig& s) {
  std::vector<std::string> out;
  if (const auto eds = s.options.get("eds")) {
    std::string error;
    if (const auto f = canopen::eds::load(*eds, error))
      for (const auto& w : f->warnings) out.push_back(s.name + ": " + w);
  }
  return out;
}

// `oegw check`: the downstream SYNC and what the network manager reads at every boot of a
// sub-device (subdevices/network_manager.hpp).
void print_downstream_boot(const mapping::Config& cfg) {
  if (cfg.downstream.sync_period_ms != 0) {
    std::printf("  SYNC: produced every %u ms on 080h (synchronous TPDOs of type n: one every n x %u ms)\n",
                cfg.downstream.sync_period_ms, cfg.downstream.sync_period_ms);
  } else {
    std::printf("  SYNC: none (sync_period_ms 0; synchronous transmission types refused)\n");
  }
  std::printf(
      "  read at every boot, in pre-operational (NMT 80h first): 1000h; 1018h:01..04 identity (revision: "
      "major part unless revision_match exact); 1008h device name, 1009h hardware version, 100Ah software "
      "version, 1001h error register (absent = not present); logged once per boot, in the gateway status\n");
  for (const auto& s : cfg.subdevices) {
    if (s.exact_revision) std::printf("  %s: revision compared exactly\n", s.name.c_str());
    for (const auto& w : eds_warnings(s)) std::printf("  %s\n", w.c_str());
  }
}

// `oegw check`: the control socket `oegw run` will serve (mapping file `control`,
// docs/reference/control-protocol.md); what run would refuse there is among this machine's
// findings (mapping::machine_errors) already.
void print_control(const mapping::ControlConfig& c) {
  if (!c.enabled) {
    std::printf("control: off (control.enabled false): no socket, oegw status cannot ask this gateway\n");
    return;
  }
  const std::filesystem::path folder = std::filesystem::path(c.socket).parent_path();
  std::error_code ec;
  const std::string made =
      std::filesystem::is_directory(folder, ec) ? "" : ", its folder " + folder.string() + " made by oegw run";
  std::string who = "mode 0600: root only";
  if (!c.group.empty()) {
    const group* g = ::getgrnam(c.group.c_str());
    who = fmt::format("mode 0660: root and group {} (gid {})", c.group, g != nullptr ? std::to_string(g->gr_gid) : "?");
  }
  std::printf("control: socket %s%s, %s; oegw status asks it (oegw status --config FILE finds it)\n", c.socket.c_str(),
              made.c_str(), who.c_str());
}

// What a SIGHUP reload reads and checks beside the buses (a thread of its own, BackgroundWork):
// the file as `oegw run` takes it, and the drivers it names, built for the hand-over (reading
// their EDS files: build_reload_drivers). What it is checked against, the running file, is the
// loop's: compared there (apply_reload()).
struct ReloadRead {
  mapping::LoadResult read;
  ReloadDrivers drivers;
};

ReloadRead read_for_reload(const std::string& file) {
  ReloadRead out{read_file(file, Use::Here).loaded, {}};
  if (out.read.ok()) out.drivers = build_reload_drivers(*out.read.config);
  return out;
}

// What SIGHUP replaces or re-attaches in `oegw run`
// (docs/guides/install.md#reloading-the-mapping-file).
struct Running {
  const std::string& file;
  mapping::Config& config;  // the control socket's services read it: replaced in place
  std::unique_ptr<Gateway>& gw;
  FrameSink downstream;
  GatewayPublishing& publishing;
  control::GatewayControl* control;     // null: control.enabled false
  record::RecordingService& recording;  // the black box: the new gateway is tapped too
  ServiceDriver& driver;
  ServiceNotify& notify;
  EventLoop& loop;
  int& exit_status;  // set when a reload fails after the hand-over (below)
  BackgroundWork<ReloadRead>& reading;
  const ServeHooks& hooks;
  bool again = false;  // a SIGHUP came while the file was being read: read it again after
};

// What systemd's STATUS= says of `oegw run`: the gateway's states and each publishing transport
// that is down (docs/guides/install.md#systemd).
ServiceState running_state(Gateway& gw, const GatewayPublishing& publishing) {
  ServiceState state = service_state(gw);
  state.degraded = publishing.degraded();
  return state;
}

bool apply_reload(Running& r, ReloadRead read, TimePoint now);

// SIGHUP: the file read and checked as at a start (`oegw check`'s errors, the cab settings
// included) and against the running one (gateway/reload.hpp reload_refusals); every error
// logged, nothing changed. Else the gateway replaced around the same upstream device
// (reload_gateway), the control socket and publishing re-attached. systemd is told RELOADING=1
// first and READY=1 at the end, whatever the outcome: the gateway runs either way.
// The reading and checking (the file, its EDS files, the drivers built once: tens of
// milliseconds for 48 sub-devices on a PC, far more on a slow controller or a slow file system)
// runs beside the buses, which are served meanwhile; only the comparison with the running file
// and the hand-over run on the loop. A SIGHUP while the file is being read reads it once more
// after that reload.
void reload(Running& r) {
  if (r.hooks.reload_signal) r.hooks.reload_signal(r.reading.busy());
  if (r.reading.busy()) {
    r.again = true;
    spdlog::info("{}: SIGHUP while the file is read for a reload: it is read again after that one", r.file);
    return;
  }
  r.notify.reloading(r.loop.now());
  spdlog::info("{}: reloading (SIGHUP)", r.file);
  r.reading.start(
      r.loop,
      [file = std::string(r.file), hook = r.hooks.reload_reading] {
        if (hook) hook();
        return read_for_reload(file);
      },
      [&r](std::optional<ReloadRead> read, const std::string& failure) {
        if (r.loop.stop_requested()) return;  // SIGTERM in the same wake-up: the daemon stops
        if (!read) {                          // the reading itself failed (out of memory): as a file refused
          read.emplace();
          read->read.errors.push_back({{r.file, 1, 1}, "cannot be read for the reload: " + failure});
        }
        const bool applied = apply_reload(r, std::move(*read), r.loop.now());
        if (r.hooks.reload_done) r.hooks.reload_done(applied);
        if (!r.again || r.exit_status != 0 || r.loop.stop_requested()) return;
        r.again = false;
        reload(r);
      },
      {.nice_above = kNiceBesideTheLoop, .name = "oegw-reload"});
}

// False if the file was refused (or the daemon stops: the hand-over failed).
bool apply_reload(Running& r, ReloadRead read, TimePoint now) {
  std::vector<mapping::Diagnostic> errors = std::move(read.read.errors);
  if (read.read.ok()) errors = reload_refusals(r.config, *read.read.config);
  if (read.read.ok() && errors.empty()) errors = std::move(read.drivers.refusals);
  if (!errors.empty()) {
    for (const auto& e : errors) spdlog::error("{}", e.str());
    const std::string note =
        fmt::format("last reload refused: {} error{} (journal)", errors.size(), errors.size() == 1 ? "" : "s");
    spdlog::error("{}: reload refused, {} error{}; the gateway runs on as before", r.file, errors.size(),
                  errors.size() == 1 ? "" : "s");
    r.notify.reloaded(note, running_state(*r.gw, r.publishing));
    return false;
  }
  if (r.control != nullptr) r.control->detach();
  r.publishing.detach();
  r.recording.reloading(now, r.file);
  try {
    GatewayOptions options;
    options.tap = r.recording.tap();
    r.gw =
        reload_gateway(std::move(r.gw), *read.read.config, r.downstream, options, now, std::move(read.drivers.drivers));
  } catch (const std::exception& e) {
    // After the hand-over the old gateway is gone: a gateway that cannot be built now (checked
    // just before: only a file changing in between gets here) stops the daemon with a reason,
    // and systemd's Restart= starts it afresh, rather than running half-configured.
    spdlog::critical("{}: reload failed after the hand-over: {}; stopping (a restart starts afresh)", r.file, e.what());
    r.exit_status = exit_code::kCannotStart;
    r.notify.stopping();
    r.loop.stop();
    return false;
  }
  r.config = std::move(*read.read.config);
  if (r.control != nullptr) r.control->attach(*r.gw, r.config);
  r.publishing.attach(*r.gw);
  r.driver.rearm();
  spdlog::info("{}: reloaded: {} sub-devices on {}", r.file, r.config.subdevices.size(), r.config.downstream.interface);
  r.notify.reloaded("", running_state(*r.gw, r.publishing));
  return true;
}

// `oegw check`: what `oegw run` will record (mapping file `record`, docs/guides/black-box.md).
void print_record(const mapping::RecordConfig& r) {
  if (!r.enabled) {
    std::printf("record: off (record.enabled false): no black box\n");
    return;
  }
  std::printf(
      "record: both buses' frames (candump log) and the gateway's decisions into %s, a ring of at most %u MiB "
      "and %u s in %u segments (%.1f MiB or %.0f s each), %u KiB queued at most; SIGUSR1 or `oegw record keep` "
      "keeps the window in %s/kept/\n",
      r.dir.c_str(), r.max_mib, r.span_s, r.segments, static_cast<double>(r.max_mib) / r.segments,
      static_cast<double>(r.span_s) / r.segments, r.queue_kib, r.dir.c_str());
}

// Publishing for `oegw run` (docs/guides/dds-lcm.md#publishing-degrades-the-gateway-runs): a
// setting that cannot work refuses the start (false, logged with the file); a transport the machine
// cannot carry now is left down, logged once, reported, and opened again from the loop.
bool start_publishing(Gateway& gw, const mapping::Config& cfg, const std::string& file, EventLoop& loop,
                      ServiceDriver& driver, std::unique_ptr<GatewayPublishing>& out) {
  const auto log = [](bool up, const std::string& text) {
    if (up) spdlog::info("publishing: {}", text);
    else spdlog::warn("publishing: {}", text);
  };
  try {
    out = std::make_unique<GatewayPublishing>(
        gw, cfg.publish, [&loop] { return loop.now(); }, PublisherFactories{}, log);
  } catch (const publish::PublishConfigError& e) {
    spdlog::error("{}: {}", file, e.what());
    return false;
  }
  out->run_on(loop, [&driver] { driver.rearm(); });
  return true;
}

// `oegw check`: the warnings of a valid file, departing from CiA 852 / CiA 305, then this
// machine's apart; whether there was any.
bool print_warnings(const mapping::Config& cfg, const std::vector<mapping::Diagnostic>& refused_here) {
  // Valid, but departing from CiA 852 / CiA 305
  // (docs/reference/mapping-file.md#upstreamheartbeat_ms-and-upstreamidentityserial).
  bool warned = false;
  if (cfg.upstream.heartbeat_ms == 0) {
    std::printf(
        "warning: upstream.heartbeat_ms is 0: no heartbeat at power-on; CiA 852 §8.3 says the heartbeat "
        "producer shall be used (default 100 ms)\n");
    warned = true;
  }
  if (cfg.upstream.identity.serial == 0) {
    std::printf(
        "warning: upstream.identity.serial is 0 (1018h:04): two gateways of one product then share an LSS "
        "address and cannot be told apart by LSS switch state selective; give each its own serial\n");
    warned = true;
  }
  for (const auto& w : mapping::deployment_warnings(cfg)) {
    std::printf("warning: %s\n", w.str().c_str());
    warned = true;
  }
  // This machine as it is now: apart from the file's findings (mapping/deployment.hpp).
  print_on_this_machine(stdout, refused_here);
  warned = warned || !refused_here.empty();
  std::vector<mapping::Diagnostic> machine_warned = mapping::machine_warnings(cfg);
  // No route for LCM's group (docs/guides/install.md#lcm-route): oegw run would start without LCM.
  if (const auto& lcm = cfg.publish.lcm; lcm.enabled)
    if (const auto problem = publish::lcm_route_problem(lcm.url)) {
      const std::string& net = cfg.publish.dds.network;
      machine_warned.push_back({lcm.url_where.line != 0 ? lcm.url_where : lcm.where,
                                "publish.lcm.url " + lcm.url + (lcm.url_where.line != 0 ? "" : " (the default)") +
                                    ": this machine has " + *problem +
                                    ": oegw run would start without LCM and publish once a route exists; add one: " +
                                    publish::lcm_route_command(lcm.url, net == "loopback" ? "" : net) +
                                    " (docs/guides/install.md#lcm-route has the systemd-networkd file that keeps it)"});
    }
  if (!machine_warned.empty()) {
    mapping::sort_by_place(machine_warned);
    std::printf("on this machine (oegw run starts all the same):\n");
    for (const auto& w : machine_warned) std::printf("warning: %s\n", w.str().c_str());
    warned = true;
  }
  return warned;
}

// `oegw check --quiet`: the warnings the full listing has inside its sections: the EDS reader's,
// the bus load's.
void print_section_warnings(const mapping::Config& cfg) {
  for (const auto& s : cfg.subdevices)
    for (const auto& w : eds_warnings(s)) std::printf("%s\n", w.c_str());
  BusLoadPrediction load = predict_bus_load(cfg);
  load.upstream.bit_rate = upstream_bit_rate(cfg).bitrate;
  std::printf("%s%s", bus_load_warning(load.upstream, "upstream").c_str(),
              bus_load_warning(load.downstream, "downstream").c_str());
}

// `oegw check`: both buses, their bit rates and their load.
void print_buses(const mapping::Config& cfg, OeDevice& device) {
  const NodeId node{cfg.upstream.node_id};
  std::printf("upstream: network %u, node-ID %02Xh on %s, 1000h device type = %08Xh (CiA 852 Table 8)\n",
              cfg.upstream.network_id, node.value(), cfg.upstream.interface.c_str(),
              device.od().get<std::uint32_t>(0x1000, 0));
  // 1201h..: the additional SDO server channels (upstream.sdo_servers).
  for (std::size_t k = 1; k <= cfg.upstream.sdo_servers.size(); ++k) {
    const auto& s = cfg.upstream.sdo_servers[k - 1];
    const std::string cobs = s.enabled() ? fmt::format("request {:03X}h, response {:03X}h", *s.request, *s.response)
                                         : std::string("disabled until the host sets its COB-IDs");
    const std::string target =
        s.subdevice.empty() ? std::string("the gateway's own dictionary") : "bound to " + s.subdevice;
    std::printf("  SDO server %04Xh: %s, %s\n", static_cast<unsigned>(0x1200 + k), cobs.c_str(), target.c_str());
  }
  std::printf("downstream: network %u, %s, sub-device EMCYs forwarded upstream: %s, SDO time-out %u ms\n",
              cfg.downstream.network_id, cfg.downstream.interface.c_str(),
              std::string(mapping::to_string(cfg.downstream.emcy_forwarding)).c_str(), cfg.downstream.sdo_timeout_ms);
  print_downstream_boot(cfg);
  for (const auto& s : cfg.subdevices)
    std::printf("  %-12s %-16s node %02Xh%s\n", s.name.c_str(), s.driver.c_str(), s.node_id,
                s.mandatory ? "  mandatory" : "");
  // What `oegw run` does with the bit rates on this machine (docs/guides/commission.md#bit-rate).
  const auto link = netlink_can_link();
  const UpstreamBitRate up_rate = upstream_bit_rate(cfg);
  std::printf("\nbit rates (oegw run sets them at start):\n");
  std::printf("  upstream %u bit/s (%s): %s\n", up_rate.bitrate,
              up_rate.lss_stored ? fmt::format("LSS-stored, upstream.bitrate is {}", cfg.upstream.bitrate).c_str()
                                 : "upstream.bitrate",
              bit_rate_plan(*link, cfg.upstream.interface, up_rate.bitrate).c_str());
  std::printf("  downstream %u bit/s (downstream.bitrate): %s\n", cfg.downstream.bitrate,
              bit_rate_plan(*link, cfg.downstream.interface, cfg.downstream.bitrate).c_str());
  std::printf("  LSS configure bit timing and the EDS: %s\n", rate_list(device.config().supported_bit_timings).c_str());
  // What the configuration puts on each bus with the inputs held still (gateway/bus_load.hpp).
  BusLoadPrediction load = predict_bus_load(cfg);
  load.upstream.bit_rate = up_rate.bitrate;  // the rate oegw run uses (an LSS-stored one wins)
  std::printf(
      "\nbus load (steady state: periodic frames, PDOs at their worst-case length; warning above %.0f %%):\n%s%s",
      kBusLoadWarnPercent, describe_bus_load(load.upstream, "upstream").c_str(),
      describe_bus_load(load.downstream, "downstream").c_str());
}

// `oegw check`: each FE's fields, where they come from and in which PDO.
void print_fes(const mapping::Config& cfg, const OeDevice& device) {
  const auto pdos = cia852::default_pdos(device.config().fes, NodeId{cfg.upstream.node_id});
  std::printf("\nfunctional elements (field <- signal: object, PDO):\n");
  for (const auto& fe : cfg.functional_elements) {
    for (const auto& b : fe.fields) {
      const std::string arrow = fe.input() ? "<-" : "->";
      const std::string signal =
          b.subdevice + "." + b.signal + (b.signal_bit != 0xFF ? fmt::format(".bit{}", b.signal_bit) : "");
      const std::string obj = fmt::format("{:04X}h:{:02X}{}", b.field.index, b.field.sub,
                                          b.field.bit == 0xFF ? "" : fmt::format(" bit {}", b.field.bit));
      std::printf("  %-13s %-14s %s %-24s %-16s %s\n", mapping::fe_name(fe.id).c_str(), b.field.name.c_str(),
                  arrow.c_str(), signal.c_str(), obj.c_str(), pdo_place(pdos, b.field).c_str());
    }
  }
}

// `oegw check`: the mapping file's `publish`.
void print_publish(const mapping::PublishConfig& p) {
  std::printf("\npublish: every %u ms; DDS %s; LCM %s\n", p.period_ms,
              p.dds.enabled
                  ? fmt::format("domain {}, partition {}, network {}{}", p.dds.domain, p.dds.partition,
                                p.dds.network.empty() ? "(CYCLONEDDS_URI)" : p.dds.network,
                                p.dds.security ? ", DDS Security (identity " +
                                                     p.dds.security->path[mapping::DdsSecurityConfig::Certificate] + ")"
                                               : std::string())
                        .c_str()
                  : "off",
              p.lcm.enabled ? fmt::format("{}, channels {}*", p.lcm.url, p.lcm.channel_prefix).c_str() : "off");
}

// `oegw check`: where each output FE takes its commands from.
void print_commands_in(const mapping::Config& cfg) {
  bool outputs = false;
  for (const auto& fe : cfg.functional_elements) {
    if (fe.input()) continue;
    if (!outputs) std::printf("commands in (sources of each output FE; among them the last write wins):\n");
    outputs = true;
    std::printf("  %-13s %s%s%s\n", mapping::fe_name(fe.id).c_str(), mapping::describe_sources(fe.sources).c_str(),
                fe.accepts(mapping::CommandSource::Canopen)
                    ? ""
                    : "  (host: SDO download aborted 0800 0021h, its RPDO bytes ignored)",
                fe.command_timeout_ms == 0
                    ? ""
                    : fmt::format("  error values after {} ms without a command", fe.command_timeout_ms).c_str());
  }
}

// The buses outlive what their callbacks reach (the gateway, its driver): cut them on the way out.
struct Unhook {
  CanTransport* up;
  CanTransport* down;
  ~Unhook() {
    for (CanTransport* t : {up, down}) {
      t->set_receiver({});
      t->set_event_handler({});
    }
  }
};

// One bus whose kernel drops are logged (Daemon::watch_kernel_drops).
struct Watched {
  const CanTransport* bus;
  const char* side;
  std::string interface;
  std::uint64_t dropped = 0;
};

GatewayOptions tapped_by(record::RecordingService& recording) {
  GatewayOptions options;
  options.tap = recording.tap();
  return options;
}

std::unique_ptr<Gateway> logging_gateway(const mapping::Config& cfg, CanTransport& up, CanTransport& down,
                                         const GatewayOptions& options) {
  auto gw = std::make_unique<Gateway>(cfg, up.sink(), down.sink(), options);
  gw->on_log = [](const std::string& line) { spdlog::info("{}", line); };
  return gw;
}

// `oegw run` on its open buses (serve_gateway): the state its steps share, one method per step in
// the order run() takes them. Members in the order they are made, so they go in reverse.
class Daemon {
 public:
  Daemon(const std::string& f, mapping::Config& config, EventLoop& l, const GatewayBuses& b, const ServeHooks& h)
      : file(f),
        cfg(&config),
        loop(l),
        buses(b),
        hooks(h),
        up(&b.up),
        down(&b.down),
        unhook{up, down},
        // The black box (mapping file `record`): it taps every gateway from its construction on.
        recording(l, config, f),
        options(tapped_by(recording)),
        gw(logging_gateway(config, *up, *down, options)),
        driver(
            l, [this] { return gw->next_deadline(); }, [this](TimePoint now) { gw->advance(now); }) {}

  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;
  // A reload still reading its file when the daemon stops is given 2 s to end: the process's
  // static objects (the loggers, OpenSSL's for DDS Security's checks) must not go while it uses
  // them. A reading that hangs longer (a hung file system) is left to the exit.
  ~Daemon() { (void)reading.settle(std::chrono::seconds(2)); }

  int run() {
    take_frames();
    follow_bit_rate_switches();
    take_bus_events();
    watch_kernel_drops();
    if (!start_publishing(*gw, *cfg, file, loop, driver, publishing)) return exit_code::kCannotStart;
    // systemd (gateway/service_notify.hpp): READY=1, STATUS=, WATCHDOG=1 from this loop, STOPPING=1.
    systemd.emplace();
    notify.emplace(*systemd, systemd_watchdog_timeout());
    if (!open_control()) return exit_code::kCannotStart;
    handle_signals();
    // Each black-box segment begins with the running gateway's state (the one a reload made too).
    recording.give_states([this] { return static_cast<const Gateway*>(gw.get()); });
    start();
    loop.run();
    return exit_status;
  }

 private:
  void take_frames() {
    up->set_receiver([this](const CanFrame& f, TimePoint t) {
      gw->on_upstream_frame(f, t);
      driver.rearm();
    });
    down->set_receiver([this](const CanFrame& f, TimePoint t) {
      gw->on_downstream_frame(f, t);
      driver.rearm();
    });
  }

  // LSS activate bit timing (CiA 305): the node is silent; at the switch the interface is set to
  // the new rate (down, bit rate, up). Its socket then reports the interface going down once.
  void follow_bit_rate_switches() {
    gw->upstream().on_bit_rate_switch([this](std::uint32_t rate) { bit_rate_switch(rate); });
  }

  void bit_rate_switch(std::uint32_t rate) {
    const std::string& name = cfg->upstream.interface;
    // Without a bit timing to set (a transport that is not a CAN controller): as a virtual CAN
    // interface's.
    const BitRateOutcome r = buses.set_upstream_bit_rate ? buses.set_upstream_bit_rate(rate)
                                                         : BitRateOutcome{.action = BitRateAction::NoBitTiming};
    if (!r.ok()) {
      spdlog::error("LSS activate bit timing: {}; {} stays at {} bit/s", r.message, name, r.before);
      return;
    }
    switch (r.action) {
      case BitRateAction::Set:
        switched = true;
        spdlog::info("LSS activate bit timing: {} switched from {} to {} bit/s", name, r.before, rate);
        break;
      case BitRateAction::Keep: spdlog::info("LSS activate bit timing: {} is at {} bit/s already", name, rate); break;
      case BitRateAction::NoBitTiming:
        spdlog::info(
            "LSS activate bit timing: {} has no bit timing (virtual CAN): {} bit/s not applicable; the node "
            "stays on the bus",
            name, rate);
        break;
      case BitRateAction::Missing: spdlog::error("LSS activate bit timing: {} is gone", name); break;
    }
  }

  void take_bus_events() {
    up->set_event_handler([this](BusEvent e) {
      if (e == BusEvent::InterfaceDown && switched) {
        switched = false;  // the restart of the bit-rate switch
        return;
      }
      spdlog::warn("upstream {}: {}", cfg->upstream.interface, to_string(e));
      gw->on_upstream_bus_event(e, loop.now());
      driver.rearm();
    });
    down->set_event_handler([this](BusEvent e) {
      spdlog::warn("downstream {}: {}", cfg->downstream.interface, to_string(e));
      gw->on_downstream_bus_event(e, loop.now());
      driver.rearm();
    });
    watch_transport(loop, *up);
    watch_transport(loop, *down);
    if (loop.uses_io_uring()) {
      spdlog::info(
          "event loop: io_uring (the buses' frames read and the answers sent in the wait: one system call per "
          "wake-up)");
    } else if (!loop.simulated()) {
      spdlog::info("event loop: epoll (io_uring not used: {})", loop.why_not_io_uring());
    }
    if (buses.watching) buses.watching();
  }

  // Once a second the frames the kernel dropped because the gateway read them too late: each a
  // reason a heartbeat or PDO may seem lost (the fault policy then acts on it; this says why).
  void watch_kernel_drops() {
    watched = {Watched{up, "upstream", cfg->upstream.interface},
               Watched{down, "downstream", cfg->downstream.interface}};
    loop.call_every(loop.now(), std::chrono::seconds(1), [this] {
      for (Watched& w : watched) {
        const std::uint64_t now_dropped = w.bus->counters().rx_dropped;
        if (now_dropped > w.dropped)
          spdlog::warn(
              "{} {}: the kernel dropped {} received frames in the last second (the gateway read them too "
              "late; {} since the start)",
              w.side, w.interface, now_dropped - w.dropped, now_dropped);
        w.dropped = now_dropped;
      }
    });
  }

  // `oegw status`, `oegw ctl` (docs/reference/control-protocol.md); false when it cannot be opened.
  bool open_control() {
    try {
      if (cfg->control.enabled)
        control = std::make_unique<control::GatewayControl>(
            loop, *gw, *cfg, file, [this] { driver.rearm(); }, up, down);
    } catch (const control::ControlError& e) {
      spdlog::error("{}", e.what());
      return false;
    }
    if (!control) return true;
    control->add_status_field("publishing", [this] { return control::publishing_status(publishing->transports()); });
    control->add_status_field("record", [this] { return recording.status(); });
    control->add_command("record_keep", [this](const nlohmann::json&, control::ControlProtocol::Done done) {
      if (!recording.recording()) throw std::runtime_error(recording.off_reason());
      recording.keep([done](const std::string& folder, std::size_t segments, const std::string& error) {
        if (error.empty()) done(nlohmann::json{{"kept", folder}, {"segments", segments}});
        else done(nlohmann::json{{"kept", nullptr}, {"error", error}});
      });
    });
    return true;
  }

  void handle_signals() {
    running.emplace(Running{file, *cfg, gw, down->sink(), *publishing, control.get(), recording, driver, *notify, loop,
                            exit_status, reading, hooks});
    // SIGUSR1 keeps the recording's window (docs/guides/black-box.md).
    loop.handle_signals({SIGINT, SIGTERM, SIGHUP, SIGUSR1}, [this](int sig) {
      if (sig == SIGHUP) return reload(*running);
      if (sig == SIGUSR1) return recording.keep_logged("SIGUSR1");
      spdlog::info("signal {}: stopping", sig);
      notify->stopping();
      loop.stop();
    });
  }

  void start() {
    // A store that cannot be taken (canopen/301/storage.hpp): the device runs on defaults, EMCY
    // 6000h tells the host.
    const auto stored = gw->start(loop.now());
    if (!stored.ok)
      spdlog::error("upstream store refused: {}; running on defaults, EMCY 6000h sent upstream", stored.error);
    driver.rearm();
    spdlog::info("oegw: node {:02X}h on {}, {} sub-devices on {}", cfg->upstream.node_id, cfg->upstream.interface,
                 cfg->subdevices.size(), cfg->downstream.interface);
    report();  // both buses open, the device started: READY=1 once it is pre-operational
    loop.call_every(loop.now() + notify->poll_period(), notify->poll_period(), [this] { report(); });
  }

  void report() { notify->update(loop.now(), running_state(*gw, *publishing)); }

  const std::string& file;
  mapping::Config* const cfg;
  EventLoop& loop;
  const GatewayBuses& buses;
  const ServeHooks& hooks;
  CanTransport* const up;
  CanTransport* const down;
  Unhook unhook;
  record::RecordingService recording;
  GatewayOptions options;
  // Replaced at each reload (SIGHUP): everything below reaches it through this pointer.
  std::unique_ptr<Gateway> gw;
  ServiceDriver driver;
  bool switched = false;
  std::array<Watched, 2> watched{};
  std::unique_ptr<GatewayPublishing> publishing;
  std::optional<SystemdNotifier> systemd;
  std::optional<ServiceNotify> notify;
  std::unique_ptr<control::GatewayControl> control;
  int exit_status = 0;
  // Destroyed before `running`, which its outcome would reach: a read still running is dropped.
  std::optional<Running> running;
  BackgroundWork<ReloadRead> reading;
};

}  // namespace

int run_check(const std::string& file, bool quiet, bool here) {
  std::vector<mapping::Diagnostic> refused_here;  // without --here: what run refuses of this machine
  const auto cfg = load(file, here ? Use::Here : Use::File, &refused_here);
  if (!cfg) return exit_code::kBadFile;
  const auto device = eds_device(*cfg);  // the dictionary `oegw run` builds
  std::printf("%s: valid\n%s", file.c_str(), quiet ? "" : "\n");
  const bool warned = print_warnings(*cfg, refused_here);
  if (quiet) {
    print_section_warnings(*cfg);
    return exit_code::kOk;
  }
  if (warned) std::printf("\n");
  print_buses(*cfg, *device);
  print_fes(*cfg, *device);
  print_publish(cfg->publish);
  print_control(cfg->control);
  print_record(cfg->record);
  print_commands_in(*cfg);
  return 0;
}

int run_eds(const std::string& file, const std::string& out) {
  const auto cfg = load(file, Use::Eds);
  if (!cfg) return exit_code::kBadFile;
  const auto device = eds_device(*cfg);
  const EdsInfo info = eds_info(*cfg, out == "-" ? "oegw.eds" : std::filesystem::path(out).filename().string());
  if (out == "-") {
    std::cout << eds_text(device->od(), info);
    return 0;
  }
  std::string error;
  if (!write_eds(out, device->od(), info, error)) {
    std::fprintf(stderr, "oegw eds: %s\n", error.c_str());
    return exit_code::kCannotStart;
  }
  std::printf("%s: EDS of node %02Xh written\n", out.c_str(), info.node_id.value());
  return 0;
}

int run_gateway(const std::string& file) {
  const DaemonLog log;  // lines through a bounded queue: the loop never waits for the journal
  // Blocked from the start (SIGHUP's default action ends the process): served once the loop
  // runs, by the handler serve_gateway sets; one that comes while the start fails is discarded.
  EventLoop loop;
  loop.handle_signals({SIGINT, SIGTERM, SIGHUP, SIGUSR1});
  auto cfg = load(file, Use::Here);
  if (!cfg) return exit_code::kBadFile;
  // The bit rates first (docs/guides/commission.md#bit-rate): a refused one starts nothing.
  const auto link = netlink_can_link();
  const UpstreamBitRate up_rate = upstream_bit_rate(*cfg);
  if (!up_rate.note.empty()) spdlog::info("upstream: {}", up_rate.note);
  if (!set_bit_rate(*link, file, up_rate.lss_stored ? "LSS-stored bit rate" : "upstream.bitrate",
                    cfg->upstream.interface, up_rate.bitrate) ||
      !set_bit_rate(*link, file, "downstream.bitrate", cfg->downstream.interface, cfg->downstream.bitrate))
    return exit_code::kCannotStart;
  std::unique_ptr<SocketCanTransport> up, down;
  try {
    up = SocketCanTransport::open(cfg->upstream.interface);
  } catch (const CanOpenError& e) {
    spdlog::error("{}: upstream.interface: {}", file, e.what());
    return exit_code::kCannotStart;
  }
  try {
    down = SocketCanTransport::open(cfg->downstream.interface);
  } catch (const CanOpenError& e) {
    spdlog::error("{}: downstream.interface: {}", file, e.what());
    return exit_code::kCannotStart;
  }
  GatewayBuses buses{*up, *down};
  const std::string& up_name = cfg->upstream.interface;
  buses.set_upstream_bit_rate = [&link, &up_name](std::uint32_t rate) { return apply_bit_rate(*link, up_name, rate); };
  // The receive buffers (SocketCanOptions::rx_buffer_bytes): what the kernel granted.
  buses.watching = [&up, &down] {
    for (const auto& [bus, side] : {std::pair{up.get(), "upstream"}, std::pair{down.get(), "downstream"}})
      if (bus->rx_buffer_capped())
        spdlog::warn(
            "{} {}: receive buffer {} kB, less than the {} kB asked (no CAP_NET_ADMIN: net.core.rmem_max "
            "caps it); frames are lost if the gateway is held off longer",
            side, bus->interface(), bus->rx_buffer_bytes() / 1024, SocketCanOptions::kDefaultRxBufferBytes / 1024);
  };
  return serve_gateway(file, *cfg, loop, buses);
}

int serve_gateway(const std::string& file, mapping::Config& config, EventLoop& loop, const GatewayBuses& buses,
                  const ServeHooks& hooks) {
  Daemon daemon(file, config, loop, buses, hooks);
  return daemon.run();
}

}  // namespace oegw::gateway
