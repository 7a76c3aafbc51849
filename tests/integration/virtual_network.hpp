// Test support: CANopen participants on a VirtualBus, driven by an EventLoop on a
// SimulatedClock. Time only moves when a test says so; nothing sleeps.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"

namespace oegw::testing {

using namespace oegw::canopen;
using namespace oegw::canopen::io;
class VirtualNetwork {
 public:
  VirtualNetwork() : loop_(clock_) { bus_.run_on(loop_); }

  // A participant's way out onto the bus: call before constructing it.
  FrameSink sink(const std::string& name) {
    auto& port = ports_[name];
    if (!port) port = bus_.attach(name);
    VirtualPort* p = port.get();
    return [p](const CanFrame& f) { (void)p->send(f); };
  }

  // Connects a sans-I/O participant (on_frame/advance/next_deadline) to its port: received
  // frames go to on_frame, its timers run from the loop.
  template <class P>
  void attach(const std::string& name, P& participant) {
    auto& port = ports_[name];
    if (!port) port = bus_.attach(name);
    auto driver = std::make_unique<ServiceDriver>(loop_, participant);
    driver->bind_receiver(*port, participant);
    drivers_[name] = std::move(driver);
  }

  // Disconnects a participant before it is destroyed (a power cycle): its port stays.
  void detach(const std::string& name) {
    if (auto it = ports_.find(name); it != ports_.end()) it->second->set_receiver({});
    drivers_.erase(name);
  }

  // Re-arms every participant's timer (after calling into one from the test) and lets the bus
  // settle at the current time.
  void settle() {
    for (auto& [name, d] : drivers_) d->rearm();
    loop_.advance_by(Duration{0});
  }
  void run_for(Duration d) {
    settle();
    loop_.advance_by(d);
  }
  // The frames with `id` in the bus's log (bus().set_logging(true)).
  [[nodiscard]] std::vector<CanFrame> logged(std::uint32_t id) {
    std::vector<CanFrame> out;
    for (const auto& r : bus_.log())
      if (r.frame.id == id) out.push_back(r.frame);
    return out;
  }
  // One raw frame from participant `from`, then `wait`: the frames with `reply_id` that followed.
  std::vector<CanFrame> exchange(const std::string& from, const CanFrame& frame, std::uint32_t reply_id,
                                 Duration wait = std::chrono::milliseconds(5)) {
    bus_.clear_log();
    sink(from)(frame);
    run_for(wait);
    return logged(reply_id);
  }
  [[nodiscard]] TimePoint now() const { return clock_.now(); }
  VirtualBus& bus() { return bus_; }
  EventLoop& loop() { return loop_; }

  ~VirtualNetwork() {
    ports_.clear();  // ports point at drivers: they go first
    drivers_.clear();
  }

 private:
  SimulatedClock clock_;
  EventLoop loop_;
  VirtualBus bus_;
  std::map<std::string, std::unique_ptr<ServiceDriver>> drivers_;
  std::map<std::string, std::unique_ptr<VirtualPort>> ports_;
};

}  // namespace oegw::testing
