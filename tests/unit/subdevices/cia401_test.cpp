// The generic CiA 401 driver (subdevices/cia401.hpp) without a bus: its mapping read answered
// from a dictionary built from the same EDS, frames fed by hand. Documents: CiA 401 (objects
// 6000h, 6120h, 6401h, 6200h, 6411h), CiA 301 §7.2.2 / §7.5.2.35–38 (PDO communication and
// mapping parameters, bit packing), CiA 301 §7.2.7.1 Table 26 (EMCY codes), CiA 306 (EDS).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "canopen/301/pdo.hpp"
#include "canopen/state.hpp"
#include "subdevices/cia401.hpp"
#include "subdevices/families.hpp"
#include "tests/unit/canopen/state_twin.hpp"

namespace oegw::subdevices {
namespace {

using canopen::SdoAbortCode;
using Bytes = std::vector<std::uint8_t>;

const std::filesystem::path kRoot = OEGW_SOURCE_DIR;  // the source tree (tests/CMakeLists.txt)
const std::string kPedal = (kRoot / "subdevices/eds/generic_pedal.eds").string();
const std::string kCluster = (kRoot / "subdevices/eds/button_cluster.eds").string();
constexpr NodeId kNode{0x21};
const TimePoint t0{canopen::Duration{5'000'000}};

struct Fixture {
  std::vector<CanFrame> sent;
  std::unique_ptr<Cia401Driver> drv;
  std::unique_ptr<canopen::ObjectDictionary> node_od;  // what the node would answer
  std::vector<std::pair<std::size_t, SignalValue>> changes;

