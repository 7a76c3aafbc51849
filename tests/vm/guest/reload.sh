#!/bin/bash
# Guest test (vm_reload): SIGHUP = reload, outside in. `oegw run` with
# tests/fixtures/vm_gateway.yaml (its upstream heartbeat 2000 ms here: 1.5 x 1017h must outlast
# a stalled TCG guest on a loaded host, where 1.4 s gaps were seen), the cab devices in one `oegw-sim --motion` process on vcan1, the host's
# set-up by cansend on vcan0 (TPDO 1 on 1A0h, 6423h TRUE, indicators.2's error value 0Ah and
# value 05h, NMT start). Three SIGHUPs to the running process:
#   1. a valid file (joystick.2 y's deadband changed): applied;
#   2. an invalid one (node_id 0x80, a deadband -3): every error logged at file:line:column,
#      nothing changed;
#   3. a valid one that changes the upstream device (upstream.heartbeat_ms): refused, needs a
#      restart.
# The process survives all three and SIGTERM ends it with exit 0. candump on both buses judges
# the frames (reload_check.py: heartbeat gaps, EMCY 6300h, error values in between, nothing
# after a refusal); the log, the messages.
# Args: OEGW OEGW_SIM SOURCE_DIR
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1 sim=$2 src=$3
dir=/run/oegw-reload
heartbeat_ms=2000

prepare_gateway_run vm_gateway.yaml "$src" "$dir" "$oegw"
sed -i "0,/^  heartbeat_ms: 200\$/s//  heartbeat_ms: $heartbeat_ms/" "$dir/oegw.yaml"
"$oegw" check --here "$dir/oegw.yaml" >/tmp/check.out 2>&1 && grep -q "^  heartbeat_ms: $heartbeat_ms\$" "$dir/oegw.yaml" &&
  pass "oegw check: valid, upstream heartbeat $heartbeat_ms ms" || fail "oegw check: $(cat /tmp/check.out)"
cp "$dir/oegw.yaml" /tmp/oegw.yaml.orig

start_candump vcan0 /tmp/up.dump || fail "candump vcan0 did not start"
up_candump=$candump_pid
start_candump vcan1 /tmp/down.dump || fail "candump vcan1 did not start"
down_candump=$candump_pid
gateway_cab "$src"
start_gateway_scenario "$oegw" "$dir" 5 "$sim" --motion "${devices[@]}"
all_up='len(s["subdevices"]) == 5 and all(d["network_state"] == "operational" for d in s["subdevices"])'
settled="$all_up and 0x6300 not in s[\"upstream\"][\"active_emcys\"]"

# The host: TPDO 1 on 1A0h, 6423h TRUE, indicators.2 (6200h:09, the MCB-402's LEDs) error value
# 0Ah and value 05h, NMT start. Each an expedited SDO download the gateway answers at once.
for f in 620#23001801A0010000 620#2F23640001000000 620#2F0762090A000000 620#2F00620905000000 000#0120; do
  cansend vcan0 "$f"
  sleep 0.2
done
sleep 2

# hup N: marker 7FF#0N on both buses, then SIGHUP; waits for the log's outcome line (`pattern`).
hup() {
  local n=$1 pattern=$2 before
  before=$(grep -c -- "$pattern" /tmp/gateway.log)
  cansend vcan0 "7FF#0$n"
  cansend vcan1 "7FF#0$n"
  kill -HUP "$gw_pid"
  for ((i = 0; i < 600; i++)); do
    (($(grep -c -- "$pattern" /tmp/gateway.log) > before)) && return 0
    sleep 0.05
  done
  return 1
}

# 1. A valid file.
sed -i 's/y: { signal: left_grip.y, deadband: 300, invert: true }/y: { signal: left_grip.y, deadband: 200, invert: true }/' "$dir/oegw.yaml"
cmp -s "$dir/oegw.yaml" /tmp/oegw.yaml.orig && fail "the valid edit changed nothing"
hup 1 ': reloaded: ' && pass "valid file: 'reloaded' logged ($(elapsed) s)" || fail "valid file: no 'reloaded' in the log"
"$PY" "$here/status_wait.py" "$oegw" /tmp/status.json 120 "$settled" &&
  pass "valid file: every sub-device operational again, 6300h no longer active ($(elapsed) s)" ||
  fail "after the valid reload: $(head -c 2000 /tmp/status.json)"
