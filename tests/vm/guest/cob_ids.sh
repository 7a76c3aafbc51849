#!/bin/bash
# Guest test (vm_cob_ids): a sub-device whose TPDO another tool moved onto another node's COB-ID,
# under `oegw run` (tests/fixtures/vm_gateway.yaml: the demo's five devices as `oegw-sim`
# processes on vcan1). CiA 301 §7.2.2: a PDO has one producer; the gateway reads each generic
# CiA 401 node's PDO COB-IDs back at boot (18xxh:01) and refuses the node that claims one another
# node has (subdevices/network_manager.cpp cob_refusal; docs/design/device-documents.md).
#   1 the pedal (CiA 401 30h) alone in its own process with a parameter store: cansend, as the
#     other tool, disables its TPDO 1 (1800h:01 = 800001B0h), moves it to 191h (the grip's TPDO 1)
#     and stores the communication parameters (1010h:02 "save"); the pedal's process is started
#     again (a power cycle) and answers 1800h:01 = 191h;
#   2 `oegw run`: the pedal refused, naming 191h and right_grip, in the log and in `oegw status`;
#     the grip (first to claim 191h) and the three others operational; the pedal's FE faulted
#     (EMCY 7000h naming 30h on vcan0) and its frames on 191h never taken for the pedal's;
#   3 evidence clears it: the pedal replaced by one with its own COB-ID (its store removed, its
#     process started again: a boot-up) is booted, started and operational, and the gateway
#     sends its error reset (0A0#0000...).
# Args: OEGW OEGW_SIM SOURCE_DIR
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1 sim=$2 src=$3
dir=/run/oegw-cob-ids

prepare_gateway_run vm_gateway.yaml "$src" "$dir" "$oegw" || { fail "oegw check exit $?: $(cat /tmp/check.out)"; exit 1; }
start_candump vcan0 /tmp/up.dump || fail "candump vcan0 did not start"
up_candump=$candump_pid
start_candump vcan1 /tmp/down.dump || fail "candump vcan1 did not start"
down_candump=$candump_pid
gateway_cab "$src"
pedal="${devices[2]},store=$dir/pedal.store"
start_sim "$sim" /tmp/sim-pedal.log "$pedal"
pedal_pid=$sim_pid
start_sim "$sim" /tmp/sim-others.log --motion "${devices[0]}" "${devices[1]}" "${devices[@]:3}"
others_pid=$sim_pid
wait_sims

# sdo REQUEST ANSWER_PREFIX: one expedited SDO request to the pedal (630h) with cansend; its
# answer on 5B0h must start so (a FAIL line and status 1 when it does not come within 5 s).
sdo() {
  local before
  before=$(count /tmp/down.dump "vcan1 5B0#$2")
  cansend vcan1 "630#$1"
  wait_more /tmp/down.dump "vcan1 5B0#$2" "$before" 5 || { fail "1: 630#$1 not answered 5B0#$2..."; return 1; }
}

# 1 another tool moves the pedal's TPDO 1 onto the grip's COB-ID and stores it; a power cycle.
sdo 23001801B0010080 60001801 && sdo 2300180191010000 60001801 && sdo 2310100273617665 60101002 &&
  pass "1: the pedal's TPDO 1 moved to 191h (disabled, set, stored by 1010h:02)"
kill -TERM "$pedal_pid"
wait "$pedal_pid" 2>/dev/null
start_sim "$sim" /tmp/sim-pedal.log "$pedal"
pedal_pid=$sim_pid
wait_sims
sdo 4000180100000000 43001801 && grep -q 'vcan1 5B0#4300180191010000' /tmp/down.dump &&
  pass "1: after its power cycle the pedal answers 1800h:01 = 191h" || fail "1: the pedal did not keep 191h"

# 2 the gateway refuses the pedal, keeps the grip.
start_oegw_run "$oegw" "$dir/oegw.yaml"
echo "gateway started after $(elapsed) s"
refused='subs["pedal"]["state"] == "refused" and "191h is also right_grip" in str(subs["pedal"]) and '
refused+='all(subs[n]["state"] == "operational" for n in ("right_grip", "left_grip", "seat_knob", "cluster"))'
if "$PY" "$here/status_wait.py" "$oegw" /tmp/refused.json 120 "$refused"; then
  pass "2: oegw status: pedal refused naming 191h and right_grip; the grip and the three others operational"
else
  fail "2: not so in oegw status: $(head -c 3000 /tmp/refused.json)"
fi
wait_for /tmp/gateway.log "pedal: .*its PDO COB-ID 191h is also right_grip's" 10 &&
  pass "2: the log: $(grep -m1 -o "pedal: .*its PDO COB-ID 191h is also right_grip's[^\"]*" /tmp/gateway.log)" ||
  fail "2: no refusal naming 191h and right_grip in the log: $(grep pedal /tmp/gateway.log | tail -5)"
wait_for /tmp/up.dump 'vcan0 0A0#0070..30' 10 && pass "2: EMCY 7000h naming 30h upstream" ||
  fail "2: no EMCY 7000h naming 30h on vcan0"
grep -q 'vcan1 000#0130' /tmp/down.dump && fail "2: the refused pedal was started (000#0130)" ||
  pass "2: the refused pedal was never started (no 000#0130 on vcan1)"

# 3 a pedal with its own COB-ID (no store: the EDS's 1B0h) comes up in its place.
resets=$(count /tmp/up.dump 'vcan0 0A0#0000')
kill -TERM "$pedal_pid"
wait "$pedal_pid" 2>/dev/null
rm -f "$dir/pedal.store"
start_sim "$sim" /tmp/sim-pedal.log "${devices[2]}"
pedal_pid=$sim_pid
wait_sims
if "$PY" "$here/status_wait.py" "$oegw" /tmp/back.json 120 'subs["pedal"]["state"] == "operational"'; then
  pass "3: the pedal on its own 1B0h operational after $(elapsed) s"
else
  fail "3: the pedal not operational: $(head -c 3000 /tmp/back.json)"
fi
wait_more /tmp/up.dump 'vcan0 0A0#0000' "$resets" 10 && pass "3: the gateway's error reset upstream" ||
  fail "3: no error reset on vcan0 after the pedal came back"

stop_gateway "$gw_pid"
kill -TERM "$pedal_pid" "$others_pid" 2>/dev/null
wait "$pedal_pid" "$others_pid" 2>/dev/null
for candump_pid in "$down_candump" "$up_candump"; do stop_candump; done
echo "== gateway log (pedal)"
grep pedal /tmp/gateway.log | grep -v 'debug:' | sed 's/^/    /' | head -30
cp /tmp/up.dump /tmp/down.dump /tmp/gateway.log /tmp/sim-pedal.log "${OEGW_VM_OUT:-/tmp}/" 2>/dev/null
echo "cob_ids: $passes passed, $fails failed, $(elapsed s)"
((fails == 0))
