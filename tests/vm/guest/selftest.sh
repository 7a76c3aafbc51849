#!/bin/bash
# Guest self-test of the VM tier: real SocketCAN (vcan) with can-utils and
# python3-can. Run with: tests/vm/run-in-vm.sh tests/vm/guest/selftest.sh
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"

[[ ${OEGW_VM:-} == 1 ]] || echo "warning: not inside the oegw test VM" >&2

echo "== kernel $(uname -r); $(ip -br link show vcan0 | tr -s ' ')"
# The clock every time-out in the VM tier runs on (run-in-vm.sh: the host's TSC is not to be trusted).
cs=$(cat /sys/devices/system/clocksource/clocksource0/current_clocksource 2>/dev/null)
[[ $cs == hpet ]] && pass "clocksource: hpet" || fail "clocksource: '$cs', not hpet (the guest's TSC is the host's raw rdtsc)"
for d in vcan0 vcan1; do
  ip link show "$d" | grep -q 'UP' && pass "$d is up" || fail "$d is not up"
done

# --- 1. cansend -> candump ------------------------------------------------------
start_candump vcan0 /tmp/dump1 || fail "candump did not start"
cansend vcan0 123#DEADBEEF || fail "cansend failed"
cansend vcan1 7FF#00 || fail "cansend on vcan1 failed"   # must not show on vcan0
cansend vcan0 1ABCDEF0#0102 || fail "cansend (extended id) failed"
cansend vcan0 000# || fail "cansend (empty frame) failed"
sleep 0.2
stop_candump
expected=$'vcan0 123#DEADBEEF\nvcan0 1ABCDEF0#0102\nvcan0 000#'
got=$(frames /tmp/dump1)
if [[ $got == "$expected" ]]; then
  pass "candump saw cansend's frames ($(elapsed s))"
else
  fail "candump saw:"$'\n'"$(cat /tmp/dump1)"$'\n'"expected:"$'\n'"$expected"
fi

# --- 2. cansend -> python3-can ------------------------------------------------
rm -f /tmp/py.ready
"$PY" "$here/selftest_can.py" recv vcan0 /tmp/py.ready >/tmp/py.recv 2>&1 &
pypid=$!
for ((i = 0; i < 600; i++)); do [[ -e /tmp/py.ready ]] && break; sleep 0.05; done
if [[ -e /tmp/py.ready ]]; then
  cansend vcan0 321#0102030405060708
  cansend vcan0 10000001#AA
  cansend vcan0 7E5#R
  wait "$pypid"
  prc=$?
  cat /tmp/py.recv
  ((prc == 0)) && pass "python3-can received cansend's frames ($(elapsed s))" || fail "python3-can receive (exit $prc)"
else
  kill "$pypid" 2>/dev/null
  cat /tmp/py.recv
  fail "python3-can receiver never became ready"
fi

# --- 3. python3-can -> candump ----------------------------------------------
start_candump vcan0 /tmp/dump2 || fail "candump did not start"
if "$PY" "$here/selftest_can.py" send vcan0; then
  sleep 0.2
  stop_candump
  expected=$'vcan0 701#05\nvcan0 12345678#CAFE\nvcan0 080#'
  got=$(frames /tmp/dump2)
  if [[ $got == "$expected" ]]; then
    pass "candump saw python3-can's frames ($(elapsed s))"
  else
    fail "candump saw:"$'\n'"$(cat /tmp/dump2)"$'\n'"expected:"$'\n'"$expected"
  fi
else
  stop_candump
  fail "python3-can send failed"
fi

echo "== selftest checks: $passes passed, $fails failed ($(elapsed s))"
((fails == 0))
