// The client side of the control socket (docs/reference/control-protocol.md; the server:
// gateway/control/control_server.hpp): one request line, one answer line, within a time-out. Used
// by `oegw status`, `oegw ctl`, `oegw record keep` and `oegw scan` through the gateway.
#pragma once

#include <chrono>
#include <string>

namespace oegw::cli {

enum class AskStatus {
  Ok,                // `text` is the answer line
  NoDaemon,          // no socket file, or nobody listening on it
  PermissionDenied,  // the socket's mode and group keep this user out
  Timeout,           // no whole answer in time
  Failed,            // anything else (`text` says what)
};

struct AskResult {
  AskStatus status = AskStatus::Failed;
  std::string text;  // the answer line (Ok), else a message naming the socket (and its group)
};

[[nodiscard]] AskResult ask_daemon(const std::string& socket, const std::string& request_line,
                                   std::chrono::milliseconds timeout);

}  // namespace oegw::cli
