#include "cli/eds.hpp"

#include <memory>
#include <string>

#include "cli/app.hpp"
#include "gateway/programs.hpp"

namespace oegw::cli {

void register_eds(CLI::App& app) {
  struct Options {
    std::string file;
    std::string out = "-";
  };
  auto o = std::make_shared<Options>();
  auto* cmd =
      app.add_subcommand("eds", "Write the EDS of the upstream device a mapping file configures")->group(kDailyGroup);
  cmd->add_option("file", o->file, "Mapping file (YAML)")->required();
  cmd->add_option("-o,--output", o->out, "EDS file to write (default: standard output)");
  cmd->callback([o] { finish(gateway::run_eds(o->file, o->out)); });
}

}  // namespace oegw::cli
