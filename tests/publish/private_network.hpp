// Runs the calling process (and every process it starts) in a network namespace of its own
// holding only a loopback interface, so no test packet can reach a real interface.
//
// Why: LCM's udpm provider (1.3.1) joins its multicast group on the interface the routing table
// picks for the group — the default route's, e.g. eth0 — and the kernel then sends IGMP membership
// reports there, even with ttl=0 (which only keeps the data itself local). In a private namespace
// with `224.0.0.0/4 dev lo` the join and the data stay on lo. Cyclone DDS's loopback-only
// configuration needs nothing more than lo being up.
//
// Call first in main(), while the process has one thread. Needs CAP_SYS_ADMIN (root, as the tests
// run here); without it the caller is told and the tests run on the host's network.
#pragma once

#include <sched.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace oegw::test {

inline bool enter_private_network() {
  if (::unshare(CLONE_NEWNET) != 0) {
    std::fprintf(stderr,
                 "note: no private network namespace (%s); LCM's multicast join may send IGMP reports on the "
                 "default interface\n",
                 std::strerror(errno));
    return false;
  }
  if (std::system("ip link set lo up multicast on && ip route add 224.0.0.0/4 dev lo") != 0) {
    std::fprintf(stderr, "private network namespace: cannot set up lo (ip link / ip route failed)\n");
    std::exit(1);
  }
  return true;
}

}  // namespace oegw::test
