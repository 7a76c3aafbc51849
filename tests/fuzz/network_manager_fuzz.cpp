// libFuzzer target for the downstream network manager with one node of every driver family
// (elobau MFG grip 11h, MCB-402 03h, Novotechnik CiA 406 40h, generic CiA 401 pedal 30h from
// subdevices/eds/generic_pedal.eds) and a SYNC producer: it boots them, so every answer a node
// can give (boot-up, heartbeat, SDO responses of every kind, EMCY, each TPDO, LSS) arrives in
// whatever order and shape the input says, with time advancing.
//
// Input: 12-byte chunks. Byte 0 picks the node (mod 4), byte 1 the frame: 0 boot-up/heartbeat
// (700h + node), 1 SDO response (580h + node), 2 EMCY (80h + node), 3..6 TPDO 1..4, 7 LSS
// answer (7E4h), else an arbitrary 11-bit ID from bytes 1 and 4; byte 2 the time step (x 10 ms:
// SDO time-outs, heartbeat losses and boot waits all happen), byte 3 the DLC (mod 9; >= F0h an
// RTR frame), bytes 4..11 the data. An SDO response whose byte 4 is below 80h is an *answer*
// to the master's last request to that node instead (the same index and sub-index: a
// confirmation, an expedited upload of bytes 6..9, a segment), and for 1000h and 1018h:01..04
// with byte 5 even it carries the value the driver expects, so that boots run to their end and
// the fuzzer spends its time on what follows.
// Invariants (trap on breach): every frame the master sends is a classic 11-bit frame of at most
// 8 bytes; a node is Operational only after its proof of life arrived since the master's last
// NMT command to it (a heartbeat reporting operational; the pedal, without heartbeat, a TPDO of
// its own, on the COB-ID it reported at boot): never "healthy" on silence or on any other frame; its driver's input
// values are Valid only while the node is Operational; the next deadline is never in the past after advance().
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <memory>
#include <vector>

#include "canopen/master.hpp"
#include "subdevices/families.hpp"
#include "subdevices/network_manager.hpp"
#include "tests/fuzz/fuzz_support.hpp"

using namespace oegw;
using canopen::CanFrame;
using canopen::NodeId;
using canopen::TimePoint;
using fuzz::check;

