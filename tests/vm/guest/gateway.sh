#!/bin/bash
# Guest test: the whole gateway on real SocketCAN. `oegw run` with a mapping file whose upstream
# is vcan0 and downstream vcan1 (config/demo.yaml's devices and FEs); the cab devices are
# `oegw-sim --motion` processes on vcan1 (the elobau grip alone in one, so that it can be
# unplugged by killing it); python3-can is the host on vcan0 (gateway_host.py): boot-up, 1000h
# (= what `oegw check` prints), TPDO1 enabled on 1A0h, 6423h TRUE, NMT start, joystick 1 moving in
# TPDO1, then EMCY 7000h naming node 11h when the grip's process dies. candump on vcan0 confirms
# the upstream frames; SIGTERM stops the gateway with exit 0. candump on vcan1 checks that the
# gateway paces its SDO requests to the sub-devices (canopen/301/sdo_pacer.hpp).
# Args: OEGW OEGW_SIM SOURCE_DIR
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1
sim=$2
src=$3
dir=/run/oegw-gateway

# The mapping file: tests/fixtures/vm_gateway.yaml (its comments say why its timings are what they are).
prepare_gateway_run vm_gateway.yaml "$src" "$dir" "$oegw"
rc=$?
((rc == 0)) && pass "oegw check: valid" || fail "oegw check exit $rc: $(cat /tmp/check.out)"
dt=$(sed -n 's/.*1000h device type = \([0-9A-F]\{8\}\)h.*/\1/p' /tmp/check.out)
[[ -n "$dt" ]] && pass "oegw check prints 1000h = ${dt}h" || fail "no 1000h in: $(cat /tmp/check.out)"

start_candump vcan0 /tmp/up.dump || fail "candump vcan0 did not start"
up_candump=$candump_pid
start_candump vcan1 /tmp/down.dump || fail "candump vcan1 did not start"
down_candump=$candump_pid
# The host first (it waits for the boot-up), then the devices, then the gateway.
start_host /tmp/host.log /tmp/gw.host-ready 30 "$PY" "$here/gateway_host.py" vcan0 /tmp/gw.host-ready "${dt:-0}"
# start_cab SUFFIX: the grip in its own process (it is unplugged by killing it), the others in one.
gateway_cab "$src"
start_cab() {
  start_sim "$sim" "/tmp/sim-grip$1.log" --motion "${devices[0]}"
  grip_pid=$sim_pid
  start_sim "$sim" "/tmp/sim-others$1.log" --motion "${devices[@]:1}"
  others_pid=$sim_pid
}
start_cab ""
wait_sims
start_oegw_run "$oegw" "$dir/oegw.yaml"
echo "gateway started after $(elapsed) s"

# The host asks for the grip to be unplugged.
for ((i = 0; i < 1800; i++)); do
  if [[ -e /tmp/gw.kill-grip ]]; then
    echo "grip simulator killed after $(elapsed) s"
    kill -KILL "$grip_pid"
    wait "$grip_pid" 2>/dev/null
    rm -f /tmp/gw.kill-grip
  fi
  kill -0 "$host_pid" 2>/dev/null || break
  sleep 0.05
done
wait "$host_pid"
host_rc=$?
echo "host finished after $(elapsed) s"
sed 's/^/    host: /' /tmp/host.log
((host_rc == 0)) && pass "python3-can host: every check" || fail "python3-can host exit $host_rc"

# ---- `oegw status`: the control socket at its default path, /run/oegw/oegw.sock.
# The grip is gone: shown missing (or booting: the gateway retries it). The simulators start again
# (the MCB-402 sends its power-on EMCY 8100h, MCB §4, which the gateway now sees), then every
# sub-device is shown operational with its identity; then the process of the MCB-402 and the
# others is killed: the MCB-402 is shown missing with that last EMCY. Each check reads one answer
# of `oegw status --json` (status_wait.py, python3's json). A loaded TCG guest delays PDOs past
# their freshness deadline now and then (the fault clears with the next PDO, see vm_faults): a
# node the network manager holds operational may be shown `faulty` for that moment, which counts
# as up here.
sock=/run/oegw/oegw.sock
# expect_status TIMEOUT_S PY_EXPR WHAT: until `oegw status --json` shows PY_EXPR (status_wait.py).
expect_status() {
  if "$PY" "$here/status_wait.py" "$oegw" /tmp/status.json "$1" "$2"; then pass "oegw status --json: $3"; else
    fail "oegw status --json: $3: $(head -c 3000 /tmp/status.json)"
  fi
}
expect_status 20 'subs["right_grip"]["state"] in ("missing", "booting") and subs["right_grip"]["fault"] and s["upstream"]["active_emcys"] == [0x7000]' \
  "right_grip missing, 7000h active upstream"
[[ $(stat -c '%a %U' "$sock") == "600 root" ]] && pass "control socket $sock: mode 600, root" ||
  fail "control socket: $(stat -c '%a %U %G' "$sock")"
