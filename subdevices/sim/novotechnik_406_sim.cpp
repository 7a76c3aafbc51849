#include "subdevices/sim/novotechnik_406_sim.hpp"

#include <algorithm>
#include <fstream>
#include <memory>
#include <sstream>

#include "canopen/301/storage.hpp"
#include "canopen/305/lss_store.hpp"

#include "canopen/301/pdo.hpp"

namespace oegw::subdevices::sim {

using canopen::Access;
using canopen::DataType;
using canopen::encode;
using canopen::NmtState;
using canopen::ObjectDictionary;
using canopen::Origin;
using canopen::SdoAbortCode;

namespace {

constexpr std::uint32_t kPosMarkerFault = 0x7FFFFFFC;
constexpr std::uint32_t kPosMarkerOverflow = 0x7FFFFFF8;
constexpr std::uint32_t kPosMarkerUnderflow = 0x80000008;
constexpr std::uint32_t kTotalRange = 0x002C0000;   // 6002h default
constexpr std::uint32_t kStepsPerRev = 0x00010000;  // 6001h default
constexpr std::uint16_t kRevolutions = 0x002C;      // 6502h

std::uint32_t u32(std::span<const std::uint8_t> b) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < b.size() && i < 4; ++i) v |= static_cast<std::uint32_t>(b[i]) << (8 * i);
  return v;
}

void set_raw(ObjectDictionary& od, std::uint16_t index, std::uint8_t sub, std::uint64_t v) {
  if (canopen::SubObject* s = od.find(index, sub))
    for (std::size_t i = 0; i < s->value.size(); ++i) s->value[i] = static_cast<std::uint8_t>(v >> (8 * i));
}

int level_rank(std::string_view level) {
  if (level == "Info") return 1;
  if (level == "Warn") return 2;
  if (level == "Error") return 3;
  return 4;  // Hard: "Hard errors rises always"
}

}  // namespace

Novotechnik406Sim::Novotechnik406Sim(FrameSink sink, Novotechnik406SimConfig config)
    : SimulatedDevice(std::move(sink)), cfg_(std::move(config)) {
  auto od = std::make_unique<ObjectDictionary>();
  build_od(*od);
  canopen::NodeConfig nc;
  nc.node_id = cfg_.node_id;
  nc.device_type = 0x00020196;  // §4.1 1000h
  nc.device_name = "MC1-2832-A7F-614-511";
  nc.hardware_version = "400000000.00";
  nc.software_version = "V 1.03.0";
  nc.identity = {.vendor = 0x00000182, .product = cfg_.product_code, .revision = cfg_.revision, .serial = cfg_.serial};
  nc.heartbeat_ms = cfg_.heartbeat_ms;
  switch (cfg_.bit_rate_kbit) {  // CiA 305 table 0, as §6.2 lists it
    case 1000: nc.bit_timing_index = 0; break;
    case 800: nc.bit_timing_index = 1; break;
    case 500: nc.bit_timing_index = 2; break;
    case 125: nc.bit_timing_index = 4; break;
    case 50: nc.bit_timing_index = 6; break;
    default: nc.bit_timing_index = 3; break;
  }
  nc.store_path = cfg_.store_path;
  build(std::move(od), nc);
  // §4.1 1029h:02 "internal device error: measurement error", beside the core's sub 1.
  if (canopen::Object* o = this->od().find(0x1029)) {
    canopen::SubObject s;
    s.sub_index = 2;
    s.name = "Internal device error";
    s.type = DataType::Unsigned8;
    s.access = Access::ReadWrite;
    s.value = s.default_value = {0};
    s.high = std::uint64_t{2};
    o->add_sub(std::move(s));
    if (canopen::SubObject* s0 = o->find(0)) s0->value = s0->default_value = {2};
  }
  // §4.1 "1001 Error register Unsigned16": the corner error_register_size=2 replaces the core's
  // UNSIGNED8 (the EMCY producer writes it width-aware, little endian: the CiA 301 bits low).
  if (cfg_.error_register_bytes == 2) {
    (void)this->od().remove(0x1001);
    this->od().add_var(0x1001, "Error register", DataType::Unsigned16, Access::ReadOnly, encode<std::uint16_t>(0));
  }
  install_hooks();
  install_startup_rule();
}

