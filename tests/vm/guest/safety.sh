#!/bin/bash
# Guest test (vm_safety): the safety findings, outside in, on real SocketCAN. The built
# `oegw run` sits between vcan0 (the host: safety_host.py on python3-can, which also watches
# vcan1 and injects one frame there) and vcan1 (`oegw-sim` processes: the elobau grip 11h alone
# with --commands read from a FIFO the host writes, the MCB-402 03h, a CiA 401 pedal and a
# Novotechnik encoder with --motion as frame load). Only frames are judged: the host's view of
# vcan0/vcan1 (kernel timestamps) and candump's recordings of both buses.
# Scenarios (one PASS/FAIL line each; details in safety_host.py):
#   1 heartbeat never returns after a reboot   2 boot race (pre-operational heartbeat after NMT start)
#   3 outputs atomic (6200h 00h->05h->0Ah)     4 host heartbeat loss under load: error values, one frame
#   5 PDOs stop while the heartbeat goes on    6 reboot with the stick deflected (zero position)
#   4b the host's heartbeat lost again after it came back (twice more)
# Args: OEGW OEGW_SIM SOURCE_DIR
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1
sim=$2
src=$3
dir=/run/oegw-safety

# The mapping file: tests/fixtures/vm_safety.yaml (its comments say why its timings are what they are).
prepare_gateway_run vm_safety.yaml "$src" "$dir" "$oegw"
rc=$?
((rc == 0)) || { fail "oegw check exit $rc: $(cat /tmp/check.out)"; exit 1; }

start_candump vcan0 /tmp/up.dump || fail "candump vcan0 did not start"
up_candump=$candump_pid
start_candump vcan1 /tmp/down.dump || fail "candump vcan1 did not start"
down_candump=$candump_pid

# The grip's commands come from a FIFO the host writes; this shell keeps it open read-write, so
# the simulator never sees end of file (which would end it) and nobody blocks on open.
mkfifo /tmp/grip.cmd
exec 3<>/tmp/grip.cmd
# The host first (it watches both buses from before the gateway starts), then the devices, then
# the gateway.
start_host /tmp/host.log /tmp/safety.ready 45 "$PY" "$here/safety_host.py" /tmp/safety.ready /tmp/grip.cmd /tmp/safety.windows
gateway_cab "$src"  # (vm_safety.yaml: without the cluster)
start_sim "$sim" /tmp/sim-grip.log --commands "${devices[0]}"
grip_pid=$sim_pid
start_sim "$sim" /tmp/sim-others.log --motion "${devices[@]:1:3}"
others_pid=$sim_pid
wait_sims
start_oegw_run "$oegw" "$dir/oegw.yaml"
echo "gateway started after $(elapsed) s"

# The host prints as it goes; its exit status is the number of failed scenarios.
follow_host /tmp/host.log
echo "host finished after $(elapsed) s (exit $host_rc)"

kill -TERM "$gw_pid"
wait "$gw_pid"
rc=$?
((rc == 0)) || fail "oegw run exit $rc after SIGTERM"
kill -TERM "$grip_pid" "$others_pid" 2>/dev/null
wait "$grip_pid" "$others_pid" 2>/dev/null
exec 3>&-
stop_candump  # vcan1's
candump_pid=$up_candump
stop_candump

# The host's verdicts, one line per scenario.
while IFS= read -r line; do
  case $line in
    "PASS: scenario"*) pass "${line#PASS: }" ;;
    "FAIL: scenario"*) fail "${line#FAIL: }" ;;
  esac
done </tmp/host.log
grep -q '^PASS: scenario\|^FAIL: scenario' /tmp/host.log || fail "the host reported no scenario (exit $host_rc)"

# candump's own record of vcan1 (kernel timestamps, the host's clock): the MCB-402 RPDO1 frames
# (203h) in each window the host wrote ("name t_from t_to expected-frames...").
if [[ -s /tmp/safety.windows ]]; then
  while read -r name from to expected; do
    got=$(awk -v a="$from" -v b="$to" '{ t = substr($1, 2, length($1) - 2) + 0 }
           t > a && t <= b && $2 == "vcan1" && $3 ~ /^203#/ { printf "%s%s", sep, $3; sep = " " }' /tmp/down.dump)
    if [[ "$got" == "${expected//,/ }" ]]; then
      pass "candump vcan1, $name: exactly ${expected//,/ }"
    else
      fail "candump vcan1, $name: expected ${expected//,/ }, got '${got}'"
    fi
  done </tmp/safety.windows
fi

echo "== gateway log (journald format: level: message)"
grep -v 'debug:' /tmp/gateway.log | sed 's/^/    /' | head -120
echo "== grip simulator"
sed 's/^/    /' /tmp/sim-grip.log | head -60
cp /tmp/up.dump /tmp/down.dump /tmp/gateway.log /tmp/host.log /tmp/sim-grip.log /tmp/safety.windows \
  "${OEGW_VM_OUT:-/tmp}/" 2>/dev/null
echo "total $(elapsed) s; $passes passed, $fails failed"
((fails == 0))