sleep 2

# 2. An invalid file: two errors, each logged at file:line:column.
sed -i -e 's/^  node_id: 0x20$/  node_id: 0x80/' -e 's/deadband: 200, invert: true/deadband: -3, invert: true/' "$dir/oegw.yaml"
hup 2 'reload refused' && pass "invalid file: 'reload refused' logged" || fail "invalid file: no 'reload refused' in the log"
grep -q "error: $dir/oegw.yaml:7:12: node_id 0x80 is out of range" /tmp/gateway.log &&
  grep -q "error: $dir/oegw.yaml:44:41: deadband -3 is out of range" /tmp/gateway.log &&
  pass "invalid file: both errors logged at file:line:column" ||
  fail "invalid file: errors not logged: $(grep -F 'error:' /tmp/gateway.log | tail -4)"
grep -q "reload refused, 2 errors; the gateway runs on as before" /tmp/gateway.log && pass "invalid file: 2 errors, runs on" ||
  fail "invalid file: no summary line"
sleep 3

# 3. A valid file that changes the upstream device: refused, a restart applies it.
sed "0,/^  heartbeat_ms: $heartbeat_ms\$/s//  heartbeat_ms: $((heartbeat_ms * 2))/" /tmp/oegw.yaml.orig >"$dir/oegw.yaml"
hup 3 'reload refused' && pass "upstream change: 'reload refused' logged" || fail "upstream change: not refused"
grep -q "upstream.heartbeat_ms changed from $heartbeat_ms to $((heartbeat_ms * 2)): .*a reload cannot apply it, a restart can (systemctl restart oegw)" /tmp/gateway.log &&
  pass "upstream change: $(grep -o 'upstream.heartbeat_ms changed from [0-9]* to [0-9]*' /tmp/gateway.log | head -1), a restart needed" ||
  fail "upstream change: no message naming upstream.heartbeat_ms"
sleep 3
"$PY" "$here/status_wait.py" "$oegw" /tmp/status.json 20 "$settled" && pass "still every sub-device operational" ||
  fail "after the refused reloads: $(head -c 2000 /tmp/status.json)"

kill -0 "$gw_pid" 2>/dev/null && pass "oegw run survived three SIGHUPs" || fail "oegw run is gone"
n=$(grep -c 'reload: every input at its fault value' /tmp/gateway.log)
((n == 1)) && pass "the sub-devices booted again by one reload only" || fail "$n reloads applied, expected 1"
cansend vcan0 7FF#04
cansend vcan1 7FF#04
sleep 0.5
stop_gateway "$gw_pid"
[[ -e /run/oegw/oegw.sock ]] && fail "the control socket is left behind" || pass "the control socket is removed"
kill "$sim_pid" 2>/dev/null
kill -INT "$up_candump" "$down_candump" 2>/dev/null
wait "$up_candump" "$down_candump" 2>/dev/null

# Kept for a post-mortem: OEGW_VM_OUT is the run's folder on the host
# (docs/developer/vm-tier.md#run-in-vmsh-exit-status-and-environment).
[[ -n ${OEGW_VM_OUT:-} ]] && cp /tmp/up.dump /tmp/down.dump /tmp/gateway.log "$OEGW_VM_OUT/" 2>/dev/null
"$PY" "$here/reload_check.py" /tmp/up.dump /tmp/down.dump "$heartbeat_ms" >/tmp/check.txt 2>&1
cat /tmp/check.txt
passes=$((passes + $(grep -c '^PASS' /tmp/check.txt)))
fails=$((fails + $(grep -c '^FAIL' /tmp/check.txt)))
grep -q '^Traceback' /tmp/check.txt && fail "reload_check.py failed"
if ((fails > 0)); then
  echo "--- gateway log (last 60 lines)"
  tail -60 /tmp/gateway.log
fi
echo "$passes passed, $fails failed ($(elapsed) s)"
((fails == 0))
