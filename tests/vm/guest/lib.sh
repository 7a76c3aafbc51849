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
  start_oegw_run --bound "$4" "$3/oegw.yaml" || fail "the gateway did not bind vcan1"
  echo "gateway started after $(elapsed) s"
}

# gateway_cab SRC: the devices of tests/fixtures/vm_gateway.yaml as oegw-sim arguments, in the
# array $devices: right_grip (elobau 11h), left_grip (MCB-402 03h), pedal (CiA 401 30h,
# generic_pedal.eds of source tree SRC), seat_knob (Novotechnik 7Fh), cluster (CiA 401 31h,
# button_cluster.eds). A script adds its own settings to an element (`"${devices[4]},store=FILE"`).
gateway_cab() {
  devices=(elobau-mfg:0x11:name=right_grip mcb402:0x03:name=left_grip
    "cia401:0x30:name=pedal,eds=$1/subdevices/eds/generic_pedal.eds" novotechnik-406:0x7F:name=seat_knob
    "cia401:0x31:name=cluster,eds=$1/subdevices/eds/button_cluster.eds")
}

# corners_cab SRC: the devices of tests/fixtures/vm_corners.yaml at the corners of their documents
# opposite to the simulators' defaults (docs/design/device-documents.md), as oegw-sim arguments in
# the array $devices: right_grip (elobau 11h, TPDOs on the event timer only, buttons 255), left_grip
# (MCB-402 03h), seat_knob (Novotechnik 7Fh), pedal (CiA 401 30h).
corners_cab() {
  devices=("elobau-mfg:0x11:name=right_grip,tpdo=timer,buttons=255"
    "mcb402:0x03:name=left_grip,clear_after_break=none,power_on_1001h=11h"
    "novotechnik-406:0x7F:name=seat_knob,error_register_size=2,emcy_behaviour=3,has_6020h=no,work_area_emcy=enum"
    "cia401:0x30:name=pedal,eds=$1/subdevices/eds/generic_pedal.eds")
}

# start_sim SIM LOG SIM_ARGS...: one `SIM -i vcan1 SIM_ARGS` process (oegw-sim) in the background,
# its pid in $sim_pid, its output appended to LOG (a device started again keeps one log). With
# --commands among SIM_ARGS it reads its commands from fd 3 (the FIFO the script opened read-write
# with `exec 3<>FIFO`, so that it never sees end of file), otherwise from /dev/null. wait_sims
# waits until the processes started since the last wait_sims have bound vcan1.
sims_pending=0
start_sim() {
  local sim=$1 log=$2
  shift 2
  ((sims_pending++ == 0)) && sims_before=$(can_receivers vcan1)
  if [[ " $* " == *" --commands "* ]]; then
    "$sim" -i vcan1 "$@" <&3 >>"$log" 2>&1 &
  else
    "$sim" -i vcan1 "$@" </dev/null >>"$log" 2>&1 &
  fi
  sim_pid=$!
}

# wait_sims: until every start_sim process since the last wait_sims has bound vcan1 (one socket
# each); a FAIL line and status 1 when they have not within 20 s.
wait_sims() {
  local n=$sims_pending
  sims_pending=0
  ((n > 0)) || return 0
  wait_receivers vcan1 $((sims_before + n)) 20 || { fail "oegw-sim did not bind vcan1"; return 1; }
}

# start_oegw_run [--bound] OEGW CONFIG [LOG]: `OEGW run CONFIG` in the background, its pid in
# $gw_pid, its output appended to LOG (default /tmp/gateway.log; a restart keeps one log). The
# environment of the call is its own (`NOTIFY_SOCKET=... start_oegw_run ...`). With --bound it
# returns once the gateway has bound vcan1 (status 1 when not within 20 s).
start_oegw_run() {
  local bound=0 receivers
  [[ $1 == --bound ]] && { bound=1; shift; }
  receivers=$(can_receivers vcan1)
  "$1" run "$2" >>"${3:-/tmp/gateway.log}" 2>&1 &
  gw_pid=$!
  ((bound == 0)) || wait_receivers vcan1 $((receivers + 1)) 20
}

# start_gateway_scenario OEGW RUN_DIR N SIM SIM_ARGS...: the start the `oegw run` scenarios with
# an `oegw-sim` cab share, after prepare_gateway_run: SIM (oegw-sim) with SIM_ARGS on vcan1 into
# /tmp/sim.log ($sim_pid) until it has bound vcan1 (start_sim), then `oegw run RUN_DIR/oegw.yaml`
# into /tmp/gateway.log ($gw_pid), then wait_operational N.
start_gateway_scenario() {
  local oegw=$1 run_dir=$2 n=$3 sim=$4
  shift 4
  start_sim "$sim" /tmp/sim.log "$@"
  wait_sims
  start_oegw_run "$oegw" "$run_dir/oegw.yaml"
  wait_operational "$oegw" "$n"
}

# wait_operational OEGW N: `oegw status` (status_wait.py, /tmp/status.json) until N sub-devices
# are operational (their network state): a PASS or FAIL line; returns 1 when they did not come up
# within 120 s.
wait_operational() {
  local all_up="len(s[\"subdevices\"]) == $2 and all(d[\"network_state\"] == \"operational\" for d in s[\"subdevices\"])"
  if "$PY" "$(dirname "${BASH_SOURCE[0]}")/status_wait.py" "$1" /tmp/status.json 120 "$all_up"; then
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

# wait_file FILE TIMEOUT_S: until FILE exists; status 1 when it does not within TIMEOUT_S.
wait_file() {
  local i
  for ((i = 0; i < $2 * 20; i++)); do
    [[ -e $1 ]] && return 0
    sleep 0.05
  done
  [[ -e $1 ]]
}

# start_host LOG READY TIMEOUT_S CMD...: a host of the scenario (a python3-can program, started
# before what it waits for) in the background, its output into LOG, its pid in $host_pid, until
# it has created READY (once its buses are open): "host up after N s", or a FAIL line and status 1
# when it has not within TIMEOUT_S.
start_host() {
  local log=$1 ready=$2 t=$3
  shift 3
  "$@" >"$log" 2>&1 &
  host_pid=$!
  wait_file "$ready" "$t" || { fail "python3-can host did not come up"; return 1; }
  echo "host up after $(elapsed) s"
}

# follow_host LOG: start_host's host until it exits, its lines echoed ("    host: ...") as they
# come; its exit status in $host_rc.
follow_host() {
  tail -n +1 -f "$1" --pid "$host_pid" | sed -u 's/^/    host: /' &
  local tail_pid=$!
  wait "$host_pid"
  host_rc=$?
  wait "$tail_pid" 2>/dev/null
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
