// `oegw ctl`: a CiA 309-3 ASCII command line into both buses of the running `oegw run`, over its
// control socket (docs/reference/control-protocol.md; the daemon's side is
// gateway/control/ctl_service.hpp, the CiA 309-3 text canopen/309/ascii_gateway.hpp). Commands
// from standard input, one a line: interactive on a terminal (a prompt, the event lines as they
// come, a history: `history`, `!!`, `!N`), scripted otherwise. With --exit the first ERROR answer
// ends it with exit code 1.
//
// The session state is the client's, as in lely's coctl: the default network and node
// (`set network`, `set node`), the SDO time-out per network (`set sdo_timeout`), the sequence
// numbers (a line without "[n]" gets the next one). Each command is one request on the socket.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "canopen/309/ascii_gateway.hpp"
#include "cli/control_client.hpp"
#include "cli/exit_codes.hpp"

namespace oegw::cli {

struct CtlOptions {
  std::string socket;  // empty: from `config`, else mapping::kDefaultControlSocket
  std::string config;
  bool exit_on_error = false;  // --exit
  double timeout_s = 10.0;     // the longest wait for one answer (longer: the SDO time-out + 2 s)
  std::string version;         // oegw's, for `info version`
};

// Exit codes besides those of `oegw status` (3 no daemon, 4 permission, 5 time-out).
inline constexpr int kCtlOk = cli::exit_code::kOk;
inline constexpr int kCtlError = cli::exit_code::kBadFile;  // --exit: an ERROR answer; or a failed answer of the daemon
// The daemon's LSS step time-out when `_lss_fastscan` names none (CANopenNode's default too).
inline constexpr std::uint32_t kDefaultLssStepMs = 100;

class CtlSession {
 public:
  using Ask = std::function<AskResult(const std::string& request_line, std::chrono::milliseconds timeout)>;
  CtlSession(Ask ask, std::string version, std::chrono::milliseconds answer_timeout);

  struct Outcome {
    std::vector<std::string> lines;  // answer (and event) lines to print
    bool error = false;              // an ERROR answer
    int fatal = 0;                   // non-zero: the daemon could not be asked; exit with this
    std::string why;                 // fatal: what happened (for stderr)
  };
  // One command line (blank and comment lines give nothing).
  Outcome execute(std::string_view line);
  // The event lines since the last call (the first call only notes where the events are now).
  Outcome poll_events();

 private:
  Outcome ask(const nlohmann::json& request, std::chrono::milliseconds timeout, nlohmann::json& answer);
  std::string answer_of(std::uint32_t seq, const canopen::ascii::Request& r, const nlohmann::json& a,
                        bool& error) const;

  Ask ask_;
  std::string version_;
  std::chrono::milliseconds answer_timeout_;
  canopen::ascii::Defaults defaults_;
  std::map<std::uint16_t, std::uint32_t> sdo_timeout_ms_;  // per network
  std::uint32_t next_seq_ = 1;
  std::optional<std::uint64_t> last_event_;
};

int run_ctl(const CtlOptions& options);

}  // namespace oegw::cli
