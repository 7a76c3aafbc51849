#include "subdevices/novotechnik_406.hpp"

#include <algorithm>
#include <cstdio>
#include <limits>

#include "canopen/state.hpp"
#include "subdevices/driver_options.hpp"
#include "subdevices/families.hpp"

namespace oegw::subdevices {

namespace novotechnik {
namespace {

using E = EmcyEffect;
// §9.1 "Emergency Messages": Byte 0,1 error code | Byte 2 error register | Byte 3 | level.
constexpr EmcyEntry kTable[] = {
    {0x0000, 0, 0, "Hard", "sensor error reset, no error", E::Clear},
    {0x1000, 1, 0, "Hard", "unknown error, position value 0x7FFFFFFC", E::PositionError},
    {0x3100, 1, 0, "Error", "supply voltage fault", E::PositionError},
    {0x3100, 1, 1, "Warn", "supply voltage overrun, factory-set maximum threshold exceeded", E::None},
    {0x3100, 1, 2, "Warn", "supply voltage underrun, factory-set minimum threshold exceeded", E::None},
    {0x4210, 1, 1, "Warn", "temperature overrun, factory-set maximum threshold exceeded", E::None},
    {0x4210, 1, 2, "Warn", "temperature underrun, factory-set minimum threshold exceeded", E::None},
    {0x5000, 1, 0, "Hard", "device hardware fault, position value 0x7FFFFFFC", E::PositionError},
    {0x5000, 0, 0, "Info", "life guarding error", E::None},
    {0x5000, 0, 1, "Info", "maintenance required (operating time limit)", E::None},
    {0x5000, 1, 2, "Hard", "hardware ASIC fault, position value 0x7FFFFFFC", E::PositionError},
    {0x5000, 2, 0, "Hard", "memory lost", E::PositionError},
    {0x5051, 0, 0, "Info", "valid position", E::ClearPosition},
    {0x5051, 1, 0, "Error", "measurement error, position value 0x7FFFFFFC", E::PositionError},
    {0x5051, 1, 1, "Error", "position overflow error \"Out of range (+)\", position value 0x7FFFFFF8, reset via 2100h",
     E::PositionError},
    {0x5051, 1, 2, "Error", "position underflow error \"Out of range (-)\", position value 0x80000008, reset via 2100h",
     E::PositionError},
    {0x5051, 2, 1, "Warn", "position overflow warning, position value 0x7FFFFFF8", E::PositionWarning},
    {0x5051, 2, 2, "Warn", "position underflow warning, position value 0x80000008", E::PositionWarning},
    {0x6000, 1, 0, "Hard", "device software fault, position value 0x7FFFFFFC", E::PositionError},
    {0x6000, 2, 0, "Hard", "insufficient event timer value for the CAN bit rate, TPDO1 sent partially", E::None},
    {0x8110, 1, 0, "Hard", "CAN controller overflow (CAN overrun), data lost", E::None},
    {0x8110, 2, 0, "Hard", "CAN buffer overflow, data lost", E::None},
    {0x8120, 0, 0, "Hard", "CAN error passive", E::None},
    {0x8140, 0, 0, "Hard", "CAN recovered from bus-off", E::None},
    {0x9080, 1, 0, "Warn", "encoder CAM state changed", E::Cams},
    {0x9090, 1, 0, "Warn", "work area state changed", E::WorkArea},
};

}  // namespace

const EmcyEntry* find_emcy(std::uint16_t code, std::uint8_t error_register, std::uint8_t byte3) {
  for (const EmcyEntry& e : kTable)
    if (e.code == code && e.error_register == error_register && e.byte3 == byte3) return &e;
  // A stack that ORs other 1001h bits into byte 2: match code and byte 3; among several
  // candidates (5000h/x/0) the first one that faults the position wins (safe side).
  const EmcyEntry* found = nullptr;
  for (const EmcyEntry& e : kTable) {
    if (e.code != code || e.byte3 != byte3) continue;
    if (found == nullptr || (found->effect != E::PositionError && e.effect == E::PositionError)) found = &e;
  }
  return found;
}

}  // namespace novotechnik

namespace {

constexpr std::int64_t kInt32Min = std::numeric_limits<std::int32_t>::min();
constexpr std::int64_t kInt32Max = std::numeric_limits<std::int32_t>::max();
constexpr std::int64_t kInt16Min = std::numeric_limits<std::int16_t>::min();
constexpr std::int64_t kInt16Max = std::numeric_limits<std::int16_t>::max();

std::vector<std::uint8_t> le(std::uint64_t v, std::size_t n) {
  std::vector<std::uint8_t> out(n);
  for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<std::uint8_t>(v >> (8 * i));
  return out;
}

}  // namespace

Novotechnik406Driver::Novotechnik406Driver(NodeId node, FrameSink sink, Novotechnik406Options options)
    : options_(options),
      signals_{
          {"position", SignalKind::Position, kInt32Min, kInt32Max, 0, "counts"},
          {"speed", SignalKind::Speed, kInt16Min, kInt16Max, 0, "0.1 deg/s"},
          {"cams", SignalKind::Digital, 0, 15, 0, "bits"},
          {"work_area", SignalKind::Digital, 0, 7, 0, "bits"},
      } {
  init(node, std::move(sink), signals_.size());
  // TPDO1 carries position, speed, CAM and work-area state (configuration()), every
  // event_timer_ms in type 254 (§8.2); in type 255 at least as often; SYNC types (1..240) have no
  // event-timer deadline.
  set_carriers({Carrier{.cob_id = canopen::cob::kTpdo1 + node.value(),
                        .comm_index = 0x1800,
                        .event_timer_ms = options_.event_timer_ms,
                        .transmission_type = options_.transmission_type,
                        .signals = {kPosition, kSpeed, kCams, kWorkArea},
                        .length = kTpdo1Length}});
}

bool Novotechnik406Driver::is_error_position(std::int32_t position) {
  const auto u = static_cast<std::uint32_t>(position);
  return u >= 0x7FFFFFF0u && u <= 0x8000000Fu;
}

ExpectedIdentity Novotechnik406Driver::expected_identity() const {
  ExpectedIdentity id;
  id.device_type = novotechnik::kDeviceType;
  id.vendor_id = novotechnik::kVendorId;
  id.product_code = options_.product_code;
  return id;
}

std::vector<SdoWrite> Novotechnik406Driver::configuration() const {
  const std::uint32_t cob = 0x180u + node().value();
  std::vector<SdoWrite> w;
  // §8.2 step 1: deactivate TPDO1 (bit 31), keeping bit 30 (no RTR) as the default 40000180h.
  w.push_back({0x1800, 1, le(0xC0000000u | cob, 4), "TPDO1 COB-ID: disable"});
  w.push_back({0x1800, 2, le(options_.transmission_type, 1),
               "TPDO1 transmission type " + std::to_string(options_.transmission_type)});
  // §8.2 note: the event timer must be higher than the inhibit time (except 0).
  w.push_back({0x1800, 3, le(0, 2), "TPDO1 inhibit time 0"});
  w.push_back({0x1800, 5, le(options_.event_timer_ms, 2),
               "TPDO1 event timer " + std::to_string(options_.event_timer_ms) + " ms"});
  // §8.2 steps 2..4: position (6020h:01 as the §4.1 default, 6004h where the sensor has no
  // 6020h), speed, and the §8.2 mappable CAM and work-area states.
  w.push_back({0x1A00, 0, le(0, 1), "TPDO1 mapping: clear"});
  w.push_back(has_6020h_ ? SdoWrite{0x1A00, 1, le(0x60200120u, 4),
                                    "TPDO1 mapping 1: position value channel 1 (6020h:01), 32 bit"}
                         : SdoWrite{0x1A00, 1, le(0x60040020u, 4),
                                    "TPDO1 mapping 1: position value (6004h, the sensor refused 6020h), 32 bit"});
  w.push_back({0x1A00, 2, le(0x60300110u, 4), "TPDO1 mapping 2: speed value channel 1, 16 bit"});
  w.push_back({0x1A00, 3, le(0x63000108u, 4), "TPDO1 mapping 3: CAM state channel 1, 8 bit"});
  w.push_back({0x1A00, 4, le(0x64000108u, 4), "TPDO1 mapping 4: work area state channel 1, 8 bit"});
  w.push_back({0x1A00, 0, le(4, 1), "TPDO1 mapping: 4 entries"});
  // §8.2 step 5: re-activate.
  w.push_back({0x1800, 1, le(0x40000000u | cob, 4), "TPDO1 COB-ID: enable"});
  // §4.1 1029h "Error Behaviour" (0: change to pre-operational, the default; 1: no change of
  // NMT mode; 2: stopped). Sub 2 "internal device error: measurement error (EMCY 5051h/1/0/0)"
  // = 1: the sensor stays operational, sends the EMCY and the marker position 7FFFFFFCh, and the
  // driver reports Error; in pre-operational its TPDO1 would stop and the network manager
  // would see it leave operational, reboot it and report it Offline, losing the error itself.
  // Sub 1 "communication error" = 0, written as the default it is: a sensor that lost the bus
  // stops in pre-operational, and the network manager restarts it once it is back.
  // §4.3 2104h "EMCY behaviour" 0 = all events active: a stored 1..3 would silence the info
  // ("valid position" clears), warnings and errors this driver latches on (Hard errors rise anyway).
  w.push_back({0x2104, 0, le(0, 1), "EMCY behaviour: all events active"});
  w.push_back({0x1029, 1, le(0, 1), "error behaviour on a communication error: pre-operational"});
  w.push_back({0x1029, 2, le(1, 1), "error behaviour on a measurement error: stay operational"});
  // §8.1 TPDO2 (280h + ID) is synchronous by default (1801h:02 = 1): with a downstream SYNC it
  // would send a frame at every SYNC that nobody reads (the gateway uses TPDO1). Disabled (bit 31,
  // keeping bit 30 "no RTR" as the default 40000280h has it).
  w.push_back({0x1801, 1, le(0xC0000280u + node().value(), 4), "TPDO2 COB-ID: disable (unused)"});
  return w;
}

std::vector<std::uint32_t> Novotechnik406Driver::consumed_cob_ids() const { return {0x180u + node().value()}; }

void Novotechnik406Driver::fault_position(TimePoint now) {
  for (const std::size_t i : {kPosition, kSpeed, kCams, kWorkArea})
    update(i, signals_[i].neutral, SignalStatus::Error, now);
}

bool Novotechnik406Driver::on_frame(const CanFrame& frame, TimePoint now) {
  if (frame.extended || frame.rtr || frame.id != 0x180u + node().value()) {
    ++counters_.unknown_cob;
    return false;
  }
  if (frame.dlc != kTpdo1Length) {
    ++counters_.wrong_length;
    return true;
  }
  const auto& d = frame.data;
  const auto raw = static_cast<std::uint32_t>(d[0]) | static_cast<std::uint32_t>(d[1]) << 8 |
                   static_cast<std::uint32_t>(d[2]) << 16 | static_cast<std::uint32_t>(d[3]) << 24;
  const auto position = static_cast<std::int32_t>(raw);
  const auto speed = static_cast<std::int16_t>(static_cast<std::uint16_t>(d[4] | d[5] << 8));
  if (is_error_position(position)) {
    last_marker_ = raw;
    fault_position(now);
    return true;
  }
  last_marker_.reset();
  update(kPosition, position, SignalStatus::Valid, now);
  update(kSpeed, speed, SignalStatus::Valid, now);
  // 6300h:01 bits 0..3 = CAM 1..4 (§4.2: four CAMs); 6400h:01 bits 0..2 (§5.7.1). Other bits set:
  // not the objects' coding, Error.
  const std::uint8_t cams = d[6];
  const std::uint8_t area = d[7];
  update(kCams, cams > 0x0F ? 0 : cams, cams > 0x0F ? SignalStatus::Error : SignalStatus::Valid, now);
  update(kWorkArea, area > 0x07 ? 0 : area, area > 0x07 ? SignalStatus::Error : SignalStatus::Valid, now);
  return true;
}

DecodedEmcy Novotechnik406Driver::on_emcy(const EmcyMessage& emcy, TimePoint now) {
  DecodedEmcy out;
  out.code = emcy.code;
  const std::uint8_t byte3 = emcy.msef[0];
  const novotechnik::EmcyEntry* e = novotechnik::find_emcy(emcy.code, emcy.error_register, byte3);
  char head[64];
  std::snprintf(head, sizeof head, "novotechnik %04Xh/%u/%u", emcy.code, emcy.error_register, byte3);
  if (e == nullptr) {
    ++counters_.unknown_emcy;
    out.error = false;
    out.text = std::string(head) + ": unknown EMCY (ignored)";
    return out;
  }
  out.text = std::string(head) + " (" + e->level + "): " + e->text;
  out.error = false;
  switch (e->effect) {
    case novotechnik::EmcyEffect::None: break;
    case novotechnik::EmcyEffect::PositionError: {
      out.error = true;
      out.affected = {kPosition, kSpeed, kCams, kWorkArea};
      const std::uint8_t latch = latch_of(emcy.code);
      set_latches(latch, latch, now);
      break;
    }
    case novotechnik::EmcyEffect::PositionWarning:
      // The marker comes in TPDO1 as long as the warning lasts (§9.1): Error now, but no latch
      // (Driver::faulted): the next ordinary position ends it.
      out.error = true;
      out.affected = {kPosition, kSpeed, kCams, kWorkArea};
      fault_position(now);
      break;
    case novotechnik::EmcyEffect::Clear:
    case novotechnik::EmcyEffect::ClearPosition: {
      const bool all = e->effect == novotechnik::EmcyEffect::Clear;
      set_latches(all ? 0xFF : kLatchPosition, 0, std::nullopt);
      if (latches_ != 0) {
        out.text += (latches_ & kLatchSupply) != 0 ? " (the supply voltage fault stays until 0000h)"
                                                   : " (the device fault stays until 0000h)";
        break;
      }
      // The error is gone; the value itself comes with the next TPDO1. Until then the signals
      // keep the neutral value but are no longer in Error (NotAvailable: nothing vouched for).
      for (const std::size_t i : {kPosition, kSpeed, kCams, kWorkArea})
        if (value(i).status == SignalStatus::Error) update(i, signals_[i].neutral, SignalStatus::NotAvailable, now);
      break;
    }
    case novotechnik::EmcyEffect::Cams: {
      // Byte 4: changed CAM bits, byte 7: CAM state bits. Text only: `cams` comes in TPDO1.
      char tail[48];
      std::snprintf(tail, sizeof tail, ", changed 0x%X, state 0x%X", emcy.msef[1], emcy.msef[4]);
      out.text += tail;
      break;
    }
    case novotechnik::EmcyEffect::WorkArea: {
      // Byte 7: "coded according to 0x6400" or 0 valid / 1 underflow / 2 overflow (§9.1 gives
      // both). Text only: `work_area` comes in TPDO1 as 6400h:01 itself.
      char tail[40];
      std::snprintf(tail, sizeof tail, ", byte 7 = %02Xh", emcy.msef[4]);
      out.text += tail;
      break;
    }
  }
  return out;
}

std::uint8_t Novotechnik406Driver::latch_of(std::uint16_t code) {
  switch (code) {
    case 0x5051: return kLatchPosition;
    case 0x3100: return kLatchSupply;
    default: return kLatchDevice;  // 1000h, 5000h, 6000h
  }
}

void Novotechnik406Driver::set_latches(std::uint8_t mask, std::uint8_t set, std::optional<TimePoint> now) {
  latches_ = static_cast<std::uint8_t>((latches_ & ~mask) | (set & mask));
  for (const std::size_t i : kLatchFollowers) {
    if (latched(i)) {
      set_fault(i);
    } else {
      clear_fault(i);
    }
  }
  if (latches_ != 0 && now) fault_position(*now);
}

bool Novotechnik406Driver::latched(std::size_t i) const {
  return latches_ != 0 && std::find(kLatchFollowers.begin(), kLatchFollowers.end(), i) != kLatchFollowers.end();
}

std::vector<std::pair<std::uint16_t, std::uint8_t>> Novotechnik406Driver::boot_reads() const {
  std::vector<std::pair<std::uint16_t, std::uint8_t>> reads;
  if ((reads_done_ & kReadAlarms) == 0) reads.emplace_back(0x6503, 0);
  if ((reads_done_ & kReadWarnings) == 0) reads.emplace_back(0x6505, 0);
  return reads;
}

std::optional<SdoWrite> Novotechnik406Driver::instead_of_refused(const SdoWrite& write,
                                                                 canopen::SdoAbortCode /*code*/) {
  if (write.index != 0x1A00 || write.sub != 1 || !has_6020h_) return std::nullopt;
  // §4.1's default entry names 6020h:01, which §4.2's object list lacks: a sensor without it maps
  // 6004h "Position value channel 1" (§8.2's mappable objects). Kept for the later boots.
  has_6020h_ = false;
  return SdoWrite{0x1A00, 1, le(0x60040020u, 4),
                  "TPDO1 mapping 1: position value (6004h, the sensor refused 6020h), 32 bit"};
}

bool Novotechnik406Driver::on_boot_read(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                                        std::string& /*error*/) {
  if ((index != 0x6503 && index != 0x6505) || sub != 0) return true;
  reads_done_ |= index == 0x6503 ? kReadAlarms : kReadWarnings;
  if (data.size() != 2) return true;  // both are UNSIGNED16: another length is no evidence, the faults stay
  const auto bits = static_cast<std::uint16_t>(data[0] | (data[1] << 8));
  const auto has = [bits](unsigned mask) { return (bits & mask) != 0 ? 0xFF : 0; };
  if (index == 0x6503) {
    // §10.2: bit 0 measurement error, bit 12 underflow, bit 13 overflow error (latched until
    // 2100h); bit 1 unknown / hardware / ASIC / software fault / memory lost. A bit clear: the
    // fault latched before is over (a sensor that rebooted, or reset while the gateway did not see it).
    const std::uint8_t position = kLatchPosition & has((1u << 0) | (1u << 12) | (1u << 13));
    const std::uint8_t device = kLatchDevice & has(1u << 1);
    set_latches(kLatchPosition | kLatchDevice, position | device, std::nullopt);
  } else {
    set_latches(kLatchSupply, kLatchSupply & has(1u << 4), std::nullopt);  // §10.3 bit 4 supply voltage fault
  }
  return true;
}

bool Novotechnik406Driver::on_boot_read_abort(std::uint16_t index, std::uint8_t /*sub*/,
                                              canopen::SdoAbortCode /*code*/) {
  // No evidence either way: the faults stay.
  if (index == 0x6503) reads_done_ |= kReadAlarms;
  if (index == 0x6505) reads_done_ |= kReadWarnings;
  return index == 0x6503 || index == 0x6505;
}

std::vector<SdoWrite> Novotechnik406Driver::command(std::string_view name) const {
  if (name != "position_error_reset") return {};
  // §4.1 2100h "Position Error Reset", Bool, W, value 0x01.
  return {SdoWrite{0x2100, 0, {0x01}, "position error reset (2100h = 1)"}};
}

const std::vector<OptionSpec>& novotechnik_406_options() {
  using T = OptionSpec::Type;
  static const std::vector<OptionSpec> table = {
      {.name = "event_timer_ms",
       .type = T::Integer,
       .ranges = {{1, 65535}},
       .unit = "ms",
       .default_value = "10",
       .note = "(0: section 8.2 says TPDO1 is then never sent in type 254)",
       .description = "TPDO1 event timer written at boot (1800h:05); position and speed missing for 3 periods "
                      "are Stale"},
      {.name = "transmission_type",
       .type = T::Integer,
       .ranges = {{1, 240}, {254, 254}, {255, 255}},
       .default_value = "254",
       .description = "TPDO1 transmission type written at boot (1800h:02): 254 event timer, 255 measurement "
                      "cycle (1 ms), 1..240 every n-th SYNC (the SYNC period then sets the deadline)"},
      {.name = "product_code",
       .type = T::Text,
       .syntax = "0x0BD5, 0x0BB9, 0x0BBC, 0x0BC5 or 0x0BE0",
       .description = "1018h:02 checked at boot: 0x0BD5 MZ1-2200, 0x0BB9 MC1-2800, 0x0BBC MB1-3600 (section 4.1; "
                      "0x0BC5, 0x0BE0 from the LSS example); unset: only the vendor-ID 0182h is checked"},
      freshness_floor_option("200"),
  };
  return table;
}

std::unique_ptr<Driver> make_novotechnik_406_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                                    OptionRefusals& refusals) {
  Novotechnik406Options o;
  const bool ok = parse_options(
      "novotechnik-406", novotechnik_406_options(), options,
      [&o](const OptionValue& v, std::string& err) {
        const std::string_view name = v.spec->name;
        if (name == "event_timer_ms") o.event_timer_ms = static_cast<std::uint16_t>(v.number);
        if (name == "transmission_type") o.transmission_type = static_cast<std::uint8_t>(v.number);
        if (name == "product_code") {
          const auto p = parse_option_integer(v.text);
          bool known = false;
          for (const std::uint32_t c : novotechnik::kProductCodes) known = known || (p && *p == c);
          if (!known) {
            err = "novotechnik-406: product_code must be one of " + std::string(v.spec->syntax) + " (got '" + v.text +
                  "')";
            return false;
          }
          o.product_code = static_cast<std::uint32_t>(*p);
        }
        if (name == kFreshnessFloorOption) o.freshness_floor_ms = static_cast<std::uint32_t>(v.number);
        return true;
      },
      refusals);
  if (!ok) return nullptr;
  if (node.value() < 1 || node.value() > 127) {
    refusals.push_back({"", "novotechnik-406: node-ID must be 1..127"});
    return nullptr;
  }
  auto d = std::make_unique<Novotechnik406Driver>(node, std::move(sink), o);
  apply_freshness_floor(*d, o.freshness_floor_ms);
  return d;
}

