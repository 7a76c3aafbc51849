// libFuzzer target for SdoServer's remote (routed) mode (canopen/301/sdo_remote.hpp). The input is
// cut into 10-byte chunks: byte 0 gives the DLC (byte % 9) and a time step ((byte / 9) * 50 ms),
// byte 1 what the fake remote does with a pending transfer (bits 0..1: 0 nothing yet, 1 answer
// with data of bit 2..7 bytes, 2 answer with an abort code, 3 refuse at once in the next call;
// bit 7 of byte 1 set first sends a network indication choosing the remote), bytes 2..9 the data
// of a frame on the server's rx COB-ID. Besides memory errors (ASan), it traps on broken
// invariants: every frame sent is an 8-byte frame on the tx COB-ID; at most one remote transfer
// is pending; the server never calls the remote for a cancelled ticket's answer; a done of a
// cancelled ticket changes nothing; once the remote has answered everything and the time-out has
// passed the server is idle, and naming the server itself gives back a normal upload.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <vector>

#include "canopen/301/object_dictionary.hpp"
#include "canopen/301/sdo_remote.hpp"
#include "canopen/301/sdo_server.hpp"

using namespace oegw::canopen;

namespace {

void check(bool ok) {
  if (!ok) __builtin_trap();
}

class FakeRemote final : public SdoRemote {
 public:
  SdoAbortCode select(const SdoTarget& target, Selection& selection) override {
    if (target.network == 0) {
      selection = Selection::Local;
      return SdoAbortCode::None;
    }
    if (target.network > 2) return SdoAbortCode::ObjectDoesNotExist;
    selection = Selection::Remote;
    return SdoAbortCode::None;
  }
  Ticket upload(const SdoTarget&, std::uint16_t, std::uint8_t, TimePoint, Done done) override {
    return start(std::move(done));
  }
  Ticket download(const SdoTarget&, std::uint16_t, std::uint8_t, std::span<const std::uint8_t> data,
                  bool size_indicated, TimePoint, Done done) override {
    check(size_indicated || data.size() == 4);
    check(data.size() <= SdoServer::kMaxRemoteDownload);
    return start(std::move(done));
  }
  void cancel(Ticket ticket, SdoAbortCode) override {
    check(pending_ && ticket_ == ticket);  // only the pending transfer is ever cancelled
    cancelled_ = std::move(pending_);
    pending_.reset();
  }

  // Byte 1 of a chunk: answers the pending transfer, or arms an immediate refusal.
  void act(std::uint8_t how) {
    refuse_next_ = (how & 3) == 3;
    if (!pending_ || (how & 3) == 0 || (how & 3) == 3) return;
    Done done = std::move(*pending_);
    pending_.reset();
    if ((how & 3) == 1) {
      done(SdoAbortCode::None, std::vector<std::uint8_t>((how >> 2) & 0x1F, 0x5A));
    } else {
      done(SdoAbortCode::InvalidValue, {});
    }
  }
  // A late answer to a cancelled transfer: must change nothing.
  void late_done() {
    if (!cancelled_) return;
    Done done = std::move(*cancelled_);
    cancelled_.reset();
    done(SdoAbortCode::None, {1, 2, 3, 4});
  }
  [[nodiscard]] bool pending() const { return pending_.has_value(); }
  void finish_all() {
    while (pending_) act(1);
  }

 private:
  Ticket start(Done done) {
    check(!pending_);  // one transfer at a time per channel
    ++ticket_;
    if (refuse_next_) {
      refuse_next_ = false;
      done(SdoAbortCode::CannotTransferDeviceState, {});
      return ticket_;
    }
    pending_ = std::move(done);
    return ticket_;
  }
  std::optional<Done> pending_, cancelled_;
  Ticket ticket_ = 0;
  bool refuse_next_ = false;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  ObjectDictionary od;
  od.add_var(0x1000, "Device type", DataType::Unsigned32, Access::Const, encode<std::uint32_t>(0x00080196));
  int writes = 0;
  const Subscription obs = od.add_observer([&](std::uint16_t, std::uint8_t, Origin) { ++writes; });
  std::vector<CanFrame> out;
  FakeRemote remote;
  SdoServer server(
      od, [&](const CanFrame& f) { out.push_back(f); }, NodeId{3});
  server.set_remote(&remote);
  TimePoint now{std::chrono::seconds(1)};
  auto frames_ok = [&] {
    for (const CanFrame& o : out) check(o.id == 0x583 && o.dlc == 8 && !o.extended && !o.rtr);
    check(out.size() <= SdoServer::kMaxBlockSize);
  };

  for (std::size_t off = 0; off + 10 <= size; off += 10) {
    out.clear();
    if (data[off + 1] & 0x80) check(server.on_frame(CanFrame(0x603, {0xE0, 0, 0, 0, 2, 0x11, 0, 0}), now));
    CanFrame f;
    f.id = 0x603;
    f.dlc = static_cast<std::uint8_t>(data[off] % 9);
    for (std::size_t i = 0; i < 8; ++i) f.data[i] = data[off + 2 + i];
    check(server.on_frame(f, now));
    remote.act(data[off + 1]);
    remote.late_done();
    frames_ok();
    now += std::chrono::milliseconds((data[off] / 9) * 50);
    out.clear();
    server.advance(now);
    frames_ok();
  }
  // The own dictionary is only written by local transfers; nothing here targets it but 1000h (const).
  check(writes == 0);

  remote.finish_all();
  remote.late_done();
  now += SdoServer::kDefaultTimeout;
  server.advance(now);
  now += SdoServer::kDefaultTimeout;
  server.advance(now);
  check(!server.busy() && !remote.pending());
  out.clear();
  server.on_frame(CanFrame(0x603, {0xE0, 0, 0, 0, 0, 0, 0, 0}), now);  // back to the own dictionary
  check(out.size() == 1 && out[0].data[0] == 0xE0);
  out.clear();
  server.on_frame(CanFrame(0x603, {0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0}), now);
  check(out.size() == 1 && out[0] == CanFrame(0x583, {0x43, 0x00, 0x10, 0x00, 0x96, 0x01, 0x08, 0x00}));
  return 0;
}
