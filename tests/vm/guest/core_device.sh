#!/bin/bash
# Guest test: the protocol core on a real SocketCAN bus. `oegw device` (the core's demo device,
# node 0x20) runs on vcan0; python3-can (python_peer.Peer) is the host: NMT master and SDO client;
# candump (can-utils) records the bus and the frames are checked byte for byte. Nothing here is
# our own code on the host side.
# Args: OEGW_BINARY
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1
store=/run/oegw-core-device.params
rm -f "$store" "$store.lss"

start_device() {
  "$oegw" device -i vcan0 -n 0x20 --heartbeat-ms 100 --no-motion --store "$store" >>/tmp/device.log 2>&1 &
  device_pid=$!
}

start_candump vcan0 /tmp/core.dump || fail "candump did not start"
# The check script waits for the boot-up itself: start it first, then power the device on.
start_host /tmp/check.log /tmp/check.ready 20 "$PY" "$here/core_device_check.py" vcan0 /tmp/check.ready
check_pid=$host_pid
start_device
# The check script restarts the device once (power cycle) through a request file.
for ((i = 0; i < 1200; i++)); do
  if [[ -e /tmp/check.power-cycle ]]; then
    kill -TERM "$device_pid"
    wait "$device_pid"
    rc=$?
    ((rc == 0)) && pass "SIGTERM stops the device cleanly (exit 0)" || fail "device exit code $rc after SIGTERM"
    rm -f /tmp/check.power-cycle
    start_device
    touch /tmp/check.powered
  fi
  kill -0 "$check_pid" 2>/dev/null || break
  sleep 0.05
done
wait "$check_pid"
check_rc=$?
sed 's/^/    /' /tmp/check.log
((check_rc == 0)) && pass "python3-can host: every check" || fail "python3-can host exit $check_rc"
kill -TERM "$device_pid" 2>/dev/null
wait "$device_pid" 2>/dev/null
stop_candump
echo "== device log"
sed 's/^/    /' /tmp/device.log

# candump's view of the same exchanges, byte for byte.
got=$(frames /tmp/core.dump)
expect_frame() {
  if grep -qx "vcan0 $1" <<<"$got"; then pass "candump: $1 ($2)"; else fail "candump lacks $1 ($2)"; fi
}
expect_frame '720#00' "boot-up"
expect_frame '620#4000100000000000' "SDO upload request 1000h"
expect_frame '5A0#4300100091010F00' "expedited answer: device type 000F0191h"
expect_frame '620#2B171000C8000000' "SDO download 1017h = 200"
expect_frame '5A0#6017100000000000' "download confirmed"
expect_frame '620#2310100173617665' "save (signature 'save') to 1010h:01"
expect_frame '000#0120' "NMT start node 0x20"
expect_frame '720#05' "heartbeat operational"
expect_frame '220#5A' "RPDO1 from the host"
expect_frame '5A0#4F0062015A000000' "6200h:01 reads back 5Ah"
expect_frame '5A0#8000100002000106' "abort 06010002h: 1000h is read-only"
if grep -q '^vcan0 1A0#' <<<"$got"; then pass "TPDO1 on 1A0h seen"; else fail "no TPDO1 on 1A0h"; fi
echo "$passes passed, $fails failed"
((fails == 0))
