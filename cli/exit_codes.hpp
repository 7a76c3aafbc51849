// The exit codes of every oegw command, in one table (docs/reference/exit-codes.md): the
// commands of cli/ return them, the daemon (gateway/) exits with them, and `oegw --help` prints
// them once, as the app's footer. The unit's RestartPreventExitStatus= names kBadFile: a bad file
// does not get better by restarting.
#pragma once

namespace oegw::cli::exit_code {

inline constexpr int kOk = 0;
// The mapping file is refused (check, eds, run); demo: a step failed; master: not all
// operational in time; signals: options the driver refuses; scan: no node found; status, ctl: a
// bad or error answer (ctl --exit: the first ERROR answer).
inline constexpr int kBadFile = 1;
inline constexpr int kCannotStart = 2;  // a CAN interface, its bit rate or publishing cannot be set up
// The control socket (`oegw status`, `oegw ctl`, `oegw record keep`, `oegw scan` through the
// gateway; docs/guides/install.md#asking-the-running-gateway-oegw-status):
inline constexpr int kNoDaemon = 3;    // no socket, or nobody listening
inline constexpr int kPermission = 4;  // the socket's group keeps this user out
inline constexpr int kTimeout = 5;     // no answer in --timeout
inline constexpr int kUsage = 64;      // the command line is refused (EX_USAGE, sysexits.h)

// The paragraph `oegw --help` ends with (only the app's: no command repeats it).
inline constexpr const char* kHelpFooter =
    "Exit codes: 0 done; 1 bad mapping file (or a demo step / master wait failed, or options a driver refuses in "
    "signals, or no node found by scan); 2 cannot start (CAN interface, bit rate, publishing); 64 usage error "
    "(docs/reference/exit-codes.md).";

}  // namespace oegw::cli::exit_code
