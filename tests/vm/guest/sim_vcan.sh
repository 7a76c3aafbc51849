#!/bin/bash
# Guest test (vm_sim_vcan): `oegw sim --vcan vcan0,vcan1` with docs/guides/simulate.md's own cab
# file, and the independent programs its page names attached: candump on both interfaces (the
# gateway's heartbeat and TPDO 1 upstream, every sub-device's heartbeat and the gateway's SDO
# downstream), cansend as a second host on vcan0 (an NMT stop and start the gateway obeys, an
# SDO upload of 1018h:01 it answers on 5A0h), `oegw status` and `oegw ctl` on the sim's control
# socket (the grip's 1018h:01 through the gateway, 000000B4h as elobau document 000 gives it).
# Args: OEGW SOURCE_DIR
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1
src=$2
work=/tmp/sim-vcan
mkdir -p "$work"

# The page's ```yaml block, as the guide says to save it, with the pedal's EDS beside it.
awk '/^```yaml$/ { on = 1; next } /^```$/ { on = 0 } on' "$src/docs/guides/simulate.md" >"$work/cab.yaml"
cp "$src/subdevices/eds/generic_pedal.eds" "$work/"
grep -q 'driver: novotechnik-406' "$work/cab.yaml" && pass "the guide's cab file extracted" || fail "no cab file in the guide"

start_candump vcan0 /tmp/up.dump || fail "candump vcan0 did not start"
up_pid=$candump_pid
start_candump vcan1 /tmp/down.dump || fail "candump vcan1 did not start"
down_pid=$candump_pid
(cd "$work" && exec "$oegw" sim cab.yaml --vcan vcan0,vcan1 --seconds 40 --no-publish </dev/null >/tmp/sim.out 2>&1) &
sim_pid=$!

sock=""
for _ in $(seq 1 200); do
  sock=$(sed -n 's/.*oegw status --socket \([^ ]*\).*/\1/p' /tmp/sim.out | head -1)
  [[ -n $sock ]] && break
  sleep 0.1
done
[[ -n $sock ]] && pass "the sim names its control socket $sock" || fail "no control socket in: $(head -c 600 /tmp/sim.out)"

up=0
for _ in $(seq 1 120); do
  up=$("$oegw" status --socket "$sock" --json 2>/dev/null | grep -o '"network_state": *"operational"' | wc -l)
  ((up >= 4)) && break
  sleep 0.5
done
((up >= 4)) && pass "oegw status --socket: the 4 sub-devices operational after $(elapsed) s" ||
  fail "sub-devices operational: $up of 4"

# The read needs the grip operational. `oegw sim` runs the sub-devices and the gateway in one
# process, in real time: a stall of the TCG guest makes them late together, and the event loop
# delivers the heartbeats their overdue timers send before it judges the gateway's overdue
# deadlines. So no sub-device is lost, and the read is answered at the first try.
printf '%s\n' '[1] 2 17 r 0x1018 1 u32' | "$oegw" ctl --socket "$sock" --exit >/tmp/ctl.out 2>&1
grep -qxF '[1] 0x000000B4' /tmp/ctl.out && pass "oegw ctl --socket: the grip's 1018h:01 = 0x000000B4" ||
  fail "oegw ctl answer: $(cat /tmp/ctl.out)"
! grep -q 'missing (heartbeat lost)' /tmp/sim.out && pass "no sub-device lost while the sim ran (stalls included)" ||
  fail "sub-devices lost in one process: $(grep 'missing (heartbeat lost)' /tmp/sim.out | head -3)"

# A second host on vcan0: NMT stop, then start, to node 20h; an SDO upload of 1018h:01.
cansend vcan0 000#0220
sleep 1
cansend vcan0 000#0120
sleep 1
cansend vcan0 620#4018100100000000
sleep 1

kill -TERM "$sim_pid" 2>/dev/null
wait "$sim_pid"
rc=$?
((rc == 0)) && pass "oegw sim: SIGTERM, exit 0" || fail "oegw sim exit $rc: $(tail -5 /tmp/sim.out)"
[[ ! -e $sock ]] && pass "its control socket and private folder removed" || fail "$sock left behind"
kill -INT "$up_pid" "$down_pid" 2>/dev/null
wait "$up_pid" "$down_pid" 2>/dev/null

count_of() { grep -Ec "$2" "$1" 2>/dev/null; }
n=$(count_of /tmp/up.dump ' vcan0 720#05$')
((n >= 5)) && pass "vcan0: the gateway's heartbeat in operational ($n)" || fail "vcan0: 720#05 seen $n times"
n=$(count_of /tmp/up.dump ' vcan0 1A0#')
((n >= 5)) && pass "vcan0: TPDO 1 on 1A0h ($n)" || fail "vcan0: 1A0h seen $n times"
grep -qE ' vcan0 720#04$' /tmp/up.dump && pass "vcan0: the gateway stopped at the second host's NMT stop (720#04)" ||
  fail "no 720#04 after 000#0220"
awk '/ vcan0 720#04$/ { s = 1 } s && / vcan0 720#05$/ { f = 1 } END { exit !f }' /tmp/up.dump &&
  pass "vcan0: operational again after NMT start" || fail "no 720#05 after the stop"
# The gateway's own 1018h:01: the file gives no upstream.identity, so vendor 0.
grep -qE ' vcan0 5A0#4318100100000000$' /tmp/up.dump &&
  pass "vcan0: the gateway answered the second host's SDO upload of 1018h:01 (5A0#4318100100000000)" ||
  fail "no 5A0#4318100100000000 answer to 620#4018100100000000"
for hb in 711 703 730 77F; do
  n=$(count_of /tmp/down.dump " vcan1 $hb#05\$")
  ((n >= 5)) && pass "vcan1: heartbeat $hb#05 ($n)" || fail "vcan1: $hb#05 seen $n times"
done
n=$(count_of /tmp/down.dump ' vcan1 611#')
((n >= 1)) && pass "vcan1: the gateway's SDO to the grip on 611h ($n)" || fail "vcan1: no SDO request to 611h"
cp /tmp/up.dump /tmp/down.dump /tmp/sim.out "${OEGW_VM_OUT:-/tmp}/" 2>/dev/null
echo "total $(elapsed) s; $passes passed, $fails failed"
((fails == 0))
