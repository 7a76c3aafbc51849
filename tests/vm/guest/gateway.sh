#!/bin/bash
# Guest test: the whole gateway on real SocketCAN. `oegw run` with a mapping file whose upstream
# is vcan0 and downstream vcan1 (config/demo.yaml's devices and FEs); the cab devices are
# `oegw-sim --motion` processes on vcan1 (the elobau grip alone in one, so that it can be
# unplugged by killing it); python3-can is the host on vcan0 (gateway_host.py): boot-up, 1000h
# (= what `oegw check` prints), TPDO1 enabled on 1A0h, 6423h TRUE, NMT start, joystick 1 moving in
# TPDO1, then EMCY 7000h naming node 11h when the grip's process dies. candump on vcan0 confirms
# the upstream frames; SIGTERM stops the gateway with exit 0.
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
"$PY" "$here/gateway_host.py" vcan0 /tmp/gw.host-ready "${dt:-0}" >/tmp/host.log 2>&1 &
host_pid=$!
for ((i = 0; i < 600; i++)); do [[ -e /tmp/gw.host-ready ]] && break; sleep 0.05; done
[[ -e /tmp/gw.host-ready ]] && echo "host up after $(elapsed) s" || fail "python3-can host did not come up"
receivers=$(can_receivers vcan1)
"$sim" -i vcan1 --motion elobau-mfg:0x11:name=right_grip >/tmp/sim-grip.log 2>&1 &
grip_pid=$!
"$sim" -i vcan1 --motion mcb402:0x03:name=left_grip \
  "cia401:0x30:name=pedal,eds=$src/subdevices/eds/generic_pedal.eds" novotechnik-406:0x7F:name=seat_knob \
  "cia401:0x31:name=cluster,eds=$src/subdevices/eds/button_cluster.eds" >/tmp/sim-others.log 2>&1 &
others_pid=$!
wait_receivers vcan1 $((receivers + 2)) 20 || fail "the simulators did not bind vcan1"
"$oegw" run "$dir/oegw.yaml" >/tmp/gateway.log 2>&1 &
gw_pid=$!
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

kill -TERM "$gw_pid"
wait "$gw_pid"
rc=$?
((rc == 0)) && pass "SIGTERM stops oegw run cleanly (exit 0)" || fail "oegw run exit $rc after SIGTERM"
kill -TERM "$others_pid" 2>/dev/null
wait "$others_pid" 2>/dev/null
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
