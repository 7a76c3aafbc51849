#!/bin/bash
# Guest test (vm_remote): remote SDO and remote EMCY through the built `oegw run` on real SocketCAN.
# The mapping file is vm_gateway.yaml's (the demo's devices, upstream vcan0, downstream vcan1)
# with one additional SDO server channel, 1201h on 690h/6B0h, bound to left_grip. The devices are
# `oegw-sim` processes on vcan1 (the MCB-402 left_grip alone, taking commands from a FIFO the host
# writes: its cable break raises EMCY 3120h); the host is remote_host.py on python3-can (vcan0):
# network indications, reads and writes of sub-devices through the gateway, the bound channel, the
# refusals and the forwarded EMCY; then docs/guides/remote-sdo.md's node-canopen recipe, extracted
# from the page and run as written. candump's recordings judge the downstream side: the SDO frames
# the host's requests caused on vcan1, and nothing of vcan1 on vcan0 but the forwarded EMCYs.
# Args: OEGW OEGW_SIM SOURCE_DIR NODE_MODULES (node-canopen's, vm_node_peer_install)
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1
sim=$2
src=$3
modules=$4
dir=/run/oegw-remote

prepare_gateway_run vm_gateway.yaml "$src" "$dir" "$oegw"
# The bound channel goes under `upstream:` (after its store line), then the file is checked again.
sed -i 's|^  store: .*|&\n  sdo_servers:\n    - { subdevice: left_grip, request: 0x690, response: 0x6B0 }|' "$dir/oegw.yaml"
"$oegw" check --here "$dir/oegw.yaml" >/tmp/check.out 2>&1
rc=$?
((rc == 0)) && pass "oegw check: valid with the bound SDO channel" || { fail "oegw check exit $rc: $(cat /tmp/check.out)"; exit 1; }
if grep -q '1201h.*690h.*6B0h.*left_grip' /tmp/check.out; then pass "oegw check prints SDO server 1201h"; else fail "oegw check does not print 1201h: $(cat /tmp/check.out)"; fi

start_candump vcan0 /tmp/up.dump || fail "candump vcan0 did not start"
up_candump=$candump_pid
start_candump vcan1 /tmp/down.dump || fail "candump vcan1 did not start"
down_candump=$candump_pid
mkfifo /tmp/left.cmd
exec 3<>/tmp/left.cmd
start_host /tmp/host.log /tmp/remote.ready 45 "$PY" "$here/remote_host.py" /tmp/remote.ready /tmp/left.cmd
gateway_cab "$src"
start_sim "$sim" /tmp/sim-left.log --commands "${devices[1]}"
left_pid=$sim_pid
start_sim "$sim" /tmp/sim-others.log --motion "${devices[0]}" "${devices[@]:2}"
others_pid=$sim_pid
wait_sims
start_oegw_run "$oegw" "$dir/oegw.yaml"
echo "gateway started after $(elapsed) s"

follow_host /tmp/host.log
echo "host finished after $(elapsed) s"
((host_rc == 0)) && pass "python3-can host: every remote check" || fail "python3-can host: $host_rc failed"

# docs/guides/remote-sdo.md's node-canopen recipe for a bound channel, EXTRACTED from the page
# (its ```js block) so that it cannot drift from what is run, and run as written with the guest's
# upstream bus for can0 and the pinned node-canopen (vm_node_peer_install) for `require`. Here
# the channel is bound to left_grip (the MCB-402: vendor-ID 58h) where the page binds right_grip.
page=$src/docs/guides/remote-sdo.md
awk '/^```js$/ { b = 1; next } /^```$/ { b = 0 } b' "$page" | sed "s/createRawChannel('can0')/createRawChannel('vcan0')/" >/tmp/recipe.js
if ! grep -q 'addSdoClientParameter(0x20, 0x690, 0x6b0)' /tmp/recipe.js || ! grep -q "createRawChannel('vcan0')" /tmp/recipe.js; then
  fail "remote-sdo.md: no node-canopen recipe for 690h/6B0h on can0 extracted: $(head -c 300 /tmp/recipe.js)"
