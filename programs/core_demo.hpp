// The protocol core's demo device and built-in host, used by `oegw core-demo` (on the virtual
// bus) and `oegw device` (on a SocketCAN interface): the protocol core alone, without the CiA 852
// device that `oegw demo` runs — a CiA 301 device with a small CiA 401-style I/O dictionary whose
// inputs move like a joystick being swept.
#pragma once

#include <filesystem>
#include <memory>

#include "canopen/node.hpp"

namespace oegw::programs {

using canopen::FrameSink;
using canopen::NodeId;
using canopen::TimePoint;

class DemoDevice {
 public:
  // 6000h:01..02 digital inputs, 6401h:01..02 analogue inputs (INTEGER16), 6200h:01 output byte,
  // TPDO1 = 6401h:01, 6401h:02, 6000h:01 (type 255, inhibit 10 ms, event timer 500 ms),
  // RPDO1 = 6200h:01 (type 255).
  DemoDevice(NodeId id, FrameSink sink, std::filesystem::path store_path, std::uint16_t heartbeat_ms);

  canopen::Node& node() { return *node_; }
  canopen::ObjectDictionary& od() { return od_; }
  // Moves the inputs to where a joystick swept with a 4 s period is at `now` (x = sine,
  // y = cosine, in CiA 401 INTEGER16 full scale ±32767), button 1 held every other second.
  void move_inputs(TimePoint now);

 private:
  canopen::ObjectDictionary od_;
  std::unique_ptr<canopen::Node> node_;
};

struct DemoOptions {
  double live_seconds = 3.0;  // how long the joystick moves in operational
  bool frames = false;        // print every frame on the bus (candump notation)
  // Publish the joystick as joystick.1 on DDS (loopback-only Cyclone configuration, partition
  // "oegw-demo") and LCM (udpm://224.0.0.1:7667?ttl=0, OEGW_DEMO_*), and take indicators.1 commands back into
  // the device's output 6200h:01. Off by default: this is the protocol core's demo; `oegw demo`
  // is the one that publishes (docs/guides/dds-lcm.md).
  bool publish = false;
};

// Runs the whole demo in real time on the virtual bus; returns the process exit code (0 when
// every step did what it should).
int run_demo(const DemoOptions& options);

struct DeviceOptions {
  std::string interface = "vcan0";
  NodeId node_id{0x20};
  std::filesystem::path store_path;
  std::uint16_t heartbeat_ms = 0;
  bool motion = true;  // move the inputs; off: they stay 0 (deterministic peers)
};

// Runs the demo device on a SocketCAN interface until SIGTERM/SIGINT. Returns the exit code;
// an interface that cannot be opened is reported precisely and gives 2.
int run_device(const DeviceOptions& options);

}  // namespace oegw::programs
