// libFuzzer target for SdoServer. The input is cut into 9-byte chunks: byte 0 gives the DLC
// (byte % 9) and a time step ((byte / 9) * 50 ms, so timeouts happen), bytes 1..8 are the data
// of a frame on the server's rx COB-ID. Besides memory errors (ASan), it traps on broken
// invariants: every frame sent is an 8-byte frame on the tx COB-ID; the object dictionary
// changes only together with a download confirmation; the server is free after its timeout and
// then serves a normal upload.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "canopen/301/object_dictionary.hpp"
#include "canopen/301/sdo_server.hpp"

using namespace oegw::canopen;

namespace {

void check(bool ok) {
  if (!ok) __builtin_trap();
}

void build(ObjectDictionary& od) {
  od.add_var(0x1000, "Device type", DataType::Unsigned32, Access::Const, encode<std::uint32_t>(0x00080196));
  od.add_var(0x1008, "Name", DataType::VisibleString, Access::Const,
             std::vector<std::uint8_t>{'f', 'u', 'z', 'z', ' ', 'd', 'e', 'v', 'i', 'c', 'e', '!'});
  od.add_var(0x2000, "U8", DataType::Unsigned8, Access::ReadWrite, {0});
  od.add_var(0x2001, "U16", DataType::Unsigned16, Access::ReadWrite, encode<std::uint16_t>(0));
  od.add_var(0x2002, "U32 wo", DataType::Unsigned32, Access::WriteOnly, encode<std::uint32_t>(0));
  od.add_var(0x2100, "Domain", DataType::Domain, Access::ReadWrite, {});
  od.find(0x2100, 0)->max_size = 300;
  od.add_var(0x2101, "String", DataType::VisibleString, Access::ReadWrite, {});
  od.find(0x2101, 0)->max_size = 10;
  Object& even = od.add_var(0x2102, "Even", DataType::Domain, Access::ReadWrite, {});
  even.add_write_hook([](Object&, std::uint8_t, std::span<const std::uint8_t> b, Origin) {
        return b.size() % 2 == 0 ? SdoAbortCode::None : SdoAbortCode::InvalidValue;
      })
      .detach();  // stateless: may live as long as the Object
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  ObjectDictionary od;
  build(od);
  int writes = 0;
  const Subscription obs = od.add_observer([&](std::uint16_t, std::uint8_t, Origin) { ++writes; });
  std::vector<CanFrame> out;
  SdoServer server(
      od, [&](const CanFrame& f) { out.push_back(f); }, NodeId{3});
  TimePoint now{std::chrono::seconds(1)};

  for (std::size_t off = 0; off + 9 <= size; off += 9) {
    CanFrame f;
    f.id = 0x603;
    f.dlc = static_cast<std::uint8_t>(data[off] % 9);
    for (std::size_t i = 0; i < 8; ++i) f.data[i] = data[off + 1 + i];
    out.clear();
    const int before = writes;
    check(server.on_frame(f, now));
    check(out.size() <= SdoServer::kMaxBlockSize);
    for (const CanFrame& o : out) check(o.id == 0x583 && o.dlc == 8 && !o.extended && !o.rtr);
    if (writes != before) {
      check(writes == before + 1 && !out.empty());
      const std::uint8_t a = out.back().data[0];
      check(a == 0x60 || (a & 0xEF) == 0x20 || a == 0xA1);
    }
    if (server.busy())
      check(server.next_deadline().has_value() && *server.next_deadline() <= now + SdoServer::kDefaultTimeout);
    now += std::chrono::milliseconds((data[off] / 9) * 50);
    out.clear();
    server.advance(now);
    for (const CanFrame& o : out) check(o.data[0] == 0x80 && get_u32(o.data.data() + 4) == 0x05040000);
  }

  now += SdoServer::kDefaultTimeout;
  server.advance(now);
  check(!server.busy());
  out.clear();
  server.on_frame(CanFrame(0x603, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), now);
  check(out.size() == 1 && out[0] == CanFrame(0x583, {0x43, 0x00, 0x10, 0x00, 0x96, 0x01, 0x08, 0x00}));
  return 0;
}
