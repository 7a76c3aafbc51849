#include "canopen/305/lss_fastscan.hpp"

namespace oegw::canopen {

using Status = LssMaster::Status;

LssMaster::Callback LssFastscan::guard(std::function<void(const LssMaster::Result&)> f) {
  return [this, gen = generation_, f = std::move(f)](const LssMaster::Result& r) {
    if (gen != generation_ || !done_) return;
    f(r);
  };
}

void LssFastscan::start(TimePoint now, Callback done, std::optional<Duration> step_timeout) {
  if (running()) cancel("a new fastscan started");
  ++generation_;
  done_ = std::move(done);
  timeout_ = step_timeout;
  sub_ = 0;
  bit_ = 31;
  retry_ = false;
  for (auto& v : value_) v = 0;
  master_.fastscan(0, lss::cs::kFastscanReset, 0, 0, now,
                   guard([this](const LssMaster::Result& reset) {
                     if (reset.status != Status::Ok) {
                       finish({Outcome::NoAnswer, std::nullopt,
                               "no answer to LSS fastscan (CiA 305 §8.4.4): no node without node-ID, or it does not "
                               "support fastscan"});
                       return;
                     }
                     step(master_.now());
                   }),
                   timeout_);
}

void LssFastscan::cancel(const std::string& why) {
  if (!running()) return;
  ++generation_;
  finish({Outcome::Cancelled, std::nullopt, why});
}

void LssFastscan::finish(Result r) {
  Callback cb = std::move(done_);
  done_ = nullptr;
  if (cb) cb(r);
}

void LssFastscan::step(TimePoint now) {
  if (bit_ >= 1) {
    const auto bit = static_cast<std::uint8_t>(bit_);
    master_.fastscan(value_[sub_], bit, sub_, sub_, now, guard([this, bit](const LssMaster::Result& r) {
                       if (r.status != Status::Ok) value_[sub_] |= 1u << bit;
                       --bit_;
                       step(master_.now());
                     }),
                     timeout_);
    return;
  }
  const auto next = static_cast<std::uint8_t>(sub_ < 3 ? sub_ + 1 : 0);
  master_.fastscan(value_[sub_], 0, sub_, next, now, guard([this](const LssMaster::Result& r) {
                     if (r.status != Status::Ok) {
                       if (retry_) {
                         finish({Outcome::Lost, std::nullopt,
                                 "LSS fastscan lost the node (no answer for either value of bit 0)"});
                         return;
                       }
                       retry_ = true;
                       value_[sub_] |= 1u;
                       step(master_.now());
                       return;
                     }
                     retry_ = false;
                     if (++sub_ < 4) {
                       bit_ = 31;
                       step(master_.now());
                       return;
                     }
                     finish({Outcome::Found, lss::Address{value_[0], value_[1], value_[2], value_[3]}, {}});
                   }),
                   timeout_);
}

}  // namespace oegw::canopen
