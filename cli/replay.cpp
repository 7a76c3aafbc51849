#include "cli/replay.hpp"

#include <memory>

#include "cli/app.hpp"
#include "cli/replay_command.hpp"

namespace oegw::cli {

void register_replay(CLI::App& app) {
  auto o = std::make_shared<cli::ReplayCommandOptions>();
  auto* cmd =
      app.add_subcommand("replay",
                         "Re-run the gateway on a recording (or a candump log) and compare its frames and decisions")
          ->group(kBlackBoxGroup);
  cmd->add_option("recording", o->recording,
                  "A recording folder (record.dir, or a kept window), one of its segment files, or a candump log")
      ->required();
  cmd->add_option("--config", o->config, "The mapping file the gateway ran with")->required();
  cmd->add_option("--from", o->from,
                  "Timeline from: seconds from the recording's start (12.5) or a time of day (14:03:12)");
  cmd->add_option("--to", o->to, "Timeline to (as --from)");
  cmd->add_option("--fe", o->fe, "Timeline of one FE only (joystick.1)");
  cmd->add_option("--subdevice", o->subdevice, "Timeline of one sub-device only (right_grip)");
  cmd->add_flag("--frames", o->frames, "Print the frames in the timeline too");
  cmd->add_flag("--logs", o->logs, "Print the gateway's log lines in the timeline too");
  cmd->add_flag("--fresh", o->fresh,
                "Re-run the recorded inputs (frames, commands, bus events) on a new gateway and print its "
                "decisions, nothing compared (what this mapping file would have made of them)");
  cmd->add_flag("-q,--quiet", o->quiet, "No timeline: the comparison's result only");
  cmd->add_option("--plot", o->plot,
                  "Draw the timeline: FILE.html (a self-contained page, Chart.js) or FILE.svg (a static picture)");
  cmd->callback([o] { finish(cli::run_replay(*o)); });
}

}  // namespace oegw::cli
