#!/bin/bash
# Guest test of python_peer.py on a real vcan0: the frames its CLI sends
# (checked with candump), clean timeouts and exit codes, answers produced by
# cansend, and python_peer_test.py (fake node) over SocketCAN.
# Run with: tests/vm/run-in-vm.sh tests/vm/guest/peer_test.sh
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
peer() { "$PY" "$here/python_peer.py" --channel vcan0 "$@"; }

# expect_rc WANT DESCRIPTION -- command...
expect_rc() {
  local want=$1 what=$2
  shift 3
  local out rc
  out=$("$@" 2>&1)
  rc=$?
  # shellcheck disable=SC2001  # every line indented, not one substitution
  echo "$out" | sed 's/^/    /'
  if ((rc == want)); then pass "$what (exit $rc)"; else fail "$what: exit $rc, want $want"; fi
  last_out=$out
}

# --- 1. frames sent, timeouts ------------------------------------------------
start_candump vcan0 /tmp/peer.dump || fail "candump did not start"
expect_rc 0 "nmt start 0x20" -- peer nmt start 0x20
expect_rc 0 "nmt preop all" -- peer nmt preop 0
expect_rc 3 "sdo-read times out" -- peer --timeout 0.5 sdo-read 0x20 0x1000 0
expect_rc 3 "sdo-write times out" -- peer sdo-write 0x20 0x1017 0 u16 1000 --timeout 0.5
expect_rc 3 "wait-heartbeat times out" -- peer wait-heartbeat 0x20 --timeout 0.5
expect_rc 2 "bad node id is a usage error" -- peer nmt start 200
sleep 0.2
stop_candump
expected='vcan0 000#0120
vcan0 000#8000
vcan0 620#4000100000000000
vcan0 620#8000100000000405
vcan0 620#2B171000E8030000
vcan0 620#8017100000000405'
got=$(frames /tmp/peer.dump)
if [[ $got == "$expected" ]]; then
  pass "candump saw exactly the expected frames ($(elapsed s))"
else
  fail "candump saw:"$'\n'"$(cat /tmp/peer.dump)"$'\n'"expected:"$'\n'"$expected"
fi

# --- 2. answers from cansend --------------------------------------------------
# respond REQUEST_ID RESPONSE_FRAME: answer the next frame on REQUEST_ID.
respond() {
  local before
  before=$(can_receivers vcan0)
  (candump -n 1 "vcan0,$1:7FF" >/dev/null && cansend vcan0 "$2") &
  wait_receivers vcan0 $((before + 1))
}
respond 620 5A0#4300100091010000
expect_rc 0 "sdo-read expedited answer" -- peer sdo-read 0x20 0x1000 0 --format uint
[[ $last_out == 401 ]] && pass "sdo-read value 401" || fail "sdo-read printed '$last_out', want 401"
respond 620 5A0#8000100000000206
expect_rc 4 "sdo-read abort answer" -- peer sdo-read 0x20 0x1000 0
[[ $last_out == *0x06020000* ]] && pass "abort code printed" || fail "abort code not printed"
respond 620 5A0#6017100000000000
expect_rc 0 "sdo-write confirmed" -- peer sdo-write 0x20 0x1017 0 u16 1000
(
  wait_receivers vcan0 1 20   # the watcher below is the only receiver
  cansend vcan0 720#00; cansend vcan0 720#7F; cansend vcan0 720#05
) &
expect_rc 0 "wait-heartbeat sees operational" -- peer wait-heartbeat 0x20 --state 0x05 --timeout 20
[[ $last_out == *operational* ]] || fail "wait-heartbeat printed '$last_out'"
wait

# --- 3. the peer's own tests, over SocketCAN ---------------------------------
if PEER_TEST_INTERFACE=socketcan PEER_TEST_CHANNEL=vcan1 "$PY" "$here/python_peer_test.py" 2>&1 | sed 's/^/    /'; then
  pass "python_peer_test.py on vcan1"
else
  fail "python_peer_test.py on vcan1"
fi

echo "== peer_test checks: $passes passed, $fails failed ($(elapsed s))"
((fails == 0))
