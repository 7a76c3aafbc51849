// Remote SDO access (CiA 302-7 multi-level networking): an SDO server channel whose requests are
// carried to a node of another network. The SdoServer speaks the SDO protocol with its client
// (expedited, segmented and block, both directions, as the client chooses) and hands each whole
// transfer to an SdoRemote, which performs it on the other network with an SDO client of its own
// and reports the result; the server then answers its client. Sans I/O like every service here.
//
// The SDO network indication (client command specifier 7, CiA 301 v4.2 §7.2.4.3; the service
// CiA 302-7 builds on) names the target of one server channel. No public source the project
// could consult prints the frame layout (searched: CiA 301/302-7 "SDO network indication",
// "ccs 7", "multi-level networking", in documentation, code, issue and web corpora); the layout
// below is therefore this project's decision, chosen to look like every other SDO request:
//
//   request  (client -> server)  E0h | 00 00 00 | network | node | 00 00
//            byte 0: ccs = 7 (bits 7..5), bits 4..0 reserved 0 (sent 0; the SdoServer takes
//            any byte 0 with ccs = 7, as it takes any abort with ccs = 4); bytes 1..3: the multiplexer,
//            which names no object here and is sent 0; byte 4: network ID (1..127); byte 5:
//            node-ID (1..127); bytes 6..7 reserved (sent 0, ignored).
//   response (server -> client)  E0h | bytes 1..7 of the request echoed (scs = 7)
//   refusal                      the abort frame 80h | 00 00 00 | abort code (CiA 301 §7.2.4.3.17)
//
// The target stays until the client names another one, the server's COB-IDs change, or the
// server is reset (NMT reset communication, power-on, entering NMT stopped: canopen/node.cpp
// resets its SDO servers then): the server's own dictionary is the target
// again. Naming the server itself (its own network ID and node-ID, or network 0 and node 0)
// returns to the own dictionary. A channel bound to a target by configuration refuses network
// indications (0800 0021h).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "canopen/types.hpp"

namespace oegw::canopen {

// A node of some network, as a network indication (or a channel binding) names it.
struct SdoTarget {
  std::uint8_t network = 0;  // CiA 302-7 network ID, 1..127 (0: the server itself)
  std::uint8_t node = 0;     // node-ID, 1..127
  friend bool operator==(const SdoTarget&, const SdoTarget&) = default;
};

// The other side of a routed server channel (implemented by the gateway).
class SdoRemote {
 public:
  // A transfer's one result: SdoAbortCode::None and the data (empty for a download), or the
  // abort code to send to the server's client (the remote server's own code passed on
  // unchanged, 0504 0000h on a remote time-out, ...).
  using Done = std::function<void(SdoAbortCode code, std::vector<std::uint8_t> data)>;
  using Ticket = std::uint32_t;
  // How select() answers a network indication.
  enum class Selection : std::uint8_t { Local, Remote };

  SdoRemote() = default;
  SdoRemote(const SdoRemote&) = delete;
  SdoRemote& operator=(const SdoRemote&) = delete;
  virtual ~SdoRemote() = default;

  // A network indication named `target` (bytes 4 and 5 as received, not range-checked by the
  // server): SdoAbortCode::None and Local (the server's own dictionary) or Remote, or the code
  // the server aborts the indication with (the target then does not change).
  virtual SdoAbortCode select(const SdoTarget& target, Selection& selection) = 0;
  // Starts a transfer to `target`. `done` is called exactly once — possibly before this returns
  // (a request refused at once), or later from anywhere (the other bus's frame handling): the
  // server sends its answer from inside `done` — unless the ticket is cancelled first. A
  // server has at most one transfer pending; it never cancels a ticket whose done was called.
  // `data` (a download's whole value, at most SdoServer::kMaxRemoteDownload bytes) is valid only
  // during the call. `size_indicated` false: the client sent an expedited download without a
  // size (e = 1, s = 0, CiA 301 §7.2.4.3.3); `data` is its four bytes and the remote must send it
  // the same way, for the remote server to take as many as its object has. `now` is the time of
  // the server's frame that completed the request (the remote's own SDO time-outs run from it).
  virtual Ticket upload(const SdoTarget& target, std::uint16_t index, std::uint8_t sub, TimePoint now, Done done) = 0;
  virtual Ticket download(const SdoTarget& target, std::uint16_t index, std::uint8_t sub,
                          std::span<const std::uint8_t> data, bool size_indicated, TimePoint now, Done done) = 0;
  // The server's client gave up on the transfer: `why` is the client's own abort code, or
  // 0x060A0023 (a new request while this one is in flight), 0x05040001 (a malformed frame),
  // 0x08000000 (the channel reset, its COB-IDs changed, rebound, or the server destroyed). The
  // remote transfer is aborted with `why` (queued: dropped) and `done` must not be called (the
  // server ignores it if it is).
  virtual void cancel(Ticket ticket, SdoAbortCode why) = 0;
};

}  // namespace oegw::canopen
