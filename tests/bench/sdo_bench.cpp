// SDO transfer rates between a host (Master's SDO client) and a device (Node's SDO server), with a
// simulated clock: expedited upload/download round trips, a segmented upload of a 100-byte
// VISIBLE_STRING and a block upload of a 4 KiB DOMAIN.
//
// Three wirings, so that each layer's cost is visible:
//   Bus     Master and Node on a VirtualBus (the tier-2 integration pattern): frames are queued
//           on the bus and delivered by VirtualBus::deliver_all().
//   Direct  the same Master and Node, each one's sink calling the other's on_frame() at once.
//   Bare    an SdoClient and an SdoServer wired to each other, no Node/Master dispatch.
// One iteration = one complete transfer (request queued, every frame exchanged, callback run),
// so the Time column is the time per round trip / per transfer. "allocs/iter" counts the heap
// allocations per transfer. *_Percentiles time 10,000 single transfers with steady_clock (after
// 10,000 warm-up ones) and report p50/p90/p99/p99.9/max in ns; "clock_ns" is the cost of the
// two clock reads included in every sample.
#include <benchmark/benchmark.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "bench_support.hpp"
#include "canopen/301/sdo_client.hpp"
#include "canopen/301/sdo_server.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "canopen/master.hpp"
#include "canopen/node.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
using oegw::bench::AllocCounter;
using oegw::bench::report_percentiles;

namespace {

constexpr NodeId kDevice{0x20};
constexpr std::uint32_t kDeviceType = 0x000F0191;
constexpr std::uint16_t kU32 = 0x2100;     // UNSIGNED32, rw
constexpr std::uint16_t kString = 0x2200;  // VISIBLE_STRING, 100 bytes
constexpr std::uint16_t kDomain = 0x2300;  // DOMAIN, 4 KiB
constexpr std::size_t kStringSize = 100;
constexpr std::size_t kDomainSize = 4096;
constexpr std::size_t kSamples = 10'000;

void add_bench_objects(ObjectDictionary& od) {
  od.add_var(kU32, "Bench UNSIGNED32", DataType::Unsigned32, Access::ReadWrite, encode<std::uint32_t>(0));
  std::vector<std::uint8_t> text(kStringSize);
  for (std::size_t i = 0; i < text.size(); ++i) text[i] = static_cast<std::uint8_t>('a' + i % 26);
  od.add_var(kString, "Bench VISIBLE_STRING", DataType::VisibleString, Access::ReadOnly, text);
  std::vector<std::uint8_t> blob(kDomainSize);
  for (std::size_t i = 0; i < blob.size(); ++i) blob[i] = static_cast<std::uint8_t>(i * 7 + 3);
  od.add_var(kDomain, "Bench DOMAIN", DataType::Domain, Access::ReadWrite, blob);
  od.find(kDomain, 0)->max_size = kDomainSize;
  od.reset_to_defaults(kU32, kDomain);
}

// Master and Node on a virtual bus.
class BusRig {
 public:
  BusRig() {
    add_bench_objects(dev_od_);
    NodeConfig cfg;
    cfg.node_id = kDevice;
    cfg.device_type = kDeviceType;
    device_ = std::make_unique<Node>(dev_od_, cfg, dev_port_->sink());
    host_ = std::make_unique<Master>(host_od_, host_port_->sink());
    dev_port_->set_receiver([this](const CanFrame& f, TimePoint t) { (void)device_->on_frame(f, t); });
    host_port_->set_receiver([this](const CanFrame& f, TimePoint t) { (void)host_->on_frame(f, t); });
    (void)device_->start(now_);
    bus_.deliver_all(now_);
    client_ = &host_->sdo(kDevice);
  }
  SdoClient& client() { return *client_; }
  // Runs the queued request to completion: the host's advance() starts it, the bus carries it.
  void run() {
    now_ += 1us;
    host_->advance(now_);
    bus_.deliver_all(now_);
  }

