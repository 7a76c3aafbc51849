// The FE samples on DDS (Cyclone DDS C API), commands back from DDS.
//
// Topics (type from publish/oegw.idl, prefix configurable, default "oegw/"):
//   oegw/joystick  oegw/pedal  oegw/wheel  oegw/encoder  oegw/buttons   FE samples, keyed by instance
//   oegw/status                                                       gateway status (transient-local)
//   oegw/indicators  oegw/display                                     commands in, keyed by instance
// QoS of the FE topics: reliable, keep-last 1 per instance, deadline = the publish period (a
// reader asking for a deadline >= the period is told when an instance stops arriving). The
// status topic: reliable, keep-last 1, transient-local (a late reader gets the last status). All
// in the configured partition.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "gateway/fe_samples.hpp"
#include "publish/dds_security.hpp"
#include "publish/publish_errors.hpp"

namespace oegw::publish {

struct DdsSettings {
  std::uint32_t domain = 0;        // publish.dds.domain
  std::string partition = "oegw";  // publish.dds.partition
  // publish.dds.network: "loopback" (tests, demo: nothing leaves the host), an interface name
  // (a deployment: the cab network), or "" (Cyclone's own configuration, CYCLONEDDS_URI).
  std::string network = "loopback";
  std::int64_t period_us = 100'000;  // the publish period; the FE topics' deadline
  std::string topic_prefix = "oegw/";
  // publish.dds.security: DDS Security for the participant (dds_security.hpp); needs a network
  // other than "" (the settings go into the domain's configuration).
  std::optional<DdsSecuritySettings> security;
};

// The Cyclone DDS configuration (XML) the publisher applies for `network`: loopback only (no
// multicast, unicast discovery to 127.0.0.1), or the named interface, with the <Security> of
// `security` when given. Empty for "".
std::string dds_config_xml(const std::string& network, const std::optional<DdsSecuritySettings>& security = {});

class DdsPublisher final : public gateway::Publisher {
 public:
  // Throws PublishConfigError for a setting Cyclone DDS refuses, PublishUnavailable when the
  // interface publish.dds.network names is not on this machine (yet).
  explicit DdsPublisher(const DdsSettings& settings);
  ~DdsPublisher() override;
  DdsPublisher(const DdsPublisher&) = delete;
  DdsPublisher& operator=(const DdsPublisher&) = delete;

  void publish(const gateway::JoystickSample&) override;
  void publish(const gateway::PedalSample&) override;
  void publish(const gateway::WheelSample&) override;
  void publish(const gateway::EncoderSample&) override;
  void publish(const gateway::ButtonClusterSample&) override;
  void publish(const gateway::GatewayStatus&) override;

  // Readable when a command arrived (an eventfd a Cyclone listener signals); poll() takes the
  // commands and calls on_indicator_command / on_display_command in the caller's thread.
  [[nodiscard]] int fd() const override;
  void poll() override;

  // Readers matched on the joystick topic (tests and the demo wait for a subscriber with it).
  [[nodiscard]] std::uint32_t joystick_readers() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace oegw::publish
