#include "programs/device_command.hpp"

#include <cstdint>
#include <memory>
#include <string>

#include "cli/app.hpp"
#include "programs/core_demo.hpp"

namespace oegw::programs {

void register_device(CLI::App& app) {
  struct Options {
    DeviceOptions device;
    int node_id = 0x20;
    bool no_motion = false;
    std::string store;
  };
  auto o = std::make_shared<Options>();
  auto* cmd = app.add_subcommand("device", "Run the protocol core's demo device on a SocketCAN interface")
                  ->group(cli::kToolsGroup);
  cmd->add_option("-i,--interface", o->device.interface, "SocketCAN interface")->required();
  cmd->add_option("-n,--node-id", o->node_id, "CANopen node-ID 1..127 (0x.. accepted)")->check(CLI::Range(1, 127));
  cmd->add_option("--heartbeat-ms", o->device.heartbeat_ms, "Producer heartbeat time (1017h default)");
  cmd->add_option("--store", o->store, "Parameter file for 1010h/1011h and LSS store");
  cmd->add_flag("--no-motion", o->no_motion, "Keep the inputs still (for scripted peers)");
  cmd->callback([o] {
    o->device.node_id = canopen::NodeId{static_cast<std::uint8_t>(o->node_id)};
    o->device.store_path = o->store;
    o->device.motion = !o->no_motion;
    cli::finish(run_device(o->device));
  });
}

}  // namespace oegw::programs
