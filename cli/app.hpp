// What every oegw command shares on the command line (CLI11): the app's settings, the groups
// `oegw --help` lists the commands in, the parse with its exit codes (cli/exit_codes.hpp), and the
// way a command's run hands its exit code back to main().
#pragma once

#include <CLI/CLI.hpp>

namespace oegw::cli {

// `oegw --help` lists the daily commands first, the bench and test tools last (CLI11 lists the
// groups in the order their first command was registered: programs/main.cpp registers in this order).
inline constexpr const char* kDailyGroup = "Commands";
inline constexpr const char* kBlackBoxGroup = "Black box";
inline constexpr const char* kToolsGroup = "Bench and test tools";

// The app before any command is registered: the help formatter, --version, at most one command.
void configure(CLI::App& app);

// Ends a command's run with `code` (a callback returns nothing: run() returns it).
[[noreturn]] void finish(int code);

// Parses the command line and runs the command given (a callback of register_<cmd>); the exit code
// of cli/exit_codes.hpp: the command's, 0 for --help and --version, 64 for every usage error.
int run(CLI::App& app, int argc, char** argv);

}  // namespace oegw::cli
