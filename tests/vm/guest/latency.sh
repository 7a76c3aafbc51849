#!/bin/bash
# Guest test vm_latency: the figures of the real SocketCAN path, printed
# and never asserted against time (a slow machine must not fail it); it fails only if a path does
# not forward at all (or oegw run does not end cleanly).
#
# 1. Latency, side by side in one boot: `oegw run` (tests/fixtures/vm_syscalls.yaml: one elobau grip
#    on joystick.1, nothing published) translating the grip's TPDO #0 (191h on vcan1) to the
#    host's TPDO 1 (1A0h on vcan0), the floor (can_floor: a blocking read on vcan2 and write on
#    vcan3, nothing else; 191h forwarded unchanged) and a python3-can translator
#    (latency_translator.py, vcan4 -> vcan5; python `canopen` is not installable here) — each on
#    its own interfaces, so none wakes for another's frames. The grip itself is `oegw-sim
#    --commands` with its TPDOs off (`grip pdo off`: heartbeat and SDO go on, the gateway boots it
#    as usual), so every grip PDO on the wire is the probe's. One measurer for all (can_probe
#    paths): ping-pong, one frame in flight, latency = the kernel timestamps of the frame in and
#    the translation out, the paths sampled in turn (a random order each cycle) so the guest's
#    swings of speed fall on all of them alike. A fourth path, the floor as an event loop
#    (`can_floor ... loop`, vcan6 -> vcan7: epoll_wait, a clock reading, recvmmsg, sendmmsg),
#    splits oegw's cost above the floor into its system calls and its own work. oegw-sim drops the
#    probe's frames on its grip's TPDO COB-ID in the kernel (its acceptance filter): before, the
#    simulator woke for each and that cost fell on whichever path shared its bus. ROUNDS rounds of SAMPLES per path, every
#    translator started afresh each round; medians and p99 per round and over all rounds, and the
#    ratios to the floor. The python translator's frames are checked byte for byte against the
#    gateway's.
# 2. CPU at full load: can_probe pace sends the grip's TPDO #0 at RATE frames/s (8000: a 1 Mbit/s
#    bus at its physical maximum), every frame a change, to `oegw run` with nothing published
#    (vm_syscalls.yaml) for FLOOR_WINDOW_S, to `oegw run` with publishing on
#    (tests/fixtures/vm_latency.yaml: DDS on the loopback and LCM, every change) for WINDOW_S, and
#    to the floor for FLOOR_WINDOW_S: CPU % of one core (utime + stime of /proc/PID/stat, every
#    thread), VmRSS at the window's start and end, the guest's own busy %. Frames in and out are
#    the vcan interfaces' tx_packets counters (no candump beside: it would cost CPU itself); with
#    publishing on also the grip's frames the gateway read and its resets of the grip (`oegw status`).
# 3. The black box: `oegw run` with vm_syscalls.yaml, recording off and on (its `record` section
#    added, the ring on the guest's tmpfs, /run: its fdatasync costs nothing) in turn, twice
#    (off, on, off, on): the latency probe (SAMPLES each in the first pair) and part 2's CPU
#    window for FLOOR_WINDOW_S each; the ratios on/off of CPU per frame (per pair and over both),
#    median and p99 latency; the ring must hold segment files after it.
# The figures also go to $OEGW_VM_OUT/figures.txt (CTest keeps it in the build tree,
# tests/vm/vm_latency.out/; scripts/test-all.sh prints it).
# Args: OEGW OEGW_SIM SOURCE_DIR PROBE FLOOR [ROUNDS] [SAMPLES] [WINDOW_S] [RATE] [FLOOR_WINDOW_S]
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1
sim=$2
src=$3
probe=$4
floor=$5
rounds=${6:-4}
samples=${7:-1000}
window=${8:-40}
rate=${9:-8000}
floor_window=${10:-20}
dir=/run/oegw-latency
figures=${OEGW_VM_OUT:-/tmp}/figures.txt
: >"$figures"
report() { echo "$*" | tee -a "$figures"; }

prepare_gateway_run vm_syscalls.yaml "$src" "$dir/can" "$oegw" && pass "oegw check: vm_syscalls.yaml valid" ||
  { fail "oegw check: $(cat /tmp/check.out)"; exit 1; }