kill -TERM "$others_pid" 2>/dev/null
wait "$others_pid" 2>/dev/null
start_cab 2
all_up='len(s["subdevices"]) == 5 and all(d["network_state"] == "operational" and d["state"] in ("operational", "faulty") for d in s["subdevices"])'
expect_status 120 "$all_up"' and s["upstream"]["node_id"] == 0x20 and s["upstream"]["interface"] == "vcan0" and s["upstream"]["nmt_state"] == "operational"' \
  "every sub-device operational; upstream node-ID 20h on vcan0, operational"
echo "status: every sub-device operational after $(elapsed) s"
"$PY" -c 'import json, sys
s = json.load(open("/tmp/status.json"))["status"]
subs = {d["name"]: d for d in s["subdevices"]}
for d in s["subdevices"]: print("    identity:", d["name"], d["identity"], d["device_name"], d["software_version"])
ok = all(isinstance(d["identity"]["vendor_id"], int) and isinstance(d["identity"]["product_code"], int) and d["counters"]["frames"] > 0 for d in s["subdevices"])
ok = ok and subs["right_grip"]["identity"]["vendor_id"] == 0xB4 and subs["left_grip"]["device_name"] == "CO4013A"
# The new grip process boots on its own: a reboot seen, or (when its boot-up meets the reset
# communication of a retry) the answer to that reset; its first boot answered a gateway reset.
g = subs["right_grip"]["counters"]
ok = ok and g["reboots_seen"] + g["gateway_resets"] >= 2 and g["gateway_resets"] >= 1
ok = ok and subs["left_grip"]["last_emcy"]["code"] == 0x8100 and subs["left_grip"]["last_emcy"]["error_register"] == 0x11
ok = ok and any(fe["name"] == "joystick.1" for fe in s["functional_elements"])
# The SDO pacing at downstream.bitrate 250000 (SdoPacer::gap_for: 270 bits / (250 kbit/s x 0.85)),
# and requests that waited for it: five devices configured at once after their boot-ups.
p = s["downstream"]["sdo_pacing"]
print("    sdo_pacing:", p)
ok = ok and p["gap_us"] == 1271 and p["delayed_starts"] > 0
sys.exit(0 if ok else 1)' && pass "oegw status --json: identities (1018h, 1008h), frames, the grip's reboot, left_grip's power-on EMCY 8100h; SDO requests paced 1,271 us apart" ||
  fail "oegw status --json: identities/counters/EMCY: $(head -c 3000 /tmp/status.json)"
"$oegw" status --timeout 10 >/tmp/status.txt 2>&1
rc=$?
sed 's/^/    status: /' /tmp/status.txt
((rc == 0)) && pass "oegw status: exit 0" || fail "oegw status: exit $rc"
awk 'length($0) > 100 { bad = 1 } END { exit bad }' /tmp/status.txt && pass "oegw status: fits 100 columns" ||
  fail "oegw status: a line over 100 columns"
for name in right_grip left_grip pedal seat_knob cluster; do
  grep -qE "^$name +[0-9A-F]{2}h [a-z0-9-]+ +(operational|faulty) " /tmp/status.txt && pass "oegw status: $name operational" ||
    fail "oegw status: no operational row for $name"
done
kill -KILL "$others_pid"
wait "$others_pid" 2>/dev/null
expect_status 30 'subs["left_grip"]["state"] == "missing" and subs["left_grip"]["last_emcy"]["code"] == 0x8100' \
  "left_grip missing, its last EMCY 8100h kept"
echo "status: left_grip missing after $(elapsed) s"
"$oegw" status --timeout 10 >/tmp/status2.txt 2>&1
# Its row, its identity and firmware lines, then the EMCY line.
grep -A3 -E '^left_grip +03h mcb402 +(missing|booting) ' /tmp/status2.txt | grep -qE '^    last EMCY 8100h reg 11h data 0000000000, ' &&
  pass "oegw status: left_grip missing, last EMCY 8100h" || fail "oegw status: left_grip: $(grep -A4 left_grip /tmp/status2.txt)"
# Only root (mode 0600 without control.group): another user is told so, exit 4.
setpriv --reuid=65534 --regid=65534 --clear-groups "$oegw" status >/tmp/status3.txt 2>&1
rc=$?
((rc == 4)) && grep -q "permission denied on $sock (root:root, mode 0600)" /tmp/status3.txt &&
  pass "oegw status as nobody: permission denied (exit 4)" || fail "oegw status as nobody: exit $rc: $(cat /tmp/status3.txt)"
# A second gateway never takes a live daemon's socket.
"$oegw" run "$dir/oegw.yaml" >/tmp/gateway2.log 2>&1
rc=$?
((rc == 2)) && grep -q "control.socket: $sock is served by a running gateway" /tmp/gateway2.log &&
  pass "a second oegw run refuses the live socket (exit 2)" || fail "second oegw run: exit $rc: $(cat /tmp/gateway2.log)"

