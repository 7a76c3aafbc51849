// A reload of the mapping file (SIGHUP to `oegw run`, `systemctl reload oegw`;
// docs/guides/install.md#reloading-the-mapping-file): what it may change, and the step that applies
// it. Sans I/O: a Gateway in, a Gateway out, frames on the buses the gateways were given.
//
// Rules (the decisions are docs/guides/install.md#reloading-the-mapping-file's):
//  * The upstream device goes on. Its NMT state, heartbeat, node-ID, the PDO and other settings
//    the host wrote, its active EMCYs: a reload changes none of them, so the host sees no boot-up
//    and its heartbeat consumer no gap. Hence a file that would change the device — its node-ID,
//    bit rate, interface, identity, heartbeat, store, extra SDO server COB-IDs, the FE set (the
//    dictionary, CiA 852 clause 9, and 1000h, Table 8) or whether 3000h exists — is refused as
//    a whole (reload_refusals: each such setting at its place, "needs a restart"): a restart is
//    the honest way to show the host another device. So are the parts of the program a reload
//    does not rebuild: the downstream interface and bit rate, publishing (publish.*), the control
//    socket (control.*). Nothing of a refused file is applied.
//  * Everything else is applied as at a start: a new Gateway (sub-devices, FE bindings,
//    translators, fault values, output sources and watchdogs, downstream SDO time-out, SYNC,
//    EMCY forwarding, network IDs, SDO server bindings) around the same upstream device.
//    In between (Gateway::hand_over, Gateway::resume): every output at its CiA 401 error value
//    (sent to each sub-device while it is still operational), every input at its fault value,
//    EMCY 6300h held until each sub-device of the new file is operational or faulty; every
//    sub-device is booted again (NMT reset communication: the simplest rule that never keeps a
//    node configured by another file), one the file no longer has is sent NMT enter
//    pre-operational. A fault clears only on evidence across a reload too.
//  * What is not kept: the old gateway's counters (EMCYs, reboots, refused commands), a host's
//    remote SDO transfer in flight (dropped: the host's SDO time-out ends it) and an SDO network
//    indication's redirect (the channels serve the gateway's own dictionary again, or their
//    binding in the new file).
#pragma once

#include <memory>
#include <vector>

#include "gateway/gateway.hpp"
#include "mapping/config.hpp"

namespace oegw::gateway {

// The settings of `next` a reload cannot apply over `running`, each at its place in `next` (or
// at its section, or the file's first line when `next` does not write it): empty when it may.
[[nodiscard]] std::vector<mapping::Diagnostic> reload_refusals(const mapping::Config& running,
                                                               const mapping::Config& next);

// The drivers of `next`, one per sub-device in its order, built before the hand-over, their
// frames going nowhere until the new gateway binds them (reload_gateway). A file a driver reads at
// its construction (a cia401 node's EDS) is read here, so by the thread that reads a reload's file
// beside the buses (gateway/programs.cpp), not in the event loop; one that vanished or changed
// since `next` was loaded refuses the reload here (at the sub-device's place), while the running
// gateway is still untouched.
struct ReloadDrivers {
  std::vector<std::unique_ptr<subdevices::Driver>> drivers;  // empty when any is refused
  std::vector<mapping::Diagnostic> refusals;                 // empty when every driver builds
};
[[nodiscard]] ReloadDrivers build_reload_drivers(const mapping::Config& next);

// The reload step, for a `next` reload_refusals() accepts: `running` hands over and is
// destroyed; returned is the gateway of `next` around the same upstream device, resumed at `now`
// (Gateway::resume). Its on_log is `running`'s. `downstream` is the sink its sub-devices' frames
// go to (the same bus). `drivers`: build_reload_drivers(next)'s, or none (then built here).
[[nodiscard]] std::unique_ptr<Gateway> reload_gateway(std::unique_ptr<Gateway> running, const mapping::Config& next,
                                                      canopen::FrameSink downstream, GatewayOptions options,
                                                      canopen::TimePoint now,
                                                      std::vector<std::unique_ptr<subdevices::Driver>> drivers = {});

}  // namespace oegw::gateway
