// LSS master (CiA 305), sans I/O: requests are queued and run one at a time; each one that
// expects an answer on 7E4h completes with that answer or with a timeout.
//
// Every request method takes `now` (the moment it is issued, which starts its timeout if the
// queue is idle) and a completion callback. Requests that have no answer in CiA 305 (switch
// state global, activate bit timing) complete with Status::Ok as soon as they are sent.
// "Identify" requests complete with Ok on the first answer and with NoAnswer at the timeout
// (no slave matched): for them silence is a result, not an error.
#pragma once

#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <vector>

#include "canopen/305/lss.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

class LssMaster {
 public:
  enum class Status : std::uint8_t {
    Ok,        // answered with error code 0 (or no answer expected)
    Refused,   // answered with a non-zero error code (see Result::error)
    Timeout,   // no answer in time
    NoAnswer,  // identify: no slave matched
  };
  struct Result {
    Status status = Status::Ok;
    std::uint8_t error = 0;           // error code of 11h/13h/17h answers
    std::uint8_t specific_error = 0;  // implementation-specific error (error code FFh)
    std::uint32_t value = 0;          // inquire answers (node-ID in the low byte for 5Eh)
  };
  using Callback = std::function<void(const Result&)>;

  enum class Inquiry : std::uint8_t { Vendor = 0x5A, Product = 0x5B, Revision = 0x5C, Serial = 0x5D, NodeId = 0x5E };

  explicit LssMaster(FrameSink sink, Duration timeout = std::chrono::milliseconds(100));

  void switch_state_global(lss::Mode mode, TimePoint now, Callback cb = {});
  void switch_state_selective(const lss::Address& address, TimePoint now, Callback cb = {});
  void configure_node_id(NodeId id, TimePoint now, Callback cb = {});
  void configure_bit_timing(std::uint8_t table_index, TimePoint now, Callback cb = {});
  void activate_bit_timing(std::uint16_t switch_delay_ms, TimePoint now, Callback cb = {});
  void store_configuration(TimePoint now, Callback cb = {});
  void inquire(Inquiry what, TimePoint now, Callback cb = {});
  // Every slave in the range answers (4Fh). `whole_window` (LSS slowscan, lss_slowscan.hpp):
  // like a fastscan step, the request lasts the whole time-out, so that a second slave's late
  // answer is not taken for the next request's; else it ends at the first answer.
  void identify_remote_slave(const lss::AddressRange& range, TimePoint now, Callback cb = {},
                             std::optional<Duration> whole_window = std::nullopt);
  void identify_non_configured(TimePoint now, Callback cb = {});
  // One step of LSS fastscan (CiA 305 §8.4.4, cs 51h): every slave without node-ID whose address
  // matches answers (4Fh), so the step always lasts the whole timeout and then completes Ok if
  // any answer came, NoAnswer if none: a late second answer must not be taken for the next
  // step's. `bit_checked` 0..31, or lss::cs::kFastscanReset.
  // `timeout`: this step's own (default: the master's).
  void fastscan(std::uint32_t id_number, std::uint8_t bit_checked, std::uint8_t sub, std::uint8_t next, TimePoint now,
                Callback cb = {}, std::optional<Duration> timeout = std::nullopt);

  // True for a frame on 7E4h (answers that match no pending request are dropped).
  bool on_frame(const CanFrame& frame, TimePoint now);
  void advance(TimePoint now);
  [[nodiscard]] std::optional<TimePoint> next_deadline() const;

  // The latest time a request, frame or advance() gave (for callbacks that issue the next request).
  [[nodiscard]] TimePoint now() const { return now_; }

  [[nodiscard]] bool idle() const { return !active_ && queue_.empty(); }
  [[nodiscard]] Duration timeout() const { return timeout_; }
  [[nodiscard]] std::size_t pending() const { return queue_.size() + (active_ ? 1 : 0); }

 private:
  struct Request {
    std::vector<CanFrame> frames;
    std::uint8_t answer = 0;  // command specifier of the expected answer; 0 = none
    bool has_error_code = false;
    bool silence_is_answer = false;
    Callback cb;
    bool whole_window = false;        // fastscan: collect answers until the timeout
    bool answered = false;            // whole_window: an answer came
    std::optional<Duration> timeout;  // this request's own (fastscan)
  };
  static CanFrame frame(std::uint8_t cs, std::uint32_t value = 0);
  void enqueue(Request r, TimePoint now);
  void pump(TimePoint now);
  void finish(const Result& result, TimePoint now);

  FrameSink sink_;
  Duration timeout_;
  std::deque<Request> queue_;
  std::optional<Request> active_;
  TimePoint deadline_{};
  TimePoint now_{};
};

}  // namespace oegw::canopen
