#!/bin/bash
# Guest test: a bounded soak of `oegw run`. config/demo.yaml's cab (vm_gateway.yaml) as
# `oegw-sim --motion` processes on vcan1, every device sending; a python3-can host on vcan0
# (soak_host.py) keeping SDO and NMT traffic going for SECONDS and checking every answer; the
# grip's simulator killed every 25 s and restarted 4 s later (a sub-device reboot); cangen (can-
# utils) mixing random frames into both buses. Judged from outside: candump on vcan0 and
# soak_check.py (TPDO1 never missing while operational, neutral while the grip is dead), the
# host's own checks, the gateway's resident memory sampled from /proc (flat after warm-up), and a
# clean exit on SIGTERM.
# Args: OEGW OEGW_SIM SOURCE_DIR [SECONDS]
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1
sim=$2
src=$3
seconds=${4:-120}
dir=/run/oegw-soak

prepare_gateway_run vm_gateway.yaml "$src" "$dir" "$oegw"
rc=$?
((rc == 0)) && pass "oegw check: valid" || fail "oegw check exit $rc: $(cat /tmp/check.out)"
dt=$(sed -n 's/.*1000h device type = \([0-9A-F]\{8\}\)h.*/\1/p' /tmp/check.out)

start_candump vcan0 /tmp/soak-up.dump || fail "candump vcan0 did not start"
start_host /tmp/soak-host.log /tmp/soak.host-ready 30 \
  "$PY" "$here/soak_host.py" vcan0 /tmp/soak.host-ready "${dt:-0}" "$seconds" /tmp/soak.windows
gateway_cab "$src"
start_grip() {
  start_sim "$sim" /tmp/soak-grip.log --motion "${devices[0]}"
  grip_pid=$sim_pid
}
start_grip
start_sim "$sim" /tmp/soak-others.log --motion "${devices[@]:1}"
others_pid=$sim_pid
wait_sims
start_oegw_run "$oegw" "$dir/oegw.yaml" /tmp/soak-gateway.log
start_time=$(date +%s.%N)
# Random frames: an unconfigured node's TPDO1 downstream (counted, ignored), LSS-answer frames
# upstream (the gateway is an LSS slave: it never takes 7E4h), random lengths and data.
cangen vcan1 -I 1E0 -L r -D r -g 20 >/dev/null 2>&1 &
gen1=$!
cangen vcan0 -I 7E4 -L r -D r -g 50 >/dev/null 2>&1 &
gen2=$!

: >/tmp/soak.kills
rss=()
next_kill=25
next_sample=0
while kill -0 "$host_pid" 2>/dev/null; do
  now=$(awk -v a="$start_time" -v b="$(date +%s.%N)" 'BEGIN { printf "%d", b - a }')
  if ((now >= next_sample)); then
    r=$(awk '/^VmRSS:/ { print $2 }' "/proc/$gw_pid/status" 2>/dev/null)
    [[ -n $r ]] && rss+=("$now:$r")
    next_sample=$((next_sample + 5))
  fi
  if ((now >= next_kill && now + 10 < seconds)); then
    k=$(date +%s.%N)
    kill -KILL "$grip_pid"
    wait "$grip_pid" 2>/dev/null
    sleep 4
    start_grip
    echo "$k $(date +%s.%N)" >>/tmp/soak.kills
    next_kill=$((next_kill + 25))
  fi
  kill -0 "$gw_pid" 2>/dev/null || { fail "oegw run died during the soak"; break; }
  sleep 0.2
done
end_time=$(date +%s.%N)
wait "$host_pid"
host_rc=$?
sed 's/^/    host: /' /tmp/soak-host.log | tail -15
((host_rc == 0)) && pass "python3-can host: every SDO answer right" || fail "python3-can host exit $host_rc"
kill "$gen1" "$gen2" 2>/dev/null
wait "$gen1" "$gen2" 2>/dev/null
kill -TERM "$gw_pid"
wait "$gw_pid"
rc=$?
((rc == 0)) && pass "SIGTERM stops oegw run cleanly after the soak (exit 0)" || fail "oegw run exit $rc after SIGTERM"
kill -TERM "$others_pid" "$grip_pid" 2>/dev/null
wait "$others_pid" "$grip_pid" 2>/dev/null
stop_candump

echo "grip losses: $(wc -l </tmp/soak.kills)"
if out=$("$PY" "$here/soak_check.py" /tmp/soak-up.dump /tmp/soak.windows /tmp/soak.kills \
  "$(awk -v a="$start_time" 'BEGIN { printf "%.3f", a + 10 }')" "$end_time"); then
  pass "candump vcan0: $out"
else
  fail "candump vcan0: $out"
fi
# Resident memory: the samples after 30 s (boot and warm-up done) grow by at most 1 MiB.
echo "resident memory (s:KiB): ${rss[*]}"
base=""
max=0
for s in "${rss[@]}"; do
  t=${s%%:*} v=${s##*:}
  ((t < 30)) && continue
  [[ -z $base ]] && base=$v
  ((v > max)) && max=$v
done
if [[ -n $base ]] && ((max - base <= 1024)); then
  pass "resident memory flat: $base KiB at 30 s, at most $max KiB after"
else
  fail "resident memory grew: ${base:-?} KiB at 30 s, $max KiB later"
fi
bad=$(grep -c -E '^(critical|error):' /tmp/soak-gateway.log)
echo "gateway log: $(wc -l </tmp/soak-gateway.log) lines, $bad error lines"
grep -E '^(critical|error):' /tmp/soak-gateway.log | head -5 | sed 's/^/    /'
cp /tmp/soak-up.dump /tmp/soak-gateway.log /tmp/soak-host.log /tmp/soak.kills "${OEGW_VM_OUT:-/tmp}/" 2>/dev/null
echo "total $(elapsed) s; $passes passed, $fails failed"
((fails == 0))
