// `oegw signals [DRIVER]`: every driver's signals and options, read from the drivers themselves
// (their signals() and their option tables, subdevices/driver_options.hpp), so that the mapping
// file's author learns them before writing it, not from `oegw check`'s errors.
// docs/reference/drivers.md carries the --markdown output of all drivers between marker comments;
// a test keeps the two equal (scripts/signals_readme.sh).
#pragma once

#include <string>
#include <vector>

#include "subdevices/driver_options.hpp"

namespace oegw::cli {

struct SignalsOptions {
  std::string driver;                // empty: every driver
  std::vector<std::string> options;  // "key=value": the driver's options, as in the mapping file
  std::string eds;                   // cia401: the EDS whose signals to list (= option eds)
  bool markdown = false;             // Markdown tables (docs/reference/drivers.md) instead of text
};

// 0 listed; 1 the driver refuses the options (an EDS it cannot read, a value out of range);
// 64 an unknown driver (the list of known ones printed), options without a driver.
int run_signals(const SignalsOptions& options);

// The listing itself (what run_signals prints on success); `error` set and "" on a refusal.
[[nodiscard]] std::string signals_listing(const SignalsOptions& options, std::string& error);

}  // namespace oegw::cli
