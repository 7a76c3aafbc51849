// The FE samples on LCM (liblcm C API, types from publish/lcm/*.lcm), commands back.
//
// Channels (prefix configurable, default "OEGW_"), one per FE instance n:
//   OEGW_JOYSTICK_n  OEGW_PEDAL_n  OEGW_WHEEL_n  OEGW_ENCODER_n  OEGW_BUTTONS_n   FE samples out
//   OEGW_STATUS                                                                gateway status out
//   OEGW_INDICATORS_n  OEGW_DISPLAY_n                                           commands in
// LCM has no QoS: every sample is one UDP datagram, best effort; the seq numbers show loss.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "gateway/fe_samples.hpp"
#include "publish/dds_publisher.hpp"  // PublishConfigError

namespace oegw::publish {

struct LcmSettings {
  // publish.lcm.url. ttl=0: multicast that never leaves the host (tests, demo).
  std::string url = "udpm://224.0.0.1:7667?ttl=0";
  std::string channel_prefix = "OEGW_";  // publish.lcm.channel_prefix
};

class LcmPublisher final : public gateway::Publisher {
 public:
  // Throws PublishConfigError for a URL or prefix that cannot work, PublishUnavailable when the
  // machine cannot carry it now (no route for the group, liblcm's self-test failed, a tcpq://
  // server not listening).
  explicit LcmPublisher(const LcmSettings& settings);
  ~LcmPublisher() override;
  LcmPublisher(const LcmPublisher&) = delete;
  LcmPublisher& operator=(const LcmPublisher&) = delete;

  void publish(const gateway::JoystickSample&) override;
  void publish(const gateway::PedalSample&) override;
  void publish(const gateway::WheelSample&) override;
  void publish(const gateway::EncoderSample&) override;
  void publish(const gateway::ButtonClusterSample&) override;
  void publish(const gateway::GatewayStatus&) override;

  // lcm_get_fileno(); poll() handles whatever is readable without blocking.
  [[nodiscard]] int fd() const override;
  void poll() override;

  [[nodiscard]] const std::string& prefix() const { return prefix_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string prefix_;
};

}  // namespace oegw::publish
