// What the example subscribers print for a joystick sample (examples/dds_subscriber.c,
// examples/lcm_subscriber.cpp), built from the sample the test published: the tests compare the
// two line by line.
#pragma once

#include <cstdio>
#include <string>

#include "gateway/fe_samples.hpp"

namespace oegw::test {

inline const char* status_name(gateway::FeStatus s) {
  static const char* const names[] = {"valid", "error", "not_available", "stale", "offline"};
  return names[static_cast<int>(s)];
}

// The subscribers' line, without the trailing " rx_us=...".
inline std::string line_of(const gateway::JoystickSample& j) {
  char b[256];
  std::snprintf(b, sizeof b,
                "joystick instance=%u status=%s seq=%u ts_us=%lld x=%d y=%d z=%d buttons=0x%02x memory=0x%02x",
                j.h.instance, status_name(j.h.status), j.h.seq, static_cast<long long>(j.h.timestamp_us), j.x, j.y, j.z,
                j.buttons, j.memory);
  return b;
}
inline std::string without_rx(const std::string& l) { return l.substr(0, l.find(" rx_us=")); }

}  // namespace oegw::test
