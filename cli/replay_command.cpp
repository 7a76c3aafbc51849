#include "cli/replay_command.hpp"

#include <cstdio>
#include <ctime>
#include <filesystem>
#include <iostream>

#include <fmt/format.h>

#include "gateway/control/control_protocol.hpp"
#include "gateway/programs.hpp"
#include "gateway/record/plot.hpp"
#include "gateway/record/replay.hpp"

namespace oegw::cli {

// The command line of the black box's reader and replay (gateway/record), which this file only calls.
using namespace gateway::record;

namespace {

// "12.5" / "+12.5" (seconds from the first line) or "14:03", "14:03:12", "14:03:12.25" (local
// time on the first line's day; the next day when earlier than the first line).
std::optional<std::int64_t> parse_when(const std::string& s, std::int64_t first_wall_us) {
  if (s.find(':') == std::string::npos) {
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (end == s.c_str() || *end != '\0') return std::nullopt;
    return first_wall_us + static_cast<std::int64_t>(v * 1e6);
  }
  int h = 0, m = 0;
  double sec = 0;
  const int n = std::sscanf(s.c_str(), "%d:%d:%lf", &h, &m, &sec);
  if (n < 2 || h < 0 || h > 23 || m < 0 || m > 59 || sec < 0 || sec >= 61) return std::nullopt;
  const std::time_t first = static_cast<std::time_t>(first_wall_us / 1000000);
  std::tm tm{};
  ::localtime_r(&first, &tm);
  tm.tm_hour = h;
  tm.tm_min = m;
  tm.tm_sec = 0;
  tm.tm_isdst = -1;
  std::int64_t at = static_cast<std::int64_t>(std::mktime(&tm)) * 1000000 + static_cast<std::int64_t>(sec * 1e6);
  if (at < first_wall_us - 12ll * 3600 * 1000000) at += 24ll * 3600 * 1000000;
  return at;
}

}  // namespace

int run_replay(const ReplayCommandOptions& o) {
  const std::string plot_kind = o.plot.empty() ? "" : std::filesystem::path(o.plot).extension().string();
  if (!o.plot.empty() && plot_kind != ".html" && plot_kind != ".svg") {
    std::fprintf(stderr, "oegw replay: --plot %s: expected FILE.html (a self-contained page) or FILE.svg (a picture)\n",
                 o.plot.c_str());
    return exit_code::kUsage;
  }
  auto loaded = mapping::load_config(o.config, gateway::driver_catalogue());
  if (!loaded.ok()) {
    std::fprintf(stderr, "%s\n%s: the mapping file is refused; nothing replayed\n", loaded.error_text().c_str(),
                 o.config.c_str());
    return exit_code::kBadFile;
  }
  std::string error;
  const auto runs = gateway::record::find_runs(o.recording, error);
  if (!runs) {
    std::fprintf(stderr, "oegw replay: %s\n", error.c_str());
    return exit_code::kCannotStart;
  }
  gateway::record::ReplayOptions ro;
  ro.timeline = o.quiet ? nullptr : &std::cout;
  ro.fresh = o.fresh;
  ro.frames = o.frames;
  ro.logs = o.logs;
  ro.fe = o.fe;
  ro.subdevice = o.subdevice;
  if (!o.from.empty() || !o.to.empty()) {
    // The first entry's time, the origin of "12.5"; the replay reads the segment itself.
    const std::int64_t first = SegmentReader(runs->front().segments.front()).first_wall_us().value_or(0);
    for (const auto& [text, out] : {std::pair{&o.from, &ro.from_us}, std::pair{&o.to, &ro.to_us}}) {
      if (text->empty()) continue;
      *out = parse_when(*text, first);
      if (!*out) {
        std::fprintf(stderr,
                     "oegw replay: '%s': expected seconds from the recording's start (12.5) or a time of day "
                     "(14:03:12)\n",
                     text->c_str());
        return exit_code::kUsage;
      }
    }
  }
  gateway::record::PlotData plot;
  if (!o.plot.empty()) ro.plot = &plot;
  std::vector<gateway::record::RunReport> reports;
  try {
    reports = gateway::record::replay(*runs, *loaded.config, ro);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "oegw replay: %s\n", e.what());
    return exit_code::kCannotStart;
  }
  std::cout.flush();
  bool diverged = false;
  for (const RunReport& r : reports) {
    for (const auto& n : r.notes) std::fprintf(stderr, "note: %s\n", n.c_str());
    if (r.mode != ReplayMode::Exact) {
      const bool shown = r.mode == ReplayMode::Recorded;
      std::fprintf(stderr, "run %s: %s: %llu inputs (%llu frames), %llu frames sent, %llu decisions; %s\n",
                   r.run.c_str(), shown ? "shown as recorded" : "replayed on a fresh gateway",
                   static_cast<unsigned long long>(r.inputs), static_cast<unsigned long long>(r.frames_in),
                   static_cast<unsigned long long>(r.frames_out), static_cast<unsigned long long>(r.decisions),
                   shown ? "not re-run (its start has left the ring, no state to begin in)" : "nothing compared");
      continue;
    }
    if (r.divergence) {
      diverged = true;
      std::fprintf(stderr, "run %s: DIVERGED at %s, after the input %s%s\n  recorded: %s\n  replayed: %s\n",
                   r.run.c_str(), r.divergence->when.c_str(), r.divergence->after.c_str(),
                   r.from_state.empty() ? "" : (" (replayed from the state at " + r.from_state + ")").c_str(),
                   r.divergence->recorded.c_str(), r.divergence->replayed.c_str());
      continue;
    }
    std::fprintf(stderr,
                 "run %s: exact replay%s, %llu inputs (%llu frames), %llu outputs and %llu segment states compared: "
                 "no divergence%s%s\n",
                 r.run.c_str(),
                 r.from_state.empty()
                     ? ""
                     : (" from the state at " + r.from_state + " (its start has left the ring)").c_str(),
                 static_cast<unsigned long long>(r.inputs), static_cast<unsigned long long>(r.frames_in),
                 static_cast<unsigned long long>(r.compared), static_cast<unsigned long long>(r.states),
                 r.stopped.empty() ? "" : "; compared up to ", r.stopped.c_str());
  }
  if (!o.plot.empty()) {
    const std::string title = "oegw replay " + o.recording + " (" + o.config + ")";
    if (!(plot_kind == ".svg" ? plot.write_svg(o.plot, title, error) : plot.write_html(o.plot, title, error))) {
      std::fprintf(stderr, "oegw replay: --plot: %s\n", error.c_str());
      return exit_code::kCannotStart;
    }
    std::fprintf(stderr, "plot: %s\n", o.plot.c_str());
  }
  return diverged ? exit_code::kBadFile : exit_code::kOk;
}

