#include "subdevices/mcb402_commissioning.hpp"

#include <bit>
#include <cstdio>

namespace oegw::subdevices {

namespace {

// [MCB §2] CN6: BP1 on pin 13, BP2 on 11, ... BP7 on 1 (each shorts its input to GND).
int cn6_pin(std::size_t button) { return 15 - 2 * static_cast<int>(button); }

std::string hex2(std::uint8_t v) {
  char b[4];
  std::snprintf(b, sizeof b, "%02X", v);
  return b;
}

}  // namespace

ButtonBitsFinder::ButtonBitsFinder(Options options, canopen::FrameSink send,
                                   std::function<void(const std::string&)> say)
    : options_(options), send_(std::move(send)), say_(std::move(say)) {}

void ButtonBitsFinder::start(canopen::TimePoint now) {
  state_ = State::Listening;
  char cob[8];
  std::snprintf(cob, sizeof cob, "%03X", static_cast<unsigned>(canopen::cob::kTpdo1 + options_.node.value()));
  say_("listening for TPDO1 of node " + hex2(options_.node.value()) + "h (COB-ID " + cob + "h, byte 2 = 6000h:03)");
  deadline_ = now + options_.start_after;
  if (options_.start_after.count() == 0) ask(now);
}

void ButtonBitsFinder::ask(canopen::TimePoint now) {
  ++button_;
  if (button_ > mcb402::kButtons) {
    result_ = bits_;
    state_ = State::Done;
    deadline_.reset();
    return;
  }
  state_ = State::Pressing;
  deadline_ = now + options_.step_timeout;
  say_("press and hold BP" + std::to_string(button_) + " (CN6 pin " + std::to_string(cn6_pin(button_)) + ")");
}

void ButtonBitsFinder::fail(const std::string& why) {
  error_ = why;
  state_ = State::Failed;
  deadline_.reset();
  say_(why);
}

bool ButtonBitsFinder::on_frame(const canopen::CanFrame& frame, canopen::TimePoint now) {
  if (frame.extended || frame.rtr || frame.id != canopen::cob::kTpdo1 + options_.node.value()) return false;
  if (frame.dlc <= mcb402::kButtonByte) return true;  // not the operation mode 4 mapping
  const std::uint8_t cc = frame.data[mcb402::kButtonByte];
  switch (state_) {
    case State::Listening:
    case State::Started:
      // The first TPDO1, before any prompt: nothing is pressed.
      released_ = cc;
      if (cc != 0)
        say_("released, byte 2 reads " + hex2(cc) +
             "h (6002h:03 inverts some inputs; the gateway writes 00h at boot): "
             "presses are read against it");
      ask(now);
      return true;
    case State::Pressing: {
      const auto changed = static_cast<std::uint8_t>(cc ^ released_);
      if (changed == 0) return true;
      if (std::popcount(changed) != 1) {
        say_("byte 2 reads " + hex2(cc) + "h: more than one bit changed; release every button and press BP" +
             std::to_string(button_) + " alone");
        state_ = State::Releasing;
        button_ -= 1;  // asked again once released
        return true;
      }
      const auto bit = static_cast<std::uint8_t>(std::countr_zero(changed));
      if ((used_ & (1u << bit)) != 0) {
        say_("bit " + std::to_string(bit) + " is an earlier button's; release and press BP" + std::to_string(button_) +
             " alone");
        state_ = State::Releasing;
        button_ -= 1;
        return true;
      }
      bits_[button_ - 1] = bit;
      used_ |= 1u << bit;
      say_("BP" + std::to_string(button_) + " sets bit " + std::to_string(bit) + " (byte 2 = " + hex2(cc) +
           "h); release it");
      state_ = State::Releasing;
      return true;
    }
    case State::Releasing:
      if (cc == released_) ask(now);
      return true;
    default: return true;
  }
}

void ButtonBitsFinder::advance(canopen::TimePoint now) {
  if (!deadline_ || now < *deadline_) return;
  switch (state_) {
    case State::Listening:
      if (options_.start_after.count() != 0) {
        // [MCB §4] "Write on bus : 000 01 03 — Starts MCB402 at address 0x03".
        if (send_) send_(canopen::CanFrame(0x000, {0x01, options_.node.value()}));
        say_("no TPDO1 within " +
             std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(options_.start_after).count()) +
             " ms: sent NMT start node " + hex2(options_.node.value()) + "h (000#01" + hex2(options_.node.value()) +
             ")");
        state_ = State::Started;
        deadline_ = now + options_.start_after;
      }
      break;
    case State::Started:
      // Started and still silent: a board whose TPDO1 is sent on change only; nothing pressed reads 00h.
      released_ = 0x00;
      ask(now);
      break;
    case State::Pressing:
    case State::Releasing:
      fail("no " + std::string(state_ == State::Pressing ? "press" : "release") + " of BP" + std::to_string(button_) +
           " seen within " +
           std::to_string(std::chrono::duration_cast<std::chrono::seconds>(options_.step_timeout).count()) +
           " s (is the board's TPDO1 on this bus, node " + hex2(options_.node.value()) + "h?)");
      break;
    default: break;
  }
}

std::optional<canopen::TimePoint> ButtonBitsFinder::next_deadline() const { return deadline_; }

std::string ButtonBitsFinder::yaml_line(const mcb402::ButtonBits& bits) {
  std::string out = "button_bits: [";
  for (std::size_t i = 0; i < bits.size(); ++i) out += (i == 0 ? "" : ", ") + std::to_string(bits[i]);
  return out + "]";
}

std::string ButtonBitsFinder::command_line_option(const mcb402::ButtonBits& bits) {
  std::string out = "button_bits=";
  for (std::size_t i = 0; i < bits.size(); ++i) out += (i == 0 ? "" : "/") + std::to_string(bits[i]);
  return out;
}

}  // namespace oegw::subdevices
