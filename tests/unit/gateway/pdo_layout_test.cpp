// The default PDOs of the upstream device (CiA 852 clause 12) against the printed tables, as a
// property over every combination of configured instances: for each group of FE instances that
// share PDOs and each non-empty subset of it, the device built with exactly those FEs has every
// PDO of the kind, each mapping exactly its table's entries, and a changed value of a configured
// instance appears at its table's byte position in the TPDO frame (for RPDOs: an RPDO's bytes at
// that position reach the configured instance only). The table is written here from the document,
// not taken from profiles/cia852/pdo_defaults; where the document contradicts itself, it follows
// docs/design/cia852-decisions.md (TPDO n at 1800h + n − 1, Table 5/6/7 ranges, RPDO 34 absent).
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "gateway/gateway.hpp"
#include "gateway/oe_device.hpp"
#include "gateway/runtime_config.hpp"

namespace oegw::gateway {
namespace {

using namespace std::chrono_literals;
using canopen::CanFrame;
using canopen::NodeId;
using canopen::SdoAbortCode;
using canopen::TimePoint;
using mapping::FeId;
using mapping::FeKind;
using Bytes = std::vector<std::uint8_t>;

constexpr NodeId kId{0x20};

// ------------------------------------------------------------------ the tables, from CiA 852

// One mapping entry of a table: the object it maps, and which FE value it carries — the field a
// test writes to change it (a one-bit field changes its byte's bit `bit`).
struct DocEntry {
  std::uint32_t map = 0;  // index << 16 | sub << 8 | length
  FeId fe;
  std::string field;
  std::int64_t value = 0;  // what the test writes into `field`
  std::uint8_t expect_byte_or_bits = 0;
};
struct DocPdo {
  bool transmit = true;
  unsigned number = 0;
  std::vector<DocEntry> entries;
};

constexpr std::uint32_t map(unsigned index, unsigned sub, unsigned bits) { return index << 16 | sub << 8 | bits; }
FeId fe(FeKind k, unsigned n) { return {k, static_cast<std::uint8_t>(n)}; }

// An INTEGER16/32 value unique to the instance and the entry, never 0.
std::int64_t value16(unsigned n, unsigned i) { return 0x1100 + 0x10 * n + i; }

// Every PDO of a kind, as clause 12 prints it.
std::vector<DocPdo> doc_pdos(FeKind k) {
  std::vector<DocPdo> out;
  switch (k) {
    case FeKind::Joystick:
      // §12.2.1 Table 12 (TPDO 1) and §12.2.2 (TPDO 5..19 = joysticks 2..16, Table 1): 6401 x, y, z
      // (3n−2 … 3n, 10h), 6000 memory (2n−1, 08h), 6000 buttons (2n, 08h).
      for (unsigned n = 1; n <= 16; ++n) {
        const FeId j = fe(k, n);
        out.push_back({true,
                       n == 1 ? 1u : n + 3,
                       {{map(0x6401, 3 * n - 2, 0x10), j, "x", value16(n, 1)},
                        {map(0x6401, 3 * n - 1, 0x10), j, "y", value16(n, 2)},
                        {map(0x6401, 3 * n, 0x10), j, "z", value16(n, 3)},
                        {map(0x6000, 2 * n - 1, 0x08), j, "memory_y", 1, 0x02},
                        {map(0x6000, 2 * n, 0x08), j, "buttons[3]", 1, 0x04}}});
      }
      break;
    case FeKind::FootPedal:
      // §12.2.3 Table 16 (TPDO 20: 6000 21 08h, 6401 31 10h, 6000 22 08h, 6401 32 10h) and
      // §12.2.4 (TPDO 21..27: pedals 3..16, Table 2: memory 6000 20h+n, position 6401 30h+n).
      for (unsigned k2 = 0; k2 < 8; ++k2) {
        DocPdo p{true, 20 + k2, {}};
        for (unsigned n = 2 * k2 + 1; n <= 2 * k2 + 2; ++n) {
          p.entries.push_back({map(0x6000, 0x20 + n, 0x08), fe(k, n), "memory_x", 1, 0x01});
          p.entries.push_back({map(0x6401, 0x30 + n, 0x10), fe(k, n), "position", value16(n, 1)});
        }
        out.push_back(std::move(p));
      }
      break;
    case FeKind::Encoder:
      // §12.2.5 Table 20 (TPDO 28: 6120 81h, 6120 82h; 32 bits, §9.4) and §12.2.6 (TPDO 29..31).
      for (unsigned k2 = 0; k2 < 4; ++k2) {
        DocPdo p{true, 28 + k2, {}};
        for (unsigned n = 2 * k2 + 1; n <= 2 * k2 + 2; ++n)
          p.entries.push_back({map(0x6120, 0x80 + n, 0x20), fe(k, n), "position", 0x01020300 + n});
        out.push_back(std::move(p));
      }
      break;
    case FeKind::Wheel:
      // §12.2.7 Table 24 (TPDO 32: 6401 41h..44h, 10h) and §12.2.8 (TPDO 33: wheels 5..8, Table 4).
      for (unsigned k2 = 0; k2 < 2; ++k2) {
        DocPdo p{true, 32 + k2, {}};
        for (unsigned n = 4 * k2 + 1; n <= 4 * k2 + 4; ++n)
          p.entries.push_back({map(0x6401, 0x40 + n, 0x10), fe(k, n), "position", value16(n, 1)});
        out.push_back(std::move(p));
      }
      break;
    case FeKind::ButtonCluster:
      // §12.2.9 Table 28 (TPDO 34: 6000 31h..38h, 08h) and §12.2.10 (TPDO 35..41: clusters 2..8,
      // Table 5; cluster n at 31h + 8(n−1)).
      for (unsigned n = 1; n <= 8; ++n) {
        DocPdo p{true, 33 + n, {}};
        for (unsigned b = 0; b < 8; ++b)
          p.entries.push_back(
              {map(0x6000, 0x31 + 8 * (n - 1) + b, 0x08), fe(k, n), fmt::format("switch[{}]", 8 * b + 2), 1, 0x02});
        out.push_back(std::move(p));
      }
      break;
    case FeKind::IndicatorCluster:
      // §12.2.11 Table 32 (RPDO 1: 6200 01h..08h, 08h) and §12.2.12 (RPDO 5..11: clusters 2..8,
      // Table 6; cluster n at 01h + 8(n−1)).
      for (unsigned n = 1; n <= 8; ++n) {
        DocPdo p{false, n == 1 ? 1u : n + 3, {}};
        for (unsigned b = 0; b < 8; ++b)
          p.entries.push_back({map(0x6200, 1 + 8 * (n - 1) + b, 0x08), fe(k, n), "", 0x11 * (b + 1), 0});
        out.push_back(std::move(p));
      }
      break;
    case FeKind::Display:
      // §12.2.13 Table 36 (RPDO 2: 6411 01h..04h, 10h), §12.2.14 (display 1 also on RPDO 4 and 12,
      // displays 2..8 on RPDO 13..33, three each; Table 7: parameter p of display n at 12(n−1)+p).
      for (unsigned n = 1; n <= 8; ++n) {
        const unsigned numbers[3] = {n == 1 ? 2u : 13 + 3 * (n - 2), n == 1 ? 4u : 14 + 3 * (n - 2),
                                     n == 1 ? 12u : 15 + 3 * (n - 2)};
        for (unsigned r = 0; r < 3; ++r) {
          DocPdo p{false, numbers[r], {}};
          for (unsigned i = 1; i <= 4; ++i)
            p.entries.push_back({map(0x6411, 12 * (n - 1) + 4 * r + i, 0x10), fe(k, n), "", value16(n, 4 * r + i), 0});
          out.push_back(std::move(p));
        }
      }
      break;
  }
  return out;
}

// The groups of instances that share PDOs (each instance of the other kinds is its own group).
std::vector<std::vector<FeId>> groups() {
  std::vector<std::vector<FeId>> g;
  for (unsigned n = 1; n <= 16; ++n) g.push_back({fe(FeKind::Joystick, n)});
  for (unsigned k2 = 0; k2 < 8; ++k2)
    g.push_back({fe(FeKind::FootPedal, 2 * k2 + 1), fe(FeKind::FootPedal, 2 * k2 + 2)});
  for (unsigned k2 = 0; k2 < 4; ++k2) g.push_back({fe(FeKind::Encoder, 2 * k2 + 1), fe(FeKind::Encoder, 2 * k2 + 2)});
  for (unsigned k2 = 0; k2 < 2; ++k2) {
    std::vector<FeId> w;
    for (unsigned n = 4 * k2 + 1; n <= 4 * k2 + 4; ++n) w.push_back(fe(FeKind::Wheel, n));
    g.push_back(w);
  }
  for (const FeKind k : {FeKind::ButtonCluster, FeKind::IndicatorCluster, FeKind::Display})
    for (unsigned n = 1; n <= 8; ++n) g.push_back({fe(k, n)});
  return g;
}

// ------------------------------------------------------------------ the device

class Device {
 public:
  explicit Device(std::vector<FeId> fes) {
    OeDeviceConfig c;
    c.node_id = kId;
    c.heartbeat_ms = 0;
    c.fes = std::move(fes);
    dev = std::make_unique<OeDevice>(std::move(c), [this](const CanFrame& f) { out.push_back(f); });
    dev->start(now);
    out.clear();
  }
  void rx(std::uint32_t id, const Bytes& b) {
    out.clear();
    dev->on_frame(CanFrame(id, std::span<const std::uint8_t>(b)), now);
  }
  // An expedited SDO download; the abort code (0 = confirmed).
  std::uint32_t download(std::uint16_t index, std::uint8_t sub, const Bytes& data) {
    const auto cs = static_cast<std::uint8_t>(0x23 | ((4 - data.size()) << 2));
    Bytes f{cs, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0};
    std::copy(data.begin(), data.end(), f.begin() + 4);
    rx(0x600 + kId.value(), f);
    const auto r = frames(0x580 + kId.value());
    if (r.size() != 1) return 0xFFFFFFFFu;
    if (r[0].data[0] == 0x60) return 0;
    return static_cast<std::uint32_t>(r[0].data[4] | r[0].data[5] << 8 | r[0].data[6] << 16 | r[0].data[7] << 24);
  }
  // An expedited SDO upload: the bytes, empty on an abort.
  Bytes upload(std::uint16_t index, std::uint8_t sub) {
    rx(0x600 + kId.value(),
       {0x40, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub, 0, 0, 0, 0});
    const auto r = frames(0x580 + kId.value());
    if (r.size() != 1 || (r[0].data[0] & 0xE3) != 0x43) return {};
    const std::size_t n = 4 - ((r[0].data[0] >> 2) & 3);
    return Bytes(r[0].data.begin() + 4, r[0].data.begin() + 4 + static_cast<std::ptrdiff_t>(n));
  }
  std::vector<CanFrame> frames(std::uint32_t id) const {
    std::vector<CanFrame> r;
    for (const auto& f : out)
      if (f.id == id) r.push_back(f);
    return r;
  }
  canopen::ObjectDictionary& od() { return dev->od(); }

