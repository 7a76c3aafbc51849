#!/bin/bash
# Guest test (vm_starts): `oegw run` with the cab of tests/fixtures/vm_corners.yaml (freshness
# deadlines left to the drivers: 3 x each event timer raised to the family's 200 ms floor,
# docs/reference/drivers.md#freshness-floors) started COUNT times, each with a fresh `oegw-sim` cab
# under --motion, until every sub-device is operational (`oegw status --json`), then left running
# HOLD_S seconds and stopped with SIGTERM. Figures, one line per start: the seconds to every
# sub-device operational, the stale faults of its log ("<name>: fault (<signal> stale ...") and
# the guest's longest stall meanwhile (the longest gap between two 10 ms waits of a shell loop, from
# the gateway's start to its stop): a stale fault with a stall near the floor is the guest's, one
# without is the gateway's. A TCG guest on a loaded host may stall longer than a floor rides out,
# so stale faults are reported, not asserted; the test fails when a start does not bring every sub-device up or
# `oegw run` does not exit 0. The totals go to $OEGW_VM_OUT/starts.txt as well.
# Args: OEGW OEGW_SIM SOURCE_DIR [COUNT 15] [HOLD_S 5]
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1 sim=$2 src=$3
count=${4:-15}
hold=${5:-5}
dir=/run/oegw-starts
out=${OEGW_VM_OUT:-/tmp}

prepare_gateway_run vm_corners.yaml "$src" "$dir" "$oegw" || { fail "oegw check: $(cat /tmp/check.out)"; exit 1; }
corners_cab "$src"

# stall_probe FILE: until killed, the longest gap in ms between two 10 ms waits so far, in FILE.
stall_probe() {
  local fd last now max=0
  exec {fd}<>/tmp/probe.fifo  # nothing writes it: each read waits its 10 ms time-out
  last=${EPOCHREALTIME/./}
  while :; do
    read -r -t 0.01 -u "$fd" _
    now=${EPOCHREALTIME/./}
    if ((now - last > max)); then
      max=$((now - last))
      echo $((max / 1000)) >"$1"
    fi
    last=$now
  done
}
mkfifo /tmp/probe.fifo

stale_total=0
stall_max=0
report=""
for ((i = 1; i <= count; i++)); do
  rm -f "$dir"/*.store "$dir"/*.store.lss
  t=$(date +%s.%N)
  echo 0 >/tmp/stall.ms
  stall_probe /tmp/stall.ms &
  probe_pid=$!
  : >/tmp/gateway.log
  start_oegw_run --bound "$oegw" "$dir/oegw.yaml" || fail "start $i: the gateway did not bind vcan1"
  start_sim "$sim" /tmp/sim.log --motion "${devices[@]}"
  if "$PY" "$here/status_wait.py" "$oegw" /tmp/status.json 90 \
    'all(d["state"] == "operational" for d in s["subdevices"]) and len(s["subdevices"]) == 4'; then
    up=$(awk -v a="$t" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
    sleep "$hold"
    stale=$(grep -cE ': fault \([^ ]+ stale' /tmp/gateway.log)
    stale_total=$((stale_total + stale))
    stall=$(cat /tmp/stall.ms)
    ((stall > stall_max)) && stall_max=$stall
    line="start $i: every sub-device operational after $up s; stale faults $stale; longest guest stall $stall ms"
    pass "$line"
    report+="$line"$'\n'
    ((stale > 0)) && grep -E ': fault \([^ ]+ stale' /tmp/gateway.log | sed 's/^/    /'
  else
    fail "start $i: not every sub-device operational within 90 s: $(cut -c1-300 /tmp/status.json)"
    grep -v 'debug:' /tmp/gateway.log | tail -20 | sed 's/^/    /'
  fi
  stop_gateway "$gw_pid"
  kill "$probe_pid" 2>/dev/null
  wait "$probe_pid" 2>/dev/null
  kill -TERM "$sim_pid" 2>/dev/null
  wait "$sim_pid" 2>/dev/null
done
summary="$count starts, stale faults in all: $stale_total; longest guest stall $stall_max ms"
echo "$summary"
printf '%s%s\n' "$report" "$summary" >"$out/starts.txt" 2>/dev/null
echo "total $(elapsed) s; $passes passed, $fails failed"
((fails == 0))
