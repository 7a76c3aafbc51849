// Store/restore parameters, 1010h/1011h (CiA 301 §7.5.2.13/14). Signatures from the Novotechnik
// manual (004_965670f51e9c840d, §4.1 objects 1010h/1011h: "save" = 0x65766173, "load" =
// 0x64616f6c; §7.1 SDO download examples "23 10 10 01 73 61 76 65" and
// "23 11 10 01 6C 6F 61 64") and the elobau manual (000_499d7da4c768c72f, §8 "Parameter
// Settings": "save" into 1010h.1; §9 "Restore Default Parameters": "load" into 1011h.1, then
// restart).
#include "canopen/301/storage.hpp"

#include "canopen/301/heartbeat.hpp"
#include "canopen/301/nmt_slave.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fstream>
#include <sstream>

using namespace oegw::canopen;
namespace fs = std::filesystem;

namespace {

class TempDir {
 public:
  TempDir() {
    std::string tmpl = (fs::temp_directory_path() / "oegw_storage_XXXXXX").string();
    if (::mkdtemp(tmpl.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  [[nodiscard]] const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
void spit(const fs::path& p, const std::string& s) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << s;
}

// A small dictionary in the spirit of the Novotechnik object library (§4.1–4.3).
void build(ObjectDictionary& od) {
  od.add_var(0x1000, "Device type", DataType::Unsigned32, Access::Const, encode<std::uint32_t>(0x00020196));
  od.add_var(0x1017, "Producer heartbeat time", DataType::Unsigned16, Access::ReadWrite, encode<std::uint16_t>(0));
  od.add_var(0x2000, "Node-ID", DataType::Unsigned8, Access::ReadWrite, {0x7F});
  od.add_var(0x2002, "Temperature", DataType::Integer16, Access::ReadOnly, encode<std::int16_t>(0));
  od.add_var(0x2100, "Name", DataType::VisibleString, Access::ReadWrite, {'a', 'b'});
  od.add_var(0x6003, "Preset value", DataType::Unsigned32, Access::ReadWrite, encode<std::uint32_t>(0));
  od.add_var(0x6004, "Position value", DataType::Integer32, Access::ReadOnly, encode<std::int32_t>(0), true);
}

struct StorageFixture : ::testing::Test {
  TempDir dir;
  fs::path file = dir.path() / "od.store";
  ObjectDictionary od;
  std::unique_ptr<ParameterStore> store;
  void SetUp() override {
    build(od);
    store = std::make_unique<ParameterStore>(od, file);
  }
  SdoAbortCode write_bytes(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> b) {
    return od.write(index, sub, b, Origin::Sdo);
  }
  void change_values() {
    ASSERT_EQ(od.set<std::uint16_t>(0x1017, 0, 500, Origin::Sdo), SdoAbortCode::None);
    ASSERT_EQ(od.set<std::uint8_t>(0x2000, 0, 0x40, Origin::Sdo), SdoAbortCode::None);
    ASSERT_EQ(od.set<std::uint32_t>(0x6003, 0, 1234, Origin::Sdo), SdoAbortCode::None);
    ASSERT_EQ(od.set<std::int16_t>(0x2002, 0, 55, Origin::Local), SdoAbortCode::None);
  }
  // A fresh boot: a new dictionary with defaults, then the stored values over them.
  ParameterStore::LoadResult reboot(ObjectDictionary& fresh) {
    build(fresh);
    ParameterStore s(fresh, file);
    return s.load();
  }
};

TEST(StorageFormat, SignaturesAreAsciiLittleEndian) {
  // Novotechnik §4.1: "save" (0x65766173), "load" (0x64616f6c).
  const std::uint8_t save[4] = {'s', 'a', 'v', 'e'};
  const std::uint8_t load[4] = {'l', 'o', 'a', 'd'};
  EXPECT_EQ(get_u32(save), ParameterStore::kSaveSignature);
  EXPECT_EQ(get_u32(load), ParameterStore::kLoadSignature);
  EXPECT_EQ(ParameterStore::kSaveSignature, 0x65766173u);
  EXPECT_EQ(ParameterStore::kLoadSignature, 0x64616F6Cu);
}

TEST(StorageFormat, Crc32CheckValueAndExactText) {
  EXPECT_EQ(ParameterStore::crc32("123456789"), 0xCBF43926u);  // CRC-32/ISO-HDLC check value
  ParameterStore::Entries e;
  e[{0x1017, 0}] = {0xE8, 0x03};
  e[{0x2100, 0}] = {};
  const std::string text = ParameterStore::serialize(e);
  const std::string body = "OEGW-OD-STORE 1\n1017 00 E803\n2100 00 -\n";
  char crc[9];
  std::snprintf(crc, sizeof crc, "%08X", ParameterStore::crc32(body));
  EXPECT_EQ(text, body + "END 2 " + crc + "\n");
  std::string err;
  auto back = ParameterStore::parse(text, err);
  ASSERT_TRUE(back) << err;
  EXPECT_EQ(*back, e);
}

TEST_F(StorageFixture, ReadsOneMeaningSavesOnCommand) {
  for (std::uint16_t index : {0x1010, 0x1011}) {
    EXPECT_EQ(od.get<std::uint8_t>(index, 0), 3);
    for (std::uint8_t sub = 1; sub <= 3; ++sub) EXPECT_EQ(od.get<std::uint32_t>(index, sub), 1u);
  }
}

// Novotechnik §7.1: "23 10 10 01 73 61 76 65" = write "save" to 1010h/1 -> 60 (accepted).
TEST_F(StorageFixture, NovotechnikSaveSignaturePersistsWritableObjects) {
  change_values();
  EXPECT_EQ(write_bytes(0x1010, 1, {0x73, 0x61, 0x76, 0x65}), SdoAbortCode::None);
  EXPECT_EQ(od.get<std::uint32_t>(0x1010, 1), 1u);  // still reads "saves on command"
  ASSERT_TRUE(fs::exists(file));
  EXPECT_FALSE(fs::exists(store->temp_path()));
  const std::string text = slurp(file);
  EXPECT_NE(text.find("1017 00 F401\n"), std::string::npos);
  EXPECT_NE(text.find("2000 00 40\n"), std::string::npos);
  EXPECT_NE(text.find("6003 00 D2040000\n"), std::string::npos);
  EXPECT_EQ(text.find("1000 00"), std::string::npos);  // const
  EXPECT_EQ(text.find("2002 00"), std::string::npos);  // ro
  EXPECT_EQ(text.find("6004 00"), std::string::npos);  // ro
  EXPECT_EQ(text.find("1010 "), std::string::npos);
  EXPECT_EQ(text.find("2100 00"), std::string::npos);  // at its default: follows the default

  ObjectDictionary fresh;
  const auto r = reboot(fresh);
  EXPECT_TRUE(r.ok) << r.error;
  EXPECT_TRUE(r.file_present);
  EXPECT_EQ(r.applied, 3u);  // 1017, 2000, 6003 (2100 is at its default)
  EXPECT_EQ(fresh.get<std::uint16_t>(0x1017, 0), 500);
  EXPECT_EQ(fresh.get<std::uint8_t>(0x2000, 0), 0x40);
  EXPECT_EQ(fresh.get<std::uint32_t>(0x6003, 0), 1234u);
  EXPECT_EQ(fresh.get<std::int16_t>(0x2002, 0), 0);  // read-only: not stored
}

TEST_F(StorageFixture, WrongSignatureRefusedWith08000020) {
  change_values();
  EXPECT_EQ(write_bytes(0x1010, 1, {0x73, 0x61, 0x76, 0x66}), SdoAbortCode::CannotTransfer);
  EXPECT_EQ(write_bytes(0x1010, 2, {0x6C, 0x6F, 0x61, 0x64}), SdoAbortCode::CannotTransfer);  // "load" on 1010h
  EXPECT_EQ(write_bytes(0x1011, 1, {0x73, 0x61, 0x76, 0x65}), SdoAbortCode::CannotTransfer);  // "save" on 1011h
  EXPECT_FALSE(fs::exists(file));
  EXPECT_EQ(od.get<std::uint32_t>(0x1010, 1), 1u);
}

TEST_F(StorageFixture, MissingFileLoadsNothing) {
  const auto r = store->load();
  EXPECT_TRUE(r.ok);
  EXPECT_FALSE(r.file_present);
  EXPECT_EQ(r.applied, 0u);
}

TEST_F(StorageFixture, SavingOneGroupKeepsTheOthers) {
  change_values();
  ASSERT_EQ(store->save(ParameterStore::Group::All), SdoAbortCode::None);
  ASSERT_EQ(od.set<std::uint16_t>(0x1017, 0, 700, Origin::Sdo), SdoAbortCode::None);
  ASSERT_EQ(od.set<std::uint32_t>(0x6003, 0, 99, Origin::Sdo), SdoAbortCode::None);
  // 1010h/2: communication parameters only.
  ASSERT_EQ(od.set<std::uint32_t>(0x1010, 2, ParameterStore::kSaveSignature, Origin::Sdo), SdoAbortCode::None);
  ObjectDictionary fresh;
  ASSERT_TRUE(reboot(fresh).ok);
  EXPECT_EQ(fresh.get<std::uint16_t>(0x1017, 0), 700);
  EXPECT_EQ(fresh.get<std::uint32_t>(0x6003, 0), 1234u);  // not re-saved
  // 1010h/3: application parameters (6000h–9FFFh).
  ASSERT_EQ(od.set<std::uint32_t>(0x1010, 3, ParameterStore::kSaveSignature, Origin::Sdo), SdoAbortCode::None);
  ObjectDictionary fresh2;
  ASSERT_TRUE(reboot(fresh2).ok);
  EXPECT_EQ(fresh2.get<std::uint32_t>(0x6003, 0), 99u);
}

// Power loss in the middle of a store: the temp file is partial, the rename never happened.
TEST_F(StorageFixture, PowerLossMidStoreKeepsPreviousCopy) {
  change_values();
  ASSERT_EQ(store->save(ParameterStore::Group::All), SdoAbortCode::None);
  const std::string previous = slurp(file);
  ASSERT_EQ(od.set<std::uint16_t>(0x1017, 0, 900, Origin::Sdo), SdoAbortCode::None);
  ParameterStore::Entries next;
  next[{0x1017, 0}] = {0x84, 0x03};
  const std::string full = ParameterStore::serialize(next);
  spit(store->temp_path(), full.substr(0, full.size() / 2));  // what the crash left behind

  ObjectDictionary fresh;
  const auto r = reboot(fresh);
  EXPECT_TRUE(r.ok) << r.error;
  EXPECT_EQ(fresh.get<std::uint16_t>(0x1017, 0), 500);  // the previous copy
  EXPECT_EQ(slurp(file), previous);
  // The next store overwrites the leftover and completes.
  ASSERT_EQ(store->save(ParameterStore::Group::All), SdoAbortCode::None);
  EXPECT_FALSE(fs::exists(store->temp_path()));
  ObjectDictionary fresh2;
  ASSERT_TRUE(reboot(fresh2).ok);
  EXPECT_EQ(fresh2.get<std::uint16_t>(0x1017, 0), 900);
}

TEST_F(StorageFixture, CorruptOrTruncatedFileRefusedAndNothingChanges) {
  change_values();
  ASSERT_EQ(store->save(ParameterStore::Group::All), SdoAbortCode::None);
  const std::string good = slurp(file);

  auto expect_refused = [&](const std::string& text, const std::string& why) {
    spit(file, text);
    ObjectDictionary fresh;
    build(fresh);
    ASSERT_EQ(fresh.set<std::uint16_t>(0x1017, 0, 42), SdoAbortCode::None);
    ParameterStore s(fresh, file);
    const auto r = s.load();
    EXPECT_FALSE(r.ok) << why;
    EXPECT_TRUE(r.file_present);
    EXPECT_EQ(r.applied, 0u);
    EXPECT_NE(r.error.find(why), std::string::npos) << r.error;
    EXPECT_EQ(s.last_error(), r.error);
    EXPECT_EQ(fresh.get<std::uint16_t>(0x1017, 0), 42);  // untouched
    EXPECT_EQ(fresh.get<std::uint8_t>(0x2000, 0), 0x7F);
    EXPECT_EQ(fresh.get<std::uint32_t>(0x6003, 0), 0u);
  };
  std::string flipped = good;
  flipped[flipped.find("F401")] = 'E';  // one value changed, CRC no longer matches
  expect_refused(flipped, "CRC mismatch");
  expect_refused(good.substr(0, good.size() - 12), "truncated");
  expect_refused(good.substr(0, good.find("2000")), "truncated");
  expect_refused(good.substr(0, 5), "bad header");
  expect_refused("", "bad header");
  std::string bad_line = good;
  bad_line.replace(bad_line.find("2000 00 40"), 10, "2000 00 4G");
  expect_refused(bad_line, "malformed entry");
  expect_refused(good + "junk", "trailing data");
}

TEST_F(StorageFixture, EntriesForUnknownOrChangedObjectsAreSkipped) {
  ParameterStore::Entries e;
  e[{0x1017, 0}] = {0x10, 0x00};
  e[{0x3000, 0}] = {0x01};           // no such object
  e[{0x2000, 0}] = {0x01, 0x02};     // UNSIGNED8 now: size changed
  e[{0x2002, 0}] = {0x05, 0x00};     // read-only
  e[{0x2100, 0}] = {'x', 'y', 'z'};  // strings may change length
  spit(file, ParameterStore::serialize(e));
  const auto r = store->load();
  EXPECT_TRUE(r.ok) << r.error;
  EXPECT_EQ(r.applied, 2u);
  EXPECT_EQ(r.skipped, 3u);
  EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 0x10);
  EXPECT_EQ(od.find(0x2100, 0)->value, (std::vector<std::uint8_t>{'x', 'y', 'z'}));
  EXPECT_EQ(od.get<std::uint8_t>(0x2000, 0), 0x7F);
}

// Novotechnik §7.1 "23 11 10 01 6C 6F 61 64" / elobau §9: "load" into 1011h/1, then restart.
TEST_F(StorageFixture, LoadSignatureRestoresDefaultsAtNextReset) {
  change_values();
  ASSERT_EQ(store->save(ParameterStore::Group::All), SdoAbortCode::None);
  EXPECT_EQ(write_bytes(0x1011, 1, {0x6C, 0x6F, 0x61, 0x64}), SdoAbortCode::None);
  EXPECT_EQ(od.get<std::uint32_t>(0x1011, 1), 1u);
  EXPECT_FALSE(fs::exists(file));
  EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 500);  // unchanged until the reset
  // Reset node: defaults, then whatever is stored (nothing).
  od.reset_to_defaults(0x0000, 0xFFFF);
  const auto r = store->load();
  EXPECT_TRUE(r.ok);
  EXPECT_FALSE(r.file_present);
  EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 0);
  EXPECT_EQ(od.get<std::uint8_t>(0x2000, 0), 0x7F);
  EXPECT_EQ(od.get<std::uint32_t>(0x1010, 1), 1u);
}

TEST_F(StorageFixture, RestoreCommunicationOnlyKeepsApplicationValues) {
  change_values();
  ASSERT_EQ(store->save(ParameterStore::Group::All), SdoAbortCode::None);
  ASSERT_EQ(od.set<std::uint32_t>(0x1011, 2, ParameterStore::kLoadSignature, Origin::Sdo), SdoAbortCode::None);
  ASSERT_TRUE(fs::exists(file));
  // Reset communication: 1000h–1FFFh back to defaults, then the stored values of that range.
  od.reset_to_defaults(0x1000, 0x1FFF);
  ASSERT_TRUE(store->load(0x1000, 0x1FFF).ok);
  EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 0);
  ObjectDictionary fresh;
  ASSERT_TRUE(reboot(fresh).ok);
  EXPECT_EQ(fresh.get<std::uint16_t>(0x1017, 0), 0);
  EXPECT_EQ(fresh.get<std::uint8_t>(0x2000, 0), 0x40);
  EXPECT_EQ(fresh.get<std::uint32_t>(0x6003, 0), 1234u);
  // 1011h/3 drops the application ones too.
  ASSERT_EQ(store->restore_defaults(ParameterStore::Group::Application), SdoAbortCode::None);
  ObjectDictionary fresh2;
  ASSERT_TRUE(reboot(fresh2).ok);
  EXPECT_EQ(fresh2.get<std::uint32_t>(0x6003, 0), 0u);
  EXPECT_EQ(fresh2.get<std::uint8_t>(0x2000, 0), 0x40);
}