int run_record_keep(const StatusOptions& o) {
  bool ok = false;
  const std::string path = control_socket_of(o.socket, o.config, "oegw record keep", ok);
  if (!ok) return kStatusFailed;
  const auto timeout = std::chrono::milliseconds(static_cast<std::int64_t>(o.timeout_s * 1000.0));
  const AskResult r =
      ask_daemon(path,
                 gateway::control::json_line(
                     nlohmann::json{{"protocol", gateway::control::kControlProtocol}, {"command", "record_keep"}}),
                 timeout);
  if (r.status != AskStatus::Ok) {
    std::fprintf(stderr, "oegw record keep: %s\n", r.text.c_str());
    return ask_exit_code(r.status);
  }
  const auto answer = nlohmann::json::parse(r.text, nullptr, false);
  if (o.json) std::printf("%s\n", r.text.c_str());
  if (!answer.is_object() || !answer.value("ok", false)) {
    const std::string why = answer.is_object() && answer.contains("error") && answer["error"].is_object()
                                ? answer["error"].value("message", r.text)
                                : r.text;
    if (!o.json) std::fprintf(stderr, "oegw record keep: %s\n", why.c_str());
    return kStatusFailed;
  }
  if (!answer.contains("kept") || !answer["kept"].is_string()) {
    if (!o.json)
      std::fprintf(stderr, "oegw record keep: %s\n", answer.value("error", std::string("nothing kept")).c_str());
    return kStatusFailed;
  }
  if (!o.json)
    std::printf("kept: %s (%llu segments)\n", answer["kept"].get<std::string>().c_str(),
                static_cast<unsigned long long>(answer.value("segments", 0ull)));
  return kStatusOk;
}

}  // namespace oegw::cli
