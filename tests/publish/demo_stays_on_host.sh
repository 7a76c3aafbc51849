#!/bin/sh
# `oegw demo` as a user runs it — on the host's own network, publishing by default — watched by
# both example subscribers (demo_publish_check.sh), while tcpdump (an independent peer) captures
# what leaves on every other interface. Passes when:
#   * the subscribers see the demo's samples (valid while moving, offline when the grip is lost);
#   * on lo the capture sees the DDS traffic (so the capture itself works);
#   * on every interface but lo it sees nothing outbound: no IGMP report (LCM's group 224.0.0.1
#     is never reported, RFC 3376 §5), no multicast, no DDS or LCM port.
# Needs tcpdump and the right to capture (root / CAP_NET_RAW): without them it fails, naming why.
#   demo_stays_on_host.sh OEGW DDS_SUBSCRIBER LCM_SUBSCRIBER
set -eu
here=$(cd "$(dirname "$0")" && pwd)
oegw=$1 dds_sub=$2 lcm_sub=$3
command -v tcpdump >/dev/null || { echo "FAILED: tcpdump is missing (scripts/install-deps.sh installs it)" >&2; exit 1; }
dir=$(mktemp -d)
pids=""
cleanup() {
  for p in $pids; do kill "$p" 2>/dev/null || true; done
  rm -rf "$dir"
}
trap cleanup EXIT
# Whatever the demo or the subscribers could send: IGMP, any IPv4 multicast, DDS (7400+) and LCM
# (7667) ports. Outbound only (-Q out) on real interfaces: what other hosts send us is not ours.
filter='igmp or (ip and dst net 224.0.0.0/4) or udp portrange 7400-7700'
ifaces=$(ls /sys/class/net)
for i in $ifaces; do
  [ "$(cat /sys/class/net/$i/operstate 2>/dev/null)" = down ] && continue
  # lo: both directions (its packets do not all show as outbound); elsewhere outbound only.
  if [ "$i" = lo ]; then dir_opt=""; else dir_opt="-Q out"; fi
  # shellcheck disable=SC2086
  tcpdump -i "$i" $dir_opt -n -U -w "$dir/$i.pcap" "$filter" 2>"$dir/$i.err" &
  pids="$pids $!"
  echo "$i" >> "$dir/captured"
done
# Wait (bounded) until every capture is listening.
for i in $(cat "$dir/captured"); do
  n=0
  until grep -q 'listening on' "$dir/$i.err" 2>/dev/null; do
    if grep -qi 'permission\|not permitted\|error' "$dir/$i.err" 2>/dev/null; then
      echo "FAILED: cannot capture on $i: $(cat "$dir/$i.err")" >&2; exit 1
    fi
    n=$((n + 1)); [ $n -lt 200 ] || { echo "FAILED: tcpdump on $i did not start: $(cat "$dir/$i.err")" >&2; exit 1; }
    sleep 0.05
  done
done
rc=0
"$here/demo_publish_check.sh" "$oegw" "$dds_sub" "$lcm_sub" || rc=1
sleep 0.5  # let the last datagrams reach the capture buffers
for p in $pids; do kill -INT "$p" 2>/dev/null || true; done
for p in $pids; do wait "$p" 2>/dev/null || true; done
pids=""
for i in $(cat "$dir/captured"); do
  count=$(tcpdump -r "$dir/$i.pcap" -n 2>/dev/null | wc -l)
  if [ "$i" = lo ]; then
    echo "lo: $count packets (the demo's DDS traffic; expected some)"
    [ "$count" -gt 0 ] || { rc=1; echo "FAILED: nothing captured on lo: the capture or the demo's DDS did not work" >&2; }
  else
    echo "$i: $count packets leaving (expected 0)"
    if [ "$count" -ne 0 ]; then
      rc=1
      echo "FAILED: traffic left the host on $i:" >&2
      tcpdump -r "$dir/$i.pcap" -n 2>/dev/null | head -5 >&2
    fi
  fi
done
grep -qx lo "$dir/captured" || { rc=1; echo "FAILED: lo is down, nothing captured" >&2; }
exit $rc