namespace {

constexpr std::uint8_t kNodes[4] = {0x11, 0x03, 0x40, 0x30};

// OEGW_FUZZ_TRACE=1 prints every frame and node state of a run (to read a crash input).
const bool kTrace = std::getenv("OEGW_FUZZ_TRACE") != nullptr;
void trace(const char* dir, const CanFrame& f) {
  if (!kTrace) return;
  std::fprintf(stderr, "%s %03X [%u]", dir, static_cast<unsigned>(f.id), static_cast<unsigned>(f.dlc));
  for (unsigned i = 0; i < f.dlc && i < 8; ++i) std::fprintf(stderr, " %02X", f.data[i]);
  std::fprintf(stderr, "\n");
}

// The answer a node gives to the master's SDO request `req` (CiA 301 §7.2.4.3), shaped by the
// chunk `c`; false for a request it does not answer this way (block transfers, aborts).
bool answer(const CanFrame& req, const subdevices::Driver& driver, const std::uint8_t* c, CanFrame& f) {
  const std::uint8_t ccs = req.data[0] >> 5;
  f.dlc = 8;
  f.data = {};
  f.data[1] = req.data[1];
  f.data[2] = req.data[2];
  f.data[3] = req.data[3];
  switch (ccs) {
    case 1:  // initiate download -> confirmation
      f.data[0] = 0x60;
      return true;
    case 0:  // download segment -> confirmation with its toggle
      f.data = {};
      f.data[0] = static_cast<std::uint8_t>(0x20 | (req.data[0] & 0x10));
      return true;
    case 3:  // upload segment -> the last segment, 1..7 bytes
      f.data = {};
      f.data[0] = static_cast<std::uint8_t>((req.data[0] & 0x10) | ((c[6] % 7) << 1) | 1);
      for (int i = 1; i < 8; ++i) f.data[i] = c[4 + i];
      return true;
    case 2: {  // initiate upload -> expedited, 4 bytes
      const std::uint16_t index = static_cast<std::uint16_t>(req.data[1] | (req.data[2] << 8));
      const std::uint8_t sub = req.data[3];
      std::uint32_t v = static_cast<std::uint32_t>(c[6] | (c[7] << 8) | (c[8] << 16) | (c[9] << 24));
      const auto id = driver.expected_identity();
      std::optional<std::uint32_t> expected;
      if (index == 0x1000 && sub == 0) expected = id.device_type;
      if (index == 0x1018 && sub == 1) expected = id.vendor_id;
      if (index == 0x1018 && sub == 2) expected = id.product_code;
      if (index == 0x1018 && sub == 3) expected = id.revision;
      if (index == 0x1018 && sub == 4) expected = id.serial;
      if (expected && c[5] % 2 == 0) v = *expected;
      // 1..4 bytes from byte 5; 1001h (UNSIGNED8) always 1, the identity 4.
      // 1..4 bytes from byte 5, except where CiA 301 fixes the size of what the boot reads:
      // 1001h UNSIGNED8, the identity UNSIGNED32, the PDO parameters (§7.5.2.35-38).
      unsigned bytes = 4 - ((c[5] >> 1) & 3u);
      if (index == 0x1001) bytes = 1;
      if (expected) bytes = 4;
      if (index >= 0x1400 && index <= 0x1BFF && (index & 0x0200) == 0)  // communication parameters
        bytes = sub == 1 ? 4 : (sub == 2 || sub == 0 || sub == 4 || sub == 6) ? 1 : 2;
      if (index >= 0x1600 && index <= 0x1BFF && (index & 0x0200) != 0) bytes = sub == 0 ? 1 : 4;  // mapping
      f.data[0] = static_cast<std::uint8_t>(0x43 | ((4 - bytes) << 2));
      for (int i = 0; i < 4; ++i) f.data[4 + i] = static_cast<std::uint8_t>(v >> (8 * i));
      return true;
    }
    default: return false;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::vector<CanFrame> out;
  const canopen::FrameSink sink = [&](const CanFrame& f) { out.push_back(f); };
  canopen::ObjectDictionary od;
  canopen::Master master(od, sink, canopen::MasterConfig{.sync_period = std::chrono::milliseconds(20)});
  subdevices::NetworkManager network(master);
  std::map<std::string, subdevices::NodeState> states;
  network.on_node_state = [&](const std::string& name, subdevices::NodeState s, const std::string& why) {
    states[name] = s;
    if (kTrace) std::fprintf(stderr, "%s: %s (%s)\n", name.c_str(), std::string(to_string(s)).c_str(), why.c_str());
  };
  std::vector<subdevices::Driver*> drivers;
  std::string error;
  const char* names[4] = {"grip", "mcb", "encoder", "pedal"};
  for (int i = 0; i < 4; ++i) {
    const NodeId node{kNodes[i]};
    std::unique_ptr<subdevices::Driver> d;
    if (i == 0) d = subdevices::make_elobau_mfg_driver(node, sink, {}, error);
    if (i == 1)  // the bit order is a commissioning choice (docs/guides/commission.md#commissioning-choices)
      d = subdevices::make_mcb402_driver(node, sink, subdevices::DriverOptions{{{"button_bits", "1,2,3,4,5,7,6"}}},
                                         error);
    if (i == 2) d = subdevices::make_novotechnik_406_driver(node, sink, {}, error);
    if (i == 3)
      d = subdevices::make_cia401_driver(node, sink,
                                         subdevices::DriverOptions{{{"eds", std::string(OEGW_SOURCE_DIR) +
                                                                                "/subdevices/eds/generic_pedal.eds"}}},
                                         error);
    check(d != nullptr);
    drivers.push_back(d.get());
    subdevices::NodeSettings s;
    s.name = names[i];
    s.node = node;
    s.heartbeat_ms = i == 3 ? 0 : 100;  // the pedal without heartbeat: PDOs are its proof of life
    s.pdo_timeout_ms = i == 3 ? 300 : 0;
    s.mandatory = i == 0;
    check(network.add(std::move(s), std::move(d)));
  }
  TimePoint now{std::chrono::seconds(1)};
  network.start(now);

  // Frames from each node since the master last sent it NMT start (or reset).
  std::map<std::uint8_t, bool> heard_since_start;
  std::map<std::uint8_t, CanFrame> last_request;  // the master's last SDO request per node
  const auto sent_ok = [&] {
    for (const CanFrame& f : out) {
      trace("TX", f);
      check(f.dlc <= 8 && f.id <= 0x7FF && !f.extended);
      if (f.id > 0x600 && f.id <= 0x67F) last_request[static_cast<std::uint8_t>(f.id - 0x600)] = f;
      if (f.id == 0x000 && f.dlc >= 2)
        for (const std::uint8_t n : kNodes)
          if (f.data[1] == n || f.data[1] == 0) heard_since_start[n] = false;
    }
    out.clear();
  };
  const auto invariants = [&] {
    for (int i = 0; i < 4; ++i) {
      const auto it = states.find(names[i]);
      const bool operational = it != states.end() && it->second == subdevices::NodeState::Operational;
      if (operational) check(heard_since_start[kNodes[i]]);
      if (!operational)
        for (std::size_t k = 0; k < drivers[i]->signals().size(); ++k)
          if (drivers[i]->signals()[k].kind != subdevices::SignalKind::Output)
            check(drivers[i]->value(k).status != subdevices::SignalStatus::Valid);
    }
  };
  sent_ok();
  for (std::size_t off = 0; off + 12 <= size; off += 12) {
    const std::uint8_t* c = data + off;
    const std::uint8_t node = kNodes[c[0] % 4];
    static constexpr std::uint32_t kBase[8] = {0x700, 0x580, 0x080, 0x180, 0x280, 0x380, 0x480, 0x7E4};
    CanFrame f;
    if (c[1] < 8) f.id = c[1] == 7 ? 0x7E4 : kBase[c[1]] + node;
    else f.id = ((static_cast<std::uint32_t>(c[1]) << 3) | (c[4] & 0x07)) & 0x7FF;
    f.dlc = static_cast<std::uint8_t>(c[3] % 9);
    f.rtr = c[3] >= 0xF0;
    for (std::size_t i = 0; i < 8; ++i) f.data[i] = c[4 + i];
    if (c[1] == 1 && c[4] < 0x80 && !f.rtr) {
      const auto req = last_request.find(node);
      if (req == last_request.end() || !answer(req->second, *drivers[c[0] % 4], c, f)) continue;
    }
    // Proof of life (network_manager.hpp step 8): a heartbeat reporting operational, or for the
    // pedal (no heartbeat) one of its TPDOs: a frame on a COB-ID its driver consumes, which is
    // whatever the node answered for 18xxh:01 at boot (not necessarily 180h + its node-ID).
    // Nothing else counts.
    const std::uint8_t from = static_cast<std::uint8_t>(f.id & 0x7F);
    const auto pedal_cobs = drivers[3]->consumed_cob_ids();
    const bool pedal_pdo = std::find(pedal_cobs.begin(), pedal_cobs.end(), f.id) != pedal_cobs.end();
    const bool heartbeat = (f.id & 0x780) == 0x700 && from != kNodes[3] && f.dlc == 1 && f.data[0] == 0x05;
    if (!f.rtr && pedal_pdo && heard_since_start.count(kNodes[3]) != 0) heard_since_start[kNodes[3]] = true;
    if (!f.rtr && heartbeat && heard_since_start.count(from) != 0) heard_since_start[from] = true;
    trace("RX", f);
    (void)network.on_frame(f, now);
    sent_ok();
    invariants();
    now += std::chrono::milliseconds(c[2] * 10);
    network.advance(now);
    sent_ok();
    invariants();
    if (const auto d = network.next_deadline()) check(*d > now - std::chrono::milliseconds(1));
  }
  return 0;
}
