// PDO encode and decode rates, "sans I/O", simulated clock.
//
// Three mapping layouts, each filling the 8 data bytes of a classical CAN frame:
//   I16x4    4 × INTEGER16
//   U8x8     8 × UNSIGNED8
//   Boolx64  64 × BOOLEAN, bit-mapped (mapping length 1, 64 mapping entries: CiA 301 §7.4.7.1
//            lets a BOOLEAN map as one bit, and PdoService supports it, see check_mapping)
//
// BM_TpdoEncode      TPDO 1 event-driven (type 255, no inhibit time): each iteration writes one
//                    mapped input with ObjectDictionary::set (Origin::Local, as an application
//                    does), calls advance(now), and the frame comes out of the sink.
// BM_RpdoDecode      RPDO 1 (type 255) frames straight into PdoService::on_frame in Operational:
//                    every mapped entry is written to the OD (limits, hooks, observers).
// BM_NodeRpdo        the same RPDO frames through Node::on_frame (NMT, LSS, heartbeat, SYNC and
//                    SDO get to see each frame first) — the path a device node's frames take.
// BM_NodeTpdoEncode  the encode case through a Node (Node::advance runs every service).
// BM_BusNodeRpdo     RPDO frames injected on a VirtualBus and delivered to a Node, in batches of
//                    range(0) frames per deliver_all().
// One iteration = one frame, so items_per_second is frames/s. "allocs/iter" = heap allocations
// per frame.
#include <benchmark/benchmark.h>

#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

#include "bench_support.hpp"
#include "canopen/301/pdo.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "canopen/node.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
using oegw::bench::AllocCounter;

