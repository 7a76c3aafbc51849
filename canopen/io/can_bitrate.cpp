#include "canopen/io/can_bitrate.hpp"

#include <fcntl.h>
#include <libsocketcan.h>
#include <linux/can/netlink.h>
#include <linux/if_link.h>
#include <linux/netlink.h>
#include <linux/rtnetlink.h>
#include <net/if.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string_view>

#include "canopen/io/socketcan_transport.hpp"

// The kernel's netlink macros (NLMSG_*, RTA_*, IFLA_RTA) are C casts.
#pragma GCC diagnostic ignored "-Wold-style-cast"
#pragma GCC diagnostic ignored "-Wcast-align"

namespace oegw::canopen::io {

namespace {

std::string errno_text(int e) { return std::strerror(e); }

// Runs a libsocketcan call and returns 0 or the errno it left (set from the netlink
// acknowledgement; EIO when it failed without one). libsocketcan reports a refusal with
// perror(), and glibc's perror() overwrites errno (EINVAL) when stderr is a write-only file, as
// under journald or a redirect: the call runs with stderr on /dev/null opened read-write, which
// keeps the kernel's errno and leaves the log to the caller's one line.
template <class Call>
int socketcan_call(Call&& call) {
  std::fflush(stderr);
  const int saved = ::dup(STDERR_FILENO);
  const int null = ::open("/dev/null", O_RDWR | O_CLOEXEC);
  if (saved >= 0 && null >= 0) ::dup2(null, STDERR_FILENO);
  errno = 0;
  const int rc = call();
  const int e = rc == 0 ? 0 : (errno != 0 ? errno : EIO);
  if (saved >= 0) {
    ::dup2(saved, STDERR_FILENO);
    ::close(saved);
  }
  if (null >= 0) ::close(null);
  return e;
}

// Walks the attributes in [data, data + len).
template <class F>
void for_each_attr(const void* data, std::size_t len, F&& f) {
  auto* rta = static_cast<const rtattr*>(data);
  auto left = static_cast<int>(len);
  for (; RTA_OK(rta, left); rta = RTA_NEXT(rta, left)) f(*rta);
}

class NetlinkCanLink final : public CanLink {
 public:
  int query(const std::string& interface, CanLinkState& state) override {
    state = {};
    InterfaceInfo info;
    try {
      info = probe_interface(interface);
    } catch (const CanOpenError& e) {
      return e.error() != 0 ? e.error() : EINVAL;
    }
    if (!info.exists) return 0;
    state.exists = true;
    state.up = info.up;
    return get_link(info.index, state);
  }
  int stop(const std::string& interface) override {
    return socketcan_call([&] { return can_do_stop(interface.c_str()); });
  }
  int set_bitrate(const std::string& interface, std::uint32_t bitrate) override {
    return socketcan_call([&] { return can_set_bitrate(interface.c_str(), bitrate); });
  }
  int start(const std::string& interface) override {
    return socketcan_call([&] { return can_do_start(interface.c_str()); });
  }

