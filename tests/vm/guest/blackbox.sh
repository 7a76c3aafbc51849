#!/bin/bash
# Guest test (vm_blackbox): the black box outside in (docs/guides/black-box.md). `oegw run`
# records tests/fixtures/vm_gateway.yaml's cab (its `record` section added) through a scripted
# incident on real SocketCAN — the grip's cable pulled (`right_grip silent on`), an MCB-402 cable
# break (EMCY 3120h), the host's heartbeat lost (EMCY 8130h), the grip rebooted — and is killed
# with SIGKILL. Then:
#   1 `oegw replay` of the recording: exact, zero divergence; also of the ring without its start,
#     from its first segment's state;
#   2 the timeline and the plot (OEGW_VM_OUT/blackbox.html; vm_blackbox_plot loads it in
#     chromium on the host) show the incident;
#   3 the recording with one edited frame diverges right after that frame;
#   4 a full disk (record.dir on a 256 KiB tmpfs) loses recording, never bus service: the
#     gateway's heartbeat and TPDO 1 go on on candump, `oegw status` reports ENOSPC, the files
#     read back.
# The devices: the elobau grip and the MCB-402 in one `oegw-sim --commands` process fed from a
# FIFO, the pedal, encoder and cluster under --motion. The host: cansend. No wall-clock bound is
# asserted: the replay is judged by its own comparison, the bus by the frames' order on candump.
# Args: OEGW OEGW_SIM SOURCE_DIR
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1
sim=$2
src=$3
out=${OEGW_VM_OUT:-/tmp}
dir=/run/oegw-blackbox
rec=$dir/record

prepare_gateway_run vm_gateway.yaml "$src" "$dir" "$oegw"
cat >>"$dir/oegw.yaml" <<EOF
record: { enabled: true, dir: $rec, max_mib: 64, span_s: 600, segments: 8 }
EOF
"$oegw" check --here "$dir/oegw.yaml" >/tmp/check.out 2>&1 || { fail "oegw check: $(cat /tmp/check.out)"; exit 1; }
grep -q "^record: both buses' frames" /tmp/check.out && pass "oegw check prints what it records" ||
  fail "oegw check: no record line"

start_candump vcan0 /tmp/up.dump || fail "candump vcan0 did not start"
up_candump=$candump_pid
start_candump vcan1 /tmp/down.dump || fail "candump vcan1 did not start"

mkfifo /tmp/cab.cmd
exec 3<>/tmp/cab.cmd
gateway_cab "$src"
start_sim "$sim" /tmp/sim-cmd.log --commands "${devices[@]:0:2}"
cmd_pid=$sim_pid
start_sim "$sim" /tmp/sim-motion.log --motion "${devices[@]:2}"
motion_pid=$sim_pid
wait_sims