namespace {

constexpr NodeId kDevice{0x20};
constexpr std::uint16_t kInputs = 0x6100;   // mapped into TPDO 1, ro
constexpr std::uint16_t kOutputs = 0x6300;  // mapped into RPDO 1, rw
constexpr std::uint32_t kTpdoCob = cob::kTpdo1 + 0x20;
constexpr std::uint32_t kRpdoCob = cob::kRpdo1 + 0x20;

enum class Layout { I16x4, U8x8, Boolx64 };

struct Shape {
  DataType type;
  std::uint8_t count;
  std::uint8_t bits;
};

constexpr Shape shape(Layout l) {
  switch (l) {
    case Layout::I16x4: return {DataType::Integer16, 4, 16};
    case Layout::U8x8: return {DataType::Unsigned8, 8, 8};
    case Layout::Boolx64: return {DataType::Boolean, 64, 1};
  }
  return {};
}

// The application objects and PDOs of the device; call before constructing the PdoService/Node.
void build(ObjectDictionary& od, Layout l) {
  const Shape s = shape(l);
  std::vector<std::uint8_t> zero(fixed_size(s.type), 0);
  od.add_array(kInputs, "Bench inputs", s.type, Access::ReadOnly, s.count, zero, true);
  od.add_array(kOutputs, "Bench outputs", s.type, Access::ReadWrite, s.count, zero, true);
  od.reset_to_defaults(kInputs, kOutputs);
  PdoParameters tp{.cob_id = kTpdoCob, .transmission_type = 0xFF, .mapping = {}, .mapping_capacity = s.count};
  PdoParameters rp{.cob_id = kRpdoCob, .transmission_type = 0xFF, .mapping = {}, .mapping_capacity = s.count};
  for (std::uint8_t i = 1; i <= s.count; ++i) {
    tp.mapping.push_back(pdo_map(kInputs, i, s.bits));
    rp.mapping.push_back(pdo_map(kOutputs, i, s.bits));
  }
  install_tpdo(od, 1, tp);
  install_rpdo(od, 1, rp);
}

// Writes input number (i mod count) + 1 with a value different from the one it holds (a BOOLEAN
// is read and flipped).
void touch_input(ObjectDictionary& od, Layout l, std::uint32_t i) {
  const Shape s = shape(l);
  const auto sub = static_cast<std::uint8_t>(1 + i % s.count);
  switch (l) {
    case Layout::I16x4: (void)od.set<std::int16_t>(kInputs, sub, static_cast<std::int16_t>(i)); break;
    case Layout::U8x8: (void)od.set<std::uint8_t>(kInputs, sub, static_cast<std::uint8_t>(i)); break;
    case Layout::Boolx64:
      (void)od.set<std::uint8_t>(kInputs, sub, static_cast<std::uint8_t>(od.get<std::uint8_t>(kInputs, sub) ^ 1u));
      break;
  }
}

// A valid RPDO frame for the layout (BOOLEANs take any bit pattern; INTEGER16/UNSIGNED8 any value).
CanFrame rpdo_frame(std::uint32_t i) {
  CanFrame f;
  f.id = kRpdoCob;
  f.dlc = 8;
  for (std::size_t b = 0; b < 8; ++b) f.data[b] = static_cast<std::uint8_t>(i * 31 + b * 7);
  return f;
}

// The OD holds the payload of `f` in the outputs (checks that the frames were really applied).
bool outputs_hold(const ObjectDictionary& od, Layout l, const CanFrame& f) {
  const Shape s = shape(l);
  for (std::uint8_t i = 1; i <= s.count; ++i) {
    const auto& v = od.find(kOutputs, i)->value;
    const unsigned bit = (i - 1u) * s.bits;
    if (s.bits == 1) {
      if (v[0] != ((f.data[bit / 8] >> (bit % 8)) & 1)) return false;
    } else if (std::memcmp(v.data(), f.data.data() + bit / 8, s.bits / 8) != 0) {
      return false;
    }
  }
  return true;
}

std::uint64_t iterations(const benchmark::State& state) { return static_cast<std::uint64_t>(state.iterations()); }

void frames_processed(benchmark::State& state) {
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}

template <Layout L>
void BM_TpdoEncode(benchmark::State& state) {
  ObjectDictionary od;
  build(od, L);
  std::uint64_t frames = 0;
  CanFrame last;
  PdoService pdo(od, [&](const CanFrame& f) {
    ++frames;
    last = f;
  });
  TimePoint now{};
  pdo.set_operational(true, now);
  pdo.advance(now);  // entering Operational sends the TPDO once
  frames = 0;
  std::uint32_t i = 0;
  const AllocCounter allocs;
  for (auto _ : state) {
    now += 1us;
    touch_input(od, L, ++i);
    pdo.advance(now);
  }
  allocs.report(state);
  benchmark::DoNotOptimize(last);
  if (frames != iterations(state) || last.id != kTpdoCob || last.dlc != 8) {
    state.SkipWithError("not one TPDO per input change");
    return;
  }
  frames_processed(state);
}

template <Layout L>
void BM_RpdoDecode(benchmark::State& state) {
  ObjectDictionary od;
  build(od, L);
  PdoService pdo(od, [](const CanFrame&) {});
  std::uint64_t applied = 0;
  pdo.on_rpdo = [&applied](std::uint16_t) { ++applied; };
  TimePoint now{};
  pdo.set_operational(true, now);
  CanFrame f;
  std::uint32_t i = 0;
  const AllocCounter allocs;
  for (auto _ : state) {
    now += 1us;
    f = rpdo_frame(++i);
    (void)pdo.on_frame(f, now);
  }
  allocs.report(state);
  if (applied != iterations(state) || !outputs_hold(od, L, f)) {
    state.SkipWithError("RPDOs not applied");
    return;
  }
  frames_processed(state);
}

// A device Node in NMT Operational with the layout's PDOs.
class OperationalNode {
 public:
  explicit OperationalNode(Layout l) {
    build(od_, l);
    NodeConfig cfg;
    cfg.node_id = kDevice;
    node_ = std::make_unique<Node>(od_, cfg, [this](const CanFrame& f) {
      ++frames_;
      last_ = f;
    });
    (void)node_->start(now_);
    (void)node_->on_frame(CanFrame{cob::kNmt, {0x01, kDevice.value()}}, now_);  // NMT start
    node_->advance(now_);
    frames_ = 0;
    node_->pdo().on_rpdo = [this](std::uint16_t) { ++applied_; };
  }
  [[nodiscard]] bool operational() const { return node_->state() == NmtState::Operational; }
  Node& node() { return *node_; }
  ObjectDictionary& od() { return od_; }
  TimePoint tick() { return now_ += 1us; }
  [[nodiscard]] std::uint64_t frames() const { return frames_; }
  [[nodiscard]] std::uint64_t applied() const { return applied_; }
  [[nodiscard]] const CanFrame& last() const { return last_; }

