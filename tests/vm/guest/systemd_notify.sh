#!/bin/bash
# Guest test: what `oegw run` tells systemd (gateway/service_notify.hpp, the unit's Type=notify),
# outside in. notify_listen.py plays systemd's side: a datagram Unix socket named by
# NOTIFY_SOCKET, with WATCHDOG_USEC=10000000 (WatchdogSec=10s: wide, since a TCG guest on a busy
# host stalls for seconds at times). `oegw run` on vm_gateway.yaml
# (upstream vcan0, downstream vcan1) with the five simulated devices in one oegw-sim process:
# READY=1 once the upstream device is pre-operational; STATUS= lines (the first naming devices not
# yet up, then "5/5 sub-devices operational"), each sent once, not repeated; WATCHDOG=1 every half
# of the time-out (the median gap 4.5..6.5 s: 5 s, polled each second) and never a time-out of
# the guest's running time apart (a stall of the whole guest excepted: notify_listen.py's ticks);
# SIGTERM: STOPPING=1, exit 0. Then the
# same without NOTIFY_SOCKET: nothing to send to, the gateway runs and stops as before.
# This checks the wire (timing systemd's own view does not show); the unit under a real systemd
# as PID 1 is vm_systemd_real (guest/systemd_real.sh, docs/developer/vm-tier.md#systemd).
# Args: OEGW OEGW_SIM SOURCE_DIR
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1
sim=$2
src=$3
dir=/run/oegw-notify

prepare_gateway_run vm_gateway.yaml "$src" "$dir" "$oegw"
rc=$?
((rc == 0)) && pass "oegw check: valid" || fail "oegw check exit $rc: $(cat /tmp/check.out)"

gateway_cab "$src"
start_sim "$sim" /tmp/sim.log "${devices[@]}"
wait_sims

"$PY" "$here/notify_listen.py" "$dir/notify.sock" /tmp/notify.log /tmp/notify.ready 120 /tmp/notify.ticks &
listen_pid=$!
wait_file /tmp/notify.ready 10 || fail "notify socket not bound"

NOTIFY_SOCKET=$dir/notify.sock WATCHDOG_USEC=10000000 start_oegw_run "$oegw" "$dir/oegw.yaml"
echo "gateway started after $(elapsed) s"

# Until every sub-device is operational (at most 60 s on a slow TCG guest), then 16 s more of pings.
for ((i = 0; i < 1200; i++)); do
  grep -q 'STATUS=.* 5/5 sub-devices operational' /tmp/notify.log 2>/dev/null && break
  kill -0 "$gw_pid" 2>/dev/null || break
  sleep 0.05
done
sleep 16
kill -TERM "$gw_pid"
wait "$gw_pid"
gw_rc=$?
sleep 0.5
kill -TERM "$listen_pid" 2>/dev/null
wait "$listen_pid" 2>/dev/null
kill -TERM "$sim_pid" 2>/dev/null
wait "$sim_pid" 2>/dev/null
echo "--- notify messages (first 20)"
head -20 /tmp/notify.log
echo "--- gateway log (last 10 lines)"
tail -10 /tmp/gateway.log

msgs=$(cut -d' ' -f2- /tmp/notify.log)
((gw_rc == 0)) && pass "SIGTERM: exit 0" || fail "oegw run exit $gw_rc"
n=$(grep -cx 'READY=1' <<<"$msgs")
((n == 1)) && pass "READY=1 once" || fail "READY=1 $n times"
first=$(head -1 <<<"$msgs")
[[ $first == READY=1 ]] && pass "READY=1 first" || fail "first message: $first"
grep -qx 'STATUS=upstream pre-operational, node 20h; 5/5 sub-devices operational' <<<"$msgs" &&
  pass "STATUS: upstream pre-operational, 5/5 sub-devices operational" || fail "no 5/5 STATUS line"
grep -q '^STATUS=upstream pre-operational, node 20h; [0-4]/5 sub-devices operational; ' <<<"$msgs" &&
  pass "STATUS while booting names the sub-devices not yet up" || fail "no STATUS line naming the missing ones"
dup=$(grep '^STATUS=' <<<"$msgs" | uniq -d | head -1)
[[ -z $dup ]] && pass "no STATUS line repeated" || fail "STATUS repeated: $dup"
pings=$(awk '$2 == "WATCHDOG=1" { print $1 }' /tmp/notify.log)
np=$(wc -l <<<"$pings")
gaps=$(awk 'NR > 1 { printf "%.3f\n", $1 - p } { p = $1 }' <<<"$pings" | sort -n)
gap=$(tail -1 <<<"$gaps")
median=$(awk '{ g[NR] = $1 } END { printf "%.2f", NR ? g[int((NR + 1) / 2)] : 0 }' <<<"$gaps")
((np >= 4)) && pass "WATCHDOG=1 $np times" || fail "WATCHDOG=1 only $np times"
awk -v m="$median" 'BEGIN { exit !(m >= 4.5 && m <= 6.5) }' && pass "WATCHDOG=1 every half time-out (median gap $median s)" ||
  fail "WATCHDOG=1 median gap $median s, expected about 5 s (half of WATCHDOG_USEC)"
# The time-out is judged on the guest's running time between two pings: the part of the gap
# notify_listen.py's own wake-ups (every 100 ms while the guest runs) cover with gaps of at most
# 0.4 s. A stall of the whole TCG guest (seconds at times) is no silence of the gateway; a loop
# that stops pinging while the guest runs fails by the length of its stop. The exact cadence is
# judged on simulated time (service_notify_test: TheEventLoopPingsTheWatchdogAtHalfItsTimeOut).
running=$(awk 'NR == FNR { tick[++n] = $1; next } $2 == "WATCHDOG=1" { if (p != "") { r = 0; last = p
    for (i = 1; i <= n; i++) if (tick[i] > p && tick[i] < $1) { if (tick[i] - last <= 0.4) r += tick[i] - last; last = tick[i] }
    if ($1 - last <= 0.4) r += $1 - last
    if (r > m) { m = r; g = $1 - p } } p = $1 }
  END { printf "%.3f %.3f", m, g }' /tmp/notify.ticks /tmp/notify.log)
read -r run_max run_gap <<<"$running"
echo "WATCHDOG=1 gaps: largest $gap s of wall time; largest running time between two pings $run_max s (of a $run_gap s gap)"
awk -v g="$run_max" 'BEGIN { exit !(g < 10.0) }' && pass "WATCHDOG=1 never a time-out of the guest's running time apart (largest $run_max s)" ||
  fail "WATCHDOG=1: $run_max s of running time without a ping: systemd would have restarted it"
last=$(tail -1 <<<"$msgs")
[[ $last == STOPPING=1 ]] && pass "STOPPING=1 last" || fail "last message: $last"

# Not started by systemd: no socket named, nothing sent, nothing fails. SIGTERM once it has
# started (its "oegw: node 20h on vcan0" line): before, the handler is not installed yet.
start_oegw_run "$oegw" "$dir/oegw.yaml" /tmp/gateway2.log
for ((i = 0; i < 1200; i++)); do
  grep -q '^info: oegw: node 20h on vcan0' /tmp/gateway2.log && break
  kill -0 "$gw_pid" 2>/dev/null || break
  sleep 0.05
done
sleep 1
kill -TERM "$gw_pid"
wait "$gw_pid"
rc=$?
((rc == 0)) && pass "without NOTIFY_SOCKET: runs, SIGTERM exit 0" || fail "without NOTIFY_SOCKET: exit $rc: $(tail -3 /tmp/gateway2.log)"

echo "$passes passed, $fails failed"
((fails == 0))
