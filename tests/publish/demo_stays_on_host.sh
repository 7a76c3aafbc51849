#!/bin/sh
# `oegw demo` as a user runs it — publishing by default — on a machine whose default route leads
# to a network, watched by both example subscribers (demo_publish_check.sh), while tcpdump (an
# independent peer) captures everything that leaves towards that network.
#
# The "machine" is a private network namespace with lo and a veth link that carries its default
# route (192.0.2.2/24 via 192.0.2.1, TEST-NET-1): exactly where LCM joins its multicast group and
# where an IGMP report or a ttl>0 datagram would go. The capture sits on the veth's host end, so
# no other traffic of this computer can be mistaken for the demo's. Passes when:
#   * the subscribers see the demo's samples (valid while moving, offline when the grip is lost),
#     and lcm-logger's recording of the session decodes with the oegw LCM types;
#   * on the namespace's lo the capture sees the DDS traffic (so capturing works);
#   * on the link not one packet arrives: no IGMP report (LCM's group 224.0.0.1 is never
#     reported, RFC 3376 §5), no multicast, nothing on the DDS or LCM ports, not even an ARP.
# Needs root (ip netns, tcpdump): without it, it fails and says why.
#   demo_stays_on_host.sh OEGW DDS_SUBSCRIBER LCM_SUBSCRIBER [LCM_LOG_DECODE LCM_LOGGER]
set -eu
here=$(cd "$(dirname "$0")" && pwd)
oegw=$1 dds_sub=$2 lcm_sub=$3
shift 3  # the rest (LCM_LOG_DECODE LCM_LOGGER) goes to demo_publish_check.sh
command -v tcpdump >/dev/null || { echo "FAILED: tcpdump is missing (scripts/install-deps.sh installs it)" >&2; exit 1; }
[ "$(id -u)" -eq 0 ] || { echo "FAILED: needs root for a network namespace and tcpdump" >&2; exit 1; }
# Names of this run only (a random suffix: a PID reused in a container cannot clash).
rnd=$(od -An -N3 -tx1 /dev/urandom | tr -d ' \n')
ns=oegw-demo-$rnd
up=oegwu$rnd      # host end of the link
down=oegwd$rnd    # the namespace's end: its default route
dir=$(mktemp -d)
pids=""
made_ns=0
# Called by the traps below.
# shellcheck disable=SC2317
cleanup() {
  for p in $pids; do kill "$p" 2>/dev/null || true; done
  if [ "$made_ns" -eq 1 ]; then
    ip netns pids "$ns" 2>/dev/null | xargs -r kill 2>/dev/null || true  # the demo, subscribers, capture
    ip netns del "$ns" 2>/dev/null || true
  fi
  rm -rf "$dir"
}
trap cleanup EXIT
# dash runs an EXIT trap on exit only: a ctest timeout (SIGTERM) or Ctrl-C cleans up too.
trap 'exit 143' TERM
trap 'exit 130' INT
trap 'exit 129' HUP
ip netns add "$ns" 2>"$dir/netns.err" || { echo "FAILED: cannot create a network namespace: $(cat "$dir/netns.err")" >&2; exit 1; }
made_ns=1
ip link add "$up" type veth peer name "$down" netns "$ns"
ip link set "$up" up
ip netns exec "$ns" sh -e -c "
  sysctl -qw net.ipv6.conf.all.disable_ipv6=1 net.ipv6.conf.default.disable_ipv6=1 2>/dev/null || true
  ip link set lo up
  ip addr add 192.0.2.2/24 dev $down
  ip link set $down up
  ip route add default via 192.0.2.1"
# On the link: everything that arrives from the namespace (-Q in on the host end; IPv6 is off
# there, so nothing is expected at all: no IGMP, no multicast, no ARP for a unicast off the host).
# On lo: the DDS and LCM ports, to prove the capture and the demo work.
timeout 110 tcpdump -i "$up" -Q in -n -U -w "$dir/link.pcap" 2>"$dir/link.err" &
pids="$pids $!"
timeout 110 ip netns exec "$ns" tcpdump -i lo -n -U -w "$dir/lo.pcap" 'udp portrange 7400-7700' 2>"$dir/lo.err" &
pids="$pids $!"
for c in link lo; do
  n=0
  until grep -q 'listening on' "$dir/$c.err" 2>/dev/null; do
    n=$((n + 1)); [ $n -lt 200 ] || { echo "FAILED: tcpdump ($c) did not start: $(cat "$dir/$c.err")" >&2; exit 1; }
    sleep 0.05
  done
done
rc=0
# In the background and waited for: a signal interrupts `wait` and the traps run at once.
ip netns exec "$ns" "$here/demo_publish_check.sh" "$oegw" "$dds_sub" "$lcm_sub" "$@" &
check=$!
wait "$check" || rc=1
sleep 0.5  # let the last datagrams reach the capture buffers
for p in $pids; do kill -INT "$p" 2>/dev/null || true; done
for p in $pids; do wait "$p" 2>/dev/null || true; done
pids=""
lo=$(tcpdump -r "$dir/lo.pcap" -n 2>/dev/null | wc -l)
link=$(tcpdump -r "$dir/link.pcap" -n 2>/dev/null | wc -l)
echo "lo: $lo packets (the demo's DDS traffic; expected some)"
echo "default-route link: $link packets leaving (expected 0)"
[ "$lo" -gt 0 ] || { rc=1; echo "FAILED: nothing captured on lo: the capture or the demo's DDS did not work" >&2; }
if [ "$link" -ne 0 ]; then
  rc=1
  echo "FAILED: traffic left on the default route's link:" >&2
  tcpdump -r "$dir/link.pcap" -n 2>/dev/null | head -5 >&2
fi
exit $rc