 private:
  TimePoint now_{};
  VirtualBus bus_;
  std::unique_ptr<VirtualPort> host_port_ = bus_.attach("host");
  std::unique_ptr<VirtualPort> dev_port_ = bus_.attach("device");
  ObjectDictionary dev_od_;
  ObjectDictionary host_od_;
  std::unique_ptr<Node> device_;
  std::unique_ptr<Master> host_;
  SdoClient* client_ = nullptr;
};

// The same Master and Node, each sink calling the peer's on_frame() directly.
class DirectRig {
 public:
  DirectRig() {
    add_bench_objects(dev_od_);
    NodeConfig cfg;
    cfg.node_id = kDevice;
    cfg.device_type = kDeviceType;
    device_ = std::make_unique<Node>(dev_od_, cfg, [this](const CanFrame& f) { (void)host_->on_frame(f, now_); });
    host_ = std::make_unique<Master>(host_od_, [this](const CanFrame& f) { (void)device_->on_frame(f, now_); });
    (void)device_->start(now_);
    client_ = &host_->sdo(kDevice);
  }
  SdoClient& client() { return *client_; }
  void run() {
    now_ += 1us;
    host_->advance(now_);
  }

 private:
  TimePoint now_{};
  ObjectDictionary dev_od_;
  ObjectDictionary host_od_;
  std::unique_ptr<Node> device_;
  std::unique_ptr<Master> host_;
  SdoClient* client_ = nullptr;
};

// A bare SdoClient and SdoServer on one object dictionary holding 1000h and the bench objects.
class BareRig {
 public:
  BareRig() {
    od_.add_var(0x1000, "Device type", DataType::Unsigned32, Access::Const, encode<std::uint32_t>(kDeviceType));
    od_.reset_to_defaults(0x1000, 0x1000);
    add_bench_objects(od_);
  }
  SdoClient& client() { return client_; }
  void run() {
    now_ += 1us;
    client_.advance(now_);
  }

