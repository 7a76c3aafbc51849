// Test support for the run-time state's twin tests (canopen/state.hpp): a copy given another
// object's state.
#pragma once

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "canopen/state.hpp"

namespace oegw::canopen::test_support {

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

}  // namespace oegw::canopen::test_support
