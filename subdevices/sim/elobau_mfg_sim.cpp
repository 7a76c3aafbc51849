// Simulated elobau MFG 34xG / 36xG grip; what is modelled is listed in elobau_mfg_sim.hpp.
#include "subdevices/sim/elobau_mfg_sim.hpp"

#include "subdevices/sim/signal_names.hpp"

#include <algorithm>
#include <cstdlib>
#include <string>

namespace oegw::subdevices::sim {

using canopen::Access;
using canopen::DataType;
using canopen::encode;
using canopen::NmtState;
using canopen::ObjectDictionary;
using canopen::Origin;
using canopen::SdoAbortCode;

namespace {

constexpr std::array<std::string_view, 5> kAxes = {"x", "y", "wheel_a", "wheel_b", "wheel_c"};
constexpr std::uint16_t kAxis = 0x2000;
constexpr std::uint16_t kButtons = 0x2100;
constexpr std::uint16_t kLed = 0x2200;
constexpr std::uint16_t kErrorBehaviour = 0x4000;
constexpr std::uint16_t kErrorCode = 0x4001;
constexpr std::uint16_t kErrorField = 0x4002;
constexpr std::uint16_t kAutoStart = 0x5000;
constexpr std::uint16_t kBusOffLimit = 0x5001;
constexpr std::uint16_t kLss = 0x5999;
constexpr std::uint32_t kSave = 0x65766173;  // "save"

// Table 9, byte by byte: for RPDO byte b (2200h sub b+1) and the 2-bit field at `shift`, the LED
// number (bit of the mask 2200h:0Ah + 1); 0 = spare.
struct Field {
  std::uint8_t shift;
  std::uint8_t led;
};
constexpr std::array<std::array<Field, 4>, 8> kTable9 = {{
    {{{0, 1}, {2, 2}, {4, 3}, {6, 4}}},     // byte 0: button 1 LED 1/2, button 2 LED 1/2
    {{{0, 5}, {2, 6}, {4, 7}, {6, 8}}},     // byte 1: button 3 LED 1/2, button 4 LED 1/2
    {{{0, 9}, {2, 10}, {4, 0}, {6, 0}}},    // byte 2: button 5 LED 1/2, spare, spare
    {{{0, 0}, {2, 0}, {4, 0}, {6, 0}}},     // byte 3: spare
    {{{0, 0}, {2, 0}, {4, 0}, {6, 0}}},     // byte 4: spare
    {{{0, 11}, {2, 12}, {4, 15}, {6, 0}}},  // byte 5: wheel A LED 2-2 (bit 10), 2-1 (11), 1+3 (14)
    {{{0, 13}, {2, 14}, {4, 16}, {6, 0}}},  // byte 6: wheel B LED 2-2 (bit 12), 2-1 (13), 1+3 (15)
    {{{0, 0}, {2, 0}, {4, 0}, {6, 0}}},     // byte 7: spare
}};

// Table 10: the default transformation, X (mV) / Y (%) pairs.
constexpr std::array<std::uint16_t, 10> kX = {200, 600, 2300, 2700, 4400, 4800, 4800, 4800, 4800, 4800};
constexpr std::array<std::int8_t, 10> kY = {-100, -100, 0, 0, 100, 100, 100, 100, 100, 100};

void member(ObjectDictionary& od, std::uint16_t idx, std::uint8_t sub, const std::string& name, DataType t, Access a,
            std::vector<std::uint8_t> def, bool mappable = false) {
  od.add_record_member(idx, sub, name, t, a, std::move(def), mappable);
}

}  // namespace

std::optional<std::size_t> ElobauMfgSim::axis_index(std::string_view name) {
  for (std::size_t i = 0; i < kAxes.size(); ++i)
    if (kAxes[i] == name) return i;
  return std::nullopt;
}

ElobauMfgSim::ElobauMfgSim(FrameSink sink, ElobauMfgSimConfig config)
    : SimulatedDevice(std::move(sink)),
      parameters_saved_(config.parameters_saved),
      tpdo_on_change_(config.tpdo_on_change) {
  auto od = std::make_unique<ObjectDictionary>();
  build_od(*od, config);
  canopen::NodeConfig nc;
  nc.node_id = config.node_id;
  nc.device_type = 0x00000000;  // Table 14: no standardized device profile
  nc.device_name = "JST";
  nc.hardware_version = "0.00";
  nc.software_version = "0.00";
  nc.identity = {.vendor = 0x000000B4, .product = config.product_code, .revision = 0, .serial = config.serial};
  nc.heartbeat_ms = config.heartbeat_ms;
  nc.bit_timing_index = 3;  // 250 kbit/s
  nc.store_path = config.store_path;
  build(std::move(od), nc);

  ObjectDictionary& d = this->od();
  d.find(0x1014, 0)->access = Access::ReadOnly;  // Table 14: COB-ID EMCY ro

  // LED commands: apply each RPDO (or SDO) byte to the LED states.
  subs_ += d.add_observer([this](std::uint16_t index, std::uint8_t sub, Origin origin) {
    if (index == kLed && sub >= 1 && sub <= 8 && origin != Origin::Local)
      apply_led_byte(sub, this->od().get<std::uint8_t>(kLed, sub));
    if (index == kLss && sub == 2) node().nmt().set_pending_node_id(NodeId{this->od().get<std::uint8_t>(kLss, 2)});
    if (index == 0x1010 && sub == 1) parameters_saved_ = true;  // committed: the store accepted "save"
  });
  // 5999h: baud rate from the list of §16, "save" signature on :03.
  subs_ +=
      d.find(kLss)->add_write_hook([this](canopen::Object&, std::uint8_t sub, std::span<const std::uint8_t> b, Origin) {
        if (sub == 1 && b.size() == 2) {
          const std::uint16_t v = canopen::get_u16(b.data());
          static constexpr std::uint16_t kRates[] = {20, 50, 125, 250, 500, 800, 1000};
          if (std::find(std::begin(kRates), std::end(kRates), v) == std::end(kRates)) return SdoAbortCode::InvalidValue;
        }
        if (sub == 3 && b.size() == 4) {
          if (canopen::get_u32(b.data()) != kSave) return SdoAbortCode::CannotTransfer;
          if (this->od().find(0x1010) == nullptr) return SdoAbortCode::CannotTransfer;
          return this->od().write(0x1010, 1, encode<std::uint32_t>(kSave), Origin::Local);
        }
        return SdoAbortCode::None;
      });
  // After every reset the dictionary holds defaults: put the inputs back (the device keeps
  // reading its sensors). A restart (power-on, reset node, reset communication) re-checks the
  // parameters: never saved, 0002h is set again (Table 6 "until first parameter saving process");
  // saved since, it is over.
  node().on_state_change = [this](NmtState s) {
    if (s != NmtState::PreOperational || last_state_ != NmtState::Initialisation) {
      last_state_ = s;
      if (s == NmtState::PreOperational) publish();
      return;
    }
    last_state_ = s;
    publish();
    if (parameters_saved_ && errors_.erase(0x0002) != 0) publish();
    refresh_error_code();
    if (!parameters_saved_) raise_error(0x0002, node().nmt().last_transition());
  };
  publish();
}

void ElobauMfgSim::build_od(ObjectDictionary& od, const ElobauMfgSimConfig& c) {
  const std::uint8_t id = c.node_id.value();
  // Axes 2000h..2004h (Table 14, "dto." for Y and the wheels).
  for (std::size_t a = 0; a < kAxes.size(); ++a) {
    const auto idx = static_cast<std::uint16_t>(kAxis + a);
    od.add_record(idx, std::string(kAxes[a]));
    member(od, idx, 0x01, "Configuration", DataType::Unsigned8, Access::ReadWrite, {c.axis_config[a]});
    od.find(idx, 0x01)->high = std::uint64_t{3};
    member(od, idx, 0x02, "Raw Signal 1", DataType::Unsigned16, Access::ReadOnly, encode<std::uint16_t>(0));
    member(od, idx, 0x03, "Raw Signal 2", DataType::Unsigned16, Access::ReadOnly, encode<std::uint16_t>(0));
    member(od, idx, 0x04, "Analogue Signal Filter Constant", DataType::Unsigned8, Access::ReadWrite, {0});
    member(od, idx, 0x05, "Maximal Difference Signal 1_2", DataType::Unsigned16, Access::ReadWrite,
           encode<std::uint16_t>(0));
    od.find(idx, 0x05)->high = std::uint64_t{5000};
    for (std::uint8_t p = 0; p < 10; ++p) {
      const auto sx = static_cast<std::uint8_t>(0x06 + 2 * p);
      member(od, idx, sx, "Transformation Function X" + std::to_string(p + 1), DataType::Unsigned16, Access::ReadWrite,
             encode<std::uint16_t>(kX[p]));
      od.find(idx, sx)->high = std::uint64_t{5000};
      member(od, idx, static_cast<std::uint8_t>(sx + 1), "Transformation Function Y" + std::to_string(p + 1),
             DataType::Integer8, Access::ReadWrite, encode<std::int8_t>(kY[p]));
    }
    member(od, idx, 0x1A, "Spare", DataType::Unsigned8, Access::ReadOnly, {0});
    member(od, idx, 0x1B, "Error Value", DataType::Integer8, Access::ReadWrite, encode<std::int8_t>(126));
    member(od, idx, 0x1C, "Not Available Value", DataType::Integer8, Access::ReadWrite, encode<std::int8_t>(127));
    for (std::uint8_t s = 0x1D; s <= 0x1F; ++s) member(od, idx, s, "Spare", DataType::Unsigned8, Access::ReadOnly, {0});
    member(od, idx, 0x20, "Transformed Signal 1", DataType::Integer8, Access::ReadOnly, encode<std::int8_t>(0), true);
    member(od, idx, 0x21, "Transformed Signal 2", DataType::Integer8, Access::ReadOnly, encode<std::int8_t>(0), true);
  }
  // Buttons 2100h.
  od.add_record(kButtons, "Buttons 1_16");
  member(od, kButtons, 0x01, "Configuration 8_1", DataType::Unsigned8, Access::ReadWrite, {c.buttons_1_8});
  member(od, kButtons, 0x02, "Configuration 16_9", DataType::Unsigned8, Access::ReadWrite, {c.buttons_9_16});
  member(od, kButtons, 0x03, "Raw Signal 8_1", DataType::Unsigned8, Access::ReadOnly, {0});
  member(od, kButtons, 0x04, "Raw Signal 16_9", DataType::Unsigned8, Access::ReadOnly, {0});
  member(od, kButtons, 0x05, "Debounce Time", DataType::Unsigned8, Access::ReadWrite, {0});
  member(od, kButtons, 0x06, "Spare", DataType::Unsigned8, Access::ReadOnly, {0});
  member(od, kButtons, 0x07, "Spare", DataType::Unsigned8, Access::ReadOnly, {0});
  member(od, kButtons, 0x08, "Timeout", DataType::Unsigned8, Access::ReadWrite, {0});
  member(od, kButtons, 0x09, "Error Value", DataType::Unsigned8, Access::ReadWrite, {0});
  od.find(kButtons, 0x09)->high = std::uint64_t{1};
  member(od, kButtons, 0x0A, "Not Available Value", DataType::Unsigned8, Access::ReadWrite, {0});
  od.find(kButtons, 0x0A)->high = std::uint64_t{1};
  for (std::uint8_t s = 0x0B; s <= 0x0F; ++s)
    member(od, kButtons, s, "Spare", DataType::Unsigned8, Access::ReadOnly, {0});
  member(od, kButtons, 0x10, "Transformed Signal 8_1", DataType::Unsigned8, Access::ReadOnly, {0}, true);
  member(od, kButtons, 0x11, "Transformed Signal 16_9", DataType::Unsigned8, Access::ReadOnly, {0}, true);
  // LED commands 2200h (wo, mapped by RPDO #0). Sub 8 is a spare the RPDO maps: wo here.
  od.add_record(kLed, "LED Commands");
  for (std::uint8_t s = 1; s <= 8; ++s)
    member(od, kLed, s, s == 8 ? "Spare" : "LED command " + std::to_string(s), DataType::Unsigned8, Access::WriteOnly,
           {0}, true);
  member(od, kLed, 0x09, "Timeout", DataType::Unsigned8, Access::ReadWrite, {0});
  member(od, kLed, 0x0A, "LED Mask configuration", DataType::Unsigned16, Access::ReadWrite,
         encode<std::uint16_t>(0xFFFF));
  od.find(kLed, 0)->value = {9};  // Table 14: "Number of Entries 9"
  od.find(kLed, 0)->default_value = {9};
  // Error handling (§12).
  od.add_var(kErrorBehaviour, "Error Behavior", DataType::Unsigned8, Access::ReadWrite, {1});
  od.find(kErrorBehaviour, 0)->high = std::uint64_t{2};
  od.add_var(kErrorCode, "Error Code", DataType::Unsigned16, Access::ReadOnly, encode<std::uint16_t>(0));
  od.add_var(kErrorField, "Error Field", DataType::Unsigned8, Access::ReadOnly, {0xFF}, true);
  od.add_var(kAutoStart, "Auto NMT Start", DataType::Unsigned8, Access::ReadWrite, {0});
  od.find(kAutoStart, 0)->high = std::uint64_t{1};
  od.add_var(kBusOffLimit, "Bus-Off Counter Limit", DataType::Unsigned16, Access::ReadWrite, encode<std::uint16_t>(20));
  od.find(kBusOffLimit, 0)->high = std::uint64_t{10000};
  od.add_record(kLss, "LSS");
  member(od, kLss, 1, "Baud rate", DataType::Unsigned16, Access::ReadWrite, encode<std::uint16_t>(250));
  member(od, kLss, 2, "Node-ID", DataType::Unsigned8, Access::ReadWrite, {id});
  od.find(kLss, 2)->low = std::uint64_t{1};
  od.find(kLss, 2)->high = std::uint64_t{127};
  member(od, kLss, 3, "Save all Parameters (incl. LSS)", DataType::Unsigned32, Access::ReadWrite,
         encode<std::uint32_t>(0));

  // PDOs (Table 14): RPDO #0, TPDO #0, TPDO #1, all type 254; TPDOs 100 ms, inhibit 20 x 100 µs.
  using canopen::pdo_map;
  std::vector<std::uint32_t> rmap;
  for (std::uint8_t s = 1; s <= 8; ++s) rmap.push_back(pdo_map(kLed, s, 8));
  canopen::install_rpdo(od, 1, {.cob_id = 0x200u + id, .transmission_type = 254, .mapping = rmap});
  std::vector<std::uint32_t> t0, t1;
  for (std::uint16_t a = 0; a < 5; ++a) t0.push_back(pdo_map(static_cast<std::uint16_t>(kAxis + a), 0x20, 8));
  t0.push_back(pdo_map(kButtons, 0x10, 8));
  t0.push_back(pdo_map(kButtons, 0x11, 8));
  t0.push_back(pdo_map(kErrorField, 0, 8));
  for (std::uint16_t a = 0; a < 5; ++a) t1.push_back(pdo_map(static_cast<std::uint16_t>(kAxis + a), 0x21, 8));
  for (int i = 0; i < 3; ++i) t1.push_back(pdo_map(kErrorField, 0, 8));
  canopen::install_tpdo(od, 1,
                        {.cob_id = 0x180u + id,
                         .transmission_type = 254,
                         .inhibit_time = 20,
                         .event_timer = 100,
                         .mapping = t0});
  canopen::install_tpdo(od, 2,
                        {.cob_id = 0x280u + id,
                         .transmission_type = 254,
                         .inhibit_time = 20,
                         .event_timer = 100,
                         .mapping = t1});
  // Access and sub-indices as Table 14 lists them.
  auto* rc = od.find(0x1400);
  rc->subs().erase(5);
  for (std::uint8_t s = 0; s <= 2; ++s) rc->find(s)->access = Access::ReadOnly;
  rc->find(0)->value = rc->find(0)->default_value = {2};
  for (std::uint16_t idx : {std::uint16_t{0x1800}, std::uint16_t{0x1801}}) {
    auto* tc = od.find(idx);
    tc->subs().erase(6);
    member(od, idx, 4, "Reserved", DataType::Unsigned8, Access::ReadWrite, {0});
    for (std::uint8_t s : {0, 1, 2, 3}) tc->find(s)->access = Access::ReadOnly;
    tc->find(0)->value = tc->find(0)->default_value = {5};
  }
  for (std::uint16_t idx : {std::uint16_t{0x1600}, std::uint16_t{0x1A00}, std::uint16_t{0x1A01}})
    for (auto& [s, so] : od.find(idx)->subs()) so.access = Access::ReadOnly;
}

void ElobauMfgSim::publish() {
  ObjectDictionary& d = od();
  const bool substitute = true;  // error values are sent whatever 4000h says; 0/2 also change state
  for (std::size_t a = 0; a < kAxes.size(); ++a) {
    const auto idx = static_cast<std::uint16_t>(kAxis + a);
    if (zero_lock_[a] && physical_[a] == 0) zero_lock_[a] = false;  // §4: seen at zero
    const int v = zero_lock_[a] ? 0 : physical_[a];
    const std::uint8_t cfg = d.get<std::uint8_t>(idx, 0x01);
    const auto err = d.get<std::int8_t>(idx, 0x1B);
    const auto na = d.get<std::int8_t>(idx, 0x1C);
    const auto base = static_cast<std::uint16_t>((a + 1) << 4);  // Table 6: 10h X, 20h Y, ...
    for (int ch = 0; ch < 2; ++ch) {
      int out = std::clamp(ch == 0 ? v : v + offset2_[a], -128, 127);
      if ((cfg & (1u << ch)) == 0 || faults_[a][ch] == Fault::NotAvailable) {
        out = na;
      } else if (faults_[a][ch] == Fault::Error ||
                 (substitute && errors_.contains(static_cast<std::uint16_t>(base + ch)))) {
        out = err;
      }
      put(idx, static_cast<std::uint8_t>(0x20 + ch), static_cast<std::uint8_t>(static_cast<std::int8_t>(out)));
      // Raw ADC value (mV) by Table 10, roughly: 2500 mV at 0 %, 4400/600 mV at ±100 %.
      (void)d.set<std::uint16_t>(idx, static_cast<std::uint8_t>(0x02 + ch),
                                 static_cast<std::uint16_t>(std::clamp(2500 + physical_[a] * 19, 0, 5000)));
    }
  }
  const std::uint16_t fitted =
      static_cast<std::uint16_t>(d.get<std::uint8_t>(kButtons, 1) | (d.get<std::uint8_t>(kButtons, 2) << 8));
  const bool err_value = d.get<std::uint8_t>(kButtons, 9) != 0;
  const bool na_value = d.get<std::uint8_t>(kButtons, 0x0A) != 0;
  std::uint16_t out = 0;
  for (unsigned b = 0; b < 16; ++b) {
    bool bit = (buttons_ >> b) & 1u;
    if (((fitted >> b) & 1u) == 0) {
      bit = na_value;
    } else if (errors_.contains(static_cast<std::uint16_t>(0x61 + b))) {
      bit = err_value;
    }
    if (bit) out = static_cast<std::uint16_t>(out | (1u << b));
  }
  (void)d.set<std::uint8_t>(kButtons, 0x03, static_cast<std::uint8_t>(buttons_));
  (void)d.set<std::uint8_t>(kButtons, 0x04, static_cast<std::uint8_t>(buttons_ >> 8));
  put(kButtons, 0x10, static_cast<std::uint8_t>(out));
  put(kButtons, 0x11, static_cast<std::uint8_t>(out >> 8));
}

void ElobauMfgSim::put(std::uint16_t index, std::uint8_t sub, std::uint8_t raw) {
  if (tpdo_on_change_) {
    (void)od().set<std::uint8_t>(index, sub, raw);  // an application event: the TPDO goes out
  } else if (canopen::SubObject* s = od().find(index, sub)) {
    s->value = {raw};  // sampled by the event timer only
  }
}

void ElobauMfgSim::refresh_error_code() {
  (void)od().set<std::uint16_t>(kErrorCode, 0, errors_.empty() ? std::uint16_t{0} : *errors_.rbegin());
}

void ElobauMfgSim::apply_led_byte(std::uint8_t sub, std::uint8_t byte) {
  for (const Field& f : kTable9[sub - 1]) {
    if (f.led == 0) continue;
    const auto code = static_cast<std::uint8_t>((byte >> f.shift) & 0x3);
    if (code != 0x3) leds_[f.led - 1] = code;  // Table 13: 11 = no change
  }
}

std::uint8_t ElobauMfgSim::led_displayed(std::size_t i) {
  const auto mask = od().get<std::uint16_t>(kLed, 0x0A);
  return ((mask >> (i - 1)) & 1u) ? leds_.at(i - 1) : 0;
}

std::int8_t ElobauMfgSim::transmitted(std::string_view axis, int channel) {
  const auto a = axis_index(axis);
  if (!a || channel < 1 || channel > 2) return 0;
  return od().get<std::int8_t>(static_cast<std::uint16_t>(kAxis + *a), static_cast<std::uint8_t>(0x1F + channel));
}

bool ElobauMfgSim::zero_locked(std::string_view axis) const {
  const auto a = axis_index(axis);
  return a && zero_lock_[*a];
}

std::uint16_t ElobauMfgSim::baud_rate() { return od().get<std::uint16_t>(kLss, 1); }

bool ElobauMfgSim::move_axis(std::string_view axis, int percent, int channel2_offset) {
  const auto a = axis_index(axis);
  if (!a) return false;
  physical_[*a] = std::clamp(percent, -110, 110);
  offset2_[*a] = channel2_offset;
  publish();
  return true;
}

std::optional<int> ElobauMfgSim::apply_voltage(std::string_view axis, int millivolts) {
  const auto a = axis_index(axis);
  if (!a) return std::nullopt;
  const auto idx = static_cast<std::uint16_t>(kAxis + *a);
  std::array<int, 10> x{}, y{};
  for (std::uint8_t p = 0; p < 10; ++p) {
    x[p] = od().get<std::uint16_t>(idx, static_cast<std::uint8_t>(0x06 + 2 * p));
    y[p] = od().get<std::int8_t>(idx, static_cast<std::uint8_t>(0x07 + 2 * p));
  }
  const bool out_of_range = millivolts < x[0] || millivolts > x[9];
  faults_[*a] = {out_of_range ? Fault::Error : Fault::None, out_of_range ? Fault::Error : Fault::None};
  if (out_of_range) {
    publish();
    return std::nullopt;
  }
  int percent = y[9];
  for (std::size_t p = 0; p + 1 < 10; ++p) {
    if (millivolts < x[p] || millivolts > x[p + 1]) continue;
    const bool to_detent = std::abs(y[p + 1]) > 100 && std::abs(y[p]) <= 100;    // e.g. X8 -> X9
    const bool from_detent = std::abs(y[p]) > 100 && std::abs(y[p + 1]) <= 100;  // e.g. X2 -> X3
    if (to_detent) {
      percent = millivolts >= x[p + 1] ? y[p + 1] : y[p];  // the jump at X9
    } else if (from_detent) {
      percent = millivolts <= x[p] ? y[p] : y[p + 1];  // the jump at X2
    } else if (x[p + 1] == x[p]) {
      percent = y[p];
    } else {
      percent = y[p] + (y[p + 1] - y[p]) * (millivolts - x[p]) / (x[p + 1] - x[p]);
    }
    break;
  }
  physical_[*a] = percent;
  offset2_[*a] = 0;
  publish();
  return percent;
}

bool ElobauMfgSim::inject(std::string_view axis, Fault fault, int channel) {
  const auto a = axis_index(axis);
  if (!a || channel < 0 || channel > 2) return false;
  if (channel != 2) faults_[*a][0] = fault;
  if (channel != 1) faults_[*a][1] = fault;
  publish();
  return true;
}

bool ElobauMfgSim::press(int button) {
  if (button < 1 || button > 16) return false;
  buttons_ = static_cast<std::uint16_t>(buttons_ | (1u << (button - 1)));
  publish();
  return true;
}

bool ElobauMfgSim::release(int button) {
  if (button < 1 || button > 16) return false;
  buttons_ = static_cast<std::uint16_t>(buttons_ & ~(1u << (button - 1)));
  publish();
  return true;
}

void ElobauMfgSim::send_emcy(std::uint16_t code, std::uint16_t manufacturer, TimePoint /*now*/) {
  // §12.1: no EMCY in Stopped (nor before boot-up).
  const NmtState s = node().state();
  if (s != NmtState::PreOperational && s != NmtState::Operational) return;
  const canopen::CobId cob{od().get<std::uint32_t>(0x1014, 0)};
  if (!cob.valid()) return;
  // Table 5: code, error register (always 0), 4001h, FFh FFh FFh.
  out()(CanFrame(cob.can_id(), {static_cast<std::uint8_t>(code), static_cast<std::uint8_t>(code >> 8), 0x00,
                                static_cast<std::uint8_t>(manufacturer), static_cast<std::uint8_t>(manufacturer >> 8),
                                0xFF, 0xFF, 0xFF}));
}

void ElobauMfgSim::raise_error(std::uint16_t code, TimePoint now) {
  if (!errors_.insert(code).second) return;
  (void)od().set<std::uint16_t>(kErrorCode, 0, code);
  send_emcy(0x1000, code, now);  // §12.4: 1000h generic = manufacturer specific
  publish();
  switch (od().get<std::uint8_t>(kErrorBehaviour, 0)) {  // §12.2
    case 0:
      if (node().state() == NmtState::Operational) node().nmt().enter(NmtState::PreOperational, now);
      break;
    case 2: node().nmt().enter(NmtState::Stopped, now); break;
    default: break;
  }
}

void ElobauMfgSim::clear_error(std::uint16_t code, TimePoint now) {
  if (errors_.erase(code) == 0) return;
  publish();
  if (errors_.empty()) {
    (void)od().set<std::uint16_t>(kErrorCode, 0, 0);
    send_emcy(0x0000, 0x0000, now);
  } else {
    (void)od().set<std::uint16_t>(kErrorCode, 0, *errors_.rbegin());
  }
}

void ElobauMfgSim::arm_zero_rule() {
  for (std::size_t a = 0; a < kAxes.size(); ++a) zero_lock_[a] = physical_[a] != 0;
}

void ElobauMfgSim::bus_off(TimePoint now) {
  ++bus_off_count_;
  const auto limit = od().get<std::uint16_t>(kBusOffLimit, 0);
  if (limit > 0 && bus_off_count_ > limit) {
    set_silent(true);  // 5001h: off-line mode, no broadcast, no receive
    return;
  }
  arm_zero_rule();  // §4: "after power on and bus off"
  publish();
  send_emcy(0x8140, bus_off_count_, now);  // §12.4: the count of bus-offs
}

void ElobauMfgSim::start(TimePoint now) {
  leds_.fill(0);
  arm_zero_rule();
  publish();
  last_state_ = NmtState::Initialisation;
  SimulatedDevice::start(now);  // 0002h, until the first saving: on_state_change
  if (od().get<std::uint8_t>(kAutoStart, 0) == 1) node().nmt().enter(NmtState::Operational, now);
}

void ElobauMfgSim::reboot(TimePoint now) {
  last_state_ = NmtState::Initialisation;
  SimulatedDevice::reboot(now);
  if (od().get<std::uint8_t>(kAutoStart, 0) == 1) node().nmt().enter(NmtState::Operational, now);
}

void ElobauMfgSim::on_power_cycle(TimePoint /*now*/) {
  leds_.fill(0);
  errors_.clear();
  bus_off_count_ = 0;
  set_silent(false);
  arm_zero_rule();
  // The reset that follows restores the dictionary; publish() runs when it is pre-operational.
}

}  // namespace oegw::subdevices::sim

