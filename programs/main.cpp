// oegw — the CiA 852 operator-environment gateway program: its commands, each registered by its
// own file (cli/ for the daemon's and the control socket's, programs/ for the demos and the bench
// tools), in the order `oegw --help` lists them: the daily commands first, the tools last.
#include <CLI/CLI.hpp>

#include "cli/app.hpp"
#include "cli/check.hpp"
#include "cli/ctl.hpp"
#include "cli/eds.hpp"
#include "cli/record.hpp"
#include "cli/replay.hpp"
#include "cli/run.hpp"
#include "cli/scan.hpp"
#include "cli/signals.hpp"
#include "cli/status.hpp"
#include "programs/core_demo_command.hpp"
#include "programs/demo_command.hpp"
#include "programs/device_command.hpp"
#include "programs/master_command.hpp"
#include "programs/sim_command.hpp"

int main(int argc, char** argv) {
  CLI::App app{"oegw — CiA 852 operator-environment gateway"};
  oegw::cli::configure(app);
  oegw::cli::register_run(app);
  oegw::cli::register_check(app);
  oegw::cli::register_status(app);
  oegw::cli::register_ctl(app);
  oegw::cli::register_scan(app);
  oegw::cli::register_signals(app);
  oegw::cli::register_eds(app);
  oegw::programs::register_demo(app);
  oegw::programs::register_sim(app);
  oegw::cli::register_replay(app);
  oegw::cli::register_record(app);
  oegw::programs::register_core_demo(app);
  oegw::programs::register_device(app);
  oegw::programs::register_master(app);
  return oegw::cli::run(app, argc, argv);
}
