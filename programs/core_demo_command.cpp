#include "programs/core_demo_command.hpp"

#include <memory>

#include "cli/app.hpp"
#include "programs/core_demo.hpp"

namespace oegw::programs {

void register_core_demo(CLI::App& app) {
  auto o = std::make_shared<DemoOptions>();
  auto* cmd = app.add_subcommand("core-demo", "The protocol core's demo: one CiA 301 device and a host")
                  ->group(cli::kToolsGroup);
  cmd->add_option("--seconds", o->live_seconds, "How long the inputs move in operational")
      ->check(CLI::Range(0.0, 3600.0));
  cmd->add_flag("--frames", o->frames, "Print every CAN frame (candump notation)");
  cmd->add_flag("--publish", o->publish,
                "Publish the joystick on DDS (loopback) and LCM (ttl=0), take indicator commands back");
  cmd->callback([o] { cli::finish(run_demo(*o)); });
}

}  // namespace oegw::programs
