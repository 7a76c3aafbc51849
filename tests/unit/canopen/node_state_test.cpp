// Run-time state export/import of a whole Node (canopen/state.hpp): the dictionary, every
// service, the LSS slave and the SDO servers, and what the Node itself holds. As the services'
// twin tests (301/service_state_test.cpp): node A is driven into a mid-life state, B is built on
// a fresh dictionary with the same configuration and given A's state in place of start(), a
// third node is started fresh; all three get the same frames, bus events and times, and B must
// send and report exactly what A does, at the same times, while the fresh one does not.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "canopen/305/lss_slave.hpp"
#include "canopen/305/lss_store.hpp"
#include "canopen/node.hpp"
#include "canopen/state.hpp"
#include "node_test_support.hpp"
#include "state_twin.hpp"

namespace oegw::canopen {
namespace {

using namespace std::chrono_literals;
using test_support::copy_state;

constexpr NodeId kId{0x20};
const TimePoint t0{std::chrono::seconds(100)};

NodeConfig config() {
  NodeConfig c;
  c.node_id = kId;
  c.device_type = 0x000F0191;
  c.device_name = "oegw node";  // nine bytes: read by segmented SDO
  c.identity = {.vendor = 0x1234, .product = 0x852, .revision = 0x10002, .serial = 42};
  c.heartbeat_ms = 100;
  c.heartbeat_consumers = 2;
  c.sdo_servers = {SdoServerChannel{.request = 0x640, .response = 0x5C0}};
  return c;
}

// A node on its own dictionary, and everything it did with the time it did it.
struct Side {
  ObjectDictionary od;
  std::unique_ptr<Node> node;
  TimePoint now = t0;
  std::vector<std::string> log;

