#include "canopen/io/virtual_bus.hpp"

#include <stdexcept>

#include "canopen/frame_bits.hpp"
#include "canopen/io/event_loop.hpp"

namespace oegw::canopen::io {

std::string BusRecord::to_string() const { return sender + ": " + frame.to_string(); }

VirtualPort::~VirtualPort() {
  if (bus_ != nullptr) bus_->detach(id_);
}

SendResult VirtualPort::send(const CanFrame& frame) {
  if (!is_valid_frame(frame)) {
    ++counters_.errors;
    return {SendStatus::InvalidFrame, 0};
  }
  if (!connected_ || bus_ == nullptr) {
    ++counters_.tx_dropped;
    return {};
  }
  ++counters_.tx_frames;
  bus_->enqueue(id_, name_, frame);
  return {};
}

VirtualBus::~VirtualBus() {
  for (auto& [id, port] : ports_) port->bus_ = nullptr;
  if (timed_loop_ != nullptr) {
    if (deliver_timer_ != 0) timed_loop_->cancel(deliver_timer_);
    if (idle_timer_ != 0) timed_loop_->cancel(idle_timer_);
  }
}

std::unique_ptr<VirtualPort> VirtualBus::attach(std::string name, PortOptions options) {
  const std::uint64_t id = next_id_++;
  std::unique_ptr<VirtualPort> port(new VirtualPort(this, id, std::move(name), options));
  ports_.emplace(id, port.get());
  return port;
}

SendResult VirtualBus::inject(const CanFrame& frame, std::string sender) {
  if (!is_valid_frame(frame)) return {SendStatus::InvalidFrame, 0};
  enqueue(0, sender, frame);
  return {};
}

void VirtualBus::drop_next(std::size_t count, FramePredicate match) {
  drop_count_ = count;
  drop_match_ = std::move(match);
}

void VirtualBus::enqueue(std::uint64_t sender_id, const std::string& sender, const CanFrame& frame) {
  if (drop_count_ > 0 && (!drop_match_ || drop_match_(frame))) {
    --drop_count_;
    ++dropped_;
    return;
  }
  if (timed()) {
    waiting_.emplace(std::pair{arbitration_key(frame), send_seq_++}, Pending{sender_id, sender, frame});
    // Every frame sent at this instant competes: arbitration runs after the current callback.
    if (!on_wire_ && !arbitration_posted_) {
      arbitration_posted_ = true;
      timed_loop_->post([this, alive = std::weak_ptr<int>(alive_)] {
        if (alive.expired()) return;
        arbitration_posted_ = false;
        arbitrate();
      });
    }
    return;
  }
  const bool was_empty = pending() == 0;
  queue_.push_back(Pending{sender_id, sender, frame});
  if (was_empty && !delivering_ && wakeup_) wakeup_();
}

void VirtualBus::deliver_one(Pending p, TimePoint now) {
  BusRecord record{now, std::move(p.sender), p.frame};
  if (logging_) log_.push_back(record);
  if (tap_) tap_(record);
  // Snapshot: receivers may attach or destroy ports while we deliver.
  std::vector<std::uint64_t>& targets = targets_;  // reused: deliveries are not re-entered
  targets.clear();
  for (const auto& [id, port] : ports_) targets.push_back(id);
  for (std::uint64_t id : targets) {
    auto it = ports_.find(id);
    if (it == ports_.end()) continue;
    VirtualPort* port = it->second;
    if (!port->connected_) continue;
    if (id == p.sender_id && !port->options_.receive_own) continue;
    port->deliver_frame(record.frame, now);
  }
}

std::size_t VirtualBus::deliver_all(TimePoint now, std::size_t max_frames) {
  if (timed()) throw std::logic_error("VirtualBus::deliver_all on a timed bus: its event loop moves the frames");
  if (delivering_) return 0;
  delivering_ = true;
  struct Reset {
    bool& flag;
    ~Reset() { flag = false; }
  } reset{delivering_};

  std::size_t delivered = 0;
  while (head_ < queue_.size() && delivered < max_frames) {
    Pending p = std::move(queue_[head_++]);
    if (head_ == queue_.size()) {
      queue_.clear();  // keeps the capacity: queueing a frame does not allocate
      head_ = 0;
    } else if (head_ >= 1024 && head_ * 2 >= queue_.size()) {
      // Never drained (a flood delivered in batches): drop the delivered half.
      queue_.erase(queue_.begin(), queue_.begin() + static_cast<std::ptrdiff_t>(head_));
      head_ = 0;
    }
    ++delivered;
    deliver_one(std::move(p), now);
  }
  return delivered;
}

void VirtualBus::run_on(EventLoop& loop) {
  // Delivers in batches so that a frame storm cannot starve the loop's timers and descriptors.
  constexpr std::size_t kBatch = 1024;
  std::weak_ptr<int> alive = alive_;
  auto post_delivery = std::make_shared<std::function<void()>>();
  *post_delivery = [this, &loop, alive, weak_self = std::weak_ptr(post_delivery)] {
    loop.post([this, &loop, alive, weak_self] {
      if (alive.expired()) return;
      deliver_all(loop.now(), kBatch);
      if (pending() != 0) {
        if (auto self = weak_self.lock()) (*self)();
      }
    });
  };
  set_wakeup([post_delivery] { (*post_delivery)(); });
  if (pending() != 0) (*post_delivery)();
}

}  // namespace oegw::canopen::io

namespace oegw::canopen::io {

void VirtualBus::run_timed_on(EventLoop& loop, std::uint32_t bit_rate) {
  if (bit_rate == 0) throw std::invalid_argument("VirtualBus::run_timed_on: bit rate 0");
  bit_rate_ = bit_rate;
  timed_loop_ = &loop;
  set_wakeup({});
}

Duration VirtualBus::bit_time(std::uint64_t bits) const {
  if (bit_rate_ == 0) return Duration{0};
  return Duration{static_cast<Duration::rep>((bits * 1'000'000ull + bit_rate_ - 1) / bit_rate_)};
}

void VirtualBus::arbitrate() {
  if (on_wire_ || waiting_.empty()) return;
  // ISO 11898-1 §10.8.3: of the frames waiting when the bus goes idle, the lowest arbitration
  // field wins; among equal ones (the same frame from two senders) the one sent first.
  auto first = waiting_.begin();
  Pending p = std::move(first->second);
  waiting_.erase(first);
  on_wire_ = true;
  const std::uint32_t bits = frame_bits(p.frame);
  const TimePoint start = timed_loop_->now();
  const TimePoint received = start + bit_time(bits - kIntermissionBits);
  const TimePoint idle = start + bit_time(bits);
  ++stats_.frames;
  stats_.bits += bits;
  stats_.busy += idle - start;
  auto shared = std::make_shared<Pending>(std::move(p));
  deliver_timer_ = timed_loop_->call_at(received, [this, shared, received] {
    deliver_timer_ = 0;
    deliver_one(std::move(*shared), received);
  });
  idle_timer_ = timed_loop_->call_at(idle, [this] {
    idle_timer_ = 0;
    on_wire_ = false;
    arbitrate();
  });
}

}  // namespace oegw::canopen::io