prepare_gateway_run vm_latency.yaml "$src" "$dir/publish" "$oegw" && pass "oegw check: vm_latency.yaml valid" ||
  { fail "oegw check: $(cat /tmp/check.out)"; exit 1; }
# Part 3's gateway: vm_syscalls.yaml with the black box on (its ring on the guest's tmpfs, /run).
prepare_gateway_run vm_syscalls.yaml "$src" "$dir/record" "$oegw" &&
  echo "record: { enabled: true, dir: $dir/record/ring, max_mib: 64, span_s: 600, segments: 8 }" >>"$dir/record/oegw.yaml" &&
  "$oegw" check --here "$dir/record/oegw.yaml" >/tmp/check.out 2>&1 && grep -q "^record: both buses' frames" /tmp/check.out &&
  pass "oegw check: vm_syscalls.yaml with recording on valid" || { fail "oegw check (recording): $(cat /tmp/check.out)"; exit 1; }
# DDS and LCM on the loopback: multicast routed to lo (the guest has no other interface).
ip link set lo multicast on && ip route add 224.0.0.0/4 dev lo

# The grip: heartbeat and SDO, its TPDOs off (the probe sends them).
mkfifo /tmp/sim.in
receivers=$(can_receivers vcan1)
"$sim" -i vcan1 --commands elobau-mfg:0x11:name=grip </tmp/sim.in >/tmp/sim.log 2>&1 &
exec 3>/tmp/sim.in
echo "grip pdo off" >&3
wait_receivers vcan1 $((receivers + 1)) 20 || { fail "the simulator did not bind vcan1"; exit 1; }

# start_gateway YAML: `oegw run` (pid in gw_pid) until its boot-up, then the host's part by
# cansend: TPDO 1 valid on 1A0h (1800h:01), 6423h TRUE, NMT start. The probe's warm-up proves it.
start_gateway() {
  local before
  before=$(can_receivers vcan0)
  timeout 60 candump -n 1 vcan0,720:7FF >/dev/null 2>&1 &
  local bootup=$!
  wait_receivers vcan0 $((before + 1))
  "$oegw" run "$1" >>/tmp/gateway.log 2>&1 &
  gw_pid=$!
  wait "$bootup" || fail "no boot-up of oegw run within 60 s"
  cansend vcan0 620#23001801A0010000
  cansend vcan0 620#2F23640001000000
  cansend vcan0 000#0120
}
stop_gateway() {
  kill -TERM "$gw_pid" 2>/dev/null
  wait "$gw_pid"
  local rc=$?
  ((rc == 0)) || fail "oegw run exit $rc after SIGTERM: $(tail -5 /tmp/gateway.log)"
}
# start_translator IF CMD...: in the background (pid in tr_pid) until it listens on IF.
start_translator() {
  local before dev=$1
  shift
  before=$(can_receivers "$dev")
  "$@" >>/tmp/translator.log 2>&1 &
  tr_pid=$!
  wait_receivers "$dev" $((before + 1)) 60 || fail "$1 did not bind $dev: $(tail -3 /tmp/translator.log)"
}
stop_translator() { kill -TERM "$tr_pid" 2>/dev/null; wait "$tr_pid" 2>/dev/null; }

# probe NAME OUT_ID EXPECT SAMPLES: the latency probe on the gateway alone (part 2's check that it
# translates), its samples in /tmp/lat.NAME.
probe() {
  local out rc
  out=$("$probe" latency vcan1 0x191 vcan0 "$2" "$3" "$4" "/tmp/lat.$1")
  rc=$?
  report "  $(printf '%-6s' "$1") $out"
  ((rc == 0)) || fail "$1 did not forward (probe exit $rc)"
}

# Each path on its own pair of interfaces, so no translator wakes for another's frames: the
# gateway vcan1 -> vcan0 (its grip and host), the floor vcan2 -> vcan3, python vcan4 -> vcan5,
# the floor as an event loop (can_floor ... loop) vcan6 -> vcan7.
for d in vcan2 vcan3 vcan4 vcan5 vcan6 vcan7; do
  ip link add dev $d type vcan && ip link set $d up || { fail "ip link add $d type vcan"; exit 1; }
