#!/bin/sh
# `oegw demo` as a user runs it — publishing by default — on a machine whose default route leads
# to a network, watched by both example subscribers (demo_publish_check.sh), while tcpdump (an
# independent peer) captures everything that leaves towards that network.
#
# The "machine" is a private network namespace with lo and a veth link that carries its default
# route (192.0.2.2/24 via 192.0.2.1, TEST-NET-1): exactly where LCM joins its multicast group and
# where an IGMP report or a ttl>0 datagram would go. The capture sits on the veth's host end, so
# no other traffic of this computer can be mistaken for the demo's. Passes when:
#   * the subscribers see the demo's samples (valid while moving, offline when the grip is lost);
#   * on the namespace's lo the capture sees the DDS traffic (so capturing works);
#   * on the link not one packet arrives: no IGMP report (LCM's group 224.0.0.1 is never
#     reported, RFC 3376 §5), no multicast, nothing on the DDS or LCM ports.
# Needs root (ip netns, tcpdump): without it, it fails and says why.
#   demo_stays_on_host.sh OEGW DDS_SUBSCRIBER LCM_SUBSCRIBER
set -eu
here=$(cd "$(dirname "$0")" && pwd)
oegw=$1 dds_sub=$2 lcm_sub=$3
command -v tcpdump >/dev/null || { echo "FAILED: tcpdump is missing (scripts/install-deps.sh installs it)" >&2; exit 1; }
[ "$(id -u)" -eq 0 ] || { echo "FAILED: needs root for a network namespace and tcpdump" >&2; exit 1; }
ns=oegw-demo-$$
up=oegwu$$      # host end of the link
down=oegwd$$    # the namespace's end: its default route
dir=$(mktemp -d)
pids=""
cleanup() {
  for p in $pids; do kill "$p" 2>/dev/null || true; done
  ip netns del "$ns" 2>/dev/null || true
  rm -rf "$dir"
}
trap cleanup EXIT
ip netns add "$ns"
ip link add "$up" type veth peer name "$down" netns "$ns"
ip link set "$up" up
ip netns exec "$ns" sh -e -c "
  sysctl -qw net.ipv6.conf.all.disable_ipv6=1 net.ipv6.conf.default.disable_ipv6=1
  ip link set lo up
  ip addr add 192.0.2.2/24 dev $down
  ip link set $down up
  ip route add default via 192.0.2.1"
# Whatever the demo or the subscribers could send: IGMP, any IPv4 multicast, DDS (7400+) and LCM
# (7667) ports. On the link: what arrives from the namespace (-Q in on the host end).
filter='igmp or (ip and dst net 224.0.0.0/4) or udp portrange 7400-7700'
tcpdump -i "$up" -Q in -n -U -w "$dir/link.pcap" "$filter" 2>"$dir/link.err" &
pids="$pids $!"
ip netns exec "$ns" tcpdump -i lo -n -U -w "$dir/lo.pcap" "$filter" 2>"$dir/lo.err" &
pids="$pids $!"
for c in link lo; do
  n=0
  until grep -q 'listening on' "$dir/$c.err" 2>/dev/null; do
    n=$((n + 1)); [ $n -lt 200 ] || { echo "FAILED: tcpdump ($c) did not start: $(cat "$dir/$c.err")" >&2; exit 1; }
    sleep 0.05
  done
done
rc=0
ip netns exec "$ns" "$here/demo_publish_check.sh" "$oegw" "$dds_sub" "$lcm_sub" || rc=1
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
