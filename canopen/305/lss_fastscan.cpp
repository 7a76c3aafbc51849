#include "canopen/305/lss_fastscan.hpp"

namespace oegw::canopen {

using Status = LssMaster::Status;

void LssFastscan::start(TimePoint now, Callback done, std::optional<Duration> step_timeout, Known known) {
  begin(std::move(done), "a new fastscan started");
  timeout_ = step_timeout;
  sub_ = 0;
  bit_ = 31;
  retry_ = false;
  known_ = known;
  const std::uint32_t parts[4] = {known.value.vendor, known.value.product, known.value.revision, known.value.serial};
  for (std::size_t i = 0; i < 4; ++i) value_[i] = parts[i] & known.mask[i];
  master_.fastscan(0, lss::cs::kFastscanReset, 0, 0, now, guard([this](const LssMaster::Result& reset) {
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

void LssFastscan::step(TimePoint now) {
  while (bit_ >= 1 && (known_.mask[sub_] >> bit_ & 1u) != 0) --bit_;  // known: value_ has it
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
  master_.fastscan(
      value_[sub_], 0, sub_, next, now, guard([this](const LssMaster::Result& r) {
        if (r.status != Status::Ok) {
          if ((known_.mask[sub_] & 1u) != 0) {  // bit 0 known: not tried the other way
            static const char* const part[4] = {"vendor-ID", "product code", "revision number", "serial number"};
            finish({Outcome::Lost, std::nullopt,
                    std::string("LSS fastscan: no node without node-ID has the known bits of the ") + part[sub_]});
            return;
          }
          if (retry_) {
            finish({Outcome::Lost, std::nullopt, "LSS fastscan lost the node (no answer for either value of bit 0)"});
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
