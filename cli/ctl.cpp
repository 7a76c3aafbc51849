#include "cli/ctl.hpp"

#include <memory>

#include "cli/app.hpp"
#include "cli/ctl_command.hpp"
#include "cli/version.hpp"

namespace oegw::cli {

void register_ctl(CLI::App& app) {
  auto o = std::make_shared<cli::CtlOptions>();
  o->version = kVersion;
  auto* cmd = app.add_subcommand("ctl",
                                 "CiA 309-3 ASCII commands (read, write, NMT, LSS, info version, events) into the "
                                 "running `oegw run`")
                  ->group(kDailyGroup);
  cmd->add_option("--socket", o->socket,
                  "Control socket (default: the mapping file's control.socket, else /run/oegw/oegw.sock)");
  cmd->add_option("--config", o->config, "Mapping file whose control.socket to ask");
  cmd->add_flag("-e,--exit", o->exit_on_error, "Exit 1 at the first ERROR answer (scripts)");
  cmd->add_option("--timeout", o->timeout_s, "Seconds to wait for one answer (at least the SDO time-out + 2 s)")
      ->check(CLI::Range(0.1, 120.0));
  cmd->footer(
      "Commands, one a line on standard input (docs/reference/control-protocol.md, docs/guides/commission.md):\n"
      "  [seq] [[net] node] r[ead] <index> <sub> <type>      [seq] [[net] node] w[rite] <index> <sub> <type> <value>\n"
      "  [seq] [[net] node] start|stop|preop|reset node|reset comm\n"
      "  [seq] set network N | [net] set node N | [net] set sdo_timeout MS | info version\n"
      "  [seq] [net] lss_switch_glob 0|1 | lss_switch_sel <vendor> <product> <revision> <serial>\n"
      "  [seq] [net] lss_set_node ID | lss_conf_bitrate 0 INDEX | lss_activate_bitrate MS | lss_store\n"
      "  [seq] [net] lss_inquire_addr [0..3] | lss_get_node | lss_ident_nonconf | _lss_fastscan [MS]\n"
      "  [seq] [net] _lss_fastscan <vendor> <mask> <product> <mask> <revision> <mask> <serial> <mask>\n"
      "  [seq] [net] lss_identity|_lss_slowscan <vendor> <product> <rev lo> <rev hi> <serial lo> <serial hi>\n"
      "  types: b u8 u16 u32 u64 i8 i16 i32 i64 r32 r64 vs os d; interactive: history, !!, !N\n");
  cmd->callback([o] { finish(cli::run_ctl(*o)); });
}

}  // namespace oegw::cli
