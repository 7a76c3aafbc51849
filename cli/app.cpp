#include "cli/app.hpp"

#include <spdlog/spdlog.h>

#include <memory>
#include <regex>
#include <string>

#include "cli/exit_codes.hpp"
#include "cli/version.hpp"

namespace oegw::cli {
namespace {

// CLI11 names a flag with a default value (`!--no-lss`, `--publish,!--no-publish`) with that value
// in braces, `--no-lss{false}`: a parser detail, not a word the user types. The help names the
// flags as they are typed.
class HelpFormatter : public CLI::Formatter {
 public:
  std::string make_option_name(const CLI::Option* opt, bool is_positional) const override {
    const std::string name = CLI::Formatter::make_option_name(opt, is_positional);
    if (is_positional || opt->get_items_expected() != 0) return name;
    static const std::regex kFlagValue{"\\{[^}]*\\}"};
    return std::regex_replace(name, kFlagValue, "");
  }
};

}  // namespace

void configure(CLI::App& app) {
  app.formatter(std::make_shared<HelpFormatter>());  // the commands registered later inherit it
  app.require_subcommand(0, 1);
  app.set_version_flag("--version", std::string("oegw ") + kVersion + " (git " + kGitRevision + ")");
}

void finish(int code) { throw CLI::RuntimeError(code); }

int run(CLI::App& app, int argc, char** argv) {
  // Set here, after every command is registered: a command registered after it would inherit the
  // footer (CLI11 copies it), and the exit codes are said once, in `oegw --help`.
  app.footer(exit_code::kHelpFooter);
  spdlog::set_pattern("%^%l%$: %v");  // journald adds its own timestamps
  try {
    app.parse(argc, argv);
  } catch (const CLI::RuntimeError& e) {
    return e.get_exit_code();  // a command's run ended (finish)
  } catch (const CLI::ParseError& e) {
    // --help and --version end here with 0; every other parse error (CLI11's 105..109 and the
    // rest) is one usage error, 64 (EX_USAGE, sysexits.h), after CLI11's message.
    const int rc = app.exit(e);
    return rc == 0 ? exit_code::kOk : exit_code::kUsage;
  }
  return exit_code::kOk;
}

}  // namespace oegw::cli