done
report "vm_latency: the SocketCAN path in a TCG VM (qemu, 1 vCPU), kernel $(uname -r)"
report "1. latency, grip TPDO 191h -> its translation, kernel timestamps, one frame in flight, the four"
report "   paths side by side and sampled in turn (can_probe paths), $rounds rounds x $samples samples per"
report "   path, every translator started afresh each round (µs)"
for ((r = 1; r <= rounds; r++)); do
  start_translator vcan2 "$floor" vcan2 vcan3 0x191
  floor_pid=$tr_pid
  start_translator vcan4 "$PY" "$here/latency_translator.py" vcan4 vcan5
  python_pid=$tr_pid
  start_translator vcan6 "$floor" vcan6 vcan7 0x191 loop
  loop_pid=$tr_pid
  start_gateway "$dir/can/oegw.yaml"
  out=$("$probe" paths "$samples" 2000 30 "/tmp/lat.$r" oegw:vcan1:0x191:vcan0:0x1A0:cia852 \
    floor:vcan2:0x191:vcan3:0x191:copy python:vcan4:0x191:vcan5:0x1A0:cia852 floor-loop:vcan6:0x191:vcan7:0x191:copy)
  rc=$?
  while read -r line; do report "  round $r $line"; done <<<"$out"
  ((rc == 0)) || fail "a path did not forward (round $r, probe exit $rc)"
  stop_gateway
  tr_pid=$floor_pid stop_translator
  tr_pid=$python_pid stop_translator
  tr_pid=$loop_pid stop_translator
done

# percentile P FILE...: nearest rank over the answered samples of the files.
percentile() {
  local p=$1
  shift
  awk '$3 != "miss" { print $3 }' "$@" | sort -n |
    awk -v p="$p" '{ v[NR] = $1 } END { if (!NR) { print "-"; exit } i = int((NR * p + 99) / 100); print v[i < 1 ? 1 : i] }'
}
ratio() { awk -v a="$1" -v b="$2" 'BEGIN { if (a == "-" || b == "-" || b == 0) print "-"; else printf "%.2f", a / b }'; }
report "   each round's ratio of oegw to the floor (median, p99):$(for ((r = 1; r <= rounds; r++)); do
  printf ' %s×/%s×' "$(ratio "$(percentile 50 /tmp/lat.$r.oegw)" "$(percentile 50 /tmp/lat.$r.floor)")" \
    "$(ratio "$(percentile 99 /tmp/lat.$r.oegw)" "$(percentile 99 /tmp/lat.$r.floor)")"
done)"
fmed=$(percentile 50 /tmp/lat.[0-9]*.floor)
fp99=$(percentile 99 /tmp/lat.[0-9]*.floor)
report "   over all rounds (µs)       median      p99   ratio to the floor (median, p99)   answered"
for p in oegw floor python floor-loop; do
  med=$(percentile 50 /tmp/lat.[0-9]*.$p)
  p99=$(percentile 99 /tmp/lat.[0-9]*.$p)
  n=$(cat /tmp/lat.[0-9]*.$p | awk '$3 != "miss"' | wc -l)
  report "$(printf '   %-24s %9s %9s   %6s× %6s×   %30s' "$p" "$med" "$p99" "$(ratio "$med" "$fmed")" "$(ratio "$p99" "$fp99")" "$n/$((rounds * samples))")"
