#include "subdevices/sim/mcb402_sim.hpp"

#include "subdevices/sim/signal_names.hpp"

#include <stdexcept>
#include <string>

namespace oegw::subdevices::sim {

namespace {

using canopen::Access;
using canopen::DataType;
using canopen::encode;
using canopen::ObjectDictionary;
using canopen::Origin;
using canopen::pdo_map;
using canopen::PdoParameters;

std::vector<std::uint8_t> text(const std::string& s) { return {s.begin(), s.end()}; }

// The controller's own objects ([CO4013] chapter 5, operation mode 4), before the Node adds the
// communication objects.
std::unique_ptr<ObjectDictionary> build_od(const Mcb402SimConfig& cfg) {
  auto od = std::make_unique<ObjectDictionary>();
  const std::uint8_t id = cfg.node_id.value();
  od->add_var(0x1002, "Manufacturer status register", DataType::Unsigned32, Access::ReadOnly, encode<std::uint32_t>(0),
              true);
  od->add_var(0x100C, "Guard time", DataType::Unsigned16, Access::ReadWrite, encode<std::uint16_t>(0));
  od->add_var(0x100D, "Life time factor", DataType::Unsigned16, Access::ReadWrite, encode<std::uint16_t>(0));
  od->add_var(0x100E, "COB-ID guard", DataType::Unsigned32, Access::ReadWrite, encode<std::uint32_t>(0x700u + id));
  od->add_var(0x2000, "Device manufacturer", DataType::VisibleString, Access::ReadOnly, text("Frenzel + Berg"));
  // "the inverted setting of the configuration input bits CFG0 to CFG3": mode 4 = 1011b -> 0100b.
  od->add_var(0x2101, "System configuration", DataType::Unsigned32, Access::ReadOnly, encode<std::uint32_t>(4));
  od->add_var(0x2180, "CAN restart time", DataType::Unsigned16, Access::ReadWrite, encode<std::uint16_t>(0));

  od->add_array(0x5003, "Filter time digital input", DataType::Unsigned8, Access::ReadWrite, 20, {40});
  od->add_array(0x5401, "Axis zero position enlargement", DataType::Unsigned16, Access::ReadWrite, 4,
                encode<std::uint16_t>(0x1000));
  od->add_array(0x6000, "Digital input 8 bit", DataType::Unsigned8, Access::ReadOnly, 4, {0}, true);
  od->add_array(0x6002, "Polarity input 8 bit", DataType::Unsigned8, Access::ReadWrite, 4, {0});
  od->add_var(0x6005, "Global interrupt enable", DataType::Boolean, Access::ReadWrite, {1});
  od->add_array(0x6006, "Interrupt mask any change", DataType::Unsigned8, Access::ReadWrite, 4, {0xFF});
  od->add_array(0x6007, "Interrupt mask rising edge", DataType::Unsigned8, Access::ReadWrite, 4, {0});
  od->add_array(0x6008, "Interrupt mask falling edge", DataType::Unsigned8, Access::ReadWrite, 4, {0});
  od->add_array(0x6200, "Write to digital output", DataType::Unsigned8, Access::WriteOnly, 1, {0}, true);
  od->add_array(0x6202, "Polarity output 8 bit", DataType::Unsigned8, Access::ReadWrite, 1, {0});
  od->add_array(0x6206, "Error mode output 8 bit", DataType::Unsigned8, Access::ReadWrite, 1, {0xFF});
  od->add_array(0x6207, "Error value output 8 bit", DataType::Unsigned8, Access::ReadWrite, 1, {0});
  od->add_array(0x6401, "Read analog input 16 bit", DataType::Integer16, Access::ReadOnly, 4, encode<std::int16_t>(0),
                true);
  od->add_array(0x6421, "Analog input interrupt trigger", DataType::Unsigned8, Access::ReadWrite, 4, {7});
  od->add_var(0x6423, "Analog input global interrupt enable", DataType::Boolean, Access::ReadWrite, {0});
  const char* limits[] = {"Analog input upper limit", "Analog input lower limit", "Analog input interrupt delta",
                          "Analog input negative delta", "Analog input positive delta"};
  for (std::uint16_t i = 0; i < 5; ++i)
    od->add_array(static_cast<std::uint16_t>(0x6424 + i), limits[i], DataType::Integer32, Access::ReadWrite, 4,
                  encode<std::int32_t>(0));
  od->add_array(0x6431, "Analog input offset", DataType::Integer32, Access::ReadWrite, 4, encode<std::int32_t>(0));

  // [CO4013 "Operation mode 4"] default PDO mapping; [CO4013 Index 1400] type FFh, event time 0.
  canopen::install_rpdo(*od, 1,
                        PdoParameters{.cob_id = canopen::cob::kRpdo1 + id,
                                      .transmission_type = 0xFF,
                                      .mapping = {pdo_map(0x6200, 1, 8)}});
  canopen::install_tpdo(*od, 1,
                        PdoParameters{.cob_id = canopen::cob::kTpdo1 + id,
                                      .transmission_type = 0xFF,
                                      .inhibit_time = 0,
                                      .event_timer = 0,
                                      .mapping = {pdo_map(0x6000, 1, 8), pdo_map(0x6000, 2, 8), pdo_map(0x6000, 3, 8),
                                                  pdo_map(0x6000, 4, 8)}});
  canopen::install_tpdo(*od, 2,
                        PdoParameters{.cob_id = canopen::cob::kTpdo2 + id,
                                      .transmission_type = 0xFF,
                                      .inhibit_time = 0,
                                      .event_timer = 0,
                                      .mapping = {pdo_map(0x6401, 1, 16), pdo_map(0x6401, 2, 16),
                                                  pdo_map(0x6401, 3, 16), pdo_map(0x6401, 4, 16)}});
  return od;
}

std::uint8_t bit_timing_for(std::uint16_t kbaud) {
  switch (kbaud) {  // CiA 305 Table 1
    case 500: return 2;
    case 250: return 3;
    case 125: return 4;
    case 50: return 6;
    case 20: return 7;
    default: throw std::invalid_argument("MCB-402: bit rate must be 20, 50, 125, 250 or 500 kbit/s");
  }
}

}  // namespace

std::optional<co4013::ButtonBits> co4013::parse_wiring(std::string_view text) {
  ButtonBits bits{};
  std::size_t n = 0;
  unsigned seen = 0;
  const char separator = text.find('/') != std::string_view::npos ? '/' : ',';
  while (true) {
    const auto end = text.find(separator);
    const std::string_view item = text.substr(0, end);
    if (item.size() != 1 || item[0] < '0' || item[0] > '7' || n == kButtons) return std::nullopt;
    const auto bit = static_cast<std::uint8_t>(item[0] - '0');
    if ((seen & (1u << bit)) != 0) return std::nullopt;
    seen |= 1u << bit;
    bits[n++] = bit;
    if (end == std::string_view::npos) break;
    text.remove_prefix(end + 1);
  }
  if (n != kButtons) return std::nullopt;
  return bits;
}

std::optional<Mcb402SimConfig> Mcb402SimConfig::from_jumpers(std::uint8_t address_pins, std::uint8_t baud_pins) {
  const auto address = static_cast<std::uint8_t>(~address_pins & 0x7F);
  if (address == 0) return std::nullopt;
  Mcb402SimConfig c;
  c.node_id = NodeId{address};
  switch (baud_pins & 0x07) {
    case 0b101: c.kbaud = 500; break;
    case 0b100: c.kbaud = 250; break;
    case 0b011: c.kbaud = 125; break;
    case 0b010: c.kbaud = 50; break;
    case 0b001: c.kbaud = 20; break;
    default: return std::nullopt;
  }
  return c;
}

Mcb402Sim::Mcb402Sim(FrameSink sink, Mcb402SimConfig config) : SimulatedDevice(std::move(sink)), cfg_(config) {
  if (!cfg_.node_id.valid()) throw std::invalid_argument("MCB-402: node-ID must be 1..127");
  canopen::NodeConfig nc;
  nc.node_id = cfg_.node_id;
  nc.device_type = co4013::kDeviceType;
  nc.device_name = "CO4013A";
  nc.hardware_version = "1.0";
  nc.identity = {.vendor = co4013::kVendorId, .product = co4013::kProductCode, .revision = cfg_.revision, .serial = 0};
  nc.heartbeat_ms = cfg_.heartbeat_ms;
  nc.bit_timing_index = bit_timing_for(cfg_.kbaud);
  nc.store_path = cfg_.store_path;
  build(build_od(cfg_), nc);
  dict_ = &od();

  // [CO4013 Index 1018] sub-index 0 = 3: no serial number. No 100Ah in the document's table.
  auto& identity = *od().find(0x1018);
  identity.subs().erase(4);
  identity.find(0)->value = {3};
  identity.find(0)->default_value = {3};
  (void)od().remove(0x100A);

  node().on_state_change = [this](canopen::NmtState s) {
    // [CO4013 Index 1002] bit 31: the device is in operational state.
    auto* status = od().find(0x1002, 0);
    const std::uint32_t v = s == canopen::NmtState::Operational ? 0x80000000u : 0u;
    status->value = encode<std::uint32_t>(v);
    // After a reset the dictionary holds its defaults: the pins are read again, and 1001h shows
    // what is still active (a reset does not mend a cable).
    refresh_inputs(true);
    refresh_error_register();
  };
  subs_ += od().add_observer([this](std::uint16_t index, std::uint8_t, Origin origin) {
    if (origin == Origin::Sdo && (index == 0x6002 || index == 0x6431)) refresh_inputs(true);
  });
}

std::uint8_t Mcb402Sim::bit_timing_index() const { return bit_timing_for(cfg_.kbaud); }

void Mcb402Sim::write_input(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> bytes, bool notify) {
  if (notify) {
    (void)od().write(index, sub, bytes, Origin::Local);  // observers: the TPDO sees a change
  } else {
    od().find(index, sub)->value.assign(bytes.begin(), bytes.end());  // sampled, no event
  }
}

bool Mcb402Sim::digital_interrupt(std::uint8_t before, std::uint8_t after, std::uint8_t sub) const {
  if (dict_->get<std::uint8_t>(0x6005, 0) == 0) return false;
  const auto changed = static_cast<std::uint8_t>(before ^ after);
  const auto rising = static_cast<std::uint8_t>(after & ~before);
  const auto falling = static_cast<std::uint8_t>(before & ~after);
  return ((changed & dict_->get<std::uint8_t>(0x6006, sub)) | (rising & dict_->get<std::uint8_t>(0x6007, sub)) |
          (falling & dict_->get<std::uint8_t>(0x6008, sub))) != 0;
}

bool Mcb402Sim::analogue_interrupt(std::size_t axis, std::int16_t before, std::int16_t after) const {
  if (dict_->get<std::uint8_t>(0x6423, 0) == 0) return false;
  const auto sub = static_cast<std::uint8_t>(axis + 1);
  const std::uint8_t trigger = dict_->get<std::uint8_t>(0x6421, sub);
  const std::int32_t delta = std::int32_t{after} - std::int32_t{before};
  bool fire = false;
  if ((trigger & 0x01) != 0 && after > dict_->get<std::int32_t>(0x6424, sub)) fire = true;
  if ((trigger & 0x02) != 0 && after < dict_->get<std::int32_t>(0x6425, sub)) fire = true;
  if ((trigger & 0x04) != 0 && (delta < 0 ? -delta : delta) > dict_->get<std::int32_t>(0x6426, sub)) fire = true;
  if ((trigger & 0x08) != 0 && -delta > dict_->get<std::int32_t>(0x6427, sub)) fire = true;
  if ((trigger & 0x10) != 0 && delta > dict_->get<std::int32_t>(0x6428, sub)) fire = true;
  return fire;
}

void Mcb402Sim::refresh_inputs(bool notify) {
  // 6000h: NOT(pin) XOR polarity. Sub 1 (memory flags) is forced to 0 in mode 4; the direction
  // inputs and IN11..IN8 are not wired on the MCB-402 (pulled up).
  const std::array<std::uint8_t, 4> level{0x00, 0x00, static_cast<std::uint8_t>(~pins_), 0x00};
  for (std::uint8_t sub = 1; sub <= 4; ++sub) {
    std::uint8_t v = level[sub - 1];
    if (sub > 1) v = static_cast<std::uint8_t>(v ^ od().get<std::uint8_t>(0x6002, sub));
    if (sub == 4) v &= 0x0F;
    const std::uint8_t before = od().get<std::uint8_t>(0x6000, sub);
    if (v == before) continue;
    const std::array<std::uint8_t, 1> b{v};
    write_input(0x6000, sub, b, notify && digital_interrupt(before, v, sub));
  }
  for (std::size_t a = 0; a < co4013::kAxes; ++a) {
    const auto sub = static_cast<std::uint8_t>(a + 1);
    const std::int32_t physical = (broken_ & (1u << a)) != 0 ? -32768 : axes_[a];
    const auto v = static_cast<std::int16_t>(
        static_cast<std::uint16_t>(static_cast<std::uint32_t>(physical + od().get<std::int32_t>(0x6431, sub))));
    const auto before = od().get<std::int16_t>(0x6401, sub);
    if (v == before) continue;
    const auto b = encode<std::int16_t>(v);
    write_input(0x6401, sub, b, notify && analogue_interrupt(a, before, v));
  }
}

void Mcb402Sim::move_axis(std::size_t axis, std::int16_t raw, TimePoint now) {
  if (axis < 1 || axis > co4013::kAxes) throw std::out_of_range("MCB-402 axis is 1..4");
  axes_[axis - 1] = raw;
  refresh_inputs(true);
  node().advance(now);
}

void Mcb402Sim::convert_axis(std::size_t axis, std::int16_t converted, TimePoint now) {
  if (axis < 1 || axis > co4013::kAxes) throw std::out_of_range("MCB-402 axis is 1..4");
  const std::int32_t z = od().get<std::uint16_t>(0x5401, static_cast<std::uint8_t>(axis));
  const std::int32_t v = converted;
  const std::int32_t out = v > z ? v - z : (v < -z ? v + z : 0);
  move_axis(axis, static_cast<std::int16_t>(out), now);
}

void Mcb402Sim::set_button(std::size_t button, bool pressed, TimePoint now) {
  if (button < 1 || button > co4013::kButtons) throw std::out_of_range("MCB-402 button is 1..7");
  const auto bit = static_cast<std::uint8_t>(1u << cfg_.button_bits[button - 1]);
  // CN6: a button shorts its input to GND.
  pins_ = static_cast<std::uint8_t>(pressed ? (pins_ & ~bit) : (pins_ | bit));
  refresh_inputs(true);
  node().advance(now);
}

void Mcb402Sim::cable_break(std::size_t axis, bool broken, TimePoint now) {
  if (axis < 1 || axis > co4013::kAxes) throw std::out_of_range("MCB-402 axis is 1..4");
  const std::uint8_t before = broken_;
  const auto bit = static_cast<std::uint8_t>(1u << (axis - 1));
  broken_ = static_cast<std::uint8_t>(broken ? (broken_ | bit) : (broken_ & ~bit));
  refresh_inputs(true);
  if (broken_ == before) return;
  refresh_error_register();
  // "20 31 81 00 8x 00 00 00": 1001h in byte 2, byte 4 = 80h | the broken axes (ORed). The last
  // one mended: the error reset, or nothing (clear_with_error_reset).
  if (broken_ != 0) {
    send_emcy(co4013::kEmcyCableBreak, static_cast<std::uint8_t>(0x80 | broken_));
  } else if (cfg_.clear_with_error_reset) {
    send_emcy(0x0000, 0x00);
  }
  node().advance(now);
}

std::uint8_t Mcb402Sim::error_register() const { return dict_->get<std::uint8_t>(0x1001, 0); }

void Mcb402Sim::refresh_error_register() {
  std::uint8_t reg = broken_ != 0 ? co4013::kRegisterDeviceError : 0x00;
  if (communication_bits_) reg |= co4013::kRegisterCommunication;
  if (canopen::SubObject* s = od().find(0x1001, 0)) s->value = {reg};
}

void Mcb402Sim::send_emcy(std::uint16_t code, std::uint8_t byte4) {
  // [CO4013 "Emergency Messages"]: "EMY-Code | 1001 | 0 | CO4011-Code"; the ID is fixed to
  // 80h + node-ID. Sent in pre-operational and operational (CiA 301 §7.2.7).
  const canopen::NmtState st = node().state();
  if (st != canopen::NmtState::PreOperational && st != canopen::NmtState::Operational) return;
  out()(CanFrame(canopen::cob::kEmcy + cfg_.node_id.value(),
                 {static_cast<std::uint8_t>(code), static_cast<std::uint8_t>(code >> 8), error_register(), 0x00, byte4,
                  0x00, 0x00, 0x00}));
}

void Mcb402Sim::send_can_warning(std::uint16_t code, TimePoint /*now*/) {
  // "00 81 11", "30 81 11", "40 81 11": byte 2 = 1001h with bits 0 and 4 as the frame is sent;
  // afterwards 1001h keeps them or not (keep_communication_bits: the document shows no reset).
  const std::uint8_t kept = error_register();
  if (canopen::SubObject* s = od().find(0x1001, 0))
    s->value = {static_cast<std::uint8_t>(kept | co4013::kRegisterCommunication)};
  send_emcy(code, 0x00);
  communication_bits_ = communication_bits_ || cfg_.keep_communication_bits;
  refresh_error_register();
}

std::uint8_t Mcb402Sim::leds() const {
  // [CO4013 Index 6200]: 6200h XOR 6202h, then inverted onto the active-low pins: a 1 lights the
  // LED wired from +5 V (CN10). 6206h/6207h: in a device error the outputs selected by 6206h take
  // the 6207h value (1 = active).
  std::uint8_t v = dict_->get<std::uint8_t>(0x6200, 1) ^ dict_->get<std::uint8_t>(0x6202, 1);
  if (device_error_) {
    const std::uint8_t mode = dict_->get<std::uint8_t>(0x6206, 1);
    v = static_cast<std::uint8_t>((v & ~mode) | (dict_->get<std::uint8_t>(0x6207, 1) & mode));
  }
  return static_cast<std::uint8_t>(v & 0x0F);
}

void Mcb402Sim::on_power_cycle(TimePoint /*now*/) {
  device_error_ = false;
  communication_bits_ = false;
}

// [MCB §4] "At the power on, MCB402 writes on the bus: 703 00 ... 083 00 81 11 0": the [CO4013
// "Emergency Messages"] "CAN Bus in Error Warning state" frame 00 81 11 00 00 00 00 00 (1001h =
// 11h, generic + communication). A board that comes up with a broken cable shows it in 1001h
// (bit 7) without repeating the 3120h.
void Mcb402Sim::start(TimePoint now) {
  SimulatedDevice::start(now);
  refresh_error_register();
  send_can_warning(co4013::kEmcyCanWarning, now);
}

void Mcb402Sim::reboot(TimePoint now) {
  SimulatedDevice::reboot(now);
  refresh_error_register();
  send_can_warning(co4013::kEmcyCanWarning, now);
}

}  // namespace oegw::subdevices::sim

