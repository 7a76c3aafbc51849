#pragma once
// The FE samples (gateway/fe_samples.hpp) as the DDS types idlc generates from oegw.idl, written
// into the caller's storage. Private to the DDS publisher and its tests: it names the generated types.
//
// Each sample starts as all-zero bytes, padding included. Cyclone DDS serialises a type whose
// in-memory layout matches its CDR layout by copying the bytes (its "optimised" write): the 3 bytes
// after `instance` are copied onto the wire with the fields. Filled by aggregate initialisation they
// are whatever the stack held (valgrind: "sendmsg ... points to uninitialised byte(s)"), i.e. memory
// of the gateway on the cab network. Zero-filling the whole object is the one portable way: C++
// leaves padding unspecified under an initialiser list.

#include <cstring>
#include <type_traits>

#include "gateway/fe_samples.hpp"
#include "oegw.h"

namespace oegw::publish::dds_samples {

template <class T>
void zero(T& m) {
  static_assert(std::is_trivially_copyable_v<T>, "a generated DDS type without pointers");
  std::memset(&m, 0, sizeof m);
}

inline oegw_FeStatus status(gateway::FeStatus s) { return static_cast<oegw_FeStatus>(static_cast<int>(s)); }

template <class T>
void header(const gateway::SampleHeader& h, T& m) {
  m.instance = h.instance;
  m.status = status(h.status);
  m.timestamp_us = h.timestamp_us;
  m.seq = h.seq;
}

inline void fill(const gateway::JoystickSample& s, oegw_Joystick& m) {
  zero(m);
  header(s.h, m);
  m.x = s.x;
  m.y = s.y;
  m.z = s.z;
  m.buttons = s.buttons;
  m.memory = s.memory;
}
inline void fill(const gateway::PedalSample& s, oegw_Pedal& m) {
  zero(m);
  header(s.h, m);
  m.position = s.position;
  m.memory = s.memory;
}
inline void fill(const gateway::WheelSample& s, oegw_Wheel& m) {
  zero(m);
  header(s.h, m);
  m.position = s.position;
}
inline void fill(const gateway::EncoderSample& s, oegw_Encoder& m) {
  zero(m);
  header(s.h, m);
  m.position = static_cast<std::int32_t>(s.position);  // 6120h UNSIGNED32's 32 bits in a DDS `long`
}
inline void fill(const gateway::ButtonClusterSample& s, oegw_ButtonCluster& m) {
  zero(m);
  header(s.h, m);
  m.switches = s.switches;
}
inline void fill(const gateway::EmcySample& e, oegw_Emcy& m) {
  zero(m);
  m.code = e.code;
  m.error_register = e.error_register;
  std::memcpy(m.msef, e.msef.data(), sizeof m.msef);
  m.timestamp_us = e.timestamp_us;
}

}  // namespace oegw::publish::dds_samples