 private:
  TimePoint now_{};
  ObjectDictionary od_;
  SdoServer server_{od_, [this](const CanFrame& f) { (void)client_.on_frame(f, now_); }, kDevice};
  SdoClient client_{[this](const CanFrame& f) { (void)server_.on_frame(f, now_); }, kDevice};
};

struct Outcome {
  std::uint64_t done = 0;
  std::uint64_t failed = 0;
  std::uint64_t bytes = 0;
  std::uint32_t first_word = 0;
};

// The client callback: one pointer captured, so std::function keeps it inline (no allocation).
SdoClient::Callback record(Outcome& o) {
  return [&o](SdoAbortCode code, std::vector<std::uint8_t> data) {
    ++o.done;
    if (code != SdoAbortCode::None) ++o.failed;
    o.bytes += data.size();
    if (data.size() >= 4) o.first_word = get_u32(data.data());
  };
}

// Marks the run failed unless every transfer completed, each with `bytes_each` bytes.
bool check(benchmark::State& state, const Outcome& o, std::uint64_t transfers, std::size_t bytes_each) {
  if (o.done != transfers || o.failed != 0 || o.bytes != transfers * bytes_each) {
    state.SkipWithError("SDO transfers did not complete as expected");
    return false;
  }
  return true;
}

void per_transfer_counters(benchmark::State& state, std::size_t bytes_each) {
  const auto n = static_cast<std::int64_t>(state.iterations());
  state.SetItemsProcessed(n);
  if (bytes_each != 0) state.SetBytesProcessed(n * static_cast<std::int64_t>(bytes_each));
}

// --- expedited upload of 1000h (device type, UNSIGNED32) ----------------------------------------

template <class Rig>
void BM_SdoUploadExpedited(benchmark::State& state) {
  Rig rig;
  Outcome o;
  const auto cb = record(o);
  const AllocCounter allocs;
  for (auto _ : state) {
    rig.client().upload(0x1000, 0, cb);
    rig.run();
  }
  allocs.report(state);
  if (!check(state, o, state.iterations(), 4) || o.first_word != kDeviceType) return;
  per_transfer_counters(state, 0);
}

// --- expedited download of an UNSIGNED32 --------------------------------------------------------

template <class Rig>
void BM_SdoDownloadExpedited(benchmark::State& state) {
  Rig rig;
  Outcome o;
  const auto cb = record(o);
  const AllocCounter allocs;
  std::uint32_t v = 0;
  for (auto _ : state) {
    // The client API takes the data as a std::vector by value: one allocation per request.
    rig.client().download(kU32, 0, encode<std::uint32_t>(++v), cb);
    rig.run();
  }
  allocs.report(state);
  if (!check(state, o, state.iterations(), 0)) return;
  per_transfer_counters(state, 0);
}

// --- segmented upload of a 100-byte VISIBLE_STRING (1 initiate + 15 segments) -------------------

template <class Rig>
void BM_SdoUploadSegmented100(benchmark::State& state) {
  Rig rig;
  Outcome o;
  const auto cb = record(o);
  const AllocCounter allocs;
  for (auto _ : state) {
    rig.client().upload(kString, 0, cb, SdoTransfer::Auto);
    rig.run();
  }
  allocs.report(state);
  if (!check(state, o, state.iterations(), kStringSize)) return;
  per_transfer_counters(state, kStringSize);
}

// --- block upload of a 4 KiB DOMAIN (586 segments in 5 sub-blocks of 127, CRC) ----------------

template <class Rig>
void BM_SdoUploadBlock4K(benchmark::State& state) {
  Rig rig;
  Outcome o;
  const auto cb = record(o);
  const AllocCounter allocs;
  for (auto _ : state) {
    rig.client().upload(kDomain, 0, cb, SdoTransfer::Block);
    rig.run();
  }
  allocs.report(state);
  if (!check(state, o, state.iterations(), kDomainSize)) return;
  per_transfer_counters(state, kDomainSize);
}

// --- latency distributions ----------------------------------------------------------------------

template <class Rig>
void BM_SdoUploadExpedited_Percentiles(benchmark::State& state) {
  Rig rig;
  Outcome o;
  const auto cb = record(o);
  for (auto _ : state) {
    state.SetIterationTime(report_percentiles(state, kSamples, [&] {
      rig.client().upload(0x1000, 0, cb);
      rig.run();
    }));
  }
  (void)check(state, o, 2 * kSamples, 4);
}

template <class Rig>
void BM_SdoDownloadExpedited_Percentiles(benchmark::State& state) {
  Rig rig;
  Outcome o;
  const auto cb = record(o);
  std::uint32_t v = 0;
  for (auto _ : state) {
    state.SetIterationTime(report_percentiles(state, kSamples, [&] {
      rig.client().download(kU32, 0, encode<std::uint32_t>(++v), cb);
      rig.run();
    }));
  }
  (void)check(state, o, 2 * kSamples, 0);
}

}  // namespace

#define OEGW_SDO_BENCH(fn)                                         \
  BENCHMARK_TEMPLATE(fn, BusRig)->Unit(benchmark::kNanosecond);    \
  BENCHMARK_TEMPLATE(fn, DirectRig)->Unit(benchmark::kNanosecond); \
  BENCHMARK_TEMPLATE(fn, BareRig)->Unit(benchmark::kNanosecond)

#define OEGW_SDO_PERCENTILES(fn)                                                                   \
  BENCHMARK_TEMPLATE(fn, BusRig)->Unit(benchmark::kNanosecond)->Iterations(1)->UseManualTime();    \
  BENCHMARK_TEMPLATE(fn, DirectRig)->Unit(benchmark::kNanosecond)->Iterations(1)->UseManualTime(); \
  BENCHMARK_TEMPLATE(fn, BareRig)->Unit(benchmark::kNanosecond)->Iterations(1)->UseManualTime()

OEGW_SDO_BENCH(BM_SdoUploadExpedited);
OEGW_SDO_BENCH(BM_SdoDownloadExpedited);
OEGW_SDO_BENCH(BM_SdoUploadSegmented100);
OEGW_SDO_BENCH(BM_SdoUploadBlock4K);
OEGW_SDO_PERCENTILES(BM_SdoUploadExpedited_Percentiles);
OEGW_SDO_PERCENTILES(BM_SdoDownloadExpedited_Percentiles);
