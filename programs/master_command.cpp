#include "programs/master_command.hpp"

#include <memory>

#include "cli/app.hpp"
#include "programs/bench_programs.hpp"

namespace oegw::programs {

void register_master(CLI::App& app) {
  auto o = std::make_shared<MasterOptions>();
  auto* cmd = app.add_subcommand("master", "Run the downstream network manager with drivers on a SocketCAN interface")
                  ->group(cli::kToolsGroup);
  cmd->add_option("-i,--interface", o->interface, "SocketCAN interface")->required();
  cmd->add_option("--heartbeat-ms", o->heartbeat_ms, "Producer heartbeat written to every node")
      ->check(CLI::Range(0, 65535));
  cmd->add_option("--until-operational", o->until_operational,
                  "Exit 0 once every node is operational, 1 after this many seconds");
  cmd->add_option("devices", o->devices,
                  "family:node[:key=value,...], as for oegw-sim, with the driver's options (mcb402 requires "
                  "button_bits=1/2/3/4/5/7/6, or its board's order: "
                  "docs/design/device-documents.md#mcb-402-button-bits-a-required-commissioning-choice)")
      ->required();
  cmd->callback([o] { cli::finish(run_master(*o)); });
}

}  // namespace oegw::programs
