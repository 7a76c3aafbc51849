// The black box in `oegw run` (docs/guides/black-box.md): the mapping file's `record`
// section made into a Recorder (its writer thread) and a GatewayRecorder on the running Gateway;
// the window kept on request (the control socket's `record_keep`, SIGUSR1); its state for
// `oegw status`. A folder that cannot be used costs the recording, never the buses: the gateway
// runs without it and `oegw status` says why.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "canopen/io/event_loop.hpp"
#include "gateway/gateway.hpp"
#include "gateway/record/gateway_recorder.hpp"
#include "gateway/record/recorder.hpp"
#include "mapping/config.hpp"

namespace oegw::gateway::record {

// Gives the recorder the gateway's state when a segment is due (Recorder::segment_due): at the
// gateway's first quiet moment (Gateway::busy() "") with room in the recorder's queue, taken
// there, between two of its calls; after kWait without one, `state none (for 2 s: WHY)`. Looked
// at on the loop every kPoll. Only a state begins the FE lines anew (GatewayRecorder), and
// only a state's line makes the replay do so.
class StateGiver {
 public:
  static constexpr canopen::Duration kPoll = std::chrono::milliseconds(100);
  static constexpr canopen::Duration kWait = std::chrono::seconds(2);
  StateGiver(Recorder& recorder, GatewayRecorder& tap) : recorder_(recorder), tap_(tap) {}
  // `gw`: the gateway running now (nullptr: none).
  void offer(const Gateway* gw, canopen::TimePoint now);

 private:
  Recorder& recorder_;
  GatewayRecorder& tap_;
  std::optional<canopen::TimePoint> busy_since_;  // a segment due, no state taken since
  std::size_t last_bytes_ = 0;                    // the last state's size
};

// The Recorder's settings for a mapping file's `record` section (`file`: the mapping file, copied
// into the recording with the upstream store).
[[nodiscard]] RecorderSettings recorder_settings(const mapping::Config& config, const std::string& file);

class RecordingService {
 public:
  // Records when config.record.enabled: give tap() to each gateway (GatewayOptions::tap) from
  // its construction on. `loop` outlives it; it outlives the gateways it taps.
  RecordingService(canopen::io::EventLoop& loop, const mapping::Config& config, const std::string& file);
  ~RecordingService();
  RecordingService(const RecordingService&) = delete;
  RecordingService& operator=(const RecordingService&) = delete;

  [[nodiscard]] bool recording() const { return recorder_ != nullptr; }
  // The gateways' tap; nullptr when not recording.
  [[nodiscard]] GatewayTap* tap() { return tap_.get(); }
  // The gateway whose state begins each segment (`current`: the one running now, nullptr
  // while there is none): StateGiver on a timer of the loop.
  void give_states(std::function<const Gateway*()> current);
  // The mapping file reloaded (SIGHUP): noted in the recording, where a replay stops comparing.
  void reloading(canopen::TimePoint now, const std::string& file);
  // Why it does not record: "recording is off (record.enabled …)", or the folder's refusal.
  [[nodiscard]] std::string off_reason() const;
  // Keeps the window now; `done(kept folder or empty, error)` on the loop once the links exist.
  using Done = std::function<void(const std::string& folder, std::size_t segments, const std::string& error)>;
  void keep(Done done);
  // The `record` object of `oegw status`
  // (docs/reference/control-protocol.md#record_keep-and-the-record-object-of-status).
  [[nodiscard]] nlohmann::json status() const;
  // One line for the log at a keep asked by a signal.
  void keep_logged(const std::string& why);

 private:
  canopen::io::EventLoop& loop_;
  mapping::RecordConfig config_;  // as at the start: a reload does not change the recording
  std::string error_;             // why it does not record (the folder refused at start)
  std::unique_ptr<Recorder> recorder_;
  std::unique_ptr<GatewayRecorder> tap_;
  canopen::io::EventLoop::WatchId watch_ = 0;
  std::optional<StateGiver> states_;
  canopen::io::EventLoop::TimerId state_timer_ = 0;
};

// `oegw status`'s line for the `record` object: "recording: on, /var/lib/oegw/record, 12 segments,
// 3.2 MiB, 5 min 12 s; dropped 0, lost 0; kept 1 window (…)"; "recording: off (record.enabled)".
[[nodiscard]] std::string record_status_line(const nlohmann::json& record);

}  // namespace oegw::gateway::record
