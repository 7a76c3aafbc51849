#include "gateway/bus_load.hpp"

#include <algorithm>
#include <initializer_list>
#include <stdexcept>

#include <fmt/format.h>

#include "canopen/frame_bits.hpp"
#include "canopen/types.hpp"

namespace oegw::gateway {

namespace sd = oegw::subdevices;

double BusLoad::frames_per_second() const {
  double f = 0;
  for (const auto& s : periodic) f += s.per_second;
  return f;
}

double BusLoad::bits_per_second() const {
  double b = 0;
  for (const auto& s : periodic) b += s.bits_per_second();
  return b;
}

double BusLoad::percent() const { return bit_rate == 0 ? 0 : 100.0 * bits_per_second() / bit_rate; }

namespace {

// A stream whose data varies (a PDO): every frame at its worst-case length.
void add(BusLoad& load, std::string what, std::uint32_t cob_id, std::uint8_t length, double period_ms) {
  if (period_ms <= 0) return;
  load.periodic.push_back(
      BusStream{std::move(what), cob_id, length, 1000.0 / period_ms, canopen::frame_bits_worst_case(length)});
}

// A stream whose frames are known bit for bit: its exact length (the longest of `variants`).
void add_exact(BusLoad& load, std::string what, std::uint32_t cob_id, std::initializer_list<canopen::CanFrame> variants,
               double period_ms) {
  if (period_ms <= 0) return;
  std::uint32_t bits = 0;
  for (const auto& f : variants) bits = std::max(bits, canopen::frame_bits(f));
  load.periodic.push_back(BusStream{std::move(what), cob_id, variants.begin()->dlc, 1000.0 / period_ms, bits, true});
}

// A heartbeat (CiA 301 §7.2.8.3.2.2: 1 byte, the NMT state): operational in the steady state, but
// counted at the longest of operational, pre-operational and stopped, so the figure stays an upper
// bound whatever state the host or the gateway leaves the node in.
void add_heartbeat(BusLoad& load, std::string what, std::uint32_t cob_id, double period_ms) {
  const auto id = static_cast<std::uint16_t>(cob_id);
  add_exact(load, std::move(what), cob_id,
            {canopen::CanFrame(id, {0x05}), canopen::CanFrame(id, {0x7F}), canopen::CanFrame(id, {0x04})}, period_ms);
}

std::string inhibit_bound(std::uint16_t inhibit_100us) {
  if (inhibit_100us == 0) return "no inhibit time: as often as the device sends";
  return fmt::format("at most {:.0f}/s (inhibit time {:.1f} ms)", 10000.0 / inhibit_100us, inhibit_100us / 10.0);
}

void add_subdevice(BusLoad& load, const mapping::Config& cfg, const mapping::SubdeviceConfig& s) {
  const canopen::NodeId node = s.node();
  if (s.heartbeat_ms != 0)
    add_heartbeat(load, fmt::format("{} heartbeat {:03X}h, every {} ms", s.name, 0x700 + node.value(), s.heartbeat_ms),
                  0x700u + node.value(), s.heartbeat_ms);
  std::string error;
  auto driver = sd::make_driver(s.driver, node, {}, s.options, error);
  if (!driver) throw std::runtime_error(s.where.str() + ": " + error);
  // The boot's writes, in the network manager's order: the driver's configuration, then `sdo`.
  std::vector<sd::SdoWrite> writes = driver->configuration();
  for (const auto& w : s.sdo) writes.push_back(w.to_sdo_write());
  for (const auto& t : driver->expected_tpdos(writes)) {
    const std::string pdo = fmt::format("{} TPDO {:03X}h, {} bytes", s.name, t.cob_id, t.length);
    const bool async = t.transmission_type >= 254;
    if (async && t.event_timer_ms != 0) {
      add(load, fmt::format("{}, event timer {} ms", pdo, t.event_timer_ms), t.cob_id, t.length, t.event_timer_ms);
      load.on_change.push_back(fmt::format("{}: besides, on change ({})", pdo, inhibit_bound(t.inhibit_100us)));
    } else if (t.transmission_type >= 1 && t.transmission_type <= 240) {
      if (cfg.downstream.sync_period_ms != 0)
        add(load, fmt::format("{}, every {} SYNC", pdo, t.transmission_type), t.cob_id, t.length,
            double(t.transmission_type) * cfg.downstream.sync_period_ms);
      else
        load.on_change.push_back(
            fmt::format("{}: synchronous type {} and no SYNC: never sent", pdo, t.transmission_type));
    } else {
      load.on_change.push_back(fmt::format("{}: on change only ({})", pdo, inhibit_bound(t.inhibit_100us)));
    }
  }
}

}  // namespace

BusLoadPrediction predict_bus_load(const mapping::Config& cfg) {
  BusLoadPrediction p;
  p.downstream.bit_rate = cfg.downstream.bitrate;
  p.upstream.bit_rate = cfg.upstream.bitrate;
  if (cfg.downstream.sync_period_ms != 0)
    add_exact(p.downstream, fmt::format("SYNC 080h, every {} ms", cfg.downstream.sync_period_ms), 0x080,
              {canopen::CanFrame(0x080, std::initializer_list<std::uint8_t>{})}, cfg.downstream.sync_period_ms);
  for (const auto& s : cfg.subdevices) add_subdevice(p.downstream, cfg, s);
  p.downstream.on_change.push_back("the gateway's RPDOs to the sub-devices' outputs: on command");
  if (cfg.upstream.heartbeat_ms != 0)
    add_heartbeat(p.upstream,
                  fmt::format("gateway heartbeat {:03X}h, every {} ms", 0x700 + cfg.upstream.node_id,
                              cfg.upstream.heartbeat_ms),
                  0x700u + cfg.upstream.node_id, cfg.upstream.heartbeat_ms);
  p.upstream.on_change.push_back(
      "the gateway's TPDOs (CiA 852 clause 12): disabled at power-on; once the host enables them, on change of "
      "their FE fields (event timer and inhibit time as the host writes them, 0 by default)");
  return p;
}

std::string describe_bus_load(const BusLoad& load, const std::string& name) {
  std::string out =
      fmt::format("  {} {} bit/s: {:.1f} % steady state ({:.1f} frames/s, {:.0f} bit/s; PDOs at worst-case stuffing)\n",
                  name, load.bit_rate, load.percent(), load.frames_per_second(), load.bits_per_second());
  for (const auto& s : load.periodic)
    out += fmt::format("    {:<58} {:7.1f}/s x {:3} bits = {:5.2f} %\n", s.what, s.per_second, s.bits,
                       load.bit_rate == 0 ? 0.0 : 100.0 * s.bits_per_second() / load.bit_rate);
  for (const auto& c : load.on_change) out += "    not counted: " + c + "\n";
  return out + bus_load_warning(load, name);
}

std::string bus_load_warning(const BusLoad& load, const std::string& name) {
  if (load.percent() <= kBusLoadWarnPercent) return "";
  return fmt::format(
      "warning: the {} bus is {:.1f} % loaded in the steady state, above {:.0f} %: too little room for "
      "change-driven frames, boot SDO traffic and retransmissions (lower the rates or raise {}.bitrate)\n",
      name, load.percent(), kBusLoadWarnPercent, name);
}

}  // namespace oegw::gateway