void Novotechnik406Sim::build_od(ObjectDictionary& od) {
  const auto id = cfg_.node_id.value();
  // §4.1 communication objects the Node does not add itself.
  od.add_var(0x1002, "Manufacturer status register", DataType::Unsigned32, Access::ReadOnly, encode<std::uint32_t>(0));
  od.add_var(0x100C, "Guard time", DataType::Unsigned16, Access::ReadWrite, encode<std::uint16_t>(0));
  od.add_var(0x100D, "Life time factor", DataType::Unsigned8, Access::ReadWrite, {0});
  // 1010h subs 1..5 / 1011h subs 1..4 (the ParameterStore adds its hooks to these).
  od.add_array(0x1010, "Store parameter field", DataType::Unsigned32, Access::ReadWrite, 5, encode<std::uint32_t>(1));
  od.add_array(0x1011, "Restore default parameters", DataType::Unsigned32, Access::ReadWrite, 4,
               encode<std::uint32_t>(1));
  od.add_var(0x1F80, "NMT startup", DataType::Unsigned32, Access::ReadWrite, encode<std::uint32_t>(0));

  // §4.3 manufacturer specific.
  od.add_var(0x2000, "Node-ID", DataType::Unsigned8, Access::ReadWrite, {id});
  od.find(0x2000, 0)->low = std::uint64_t{1};
  od.find(0x2000, 0)->high = std::uint64_t{127};
  od.add_var(0x2001, "CAN bit rate", DataType::Unsigned16, Access::ReadWrite,
             encode<std::uint16_t>(cfg_.bit_rate_kbit));
  od.add_var(0x2002, "Temperature", DataType::Integer16, Access::ReadOnly, encode<std::int16_t>(350), true);
  od.add_var(0x2003, "Supply voltage", DataType::Unsigned16, Access::ReadOnly, encode<std::uint16_t>(240), true);
  od.add_array(0x2010, "Filter position and speed", DataType::Unsigned8, Access::ReadWrite, 2, {0});
  od.find(0x2010, 1)->high = std::uint64_t{7};
  od.find(0x2010, 2)->value = od.find(0x2010, 2)->default_value = {3};
  od.find(0x2010, 2)->high = std::uint64_t{8};
  od.add_var(0x2100, "Position error reset", DataType::Boolean, Access::WriteOnly, {0});
  od.add_var(0x2101, "Power management", DataType::Boolean, Access::WriteOnly, {0});
  od.add_var(0x2104, "EMCY behaviour", DataType::Unsigned8, Access::ReadWrite, {cfg_.emcy_behaviour});
  od.find(0x2104, 0)->high = std::uint64_t{3};

  // §4.2 device profile.
  od.add_var(0x6000, "Operating parameter", DataType::Unsigned8, Access::ReadWrite, {0});
  od.find(0x6000, 0)->high = std::uint64_t{7};
  od.add_var(0x6001, "Measuring units per revolution", DataType::Unsigned32, Access::ReadWrite,
             encode<std::uint32_t>(kStepsPerRev));
  od.find(0x6001, 0)->low = std::uint64_t{1};
  od.find(0x6001, 0)->high = std::uint64_t{kStepsPerRev};  // §5.4: can only be reduced
  od.add_var(0x6002, "Total measuring range", DataType::Unsigned32, Access::ReadWrite,
             encode<std::uint32_t>(kTotalRange));
  od.find(0x6002, 0)->low = std::uint64_t{1};
  od.find(0x6002, 0)->high = std::uint64_t{kTotalRange};  // §5.5
  od.add_var(0x6003, "Preset value", DataType::Unsigned32, Access::ReadWrite, encode<std::uint32_t>(0));
  od.add_var(0x6004, "Position value", DataType::Integer32, Access::ReadOnly, encode<std::int32_t>(0), true);
  od.add_var(0x600C, "Position raw value", DataType::Unsigned32, Access::ReadOnly, encode<std::uint32_t>(0), true);
  if (cfg_.has_6020h)
    od.add_array(0x6020, "Position value channel", DataType::Integer32, Access::ReadOnly, 1, encode<std::int32_t>(0),
                 true);
  od.add_array(0x6030, "Speed value", DataType::Integer16, Access::ReadOnly, 1, encode<std::int16_t>(0), true);
  od.add_array(0x6031, "Speed parameter", DataType::Unsigned8, Access::ReadWrite, 1, {2});
  od.add_record_member(0x6031, 2, "Speed integration time", DataType::Unsigned16, Access::ReadWrite,
                       encode<std::uint16_t>(1));
  if (canopen::SubObject* s0 = od.find(0x6031, 0)) s0->value = s0->default_value = {2};
  od.add_array(0x6300, "CAM state register", DataType::Unsigned8, Access::ReadOnly, 1, {0}, true);
  od.add_array(0x6301, "CAM enable", DataType::Unsigned8, Access::ReadWrite, 1, {0});
  od.add_array(0x6302, "CAM polarity", DataType::Unsigned8, Access::ReadWrite, 1, {0});
  for (std::uint16_t i = 0; i < 4; ++i) {
    od.add_array(static_cast<std::uint16_t>(0x6310 + i), "CAM low limit", DataType::Integer32, Access::ReadWrite, 1,
                 encode<std::int32_t>(0));
    od.add_array(static_cast<std::uint16_t>(0x6320 + i), "CAM high limit", DataType::Integer32, Access::ReadWrite, 1,
                 encode<std::int32_t>(0x002BFFFF));
    od.add_array(static_cast<std::uint16_t>(0x6330 + i), "CAM hysteresis", DataType::Unsigned16, Access::ReadWrite, 1,
                 encode<std::uint16_t>(0));
  }
  od.add_array(0x6400, "Work area state", DataType::Unsigned8, Access::ReadOnly, 1, {0}, true);
  od.add_array(0x6401, "Work area low limit", DataType::Integer32, Access::ReadWrite, 1, encode<std::int32_t>(0));
  od.add_array(0x6402, "Work area high limit", DataType::Integer32, Access::ReadWrite, 1,
               encode<std::int32_t>(0x002BFFFF));
  od.add_var(0x6500, "Operating status", DataType::Unsigned16, Access::ReadOnly, encode<std::uint16_t>(0));
  od.add_var(0x6501, "Singleturn resolution", DataType::Unsigned32, Access::ReadOnly,
             encode<std::uint32_t>(kStepsPerRev));
  od.add_var(0x6502, "Number of distinguishable revolutions", DataType::Unsigned16, Access::ReadOnly,
             encode<std::uint16_t>(kRevolutions));
  od.add_var(0x6503, "Alarms", DataType::Unsigned16, Access::ReadOnly, encode<std::uint16_t>(0), true);
  od.add_var(0x6504, "Supported alarms", DataType::Unsigned16, Access::ReadOnly, encode<std::uint16_t>(0xC002));
  od.add_var(0x6505, "Warnings", DataType::Unsigned16, Access::ReadOnly, encode<std::uint16_t>(0), true);
  od.add_var(0x6506, "Supported warnings", DataType::Unsigned16, Access::ReadOnly, encode<std::uint16_t>(0xC05C));
  od.add_var(0x6507, "Profile and software version", DataType::Unsigned32, Access::ReadOnly,
             encode<std::uint32_t>(0x01020302));
  od.add_var(0x6508, "Operating time", DataType::Unsigned32, Access::ReadOnly, encode<std::uint32_t>(0));
  od.add_var(0x6509, "Offset value", DataType::Integer32, Access::ReadOnly, encode<std::int32_t>(0));
  od.add_record(0x650A, "Module identification");
  od.add_record_member(0x650A, 1, "Manufacturer offset value", DataType::Integer32, Access::ReadOnly,
                       encode<std::int32_t>(0));
  od.add_record_member(0x650A, 2, "Manufacturer min position value", DataType::Integer32, Access::ReadOnly,
                       encode<std::int32_t>(0));
  od.add_record_member(0x650A, 3, "Manufacturer max position value", DataType::Integer32, Access::ReadOnly,
                       encode<std::int32_t>(0x002BFFFF));
  od.add_var(0x650B, "Serial number", DataType::Unsigned32, Access::ReadOnly, encode<std::uint32_t>(cfg_.serial));
  od.add_var(0x650D, "Absolute accuracy", DataType::Unsigned8, Access::ReadOnly, {0x10});
  od.add_var(0x650E, "Device capability", DataType::Unsigned16, Access::ReadOnly, encode<std::uint16_t>(0x0003));

  // §4.1 TPDOs: default mapping 60200120h (position ch. 1) + 60300110h (speed ch. 1); without
  // 6020h (§4.2's list has none) the position object 6004h, 32 bit.
  const std::vector<std::uint32_t> mapping = {cfg_.has_6020h ? 0x60200120u : 0x60040020u, 0x60300110};
  canopen::install_tpdo(od, 1,
                        canopen::PdoParameters{.cob_id = 0x40000000u | (0x180u + id),
                                               .transmission_type = 0xFE,
                                               .inhibit_time = 0,
                                               .event_timer = 0,
                                               .sync_start = 0,
                                               .mapping = mapping,
                                               .mapping_capacity = 5});
  canopen::install_tpdo(od, 2,
                        canopen::PdoParameters{.cob_id = 0x40000000u | (0x280u + id),
                                               .transmission_type = 0x01,
                                               .inhibit_time = 0,
                                               .event_timer = 0,
                                               .sync_start = 0,
                                               .mapping = mapping,
                                               .mapping_capacity = 5});
}

