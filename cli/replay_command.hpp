// `oegw replay` and `oegw record keep` (docs/guides/black-box.md).
#pragma once

#include <string>

#include "cli/status_command.hpp"

namespace oegw::cli {

struct ReplayCommandOptions {
  std::string recording;  // a folder, a segment file, or a plain candump log
  std::string config;     // the mapping file
  std::string from, to;   // "12.5" (seconds from the recording's first line) or "14:03[:12[.5]]" (local time)
  std::string fe, subdevice;
  bool frames = false, logs = false, quiet = false;
  bool fresh = false;  // re-run every recording on a fresh gateway, nothing compared
  std::string plot;    // FILE.html
};

// The replay's exit codes: 0 the same frames and decisions (or a window shown as recorded, or a
// fresh replay printed), 1 a divergence or a refused mapping file, 2 an unreadable recording or
// plot file, 64 usage (--from/--to unreadable).
int run_replay(const ReplayCommandOptions& options);

// Asks the running gateway to keep its recording's window; 0 with the folder printed, 1 when it
// could not (recording off, a link refused), 3/4/5 as `oegw status`.
int run_record_keep(const StatusOptions& options);

}  // namespace oegw::cli