 private:
  ObjectDictionary od_;
  std::unique_ptr<Node> node_;
  TimePoint now_{};
  std::uint64_t frames_ = 0;
  std::uint64_t applied_ = 0;
  CanFrame last_;
};

template <Layout L>
void BM_NodeRpdo(benchmark::State& state) {
  OperationalNode dev(L);
  CanFrame f;
  std::uint32_t i = 0;
  const AllocCounter allocs;
  for (auto _ : state) {
    const TimePoint now = dev.tick();
    f = rpdo_frame(++i);
    (void)dev.node().on_frame(f, now);
  }
  allocs.report(state);
  if (!dev.operational() || dev.applied() != iterations(state) || !outputs_hold(dev.od(), L, f)) {
    state.SkipWithError("RPDOs not applied by the node");
    return;
  }
  frames_processed(state);
}

template <Layout L>
void BM_NodeTpdoEncode(benchmark::State& state) {
  OperationalNode dev(L);
  std::uint32_t i = 0;
  const AllocCounter allocs;
  for (auto _ : state) {
    const TimePoint now = dev.tick();
    touch_input(dev.od(), L, ++i);
    dev.node().advance(now);
  }
  allocs.report(state);
  if (!dev.operational() || dev.frames() != iterations(state) || dev.last().id != kTpdoCob) {
    state.SkipWithError("not one TPDO per input change");
    return;
  }
  frames_processed(state);
}

// RPDO frames over a VirtualBus to a Node; range(0) frames are queued per deliver_all().
void BM_BusNodeRpdo(benchmark::State& state) {
  const auto batch = static_cast<std::size_t>(state.range(0));
  OperationalNode dev(Layout::I16x4);
  VirtualBus bus;
  auto port = bus.attach("device");
  port->set_receiver([&dev](const CanFrame& f, TimePoint t) { (void)dev.node().on_frame(f, t); });
  std::uint32_t i = 0;
  CanFrame f;
  const AllocCounter allocs;
  for (auto _ : state) {
    for (std::size_t k = 0; k < batch; ++k) {
      f = rpdo_frame(++i);
      (void)bus.inject(f, "host");
    }
    bus.deliver_all(dev.tick());
  }
  const auto frames = static_cast<std::int64_t>(state.iterations() * batch);
  // allocs/iter is per deliver_all() (= `batch` frames); allocs/frame divides it further.
  allocs.report(state);
  state.counters["allocs/frame"] = state.counters["allocs/iter"].value / static_cast<double>(batch);
  if (dev.applied() != static_cast<std::uint64_t>(frames) || !outputs_hold(dev.od(), Layout::I16x4, f)) {
    state.SkipWithError("RPDOs not applied by the node");
    return;
  }
  state.SetItemsProcessed(frames);
}

}  // namespace

BENCHMARK_TEMPLATE(BM_TpdoEncode, Layout::I16x4);
BENCHMARK_TEMPLATE(BM_TpdoEncode, Layout::U8x8);
BENCHMARK_TEMPLATE(BM_TpdoEncode, Layout::Boolx64);
BENCHMARK_TEMPLATE(BM_RpdoDecode, Layout::I16x4);
BENCHMARK_TEMPLATE(BM_RpdoDecode, Layout::U8x8);
BENCHMARK_TEMPLATE(BM_RpdoDecode, Layout::Boolx64);
BENCHMARK_TEMPLATE(BM_NodeRpdo, Layout::I16x4);
BENCHMARK_TEMPLATE(BM_NodeRpdo, Layout::U8x8);
BENCHMARK_TEMPLATE(BM_NodeRpdo, Layout::Boolx64);
BENCHMARK_TEMPLATE(BM_NodeTpdoEncode, Layout::I16x4);
BENCHMARK(BM_BusNodeRpdo)->Arg(1)->Arg(64);