 private:
  // RTM_GETLINK for one interface: its link kind and, for "can", the bit timing it has.
  static int get_link(int index, CanLinkState& state) {
    const int fd = ::socket(AF_NETLINK, SOCK_RAW | SOCK_CLOEXEC, NETLINK_ROUTE);
    if (fd < 0) return errno;
    struct {
      nlmsghdr header;
      ifinfomsg info;
    } request{};
    request.header.nlmsg_len = NLMSG_LENGTH(sizeof(ifinfomsg));
    request.header.nlmsg_type = RTM_GETLINK;
    request.header.nlmsg_flags = NLM_F_REQUEST;
    request.header.nlmsg_seq = 1;
    request.info.ifi_family = AF_UNSPEC;
    request.info.ifi_index = index;
    int error = 0;
    if (::send(fd, &request, request.header.nlmsg_len, 0) < 0) {
      error = errno;
      ::close(fd);
      return error;
    }
    alignas(nlmsghdr) std::array<char, 16384> buffer{};
    const ssize_t n = ::recv(fd, buffer.data(), buffer.size(), 0);
    if (n < 0) error = errno;
    ::close(fd);
    if (n < 0) return error;
    auto left = static_cast<int>(n);
    for (auto* h = reinterpret_cast<const nlmsghdr*>(buffer.data()); NLMSG_OK(h, left); h = NLMSG_NEXT(h, left)) {
      if (h->nlmsg_type == NLMSG_ERROR) {
        const auto* e = static_cast<const nlmsgerr*>(NLMSG_DATA(h));
        return e->error < 0 ? -e->error : 0;
      }
      if (h->nlmsg_type != RTM_NEWLINK) continue;
      const auto* info = static_cast<const ifinfomsg*>(NLMSG_DATA(h));
      for_each_attr(IFLA_RTA(info), IFLA_PAYLOAD(h), [&state](const rtattr& a) {
        if (a.rta_type != IFLA_LINKINFO) return;
        bool can = false;
        const rtattr* data = nullptr;
        for_each_attr(RTA_DATA(&a), RTA_PAYLOAD(&a), [&](const rtattr& li) {
          if (li.rta_type == IFLA_INFO_KIND) can = std::string_view(static_cast<const char*>(RTA_DATA(&li))) == "can";
          if (li.rta_type == IFLA_INFO_DATA) data = &li;
        });
        state.has_bit_timing = can;
        if (!can || data == nullptr) return;
        for_each_attr(RTA_DATA(data), RTA_PAYLOAD(data), [&state](const rtattr& c) {
          if (c.rta_type != IFLA_CAN_BITTIMING || RTA_PAYLOAD(&c) < sizeof(can_bittiming)) return;
          can_bittiming bt{};
          std::memcpy(&bt, RTA_DATA(&c), sizeof bt);
          state.bitrate = bt.bitrate;
        });
      });
      return 0;
    }
    return EIO;
  }
};

std::string failure(const std::string& interface, std::uint32_t bitrate, int error) {
  return "cannot set " + interface + " to " + std::to_string(bitrate) + " bit/s: " + errno_text(error);
}

}  // namespace

std::unique_ptr<CanLink> netlink_can_link() { return std::make_unique<NetlinkCanLink>(); }

BitRateOutcome plan_bit_rate(CanLink& link, const std::string& interface, std::uint32_t bitrate) {
  BitRateOutcome out;
  CanLinkState state;
  if (const int e = link.query(interface, state); e != 0) {
    out.error = e;
    out.message = "cannot query " + interface + ": " + errno_text(e);
    return out;
  }
  out.before = state.bitrate;
  out.was_up = state.up;
  if (!state.exists) {
    out.action = BitRateAction::Missing;
  } else if (!state.has_bit_timing) {
    out.action = BitRateAction::NoBitTiming;
  } else {
    out.action = state.bitrate == bitrate ? BitRateAction::Keep : BitRateAction::Set;
  }
  return out;
}

BitRateOutcome apply_bit_rate(CanLink& link, const std::string& interface, std::uint32_t bitrate) {
  BitRateOutcome out = plan_bit_rate(link, interface, bitrate);
  if (!out.ok() || out.action != BitRateAction::Set) return out;
  auto failed = [&](int e) {
    out.error = e;
    out.message = failure(interface, bitrate, e);
    return out;
  };
  if (out.was_up) {
    if (const int e = link.stop(interface); e != 0) return failed(e);
  }
  if (const int e = link.set_bitrate(interface, bitrate); e != 0) {
    if (out.was_up) (void)link.start(interface);  // back as it was, at the old rate
    return failed(e);
  }
  if (const int e = link.start(interface); e != 0) return failed(e);
  return out;
}

}  // namespace oegw::canopen::io