else
  NODE_PATH=$modules timeout 60 node /tmp/recipe.js >/tmp/recipe.out 2>&1
  rc=$?
  if ((rc == 0)) && grep -q '^vendor-ID 00000058h$' /tmp/recipe.out; then
    pass "remote-sdo.md's node-canopen recipe, as written: vendor-ID 00000058h on the bound channel"
  else
    fail "remote-sdo.md's node-canopen recipe: exit $rc: $(tail -5 /tmp/recipe.out)"
  fi
fi

# can-utils, a second peer we did not write, as a plain SDO client on the bound channel: upload
# 1018h:02 of left_grip (the MCB-402's product code 0104 0131h comes back on 6B0h; checked below).
cansend vcan0 690#4018100200000000
sleep 1
kill -TERM "$gw_pid"
wait "$gw_pid"
rc=$?
((rc == 0)) && pass "SIGTERM stops oegw run cleanly (exit 0)" || fail "oegw run exit $rc after SIGTERM"
kill -TERM "$others_pid" "$left_pid" 2>/dev/null
wait "$others_pid" "$left_pid" 2>/dev/null
stop_candump
candump_pid=$up_candump
stop_candump
echo "== gateway log (journald format: level: message)"
grep -E 'remote SDO|EMCY' /tmp/gateway.log | sed 's/^/    /' | head -40

# candump's view of both buses: the downstream SDO frames the host's requests caused.
up=$(frames /tmp/up.dump)
down=$(frames /tmp/down.dump)
expect() {  # BUS-DUMP-VAR REGEX WHAT
  if grep -qE "^$2\$" <<<"$1"; then pass "candump: $2 ($3)"; else fail "candump lacks $2 ($3)"; fi
}
expect "$up" 'vcan0 620#E000000002110000' "host: network indication, network 2, node 11h"
expect "$up" 'vcan0 5A0#E000000002110000' "gateway: accepted"
expect "$up" 'vcan0 620#4018100100000000' "host: upload 1018h:01"
expect "$down" 'vcan1 611#4018100100000000' "gateway -> grip: upload 1018h:01"
expect "$down" 'vcan1 591#43181001B4000000' "grip: vendor-ID B4h"
expect "$up" 'vcan0 5A0#43181001B4000000' "gateway -> host: the grip's answer"
expect "$down" 'vcan1 67F#4008100000000000' "gateway -> seat_knob: upload 1008h (segmented follows)"
expect "$up" 'vcan0 690#4018100100000000' "host on the bound channel: upload 1018h:01"
expect "$down" 'vcan1 603#4018100100000000' "gateway -> left_grip: upload 1018h:01"
expect "$up" 'vcan0 6B0#4318100158000000' "bound channel answer: MCB-402 vendor-ID 58h"
expect "$up" 'vcan0 6B0#4318100231010401' "cansend's upload on the bound channel: MCB-402 product code 01040131h"
expect "$down" 'vcan1 083#2031810081000000' "left_grip: EMCY 3120h cable break"
expect "$up" 'vcan0 0A0#2031[0-9A-F]{2}0381008100' "gateway: left_grip's EMCY 3120h, node 03h, register 81h"
# The refused write never reached the grip.
if grep -qE '^vcan1 611#23001801' <<<"$down"; then fail "the refused 1800h:01 write reached the grip"; else pass "the refused 1800h:01 write never reached vcan1"; fi
if grep -qE '^vcan0 (711|703|730|77F|731|591|583|5FF)#' <<<"$up"; then fail "sub-device frames on vcan0"; else pass "vcan0 carries no sub-device frames"; fi
cp /tmp/up.dump /tmp/down.dump /tmp/gateway.log /tmp/host.log "${OEGW_VM_OUT:-/tmp}/" 2>/dev/null
echo "total $(elapsed) s; $passes passed, $fails failed"
((fails == 0))