void Novotechnik406Sim::install_hooks() {
  ObjectDictionary& d = od();
  // §5.4/§5.5: writing 6001h/6002h only with scaling on (6000h bit 2 = 0); each updates the other.
  for (const std::uint16_t index : {std::uint16_t{0x6001}, std::uint16_t{0x6002}}) {
    subs_ += d.find(index)->add_write_hook(
        [this, index](canopen::Object&, std::uint8_t, std::span<const std::uint8_t> b, Origin origin) {
          if (origin != Origin::Sdo) return SdoAbortCode::None;
          if ((od().get<std::uint8_t>(0x6000, 0) & 0x04) != 0) return SdoAbortCode::CannotTransferDeviceState;
          const std::uint32_t v = u32(b);
          if (index == 0x6001) {
            set_raw(od(), 0x6002, 0, static_cast<std::uint64_t>(v) * kRevolutions);
            set_raw(od(), 0x6501, 0, v);
          } else {
            const std::uint32_t per_rev = v / kRevolutions;
            if (per_rev == 0) return SdoAbortCode::InvalidValue;
            set_raw(od(), 0x6001, 0, per_rev);
            set_raw(od(), 0x6501, 0, per_rev);
          }
          return SdoAbortCode::None;
        });
  }
  // §4.2 6031h:02: "The following values are allowed: 1, 2, 3, 6, 12, 25 ms"; §5.2 couples it
  // with 2010h:02.
  subs_ += d.find(0x6031)->add_write_hook(
      [this](canopen::Object&, std::uint8_t sub, std::span<const std::uint8_t> b, Origin) {
        if (sub != 2) return SdoAbortCode::None;
        static constexpr std::pair<std::uint16_t, std::uint8_t> kTable[] = {{1, 3}, {2, 4},  {3, 5},
                                                                            {6, 6}, {12, 7}, {25, 8}};
        const auto v = static_cast<std::uint16_t>(u32(b));
        for (const auto& [ms, filter] : kTable)
          if (ms == v) {
            set_raw(od(), 0x2010, 2, filter);
            return SdoAbortCode::None;
          }
        return SdoAbortCode::InvalidValue;
      });
  subs_ += d.find(0x2010)->add_write_hook(
      [this](canopen::Object&, std::uint8_t sub, std::span<const std::uint8_t> b, Origin) {
        if (sub != 2 || b.empty()) return SdoAbortCode::None;
        static constexpr std::uint16_t kMs[] = {0, 0, 1, 1, 2, 3, 6, 12, 25};  // §5.2, filter 0..8
        if (b[0] < std::size(kMs)) set_raw(od(), 0x6031, 2, kMs[b[0]]);
        return SdoAbortCode::None;
      });
  // §4.3 2000h: the new node-ID becomes effective after a communication restart (§7.1).
  subs_ += d.find(0x2000)->add_write_hook(
      [this](canopen::Object&, std::uint8_t, std::span<const std::uint8_t> b, Origin origin) {
        if (origin == Origin::Sdo && !b.empty()) node().nmt().set_pending_node_id(NodeId{b[0]});
        return SdoAbortCode::None;
      });
  subs_ += d.find(0x2001)->add_write_hook([](canopen::Object&, std::uint8_t, std::span<const std::uint8_t> b, Origin) {
    switch (u32(b)) {
      case 50:
      case 125:
      case 250:
      case 500:
      case 800:
      case 1000: return SdoAbortCode::None;
      default: return SdoAbortCode::InvalidValue;
    }
  });
  // §4.3 2100h position error reset: clears "Out of range (+/-)" once the sensor is back in range.
  subs_ +=
      d.find(0x2100)->add_write_hook([this](canopen::Object&, std::uint8_t, std::span<const std::uint8_t>, Origin) {
        if (fault_ == Fault::Overflow || fault_ == Fault::Underflow) {
          const auto lo = od().get<std::int32_t>(0x650A, 2);
          const auto hi = od().get<std::int32_t>(0x650A, 3);
          if (position_ > lo && position_ < hi) {
            fault_ = Fault::Measurement;  // lets clear_fault() run the common path
            (void)clear_fault(now_);      // "an EMCY with 0x0000 (valid position) is sent"
          }
        }
        return SdoAbortCode::None;
      });
}