done
# The python translator does what the gateway does: the same output for every input both saw.
cat /tmp/lat.[0-9]*.oegw >/tmp/lat.oegw.all
cat /tmp/lat.[0-9]*.python >/tmp/lat.python.all
same=$(awk 'FNR == 1 { f++ } f == 1 && $3 != "miss" { o[$1] = $2; next } $3 != "miss" && ($1 in o) { n++; if (o[$1] != $2) { bad++; if (bad < 4) print "  " $1 ": oegw " o[$1] ", python " $2 > "/tmp/lat.diff" } }
  END { print n + 0, bad + 0 }' /tmp/lat.oegw.all /tmp/lat.python.all)
read -r n bad <<<"$same"
((n > 0 && bad == 0)) && pass "the python translator's TPDO 1 equals the gateway's for all $n inputs both answered" ||
  fail "the python translator differs from the gateway for $bad of $n inputs: $(cat /tmp/lat.diff 2>/dev/null)"
floor_bad=$(cat /tmp/lat.[0-9]*.floor /tmp/lat.[0-9]*.floor-loop | awk '$3 != "miss" && $1 != $2' | wc -l)
((floor_bad == 0)) && pass "the floor (both kinds) forwarded every frame unchanged" || fail "$floor_bad frames changed by the floor"

# grip_status: "FRAMES RESETS DROPPED FAULT" of the grip (DROPPED: vcan1's frames the kernel dropped) as `oegw status --json` shows them (control on).
grip_status() {
  "$oegw" status --json 2>/dev/null | "$PY" -c 'import json, sys
s = json.load(sys.stdin)["status"]
g = s["subdevices"][0]
print(g["counters"]["frames"], g["counters"]["gateway_resets"], s["downstream"].get("bus", {}).get("rx_dropped", 0),
      g.get("fault") or "none")' 2>/dev/null || echo "0 0 0 unknown"
}
# cpu_window NAME PID SECONDS [status]: the pacer at RATE for a settling 3 s plus SECONDS; CPU %,
# frames, RSS; with "status", the grip's frames read and resets by the gateway's own count.
ticks() { awk '{ print $14 + $15 }' "/proc/$1/stat"; }
txp() { cat "/sys/class/net/$1/statistics/tx_packets"; }
idle() { awk '/^cpu / { print $5 + $6, $2 + $3 + $4 + $5 + $6 + $7 + $8 + $9 }' /proc/stat; }
rss() { awk '/^VmRSS/ { print $2 }' "/proc/$1/status"; }
declare -A window_cpu window_out  # CPU % and frames/s out of each window, by name
cpu_window() {
  local name=$1 pid=$2 secs=$3
  "$probe" pace vcan1 0x191 "$rate" $((secs + 4)) >"/tmp/pace.$name" 2>&1 &
  local pacer=$!
  sleep 3
  local t0 c0 in0 out0 rss0 i0
  t0=$(date +%s.%N) c0=$(ticks "$pid") in0=$(txp vcan1) out0=$(txp vcan0) rss0=$(rss "$pid") i0=$(idle)
  # VmRSS every tenth of the window: flat, or still growing at the end?
  local step=$(((secs + 9) / 10)) left=$secs trace=""
  while ((left > 0)); do
    sleep $((left < step ? left : step))
    left=$((left - step))
    trace+=" $(rss "$pid")"
  done
  local t1 c1 in1 out1 rss1 i1
  t1=$(date +%s.%N) c1=$(ticks "$pid") in1=$(txp vcan1) out1=$(txp vcan0) rss1=$(rss "$pid") i1=$(idle)
  # The gateway's own count, after the window (python's start costs CPU): from the settled start.
  local st0 st1
  [[ ${4:-} == status ]] && st0=$gw_status && st1=$(grip_status)
  wait "$pacer"
  local hz
  hz=$(getconf CLK_TCK)
  local cpu fin fout busy figures_line
  figures_line=$(awk -v t0="$t0" -v t1="$t1" -v c="$((c1 - c0))" -v hz="$hz" -v i="$((in1 - in0))" \
    -v o="$((out1 - out0))" -v i0="$i0" -v i1="$i1" 'BEGIN { d = t1 - t0; split(i0, a, " "); split(i1, b, " ");
      printf "%.1f %.0f %.0f %.0f\n", 100 * c / hz / d, i / d, o / d, 100 * (1 - (b[1] - a[1]) / (b[2] - a[2])) }')
  read -r cpu fin fout busy <<<"$figures_line"
  window_cpu[$name]=$cpu window_out[$name]=$fout
  report "$(printf '   %-8s %5s %% of one core over %s s at %s frames/s in, %s frames/s out (guest CPU %s %% busy); VmRSS %s kB at the start, %s kB at the end' \
    "$name" "$cpu" "$secs" "$fin" "$fout" "$busy" "$rss0" "$rss1")"
  report "            VmRSS (kB) every $step s:$trace"
  report "            pacer: $(cat "/tmp/pace.$name")"
  if [[ ${4:-} == status ]]; then
    local f0 r0 d0 f1 r1 d1 fault
    read -r f0 r0 d0 _ <<<"$st0"
    read -r f1 r1 d1 fault <<<"$st1"
    report "            oegw status: $(((f1 - f0) / (secs + 3))) grip frames/s read, $(((d1 - d0) / (secs + 3))) frames/s dropped by the kernel before the gateway read them, the grip reset $((r1 - r0)) times (NMT, heartbeat or PDOs lost) from the pacer's start to the window's end; fault now: $fault"
  fi
  ((out1 - out0 > 10 + 6 * secs)) && pass "$name forwarded under full load ($((out1 - out0)) frames out)" ||
    fail "$name forwarded nothing under full load ($((out1 - out0)) frames out on vcan0)"
}

report "2. CPU at full load: grip TPDO 191h at $rate frames/s on vcan1, every frame a change (can_probe pace)"
start_gateway "$dir/can/oegw.yaml"
probe oegw-can 0x1A0 cia852 50
cpu_window "oegw run, nothing published" "$gw_pid" "$floor_window"
stop_gateway
start_gateway "$dir/publish/oegw.yaml"
probe oegw-publishing 0x1A0 cia852 50
gw_status=$(grip_status)
cpu_window "oegw run, publishing on" "$gw_pid" "$window" status
stop_gateway
start_translator vcan1 "$floor" vcan1 vcan0 0x191
cpu_window floor "$tr_pid" "$floor_window"
stop_translator

report "3. the black box: recording on (record.enabled, the ring on the guest's tmpfs) against off, in turn"
# CPU per translated frame: the guest may not keep up at RATE (the kernel drops what the gateway
# reads too late), so the windows' CPU % alone compare different amounts of work.
per_frame() { awk -v c="$1" -v o="$2" 'BEGIN { if (o > 0) printf "%.3f", 1e4 * c / o; else print "-" }'; }
# Off, on, off, on: each pair's windows a minute apart at most, so a swing of the guest's speed
# (a TCG guest on a shared host) falls on both alike; the ratio is over both pairs.
on_sum=0 off_sum=0
for pair in 1 2; do
  start_gateway "$dir/can/oegw.yaml"
  if ((pair == 1)); then probe rec-off 0x1A0 cia852 "$samples"; else probe rec-off-2 0x1A0 cia852 50; fi
  cpu_window "oegw run, recording off ($pair)" "$gw_pid" "$floor_window"
  stop_gateway
  start_gateway "$dir/record/oegw.yaml"
  if ((pair == 1)); then probe rec-on 0x1A0 cia852 "$samples"; else probe rec-on-2 0x1A0 cia852 50; fi
  cpu_window "oegw run, recording on ($pair)" "$gw_pid" "$floor_window"
  "$oegw" status >/tmp/record-status.txt 2>&1 || true
  stop_gateway
  on=$(per_frame "${window_cpu[oegw run, recording on ($pair)]}" "${window_out[oegw run, recording on ($pair)]}")
  off=$(per_frame "${window_cpu[oegw run, recording off ($pair)]}" "${window_out[oegw run, recording off ($pair)]}")
  report "   pair $pair: CPU per translated frame (µs of one core): recording on $on, off $off: $(ratio "$on" "$off")×"
  # A window that forwarded nothing ("-", failed above) counts in neither sum.
  if [[ $on != - && $off != - ]]; then
    on_sum=$(awk -v a="$on_sum" -v b="$on" 'BEGIN { print a + b }')
    off_sum=$(awk -v a="$off_sum" -v b="$off" 'BEGIN { print a + b }')
  fi
done
report "   recording on / off: CPU per frame $(ratio "$on_sum" "$off_sum")× (both pairs), latency median $(ratio "$(percentile 50 /tmp/lat.rec-on)" "$(percentile 50 /tmp/lat.rec-off)")×, p99 $(ratio "$(percentile 99 /tmp/lat.rec-on)" "$(percentile 99 /tmp/lat.rec-off)")×"
segments=$(find "$dir/record/ring" -maxdepth 1 -name '*.log' 2>/dev/null | wc -l)
bytes=$(du -sk "$dir/record/ring" 2>/dev/null | awk '{ print $1 }')
report "   the ring after the run: $segments segment files, ${bytes:-0} KiB"
((segments > 0)) && pass "recording on: the ring holds the run ($segments segments, ${bytes:-0} KiB)" ||
  fail "recording on: no segment in $dir/record/ring: $(ls -la "$dir/record/ring" 2>&1 | head -5)"

cp /tmp/gateway.log /tmp/sim.log "${OEGW_VM_OUT:-/tmp}/" 2>/dev/null  # for a look afterwards
echo "$passes passed, $fails failed"
((fails == 0))