start_run() { start_oegw_run "$oegw" "$dir/oegw.yaml"; }  # the gateway on $dir/oegw.yaml; its pid in $gw_pid
expect_status() {  # TIMEOUT_S PY_EXPR WHAT
  if "$PY" "$here/status_wait.py" "$oegw" /tmp/status.json "$1" "$2"; then pass "oegw status: $3"; else
    fail "oegw status: $3: $(head -c 1500 /tmp/status.json)"
  fi
}
all_up='all(d["state"] == "operational" for d in s["subdevices"])'
# The host: TPDO 1 on 1A0h, 6423h TRUE, with `watched` its heartbeat (701h) consumed in 1000 ms
# (1016h:01; a loss takes the gateway to pre-operational, CiA 301 1029h), NMT start.
host_starts() {
  local watch=""
  [[ ${1:-} == watched ]] && watch=620#23161001E8030100
  for f in 620#23001801A0010000 620#2F23640001000000 $watch 000#0120; do
    cansend vcan0 "$f"
    sleep 0.2
  done
}
touch /tmp/hb.on
( while true; do [[ -e /tmp/hb.on ]] && cansend vcan0 701#05; sleep 0.2; done ) &
hb_pid=$!
cab() { echo "$1" >&3; sleep "${2:-0}"; }
# replay_into RECORDING ERR [options...]: `oegw replay` of RECORDING with the mapping file, its
# result (standard error) in ERR and printed, its exit status in $rc; standard output as given.
replay_into() {
  local where=$1 err=$2
  shift 2
  "$oegw" replay "$where" --config "$dir/oegw.yaml" "$@" 2>"$err"
  rc=$?
  sed 's/^/    replay: /' "$err" | head -8
}

start_run
expect_status 90 "$all_up and s['record']['recording']" "every sub-device operational, recording on"
host_starts watched
cab "right_grip x 50" 2
cab "right_grip silent on" 2.5  # the cable pulled: no heartbeat, no PDO
cab "right_grip silent off"
expect_status 90 "$all_up" "the grip back after its cable was plugged in"
cab "right_grip x 0" 1
cab "left_grip cable_break 2 on" 1.5
cab "left_grip cable_break 2 off" 1.5
rm /tmp/hb.on
sleep 2.5  # the host's heartbeat lost: EMCY 8130h
touch /tmp/hb.on
cansend vcan0 000#0120
sleep 1
cab "right_grip reboot" 1
expect_status 90 "$all_up" "the grip back after its reboot"
cab "right_grip x -40" 2
# Keeping the window: the control command, then the signal.
"$oegw" record keep >/tmp/keep.out 2>&1
rc=$?
kept=$(sed -n 's/^kept: \(.*\) ([0-9]* segments)$/\1/p' /tmp/keep.out)
((rc == 0)) && [[ -d $kept ]] && pass "oegw record keep: $(cat /tmp/keep.out)" || fail "oegw record keep: exit $rc: $(cat /tmp/keep.out)"
kill -USR1 "$gw_pid"
for ((i = 0; i < 200; i++)); do grep -q 'record: SIGUSR1: the window kept in' /tmp/gateway.log && break; sleep 0.1; done
grep -q 'record: SIGUSR1: the window kept in' /tmp/gateway.log && pass "SIGUSR1 kept a window: $(grep -o 'kept in .*' /tmp/gateway.log)" ||
  fail "SIGUSR1: no window kept"
cab "right_grip x 20" 1
"$oegw" status >/tmp/status.txt 2>&1
grep -q '^recording: on, ' /tmp/status.txt && grep -q '^  kept: ' /tmp/status.txt &&
  pass "oegw status shows the recording and the kept windows" ||
  fail "oegw status: $(grep -i -A3 recording /tmp/status.txt)"
kill -KILL "$gw_pid"
wait "$gw_pid" 2>/dev/null
echo "gateway killed (SIGKILL) after $(elapsed) s"

# 1: the replay, exact.
ls -l "$rec" | sed 's/^/    /'
replay_into "$rec" /tmp/replay.err --plot "$out/blackbox.html" >"$out/timeline.txt"
if ((rc == 0)) && grep -q 'exact replay, .* no divergence$' /tmp/replay.err; then
  pass "oegw replay: exact, no divergence ($(grep -o '[0-9]* outputs and [0-9]* segment states compared' /tmp/replay.err))"
else
  fail "oegw replay: exit $rc"
fi
# The window kept before the end replays on its own, exactly.
if [[ -n $kept ]]; then
  replay_into "$kept" /tmp/kept.err -q >/dev/null
  ((rc == 0)) && grep -q 'exact replay, .* no divergence$' /tmp/kept.err && pass "the kept window replays exactly" ||
    fail "the kept window: exit $rc"
fi
# The ring from its first segment that begins with a state (the run's start and the segment the
# keep opened gone, as after a long run): replayed exactly from that state.
from=
for f in "$rec"/*.events; do grep -q ' state crc32=' "$f" && { from=$f; break; }; done
if [[ -n $from ]]; then
  tail_dir=$(mktemp -d)
  for f in "$rec"/*.events; do [[ $f < $from ]] || cp "$f" "${f%.events}.log" "$tail_dir"/; done
  replay_into "$tail_dir" /tmp/tail.err -q >/dev/null
  if ((rc == 0)) && grep -q 'exact replay from the state at .* no divergence$' /tmp/tail.err; then
    pass "a window from $(basename "$from") replays exactly from its state ($(grep -o '[0-9]* outputs and [0-9]* segment states compared' /tmp/tail.err))"
  else
    fail "a window from the state of $(basename "$from"): exit $rc"
  fi
  rm -rf "$tail_dir"
else
  fail "no segment of $rec begins with a state"
fi
# The ring from the segment the keep opened, which begins with `state none` (the keep closed the
# segment before it): the timeline is the recording's own (the grip moved after the keep), not
# a new gateway's (which would boot the cab first: waiting-for-boot-up).
mid=$(mktemp -d)
after_keep=
for f in "$rec"/*.events; do grep -q ' state none (a window was kept' "$f" && { after_keep=$f; break; }; done
[[ -n $after_keep ]] || fail "no segment of $rec begins after the keep"
for f in "$rec"/*.events; do [[ $f < $after_keep ]] || cp "$f" "${f%.events}.log" "$mid"/; done
replay_into "$mid" /tmp/mid.err >"$out/timeline-mid.txt"
if ((rc == 0)) && grep -q 'shown as recorded: .* not re-run' /tmp/mid.err && grep -q ' fe joystick.1 ' "$out/timeline-mid.txt" &&
  ! grep -q 'waiting-for-boot-up' "$out/timeline-mid.txt"; then
  pass "a window without its start is shown as recorded ($(wc -l <"$out/timeline-mid.txt") lines)"
else
  fail "a window without its start: exit $rc: $(head -5 "$out/timeline-mid.txt")"
fi
rm -rf "$mid"
# 2: the incident on the timeline.
for want in "node right_grip missing" "fault right_grip raised" "fault right_grip cleared" "emcy left_grip 3120" \
  "emcy_sent 8130" "emcy_sent 7000" "fe joystick.1 offline" "node right_grip operational"; do
  grep -q "$want" "$out/timeline.txt" && pass "timeline: $want" || fail "timeline: no '$want'"
done
grep -q '"joystick.1.x"' "$out/blackbox.html" && pass "plot written ($(wc -c <"$out/blackbox.html") bytes)" ||
  fail "plot: no joystick.1.x series"
# The recording's frames are the buses' frames: every frame the gateway sent upstream is on candump.
sent_up=$(cat "$rec"/*.log | awk '$2 == "vcan0" && $4 == "T" { n++ } END { print n + 0 }')
dumped_up=$(awk '$2 == "vcan0" && ($3 ~ /^(1A0|720|0A0)#/) { n++ } END { print n + 0 }' /tmp/up.dump)
rec_up=$(cat "$rec"/*.log | awk '$2 == "vcan0" && $4 == "T" && ($3 ~ /^(1A0|720|0A0)#/) { n++ } END { print n + 0 }')
echo "    frames sent upstream in the recording: $sent_up (TPDO 1, heartbeat, EMCY: $rec_up; candump: $dumped_up)"
# SIGKILL loses at most the writer's last period: the candump has the recorded ones and a few more.
((rec_up > 100 && rec_up <= dumped_up)) && pass "the recording's upstream frames are on candump ($rec_up of $dumped_up)" ||
  fail "recording $rec_up vs candump $dumped_up upstream frames"

# 3: one frame edited: the replay diverges right after it.
rm -rf /tmp/edited
cp -r "$rec" /tmp/edited
# The 10th grip TPDO after the first TPDO 1 the gateway sent (the cab running, the host's set-up
# done), its x made the elobau's error value 126 (7Eh, 20xxh:1Bh; subdevices/elobau_mfg.hpp): whatever x the
# recording had there, and even with the axis held at neutral, the replayed gateway must decide
# otherwise (x in error, the grip faulty, EMCY 7000h).
target=$(awk '$2 == "vcan0" && $3 ~ /^1A0#/ && $4 == "T" { on = 1 }
  on && $2 == "vcan1" && $3 ~ /^191#/ && $4 == "R" && ++n == 10 { print FILENAME ":" FNR; exit }' /tmp/edited/*.log)
file=${target%:*}
line=${target##*:}
if [[ -n $target ]]; then
  awk -v n="$line" 'NR == n { split($3, p, "#"); $3 = p[1] "#7E" substr(p[2], 3) } { print }' \
    "$file" >/tmp/edited.log && cat /tmp/edited.log >"$file"
  echo "    edited $target: $(sed -n "${line}p" "$file")"
  replay_into /tmp/edited /tmp/edited.err -q >/dev/null
  if ((rc == 1)) && grep -q "DIVERGED at .*after the input R vcan1 191#.*($target)" /tmp/edited.err; then
    pass "an edited frame diverges right after it (exit 1)"
  else
    fail "the edited frame: exit $rc"
  fi
else
  fail "no 10th grip TPDO after the first TPDO 1 in the recording"
fi

# 4: a full disk loses recording, never bus service.
mkdir -p "$dir/full"
mount -t tmpfs -o size=256k tmpfs "$dir/full" || fail "cannot mount a tmpfs"
sed -i "s|^record: .*|record: { enabled: true, dir: $dir/full/record, max_mib: 64, segments: 4 }|" "$dir/oegw.yaml"
start_run
expect_status 90 "$all_up" "every sub-device operational on a full disk"
host_starts
cab "right_grip x 0" 1
expect_status 60 "s['record']['lost_frames'] > 0 and 'No space left on device' in (s['record']['last_error'] or '')" \
  "the full disk reported (ENOSPC, frames lost)"
# With the disk full: the stick moved (from neutral, so the interlock lets it through) between two
# marks. The host's heartbeat is not watched in this run: a stalled guest's late heartbeat would
# take the gateway to pre-operational.
cansend vcan0 7FF#02
for x in 30 60 -30 0; do cab "right_grip x $x" 1; done
cansend vcan0 7FF#03
stop_gateway "$gw_pid"
# On candump, between the marks: the gateway's heartbeat (720h) all along, and TPDO 1 following
# the stick (at least one with x off neutral: a stalled TCG guest makes the grip's PDOs stale at
# times, and the neutral interlock then holds x until the stick has been seen at zero again).
read -r hb tpdo xs <<<"$(awk '$3 == "7FF#02" { on = 1 } $3 == "7FF#03" { on = 0 }
  on && $3 ~ /^720#/ { hb++ } on && $3 ~ /^1A0#/ { t++; x = x substr($3, 5, 4) "," } END { print hb + 0, t + 0, x }' /tmp/up.dump)"
echo "    full disk: heartbeats $hb, TPDO 1 $tpdo (x bytes: $xs)"
((hb >= 10)) && pass "full disk: the heartbeat went on ($hb)" || fail "full disk: heartbeats $hb"
[[ $xs == *[1-9A-F]* ]] && pass "full disk: TPDO 1 went on ($tpdo, x bytes $xs)" || fail "full disk: TPDO 1 $tpdo ($xs)"
replay_into "$dir/full/record" /tmp/full.err -q >/dev/null
# Whole batches only: every file reads back; a gap line (when a later batch found room) ends the
# comparison there.
((rc == 0)) && grep -q 'exact replay' /tmp/full.err && pass "the full disk's recording reads back and replays ($(cat "$dir"/full/record/*.events | grep -c 'gap frames=') gap lines)" ||
  fail "the full disk's recording: exit $rc"
umount "$dir/full"

kill "$hb_pid" 2>/dev/null
kill -TERM "$cmd_pid" "$motion_pid" 2>/dev/null
wait "$cmd_pid" "$motion_pid" 2>/dev/null
exec 3>&-
stop_candump  # vcan1's, started last
candump_pid=$up_candump
stop_candump

echo "== gateway log"
grep -v 'debug:' /tmp/gateway.log | sed 's/^/    /' | head -80
cp /tmp/up.dump /tmp/down.dump /tmp/gateway.log "$out/" 2>/dev/null
echo "total $(elapsed) s; $passes passed, $fails failed"
((fails == 0))
