// Test support for the run-time state's twin tests (canopen/state.hpp): a copy given another
// object's state.
#pragma once

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <optional>
#include <string>

#include "canopen/state.hpp"

namespace oegw::canopen::test_support {

// `part`'s state as text.
template <class T>
std::string state_text(const T& part) {
  StateWriter w;
  part.export_state(w);
  return w.text();
}

// `from`'s state, given to `to`: every key must be taken by the import, and exported again the
// state must be the same.
template <class T>
void copy_state(const T& from, T& to) {
  StateWriter w;
  from.export_state(w);
  const StateReader r = StateReader::parse(w.text());
  to.import_state(r);
  EXPECT_THAT(r.unread(), ::testing::IsEmpty()) << w.text();
  StateWriter again;
  to.export_state(again);
  EXPECT_EQ(again.text(), w.text()) << "a round trip changes the state";
}

// `text` with `key`'s value replaced by `value`, or its line left out when `value` is nullopt.
// The key must be there (else the test fails and `text` comes back unchanged).
inline std::string with_value(const std::string& text, const std::string& key,
                              const std::optional<std::string>& value) {
  std::string t = "\n" + text;
  const std::size_t line = t.find("\n" + key + " ");
  EXPECT_NE(line, std::string::npos) << key << " in\n" << text;
  if (line == std::string::npos) return text;
  const std::size_t end = t.find('\n', line + 1);
  if (value) {
    t.replace(line + 1, end - line - 1, key + " " + *value);
  } else {
    t.erase(line + 1, end == std::string::npos ? std::string::npos : end - line);
  }
  return t.substr(1);
}

// The StateError `to.import_state` throws for `text`, or "accepted".
template <class T>
std::string refusal(T& to, const std::string& text) {
  try {
    to.import_state(StateReader::parse(text));
  } catch (const StateError& e) {
    return e.what();
  }
  return "accepted";
}

}  // namespace oegw::canopen::test_support
