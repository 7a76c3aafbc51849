#include "gateway/record/recording_service.hpp"

#include <spdlog/spdlog.h>

#include <fmt/format.h>

#include "canopen/305/lss_store.hpp"
#include "canopen/state.hpp"

namespace oegw::gateway::record {

using nlohmann::json;

RecorderSettings recorder_settings(const mapping::Config& c, const std::string& file) {
  RecorderSettings s;
  s.dir = c.record.dir;
  s.max_bytes = static_cast<std::uint64_t>(c.record.max_mib) << 20;
  s.span = std::chrono::seconds(c.record.span_s);
  s.segments = c.record.segments;
  s.queue_bytes = static_cast<std::size_t>(c.record.queue_kib) << 10;
  s.up_iface = c.upstream.interface;
  s.down_iface = c.downstream.interface;
  s.states = true;  // give_states()
  // What the replay needs beside the lines: the options oegw run gives the gateway.
  s.header = {"meta mapping " + file,
              fmt::format("meta gateway sdo_bus_share={}", GatewayOptions::kDefaultSdoBusShare)};
  s.run_files = {{"mapping.yaml", file},
                 {"store", c.upstream.store},
                 {"store.lss", canopen::lss_store_path(c.upstream.store)}};
  return s;
}

RecordingService::RecordingService(canopen::io::EventLoop& loop, const mapping::Config& config, const std::string& file)
    : loop_(loop), config_(config.record) {
  if (!config.record.enabled) return;
  try {
    recorder_ = std::make_unique<Recorder>(recorder_settings(config, file));
  } catch (const RecordError& e) {
    // CAN first: the gateway runs without its recording, and says so.
    error_ = e.what();
    spdlog::error("{}: record.dir: {}; the gateway runs without recording", file, e.what());
    return;
  }
  tap_ = std::make_unique<GatewayRecorder>(*recorder_);
  watch_ = loop_.watch(recorder_->event_fd(), canopen::io::events::kReadable,
                       [this](std::uint32_t) { recorder_->dispatch(); });
  spdlog::info("record: {} (at most {} MiB, {} s, run {})", config.record.dir, config.record.max_mib,
               config.record.span_s, recorder_->status().run);
}

RecordingService::~RecordingService() {
  if (state_timer_ != 0) loop_.cancel(state_timer_);
  if (watch_ != 0) loop_.unwatch(watch_);
  tap_.reset();
  recorder_.reset();  // writes what is queued and flushes
}

void StateGiver::offer(const Gateway* gw, canopen::TimePoint now) {
  if (!recorder_.segment_due()) {
    busy_since_.reset();
    return;
  }
  if (gw == nullptr) return;
  const auto wait = kWait / std::chrono::seconds(1);
  const auto no_room = [&] {
    return fmt::format("no room for {} s in the recorder's queue for the state's {} bytes (record.queue_kib)", wait,
                       last_bytes_);
  };
  std::string why;
  try {
    if (const std::string busy = gw->busy(); !busy.empty()) {
      why = fmt::format("the gateway was busy for {} s: {}", wait, busy);
    } else if (recorder_.room() < last_bytes_) {
      // A state the queue has no room for (the last one's size) is not taken: the export
      // would cost the loop for nothing.
      why = no_room();
    } else {
      // The export costs the loop once a segment (record.span_s / record.segments, 60 s by
      // default): docs/reference/limits.md#can-first-what-the-event-loop-does-beside-the-buses.
      canopen::StateWriter w;
      gw->export_state(w);
      last_bytes_ = w.text().size();
      if (recorder_.state(now, w.text())) {
        // The recorder's FE lines begin anew with the segment (the replay does so at a state).
        tap_.segment_started();
        busy_since_.reset();
        return;
      }
      why = no_room();
    }
  } catch (const std::exception& e) {
    why = std::string("the state could not be taken: ") + e.what();
    busy_since_ = now - kWait;  // no use waiting
  }
  if (!busy_since_) busy_since_ = now;
  if (now - *busy_since_ < kWait) return;
  (void)recorder_.no_state(now, why);
  busy_since_.reset();
}

void RecordingService::give_states(std::function<const Gateway*()> current) {
  if (!recorder_ || !recorder_->settings().states || state_timer_ != 0) return;
  states_.emplace(*recorder_, *tap_);
  state_timer_ = loop_.call_every(loop_.now() + StateGiver::kPoll, StateGiver::kPoll,
                                  [this, current = std::move(current)] { states_->offer(current(), loop_.now()); });
}

void RecordingService::reloading(canopen::TimePoint now, const std::string& file) {
  if (tap_) tap_->note(now, "reload " + file);
}

std::string RecordingService::off_reason() const {
  return error_.empty() ? "recording is off (record.enabled in the mapping file)" : "recording is off: " + error_;
}

void RecordingService::keep(Done done) {
  if (!recorder_) {
    done({}, 0, off_reason());
    return;
  }
  recorder_->keep([done = std::move(done)](std::optional<KeptWindow> k, std::string error) {
    if (k) done(k->path.string(), k->segments, {});
    else done({}, 0, error);
  });
}

void RecordingService::keep_logged(const std::string& why) {
  keep([why](const std::string& folder, std::size_t segments, const std::string& error) {
    if (error.empty()) spdlog::info("record: {}: the window kept in {} ({} segments)", why, folder, segments);
    else spdlog::warn("record: {}: nothing kept: {}", why, error);
  });
}

json RecordingService::status() const {
  json out{{"enabled", config_.enabled}, {"dir", config_.dir}};
  if (!recorder_) {
    out["recording"] = false;
    out["last_error"] = error_.empty() ? json(nullptr) : json(error_);
    return out;
  }
  const RecorderStatus s = recorder_->status();
  json kept = json::array();
  for (const auto& k : s.kept)
    kept.push_back(json{{"path", k.path.string()}, {"segments", k.segments}, {"bytes", k.bytes}});
  out.update(json{{"recording", true},
                  {"run", s.run},
                  {"segments", s.segments},
                  {"bytes", s.bytes},
                  {"max_bytes", static_cast<std::uint64_t>(config_.max_mib) << 20},
                  {"span_ms", s.span_us / 1000},
                  {"max_span_ms", static_cast<std::uint64_t>(config_.span_s) * 1000},
                  {"frames", s.frames},
                  {"events", s.events},
                  {"dropped_frames", s.dropped_frames},
                  {"dropped_events", s.dropped_events},
                  {"lost_frames", s.lost_frames},
                  {"lost_events", s.lost_events},
                  {"queued_bytes", s.queued_bytes},
                  {"last_error", s.last_error.empty() ? json(nullptr) : json(s.last_error)},
                  {"kept", kept}});
  return out;
}

std::string record_status_line(const json& r) {
  if (!r.value("enabled", false)) return "recording: off (record.enabled in the mapping file)\n";
  const std::string dir = r.value("dir", "");
  const auto error = r.contains("last_error") && r["last_error"].is_string() ? r["last_error"].get<std::string>() : "";
  if (!r.value("recording", false)) return fmt::format("recording: NOT recording, {}: {}\n", dir, error);
  const auto mib = [](std::uint64_t b) { return fmt::format("{:.1f} MiB", static_cast<double>(b) / (1 << 20)); };
  std::string out = fmt::format(
      "recording: on, {}, run {}, {} segments, {} of {}, {:.0f} s of {} s; frames {}, dropped {} (queue full), lost {} "
      "(disk)\n",
      dir, r.value("run", ""), r.value("segments", 0), mib(r.value("bytes", 0ull)), mib(r.value("max_bytes", 0ull)),
      r.value("span_ms", 0ll) / 1000.0, r.value("max_span_ms", 0ull) / 1000, r.value("frames", 0ull),
      r.value("dropped_frames", 0ull) + r.value("dropped_events", 0ull),
      r.value("lost_frames", 0ull) + r.value("lost_events", 0ull));
  if (!error.empty()) out += "  last error: " + error + "\n";
  if (r.contains("kept") && r["kept"].is_array())
    for (const auto& k : r["kept"])
      out += fmt::format("  kept: {} ({} segments, {})\n", k.value("path", ""), k.value("segments", 0),
                         mib(k.value("bytes", 0ull)));
  return out;
}

}  // namespace oegw::gateway::record