TEST_F(StorageFixture, UnwritableDirectoryReportsHardwareError) {
  ObjectDictionary other;
  build(other);
  ParameterStore s(other, dir.path() / "missing-subdir" / "od.store");
  EXPECT_EQ(other.set<std::uint32_t>(0x1010, 1, ParameterStore::kSaveSignature, Origin::Sdo),
            SdoAbortCode::HardwareError);
  EXPECT_NE(s.last_error().find("create temp file"), std::string::npos) << s.last_error();
}

// The daemon as another user than the store's (or a store at mode 000 without CAP_DAC_OVERRIDE):
// "Permission denied" is a refused store, not an absent one — nothing loaded, the reason said,
// and a save of one group refused (it would rewrite the file with that group only). Checked in
// a child that becomes user nobody (65534): root reads any file.
TEST_F(StorageFixture, UnreadableStoreIsRefusedNotTakenAsAbsent) {
  ASSERT_EQ(store->save(ParameterStore::Group::All), SdoAbortCode::None);
  ASSERT_EQ(::chmod(file.c_str(), 0), 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    if (::setgid(65534) != 0 || ::setuid(65534) != 0) ::_exit(10);
    ObjectDictionary other;
    build(other);
    ParameterStore s(other, file);
    const auto r = s.load();
    if (r.ok || !r.file_present || r.error.find("Permission denied") == std::string::npos) ::_exit(11);
    if (s.save(ParameterStore::Group::Communication) != SdoAbortCode::HardwareError) ::_exit(12);
    if (s.last_error().find("of one group refused") == std::string::npos) ::_exit(13);
    if (s.restore_defaults(ParameterStore::Group::Application) != SdoAbortCode::HardwareError) ::_exit(14);
    ::_exit(0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "10: cannot become nobody (run as root); 11: load; 12, 13: save; 14: restore";
}

// The owner's reset path: NMT tells it which reset; it restores the defaults of the range, then
// the stored values over them, then lets the services re-read their configuration, all before
// the boot-up. elobau §8/§9: after "save"/"load" the device is restarted to apply them.
TEST_F(StorageFixture, NmtResetsApplyDefaultsThenStoredValues) {
  std::vector<CanFrame> sent;
  NmtSlave nmt(NodeId{0x11}, [&](const CanFrame& f) { sent.push_back(f); });
  HeartbeatProducer hb(od, NodeId{0x11}, [&](const CanFrame& f) { sent.push_back(f); });
  nmt.on_reset([&](bool communication_only) {
    const std::uint16_t last = communication_only ? 0x1FFF : 0xFFFF;
    const std::uint16_t first = communication_only ? 0x1000 : 0x0000;
    od.reset_to_defaults(first, last);
    EXPECT_TRUE(store->load(first, last).ok);
    hb.reload();
  });
  nmt.start(TimePoint{});
  ASSERT_EQ(od.set<std::uint16_t>(0x1017, 0, 100, Origin::Sdo), SdoAbortCode::None);
  ASSERT_EQ(od.set<std::uint32_t>(0x1010, 1, ParameterStore::kSaveSignature, Origin::Sdo), SdoAbortCode::None);
  ASSERT_EQ(od.set<std::uint16_t>(0x1017, 0, 250, Origin::Sdo), SdoAbortCode::None);  // not saved
  ASSERT_EQ(od.set<std::uint32_t>(0x6003, 0, 77, Origin::Sdo), SdoAbortCode::None);   // not saved
  nmt.on_frame(CanFrame(0, {0x82, 0x11}), TimePoint{});                               // reset communication
  EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 100);  // stored value, not the unsaved 250
  EXPECT_EQ(hb.period(), std::chrono::milliseconds(100));
  EXPECT_EQ(od.get<std::uint32_t>(0x6003, 0), 77u);      // application area untouched
  nmt.on_frame(CanFrame(0, {0x81, 0x00}), TimePoint{});  // reset node
  EXPECT_EQ(od.get<std::uint32_t>(0x6003, 0), 0u);       // saved value was the default
  ASSERT_EQ(od.set<std::uint32_t>(0x1011, 1, ParameterStore::kLoadSignature, Origin::Sdo), SdoAbortCode::None);
  EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 100);  // until the reset
  nmt.on_frame(CanFrame(0, {0x81, 0x11}), TimePoint{});
  EXPECT_EQ(od.get<std::uint16_t>(0x1017, 0), 0);
  EXPECT_EQ(hb.period(), Duration{0});
  EXPECT_EQ(sent.size(), 4u);  // four boot-ups
}

}  // namespace
