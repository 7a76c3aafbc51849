// publish/dds_samples.hpp: the samples handed to Cyclone DDS carry the FE values in their
// fields and zero in every other byte. Cyclone copies a CDR-compatible type's bytes onto the wire,
// padding included; each test fills storage that held 0xAA bytes, as a reused stack frame would.
#include "publish/dds_samples.hpp"

#include <gtest/gtest.h>

#include <cstddef>
#include <new>
#include <vector>

namespace oegw::gateway {
namespace {

// A field's place in the object.
struct Span {
  std::size_t offset, size;
};
#define OEGW_FIELD(T, f) \
  Span { offsetof(T, f), sizeof(T::f) }

template <class Dds, class Sample>
std::vector<unsigned char> filled(const Sample& s) {
  alignas(Dds) unsigned char storage[sizeof(Dds)];
  std::memset(storage, 0xAA, sizeof storage);
  auto* m = new (storage) Dds;  // default-initialised: the 0xAA bytes stay
  publish::dds_samples::fill(s, *m);
  return {storage, storage + sizeof storage};
}

// The object those bytes hold (copied out: a vector's bytes need not be aligned for it, armhf's
// -Wcast-align says so).
template <class Dds>
Dds as(const std::vector<unsigned char>& bytes) {
  Dds m;
  std::memcpy(&m, bytes.data(), sizeof m);
  return m;
}

// The bytes of the object that no field covers (padding) are zero; returns how many there are,
// so a test can say its type has padding at all.
std::size_t padding_zero(const std::vector<unsigned char>& bytes, const std::vector<Span>& fields) {
  std::vector<bool> covered(bytes.size(), false);
  for (const Span& f : fields)
    for (std::size_t i = f.offset; i < f.offset + f.size; ++i) covered[i] = true;
  std::size_t padding = 0;
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    if (covered[i]) continue;
    ++padding;
    EXPECT_EQ(bytes[i], 0u) << "padding byte " << i << " of " << bytes.size();
  }
  return padding;
}

template <class T>
std::vector<Span> header_fields() {
  return {OEGW_FIELD(T, instance), OEGW_FIELD(T, status), OEGW_FIELD(T, timestamp_us), OEGW_FIELD(T, seq)};
}

SampleHeader header() {
  SampleHeader h;
  h.instance = 3;
  h.status = FeStatus::Error;
  h.timestamp_us = 0x0102030405060708;
  h.seq = 77;
  return h;
}

TEST(DdsSamples, AJoystickCarriesItsValuesAndZeroPadding) {
  JoystickSample s;
  s.h = header();
  s.x = -32768;
  s.y = 12345;
  s.z = -1;
  s.buttons = 0x81;
  s.memory = 0x05;
  const auto bytes = filled<oegw_Joystick>(s);
  const auto m = as<oegw_Joystick>(bytes);
  EXPECT_EQ(m.instance, 3);
  EXPECT_EQ(m.status, publish::dds_samples::status(FeStatus::Error));
  EXPECT_EQ(m.timestamp_us, 0x0102030405060708);
  EXPECT_EQ(m.seq, 77u);
  EXPECT_EQ(m.x, -32768);
  EXPECT_EQ(m.y, 12345);
  EXPECT_EQ(m.z, -1);
  EXPECT_EQ(m.buttons, 0x81);
  EXPECT_EQ(m.memory, 0x05);
  auto f = header_fields<oegw_Joystick>();
  for (Span x : {OEGW_FIELD(oegw_Joystick, x), OEGW_FIELD(oegw_Joystick, y), OEGW_FIELD(oegw_Joystick, z),
                 OEGW_FIELD(oegw_Joystick, buttons), OEGW_FIELD(oegw_Joystick, memory)})
    f.push_back(x);
  // 3 bytes after `instance` (on the wire: CDR aligns `status` to 4 as well) and the tail.
  EXPECT_GE(padding_zero(bytes, f), 3u);
}

TEST(DdsSamples, EveryOtherInputKindHasZeroPadding) {
  PedalSample p;
  p.h = header();
  p.position = -200;
  p.memory = 1;
  const auto pb = filled<oegw_Pedal>(p);
  EXPECT_EQ(as<oegw_Pedal>(pb).position, -200);
  auto pf = header_fields<oegw_Pedal>();
  pf.push_back(OEGW_FIELD(oegw_Pedal, position));
  pf.push_back(OEGW_FIELD(oegw_Pedal, memory));
  EXPECT_GE(padding_zero(pb, pf), 3u);

  WheelSample w;
  w.h = header();
  w.position = 999;
  const auto wb = filled<oegw_Wheel>(w);
  EXPECT_EQ(as<oegw_Wheel>(wb).position, 999);
  auto wf = header_fields<oegw_Wheel>();
  wf.push_back(OEGW_FIELD(oegw_Wheel, position));
  EXPECT_GE(padding_zero(wb, wf), 3u);

  EncoderSample e;
  e.h = header();
  e.position = 0xFFFFFFF0u;  // UNSIGNED32 6120h: its 32 bits in a DDS `long`
  const auto eb = filled<oegw_Encoder>(e);
  EXPECT_EQ(static_cast<std::uint32_t>(as<oegw_Encoder>(eb).position), 0xFFFFFFF0u);
  auto ef = header_fields<oegw_Encoder>();
  ef.push_back(OEGW_FIELD(oegw_Encoder, position));
  EXPECT_GE(padding_zero(eb, ef), 3u);

  ButtonClusterSample b;
  b.h = header();
  b.switches = 0x8000000000000001u;
  const auto bb = filled<oegw_ButtonCluster>(b);
  EXPECT_EQ(as<oegw_ButtonCluster>(bb).switches, 0x8000000000000001u);
  auto bf = header_fields<oegw_ButtonCluster>();
  bf.push_back(OEGW_FIELD(oegw_ButtonCluster, switches));
  EXPECT_GE(padding_zero(bb, bf), 3u);
}

TEST(DdsSamples, AnEmcyCarriesItsBytes) {
  EmcySample e;
  e.code = 0x7000;
  e.error_register = 0x81;
  e.msef = {0x11, 0x22, 0x33, 0x44, 0x55};
  e.timestamp_us = 42;
  const auto bytes = filled<oegw_Emcy>(e);
  const auto m = as<oegw_Emcy>(bytes);
  EXPECT_EQ(m.code, 0x7000);
  EXPECT_EQ(m.error_register, 0x81);
  EXPECT_EQ(m.msef[0], 0x11);
  EXPECT_EQ(m.msef[4], 0x55);
  EXPECT_EQ(m.timestamp_us, 42);
  padding_zero(bytes, {OEGW_FIELD(oegw_Emcy, code), OEGW_FIELD(oegw_Emcy, error_register), OEGW_FIELD(oegw_Emcy, msef),
                       OEGW_FIELD(oegw_Emcy, timestamp_us)});
}

}  // namespace
}  // namespace oegw::gateway
