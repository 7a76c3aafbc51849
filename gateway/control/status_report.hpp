// The answer to the control socket's `status` command (docs/reference/control-protocol.md#status):
// what the running gateway sees, built only from the Gateway's public API, so that a test drives
// a Gateway on the virtual bus and reads the same report `oegw status` prints.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "canopen/io/can_transport.hpp"
#include "canopen/types.hpp"
#include "gateway/gateway.hpp"
#include "gateway/publishing.hpp"
#include "mapping/config.hpp"

namespace oegw::gateway::control {

struct StatusContext {
  canopen::TimePoint now{};      // the gateway's clock now (ages are counted from it)
  canopen::TimePoint started{};  // when the gateway started
  // The two interfaces' counters (frames, and the frames the kernel dropped before the gateway
  // read them: SO_RXQ_OVFL), when the caller has the transports; absent: no "bus" object.
  const canopen::io::TransportCounters* upstream_bus = nullptr;
  const canopen::io::TransportCounters* downstream_bus = nullptr;
};

// The `status` object: upstream, downstream, subdevices, functional_elements, commands
// (docs/reference/control-protocol.md#status lists every field). `config` is the mapping file the
// gateway runs.
[[nodiscard]] nlohmann::json status_report(const Gateway& gw, const mapping::Config& config, const StatusContext& at);

// The `publishing` array of `oegw run`'s status (docs/reference/control-protocol.md#status): each
// transport the mapping file enables, up, or down with why and when it is tried again; empty with
// publishing off.
[[nodiscard]] nlohmann::json publishing_status(const std::vector<TransportState>& transports);

// A sub-device's state in one word: "operational", "faulty" (operational, but the fault
// policy holds its inputs), "booting" (boot-up awaited, configuring, starting), "missing",
// "refused", "idle".
[[nodiscard]] std::string subdevice_summary(subdevices::NodeState state, bool faulty);

}  // namespace oegw::gateway::control
