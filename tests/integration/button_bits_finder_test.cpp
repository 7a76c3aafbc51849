// The MCB-402 commissioning aid (subdevices/mcb402_commissioning.hpp, `oegw signals mcb402
// --find-button-bits`) against the simulated board on the virtual bus, a simulated clock, and a
// scripted user who presses each button it asks for: it finds the board's wiring, whichever of
// the damaged table's readings (or any other) the board has.
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "canopen/io/clock.hpp"
#include "canopen/io/event_loop.hpp"
#include "canopen/io/virtual_bus.hpp"
#include "subdevices/mcb402_commissioning.hpp"
#include "subdevices/sim/mcb402_sim.hpp"

using namespace oegw::canopen;
using namespace oegw::canopen::io;
using namespace std::chrono_literals;
namespace sd = oegw::subdevices;
namespace sim = oegw::subdevices::sim;

namespace {

class FinderBench {
 public:
  explicit FinderBench(sim::co4013::ButtonBits wiring, bool started) {
    bus_.run_on(loop_);
    board_port_ = bus_.attach("board");
    tool_port_ = bus_.attach("tool");
    user_port_ = bus_.attach("user");
    sim::Mcb402SimConfig c;
    c.button_bits = wiring;
    board_ = std::make_unique<sim::Mcb402Sim>(board_port_->sink(), c);
    board_drv_ = std::make_unique<ServiceDriver>(loop_, *board_);
    board_port_->set_receiver([this](const CanFrame& f, TimePoint t) {
      board_->on_frame(f, t);
      board_drv_->rearm();
    });
    finder_ = std::make_unique<sd::ButtonBitsFinder>(sd::ButtonBitsFinder::Options{}, tool_port_->sink(),
                                                     [this](const std::string& line) { lines.push_back(line); });
    finder_drv_ = std::make_unique<ServiceDriver>(
        loop_, [this] { return finder_->next_deadline(); }, [this](TimePoint now) { finder_->advance(now); });
    tool_port_->set_receiver([this](const CanFrame& f, TimePoint t) {
      (void)finder_->on_frame(f, t);
      finder_drv_->rearm();
    });
    board_->start(loop_.now());
    if (started) {
      // As a running gateway leaves it: operational, TPDO1 also every 100 ms (button_timer_ms).
      (void)board_->od().set<std::uint16_t>(0x1800, 5, 100);
      board_->node().nmt().enter(NmtState::Operational, loop_.now());
    }
    board_drv_->rearm();
  }
  // The user: presses what is asked `hold` after the prompt, releases it `hold` later.
  void run(Duration hold, Duration limit, std::size_t press_two_at = 0) {
    finder_->start(loop_.now());
    finder_drv_->rearm();
    const TimePoint end = loop_.now() + limit;
    std::size_t asked_before = 0;
    bool twice = false;
    while (!finder_->done() && loop_.now() < end) {
      const std::size_t asked = finder_->asking();
      if (asked != 0 && asked != asked_before && lines.back().rfind("press and hold", 0) == 0) {
        asked_before = asked;
        loop_.advance_by(hold);
        if (asked == press_two_at && !twice) {
          // A clumsy user, once: two buttons in one coding cycle, one TPDO1 with both bits.
          (void)user_port_->send(CanFrame(0x183, {0x00, 0x00, 0x0C, 0x00}));
          twice = true;
          asked_before = 0;
        } else {
          board_->press(asked, loop_.now());
        }
        board_drv_->rearm();
        loop_.advance_by(hold);
        for (std::size_t b = 1; b <= 7; ++b) board_->release(b, loop_.now());
        board_drv_->rearm();
      }
      loop_.advance_by(1ms);
    }
  }
  sd::ButtonBitsFinder& finder() { return *finder_; }
  std::vector<std::string> lines;

 private:
  SimulatedClock clock_;
  EventLoop loop_{clock_};
  VirtualBus bus_;
  std::unique_ptr<VirtualPort> board_port_, tool_port_, user_port_;
  std::unique_ptr<sim::Mcb402Sim> board_;
  std::unique_ptr<sd::ButtonBitsFinder> finder_;
  std::unique_ptr<ServiceDriver> board_drv_, finder_drv_;
};

// Both readings of [MCB §4]'s table and an arbitrary wiring, on a board left pre-operational
// (the finder starts it: 000#0103) and on a running one.
TEST(ButtonBitsFinder, ReadsTheWiringOffTheBoard) {
  for (const auto& wiring :
       {sim::co4013::kPrintedTableBits, sim::co4013::kRightAlignedBits, sim::co4013::ButtonBits{7, 0, 6, 1, 5, 2, 4}}) {
    for (const bool started : {false, true}) {
      FinderBench b(wiring, started);
      b.run(300ms, 60s);
      ASSERT_TRUE(b.finder().result()) << b.finder().error();
      EXPECT_EQ(*b.finder().result(), wiring);
      std::string said;
      for (const auto& l : b.lines) said += l + "\n";
      EXPECT_NE(said.find("press and hold BP1 (CN6 pin 13)"), std::string::npos) << said;
      EXPECT_NE(said.find("press and hold BP7 (CN6 pin 1)"), std::string::npos) << said;
      EXPECT_EQ(said.find("sent NMT start") != std::string::npos, !started) << said;
    }
  }
  EXPECT_EQ(sd::ButtonBitsFinder::yaml_line({1, 2, 3, 4, 5, 7, 6}), "button_bits: [1, 2, 3, 4, 5, 7, 6]");
  EXPECT_EQ(sd::ButtonBitsFinder::command_line_option({0, 1, 2, 3, 4, 6, 5}), "button_bits=0/1/2/3/4/6/5");
}

// Two buttons at once is said, and that button asked for again; no press at all ends the search
// with the reason.
TEST(ButtonBitsFinder, TwoButtonsAtOnceAreAskedAgainAndNoPressTimesOut) {
  FinderBench b(sim::co4013::kRightAlignedBits, true);
  b.run(300ms, 60s, /*press_two_at=*/3);
  ASSERT_TRUE(b.finder().result()) << b.finder().error();
  EXPECT_EQ(*b.finder().result(), sim::co4013::kRightAlignedBits);
  std::string said;
  for (const auto& l : b.lines) said += l + "\n";
  EXPECT_NE(said.find("more than one bit changed; release every button and press BP3 alone"), std::string::npos)
      << said;

  FinderBench idle(sim::co4013::kRightAlignedBits, true);
  idle.finder().start(TimePoint{});
  for (int i = 0; i < 70 && !idle.finder().done(); ++i) idle.finder().advance(TimePoint{} + std::chrono::seconds(i));
  EXPECT_TRUE(idle.finder().done());
  EXPECT_FALSE(idle.finder().result());
  EXPECT_NE(idle.finder().error().find("no press of BP1 seen within 60 s"), std::string::npos) << idle.finder().error();
}

}  // namespace
