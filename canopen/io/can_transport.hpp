// The abstract CAN transport that feeds the "sans I/O" services: frames out through send(),
// frames in through a receiver callback, bus-state changes through an event callback.
//
// Implementations: SocketCanTransport (Linux CAN_RAW), SeqpacketCanTransport (an AF_UNIX
// socketpair carrying CAN_RAW's frames, where the kernel has no AF_CAN) and VirtualBus ports
// (in-process).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string_view>

#include "canopen/bus_event.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/io/clock.hpp"
#include "canopen/io/datagram.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen::io {

// What send() did with a frame. Only InvalidFrame is a caller bug; the others are conditions of
// the bus/driver that a CANopen stack must survive (they are counted, never thrown).
enum class SendStatus : std::uint8_t {
  Ok,             // handed to the driver / put on the bus
  QueueFull,      // ENOBUFS/EAGAIN: the TX queue is full, the frame was dropped
  InterfaceDown,  // ENETDOWN
  InvalidFrame,   // dlc > 8, or an 11-bit frame with an id above 0x7FF, or id above 29 bits
  Error,          // any other failure; see SendResult::error
};

[[nodiscard]] std::string_view to_string(SendStatus status);

struct SendResult {
  SendStatus status = SendStatus::Ok;
  int error = 0;  // errno, where one applies
  [[nodiscard]] bool ok() const { return status == SendStatus::Ok; }
};

struct TransportCounters {
  std::uint64_t rx_frames = 0;     // data/remote frames delivered to the receiver
  std::uint64_t tx_frames = 0;     // frames accepted by send()
  std::uint64_t tx_dropped = 0;    // frames send() could not queue (QueueFull, detached port)
  std::uint64_t rx_dropped = 0;    // frames the kernel dropped before we read them (SO_RXQ_OVFL)
  std::uint64_t error_frames = 0;  // error frames / bus events received
  std::uint64_t errors = 0;        // other send/receive failures
};

// True if `frame` can be put on a classical CAN bus as it is.
[[nodiscard]] bool is_valid_frame(const CanFrame& frame);

class CanTransport {
 public:
  using Receiver = std::function<void(const CanFrame& frame, TimePoint timestamp)>;
  using EventHandler = std::function<void(BusEvent event)>;

  CanTransport() = default;
  CanTransport(const CanTransport&) = delete;
  CanTransport& operator=(const CanTransport&) = delete;
  virtual ~CanTransport() = default;

  // Never blocks. Failures are counted and returned, never thrown.
  virtual SendResult send(const CanFrame& frame) = 0;

  void set_receiver(Receiver receiver) { receiver_ = std::move(receiver); }
  void set_event_handler(EventHandler handler) { event_handler_ = std::move(handler); }

  // A file descriptor that becomes readable when poll_readable() has work, or -1 if the
  // transport is driven some other way (the virtual bus is drained by VirtualBus::deliver_all).
  [[nodiscard]] virtual int fd() const { return -1; }
  // Reads everything available without blocking and hands it to the receiver/event handler.
  virtual void poll_readable() {}
  // For an event loop that reads the descriptor's datagrams itself (io_uring,
  // EventLoop::receive_datagrams): how large one is; nullopt if the transport reads for itself.
  [[nodiscard]] virtual std::optional<DatagramSpec> datagram_spec() const { return std::nullopt; }
  // One datagram such a loop read (or the error its receive ended with): handled as
  // poll_readable() handles each it reads.
  virtual void take_datagram(const ReceivedDatagram& /*datagram*/) {}
  // Such a loop may also send what a wake-up's batch holds (end_batch), in the system call it
  // makes anyway to wait (EventLoop::send_datagram); an empty sender: the transport sends itself.
  void set_datagram_sender(DatagramSender sender) { datagram_sender_ = std::move(sender); }
  // A datagram sent that way that the kernel refused (EAGAIN, ENOBUFS: a full queue; others):
  // counted as send() counts its failures.
  virtual void datagram_send_failed(int /*error*/) {}

  [[nodiscard]] const TransportCounters& counters() const { return counters_; }

  // Where poll_readable() takes "now" from: the event loop's clock, read once per wake-up
  // (watch_transport sets it), so reading frames costs no clock system call of its own. Without
  // one a transport reads CLOCK_MONOTONIC itself. `clock` must outlive the transport's use of it.
  void set_clock(const Clock* clock) { clock_ = clock; }

  // Sending in batches: between begin_batch() and end_batch() a transport may hold the frames
  // send() takes and put them on the bus together at end_batch() (SocketCanTransport: one
  // sendmmsg() for all). watch_transport brackets each event-loop wake-up with them, so what one
  // wake-up sends costs one system call, not one per frame. A held frame is Ok for
  // send(); what end_batch() cannot send is counted (tx_dropped, errors) as send() would have.
  virtual void begin_batch() {}
  virtual void end_batch() {}

  // A FrameSink for the services, sending through this transport (the result is counted).
  [[nodiscard]] FrameSink sink() {
    return [this](const CanFrame& f) { (void)send(f); };
  }

 protected:
  // For implementations: count and hand over a received frame / a bus event.
  void deliver_frame(const CanFrame& frame, TimePoint timestamp);
  void deliver_event(BusEvent event);
  TransportCounters counters_;
  const Clock* clock_ = nullptr;
  DatagramSender datagram_sender_;

 private:
  Receiver receiver_;
  EventHandler event_handler_;
};

}  // namespace oegw::canopen::io
