// A service's run-time state as text: what a fresh object of the same configuration needs to carry
// on exactly where another left off (a recording's snapshot at a segment's start, replayed from
// there). Configuration is not in it: the object is rebuilt from its dictionary and settings
// first, then import_state() sets what only the run decided (timers' phases, latched faults,
// counters).
//
// The text is one `key value` pair per line, in the order written:
//
//   hb.consumer.1.status 2
//   hb.consumer.1.last 1250000          a TimePoint: µs of the loop clock
//   emcy.queue.0.frame.data #0081000000000000  bytes: '#' and two hex digits each
//
// A key is [a-z0-9_.] without an empty component, and appears once. A std::optional that is empty writes nothing:
// reading it back gives nullopt. Errors (a malformed line, a repeated key, a missing key, a value out of its type's
// range) throw StateError naming the key or the line; an import that throws has been given a state of another
// configuration or version, and its object must be thrown away.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

class StateError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class StateWriter {
 public:
  // Keys written while a Scope lives are prefixed with its name and a dot. Scopes nest.
  class Scope {
   public:
    Scope(StateWriter& w, std::string_view name);
    Scope(const Scope&) = delete;
    Scope& operator=(const Scope&) = delete;
    ~Scope();

   private:
    StateWriter& w_;
    std::size_t length_;  // the prefix's length before this scope
  };

  void put(std::string_view key, std::int64_t value);
  template <class T>
  requires(std::is_integral_v<T> || std::is_enum_v<T>) void put(std::string_view key, T value) {
    put(key, static_cast<std::int64_t>(value));
  }
  void put(std::string_view key, TimePoint t) { put(key, t.time_since_epoch().count()); }
  void put(std::string_view key, Duration d) { put(key, d.count()); }
  template <class T>
  void put(std::string_view key, const std::optional<T>& value) {
    if (value) put(key, *value);
  }
  void put_bytes(std::string_view key, std::span<const std::uint8_t> bytes);
  // A text (a log line, a reason), as its bytes.
  void put_text(std::string_view key, std::string_view text);
  // Under `key`: id, rtr, extended, dlc, data (empty for a remote frame).
  void put(std::string_view key, const CanFrame& frame);
  // A part's own state under `key`: part.export_state(*this).
  template <class Part>
  void put_state(std::string_view key, const Part& part) {
    const Scope scope(*this, key);
    part.export_state(*this);
  }
  // A list: `key.count`, then item i under `key.i`, written by item(i).
  template <class Fn>
  void put_list(std::string_view key, std::size_t count, Fn&& item) {
    const Scope list(*this, key);
    put("count", count);
    for (std::size_t i = 0; i < count; ++i) {
      const Scope one(*this, std::to_string(i));
      item(i);
    }
  }

  [[nodiscard]] const std::string& text() const { return text_; }

 private:
  void begin_line(std::string_view key);
  std::string prefix_;
  std::string text_;
};

class StateReader {
 public:
  // Throws StateError ("state line N: …") on a line without a value, a bad key or a repeated key.
  [[nodiscard]] static StateReader parse(std::string_view text);

  // The keys below `name`.
  [[nodiscard]] StateReader in(std::string_view name) const;
  [[nodiscard]] bool has(std::string_view key) const;
  // The distinct first components of the keys below this reader ("1", "2" for tpdo.1.x, tpdo.2.y),
  // for an importer to refuse entries its object does not have.
  [[nodiscard]] std::vector<std::string> children() const;
  // Throws StateError "state: '<full key>' <what>".
  [[noreturn]] void fail(std::string_view key, std::string_view what) const;

  [[nodiscard]] std::int64_t integer(std::string_view key) const;
  // An integer that must fit T (an enum: its underlying type, not checked against the
  // enumerators: the caller does); throws StateError if it does not.
  template <class T>
  [[nodiscard]] T get(std::string_view key) const {
    if constexpr (std::is_same_v<T, bool>) {
      return ranged(key, 0, 1) != 0;
    } else if constexpr (std::is_enum_v<T>) {
      return static_cast<T>(get<std::underlying_type_t<T>>(key));
    } else {
      static_assert(std::is_integral_v<T> && sizeof(T) <= 8);
      using L = std::numeric_limits<T>;
      if constexpr (std::is_unsigned_v<T> && sizeof(T) == 8) {
        return static_cast<T>(integer(key));  // written as its two's-complement int64
      } else {
        return static_cast<T>(ranged(key, static_cast<std::int64_t>(L::min()), static_cast<std::int64_t>(L::max())));
      }
    }
  }
  // get<T>(key), or nullopt when the key is absent (a std::optional written by put()).
  template <class T>
  [[nodiscard]] std::optional<T> optional(std::string_view key) const {
    return has(key) ? std::optional<T>(get<T>(key)) : std::nullopt;
  }
  // get<T>(key), or `fallback` when the key is absent.
  template <class T>
  [[nodiscard]] T get_or(std::string_view key, T fallback) const {
    return has(key) ? get<T>(key) : fallback;
  }
  [[nodiscard]] TimePoint time(std::string_view key) const { return TimePoint{Duration{integer(key)}}; }
  [[nodiscard]] Duration duration(std::string_view key) const { return Duration{integer(key)}; }
  [[nodiscard]] std::optional<TimePoint> optional_time(std::string_view key) const;
  [[nodiscard]] std::vector<std::uint8_t> bytes(std::string_view key) const;
  // A text written by put_text, of at most `max` bytes.
  [[nodiscard]] std::string text(std::string_view key, std::size_t max) const;
  [[nodiscard]] CanFrame frame(std::string_view key) const;
  // A list written by put_list: item(reader of item i) for each, in order. A count above `max`
  // throws before any item is read.
  template <class Fn>
  void read_list(std::string_view key, std::size_t max, Fn&& item) const {
    const StateReader list = in(key);
    const auto count = list.get<std::uint64_t>("count");
    if (count > max) list.fail("count", "= " + std::to_string(count) + " is above " + std::to_string(max));
    for (std::size_t i = 0; i < count; ++i) item(list.in(std::to_string(i)));
  }
  // One of the four states (is_nmt_state).
  [[nodiscard]] NmtState nmt_state(std::string_view key) const;
  // A node-ID 1..127, or FFh unconfigured (CiA 305).
  [[nodiscard]] NodeId node_id(std::string_view key) const;

  // Keys of the whole text never read through any reader made from it: a key the importer does
  // not know is a state of another version (tests require none).
  [[nodiscard]] std::vector<std::string> unread() const;

 private:
  struct Entry {
    std::string key;
    std::string value;
    std::size_t line = 0;
    bool read = false;
  };
  struct Text {
    std::vector<Entry> entries;  // sorted by key
  };
  [[nodiscard]] std::int64_t ranged(std::string_view key, std::int64_t min, std::int64_t max) const;
  [[nodiscard]] Entry* find(std::string_view key) const;
  [[nodiscard]] const std::string& value(std::string_view key) const;  // throws if missing
  [[nodiscard]] std::string full(std::string_view key) const { return prefix_ + std::string(key); }

  std::shared_ptr<Text> text_;
  std::string prefix_;
};

}  // namespace oegw::canopen