  explicit Fixture(const std::string& eds_path) {
    std::string error;
    auto d = make_cia401_driver(
        kNode, [this](const CanFrame& f) { sent.push_back(f); }, DriverOptions{{{"eds", eds_path}}}, error);
    EXPECT_TRUE(d) << error;
    drv.reset(static_cast<Cia401Driver*>(d.release()));
    drv->on_change = [this](std::size_t i, const SignalValue& v) { changes.emplace_back(i, v); };
    node_od = canopen::eds::build_dictionary(drv->eds(), kNode);
    for (std::uint16_t n = 1; n <= 4; ++n) {
      if (auto p = canopen::eds::pdo_defaults(drv->eds(), true, n, kNode)) canopen::install_tpdo(*node_od, n, *p);
      if (auto p = canopen::eds::pdo_defaults(drv->eds(), false, n, kNode)) canopen::install_rpdo(*node_od, n, *p);
    }
  }
  // The network manager's loop, answered from node_od; returns the number of reads made.
  int read_mapping() {
    int reads = 0;
    for (auto r = drv->mapping_reads(); !r.empty(); r = drv->mapping_reads()) {
      for (const auto& q : r) {
        ++reads;
        Bytes data;
        const auto code = node_od->read(q.index, q.sub, data);
        if (code == SdoAbortCode::None) {
          EXPECT_EQ(drv->apply_mapping_read(q.index, q.sub, data), SdoAbortCode::None) << q.what;
        } else {
          drv->apply_mapping_abort(q.index, q.sub, code);
        }
      }
      if (reads > 1000) break;
    }
    return reads;
  }
  std::size_t sig(const std::string& name) {
    auto i = drv->find_signal(name);
    EXPECT_TRUE(i) << name;
    return i.value_or(0);
  }
  std::int64_t val(const std::string& name) { return drv->value(sig(name)).value; }
  SignalStatus status(const std::string& name) { return drv->value(sig(name)).status; }
};

std::vector<std::string> names(const Driver& d) {
  std::vector<std::string> out;
  for (const auto& s : d.signals()) out.push_back(s.name);
  return out;
}

TEST(Cia401, SignalsFollowTheEdsObjects) {
  Fixture pedal(kPedal);
  EXPECT_EQ(names(*pedal.drv), (std::vector<std::string>{"in[1]", "analog[1]", "analog[2]"}));
  const auto& a = pedal.drv->signals()[1];
  EXPECT_EQ(a.kind, SignalKind::Analog);
  EXPECT_EQ(a.min, -32768);
  EXPECT_EQ(a.max, 32767);
  EXPECT_EQ(a.unit, "raw16");
  Fixture cl(kCluster);
  EXPECT_EQ(names(*cl.drv), (std::vector<std::string>{"in[1]", "in[2]", "in32[1]", "out[1]", "out[2]", "aout[1]"}));
  const auto& in32 = cl.drv->signals()[2];
  EXPECT_EQ(in32.kind, SignalKind::Digital) << "CiA 401 6120h is 'read input 32-bit', digital lines";
  EXPECT_EQ(in32.max, 0xFFFFFFFFll);
  const auto& out = cl.drv->signals()[3];
  EXPECT_TRUE(out.output());
  EXPECT_EQ(out.max, 255);
  const auto& aout = cl.drv->signals()[5];
  EXPECT_TRUE(aout.output());
  EXPECT_EQ(aout.min, 0) << "the EDS LowLimit of 6411h:1";
  EXPECT_EQ(aout.max, 1000) << "the EDS HighLimit of 6411h:1";
}

TEST(Cia401, FactoryOptionsAndEdsErrors) {
  std::string error;
  EXPECT_EQ(make_cia401_driver(kNode, {}, DriverOptions{}, error), nullptr);
  EXPECT_EQ(error, "cia401: option 'eds' (path of the node's EDS file) is required");
  EXPECT_EQ(make_cia401_driver(kNode, {}, DriverOptions{{{"eds", kPedal}, {"edz", "x"}}}, error), nullptr);
  EXPECT_EQ(error, "cia401: unknown option 'edz' (expected eds, freshness_floor_ms)");
  EXPECT_EQ(make_cia401_driver(kNode, {}, DriverOptions{{{"eds", "/nonexistent/x.eds"}}}, error), nullptr);
  EXPECT_EQ(error, "cia401: EDS file /nonexistent/x.eds does not exist");
  // A path that is there but cannot be read is the reader's refusal.
  EXPECT_EQ(make_cia401_driver(kNode, {}, DriverOptions{{{"eds", "/"}}}, error), nullptr);
  EXPECT_EQ(error, "cia401: /: is a directory; expected a regular file (an EDS file)");
  const auto bad = std::filesystem::temp_directory_path() / ("oegw-cia401-bad-" + std::to_string(::getpid()) + ".eds");
  {
    std::ofstream f(bad);
    f << "[MandatoryObjects]\nSupportedObjects=1\n1=0x1000\n";
  }
  EXPECT_EQ(make_cia401_driver(kNode, {}, DriverOptions{{{"eds", bad.string()}}}, error), nullptr);
  EXPECT_EQ(error,
            "cia401: " + bad.string() + ":3: expected a section [1000] for the object listed in [MandatoryObjects]");
  std::filesystem::remove(bad);
  auto ok = make_cia401_driver(kNode, {}, DriverOptions{{{"eds", kPedal}}}, error);
  ASSERT_NE(ok, nullptr);
  EXPECT_EQ(ok->family(), "cia401");
  EXPECT_EQ(ok->node(), kNode);
}

TEST(Cia401, ExpectedIdentityFromEds) {
  Fixture pedal(kPedal);
  const auto id = pedal.drv->expected_identity();
  EXPECT_EQ(id.device_type, 0x00050191u) << "CiA 401 device type: profile 401 (0191h), DI + AI";
  EXPECT_EQ(id.vendor_id, 0x00000A5Au);
  EXPECT_EQ(id.product_code, 0x401u);
  EXPECT_EQ(id.revision, 0x00010000u);
  EXPECT_FALSE(id.serial);
}

// CiA 301 §7.5.2.35–38: the reads cover COB-ID, transmission type and sub 0 first, then the
// entries 1..n once n is known; a PDO whose COB-ID is not valid needs no mapping.
TEST(Cia401, MappingReadsAreAskedStepByStep) {
  Fixture f(kPedal);
  auto r = f.drv->mapping_reads();
  ASSERT_EQ(r.size(), 6u);
  EXPECT_EQ(r[0].index, 0x1800);
  EXPECT_EQ(r[0].sub, 1);
  EXPECT_EQ(r[1].index, 0x1800);
  EXPECT_EQ(r[1].sub, 2);
  EXPECT_EQ(r[2].index, 0x1A00);
  EXPECT_EQ(r[2].sub, 0);
  EXPECT_EQ(r[3].index, 0x1801);
  EXPECT_FALSE(f.drv->mapping_complete());
  EXPECT_EQ(f.drv->apply_mapping_read(0x1800, 1, canopen::encode<std::uint32_t>(0x1A1)), SdoAbortCode::None);
  EXPECT_EQ(f.drv->apply_mapping_read(0x1800, 2, Bytes{0xFF}), SdoAbortCode::None);
  EXPECT_EQ(f.drv->apply_mapping_read(0x1A00, 0, Bytes{2}), SdoAbortCode::None);
  EXPECT_EQ(f.drv->apply_mapping_read(0x1801, 1, canopen::encode<std::uint32_t>(0x800002A1)), SdoAbortCode::None);
  EXPECT_EQ(f.drv->apply_mapping_read(0x1801, 2, Bytes{0xFF}), SdoAbortCode::None);
  r = f.drv->mapping_reads();
  ASSERT_EQ(r.size(), 3u) << "TPDO2 is not valid: its mapping is not read";
  EXPECT_EQ(r[0].index, 0x1A00);
  EXPECT_EQ(r[0].sub, 1);
  EXPECT_EQ(r[1].sub, 2);
  EXPECT_EQ(r[2].index, 0x1800) << "TPDO1's event timer, as the node has it";
  EXPECT_EQ(r[2].sub, 5);
  EXPECT_TRUE(f.drv->consumed_cob_ids().empty());
  EXPECT_EQ(f.drv->apply_mapping_read(0x1A00, 1, canopen::encode<std::uint32_t>(0x60000108)), SdoAbortCode::None);
  EXPECT_EQ(f.drv->apply_mapping_read(0x1A00, 2, canopen::encode<std::uint32_t>(0x64010210)), SdoAbortCode::None);
  EXPECT_FALSE(f.drv->mapping_complete()) << "the event timer is still unknown";
  EXPECT_EQ(f.drv->apply_mapping_read(0x1800, 5, canopen::encode<std::uint16_t>(200)), SdoAbortCode::None);
  EXPECT_TRUE(f.drv->mapping_complete());
  f.drv->apply_boot_writes({});  // what the network manager does before NMT start
  EXPECT_EQ(f.drv->freshness(f.sig("in[1]")), std::chrono::milliseconds(600)) << "3 x the node's 200 ms";
  EXPECT_EQ(f.drv->consumed_cob_ids(), (std::vector<std::uint32_t>{0x1A1}));
  EXPECT_FALSE(f.drv->needs_sync()) << "TPDO1 is event-driven (FFh)";
  // CiA 301 §7.2.2: 6000h:1 in byte 0, 6401h:2 in bytes 1..2 (this mapping, not the EDS's).
  EXPECT_TRUE(f.drv->on_frame(CanFrame(0x1A1, {0x81, 0x34, 0x12}), t0));
  EXPECT_EQ(f.val("in[1]"), 0x81);
  EXPECT_EQ(f.val("analog[2]"), 0x1234);
  EXPECT_EQ(f.status("analog[1]"), SignalStatus::Offline) << "not mapped: never updated";
  f.drv->reset_mapping();
  EXPECT_TRUE(f.drv->consumed_cob_ids().empty());
  EXPECT_EQ(f.drv->mapping_reads().size(), 6u);
}

TEST(Cia401, RefusedMappingValuesDisableThatPdo) {
  Fixture f(kPedal);
  EXPECT_EQ(f.drv->apply_mapping_read(0x1802, 1, canopen::encode<std::uint32_t>(0x1A1)),
            SdoAbortCode::ObjectDoesNotExist);
  EXPECT_EQ(f.drv->apply_mapping_read(0x1A00, 1, canopen::encode<std::uint32_t>(0x60000108)),
            SdoAbortCode::SubIndexDoesNotExist)
      << "an entry before the count is known";
  EXPECT_EQ(f.drv->apply_mapping_read(0x1800, 7, Bytes{0}), SdoAbortCode::SubIndexDoesNotExist);
  EXPECT_EQ(f.drv->apply_mapping_read(0x1800, 1, Bytes{0xA1, 0x01, 0x00}), SdoAbortCode::LengthMismatch);
  EXPECT_EQ(f.drv->apply_mapping_read(0x1A01, 0, Bytes{65}), SdoAbortCode::ValueTooHigh)
      << "CiA 301 §7.5.2.36: at most 64 mapping entries";
  EXPECT_TRUE(f.drv->mapping_reads().empty()) << "both PDOs refused: nothing left to ask";
  EXPECT_TRUE(f.drv->consumed_cob_ids().empty());
  EXPECT_FALSE(f.drv->on_frame(CanFrame(0x1A1, {1, 2, 3, 4, 5}), t0));
  EXPECT_EQ(f.drv->counters().unknown_cob, 1u);
  // An SDO abort of a read (the node lacks the object) disables that PDO too.
  Fixture g(kPedal);
  g.drv->apply_mapping_abort(0x1801, 1, SdoAbortCode::ObjectDoesNotExist);
  EXPECT_GT(g.read_mapping(), 0);
  EXPECT_EQ(g.drv->consumed_cob_ids(), (std::vector<std::uint32_t>{0x1A1}));
}

// CiA 301 §7.3.5: a PDO on a restricted CAN-ID is refused, naming the ID. An RPDO read back on
// 000h would have the gateway send its outputs as NMT commands; a TPDO on 711h would read a
// heartbeat as inputs.
TEST(Cia401, APdoOnARestrictedCanIdIsRefused) {
  for (const std::uint32_t id : {0x000u, 0x711u, 0x5A1u, 0x7E5u, 0x150u}) {
    Fixture f(kCluster);
    const std::uint16_t index = 0x1400;  // RPDO1: the outputs
    std::string error;
    EXPECT_FALSE(f.drv->on_boot_read(index, 1, canopen::encode<std::uint32_t>(id), error)) << std::hex << id;
    char want[16];
    std::snprintf(want, sizeof want, "COB-ID %03Xh", id);
    EXPECT_NE(error.find(want), std::string::npos) << error;
    EXPECT_NE(error.find("restricted CAN-ID (CiA 301 §7.3.5"), std::string::npos) << error;
    f.read_mapping();
    EXPECT_FALSE(f.drv->set_output(f.sig("out[2]"), 0x81, t0)) << "RPDO1 is not used";
    EXPECT_TRUE(f.sent.empty());
  }
  // Not valid (bit 31), or an extended 29-bit one: not restricted.
  Fixture g(kCluster);
  std::string error;
  EXPECT_TRUE(g.drv->on_boot_read(0x1400, 1, canopen::encode<std::uint32_t>(0x80000000u), error)) << error;
  Fixture h(kPedal);
  EXPECT_TRUE(h.drv->on_boot_read(0x1800, 1, canopen::encode<std::uint32_t>(0x20000711u), error)) << error;
}

// CiA 301 §7.5.2.35: transmission types 0..240 are synchronous.
TEST(Cia401, SynchronousPdoMeansSyncIsNeeded) {
  Fixture f(kPedal);
  f.node_od->find(0x1800, 2)->value = {1};
  f.read_mapping();
  EXPECT_TRUE(f.drv->needs_sync());
  f.node_od->find(0x1800, 2)->value = {0xFE};
  f.drv->reset_mapping();
  f.read_mapping();
  EXPECT_FALSE(f.drv->needs_sync());
}

TEST(Cia401, NoFrameIsUsedBeforeTheMappingIsRead) {
  Fixture f(kPedal);
  EXPECT_FALSE(f.drv->on_frame(CanFrame(0x1A1, {1, 0, 2, 0, 3}), t0));
  EXPECT_EQ(f.drv->counters().unknown_cob, 1u);
  EXPECT_TRUE(f.changes.empty());
}

// CiA 301 §7.2.2 / EDS default mapping of the pedal: 6401h:1, 6401h:2 (INTEGER16), 6000h:1.
TEST(Cia401, PedalTpdoDecodedWithSignAndStatus) {
  Fixture f(kPedal);
  f.read_mapping();
  ASSERT_TRUE(f.drv->mapping_complete());
  ASSERT_EQ(f.drv->consumed_cob_ids(), (std::vector<std::uint32_t>{0x1A1}));
  EXPECT_TRUE(f.drv->on_frame(CanFrame(0x1A1, {0xFE, 0xFF, 0xE8, 0x03, 0xA5}), t0));
  EXPECT_EQ(f.val("analog[1]"), -2);
  EXPECT_EQ(f.val("analog[2]"), 1000);
  EXPECT_EQ(f.val("in[1]"), 0xA5);
  EXPECT_EQ(f.status("analog[1]"), SignalStatus::Valid);
  EXPECT_EQ(f.drv->value(f.sig("in[1]")).timestamp, t0);
  EXPECT_EQ(f.changes.size(), 3u);
  // Wrong length: counted, ignored, nothing passed through.
  EXPECT_FALSE(f.drv->on_frame(CanFrame(0x1A1, {0x00, 0x00, 0x00, 0x00}), t0 + canopen::Duration{1000}));
  EXPECT_FALSE(f.drv->on_frame(CanFrame(0x1A1, {0, 0, 0, 0, 0, 0}), t0 + canopen::Duration{1000}));
  EXPECT_EQ(f.drv->counters().wrong_length, 2u);
  EXPECT_EQ(f.val("analog[1]"), -2);
  // Unknown COB-ID from this node: counted.
  EXPECT_FALSE(f.drv->on_frame(CanFrame(0x2A1, {0}), t0));
  EXPECT_EQ(f.drv->counters().unknown_cob, 1u);
}

// A mapping with a dummy entry (CiA 301 §7.5.2.36: index 0005h = UNSIGNED8 dummy) and an object
// the driver does not know is decoded around them.
TEST(Cia401, DummyAndForeignEntriesAreSkipped) {
  Fixture f(kPedal);
  f.node_od->add_var(0x2000, "Vendor temperature", canopen::DataType::Unsigned16, canopen::Access::ReadOnly, {0, 0},
                     true);
  ASSERT_EQ(f.node_od->write(0x1A00, 0, Bytes{0}, canopen::Origin::Local), SdoAbortCode::None);
  f.node_od->find(0x1A00, 1)->value = canopen::encode<std::uint32_t>(0x00050008);
  f.node_od->find(0x1A00, 2)->value = canopen::encode<std::uint32_t>(0x20000010);
  f.node_od->find(0x1A00, 3)->value = canopen::encode<std::uint32_t>(0x64010110);
  f.node_od->find(0x1A00, 0)->value = {3};
  f.read_mapping();
  EXPECT_TRUE(f.drv->on_frame(CanFrame(0x1A1, {0xFF, 0x11, 0x22, 0x00, 0x80}), t0));
  EXPECT_EQ(f.val("analog[1]"), -32768);
  EXPECT_EQ(f.status("in[1]"), SignalStatus::Offline);
}

TEST(Cia401, OutputsGoOutInTheReadBackRpdoRememberingTheOthers) {
  Fixture f(kCluster);
  EXPECT_FALSE(f.drv->set_output(f.sig("out[2]"), 0x81, t0)) << "no RPDO known before the mapping read";
  EXPECT_TRUE(f.sent.empty());
  f.read_mapping();
  ASSERT_TRUE(f.drv->mapping_complete());
  // EDS RPDO1 (1600h): 6200h:1, 6200h:2, 6411h:1 — 4 bytes on 200h + node-ID.
  EXPECT_TRUE(f.drv->set_output(f.sig("out[2]"), 0x81, t0));
  ASSERT_EQ(f.sent.size(), 1u);
  EXPECT_EQ(f.sent[0], CanFrame(0x221, {0x00, 0x81, 0x00, 0x00}));
  EXPECT_TRUE(f.drv->set_output(f.sig("aout[1]"), 500, t0));
  ASSERT_EQ(f.sent.size(), 2u);
  EXPECT_EQ(f.sent[1], CanFrame(0x221, {0x00, 0x81, 0xF4, 0x01}));
  EXPECT_EQ(f.val("aout[1]"), 500);
  EXPECT_EQ(f.status("aout[1]"), SignalStatus::Valid);
  EXPECT_FALSE(f.drv->set_output(f.sig("aout[1]"), 1001, t0)) << "above the EDS HighLimit";
  EXPECT_FALSE(f.drv->set_output(f.sig("out[1]"), 256, t0));
  EXPECT_FALSE(f.drv->set_output(f.sig("in[1]"), 1, t0)) << "an input";
  EXPECT_FALSE(f.drv->set_output(99, 1, t0));
  EXPECT_EQ(f.sent.size(), 2u);
  // The frames the driver sends are accepted by a node running that mapping (CiA 301 RPDO).
  canopen::PdoService pdo(*f.node_od, [](const CanFrame&) {});
  pdo.set_operational(true, t0);
  EXPECT_TRUE(pdo.on_frame(f.sent[1], t0));
  EXPECT_EQ(f.node_od->get<std::uint8_t>(0x6200, 2), 0x81);
  EXPECT_EQ(f.node_od->get<std::int16_t>(0x6411, 1), 500);
}

// Run-time state (Driver::export_state): the PDOs the boot read back travel with the state, so a
// fresh driver given it decodes the node's frames as the original does, with no mapping read of
// its own; without it, no frame is used (NoFrameIsUsedBeforeTheMappingIsRead).
TEST(Cia401, AFreshDriverGivenTheStateDecodesWithThePdosTheBootReadBack) {
  Fixture a(kPedal);
  a.read_mapping();
  a.drv->apply_boot_writes({});
  a.drv->on_online(t0);
  a.drv->set_alive_since(t0);
  ASSERT_TRUE(a.drv->on_frame(CanFrame(0x1A1, {0xFE, 0xFF, 0xE8, 0x03, 0xA5}), t0));
  Fixture b(kPedal);
  Fixture fresh(kPedal);
  canopen::StateWriter w;
  a.drv->export_state(w);
  const canopen::StateReader r = canopen::StateReader::parse(w.text());
  b.drv->import_state(r);
  EXPECT_TRUE(r.unread().empty());
  EXPECT_EQ(b.drv->consumed_cob_ids(), a.drv->consumed_cob_ids());
  EXPECT_EQ(b.drv->value(b.sig("analog[2]")), a.drv->value(a.sig("analog[2]")));
  for (Fixture* f : {&a, &b, &fresh}) f->changes.clear();
  const CanFrame next(0x1A1, {0x10, 0x00, 0xE8, 0x03, 0x5A});
  EXPECT_TRUE(a.drv->on_frame(next, t0 + canopen::Duration{1000}));
  EXPECT_TRUE(b.drv->on_frame(next, t0 + canopen::Duration{1000}));
  EXPECT_FALSE(fresh.drv->on_frame(next, t0 + canopen::Duration{1000}));
  EXPECT_EQ(b.changes, a.changes);
  EXPECT_EQ(a.changes.size(), 2u) << "analog[1] and in[1] changed; analog[2] did not";
  EXPECT_EQ(b.drv->next_deadline(), a.drv->next_deadline());
}

// The outputs as last commanded travel with the state: the RPDO that carries the next output
// carries them too (CiA 301 §7.2.2: an RPDO sets every object it maps). Exported again, the
// state is the same.
TEST(Cia401, TheOutputsAsLastCommandedCarryOverAndTheStateRoundTrips) {
  Fixture a(kCluster);
  a.read_mapping();
  a.drv->apply_boot_writes({});
  a.drv->on_online(t0);
  ASSERT_TRUE(a.drv->set_output(a.sig("out[2]"), 0x81, t0));
  canopen::StateWriter w;
  a.drv->export_state(w);
  Fixture b(kCluster);
  b.drv->import_state(canopen::StateReader::parse(w.text()));
  canopen::StateWriter again;
  b.drv->export_state(again);
  EXPECT_EQ(again.text(), w.text());
  Fixture fresh(kCluster);
  fresh.read_mapping();
  fresh.drv->apply_boot_writes({});
  fresh.drv->on_online(t0);
  for (Fixture* f : {&a, &b, &fresh}) {
    f->sent.clear();
    ASSERT_TRUE(f->drv->set_output(f->sig("aout[1]"), 500, t0));
  }
  ASSERT_EQ(a.sent.size(), 1u);
  EXPECT_EQ(a.sent[0], CanFrame(0x221, {0x00, 0x81, 0xF4, 0x01}));
  EXPECT_EQ(b.sent, a.sent);
  EXPECT_EQ(fresh.sent[0], CanFrame(0x221, {0x00, 0x00, 0xF4, 0x01}));
}

// A state no boot of this node could have left is refused with the key that shows it, and the
// node's RPDO is not sent from it.
TEST(Cia401, AStateNoBootCouldLeaveIsRefused) {
  Fixture a(kCluster);
  a.read_mapping();
  a.drv->apply_boot_writes({});
  canopen::StateWriter w;
  a.drv->export_state(w);
  const std::string text = w.text();
  const auto with = [&](const std::string& key, const std::string& value) {
    return canopen::test_support::with_value(text, key, value);
  };
  const std::pair<std::string, std::string> bad[] = {
      {with("family.pdos.0.cob_id", "0"), "state: 'family.pdos.0.cob_id' is on a restricted CAN-ID (CiA 301 §7.3.5)"},
      {with("family.pdos.0.count", "65"), "state: 'family.pdos.0.count' is above 64 mapping entries"},
      {with("family.pdos.0.transmit", "1"),  // RPDO1 comes first
       "state: 'family.pdos.0.transmit' differs: the state is of another EDS's PDOs"},
      {with("family.outputs.count", "3"), "state: 'family.outputs.count' differs from this node's signals"},
  };
  for (const auto& [t, message] : bad) {
    Fixture b(kCluster);
    EXPECT_EQ(canopen::test_support::refusal(*b.drv, t), message);
    EXPECT_TRUE(b.sent.empty());
  }
  // An output outside its signal's range (out[2] is UNSIGNED8).
  const std::size_t out2 = a.sig("out[2]");
  Fixture c(kCluster);
  const std::string key = "family.outputs." + std::to_string(out2) + ".value";
  EXPECT_EQ(canopen::test_support::refusal(*c.drv, with(key, "256")), "state: '" + key + "' is outside out[2]'s range");
  // The error register faults every input or none (one faulted alone), and never an output.
  const std::string alone = text + "signals." + std::to_string(a.sig("in[1]")) + ".fault 1\n";
  Fixture d(kCluster);
  EXPECT_EQ(canopen::test_support::refusal(*d.drv, alone)
                .rfind("state: 'family.error_register_read' cannot explain", 0),
            0u)
      << canopen::test_support::refusal(*d.drv, alone);
  const std::string output = text + "signals." + std::to_string(out2) + ".fault 1\n";
  Fixture e(kCluster);
  EXPECT_EQ(canopen::test_support::refusal(*e.drv, output),
            "state: 'family.error_register_read' cannot explain signal " + std::to_string(out2) +
                "'s fault: the error register faults every input or none, and no output");
}

TEST(Cia401, OutputNotMappedByAnyRpdoIsRefused) {
  Fixture f(kCluster);
  // The node's RPDO1 maps only 6200h:1 (remapped before boot).
  ASSERT_EQ(f.node_od->write(0x1400, 1, canopen::encode<std::uint32_t>(0x80000221), canopen::Origin::Local),
            SdoAbortCode::None);
  ASSERT_EQ(f.node_od->write(0x1600, 0, Bytes{0}, canopen::Origin::Local), SdoAbortCode::None);
  ASSERT_EQ(f.node_od->write(0x1600, 0, Bytes{1}, canopen::Origin::Local), SdoAbortCode::None);
  ASSERT_EQ(f.node_od->write(0x1400, 1, canopen::encode<std::uint32_t>(0x221), canopen::Origin::Local),
            SdoAbortCode::None);
  f.read_mapping();
  EXPECT_FALSE(f.drv->set_output(f.sig("out[2]"), 1, t0));
  EXPECT_TRUE(f.sent.empty());
  EXPECT_TRUE(f.drv->set_output(f.sig("out[1]"), 7, t0));
  ASSERT_EQ(f.sent.size(), 1u);
  EXPECT_EQ(f.sent[0], CanFrame(0x221, {0x07}));
}

TEST(Cia401, ThirtyTwoBitInputsOnTpdo2) {
  Fixture f(kCluster);
  f.read_mapping();
  EXPECT_EQ(f.drv->consumed_cob_ids(), (std::vector<std::uint32_t>{0x1A1, 0x2A1}));
  EXPECT_TRUE(f.drv->on_frame(CanFrame(0x2A1, {0x01, 0x00, 0x00, 0x80}), t0));
  EXPECT_EQ(f.val("in32[1]"), 0x80000001ll) << "UNSIGNED32: not sign-extended";
  EXPECT_TRUE(f.drv->on_frame(CanFrame(0x1A1, {0x03, 0xF0}), t0));
  EXPECT_EQ(f.val("in[1]"), 0x03);
  EXPECT_EQ(f.val("in[2]"), 0xF0);
}

// CiA 301 §7.2.7.1 Table 26: 3100h (mains voltage) is an error of a defined class; 0000h resets.
TEST(Cia401, EmcyErrorsPutInputsInErrorUntilResetOrGoodValue) {
  Fixture f(kPedal);
  f.read_mapping();
  ASSERT_TRUE(f.drv->on_frame(CanFrame(0x1A1, {0x10, 0x00, 0x20, 0x00, 0x01}), t0));
  auto d = f.drv->on_emcy(EmcyMessage{kNode, 0x3100, 0x05, {}}, t0);
  EXPECT_TRUE(d.error);
  EXPECT_EQ(d.code, 0x3100);
  EXPECT_EQ(d.text, "cia401 EMCY 3100h: voltage");
  EXPECT_EQ(d.affected.size(), 3u) << "every input: in[1], in[2], analog[1]";
  EXPECT_EQ(f.status("analog[1]"), SignalStatus::Error);
  EXPECT_EQ(f.val("analog[1]"), 0) << "the neutral value";
  EXPECT_EQ(f.val("in[1]"), 0);
  d = f.drv->on_emcy(EmcyMessage{kNode, 0x0000, 0x00, {}}, t0);
  EXPECT_FALSE(d.error);
  EXPECT_EQ(f.status("analog[1]"), SignalStatus::Offline)
      << "no longer Error; no value until the next PDO (a PDO sent on change only is never overdue)";
  EXPECT_EQ(f.val("analog[1]"), 0);
  ASSERT_TRUE(f.drv->on_frame(CanFrame(0x1A1, {0x10, 0x00, 0x20, 0x00, 0x01}), t0));
  EXPECT_EQ(f.status("analog[1]"), SignalStatus::Valid);
  EXPECT_EQ(f.val("analog[1]"), 0x10);
  // The fault is the driver's until the error reset: a good value does not end it.
  (void)f.drv->on_emcy(EmcyMessage{kNode, 0xFF01, 0x81, {}}, t0);
  EXPECT_EQ(f.status("in[1]"), SignalStatus::Error);
  ASSERT_TRUE(f.drv->on_frame(CanFrame(0x1A1, {0x10, 0x00, 0x20, 0x00, 0x01}), t0));
  EXPECT_EQ(f.status("in[1]"), SignalStatus::Error);
  (void)f.drv->on_emcy(EmcyMessage{kNode, 0x0000, 0x00, {}}, t0);
  ASSERT_TRUE(f.drv->on_frame(CanFrame(0x1A1, {0x10, 0x00, 0x20, 0x00, 0x01}), t0));
  EXPECT_EQ(f.status("in[1]"), SignalStatus::Valid);
  // 81xxh "communication" (CiA 301 Table 26): a warning, faulting nothing.
  d = f.drv->on_emcy(EmcyMessage{kNode, 0x8120, 0x11, {}}, t0);
  EXPECT_FALSE(d.error);
  EXPECT_TRUE(d.affected.empty());
  EXPECT_FALSE(f.drv->any_fault());
  EXPECT_EQ(f.status("in[1]"), SignalStatus::Valid);
  // A boot-up alone is no evidence: the node may have rebooted broken (1001h decides: below).
  (void)f.drv->on_emcy(EmcyMessage{kNode, 0x3100, 0x05, {}}, t0);
  ASSERT_TRUE(f.drv->any_fault());
  f.drv->on_application_reset(t0);
  EXPECT_TRUE(f.drv->any_fault());
  (void)f.drv->on_emcy(EmcyMessage{kNode, 0x0000, 0x00, {}}, t0);
  ASSERT_TRUE(f.drv->on_frame(CanFrame(0x1A1, {0x10, 0x00, 0x20, 0x00, 0x01}), t0));
  EXPECT_EQ(f.status("in[1]"), SignalStatus::Valid);
  // A code outside Table 26's classes: counted and ignored.
  d = f.drv->on_emcy(EmcyMessage{kNode, 0xA123, 0x01, {}}, t0);
  EXPECT_FALSE(d.error);
  EXPECT_EQ(f.drv->counters().unknown_emcy, 1u);
  EXPECT_EQ(f.status("in[1]"), SignalStatus::Valid);
  EXPECT_EQ(f.val("in[1]"), 1);
}

// 1001h "error register" (CiA 301 §7.5.2.2) read back at every (re)start decides the faults:
// no error (or a communication error alone) ends them; another bit faults every input, also
// when the EMCY went before the gateway listened; a refused read or a wrong length keeps them.
TEST(Cia401, ErrorRegisterReadBackAtEveryBootDecidesTheFaults) {
  Fixture f(kPedal);
  f.drv->begin_boot();
  const auto reads = f.drv->boot_reads();
  ASSERT_FALSE(reads.empty());
  EXPECT_EQ(reads[0], (std::pair<std::uint16_t, std::uint8_t>{0x1001, 0}));
  std::string error;
  ASSERT_TRUE(f.drv->on_boot_read(0x1001, 0, Bytes{0x05}, error)) << error;  // generic + voltage
  EXPECT_EQ(f.drv->boot_reads().size(), reads.size() - 1) << "1001h is read once per boot";
  f.read_mapping();
  EXPECT_TRUE(f.drv->any_fault()) << "an error the gateway never saw an EMCY of";
  ASSERT_TRUE(f.drv->on_frame(CanFrame(0x1A1, {0x10, 0x00, 0x20, 0x00, 0x01}), t0));
  EXPECT_EQ(f.status("analog[1]"), SignalStatus::Error);
  EXPECT_EQ(f.val("analog[1]"), 0);
  struct Case {
    Bytes answer;
    bool faulted;  // after the read-back, with the faults set before
  };
  for (const Case& c :
       {Case{Bytes{0x01}, true}, Case{Bytes{0x80}, true}, Case{Bytes{0x00, 0x00}, true}, Case{Bytes{}, true},
        Case{Bytes{0x11}, false}, Case{Bytes{0x10}, false}, Case{Bytes{0x00}, false}}) {
    SCOPED_TRACE(testing::Message() << c.answer.size() << " bytes, first " << (c.answer.empty() ? -1 : c.answer[0]));
    (void)f.drv->on_emcy(EmcyMessage{kNode, 0x5000, 0x81, {}}, t0);
    ASSERT_TRUE(f.drv->any_fault());
    f.drv->on_application_reset(t0);
    f.drv->begin_boot();
    ASSERT_TRUE(f.drv->on_boot_read(0x1001, 0, c.answer, error)) << error;
    EXPECT_EQ(f.drv->any_fault(), c.faulted);
  }
  // Refused: no evidence either way.
  (void)f.drv->on_emcy(EmcyMessage{kNode, 0x5000, 0x81, {}}, t0);
  f.drv->begin_boot();
  EXPECT_TRUE(f.drv->on_boot_read_abort(0x1001, 0, SdoAbortCode::ObjectDoesNotExist));
  EXPECT_TRUE(f.drv->any_fault());
  EXPECT_TRUE(f.drv->boot_reads().empty() || f.drv->boot_reads()[0].first != 0x1001);
}

TEST(Cia401, OfflineMarksInputsOnly) {
  Fixture f(kCluster);
  f.read_mapping();
  ASSERT_TRUE(f.drv->on_frame(CanFrame(0x1A1, {0x03, 0xF0}), t0));
  ASSERT_TRUE(f.drv->set_output(f.sig("out[1]"), 9, t0));
  f.drv->on_offline(t0);
  EXPECT_EQ(f.status("in[1]"), SignalStatus::Offline);
  EXPECT_EQ(f.val("in[2]"), 0);
  EXPECT_EQ(f.status("out[1]"), SignalStatus::Valid);
}

// Whatever a (broken or hostile) node answers to the mapping read and whatever it then sends,
// the driver neither crashes nor reports a value outside a signal's range.
TEST(Cia401, RandomMappingAnswersAndFramesStayWithinRanges) {
  Fixture f(kCluster);
  std::uint32_t seed = 77;
  auto rnd = [&seed]() {
    seed = seed * 1664525u + 1013904223u;
    return seed >> 8;
  };
  const std::uint32_t useful[] = {0x60000108, 0x60000208, 0x61200120, 0x64010110,
                                  0x62000108, 0x64110110, 0x00050008, 0x60000110};
  for (int round = 0; round < 300; ++round) {
    f.drv->reset_mapping();
    for (int guard = 0; guard < 10 && !f.drv->mapping_complete(); ++guard) {
      for (const auto& q : f.drv->mapping_reads()) {
        switch (rnd() % 25) {
          case 0: f.drv->apply_mapping_abort(q.index, q.sub, SdoAbortCode::ObjectDoesNotExist); break;
          case 1: {
            Bytes junk(rnd() % 6);
            for (auto& b : junk) b = static_cast<std::uint8_t>(rnd());
            (void)f.drv->apply_mapping_read(q.index, q.sub, junk);
            break;
          }
          default:
            if (q.sub == 0 && q.index >= 0x1600) {
              (void)f.drv->apply_mapping_read(q.index, q.sub, Bytes{static_cast<std::uint8_t>(rnd() % 9)});
            } else if (q.sub == 2) {
              (void)f.drv->apply_mapping_read(q.index, q.sub, Bytes{0xFF});
            } else if (q.sub == 5) {  // a TPDO's event timer
              (void)f.drv->apply_mapping_read(q.index, q.sub, canopen::encode<std::uint16_t>(rnd() % 500));
            } else if (q.index < 0x1600 || (q.index >= 0x1800 && q.index < 0x1A00)) {
              const std::uint32_t cob = (q.index >= 0x1800 ? 0x180u : 0x200u) + (rnd() % 4) * 0x100u + 0x21u;
              (void)f.drv->apply_mapping_read(q.index, q.sub, canopen::encode<std::uint32_t>(cob));
            } else {
              (void)f.drv->apply_mapping_read(q.index, q.sub,
                                              canopen::encode<std::uint32_t>(useful[rnd() % std::size(useful)]));
            }
        }
      }
    }
    ASSERT_TRUE(f.drv->mapping_complete());
    for (int i = 0; i < 20; ++i) {
      CanFrame fr;
      const auto ids = f.drv->consumed_cob_ids();
      fr.id = (ids.empty() || rnd() % 4 == 0) ? 0x180u + (rnd() % 4) * 0x100u + 0x21u : ids[rnd() % ids.size()];
      fr.dlc = static_cast<std::uint8_t>(rnd() % 9);
      for (auto& b : fr.data) b = static_cast<std::uint8_t>(rnd());
      (void)f.drv->on_frame(fr, t0);
      const std::size_t out = rnd() % f.drv->signals().size();
      const auto& info = f.drv->signals()[out];
      const std::int64_t v = (rnd() % 2 == 0) ? static_cast<std::int64_t>(rnd() % 70000) - 35000
                                              : info.min + static_cast<std::int64_t>(rnd() % 200);
      (void)f.drv->set_output(out, v, t0);
    }
    for (std::size_t i = 0; i < f.drv->signals().size(); ++i) {
      const auto& si = f.drv->signals()[i];
      ASSERT_GE(f.drv->value(i).value, si.min) << si.name;
      ASSERT_LE(f.drv->value(i).value, si.max) << si.name;
    }
  }
  for (const CanFrame& fr : f.sent) ASSERT_LE(fr.dlc, 8);
  std::size_t decoded = 0;
  for (const auto& [i, v] : f.changes)
    if (!f.drv->signals()[i].output() && v.status == SignalStatus::Valid) ++decoded;
  EXPECT_GT(decoded, 10u) << "the random mappings did decode frames";
  EXPECT_GT(f.sent.size(), 10u) << "and send outputs";
}

}  // namespace
}  // namespace oegw::subdevices
