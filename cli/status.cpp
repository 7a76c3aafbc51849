#include "cli/status.hpp"

#include <memory>

#include "cli/app.hpp"
#include "cli/status_command.hpp"

namespace oegw::cli {

void register_status(CLI::App& app) {
  auto o = std::make_shared<cli::StatusOptions>();
  auto* cmd =
      app.add_subcommand("status", "Ask the running `oegw run` what it sees (its control socket)")->group(kDailyGroup);
  cmd->add_option("--socket", o->socket,
                  "Control socket (default: the mapping file's control.socket, else /run/oegw/oegw.sock)");
  cmd->add_option("--config", o->config, "Mapping file whose control.socket to ask");
  cmd->add_flag("--json", o->json, "Print the daemon's JSON answer as it is (gateway/control/PROTOCOL.md)");
  cmd->add_option("--timeout", o->timeout_s, "Seconds to wait for the answer")->check(CLI::Range(0.1, 60.0));
  cmd->callback([o] { finish(cli::run_status(*o)); });
}

}  // namespace oegw::cli
