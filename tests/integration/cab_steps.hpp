// Steps of the incidents the integration tests drive the simulated cab through (rig/cab_rig.hpp).
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "gateway/gateway.hpp"
#include "rig/cab_rig.hpp"
#include "tests/fixtures/fixtures.hpp"

namespace oegw::testing {

// A mapping file of tests/fixtures/ (fixtures::mapping_file), loaded as the gateway does;
// throws std::runtime_error with the diagnostics if it does not load.
inline mapping::Config fixture_config(const std::string& name) {
  auto loaded = mapping::load_config_text(fixtures::mapping_file(name), name, gateway::driver_catalogue());
  if (!loaded.ok()) throw std::runtime_error(loaded.error_text());
  return std::move(*loaded.config);
}

// A simulator command (SimBench::command, "left_grip cable_break 2 on"); the test fails unless
// it is taken.
inline void cab_command(rig::CabRig& rig, const std::string& line) {
  const std::string r = rig.command(line);
  ASSERT_EQ(r.rfind("ok", 0), 0u) << line << ": " << r;
}

// An SDO download of the rig's host to `node`, waited for (at most 1 s); an abort fails the test.
inline void host_sdo_write(rig::CabRig& rig, canopen::NodeId node, std::uint16_t index, std::uint8_t sub,
                           std::vector<std::uint8_t> data) {
  bool done = false;
  rig.host().sdo(node).download(index, sub, std::move(data), [&](canopen::SdoAbortCode c, std::vector<std::uint8_t>) {
    EXPECT_EQ(c, canopen::SdoAbortCode::None);
    done = true;
  });
  for (int i = 0; i < 100 && !done; ++i) rig.run_for(std::chrono::milliseconds(10));
  ASSERT_TRUE(done);
}

// Moves the cab's inputs for `d`, in steps of 20 ms (SimBench::move: sine sweeps).
inline void sweep(rig::CabRig& rig, canopen::Duration d) {
  for (auto end = rig.now() + d; rig.now() < end;) {
    rig.devices().move(rig.now());
    rig.run_for(std::chrono::milliseconds(20));
  }
}

}  // namespace oegw::testing