namespace oegw::subdevices::sim {

bool ElobauMfgSim::set_input(std::string_view signal, std::int64_t value, TimePoint /*now*/) {
  if (axis_index(signal)) {
    if (value < -110 || value > 110) return false;
    return move_axis(signal, static_cast<int>(value));
  }
  if (const auto b = indexed_signal(signal, "buttons"); b && *b >= 1 && *b <= 16 && (value == 0 || value == 1))
    return value == 1 ? press(static_cast<int>(*b)) : release(static_cast<int>(*b));
  return false;
}

std::optional<std::int64_t> ElobauMfgSim::output(std::string_view signal) const {
  if (const auto n = indexed_signal(signal, "leds"); n && *n >= 1 && *n <= kLeds) return led(*n);
  return std::nullopt;
}

}  // namespace oegw::subdevices::sim

namespace oegw::subdevices::sim {

// The document says nothing of the NMT state for 1010h:01 "save all parameters" and 5999h:03
// "save all parameters (incl. LSS)" (§8, Table 14); the simulator takes CiA 301's answer for a
// store in the wrong state, 0800 0022h, while operational. The PDO mapping is read-only in
// every state (Table 14), so remapping needs no rule here.
canopen::SdoAbortCode ElobauMfgSim::refuse_download(std::uint16_t index, std::uint8_t sub,
                                                    canopen::NmtState state) const {
  if (state != NmtState::Operational) return SdoAbortCode::None;
  if ((index == 0x1010 && sub == 1) || (index == kLss && sub == 3)) return SdoAbortCode::CannotTransferDeviceState;
  return SdoAbortCode::None;
}

}  // namespace oegw::subdevices::sim