void Novotechnik406Sim::apply_startup(TimePoint now) {
  now_ = now;
  // §4.1 1F80h: "Bit 3 set: sensor starts in operational mode".
  if ((od().get<std::uint32_t>(0x1F80, 0) & 0x08) != 0) node().nmt().enter(NmtState::Operational, now);
  publish(now);
}

void Novotechnik406Sim::start(TimePoint now) {
  SimulatedDevice::start(now);
  apply_startup(now);
}

void Novotechnik406Sim::reboot(TimePoint now) {
  fault_.reset();
  forced_raw_.reset();
  SimulatedDevice::reboot(now);
  apply_startup(now);
}

void Novotechnik406Sim::publish(TimePoint now) {
  ObjectDictionary& d = od();
  std::uint32_t raw = static_cast<std::uint32_t>(position_);
  std::int16_t speed = speed_;
  if (forced_raw_) {
    raw = *forced_raw_;
    speed = 0;  // §9: "speed value is set to 0x0000"
  }
  // Direct assignment: no "change" event, so type 254 keeps to its event timer.
  set_raw(d, 0x6004, 0, raw);
  set_raw(d, 0x6020, 1, raw);  // nothing when the corner has no 6020h
  set_raw(d, 0x600C, 0, raw);
  set_raw(d, 0x6030, 1, static_cast<std::uint16_t>(speed));
  if (canopen::Tpdo* t = node().pdo().tpdo(1); t != nullptr && t->transmission_type() == 0xFF && t->active())
    t->request(now);
}