namespace oegw::subdevices::sim {

bool Mcb402Sim::set_input(std::string_view signal, std::int64_t value, TimePoint now) {
  static constexpr std::string_view kAxes[] = {"x", "y", "z", "t"};
  for (std::size_t a = 0; a < 4; ++a) {
    if (signal != kAxes[a]) continue;
    if (value < -32768 || value > 32767) return false;
    move_axis(a + 1, static_cast<std::int16_t>(value), now);
    return true;
  }
  if (const auto b = indexed_signal(signal, "buttons"); b && *b >= 1 && *b <= 7 && (value == 0 || value == 1)) {
    set_button(*b, value == 1, now);
    return true;
  }
  return false;
}

std::optional<std::int64_t> Mcb402Sim::output(std::string_view signal) const {
  if (const auto n = indexed_signal(signal, "leds"); n && *n >= 1 && *n <= 4) return led(*n) ? 1 : 0;
  return std::nullopt;
}

}  // namespace oegw::subdevices::sim

namespace oegw::subdevices::sim {

// [CO4013 Index 1010/1011] "Writing to this object is only allowed in preoperational mode", and
// note *2) of the object table: "otherwise the CO4012 will answer requests with SDO abort
// telegrams". The document gives no abort code: the simulator answers CiA 301's 0800 0022h
// "data cannot be transferred or stored to the application because of the present device
// state". The PDO parameters may be set in operational as well ("For the CO4013 setting of all
// parameters may be done in the device state operational as well as in preoperational").
canopen::SdoAbortCode Mcb402Sim::refuse_download(std::uint16_t index, std::uint8_t sub, canopen::NmtState state) const {
  if (state != canopen::NmtState::Operational || sub == 0) return canopen::SdoAbortCode::None;
  if (index == 0x1010 || index == 0x1011) return canopen::SdoAbortCode::CannotTransferDeviceState;
  return canopen::SdoAbortCode::None;
}

}  // namespace oegw::subdevices::sim