  Side() {
    test_support::build_application_od(od, kId);
    node = std::make_unique<Node>(od, config(), [this](const CanFrame& f) { add("sent " + f.to_string()); });
    node->on_state_change = [this](NmtState s) { add("state " + std::to_string(static_cast<int>(s))); };
    node->on_heartbeat_timeout = [this](NodeId id) { add("heartbeat lost " + std::to_string(id.value())); };
    node->on_bit_timing_switch = [this](std::uint8_t i) { add("bit timing " + std::to_string(i)); };
  }
  void add(const std::string& what) { log.push_back(std::to_string((now - t0) / 1ms) + " ms: " + what); }
  void at(TimePoint t) {
    now = t;
    node->advance(now);
  }
  void rx(std::uint32_t id, std::initializer_list<std::uint8_t> b) {
    std::vector<std::uint8_t> v(b);
    if (id == cob::kLssMaster) v.resize(8, 0);
    node->on_frame(CanFrame(id, std::span<const std::uint8_t>(v)), now);
    node->advance(now);
  }
  void bus(BusEvent e) {
    node->on_bus_event(e, now);
    node->advance(now);
  }
};

// A node that LSS gave node-ID 21h (its COB-IDs moved at the reset), operational, with a
// setting written, a heartbeat consumer watching node 5, the controller error passive (8120h
// active) and then bus-off, and a switch state selective half done.
TEST(NodeState, ANodeGoesOnWithItsNodeIdDictionaryServicesAndLssProgress) {
  Side a;
  a.node->start(a.now);
  a.rx(cob::kLssMaster, {0x04, 0x01});  // CiA 305: switch state global, configuration
  a.rx(cob::kLssMaster, {0x11, 0x21});  // configure node-ID 21h
  a.rx(cob::kLssMaster, {0x04, 0x00});  // back to waiting: pending until the reset
  a.at(t0 + 5ms);
  a.rx(0x000, {0x82, kId.value()});                               // reset communication: 21h from now on
  a.rx(0x000, {0x01, 0x21});                                      // start
  a.rx(0x621, {0x2B, 0x00, 0x20, 0x00, 0x09, 0x00, 0, 0});        // 2000h = 9
  a.rx(0x621, {0x23, 0x16, 0x10, 0x01, 0x2C, 0x01, 0x05, 0x00});  // 1016h:01 node 5, 300 ms
  a.at(t0 + 20ms);
  a.rx(0x705, {0x05});  // node 5's heartbeat: the consumer watches it from now
  a.bus(BusEvent::ErrorPassive);
  a.bus(BusEvent::BusOff);  // 1029h:01 = 0: pre-operational
  a.rx(0x000, {0x01, 0x21});
  a.rx(cob::kLssMaster, {0x40, 0x34, 0x12, 0x00, 0x00});  // switch state selective: vendor
  a.at(t0 + 30ms);
  ASSERT_EQ(a.node->state(), NmtState::Operational);
  ASSERT_EQ(a.node->node_id(), NodeId{0x21});
  a.log.clear();

  Side b;
  Side fresh;
  fresh.node->start(fresh.now);
  copy_state(*a.node, *b.node);
  EXPECT_EQ(b.node->node_id(), NodeId{0x21});
  EXPECT_EQ(b.od.get<std::uint32_t>(0x1800, 1), 0x1A1u) << "the COB-IDs follow the node-ID";
  EXPECT_EQ(b.node->next_deadline(), a.node->next_deadline());
  fresh.log.clear();

  for (Side* s : {&a, &b, &fresh}) {
    s->at(t0 + 40ms);
    s->rx(cob::kLssMaster, {0x41, 0x52, 0x08, 0x00, 0x00});  // product
    s->rx(cob::kLssMaster, {0x42, 0x02, 0x00, 0x01, 0x00});  // revision
    s->rx(cob::kLssMaster, {0x43, 42, 0x00, 0x00, 0x00});    // serial: selected, 44h answers
    s->rx(0x621, {0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0});      // 2000h
    s->rx(0x640, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0});      // 1000h on the second channel
    EXPECT_EQ(s->od.set<std::uint8_t>(0x6000, 1, 3), SdoAbortCode::None);
    s->node->advance(s->now);  // TPDO1, event-driven (operational only)
    s->at(t0 + 60ms);
    for (int ms = 100; ms <= 400; ms += 10) s->at(t0 + std::chrono::milliseconds(ms));  // node 5 silent
    // Reset node (CiA 301 §7.3.2.2.1): the EMCY producer restarts; the controller is still error
    // passive, so 8120h is raised again once pre-operational.
    s->rx(0x000, {0x81, 0x21});
    s->at(t0 + 410ms);
    s->bus(BusEvent::Restarted);  // after a bus-off: 8140h "recovered", and 8120h ends
  }
  EXPECT_EQ(b.log, a.log);
  EXPECT_NE(fresh.log, a.log);
  EXPECT_THAT(a.log, ::testing::Contains("320 ms: heartbeat lost 5"));
}

// An LSS activate bit timing under way (CiA 305): the copy stays silent as long, switches at the
// same time and sends its first heartbeat at the same time.
TEST(NodeState, ABitTimingSwitchUnderWayCarriesOver) {
  Side a;
  a.node->start(a.now);
  a.rx(cob::kLssMaster, {0x04, 0x01});
  a.rx(cob::kLssMaster, {0x13, 0x00, 0x04});  // 125 kbit/s
  a.rx(cob::kLssMaster, {0x15, 0x2C, 0x01});  // activate, 300 ms switch delay
  a.at(t0 + 50ms);
  ASSERT_TRUE(a.node->bit_timing_silent());
  a.log.clear();
  Side b;
  Side fresh;
  fresh.node->start(fresh.now);
  copy_state(*a.node, *b.node);
  EXPECT_TRUE(b.node->bit_timing_silent());
  fresh.log.clear();
  for (Side* s : {&a, &b, &fresh}) {
    for (int ms = 60; ms <= 700; ms += 10) s->at(t0 + std::chrono::milliseconds(ms));
    s->rx(cob::kLssMaster, {0x5E});  // inquire node-ID: answered once silence is over
  }
  EXPECT_EQ(b.log, a.log);
  EXPECT_NE(fresh.log, a.log);
  EXPECT_THAT(a.log, ::testing::Contains("300 ms: bit timing 4"));
  // The bit rate in use, once switched: the one the program sets the interface to.
  Side c;
  copy_state(*a.node, *c.node);
  EXPECT_EQ(c.node->bit_timing_index(), 4u);
  EXPECT_EQ(fresh.node->bit_timing_index(), 3u);
}

// How far an identify remote slave and a fastscan have come (CiA 305): the copy answers the
// step that completes them as the original does; a fresh slave, which has seen no earlier step,
// does not.
TEST(LssSlaveState, IdentifyAndFastscanProgressCarriesOver) {
  const lss::Address address{.vendor = 0x1234, .product = 0x852, .revision = 0x10002, .serial = 42};
  std::vector<std::string> log_a;
  std::vector<std::string> log_b;
  std::vector<std::string> log_fresh;
  const auto slave = [&](std::vector<std::string>& log) {
    return LssSlave(address, NodeId::unconfigured_id(), 3, [&log](const CanFrame& f) { log.push_back(f.to_string()); });
  };
  LssSlave a = slave(log_a);
  LssSlave b = slave(log_b);
  LssSlave fresh = slave(log_fresh);
  const auto frame = [](std::initializer_list<std::uint8_t> bytes) {
    std::vector<std::uint8_t> v(bytes);
    v.resize(8, 0);
    return CanFrame(cob::kLssMaster, std::span<const std::uint8_t>(v));
  };
  a.on_frame(frame({0x46, 0x34, 0x12}), t0);                 // identify: vendor
  a.on_frame(frame({0x47, 0x52, 0x08}), t0);                 // product
  a.on_frame(frame({0x48, 0x00, 0x00, 0x01}), t0);           // revision low 10000h
  a.on_frame(frame({0x49, 0xFF, 0xFF, 0x01}), t0);           // revision high 1FFFFh
  a.on_frame(frame({0x4A, 0x00}), t0);                       // serial low 0
  a.on_frame(frame({0x51, 0, 0, 0, 0, 0x80}), t0);           // fastscan reset: answered
  a.on_frame(frame({0x51, 0x34, 0x12, 0, 0, 0, 0, 1}), t0);  // vendor matches: on to product
  log_a.clear();
  copy_state(a, b);
  for (LssSlave* s : {&a, &b, &fresh}) {
    s->on_frame(frame({0x4B, 0xFF}), t0 + 1ms);                       // serial high FFh: 4Fh answers
    s->on_frame(frame({0x51, 0x52, 0x08, 0, 0, 0, 1, 2}), t0 + 2ms);  // product matches: answered
  }
  EXPECT_EQ(log_b, log_a);
  EXPECT_EQ(log_a.size(), 2u);
  EXPECT_TRUE(log_fresh.empty());
}

TEST(NodeState, AStateOfAnotherConfigurationOrStateMachineIsRefused) {
  Side a;
  a.node->start(a.now);
  StateWriter w;
  a.node->export_state(w);
  {
    // Three heartbeat consumers instead of two: another dictionary layout.
    ObjectDictionary od;
    test_support::build_application_od(od, kId);
    NodeConfig c = config();
    c.heartbeat_consumers = 3;
    Node other(od, c, [](const CanFrame&) {});
    EXPECT_THROW(other.import_state(StateReader::parse(w.text())), StateError);
  }
  {
    // No second SDO channel.
    ObjectDictionary od;
    test_support::build_application_od(od, kId);
    NodeConfig c = config();
    c.sdo_servers.clear();
    Node other(od, c, [](const CanFrame&) {});
    EXPECT_THROW(other.import_state(StateReader::parse(w.text())), StateError);
  }
  const auto with = [&](const std::string& key, const std::string& value) {
    return test_support::with_value(w.text(), key, value);
  };
  const std::pair<std::string, std::string> bad[] = {
      {with("cob_base", "255"), "state: 'cob_base' is no node-ID (1..127): the COB-IDs follow a valid one"},
      {with("bit_timing", "10"), "state: 'bit_timing' is no bit timing this node supports or a store gives"},
      {with("lss.pending_bit_timing", "10"),
       "state: 'lss.pending_bit_timing' is no bit timing this node supports or a store gives"},
      {with("gate", "4"), "state: 'gate' differs from the NMT state"},  // stopped, in pre-operational
      {with("lss.active_node_id", "5"), "state: 'lss.active_node_id' differs from the NMT node-ID"},
      {with("lss.mode", "2"), "state: 'lss.mode' is no LSS mode"},
      {with("lss.selective_next", "64"), "state: 'lss.selective_next' is no step of switch state selective"},
      {with("lss.fastscan_pos", "4"), "state: 'lss.fastscan_pos' is no part of the LSS address (0..3)"},
  };
  for (const auto& [text, message] : bad) {
    Side b;
    EXPECT_EQ(test_support::refusal(*b.node, text), message);
  }
}

// A store may give a bit timing the node does not support, or one table 0 reserves or leaves to
// automatic detection (read_lss_store takes 0..9): the node runs on it as stored, so a state it
// writes then is one a run leaves and is taken back.
TEST(NodeState, AStoredBitTimingTheNodeDoesNotSupportIsTakenBack) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("oegw_node_state_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::filesystem::path store = dir / "store";
  for (const std::uint8_t stored : {1, 5, 9}) {
    SCOPED_TRACE(static_cast<int>(stored));
    std::string error;
    ASSERT_TRUE(write_lss_store(store, LssStored{kId, stored}, error)) << error;
    const auto make = [&](ObjectDictionary& od) {
      test_support::build_application_od(od, kId);
      NodeConfig c = config();
      c.store_path = store;
      c.supported_bit_timings = 1u << 4;  // 125 kbit/s only
      return std::make_unique<Node>(od, c, [](const CanFrame&) {});
    };
    ObjectDictionary od_a;
    const auto a = make(od_a);
    a->start(t0);
    ASSERT_EQ(a->bit_timing_index(), stored);
    StateWriter w;
    a->export_state(w);
    ObjectDictionary od_b;
    const auto b = make(od_b);
    EXPECT_NO_THROW(b->import_state(StateReader::parse(w.text())));
    EXPECT_EQ(b->bit_timing_index(), stored);
    EXPECT_EQ(b->lss().pending_bit_timing(), stored);
  }
  std::filesystem::remove_all(dir);
}

// The store file as the node last read or wrote it is in its state (its next reset applies
// it): the text a save wrote, nothing after a restore of all groups, and the same again from a
// node given the state. A state saying neither is refused.
TEST(NodeState, TheStoreFileAsTheNodeLastSawItIsInTheState) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("oegw_node_store_state_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto make = [&](ObjectDictionary& od, const std::string& file) {
    test_support::build_application_od(od, kId);
    NodeConfig c = config();
    c.store_path = dir / file;
    return std::make_unique<Node>(od, c, [](const CanFrame&) {});
  };
  const auto seen = [](const Node& n) {
    StateWriter w;
    n.export_state(w);
    const StateReader r = StateReader::parse(w.text()).in("store");
    return std::pair{r.get<int>("file"), r.has("text") ? r.text("text", 1u << 20) : std::string("-")};
  };
  // An expedited download of `value` (UNSIGNED16: 2Bh, UNSIGNED32: 23h).
  const auto sdo = [&](Node& n, std::uint16_t index, std::uint8_t sub, std::uint32_t value, std::uint8_t cs = 0x23) {
    n.on_frame(CanFrame(0x620, {cs, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub,
                                static_cast<std::uint8_t>(value), static_cast<std::uint8_t>(value >> 8),
                                static_cast<std::uint8_t>(value >> 16), static_cast<std::uint8_t>(value >> 24)}),
               t0);
  };
  ObjectDictionary od_a;
  const auto a = make(od_a, "a.store");
  a->start(t0);
  EXPECT_EQ(seen(*a), (std::pair{0, std::string("-")})) << "no file yet";
  sdo(*a, 0x1017, 0, 250, 0x2B);
  sdo(*a, 0x1010, 1, ParameterStore::kSaveSignature);
  std::ifstream in(dir / "a.store");
  const std::string file((std::istreambuf_iterator<char>(in)), {});
  ASSERT_NE(file.find("1017 00 FA00"), std::string::npos) << file;
  EXPECT_EQ(seen(*a), (std::pair{1, file}));
  StateWriter w;
  a->export_state(w);
  ObjectDictionary od_b;
  const auto b = make(od_b, "b.store");
  b->import_state(StateReader::parse(w.text()));
  EXPECT_EQ(seen(*b), (std::pair{1, file})) << "taken from the state, not from its own (absent) file";
  sdo(*a, 0x1011, 1, ParameterStore::kLoadSignature);
  EXPECT_EQ(seen(*a), (std::pair{0, std::string("-")}));
  ObjectDictionary od_d;
  const auto d = make(od_d, "d.store");
  EXPECT_EQ(test_support::refusal(*d, test_support::with_value(w.text(), "store.file", "3")),
            "state: 'store.file' is none of 0 (absent), 1 (read), 2 (refused)");
  std::filesystem::remove_all(dir);
}

// A transfer under way is not state (it holds a client's half-sent data and callbacks): a
// server in the middle of a segmented upload cannot be exported.
TEST(NodeState, ANodeWithAnSdoTransferUnderWayIsNotExported) {
  Side a;
  a.node->start(a.now);
  a.rx(0x620, {0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0});  // 1008h device name: segmented
  StateWriter w;
  EXPECT_THROW(a.node->export_state(w), std::logic_error);
  a.rx(0x620, {0x60, 0, 0, 0, 0, 0, 0, 0});  // seven bytes
  a.rx(0x620, {0x70, 0, 0, 0, 0, 0, 0, 0});  // the last two: idle again
  StateWriter again;
  EXPECT_NO_THROW(a.node->export_state(again));
}

}  // namespace
}  // namespace oegw::canopen
