#include "canopen/301/sdo_pacer.hpp"

#include <algorithm>
#include <cmath>

#include "canopen/frame_bits.hpp"
#include "canopen/state.hpp"

namespace oegw::canopen {

Duration SdoPacer::gap_for(std::uint32_t bit_rate, double share) {
  if (bit_rate == 0 || !(share > 0.0)) return Duration{0};
  // A request and its answer: two 8-byte data frames with 11-bit identifiers (CiA 301 §7.2.4.3:
  // every SDO frame is 8 bytes) at their worst-case stuffing, intermission included.
  const double bits = 2.0 * frame_bits_worst_case(8);
  const double us = bits * 1e6 / (static_cast<double>(bit_rate) * std::min(share, 1.0));
  return Duration{static_cast<Duration::rep>(std::ceil(us))};
}

bool SdoPacer::try_start(TimePoint now, bool waited) {
  if (now < next_free_) return false;
  next_free_ = now + gap_;
  if (waited) ++delayed_starts_;
  return true;
}

void SdoPacer::export_state(StateWriter& w) const {
  w.put("next_free", next_free_);
  w.put("delayed_starts", delayed_starts_);
}

void SdoPacer::import_state(const StateReader& r) {
  const TimePoint next_free = r.time("next_free");
  delayed_starts_ = r.get<std::uint64_t>("delayed_starts");
  next_free_ = next_free;
}

}  // namespace oegw::canopen