void Novotechnik406Sim::set_position(std::int32_t position, TimePoint now) {
  now_ = now;
  position_ = position;
  update_cams_and_work_area(now);
  publish(now);
}

void Novotechnik406Sim::set_speed(std::int16_t speed, TimePoint now) {
  now_ = now;
  speed_ = speed;
  publish(now);
}

void Novotechnik406Sim::inject_error_position(std::uint32_t raw, TimePoint now) {
  now_ = now;
  forced_raw_ = raw;
  publish(now);
}

void Novotechnik406Sim::set_bits(std::uint16_t index, std::uint32_t mask, bool on) {
  const std::uint32_t v = od().get<std::uint32_t>(index, 0);
  set_raw(od(), index, 0, on ? (v | mask) : (v & ~mask));
}

void Novotechnik406Sim::inject_fault(Fault fault, TimePoint now) {
  now_ = now;
  struct Row {
    std::uint16_t code;
    std::uint8_t reg, b3;
    std::uint32_t marker;
    std::uint16_t alarm, warning;
    std::uint32_t status;  // 1002h bit (§10.1)
    const char* level;
  };
  static constexpr Row kRows[] = {
      {0x5051, 1, 0, kPosMarkerFault, 1u << 0, 0, 1u << 22, "Error"},       // Measurement
      {0x5051, 1, 1, kPosMarkerOverflow, 1u << 13, 0, 1u << 12, "Error"},   // Overflow
      {0x5051, 1, 2, kPosMarkerUnderflow, 1u << 12, 0, 1u << 13, "Error"},  // Underflow
      {0x5051, 2, 1, kPosMarkerOverflow, 0, 1u << 13, 1u << 20, "Warn"},    // OverflowWarning
      {0x5051, 2, 2, kPosMarkerUnderflow, 0, 1u << 12, 1u << 21, "Warn"},   // UnderflowWarning
      {0x5000, 1, 0, kPosMarkerFault, 1u << 1, 0, 1u << 31, "Hard"},        // HardwareFault
      {0x6000, 1, 0, kPosMarkerFault, 1u << 1, 0, 1u << 27, "Hard"},        // SoftwareFault
  };
  const Row& r = kRows[static_cast<std::size_t>(fault)];
  fault_ = fault;
  forced_raw_ = r.marker;
  set_bits(0x6503, r.alarm, true);
  set_bits(0x6505, r.warning, true);
  set_bits(0x1002, r.status, true);
  set_bits(0x1002, 1u << 26, false);  // "valid position"
  publish(now);
  send_emcy(r.code, r.reg, r.b3, {0, 0, 0, 0}, now, r.level);
  // §4.1 1029h:02 "Internal device error: measurement error (EMCY Index 0x5051 / 1 / 0 / 0)":
  // 0 (default) change to pre-operational, 1 no change of NMT mode, 2 change to stopped.
  if (fault == Fault::Measurement && node().state() == NmtState::Operational) {
    switch (od().get<std::uint8_t>(0x1029, 2)) {
      case 0: node().nmt().enter(NmtState::PreOperational, now); break;
      case 2: node().nmt().enter(NmtState::Stopped, now); break;
      default: break;
    }
  }
}

