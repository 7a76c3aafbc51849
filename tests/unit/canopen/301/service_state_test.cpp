// Run-time state export/import of the CiA 301 services (canopen/state.hpp). Each "twin" test
// drives service A into a mid-life state, builds B fresh with the same configuration, gives it
// A's dictionary values and A's state, then feeds both the same frames and times: everything B
// sends or reports must be what A does. Each also shows that B without the import acts
// differently, so a member left out of the state fails its test.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "../state_twin.hpp"
#include "canopen/301/emcy.hpp"
#include "canopen/301/heartbeat.hpp"
#include "canopen/301/nmt_slave.hpp"
#include "canopen/301/pdo.hpp"
#include "canopen/301/sdo_client.hpp"
#include "canopen/301/sdo_pacer.hpp"
#include "canopen/301/sync.hpp"
#include "canopen/state.hpp"

namespace oegw::canopen {
namespace {

using namespace std::chrono_literals;
using test_support::copy_state;
using ::testing::ElementsAre;
using ::testing::IsEmpty;

const TimePoint t0{Duration{5'000'000}};

// What a service did, and when: "12 ms: sent 185#07". A copy that acts at another time (an
// inhibit time or a timer phase lost) differs even when it sends the same frames.
struct Log {
  TimePoint now = t0;
  std::vector<std::string> lines;
  void add(const std::string& what) { lines.push_back(std::to_string((now - t0) / 1ms) + " ms: " + what); }
  FrameSink sink() {
    return [this](const CanFrame& f) { add("sent " + f.to_string()); };
  }
};

// Two dictionaries and logs for a service A and its copy B, and a third for a fresh one.
struct Sides {
  ObjectDictionary od_a;
  ObjectDictionary od_b;
  ObjectDictionary od_fresh;
  Log log_a;
  Log log_b;
  Log log_fresh;
};

void copy_values(const ObjectDictionary& from, ObjectDictionary& to) {
  StateWriter w;
  from.export_values(w);
  const StateReader r = StateReader::parse(w.text());
  to.import_values(r);
  EXPECT_THAT(r.unread(), IsEmpty());
}

// ---- object dictionary -------------------------------------------------------------------

TEST(DictionaryState, ValuesOtherThanTheDefaultsTravelAndTheRestReturnsToDefault) {
  ObjectDictionary a;
  ObjectDictionary b;
  install_heartbeat_producer_objects(a, 100);
  install_heartbeat_consumer_objects(a, 2);
  install_heartbeat_producer_objects(b, 100);
  install_heartbeat_consumer_objects(b, 2);
  ASSERT_EQ(a.set<std::uint16_t>(0x1017, 0, 250, Origin::Sdo), SdoAbortCode::None);
  ASSERT_EQ(b.set<std::uint32_t>(0x1016, 2, heartbeat_consumer_entry(NodeId{9}, 300), Origin::Sdo), SdoAbortCode::None);
  StateWriter w;
  a.export_values(w);
  EXPECT_EQ(w.text().find("1016"), std::string::npos) << "a default value is not written: " << w.text();
  const StateReader r = StateReader::parse(w.text());
  b.import_values(r);
  EXPECT_EQ(b.get<std::uint16_t>(0x1017, 0), 250);
  EXPECT_EQ(b.get<std::uint32_t>(0x1016, 2), 0u) << "B's own change is not A's: back to the default";
}

TEST(DictionaryState, ADictionaryOfAnotherLayoutIsRefused) {
  ObjectDictionary a;
  ObjectDictionary b;
  install_heartbeat_producer_objects(a, 100);
  install_heartbeat_consumer_objects(a, 2);
  install_heartbeat_producer_objects(b, 100);
  install_heartbeat_consumer_objects(b, 3);
  StateWriter w;
  a.export_values(w);
  EXPECT_THROW(b.import_values(StateReader::parse(w.text())), StateError);
  EXPECT_EQ(b.get<std::uint16_t>(0x1017, 0), 100) << "a refused import changes nothing";
  // The same entries with another default (as a node-ID changes 1014h and the PDO COB-IDs): a
  // value equal to A's default is not in A's state, so B's default would stand in for it.
  ObjectDictionary c;
  install_heartbeat_producer_objects(c, 200);
  install_heartbeat_consumer_objects(c, 2);
  EXPECT_THROW(c.import_values(StateReader::parse(w.text())), StateError);
}

TEST(DictionaryState, AValueOfTheWrongLengthIsRefusedAndChangesNothing) {
  ObjectDictionary a;
  install_heartbeat_producer_objects(a, 100);
  StateWriter w;
  a.export_values(w);
  std::string text = w.text() + "1017.00 #e80300\n";
  try {
    a.import_values(StateReader::parse(text));
    FAIL() << "accepted";
  } catch (const StateError& e) {
    EXPECT_STREQ(e.what(), "state: '1017.00' is 3 bytes, UNSIGNED16 takes 2");
  }
  EXPECT_EQ(a.get<std::uint16_t>(0x1017, 0), 100);
}

// ---- heartbeat ---------------------------------------------------------------------------

struct Heartbeats {
  ObjectDictionary od;
  Log log;
  HeartbeatProducer producer{(install_heartbeat_producer_objects(od, 100), od), NodeId{0x20}, log.sink()};
  HeartbeatConsumer consumer{(install_heartbeat_consumer_objects(od, 2), od)};
  Heartbeats() {
    EXPECT_EQ(od.set<std::uint32_t>(0x1016, 1, heartbeat_consumer_entry(NodeId{5}, 150), Origin::Sdo),
              SdoAbortCode::None);
    EXPECT_EQ(od.set<std::uint32_t>(0x1016, 2, heartbeat_consumer_entry(NodeId{6}, 150), Origin::Sdo),
              SdoAbortCode::None);
    consumer.on_timeout([this](NodeId n) { log.add("lost " + std::to_string(n.value())); });
    consumer.on_state([this](NodeId n, NmtState st) {
      log.add("state " + std::to_string(n.value()) + " " + std::to_string(static_cast<int>(st)));
    });
  }
  void frame(const CanFrame& f, TimePoint at) {
    run(at);
    log.now = at;
    consumer.on_frame(f, at);
  }
  void run(TimePoint until) {
    for (;;) {
      std::optional<TimePoint> d = producer.next_deadline();
      const std::optional<TimePoint> c = consumer.next_deadline();
      if (!d || (c && *c < *d)) d = c;
      if (!d || *d > until) return;
      log.now = *d;
      producer.advance(*d);
      consumer.advance(*d);
    }
  }
};

TEST(HeartbeatState, AConsumerTimesOutAndAProducerBeatsInThePhaseOfTheOriginal) {
  Heartbeats a;
  // Started on node-ID 21h, not the 20h it was built with: as after an LSS change (CiA 305).
  a.producer.start(NmtState::Operational, NodeId{0x21}, t0 + 30ms);
  a.frame(CanFrame{0x705, {0x05}}, t0 + 40ms);
  a.frame(CanFrame{0x706, {0x7F}}, t0 + 90ms);
  a.frame(CanFrame{0x706, {0x05, 0x00}}, t0 + 95ms);  // invalid: counted
  a.run(t0 + 100ms);
  a.log.lines.clear();

  Heartbeats b;
  Heartbeats fresh;
  copy_values(a.od, b.od);
  b.producer.reload();
  b.consumer.reload();
  copy_state(a.producer, b.producer);
  copy_state(a.consumer, b.consumer);
  EXPECT_EQ(b.consumer.invalid_frames(), 1u);
  for (Heartbeats* h : {&a, &b, &fresh}) {
    h->frame(CanFrame{0x706, {0x7F}}, t0 + 180ms);  // no change of state for A
    h->run(t0 + 300ms);
  }
  EXPECT_EQ(b.log.lines, a.log.lines);
  EXPECT_THAT(a.log.lines, ElementsAre("130 ms: sent 721#05", "190 ms: lost 5", "230 ms: sent 721#05"));
  EXPECT_NE(fresh.log.lines, a.log.lines);
}

// ---- SYNC --------------------------------------------------------------------------------

TEST(SyncState, AProducerGoesOnWithItsCounterAndPeriodPhase) {
  const SyncConfig config{.cob_id = 0x40000080, .period_us = 10'000, .counter_overflow = 5};
  Sides x;
  SyncService a(x.od_a, x.log_a.sink(), config);
  SyncService b(x.od_b, x.log_b.sink(), config);
  SyncService fresh(x.od_fresh, x.log_fresh.sink(), config);
  a.advance(t0 + 3ms);
  for (int i = 1; i <= 3; ++i) a.advance(t0 + 3ms + i * 10ms);
  x.log_a.lines.clear();
  copy_values(x.od_a, x.od_b);
  b.reload();
  copy_state(a, b);
  EXPECT_EQ(b.last_sync(), a.last_sync());
  for (int ms = 34; ms <= 80; ++ms) {
    for (auto [svc, log] : {std::pair{&a, &x.log_a}, std::pair{&b, &x.log_b}, std::pair{&fresh, &x.log_fresh}}) {
      log->now = t0 + Duration{ms * 1000};
      svc->advance(log->now);
    }
  }
  EXPECT_EQ(x.log_b.lines, x.log_a.lines);
  EXPECT_THAT(x.log_a.lines,
              ElementsAre("43 ms: sent 080#04", "53 ms: sent 080#05", "63 ms: sent 080#01", "73 ms: sent 080#02"));
  EXPECT_NE(x.log_fresh.lines, x.log_a.lines);
}

// ---- EMCY --------------------------------------------------------------------------------

TEST(EmcyState, ActiveErrorsAndFramesHeldByTheInhibitTimeCarryOver) {
  const EmcyConfig config{.inhibit_time = 50};  // 5 ms
  Sides x;
  EmcyProducer a(x.od_a, x.log_a.sink(), NodeId{0x20}, config);
  EmcyProducer b(x.od_b, x.log_b.sink(), NodeId{0x20}, config);
  EmcyProducer fresh(x.od_fresh, x.log_fresh.sink(), NodeId{0x20}, config);
  a.raise(0x7000, 0, t0);
  a.raise(0x8130, 0, t0 + 1ms);  // held until t0 + 5 ms
  x.log_a.lines.clear();
  copy_values(x.od_a, x.od_b);
  copy_state(a, b);
  EXPECT_TRUE(b.active(0x7000));
  EXPECT_EQ(b.error_register(), a.error_register());
  for (auto [p, log] : {std::pair{&a, &x.log_a}, std::pair{&b, &x.log_b}, std::pair{&fresh, &x.log_fresh}}) {
    for (const auto at : {3ms, 5ms}) {
      log->now = t0 + at;
      p->advance(log->now);
    }
    log->now = t0 + 6ms;
    p->clear(0x7000, log->now);
    log->now = t0 + 7ms;
    p->clear(0x8130, log->now);  // the last: "error reset", held until t0 + 10 ms
    log->now = t0 + 10ms;
    p->advance(log->now);
  }
  EXPECT_EQ(x.log_b.lines, x.log_a.lines);
  EXPECT_THAT(x.log_a.lines, ElementsAre("5 ms: sent 0A0#3081010000000000", "10 ms: sent 0A0#0000000000000000"));
  EXPECT_THAT(x.log_fresh.lines, IsEmpty());
}

// ---- PDO ---------------------------------------------------------------------------------

struct Pdos {
  ObjectDictionary od;
  Log log;
  std::unique_ptr<PdoService> pdo;
  Pdos() {
    od.add_array(0x6000, "Read input 8-bit", DataType::Unsigned8, Access::ReadOnly, 3, {0}, true);
    od.add_array(0x6200, "Write output 8-bit", DataType::Unsigned8, Access::ReadWrite, 2, {0}, true);
    // TPDO 1: inhibit 10 ms, event timer 50 ms. TPDO 2: every 2nd SYNC from the SYNC counting 3
    // (CiA 301 §7.5.2.37, 1800h:06). TPDO 3: synchronous on RTR (FCh): sampled at a SYNC, sent on
    // request. TPDO 4: its event timer alone (30 ms). RPDO 1: deadline 100 ms. RPDO 2: synchronous.
    install_tpdo(od, 1,
                 {.cob_id = 0x40000185,
                  .transmission_type = 255,
                  .inhibit_time = 100,
                  .event_timer = 50,
                  .mapping = {0x60000108, 0x60000208, 0x60000308}});
    install_tpdo(od, 2, {.cob_id = 0x40000285, .transmission_type = 2, .sync_start = 3, .mapping = {0x60000108}});
    install_tpdo(od, 3, {.cob_id = 0x385, .transmission_type = 252, .mapping = {0x60000108}});
    install_tpdo(od, 4, {.cob_id = 0x40000485, .transmission_type = 255, .event_timer = 30, .mapping = {0x60000208}});
    install_rpdo(od, 1, {.cob_id = 0x205, .transmission_type = 255, .event_timer = 100, .mapping = {0x62000108}});
    install_rpdo(od, 2, {.cob_id = 0x305, .transmission_type = 1, .mapping = {0x62000208}});
    pdo = std::make_unique<PdoService>(od, log.sink());
    pdo->on_rpdo = [this](std::uint16_t n) {
      log.add("rpdo " + std::to_string(n) + " " + std::to_string(od.get<std::uint8_t>(0x6200, n)));
    };
    pdo->on_rpdo_timeout = [this](std::uint16_t n) { log.add("timeout " + std::to_string(n)); };
  }
  void run(TimePoint until) {
    while (auto d = pdo->next_deadline()) {
      if (*d > until) break;
      log.now = *d;
      pdo->advance(*d);
    }
    log.now = until;
    pdo->advance(until);
  }
  void sync(std::uint8_t counter, TimePoint at) {
    run(at);
    pdo->on_sync(counter, at);
  }
  void frame(const CanFrame& f, TimePoint at) {
    run(at);
    pdo->on_frame(f, at);
  }
  void input(std::uint8_t v, TimePoint at) {
    run(at);
    ASSERT_EQ(od.set<std::uint8_t>(0x6000, 1, v), SdoAbortCode::None);
  }
};

TEST(PdoState, TimersInhibitTimesChangedDataAndHeldSynchronousDataCarryOver) {
  Pdos a;
  a.pdo->set_operational(true, t0);
  a.run(t0);
  a.input(7, t0 + 2ms);                        // TPDO 1 inhibited until t0 + 10 ms
  a.frame(CanFrame{0x205, {0x11}}, t0 + 3ms);  // RPDO 1: deadline t0 + 103 ms
  a.sync(1, t0 + 4ms);                         // TPDO 2 still waits for counter 3
  a.sync(3, t0 + 5ms);                         // TPDO 2 sends, and counts from here
  a.sync(4, t0 + 6ms);                         // TPDO 2 counts 1; TPDO 3 samples 7
  a.frame(CanFrame{0x305, {0x22}}, t0 + 7ms);  // RPDO 2: applied at the next SYNC
  a.input(9, t0 + 7ms);                        // TPDO 1 changed again, still inhibited
  a.run(t0 + 8ms);
  a.log.lines.clear();

  Pdos b;
  Pdos fresh;
  copy_values(a.od, b.od);
  b.pdo->reload();
  copy_state(*a.pdo, *b.pdo);
  for (Pdos* p : {&a, &b, &fresh}) {
    p->frame(CanFrame::remote(0x385, 1), t0 + 9ms);  // TPDO 3 answers with what it sampled
    p->sync(5, t0 + 20ms);
    p->sync(1, t0 + 25ms);
    p->run(t0 + 120ms);
  }
  EXPECT_EQ(b.log.lines, a.log.lines);
  EXPECT_THAT(a.log.lines,
              ElementsAre("9 ms: sent 385#07", "10 ms: sent 185#090000", "20 ms: rpdo 2 34", "20 ms: sent 285#09",
                          "30 ms: sent 485#00", "60 ms: sent 185#090000", "60 ms: sent 485#00", "90 ms: sent 485#00",
                          "103 ms: timeout 1", "110 ms: sent 185#090000", "120 ms: sent 485#00"));
  EXPECT_THAT(fresh.log.lines, IsEmpty());
}

TEST(PdoState, AStateNamingAPdoThisDictionaryLacksIsRefused) {
  Pdos a;
  StateWriter w;
  a.pdo->export_state(w);
  const std::string text = w.text() + "tpdo.9.requested 1\n";
  try {
    a.pdo->import_state(StateReader::parse(text));
    FAIL() << "accepted";
  } catch (const StateError& e) {
    EXPECT_STREQ(e.what(), "state: 'tpdo.9' is no PDO of this dictionary");
  }
}

// ---- NMT slave ---------------------------------------------------------------------------

TEST(NmtState, TheNodeIdLssGaveTheStateAndTheCountsCarryOver) {
  Log log_a;
  Log log_b;
  Log log_fresh;
  NmtSlave a(NodeId{0x20}, log_a.sink());
  NmtSlave b(NodeId{0x20}, log_b.sink());
  NmtSlave fresh(NodeId{0x20}, log_fresh.sink());
  a.start(t0);
  a.set_pending_node_id(NodeId{0x21});            // LSS configure node-ID (CiA 305)
  a.on_frame(CanFrame{0x000, {0x82, 0x20}}, t0);  // reset communication: now 21h
  a.on_frame(CanFrame{0x000, {0x01, 0x21}}, t0 + 1ms);
  a.on_frame(CanFrame{0x000, {0x01}}, t0 + 2ms);  // malformed: counted
  log_a.lines.clear();
  copy_state(a, b);
  EXPECT_EQ(b.node_id(), NodeId{0x21});
  EXPECT_EQ(b.state(), NmtState::Operational);
  EXPECT_EQ(b.stats().malformed, 1u);
  EXPECT_EQ(b.stats().commands, 2u);
  EXPECT_EQ(b.last_transition(), t0 + 1ms);
  fresh.start(t0);
  log_fresh.lines.clear();
  for (auto [s, log] : {std::pair{&a, &log_a}, std::pair{&b, &log_b}, std::pair{&fresh, &log_fresh}}) {
    log->now = t0 + 10ms;
    s->on_frame(CanFrame{0x000, {0x82, 0x21}}, log->now);
  }
  EXPECT_EQ(log_b.lines, log_a.lines);
  EXPECT_THAT(log_a.lines, ElementsAre("10 ms: sent 721#00"));
  EXPECT_THAT(log_fresh.lines, IsEmpty());
}

TEST(NmtState, AStateOutsideTheStateMachineIsRefused) {
  NmtSlave a(NodeId{0x20}, [](const CanFrame&) {});
  StateWriter w;
  a.export_state(w);
  std::string text = w.text();
  const std::size_t at = text.find("\nstate ");
  ASSERT_NE(at, std::string::npos);
  text.replace(at + 1, text.find('\n', at + 1) - at - 1, "state 3");
  try {
    a.import_state(StateReader::parse(text));
    FAIL() << "accepted";
  } catch (const StateError& e) {
    EXPECT_STREQ(e.what(), "state: 'state' = 3 is no NMT state");
  }
}

// ---- SDO client and pacer ----------------------------------------------------------------

// The pacer's next free slot (a master's clients share it) and its count carry over: a copy
// refuses a request as early as the original would.
TEST(SdoPacerState, TheNextFreeSlotCarriesOver) {
  SdoPacer a(10ms);
  SdoPacer b(10ms);
  SdoPacer fresh(10ms);
  ASSERT_TRUE(a.try_start(t0));
  ASSERT_FALSE(a.try_start(t0 + 4ms));
  ASSERT_TRUE(a.try_start(t0 + 10ms, true));  // waited: a delayed start
  copy_state(a, b);
  EXPECT_EQ(b.delayed_starts(), 1u);
  EXPECT_FALSE(b.try_start(t0 + 15ms));
  EXPECT_TRUE(fresh.try_start(t0 + 15ms));
  EXPECT_EQ(b.next_free(), a.next_free());
}

// An idle client's last ticket (each request's name, unique per client), stale-answer count and
// the time it was last given carry over: a copy names its next request as the original would,
// and awaits its answer as long.
TEST(SdoClientState, AnIdleClientsTicketsCountsAndTimeCarryOver) {
  Log log_a;
  Log log_b;
  Log log_fresh;
  SdoClient a(log_a.sink(), NodeId{5});
  SdoClient b(log_b.sink(), NodeId{5});
  SdoClient fresh(log_fresh.sink(), NodeId{5});
  log_a.now = t0 + 1s;
  a.advance(log_a.now);
  a.upload(0x1000, 0, [](SdoAbortCode, std::vector<std::uint8_t>) {});
  a.advance(log_a.now);                                                          // the request starts
  a.on_frame(CanFrame{0x585, {0x43, 0x08, 0x10, 0x00, 0, 0, 0, 0}}, log_a.now);  // 1008h: stale
  a.on_frame(CanFrame{0x585, {0x43, 0x00, 0x10, 0x00, 0x91, 0x01, 0x0F, 0x00}}, log_a.now + 2ms);
  ASSERT_TRUE(a.idle());
  log_a.lines.clear();
  copy_state(a, b);
  EXPECT_EQ(b.stale_answers(), 1u);
  for (auto [c, log] : {std::pair{&a, &log_a}, std::pair{&b, &log_b}, std::pair{&fresh, &log_fresh}}) {
    log->now = t0 + 1s + 2ms;
    // Queued outside on_frame()/advance(): due at the time the client was last given.
    log->add("ticket " + std::to_string(c->upload(0x1018, 1, [](SdoAbortCode, std::vector<std::uint8_t>) {})));
    const std::optional<TimePoint> due = c->next_deadline();
    log->add(due ? "answer due at " + std::to_string((*due - t0) / 1ms) + " ms" : "no deadline");
  }
  EXPECT_EQ(log_b.lines, log_a.lines);
  EXPECT_NE(log_fresh.lines, log_a.lines);
  // Busy: a transfer under way is not state.
  StateWriter w;
  EXPECT_THROW(a.export_state(w), std::logic_error);
}

}  // namespace
}  // namespace oegw::canopen