std::unique_ptr<Driver> make_novotechnik_406_driver(NodeId node, FrameSink sink, const DriverOptions& options,
                                                    std::string& error) {
  return with_error_text(error, [&](OptionRefusals& refusals) {
    return make_novotechnik_406_driver(node, std::move(sink), options, refusals);
  });
}

// The last position marker (last_error_position()), this boot's reads of 6503h/6505h, the latches
// only their evidence clears, and whether the sensor took 6020h into its TPDO (the next boot's
// configuration()).
void Novotechnik406Driver::export_family_state(canopen::StateWriter& w) const {
  w.put("last_marker", last_marker_);
  w.put("reads_done", reads_done_);
  w.put("latches", latches_);
  w.put("has_6020h", has_6020h_);
}

void Novotechnik406Driver::import_family_state(const canopen::StateReader& r) {
  last_marker_ = r.optional<std::uint32_t>("last_marker");
  has_6020h_ = r.get<bool>("has_6020h");
  reads_done_ = r.get<std::uint8_t>("reads_done");
  const auto latches = r.get<std::uint8_t>("latches");
  if ((latches & ~(kLatchPosition | kLatchDevice | kLatchSupply)) != 0) r.fail("latches", "names no latch");
  latches_ = latches;
  for (std::size_t i = 0; i < signals_.size(); ++i) {
    if (faulted(i) != latched(i)) r.fail("latches", "differs from signal " + std::to_string(i) + "'s fault");
  }
}

}  // namespace oegw::subdevices
