#include "programs/demo_command.hpp"

#include <memory>

#include "cli/app.hpp"
#include "programs/gateway_demo.hpp"

namespace oegw::programs {

void register_demo(CLI::App& app) {
  auto o = std::make_shared<GatewayDemoOptions>();
  auto* cmd = app.add_subcommand("demo", "The embedded demo: gateway, simulated cab devices and a host (default)")
                  ->group(cli::kDailyGroup);
  cmd->add_option("--seconds", o->seconds, "How long the operator moves the joysticks")->check(CLI::Range(0.0, 3600.0));
  cmd->add_flag("--frames", o->frames,
                "Print every CAN frame of both buses in candump's log format (canplayer replays it)");
  cmd->add_flag("--fast", o->fast, "Run on a simulated clock, as fast as possible (deterministic)");
  cmd->add_flag("--publish,!--no-publish", o->publish,
                "Publish every FE on DDS (loopback only) and LCM (ttl=0) and take indicator commands back "
                "(the default; --no-publish turns it off)");
  cmd->add_option("--dds-security", o->dds_security,
                  "DDS Security with the set in DIR (scripts/make-dds-security.sh --partition oegw-demo DIR): "
                  "the gateway's identity; watch with the examples' --identity-ca ... options")
      ->type_name("DIR")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--vcan", o->vcan, "Both buses also on these SocketCAN interfaces, for candump and other hosts")
      ->type_name("UP,DOWN");
  cmd->callback([o] { cli::finish(run_gateway_demo(*o)); });
  // No command is the demo with its defaults: the app's own callback runs only when no command's
  // callback ended the run (cli::finish) before it.
  app.callback([o] { cli::finish(run_gateway_demo(*o)); });
}

}  // namespace oegw::programs
