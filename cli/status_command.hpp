// `oegw status`: asks the running `oegw run` over its control socket and prints what it sees,
// as a table that fits 100 columns, or (--json) the daemon's answer as it came.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "cli/control_client.hpp"
#include "cli/exit_codes.hpp"

namespace oegw::cli {

struct StatusOptions {
  std::string socket;  // empty: from `config`, else mapping::kDefaultControlSocket
  std::string config;  // a mapping file whose control.socket to ask
  bool json = false;
  double timeout_s = 2.0;
};

// Exit codes of `oegw status` (docs/guides/install.md#asking-the-running-gateway-oegw-status), from
// the one table of every command (cli/exit_codes.hpp).
inline constexpr int kStatusOk = cli::exit_code::kOk;
inline constexpr int kStatusFailed = cli::exit_code::kBadFile;  // a bad answer, an error answer, an unreadable --config
inline constexpr int kStatusNoDaemon = cli::exit_code::kNoDaemon;      // no socket, or nobody listening
inline constexpr int kStatusPermission = cli::exit_code::kPermission;  // the socket's group keeps this user out
inline constexpr int kStatusTimeout = cli::exit_code::kTimeout;        // no answer in --timeout

int run_status(const StatusOptions& options);

// The socket to ask: `socket`, else the mapping file `config`'s control.socket, else the default
// (`ok` false, after an error on stderr naming `program`, for an unreadable `config`).
[[nodiscard]] std::string control_socket_of(const std::string& socket, const std::string& config, const char* program,
                                            bool& ok);
// The exit code (above) of a failed ask_daemon (`oegw status`, `oegw ctl`).
[[nodiscard]] int ask_exit_code(AskStatus s);

// The table for a `status` object (the answer's "status"), lines of at most 100 columns.
[[nodiscard]] std::string status_table(const nlohmann::json& status);

}  // namespace oegw::cli