kill -TERM "$gw_pid"
wait "$gw_pid"
rc=$?
((rc == 0)) && pass "SIGTERM stops oegw run cleanly (exit 0)" || fail "oegw run exit $rc after SIGTERM"
[[ ! -e $sock ]] && pass "the control socket is removed at exit" || fail "$sock left after exit"
"$oegw" status >/tmp/status4.txt 2>&1
rc=$?
((rc == 3)) && grep -q "no gateway is running" /tmp/status4.txt && pass "oegw status without a gateway: exit 3" ||
  fail "oegw status without a gateway: exit $rc: $(cat /tmp/status4.txt)"
kill -TERM "$grip_pid" 2>/dev/null
wait "$grip_pid" 2>/dev/null
stop_candump  # vcan1's
candump_pid=$up_candump
stop_candump
echo "== gateway log (journald format: level: message)"
sed 's/^/    /' /tmp/gateway.log | head -60

# candump's view of the upstream bus.
got=$(frames /tmp/up.dump)
expect_frame() {
  if grep -qx "vcan0 $1" <<<"$got"; then pass "candump vcan0: $1 ($2)"; else fail "candump vcan0 lacks $1 ($2)"; fi
}
expect_re() {
  if grep -qE "^vcan0 $1\$" <<<"$got"; then pass "candump vcan0: $1 ($2)"; else fail "candump vcan0 lacks $1 ($2)"; fi
}
expect_frame '720#00' "gateway boot-up"
expect_frame '620#4000100000000000' "SDO upload request 1000h"
expect_frame "5A0#43001000${dt:6:2}${dt:4:2}${dt:2:2}${dt:0:2}" "1000h = ${dt}h"
expect_frame '620#23001801A0010000' "TPDO1 COB-ID 1A0h"
expect_frame '5A0#6000180100000000' "download confirmed"
expect_frame '620#2F23640001000000' "6423h = TRUE"
expect_frame '000#0120' "NMT start node 20h"
expect_frame '720#05' "heartbeat operational"
expect_re '1A0#[0-9A-F]{16}' "TPDO1, 8 bytes"
expect_frame '0A0#0070011172696768' "EMCY 7000h, register 01h, node 11h, 'righ'"
n=$(grep -cE '^vcan0 1A0#' <<<"$got")
echo "candump vcan0: $n TPDO1 frames, $(wc -l </tmp/up.dump) frames in all"
# The upstream bus carried nothing of the downstream one.
if grep -qE '^vcan0 (711|703|730|77F|731)#' <<<"$got"; then fail "downstream heartbeats on vcan0"; else pass "vcan0 carries no sub-device frames"; fi
if grep -qE '^vcan1 711#05' <<<"$(frames /tmp/down.dump)"; then pass "candump vcan1: grip operational (711#05)"; else fail "no 711#05 on vcan1"; fi
# SDO pacing (canopen/301/sdo_pacer.hpp): the gateway starts its SDO requests downstream at
# least a gap apart (1,271 us at 250 kbit/s), judged exactly on simulated time (timed_bus_test:
# TheGatewayStartsItsDownstreamSdoRequestsAtLeastThePacingGapApart). Here the process shows its
# pacing in `oegw status --json` (downstream.sdo_pacing, checked above: the gap and requests that
# waited for it). candump's view is a figure, not judged: a stamp in this TCG guest is the write,
# which may lag its pacing decision by a stall, so paced requests may stand close on the wire (3
# requests within one gap: 2-5 times in ~280 on a loaded host, and more in CI, which once failed a
# bound of 1 in 25; 18 in 293 with the pacing off, when the median gap was 2.1 ms against 2.3-3.0
# ms paced: the guest's SDO round trips, not the pacing, set most gaps).
read -r n_req short span2 span10 median <<<"$("$PY" "$here/sdo_pacing.py" /tmp/down.dump 1271)"
echo "candump vcan1 (figures): $n_req SDO initiate requests, median gap $median us; 3 consecutive within less than 1,271 us: $short times (the shortest 2 gaps: $span2 us); the shortest 10 gaps span $span10 us"
# The gateway's log (journald: "level: message", no timestamps) names the lost grip.
for line in 'info: right_grip: operational (first heartbeat in operational after NMT start)' 'info: right_grip: missing (heartbeat lost)'; do
  if grep -qxF "$line" /tmp/gateway.log; then pass "log: $line"; else fail "log lacks: $line"; fi
done
# The killed grip's PDOs go stale (3 x 100 ms) before its heartbeat is missed (600 ms): either
# reason may be the fault's.
fault_re='^info: right_grip: fault \((missing \(heartbeat lost\)|[a-z_]+ stale \(no PDO for [0-9]+ ms\))\): its inputs are at their fault values, EMCY 7000h sent upstream$'
if line=$(grep -m1 -E "$fault_re" /tmp/gateway.log); then pass "log: $line"; else fail "log lacks the grip's fault line"; fi
cp /tmp/up.dump /tmp/down.dump /tmp/gateway.log /tmp/host.log "${OEGW_VM_OUT:-/tmp}/" 2>/dev/null
echo "total $(elapsed) s; $passes passed, $fails failed"
((fails == 0))
