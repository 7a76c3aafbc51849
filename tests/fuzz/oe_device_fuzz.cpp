// libFuzzer target for the upstream device as the gateway builds it: the CiA 852 dictionary of
// tests/fixtures/full_fe_set.yaml (16 joysticks, 16 pedals, 8 encoders, 8 wheels, 8 button
// clusters with their indicators, the first commanded from DDS/LCM only) with a host heartbeat
// consumer, started, fed frames on every COB-ID it listens to (NMT, SYNC, TIME, SDO, each RPDO,
// LSS, heartbeats, EMCYs) with time advancing between them.
//
// Input: 11-byte chunks. Byte 0 picks the CAN-ID: 0..8 NMT, SYNC, TIME, the SDO request, LSS,
// two heartbeats (the host is node 1), two EMCYs; 9.. each RPDO's current COB-ID (all are
// disabled by default, Table 10: a seed enables them by SDO); past those an arbitrary 11-bit ID
// from bytes 0 and 3. Byte 1 the time step (x 10 ms, so SDO, heartbeat and inhibit timers all
// expire), byte 2 the DLC (mod 9; >= F0h an RTR frame), bytes 3..10 the data.
// Invariants (trap on breach): every frame the device sends is a classic 11-bit frame of at most
// 8 bytes; its next deadline never lies in the past after advance(); and unless LSS was used (it
// may change the node-ID), an NMT reset node followed by an SDO upload of 1000h is answered with
// 1000h's value: no input leaves the device deaf.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "gateway/oe_device.hpp"
#include "gateway/runtime_config.hpp"
#include "mapping/config.hpp"
#include "tests/fixtures/fixtures.hpp"
#include "tests/fuzz/fuzz_support.hpp"

using namespace oegw;
using canopen::CanFrame;
using canopen::TimePoint;
using fuzz::catalogue;
using fuzz::check;

namespace {

const gateway::OeDeviceConfig& device_config() {
  static const gateway::OeDeviceConfig cfg = [] {
    auto r = mapping::load_config_text(fixtures::mapping_file("full_fe_set.yaml"), "full_fe_set.yaml", catalogue);
    check(r.ok());
    auto c = gateway::device_config(*r.config, std::filesystem::path("/nonexistent/oegw-fuzz.store"));
    c.host_node = 0x01;  // 1016h:01: the host's heartbeat watched, 250 ms
    c.host_heartbeat_ms = 250;
    // One output FE the host may not command (mapping-file sources without canopen): its 6200h
    // entries refuse host writes (0800 0021h) and its RPDO bytes are ignored.
    c.host_may_not_command.insert(mapping::FeId{mapping::FeKind::IndicatorCluster, 1});
    return c;
  }();
  return cfg;
}

std::uint32_t u32(const std::vector<std::uint8_t>& v) {
  std::uint32_t x = 0;
  for (std::size_t i = 0; i < v.size() && i < 4; ++i) x |= static_cast<std::uint32_t>(v[i]) << (8 * i);
  return x;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto& cfg = device_config();
  std::vector<CanFrame> out;
  gateway::OeDevice device(cfg, [&](const CanFrame& f) { out.push_back(f); });
  TimePoint now{std::chrono::seconds(1)};
  (void)device.start(now);
  const std::uint8_t node = device.node().node_id().value();

  const std::vector<std::uint32_t> ids = {0x000, 0x080, 0x100, 0x600u + node, 0x7E5, 0x701, 0x702, 0x081, 0x0FF};
  std::vector<std::uint16_t> rpdos;  // 1400h + n - 1 of each RPDO; its COB-ID is read when used
  for (std::uint16_t i = 0x1400; i < 0x1600; ++i)
    if (device.od().find(i, 1) != nullptr) rpdos.push_back(i);
  const auto can_id = [&](const std::uint8_t* c) -> std::uint32_t {
    if (c[0] < ids.size()) return ids[c[0]];
    if (c[0] - ids.size() < rpdos.size()) return u32(device.od().find(rpdos[c[0] - ids.size()], 1)->value) & 0x7FF;
    return ((static_cast<std::uint32_t>(c[0]) << 3) | (c[3] & 0x07)) & 0x7FF;
  };

  bool lss = false;
  const auto sent_ok = [&] {
    for (const CanFrame& f : out) check(f.dlc <= 8 && f.id <= 0x7FF && !f.extended);
    out.clear();
  };
  for (std::size_t off = 0; off + 11 <= size; off += 11) {
    const std::uint8_t* c = data + off;
    CanFrame f;
    f.id = can_id(c);
    f.dlc = static_cast<std::uint8_t>(c[2] % 9);
    f.rtr = c[2] >= 0xF0;
    for (std::size_t i = 0; i < 8; ++i) f.data[i] = c[3 + i];
    lss = lss || f.id == 0x7E5;
    (void)device.on_frame(f, now);
    sent_ok();
    now += std::chrono::milliseconds(c[1] * 10);
    device.advance(now);
    sent_ok();
    if (const auto d = device.next_deadline()) check(*d > now - std::chrono::milliseconds(1));
  }
  if (lss) return 0;
  // Recovery: reset node (all nodes), then an SDO upload of 1000h.
  (void)device.on_frame(CanFrame(0x000, {0x81, 0x00}), now);
  now += std::chrono::milliseconds(10);
  device.advance(now);
  out.clear();
  (void)device.on_frame(CanFrame(0x600u + node, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), now);
  bool answered = false;
  for (const CanFrame& f : out)
    answered = answered || (f.id == 0x580u + node && f.data[0] == 0x43 && f.data[1] == 0x00 && f.data[2] == 0x10);
  check(answered);
  return 0;
}
