#include "cli/check.hpp"

#include <memory>
#include <string>

#include "cli/app.hpp"
#include "gateway/programs.hpp"

namespace oegw::cli {

void register_check(CLI::App& app) {
  struct Options {
    std::string file;
    bool quiet = false;
    bool here = false;
  };
  auto o = std::make_shared<Options>();
  auto* cmd = app.add_subcommand("check", "Validate a mapping file and print the upstream layout")->group(kDailyGroup);
  cmd->add_option("file", o->file, "Mapping file (YAML)")->required();
  cmd->add_flag("-q,--quiet", o->quiet,
                "Of a valid file print only 'FILE: valid' and the warnings (errors and exit codes as without it)");
  cmd->add_flag("--here", o->here,
                "Check on the machine the file is for: refuse what this machine lacks for it (a missing store "
                "folder, control.group, ...) as oegw run does; without it those are warnings");
  cmd->callback([o] { finish(gateway::run_check(o->file, o->quiet, o->here)); });
}

}  // namespace oegw::cli