  TimePoint now{std::chrono::seconds(10)};
  std::vector<CanFrame> out;
  std::unique_ptr<OeDevice> dev;
};

std::string hex(std::uint32_t v) { return fmt::format("{:08X}h", v); }

Bytes le(std::int64_t v, unsigned bytes) {
  Bytes b;
  for (unsigned i = 0; i < bytes; ++i) b.push_back(static_cast<std::uint8_t>(static_cast<std::uint64_t>(v) >> (8 * i)));
  return b;
}

// Byte offset of entry i of a PDO.
unsigned offset_of(const DocPdo& p, std::size_t i) {
  unsigned bits = 0;
  for (std::size_t k = 0; k < i; ++k) bits += p.entries[k].map & 0xFF;
  return bits / 8;
}
unsigned length_of(const DocPdo& p) { return offset_of(p, p.entries.size()); }

bool configured(const std::vector<FeId>& fes, const FeId& f) {
  return std::find(fes.begin(), fes.end(), f) != fes.end();
}

// The mapping and communication objects of every PDO of the kind, exactly as the tables print,
// and no other PDO; every mapped entry exists, reads 0 by SDO when its instance is not
// configured.
void check_objects(Device& d, const std::vector<FeId>& subset, const std::vector<DocPdo>& pdos,
                   const std::string& what) {
  std::set<std::uint16_t> expected;
  for (const DocPdo& p : pdos) {
    const auto comm = static_cast<std::uint16_t>((p.transmit ? 0x1800 : 0x1400) + p.number - 1);
    const auto map_index = static_cast<std::uint16_t>(comm + 0x200);
    expected.insert(comm);
    expected.insert(map_index);
    const std::string pdo = fmt::format("{} {}{} ({:04X}h)", what, p.transmit ? "TPDO " : "RPDO ", p.number, map_index);
    ASSERT_NE(d.od().find(comm), nullptr) << pdo;
    ASSERT_NE(d.od().find(map_index), nullptr) << pdo;
    // Tables 10 / 14 …: disabled; TPDO 1 8000 0180h + node-ID, every other 8000 0000h; type FFh.
    const std::uint32_t cob = p.transmit && p.number == 1 ? 0x80000180u + kId.value() : 0x80000000u;
    EXPECT_EQ(d.od().get<std::uint32_t>(comm, 1), cob) << pdo;
    EXPECT_EQ(d.od().get<std::uint8_t>(comm, 2), 0xFF) << pdo;
    ASSERT_EQ(d.od().get<std::uint8_t>(map_index, 0), p.entries.size()) << pdo;
    for (std::size_t i = 0; i < p.entries.size(); ++i) {
      const DocEntry& e = p.entries[i];
      EXPECT_EQ(hex(d.od().get<std::uint32_t>(map_index, static_cast<std::uint8_t>(i + 1))), hex(e.map))
          << pdo << " sub " << i + 1;
      const auto index = static_cast<std::uint16_t>(e.map >> 16);
      const auto sub = static_cast<std::uint8_t>(e.map >> 8);
      ASSERT_NE(d.od().find(index, sub), nullptr) << pdo << " maps " << hex(e.map) << ", which does not exist";
      if (!configured(subset, e.fe)) {
        EXPECT_EQ(d.upload(index, sub), Bytes((e.map & 0xFF) / 8, 0))
            << pdo << ": " << mapping::fe_name(e.fe) << " is not configured, " << hex(e.map) << " reads 0";
      }
    }
  }
  std::set<std::uint16_t> present;
  for (const auto& [i, o] : d.od().objects())
    if (i >= 0x1400 && i <= 0x1BFF) present.insert(i);
  EXPECT_EQ(present, expected) << what << ": exactly the PDOs of the kind";
}

// Each configured instance's value changes one at a time; each change sends the TPDO, whose bytes
// at the table's position carry it. The frame's length is the table's.
void check_tpdo_frames(Device& d, const std::vector<FeId>& subset, const std::vector<DocPdo>& pdos,
                       const std::string& what) {
  // CiA 401 6423h TRUE: analogue changes are events (6423h exists with analogue inputs only).
  if (d.od().find(0x6423) != nullptr) {
    ASSERT_EQ(d.download(0x6423, 0, {1}), 0u) << what;
  }
  std::map<unsigned, std::uint32_t> cob_of;
  for (const DocPdo& p : pdos) {
    if (std::none_of(p.entries.begin(), p.entries.end(), [&](const DocEntry& e) { return configured(subset, e.fe); }))
      continue;
    cob_of[p.number] = 0x190 + p.number;
    ASSERT_EQ(d.download(static_cast<std::uint16_t>(0x1800 + p.number - 1), 1, le(cob_of[p.number], 4)), 0u) << what;
  }
  d.rx(0x000, {0x01, kId.value()});  // NMT start: every TPDO goes out once
  d.out.clear();
  for (const DocPdo& p : pdos) {
    if (!cob_of.count(p.number)) continue;
    Bytes frame(length_of(p), 0);
    for (std::size_t i = 0; i < p.entries.size(); ++i) {
      const DocEntry& e = p.entries[i];
      if (!configured(subset, e.fe)) continue;
      const std::string at = fmt::format("{}: TPDO {} {} {} (mapping sub {}, byte {})", what, p.number,
                                         mapping::fe_name(e.fe), e.field, i + 1, offset_of(p, i));
      ASSERT_TRUE(d.dev->set_input(e.fe, e.field, e.value, d.now)) << at;
      const auto sent = d.frames(cob_of[p.number]);
      ASSERT_EQ(sent.size(), 1u) << at;
      const unsigned width = (e.map & 0xFF) / 8;
      const Bytes v = e.expect_byte_or_bits != 0 ? Bytes{e.expect_byte_or_bits} : le(e.value, width);
      std::copy(v.begin(), v.end(), frame.begin() + offset_of(p, i));
      EXPECT_EQ(Bytes(sent[0].data.begin(), sent[0].data.begin() + sent[0].dlc), frame) << at;
      d.out.clear();
    }
  }
}

// An RPDO carrying a value in every entry: the configured instance's entries take them, the
// entries of an instance not configured stay 0.
void check_rpdo_frames(Device& d, const std::vector<FeId>& subset, const std::vector<DocPdo>& pdos,
                       const std::string& what) {
  for (const DocPdo& p : pdos) {
    const std::uint32_t cob = 0x200 + p.number;
    ASSERT_EQ(d.download(static_cast<std::uint16_t>(0x1400 + p.number - 1), 1, le(cob, 4)), 0u) << what;
  }
  d.rx(0x000, {0x01, kId.value()});
  for (const DocPdo& p : pdos) {
    Bytes frame;
    for (const DocEntry& e : p.entries) {
      const Bytes v = le(e.value, (e.map & 0xFF) / 8);
      frame.insert(frame.end(), v.begin(), v.end());
    }
    ASSERT_EQ(frame.size(), length_of(p));
    d.rx(0x200 + p.number, frame);
    for (std::size_t i = 0; i < p.entries.size(); ++i) {
      const DocEntry& e = p.entries[i];
      const auto index = static_cast<std::uint16_t>(e.map >> 16);
      const auto sub = static_cast<std::uint8_t>(e.map >> 8);
      const unsigned width = (e.map & 0xFF) / 8;
      const Bytes want = configured(subset, e.fe) ? le(e.value, width) : Bytes(width, 0);
      EXPECT_EQ(d.upload(index, sub), want) << what << ": RPDO " << p.number << " byte " << offset_of(p, i) << " -> "
                                            << mapping::fe_name(e.fe) << " " << hex(e.map);
    }
  }
}

std::string names(const std::vector<FeId>& fes) {
  std::string s;
  for (const auto& f : fes) s += (s.empty() ? "" : "+") + mapping::fe_name(f);
  return s;
}

// ------------------------------------------------------------------ the property

// CiA 852 clause 12, Tables 12–36: for every group and every non-empty subset of its instances.
TEST(PdoLayout, EveryCombinationOfConfiguredInstancesSitsWhereItsTablePrintsIt) {
  std::size_t devices = 0;
  for (const auto& group : groups()) {
    const std::vector<DocPdo> pdos = doc_pdos(group.front().kind);
    for (unsigned bits = 1; bits < (1u << group.size()); ++bits) {
      std::vector<FeId> subset;
      for (std::size_t i = 0; i < group.size(); ++i)
        if (bits & (1u << i)) subset.push_back(group[i]);
      const std::string what = names(subset);
      {
        Device d(subset);
        check_objects(d, subset, pdos, what);
      }
      Device d(subset);
      if (mapping::is_input(group.front().kind)) {
        check_tpdo_frames(d, subset, pdos, what);
      } else {
        check_rpdo_frames(d, subset, pdos, what);
      }
      ++devices;
      if (::testing::Test::HasFatalFailure()) return;
    }
  }
  EXPECT_EQ(devices, 16u + 8 * 3 + 4 * 3 + 2 * 15 + 3 * 8);
}

// §12.2.1 / §5.3: a cab with only a left-hand joystick (joystick 2) still has TPDO 1, Table 12's
// mapping of joystick 1's entries, which read 0 (centred, released) and never change.
TEST(PdoLayout, OnlyJoystick2HasTpdo1WithTheTablesMapping) {
  Device d({fe(FeKind::Joystick, 2)});
  ASSERT_NE(d.od().find(0x1800), nullptr);
  EXPECT_EQ(d.od().get<std::uint32_t>(0x1800, 1), 0x800001A0u);
  ASSERT_EQ(d.od().get<std::uint8_t>(0x1A00, 0), 5);
  EXPECT_EQ(d.od().get<std::uint32_t>(0x1A00, 1), 0x64010110u);
  EXPECT_EQ(d.od().get<std::uint32_t>(0x1A00, 2), 0x64010210u);
  EXPECT_EQ(d.od().get<std::uint32_t>(0x1A00, 3), 0x64010310u);
  EXPECT_EQ(d.od().get<std::uint32_t>(0x1A00, 4), 0x60000108u);
  EXPECT_EQ(d.od().get<std::uint32_t>(0x1A00, 5), 0x60000208u);
  // The host enables TPDO 1 on 1A0h and starts the node: 8 bytes of zeros, and nothing when
  // joystick 2 moves.
  ASSERT_EQ(d.download(0x6423, 0, {1}), 0u);
  ASSERT_EQ(d.download(0x1800, 1, le(0x1A0, 4)), 0u);
  d.rx(0x000, {0x01, kId.value()});
  const auto boot = d.frames(0x1A0);
  ASSERT_EQ(boot.size(), 1u);
  EXPECT_EQ(Bytes(boot[0].data.begin(), boot[0].data.begin() + boot[0].dlc), Bytes(8, 0));
  d.out.clear();
  ASSERT_TRUE(d.dev->set_input(fe(FeKind::Joystick, 2), "x", 1000, d.now));
  EXPECT_TRUE(d.frames(0x1A0).empty());
  // Joystick 1 is not an FE of this device: the gateway does not write it.
  EXPECT_FALSE(d.dev->set_input(fe(FeKind::Joystick, 1), "x", 1000, d.now));
  // 1000h: the kind, as before (joystick with buttons).
  EXPECT_EQ(d.od().get<std::uint32_t>(0x1000, 0), 0x81850191u);
}

// The entries of an instance that is not configured read their documented value by SDO (0, see
// docs/design/cia852-decisions.md), input entries are read-only, output entries refuse a host write
// (0800 0020h) and ignore their bytes in an RPDO.
TEST(PdoLayout, UnconfiguredInstancesReadTheirNeutralValueAndNeverChange) {
  Device d({fe(FeKind::FootPedal, 2), fe(FeKind::Wheel, 3), fe(FeKind::Encoder, 2), fe(FeKind::IndicatorCluster, 2),
            fe(FeKind::Display, 1)});
  EXPECT_EQ(d.upload(0x6000, 0x21), Bytes{0});             // pedal 1 memory: off
  EXPECT_EQ(d.upload(0x6401, 0x31), (Bytes{0, 0}));        // pedal 1 position
  EXPECT_EQ(d.upload(0x6401, 0x41), (Bytes{0, 0}));        // wheel 1
  EXPECT_EQ(d.upload(0x6120, 0x81), (Bytes{0, 0, 0, 0}));  // encoder 1
  EXPECT_EQ(d.upload(0x6200, 0x01), Bytes{0});             // indicator cluster 1: off
  EXPECT_EQ(d.upload(0x6411, 0x0D), (Bytes{0, 0}));        // display 2 parameter 1
  EXPECT_EQ(d.download(0x6401, 0x31, {1, 0}), static_cast<std::uint32_t>(SdoAbortCode::WriteOfReadOnly));
  EXPECT_EQ(d.download(0x6200, 0x01, {0xFF}), static_cast<std::uint32_t>(SdoAbortCode::CannotTransfer));
  EXPECT_EQ(d.download(0x6411, 0x0D, {1, 0}), static_cast<std::uint32_t>(SdoAbortCode::CannotTransfer));
  EXPECT_EQ(d.upload(0x6200, 0x01), Bytes{0});
  // The configured cluster's entries take host writes.
  EXPECT_EQ(d.download(0x6200, 0x09, {0x5A}), 0u);
  EXPECT_EQ(d.upload(0x6200, 0x09), Bytes{0x5A});
  // RPDO 1 (cluster 1, not configured) changes nothing.
  ASSERT_EQ(d.download(0x1400, 1, le(0x201, 4)), 0u);
  d.rx(0x000, {0x01, kId.value()});
  d.rx(0x201, Bytes(8, 0xFF));
  for (std::uint8_t s = 1; s <= 8; ++s) EXPECT_EQ(d.upload(0x6200, s), Bytes{0}) << int(s);
  // 6206h/6207h only for the configured cluster.
  EXPECT_EQ(d.od().find(0x6206, 0x01), nullptr);
  EXPECT_NE(d.od().find(0x6206, 0x09), nullptr);
  // Their names say so (the EDS's ParameterName).
  EXPECT_EQ(d.od().find(0x6401, 0x31)->name, "pedal 1 position (not configured)");
  EXPECT_EQ(d.od().find(0x6401, 0x32)->name, "pedal 2 position");
}

// The EDS (`oegw eds`) lists the PDOs and entries the device has and says where a host built from
// the printed tables would differ ([Comments], docs/design/cia852-decisions.md).
TEST(PdoLayout, TheEdsCommentsWhereThePrintedTablesDiffer) {
  auto r = mapping::load_config_text(
      "upstream: { interface: virtual, node_id: 0x20 }\n"
      "downstream: { interface: virtual }\n"
      "subdevices:\n"
      "  pedal: { driver: cia401, node_id: 0x30, options: { eds: " OEGW_SOURCE_DIR
      "/subdevices/eds/generic_pedal.eds } }\n"
      "functional_elements:\n"
      "  pedal.2: { position: \"pedal.analog[1]\" }\n",
      "test.yaml", driver_catalogue());
  ASSERT_TRUE(r.ok()) << r.error_text();
  const std::string eds = upstream_eds(*r.config, "oegw.eds");
  EXPECT_NE(eds.find("TPDO 20..27 are at 1813h..181Ah / 1A13h..1A1Ah"), std::string::npos) << eds;
  EXPECT_NE(eds.find("pedal 1, 3..16 not configured"), std::string::npos) << eds;
  EXPECT_NE(eds.find("[1A13sub4]\nParameterName="), std::string::npos);
  EXPECT_NE(eds.find("[6401sub31]\nParameterName=pedal 1 position (not configured)"), std::string::npos);
  EXPECT_EQ(eds.find("[1A1B]"), std::string::npos);  // no encoder: no TPDO 28
}

}  // namespace
}  // namespace oegw::gateway
