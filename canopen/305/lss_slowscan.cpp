#include "canopen/305/lss_slowscan.hpp"

namespace oegw::canopen {

using Status = LssMaster::Status;

void LssSlowscan::start(const lss::AddressRange& range, TimePoint now, Callback done,
                        std::optional<Duration> step_timeout) {
  begin(std::move(done), "a new slowscan started");
  timeout_ = step_timeout.value_or(master_.timeout());
  range_ = range;
  master_
      .identify_remote_slave(range_, now, guard([this](const LssMaster::Result& r) {
                               if (r.status != Status::Ok) {
                                 finish(
                                     {Outcome::NoAnswer, std::nullopt,
                                      "no LSS slave in the range answered identify remote slave (CiA 305 §8.4.3.6)"});
                                 return;
                               }
                               step(master_.now());
                             }),
                             timeout_);
}

void LssSlowscan::step(TimePoint now) {
  // Halve the revision range, then the serial range: the lower half answered, or it is the upper.
  const bool revision = range_.revision_low < range_.revision_high;
  if (revision || range_.serial_low < range_.serial_high) {
    std::uint32_t& low = revision ? range_.revision_low : range_.serial_low;
    std::uint32_t& high = revision ? range_.revision_high : range_.serial_high;
    const std::uint32_t mid = low + (high - low) / 2;
    lss::AddressRange half = range_;
    (revision ? half.revision_high : half.serial_high) = mid;
    master_.identify_remote_slave(half, now, guard([this, &low, &high, mid](const LssMaster::Result& r) {
                                    if (r.status == Status::Ok) high = mid;
                                    else low = mid + 1;
                                    step(master_.now());
                                  }),
                                  timeout_);
    return;
  }
  const lss::Address found{range_.vendor, range_.product, range_.revision_low, range_.serial_low};
  master_.switch_state_selective(found, now, guard([this, found](const LssMaster::Result& r) {
                                   if (r.status != Status::Ok) {
                                     finish({Outcome::Lost, std::nullopt,
                                             "LSS slowscan lost the slave: switch state selective to the address found "
                                             "was not answered"});
                                     return;
                                   }
                                   finish({Outcome::Found, found, {}});
                                 }));
}

}  // namespace oegw::canopen
