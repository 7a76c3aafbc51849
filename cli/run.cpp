#include "cli/run.hpp"

#include <spdlog/spdlog.h>

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "cli/app.hpp"
#include "gateway/programs.hpp"

namespace oegw::cli {
namespace {

// `run --log-level`: spdlog's levels by the names an integrator types, most verbose first (the
// order the refusal lists them in).
const std::vector<std::pair<std::string, spdlog::level::level_enum>> kLogLevels = {{"trace", spdlog::level::trace},
                                                                                   {"debug", spdlog::level::debug},
                                                                                   {"info", spdlog::level::info},
                                                                                   {"warn", spdlog::level::warn},
                                                                                   {"error", spdlog::level::err},
                                                                                   {"off", spdlog::level::off}};

}  // namespace

void register_run(CLI::App& app) {
  struct Options {
    std::string file;
    std::string log_level = "info";
  };
  auto o = std::make_shared<Options>();
  auto* cmd =
      app.add_subcommand("run", "Run the gateway on the CAN interfaces the mapping file names")->group(kDailyGroup);
  cmd->add_option("file", o->file, "Mapping file (YAML)")->required();
  std::vector<std::string> level_names;
  for (const auto& [name, level] : kLogLevels) level_names.push_back(name);
  cmd->add_option("--log-level", o->log_level,
                  "Least severe message logged: trace, debug, info (default), warn, error, off")
      ->check(CLI::IsMember(level_names));
  cmd->callback([o] {
    for (const auto& [name, level] : kLogLevels)
      if (name == o->log_level) spdlog::set_level(level);
    finish(gateway::run_gateway(o->file));
  });
}

}  // namespace oegw::cli
