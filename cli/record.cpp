#include "cli/record.hpp"

#include <memory>

#include "cli/app.hpp"
#include "cli/replay_command.hpp"
#include "cli/status_command.hpp"

namespace oegw::cli {

void register_record(CLI::App& app) {
  auto o = std::make_shared<cli::StatusOptions>();
  o->timeout_s = 10.0;
  auto* cmd = app.add_subcommand("record", "The running gateway's recording (the black box)")->group(kBlackBoxGroup);
  cmd->require_subcommand(1);
  auto* keep = cmd->add_subcommand("keep", "Keep the recording's window now (kept/<time>/ in record.dir)")
                   ->group("Subcommands");  // not the parent's group, which CLI11 copies
  keep->add_option("--socket", o->socket,
                   "Control socket (default: the mapping file's control.socket, else /run/oegw/oegw.sock)");
  keep->add_option("--config", o->config, "Mapping file whose control.socket to ask");
  keep->add_flag("--json", o->json, "Print the daemon's JSON answer");
  keep->add_option("--timeout", o->timeout_s, "Seconds to wait for the answer (default 10)")
      ->check(CLI::Range(0.1, 120.0));
  keep->callback([o] { finish(cli::run_record_keep(*o)); });
}

}  // namespace oegw::cli