bool Novotechnik406Sim::clear_fault(TimePoint now) {
  now_ = now;
  if (!fault_) return false;
  if (*fault_ == Fault::Overflow || *fault_ == Fault::Underflow) return false;  // 2100h only
  const bool position_error = *fault_ == Fault::Measurement;                    // also Overflow/Underflow via 2100h
  fault_.reset();
  forced_raw_.reset();
  set_raw(od(), 0x6503, 0, 0);
  set_raw(od(), 0x6505, 0, 0);
  set_raw(od(), 0x1002, 0, 1u << 26);
  publish(now);
  // §9.1: a position error (5051h/1/x) ends with "an EMCY with 0x0000 (valid position)", the
  // table's 5051h/0/0 "Valid position" (error register and byte 3 both 00h); the other faults
  // ("an EMCY with 0x0000 is sent") with 0000h "Sensor Error resetted, no error".
  if (position_error) {
    send_emcy(0x5051, 0, 0, {0, 0, 0, 0}, now, "Hard");
  } else {
    send_emcy(0x0000, 0, 0, {0, 0, 0, 0}, now, "Hard");
  }
  return true;
}

void Novotechnik406Sim::send_emcy(std::uint16_t code, std::uint8_t error_register, std::uint8_t byte3,
                                  std::array<std::uint8_t, 4> bytes4to7, TimePoint now, std::string_view level) {
  now_ = now;
  const NmtState s = node().state();
  if (s != NmtState::PreOperational && s != NmtState::Operational) return;
  const int rank = level_rank(level);
  const int suppress = od().get<std::uint8_t>(0x2104, 0);  // 1: info, 2: +warnings, 3: +errors
  if (rank < 4 && rank <= suppress) return;
  const std::uint32_t cob = od().get<std::uint32_t>(0x1014, 0);
  if ((cob & 0x80000000u) != 0) return;
  set_raw(od(), 0x1001, 0, error_register);
  CanFrame f;
  f.id = cob & 0x7FF;
  f.dlc = 8;
  f.data = {static_cast<std::uint8_t>(code),
            static_cast<std::uint8_t>(code >> 8),
            error_register,
            byte3,
            bytes4to7[0],
            bytes4to7[1],
            bytes4to7[2],
            bytes4to7[3]};
  out()(f);
}

void Novotechnik406Sim::update_cams_and_work_area(TimePoint now) {
  ObjectDictionary& d = od();
  const std::int32_t p = position_;
  // §5.6 CAMs (hysteresis not simulated); "The CAM high limit value can have a lower value than
  // the CAM low limit": then the CAM is active outside [high, low].
  const std::uint8_t enable = d.get<std::uint8_t>(0x6301, 1);
  const std::uint8_t polarity = d.get<std::uint8_t>(0x6302, 1);
  std::uint8_t cams = 0;
  for (std::uint16_t i = 0; i < 4; ++i) {
    if ((enable & (1u << i)) == 0) continue;
    const auto lo = d.get<std::int32_t>(static_cast<std::uint16_t>(0x6310 + i), 1);
    const auto hi = d.get<std::int32_t>(static_cast<std::uint16_t>(0x6320 + i), 1);
    bool active = lo <= hi ? (p >= lo && p <= hi) : (p >= lo || p <= hi);
    if ((polarity & (1u << i)) != 0) active = !active;
    if (active) cams = static_cast<std::uint8_t>(cams | (1u << i));
  }
  const std::uint8_t old_cams = d.get<std::uint8_t>(0x6300, 1);
  if (cams != old_cams) {
    set_raw(d, 0x6300, 1, cams);
    send_emcy(0x9080, 1, 0, {static_cast<std::uint8_t>(cams ^ old_cams), 0, 0, cams}, now, "Warn");
  }
  // §5.7.1 work area state.
  std::uint8_t area = 0;
  if (p < d.get<std::int32_t>(0x6401, 1)) area |= 0x04;
  if (p > d.get<std::int32_t>(0x6402, 1)) area |= 0x02;
  if (p <= d.get<std::int32_t>(0x650A, 2) || p >= d.get<std::int32_t>(0x650A, 3)) area |= 0x01;
  const std::uint8_t old_area = d.get<std::uint8_t>(0x6400, 1);
  if (area != old_area) {
    set_raw(d, 0x6400, 1, area);
    // §9.1 9090h: "State is coded according to 0x6400", or the row's list "0: Valid Work Area,
    // 1: WorkArea underflow, 2: WorkArea overflow" (which has no code for "out of range" alone).
    const std::uint8_t coded = cfg_.work_area_bits  ? area
                               : (area & 0x04) != 0 ? std::uint8_t{1}
                               : (area & 0x02) != 0 ? std::uint8_t{2}
                                                    : std::uint8_t{0};
    send_emcy(0x9090, 1, 0, {0, 0, 0, coded}, now, "Warn");
  }
}

}  // namespace oegw::subdevices::sim

