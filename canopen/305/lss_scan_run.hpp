// What the master's aggregate LSS scans share (LssFastscan, LssSlowscan: many LSS requests in a
// row on one LssMaster, ending in one address): their result, one scan at a time, its callback
// called exactly once, and the master's callbacks of a scan that has ended ignored.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "canopen/305/lss.hpp"
#include "canopen/305/lss_master.hpp"

namespace oegw::canopen {

struct LssScanResult {
  enum class Outcome : std::uint8_t {
    Found,      // `address` read; that slave is in LSS configuration mode
    NoAnswer,   // nobody answered the first step (no slave the scan looks for)
    Lost,       // a slave answered the first step but was lost on the way
    Cancelled,  // cancel() was called
  };
  Outcome outcome = Outcome::NoAnswer;
  std::optional<lss::Address> address;
  std::string note;  // why no address, in words
};

class LssScanRun {
 public:
  using Outcome = LssScanResult::Outcome;
  using Result = LssScanResult;
  using Callback = std::function<void(const Result&)>;

  LssScanRun(const LssScanRun&) = delete;
  LssScanRun& operator=(const LssScanRun&) = delete;

  // Ends a running scan: `done` gets Cancelled with `why`; the step on the wire (if any) ends
  // without effect, no further step is sent.
  void cancel(const std::string& why) {
    if (!running()) return;
    ++generation_;
    finish({Outcome::Cancelled, std::nullopt, why});
  }
  [[nodiscard]] bool running() const { return static_cast<bool>(done_); }

 protected:
  explicit LssScanRun(LssMaster& master) : master_(master) {}
  ~LssScanRun() = default;
  // A new scan: one still running is cancelled (`why`) first.
  void begin(Callback done, const char* why) {
    if (running()) cancel(why);
    ++generation_;
    done_ = std::move(done);
  }
  void finish(Result r) {
    Callback cb = std::move(done_);
    done_ = nullptr;
    if (cb) cb(r);
  }
  // The LssMaster callback of a step of this scan; ignored once the scan has ended.
  LssMaster::Callback guard(std::function<void(const LssMaster::Result&)> f) {
    return [this, gen = generation_, f = std::move(f)](const LssMaster::Result& r) {
      if (gen != generation_ || !done_) return;
      f(r);
    };
  }

  LssMaster& master_;

 private:
  Callback done_;
  std::uint64_t generation_ = 0;
};

}  // namespace oegw::canopen
