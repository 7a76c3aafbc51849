// oegw — the CiA 852 operator-environment gateway program.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "gateway/button_bits_command.hpp"
#include "gateway/control/ctl_command.hpp"
#include "gateway/control/status_command.hpp"
#include "gateway/programs.hpp"
#include "gateway/record/replay_command.hpp"
#include "gateway/scan_command.hpp"
#include "gateway/signals_command.hpp"
#include "programs/version.hpp"
#include "programs/bench_programs.hpp"
#include "programs/core_demo.hpp"
#include "programs/gateway_demo.hpp"
#include "programs/gateway_sim.hpp"

namespace {

// `run --log-level`: spdlog's levels by the names an integrator types, most verbose first (the
// order the refusal lists them in).
const std::vector<std::pair<std::string, spdlog::level::level_enum>> kLogLevels = {
    {"trace", spdlog::level::trace}, {"debug", spdlog::level::debug}, {"info", spdlog::level::info},
    {"warn", spdlog::level::warn},   {"error", spdlog::level::err},   {"off", spdlog::level::off}};

}  // namespace

int main(int argc, char** argv) {
  namespace exit_code = oegw::gateway::exit_code;
  CLI::App app{"oegw — CiA 852 operator-environment gateway"};
  app.require_subcommand(0, 1);
  app.set_version_flag("--version", std::string("oegw ") + oegw::programs::kVersion + " (git " +
                                        oegw::programs::kGitRevision + ")");
  app.footer("Exit codes: 0 done; 1 bad mapping file (or a demo step / master wait failed, or options a driver refuses in signals, or no node found by scan); 2 cannot start "
             "(CAN interface, bit rate, publishing); 64 usage error (docs/reference/exit-codes.md).");

  oegw::gateway::GatewayDemoOptions demo;
  auto* demo_cmd = app.add_subcommand("demo", "The embedded demo: gateway, simulated cab devices and a host (default)");
  demo_cmd->add_option("--seconds", demo.seconds, "How long the operator moves the joysticks")
      ->check(CLI::Range(0.0, 3600.0));
  demo_cmd->add_flag("--frames", demo.frames, "Print every CAN frame of both buses in candump's log format (canplayer replays it)");
  demo_cmd->add_flag("--fast", demo.fast, "Run on a simulated clock, as fast as possible (deterministic)");
  demo_cmd->add_flag("--publish,!--no-publish", demo.publish,
                     "Publish every FE on DDS (loopback only) and LCM (ttl=0) and take indicator commands back "
                     "(the default; --no-publish turns it off)");
  demo_cmd->add_option("--dds-security", demo.dds_security,
                       "DDS Security with the set in DIR (scripts/make-dds-security.sh --partition oegw-demo DIR): "
                       "the gateway's identity; watch with the examples' --identity-ca ... options")
      ->type_name("DIR")
      ->check(CLI::ExistingDirectory);

  oegw::gateway::GatewaySimOptions sim;
  auto* sim_cmd = app.add_subcommand(
      "sim", "Your own mapping file on a simulated cab: its sub-devices simulated, a built-in host, the live table");
  sim_cmd->add_option("file", sim.file, "The mapping file (its interfaces are not used: the buses are in-process)")
      ->required()
      ->check(CLI::ExistingFile);
  sim_cmd->add_option("--seconds", sim.seconds, "How long (default: until ^C; with --fast: the script's end + 1 s, or 10 s)")
      ->check(CLI::Range(0.0, 86400.0));
  sim_cmd->add_flag("--fast", sim.fast, "Run on a simulated clock, as fast as possible (deterministic; for CI)");
  sim_cmd->add_flag("--motion,!--no-motion", sim.motion, "The operator moves every input from the start (the default)");
  sim_cmd->add_flag("--publish,!--no-publish", sim.publish, "Publish as the file's publish section says (the default)");
  sim_cmd->add_flag("--frames", sim.frames, "Print every CAN frame of both buses in candump's log format");
  sim_cmd->add_option("--script", sim.script, "Commands at times: lines of SECONDS COMMAND (docs/guides/simulate.md)")
      ->type_name("FILE")
      ->check(CLI::ExistingFile);
  sim_cmd->add_option("--vcan", sim.vcan, "Both buses also on these SocketCAN interfaces, for candump and other hosts")
      ->type_name("UP,DOWN");

  oegw::gateway::DemoOptions core_demo;
  auto* core_cmd = app.add_subcommand("core-demo", "The protocol core's demo: one CiA 301 device and a host");
  core_cmd->add_option("--seconds", core_demo.live_seconds, "How long the inputs move in operational")
      ->check(CLI::Range(0.0, 3600.0));
  core_cmd->add_flag("--frames", core_demo.frames, "Print every CAN frame (candump notation)");
  core_cmd->add_flag("--publish", core_demo.publish,
                     "Publish the joystick on DDS (loopback) and LCM (ttl=0), take indicator commands back");

  oegw::gateway::DeviceOptions device;
  int node_id = 0x20;
  bool no_motion = false;
  std::string store;
  auto* dev_cmd = app.add_subcommand("device", "Run the protocol core's demo device on a SocketCAN interface");
  dev_cmd->add_option("-i,--interface", device.interface, "SocketCAN interface")->required();
  dev_cmd->add_option("-n,--node-id", node_id, "CANopen node-ID 1..127 (0x.. accepted)")->check(CLI::Range(1, 127));
  dev_cmd->add_option("--heartbeat-ms", device.heartbeat_ms, "Producer heartbeat time (1017h default)");
  dev_cmd->add_option("--store", store, "Parameter file for 1010h/1011h and LSS store");
  dev_cmd->add_flag("--no-motion", no_motion, "Keep the inputs still (for scripted peers)");

  oegw::gateway::MasterOptions master;
  auto* master_cmd = app.add_subcommand("master", "Run the downstream network manager with drivers on a SocketCAN interface");
  master_cmd->add_option("-i,--interface", master.interface, "SocketCAN interface")->required();
  master_cmd->add_option("--heartbeat-ms", master.heartbeat_ms, "Producer heartbeat written to every node")
      ->check(CLI::Range(0, 65535));
  master_cmd->add_option("--until-operational", master.until_operational,
                         "Exit 0 once every node is operational, 1 after this many seconds");
  master_cmd
      ->add_option("devices", master.devices,
                   "family:node[:key=value,...], as for oegw-sim, with the driver's options (mcb402 requires "
                   "button_bits=1/2/3/4/5/7/6, or its board's order: docs/design/device-documents.md#mcb-402-button-bits-a-required-commissioning-choice)")
      ->required();

  std::string config_file;
  auto* check_cmd = app.add_subcommand("check", "Validate a mapping file and print the upstream layout");
  check_cmd->add_option("file", config_file, "Mapping file (YAML)")->required();
  bool check_quiet = false;
  check_cmd->add_flag("-q,--quiet", check_quiet,
                      "Of a valid file print only 'FILE: valid' and the warnings (errors and exit codes as without it)");
  bool check_here = false;
  check_cmd->add_flag("--here", check_here,
                      "Check on the machine the file is for: refuse what this machine lacks for it (a missing store "
                      "folder, control.group, ...) as oegw run does; without it those are warnings");
  std::string eds_out = "-";
  auto* eds_cmd = app.add_subcommand("eds", "Write the EDS of the upstream device a mapping file configures");
  eds_cmd->add_option("file", config_file, "Mapping file (YAML)")->required();
  eds_cmd->add_option("-o,--output", eds_out, "EDS file to write (default: standard output)");
  auto* run_cmd = app.add_subcommand("run", "Run the gateway on the CAN interfaces the mapping file names");
  run_cmd->add_option("file", config_file, "Mapping file (YAML)")->required();
  std::string log_level = "info";
  std::vector<std::string> level_names;
  for (const auto& [name, level] : kLogLevels) level_names.push_back(name);
  run_cmd->add_option("--log-level", log_level, "Least severe message logged: trace, debug, info (default), warn, error, off")
      ->check(CLI::IsMember(level_names));

  oegw::gateway::SignalsOptions signals;
  auto* signals_cmd = app.add_subcommand(
      "signals", "Every driver's signals (name, direction, kind, range, unit, neutral) and options, from the drivers");
  signals_cmd->add_option("driver", signals.driver, "One driver: elobau-mfg, mcb402, novotechnik-406, cia401");
  signals_cmd->add_option("-o,--option", signals.options,
                          "A driver option key=value, as in the mapping file (e.g. detent=clamp); repeatable");
  signals_cmd->add_option("--eds", signals.eds, "cia401: the EDS file whose signals to list");
  signals_cmd->add_flag("--markdown", signals.markdown, "Markdown tables, as in docs/reference/drivers.md");
  // Commissioning an MCB-402: its button wiring read off the board
  // (docs/design/device-documents.md#mcb-402-button-bits-a-required-commissioning-choice).
  bool find_button_bits = false;
  oegw::gateway::FindButtonBitsOptions find_bits;
  signals_cmd->add_flag("--find-button-bits", find_button_bits,
                        "mcb402: watch the board's TPDO1 on -i IF, ask for BP1..BP7 in turn and print its button_bits line");
  signals_cmd->add_option("-i,--interface", find_bits.interface, "--find-button-bits: the sub-devices' CAN interface");
  signals_cmd->add_option("--node", find_bits.node, "--find-button-bits: the board's node-ID (default 3)")->check(CLI::Range(1, 127));
  signals_cmd->add_option("--timeout", find_bits.timeout_s, "--find-button-bits: seconds to wait for each press (default 60)")
      ->check(CLI::Range(1.0, 3600.0));

  oegw::gateway::ScanOptions scan;
  auto* scan_cmd = app.add_subcommand(
      "scan", "Find every node on the downstream bus (before the gateway runs, or through it) and write a draft mapping file");
  scan_cmd->add_option("-i,--interface", scan.interface,
                       "SocketCAN interface of the sub-devices' bus (default: the running gateway's)");
  bool via_daemon = false, via_direct = false;
  auto* scan_daemon = scan_cmd->add_flag("--daemon", via_daemon, "Scan through the running gateway only (its control socket)");
  scan_cmd->add_flag("--direct", via_direct, "Scan the interface itself, without asking a running gateway")->excludes(scan_daemon);
  scan_cmd->add_option("--socket", scan.socket, "Control socket (default: the mapping file's control.socket, else /run/oegw/oegw.sock)");
  scan_cmd->add_option("--config", scan.config, "Mapping file whose control.socket to ask");
  scan_cmd->add_option("-o,--output", scan.output, "Draft mapping file to write (default: standard output)");
  auto* scan_upstream =
      scan_cmd->add_option("--upstream", scan.upstream, "The draft's upstream interface (default can0; can1 when -i is can0)");
  scan_cmd->add_option("--bitrate", scan.bitrate, "The draft's bit rate (default 250000; not measured)")
      ->check(CLI::IsMember({10000, 20000, 50000, 125000, 250000, 500000, 800000, 1000000}));
  scan_cmd->add_option("--store", scan.store,
                       "The draft's upstream.store (default: not written, i.e. /var/lib/oegw/upstream.store)");
  scan_cmd->add_option("--timeout", scan.timeout_ms, "SDO time-out per read, ms (default 100)")->check(CLI::Range(1.0, 10000.0));
  scan_cmd->add_option("--listen", scan.listen_ms, "The scan lasts at least this long to hear heartbeats, ms (default 1000)")
      ->check(CLI::Range(0.0, 600000.0));
  scan_cmd->add_option("--parallel", scan.parallel, "Node-IDs probed at once, 1..127 (default 8)")->check(CLI::Range(1, 127));
  scan_cmd->add_option("--lss-timeout", scan.lss_timeout_ms, "LSS time-out per step, ms (default 25)")
      ->check(CLI::Range(1.0, 10000.0));
  scan_cmd->add_flag("!--no-lss", scan.lss, "Skip LSS (nodes without node-ID)");
  scan_cmd->add_flag("!--quiet,!-q", scan.progress, "No progress lines on standard error");
  scan_cmd->footer(
      "Without --direct it asks the running gateway first (--socket/--config, else the default socket): when one runs "
      "on the interface (or -i is not given), the scan goes through it: its sub-devices are reported as it knows them "
      "(never probed: their SDO channels are its own) and the other node-IDs are probed beside it.");

  oegw::gateway::StatusOptions status;
  auto* status_cmd = app.add_subcommand("status", "Ask the running `oegw run` what it sees (its control socket)");
  status_cmd->add_option("--socket", status.socket, "Control socket (default: the mapping file's control.socket, else /run/oegw/oegw.sock)");
  status_cmd->add_option("--config", status.config, "Mapping file whose control.socket to ask");
  status_cmd->add_flag("--json", status.json, "Print the daemon's JSON answer as it is (gateway/control/PROTOCOL.md)");
  status_cmd->add_option("--timeout", status.timeout_s, "Seconds to wait for the answer")->check(CLI::Range(0.1, 60.0));

  oegw::gateway::CtlOptions ctl;
  ctl.version = oegw::programs::kVersion;
  auto* ctl_cmd = app.add_subcommand(
      "ctl", "CiA 309-3 ASCII commands (read, write, NMT, LSS, info version, events) into the running `oegw run`");
  ctl_cmd->add_option("--socket", ctl.socket, "Control socket (default: the mapping file's control.socket, else /run/oegw/oegw.sock)");
  ctl_cmd->add_option("--config", ctl.config, "Mapping file whose control.socket to ask");
  ctl_cmd->add_flag("-e,--exit", ctl.exit_on_error, "Exit 1 at the first ERROR answer (scripts)");
  ctl_cmd->add_option("--timeout", ctl.timeout_s, "Seconds to wait for one answer (at least the SDO time-out + 2 s)")
      ->check(CLI::Range(0.1, 120.0));
  ctl_cmd->footer("Commands, one a line on standard input (docs/reference/control-protocol.md, docs/guides/commission.md):\n"
                  "  [seq] [[net] node] r[ead] <index> <sub> <type>      [seq] [[net] node] w[rite] <index> <sub> <type> <value>\n"
                  "  [seq] [[net] node] start|stop|preop|reset node|reset comm\n"
                  "  [seq] set network N | [net] set node N | [net] set sdo_timeout MS | info version\n"
                  "  [seq] [net] lss_switch_glob 0|1 | lss_switch_sel <vendor> <product> <revision> <serial>\n"
                  "  [seq] [net] lss_set_node ID | lss_conf_bitrate 0 INDEX | lss_activate_bitrate MS | lss_store\n"
                  "  [seq] [net] lss_inquire_addr [0..3] | lss_get_node | lss_ident_nonconf | _lss_fastscan [MS]\n"
                  "  [seq] [net] _lss_fastscan <vendor> <mask> <product> <mask> <revision> <mask> <serial> <mask>\n"
                  "  [seq] [net] lss_identity|_lss_slowscan <vendor> <product> <rev lo> <rev hi> <serial lo> <serial hi>\n"
                  "  types: b u8 u16 u32 u64 i8 i16 i32 i64 r32 r64 vs os d; interactive: history, !!, !N\n");

  oegw::gateway::record::ReplayCommandOptions replay;
  auto* replay_cmd = app.add_subcommand(
      "replay", "Re-run the gateway on a recording (or a candump log) and compare its frames and decisions");
  replay_cmd->add_option("recording", replay.recording,
                         "A recording folder (record.dir, or a kept window), one of its segment files, or a candump log")
      ->required();
  replay_cmd->add_option("--config", replay.config, "The mapping file the gateway ran with")->required();
  replay_cmd->add_option("--from", replay.from, "Timeline from: seconds from the recording's start (12.5) or a time of day (14:03:12)");
  replay_cmd->add_option("--to", replay.to, "Timeline to (as --from)");
  replay_cmd->add_option("--fe", replay.fe, "Timeline of one FE only (joystick.1)");
  replay_cmd->add_option("--subdevice", replay.subdevice, "Timeline of one sub-device only (right_grip)");
  replay_cmd->add_flag("--frames", replay.frames, "Print the frames in the timeline too");
  replay_cmd->add_flag("--logs", replay.logs, "Print the gateway's log lines in the timeline too");
  replay_cmd->add_flag("-q,--quiet", replay.quiet, "No timeline: the comparison's result only");
  replay_cmd->add_option("--plot", replay.plot, "Draw the timeline: FILE.html (a self-contained page, Chart.js) or FILE.svg (a static picture)");

  oegw::gateway::StatusOptions keep;
  keep.timeout_s = 10.0;
  auto* record_cmd = app.add_subcommand("record", "The running gateway's recording (the black box)");
  record_cmd->require_subcommand(1);
  auto* keep_cmd = record_cmd->add_subcommand("keep", "Keep the recording's window now (kept/<time>/ in record.dir)");
  keep_cmd->add_option("--socket", keep.socket, "Control socket (default: the mapping file's control.socket, else /run/oegw/oegw.sock)");
  keep_cmd->add_option("--config", keep.config, "Mapping file whose control.socket to ask");
  keep_cmd->add_flag("--json", keep.json, "Print the daemon's JSON answer");
  keep_cmd->add_option("--timeout", keep.timeout_s, "Seconds to wait for the answer (default 10)")->check(CLI::Range(0.1, 120.0));

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version end here with 0; every other parse error (CLI11's 105..109 and the
    // rest) is one usage error, 64 (EX_USAGE, sysexits.h), after CLI11's message.
    const int rc = app.exit(e);
    return rc == 0 ? exit_code::kOk : exit_code::kUsage;
  }
  spdlog::set_pattern("%^%l%$: %v");  // journald adds its own timestamps
  for (const auto& [name, level] : kLogLevels)
    if (name == log_level) spdlog::set_level(level);

  if (*master_cmd) return oegw::gateway::run_master(master);
  if (*check_cmd) return oegw::gateway::run_check(config_file, check_quiet, check_here);
  if (*eds_cmd) return oegw::gateway::run_eds(config_file, eds_out);
  if (*run_cmd) return oegw::gateway::run_gateway(config_file);
  if (*status_cmd) return oegw::gateway::run_status(status);
  if (*replay_cmd) return oegw::gateway::record::run_replay(replay);
  if (*keep_cmd) return oegw::gateway::record::run_record_keep(keep);
  if (*ctl_cmd) return oegw::gateway::run_ctl(ctl);
  if (*signals_cmd && find_button_bits) {
    if (signals.driver != "mcb402" || find_bits.interface.empty()) {
      std::fprintf(stderr, "--find-button-bits: expected `oegw signals mcb402 --find-button-bits -i IF [--node N]`\n");
      return exit_code::kUsage;
    }
    return oegw::gateway::run_find_button_bits(find_bits);
  }
  if (*signals_cmd) return oegw::gateway::run_signals(signals);
  if (*scan_cmd) {
    scan.via = via_daemon ? oegw::gateway::ScanOptions::Via::Daemon
               : via_direct ? oegw::gateway::ScanOptions::Via::Direct
                              : oegw::gateway::ScanOptions::Via::Auto;
    if (scan.via == oegw::gateway::ScanOptions::Via::Direct && scan.interface.empty()) {
      std::fprintf(stderr, "--direct: -i IF names the bus to scan\n");
      return exit_code::kUsage;
    }
    scan.upstream_given = static_cast<bool>(*scan_upstream);
    scan.bitrate_given = scan_cmd->count("--bitrate") > 0;
    // The draft's two buses must differ (oegw check refuses one interface for both).
    if (!*scan_upstream && scan.interface == scan.upstream) scan.upstream = "can1";
    if (scan.upstream == scan.interface) {
      std::fprintf(stderr, "--upstream %s is the interface scanned; expected the host's bus\n", scan.upstream.c_str());
      return exit_code::kUsage;
    }
    return oegw::gateway::run_scan(scan);
  }
  if (*dev_cmd) {
    device.node_id = oegw::canopen::NodeId{static_cast<std::uint8_t>(node_id)};
    device.store_path = store;
    device.motion = !no_motion;
    return oegw::gateway::run_device(device);
  }
  if (*sim_cmd) return oegw::gateway::run_gateway_sim(sim);
  if (*core_cmd) return oegw::gateway::run_demo(core_demo);
  return oegw::gateway::run_gateway_demo(demo);
}