namespace oegw::subdevices::sim {

bool Novotechnik406Sim::set_input(std::string_view signal, std::int64_t value, TimePoint now) {
  if (signal == "position" && value >= INT32_MIN && value <= INT32_MAX) {
    set_position(static_cast<std::int32_t>(value), now);
    return true;
  }
  if (signal == "speed" && value >= INT16_MIN && value <= INT16_MAX) {
    set_speed(static_cast<std::int16_t>(value), now);
    return true;
  }
  return false;
}

}  // namespace oegw::subdevices::sim

namespace oegw::subdevices::sim {

// §8.2 "For changing of mapping, the sensor must be in pre-operational mode", §11 "Data
// encryption to the non-volatile memory is only admitted in the pre-operational status": a
// write of the TPDO mapping 1A00h/1A01h or of 1010h while operational is answered with the §7.3
// abort 0x08000022 "wrong state".
// §4.1 1F80h "Bit 3 set: sensor starts in operational mode": after every boot-up, the power-on
// one (apply_startup) and those after NMT reset node / reset communication, as a CiA 301 node
// leaving initialisation (CiA 302-2 "NMT start-up" of a self-starting device).
void Novotechnik406Sim::install_startup_rule() {
  node().on_state_change = [this](NmtState s) {
    const NmtState before = last_state_;
    last_state_ = s;
    if (s == NmtState::PreOperational && before == NmtState::Initialisation &&
        (od().get<std::uint32_t>(0x1F80, 0) & 0x08) != 0)
      node().nmt().enter(NmtState::Operational, node().nmt().last_transition());
  };
}

canopen::SdoAbortCode Novotechnik406Sim::refuse_download(std::uint16_t index, std::uint8_t /*sub*/,
                                                         NmtState state) const {
  if (state != NmtState::Operational) return SdoAbortCode::None;
  if (index == 0x1A00 || index == 0x1A01 || index == 0x1010) return SdoAbortCode::CannotTransferDeviceState;
  return SdoAbortCode::None;
}

namespace {

using ParameterKey = canopen::ParameterStore::Key;
constexpr std::uint32_t kSave = 0x65766173;  // "save"
constexpr std::uint32_t kLoad = 0x64616F6C;  // "load"
constexpr std::uint32_t kKill = 0x6C6C696B;  // "kill", §11

// §11's table, by column: the objects "save" stores in group 2 (communication) and 3
// (application); group 1 (all) is both; group 4 (user data) is node-ID 2000h and bit rate 2001h.
// COB-ID SYNC (1005h) has a row without any mark: in no group. The condition-monitoring settings
// (230Ah, 233Ah, 235Ah, 236Ah) are not simulated.
bool in_group(std::uint8_t group, std::uint16_t index) {
  static constexpr std::uint16_t kCommunication[] = {0x100C, 0x100D, 0x1017, 0x1029, 0x1800, 0x1801,
                                                     0x1A00, 0x1A01, 0x1F80, 0x2010, 0x2104};
  const bool comm = std::find(std::begin(kCommunication), std::end(kCommunication), index) != std::end(kCommunication);
  const bool app = (index >= 0x6000 && index <= 0x6003) || index == 0x6301 || index == 0x6302 ||
                   (index >= 0x6310 && index <= 0x6333) || index == 0x6401 || index == 0x6402;
  switch (group) {
    case 1: return comm || app;
    case 2: return comm;
    case 3: return app;
    default: return false;
  }
}

}  // namespace

std::optional<canopen::SdoAbortCode> Novotechnik406Sim::handle_download(std::uint16_t index, std::uint8_t sub,
                                                                        std::span<const std::uint8_t> data) {
  if ((index != 0x1010 && index != 0x1011) || sub == 0) return std::nullopt;
  if (data.size() != 4) return SdoAbortCode::CannotTransfer;
  const std::uint32_t v = u32(data);
  if (index == 0x1010 && sub == 5) return v == kSave ? SdoAbortCode::None : SdoAbortCode::CannotTransfer;
  if (sub > 4) return SdoAbortCode::SubIndexDoesNotExist;
  if (index == 0x1010 && v == kSave) return save_group(sub);
  if (index == 0x1010 && v == kKill) return forget_group(sub, true);
  if (index == 0x1011 && v == kLoad) return cfg_.load_restores_defaults ? forget_group(sub, false) : load_group(sub);
  return SdoAbortCode::CannotTransfer;  // §7.3 0800 0020h: a wrong signature
}

canopen::SdoAbortCode Novotechnik406Sim::save_group(std::uint8_t group) {
  if (cfg_.store_path.empty()) return SdoAbortCode::HardwareError;  // §7.3 0606 0000h access error
  std::string error;
  if (group == 4) {
    // §7.1: 2000h / 2001h become effective "after a communication restart or a power up".
    std::uint8_t bt = 3;
    switch (od().get<std::uint16_t>(0x2001, 0)) {
      case 1000: bt = 0; break;
      case 800: bt = 1; break;
      case 500: bt = 2; break;
      case 125: bt = 4; break;
      case 50: bt = 6; break;
      default: break;
    }
    const canopen::LssStored stored{NodeId{od().get<std::uint8_t>(0x2000, 0)}, bt};
    return canopen::write_lss_store(cfg_.store_path, stored, error) ? SdoAbortCode::None : SdoAbortCode::HardwareError;
  }
  canopen::ParameterStore::Entries entries;
  if (std::ifstream in(cfg_.store_path); in) {
    std::ostringstream text;
    text << in.rdbuf();
    if (auto parsed = canopen::ParameterStore::parse(text.str(), error)) entries = std::move(*parsed);
  }
  for (const auto& [index, obj] : od().objects()) {
    if (!in_group(group, index)) continue;
    for (const auto& [si, so] : obj.subs()) {
      // Sub-index 0 of an ARRAY or RECORD is its count; a VAR's value is sub-index 0.
      if ((si == 0 && obj.subs().size() > 1) || !canopen::writable(so.access)) continue;
      // §11: "save all" sets the TPDO COB-IDs to their default values ("D").
      const bool as_default = group == 1 && (index == 0x1800 || index == 0x1801) && si == 1;
      entries[{index, si}] = as_default ? so.default_value : so.value;
    }
  }
  return canopen::write_file_atomically(cfg_.store_path, canopen::ParameterStore::serialize(entries), error)
             ? SdoAbortCode::None
             : SdoAbortCode::HardwareError;
}

canopen::SdoAbortCode Novotechnik406Sim::forget_group(std::uint8_t group, bool defaults_now) {
  if (cfg_.store_path.empty()) return SdoAbortCode::HardwareError;
  std::string error;
  if (group == 4 || group == 1) {
    // User data: the LSS-like store goes (group 1 "all" too: the kill "deletes data in the
    // non-volatile memory"); the factory node-ID and bit rate are "retained" (§11).
    std::error_code ec;
    std::filesystem::remove(canopen::lss_store_path(cfg_.store_path), ec);
    if (group == 4) {
      // The factory node-ID at the next reset (a stored one was made active by the last start).
      node().nmt().set_pending_node_id(cfg_.node_id);
      if (defaults_now) {
        set_raw(od(), 0x2000, 0, cfg_.node_id.value());
        set_raw(od(), 0x2001, 0, cfg_.bit_rate_kbit);
      }
      return SdoAbortCode::None;
    }
  }
  canopen::ParameterStore::Entries entries;
  if (std::ifstream in(cfg_.store_path); in) {
    std::ostringstream text;
    text << in.rdbuf();
    if (auto parsed = canopen::ParameterStore::parse(text.str(), error)) entries = std::move(*parsed);
  }
  std::erase_if(entries, [group](const auto& e) { return in_group(group, e.first.first); });
  if (!canopen::write_file_atomically(cfg_.store_path, canopen::ParameterStore::serialize(entries), error))
    return SdoAbortCode::HardwareError;
  if (defaults_now) {
    std::vector<std::pair<ParameterKey, std::vector<std::uint8_t>>> back;
    for (const auto& [index, obj] : od().objects()) {
      if (!in_group(group, index)) continue;
      for (const auto& [si, so] : obj.subs())
        if ((si != 0 || obj.subs().size() == 1) && canopen::writable(so.access) && so.value != so.default_value)
          back.push_back({{index, si}, so.default_value});
    }
    for (const auto& [key, value] : back) (void)od().write(key.first, key.second, value, Origin::Local);
  }
  return SdoAbortCode::None;
}

canopen::SdoAbortCode Novotechnik406Sim::load_group(std::uint8_t group) {
  if (cfg_.store_path.empty()) return SdoAbortCode::HardwareError;
  std::string error;
  std::ifstream in(cfg_.store_path);
  if (!in) return SdoAbortCode::None;  // nothing stored: nothing to load
  std::ostringstream text;
  text << in.rdbuf();
  const auto entries = canopen::ParameterStore::parse(text.str(), error);
  if (!entries) return SdoAbortCode::HardwareError;
  for (const auto& [key, value] : *entries)
    if (in_group(group, key.first)) (void)od().write(key.first, key.second, value, Origin::Local);
  return SdoAbortCode::None;
}

}  // namespace oegw::subdevices::sim
