# Helpers for guest scripts of the VM tier (source it; bash).
# shellcheck shell=bash

# shellcheck disable=SC2034  # used by the scripts that source this file
PY=/usr/bin/python3   # python3-can lives here; a python3 on PATH may lack it

fails=0
passes=0
# The script's clock, from the moment it sourced this file: `elapsed` prints the seconds since,
# with one decimal ("12.3"); `elapsed s` appends the unit ("12.3s").
t0=$(date +%s.%N)
elapsed() { awk -v a="$t0" -v b="$(date +%s.%N)" -v u="${1:-}" 'BEGIN { printf "%.1f%s", b - a, u }'; }

pass() { echo "PASS: $*"; passes=$((passes + 1)); }
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }

# mapping_fixture NAME SRC RUN_DIR: the mapping file tests/fixtures/NAME of source tree SRC on
# stdout, its placeholders filled (docs/developer/fixtures.md#placeholders): @EDS_DIR@ =
# SRC/subdevices/eds, @RUN_DIR@ = RUN_DIR. The guest reads the source tree through the read-only
# host root.
mapping_fixture() {
  [[ -r $2/tests/fixtures/$1 ]] || return 1
  sed -e "s|@EDS_DIR@|$2/subdevices/eds|g" -e "s|@RUN_DIR@|$3|g" "$2/tests/fixtures/$1"
}

# prepare_gateway_run FIXTURE SRC RUN_DIR OEGW: the start the `oegw run` scenarios share — the
# run folder, the mapping file tests/fixtures/FIXTURE as RUN_DIR/oegw.yaml (the script ends with
# a FAIL when it is missing), and `oegw check --here` on it (this machine is the one it runs on)
# into /tmp/check.out; returns check's status.
prepare_gateway_run() {
  mkdir -p "$3"
  mapping_fixture "$1" "$2" "$3" >"$3/oegw.yaml" || { fail "cannot read tests/fixtures/$1"; exit 1; }
  "$4" check --here "$3/oegw.yaml" >/tmp/check.out 2>&1
}

# Number of raw CAN receivers (sockets) bound to device $1.
can_receivers() {
  awk -v d="$1" '$1 == d { n++ } END { print n + 0 }' /proc/net/can/rcvlist_* 2>/dev/null
}

# wait_receivers DEV N [TIMEOUT_S]: until at least N receivers are bound to DEV.
wait_receivers() {
  local dev=$1 n=$2 t=${3:-10} i=0
  while (($(can_receivers "$dev") < n)); do
    ((i++ >= t * 20)) && { echo "timeout waiting for $n receivers on $dev" >&2; return 1; }
    sleep 0.05
  done
}

# start_candump DEV FILE [candump args...]: candump -L in the background,
# returns once it is bound; its pid is in $candump_pid.
start_candump() {
  local dev=$1 file=$2
  shift 2
  local before
  before=$(can_receivers "$dev")
  candump -L "$@" "$dev" >"$file" 2>&1 &
  candump_pid=$!
  wait_receivers "$dev" $((before + 1))
}

# stop_candump: stop the candump started last, letting it flush.
stop_candump() {
  kill -INT "$candump_pid" 2>/dev/null
  wait "$candump_pid" 2>/dev/null
  return 0
}

# frames FILE: the "IFACE ID#DATA" part of candump -L lines.
frames() { awk '{ print $2, $3 }' "$1"; }

# stop_gateway PID: SIGTERM to an `oegw run`, which must exit 0 (a PASS or FAIL line).
stop_gateway() {
  kill -TERM "$1"
  wait "$1"
  local rc=$?
  ((rc == 0)) && pass "SIGTERM: oegw run exit 0" || fail "SIGTERM: oegw run exit $rc"
}

# run_recorded FIXTURE SRC RUN_DIR OEGW: the start the candump-judged scenarios share (vm_faults,
# vm_corners): `oegw check` of tests/fixtures/FIXTURE (the script ends with a FAIL when it is
# refused), candump -L of vcan0 into /tmp/up.dump and of vcan1 into /tmp/down.dump (pids in
# $up_candump, $down_candump), then `oegw run` into /tmp/gateway.log ($gw_pid) once it has bound vcan1.
run_recorded() {
  prepare_gateway_run "$@" || { fail "oegw check exit $?: $(cat /tmp/check.out)"; exit 1; }
  local bus pids=()
  for bus in vcan0:up vcan1:down; do
    start_candump "${bus%%:*}" "/tmp/${bus##*:}.dump" || fail "candump ${bus%%:*} did not start"
    pids+=("$candump_pid")
  done
  up_candump=${pids[0]} down_candump=${pids[1]}
  local bound
  bound=$(can_receivers vcan1)
  "$4" run "$3/oegw.yaml" >/tmp/gateway.log 2>&1 &
  gw_pid=$!
  wait_receivers vcan1 $((bound + 1)) 20 || fail "the gateway did not bind vcan1"
  echo "gateway started after $(elapsed) s"
}

# start_gateway_scenario OEGW RUN_DIR N SIM SIM_ARGS...: the start the `oegw run` scenarios with
# an `oegw-sim` cab share, after prepare_gateway_run: SIM (oegw-sim) with SIM_ARGS on vcan1 into
# /tmp/sim.log ($sim_pid) until it has bound vcan1, then `oegw run RUN_DIR/oegw.yaml` into
# /tmp/gateway.log ($gw_pid), then `oegw status` (status_wait.py, /tmp/status.json) until N
# sub-devices are operational: a PASS or FAIL line; returns 1 when they did not come up.
start_gateway_scenario() {
  local oegw=$1 run_dir=$2 n=$3 sim=$4 receivers
  shift 4
  receivers=$(can_receivers vcan1)
  "$sim" -i vcan1 "$@" >/tmp/sim.log 2>&1 &
  sim_pid=$!
  wait_receivers vcan1 $((receivers + 1)) 20 || fail "oegw-sim did not bind vcan1"
  "$oegw" run "$run_dir/oegw.yaml" >/tmp/gateway.log 2>&1 &
  gw_pid=$!
  local all_up="len(s[\"subdevices\"]) == $n and all(d[\"network_state\"] == \"operational\" for d in s[\"subdevices\"])"
  if "$PY" "$(dirname "${BASH_SOURCE[0]}")/status_wait.py" "$oegw" /tmp/status.json 120 "$all_up"; then
    pass "every sub-device operational after $(elapsed) s"
  else
    fail "sub-devices not operational: $(head -c 2000 /tmp/status.json)"
    return 1
  fi
}

# end_recorded: stop_gateway of run_recorded's `oegw run`, then both candumps stopped.
end_recorded() {
  stop_gateway "$gw_pid"
  for candump_pid in "$down_candump" "$up_candump"; do stop_candump; done
}

# wait_for FILE PATTERN TIMEOUT_S: until a line of FILE matches the extended regex PATTERN.
wait_for() {
  local i
  for ((i = 0; i < $3 * 20; i++)); do
    grep -Eq "$2" "$1" 2>/dev/null && return 0
    sleep 0.05
  done
  return 1
}

# count FILE PATTERN: its lines matching the extended regex PATTERN.
count() { grep -Ec "$2" "$1" 2>/dev/null; }

# wait_more FILE PATTERN BEFORE TIMEOUT_S: until FILE has more than BEFORE lines matching PATTERN.
wait_more() {
  local i
  for ((i = 0; i < $4 * 20; i++)); do
    (($(count "$1" "$2") > $3)) && return 0
    sleep 0.05
  done
  return 1
}
