#include "cli/scan.hpp"

#include <cstdio>
#include <memory>

#include "cli/app.hpp"
#include "cli/exit_codes.hpp"
#include "cli/scan_command.hpp"

namespace oegw::cli {

void register_scan(CLI::App& app) {
  struct Options {
    cli::ScanOptions scan;
    bool via_daemon = false, via_direct = false;
  };
  auto o = std::make_shared<Options>();
  auto& scan = o->scan;
  auto* cmd = app.add_subcommand("scan",
                                 "Find every node on the downstream bus (before the gateway runs, or through it) and "
                                 "write a draft mapping file")
                  ->group(kDailyGroup);
  cmd->add_option("-i,--interface", scan.interface,
                  "SocketCAN interface of the sub-devices' bus (default: the running gateway's)");
  auto* daemon = cmd->add_flag("--daemon", o->via_daemon, "Scan through the running gateway only (its control socket)");
  cmd->add_flag("--direct", o->via_direct, "Scan the interface itself, without asking a running gateway")
      ->excludes(daemon);
  cmd->add_option("--socket", scan.socket,
                  "Control socket (default: the mapping file's control.socket, else /run/oegw/oegw.sock)");
  cmd->add_option("--config", scan.config, "Mapping file whose control.socket to ask");
  cmd->add_option("-o,--output", scan.output, "Draft mapping file to write (default: standard output)");
  auto* upstream = cmd->add_option("--upstream", scan.upstream,
                                   "The draft's upstream interface (default can0; can1 when -i is can0)");
  auto* bitrate = cmd->add_option("--bitrate", scan.bitrate, "The draft's bit rate (default 250000; not measured)")
                      ->check(CLI::IsMember({10000, 20000, 50000, 125000, 250000, 500000, 800000, 1000000}));
  cmd->add_option("--store", scan.store,
                  "The draft's upstream.store (default: not written, i.e. /var/lib/oegw/upstream.store)");
  cmd->add_option("--timeout", scan.timeout_ms, "SDO time-out per read, ms (default 100)")
      ->check(CLI::Range(1.0, 10000.0));
  cmd->add_option("--listen", scan.listen_ms, "The scan lasts at least this long to hear heartbeats, ms (default 1000)")
      ->check(CLI::Range(0.0, 600000.0));
  cmd->add_option("--parallel", scan.parallel, "Node-IDs probed at once, 1..127 (default 8)")
      ->check(CLI::Range(1, 127));
  cmd->add_option("--lss-timeout", scan.lss_timeout_ms, "LSS time-out per step, ms (default 25)")
      ->check(CLI::Range(1.0, 10000.0));
  cmd->add_flag("!--no-lss", scan.lss, "Skip LSS (nodes without node-ID)");
  cmd->add_flag("!--quiet,!-q", scan.progress, "No progress lines on standard error");
  cmd->footer(
      "Without --direct it asks the running gateway first (--socket/--config, else the default socket): when one runs "
      "on the interface (or -i is not given), the scan goes through it: its sub-devices are reported as it knows them "
      "(never probed: their SDO channels are its own) and the other node-IDs are probed beside it.");
  cmd->callback([o, upstream, bitrate] {
    auto& s = o->scan;
    using Via = cli::ScanOptions::Via;
    s.via = o->via_daemon ? Via::Daemon : o->via_direct ? Via::Direct : Via::Auto;
    if (s.via == Via::Direct && s.interface.empty()) {
      std::fprintf(stderr, "--direct: -i IF names the bus to scan\n");
      finish(exit_code::kUsage);
    }
    s.upstream_given = static_cast<bool>(*upstream);
    s.bitrate_given = static_cast<bool>(*bitrate);
    // The draft's two buses must differ (oegw check refuses one interface for both).
    if (!*upstream && s.interface == s.upstream) s.upstream = "can1";
    if (s.upstream == s.interface) {
      std::fprintf(stderr, "--upstream %s is the interface scanned; expected the host's bus\n", s.upstream.c_str());
      finish(exit_code::kUsage);
    }
    finish(cli::run_scan(s));
  });
}

}  // namespace oegw::cli
