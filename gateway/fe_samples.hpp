// What the gateway publishes about each functional element (FE) to the machine application, and
// the commands it takes back — independent of the transport (DDS, LCM). The upstream CANopen
// side uses the CiA 852 dictionary instead; these are the same values, per FE instance.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <variant>
#include <vector>

namespace oegw::gateway {

// Mirrors subdevices::SignalStatus: the worst status of the signals feeding the FE.
enum class FeStatus : std::uint8_t { Valid = 0, Error = 1, NotAvailable = 2, Stale = 3, Offline = 4 };

struct SampleHeader {
  std::uint8_t instance = 1;  // 1-based FE instance (CiA 852 §5.3)
  FeStatus status = FeStatus::Offline;
  std::int64_t timestamp_us = 0;  // source time: reception of the frame that carried the value (CLOCK_MONOTONIC µs)
  std::uint32_t seq = 0;          // per FE instance, +1 per published sample
};

struct JoystickSample {
  SampleHeader h;
  std::int16_t x = 0, y = 0, z = 0;  // CiA 401 INTEGER16 full scale
  std::uint8_t buttons = 0;          // bit i = button i+1
  std::uint8_t memory = 0;           // bits m-x, m-y, m-z
};
struct PedalSample {
  SampleHeader h;
  std::int16_t position = 0;
  std::uint8_t memory = 0;
};
struct WheelSample {
  SampleHeader h;
  std::int16_t position = 0;
};
struct EncoderSample {
  SampleHeader h;
  std::uint32_t position = 0;  // 6120h UNSIGNED32; DDS `long` and LCM int32_t carry its 32 bits
};
struct ButtonClusterSample {
  SampleHeader h;
  std::uint64_t switches = 0;  // bit i = switch i+1 (64 switches)
};

// One EMCY as received (CiA 301 §7.2.7.3: error code, the sender's 1001h, 5 manufacturer bytes)
// and when (the gateway's clock, µs, as the samples' timestamps). All zeros: none yet.
struct EmcySample {
  std::uint16_t code = 0;
  std::uint8_t error_register = 0;
  std::array<std::uint8_t, 5> msef{};
  std::int64_t timestamp_us = 0;
};
// What a sub-device said about itself at its last boot (subdevices::NodeDiagnostics): 1018h:01..04,
// 1008h/1009h/100Ah (at most 32 characters each) and 1001h. `present` says which were read:
// bits 0..3 = 1018h:01..04, bits 4..6 = 1008h/1009h/100Ah, bit 7 = 1001h; what is not present
// is 0 / "".
struct SubdeviceIdentity {
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint32_t revision = 0;
  std::uint32_t serial = 0;
  std::string device_name;
  std::string hardware_version;
  std::string software_version;
  std::uint8_t error_register = 0;
  std::uint8_t present = 0;
};
struct SubdeviceState {
  std::string name;
  std::uint8_t node_id = 0;
  std::string state;             // "operational", "missing", ...
  EmcySample last_emcy;          // the last EMCY it sent
  std::uint64_t emcy_count = 0;  // EMCYs it sent since the gateway started
  SubdeviceIdentity identity;    // read at its last boot
};
// EMCYs of another upstream node the gateway consumes (1028h).
struct UpstreamEmcy {
  std::uint8_t node_id = 0;
  EmcySample last;
  std::uint64_t count = 0;
};
struct GatewayStatus {
  std::int64_t timestamp_us = 0;
  std::uint32_t seq = 0;
  std::string upstream_state;  // upstream NMT state: "operational", ...
  std::vector<SubdeviceState> subdevices;
  std::vector<std::uint16_t> active_emcys;   // codes the gateway has active upstream
  std::uint64_t refused_commands = 0;        // Gateway::refused_commands()
  std::vector<UpstreamEmcy> upstream_emcys;  // per upstream node that sent one, by node-ID
};

// Commands in, from the machine application.
struct IndicatorCommand {
  std::uint8_t instance = 1;
  std::uint64_t indicators = 0;  // bit i = indicator i+1
};
struct DisplayCommand {
  std::uint8_t instance = 1;
  std::array<std::int16_t, 12> parameters{};
};

// Any one FE's sample: what the publishing schedule and the change coalescing keep per FE.
using FeSample = std::variant<JoystickSample, PedalSample, WheelSample, EncoderSample, ButtonClusterSample>;

// One transport (DDS or LCM). Publishing never blocks the gateway's loop for long; a transport
// that cannot keep up drops samples (keep-last) rather than queueing without bound.
class Publisher {
 public:
  virtual ~Publisher() = default;
  virtual void publish(const JoystickSample&) = 0;
  virtual void publish(const PedalSample&) = 0;
  virtual void publish(const WheelSample&) = 0;
  virtual void publish(const EncoderSample&) = 0;
  virtual void publish(const ButtonClusterSample&) = 0;
  virtual void publish(const GatewayStatus&) = 0;

  // Commands received are handed to these from poll() (in the gateway's loop).
  std::function<void(const IndicatorCommand&)> on_indicator_command;
  std::function<void(const DisplayCommand&)> on_display_command;
  // A descriptor the loop watches (or -1: call poll() periodically), and the work when readable.
  [[nodiscard]] virtual int fd() const { return -1; }
  virtual void poll() {}
};

// A Publisher that hands every sample, whatever its type, to Derived::forward(sample): a fan-out
// to several transports, a transport that may be down (gateway/publisher_link.hpp).
template <class Derived>
class ForwardingPublisher : public Publisher {
 public:
  void publish(const JoystickSample& s) override { self().forward(s); }
  void publish(const PedalSample& s) override { self().forward(s); }
  void publish(const WheelSample& s) override { self().forward(s); }
  void publish(const EncoderSample& s) override { self().forward(s); }
  void publish(const ButtonClusterSample& s) override { self().forward(s); }
  void publish(const GatewayStatus& s) override { self().forward(s); }

 private:
  Derived& self() { return static_cast<Derived&>(*this); }
};

}  // namespace oegw::gateway
