#include "programs/sim_command.hpp"

#include <memory>

#include "cli/app.hpp"
#include "programs/gateway_sim.hpp"

namespace oegw::programs {

void register_sim(CLI::App& app) {
  auto o = std::make_shared<GatewaySimOptions>();
  auto* cmd = app.add_subcommand("sim",
                                 "Your own mapping file on a simulated cab: its sub-devices simulated, a built-in "
                                 "host, the live table")
                  ->group(cli::kDailyGroup);
  cmd->add_option("file", o->file, "The mapping file (its interfaces are not used: the buses are in-process)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--seconds", o->seconds, "How long (default: until ^C; with --fast: the script's end + 1 s, or 10 s)")
      ->check(CLI::Range(0.0, 86400.0));
  cmd->add_flag("--fast", o->fast, "Run on a simulated clock, as fast as possible (deterministic; for CI)");
  cmd->add_flag("--motion,!--no-motion", o->motion, "The operator moves every input from the start (the default)");
  cmd->add_flag("--publish,!--no-publish", o->publish, "Publish as the file's publish section says (the default)");
  cmd->add_flag("--frames", o->frames, "Print every CAN frame of both buses in candump's log format");
  cmd->add_option("--script", o->script, "Commands at times: lines of SECONDS COMMAND (docs/guides/simulate.md)")
      ->type_name("FILE")
      ->check(CLI::ExistingFile);
  cmd->add_option("--vcan", o->vcan, "Both buses also on these SocketCAN interfaces, for candump and other hosts")
      ->type_name("UP,DOWN");
  cmd->add_option("--dds-security", o->dds_security,
                  "DDS Security with the set in DIR (scripts/make-dds-security.sh --partition PARTITION DIR): "
                  "the gateway's identity")
      ->type_name("DIR")
      ->check(CLI::ExistingDirectory);
  cmd->callback([o] { cli::finish(run_gateway_sim(*o)); });
}

}  // namespace oegw::programs
