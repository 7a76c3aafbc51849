#!/bin/sh
# The examples against `oegw demo` in other processes (run it in a private network namespace:
# in_private_net.sh). The demo publishes under partition oegw-demo / channels OEGW_DEMO_*, takes
# indicators.1's commands from DDS and LCM, refuses its host's SDO write to indicators.1 (counted
# in refused_commands), pulls the right grip's cable (missing, EMCY 7000h from the gateway) and
# plugs it back.
#   example_demo_check.sh status  dds|lcm OEGW EXAMPLES_DIR
#     the status printer prints the sub-devices' states and identities, the grip missing, the
#     gateway's active EMCY 7000h and the refused command;
#   example_demo_check.sh command dds|lcm OEGW EXAMPLES_DIR
#     `indicators 1 --on 1,3` from the command publisher lights the button cluster's lamps 1 and 3
#     (the demo prints indicators.1's bits), and `display 1 --set 1=5` — the demo has no display —
#     is refused and counted (the status printer shows refused_commands rise);
#   example_demo_check.sh log     lcm     OEGW EXAMPLES_DIR LCM_LOGGER
#     lcm-logger records the session (every channel: FE samples, status, a command) and
#     lcm_log_decode decodes all of it, identities included.
set -u
mode=$1 transport=$2 oegw=$3 ex=$4 logger=${5:-}
url='udpm://224.0.0.1:7667?ttl=0'
dir=$(mktemp -d)
pids=""
# shellcheck disable=SC2154  # p is the trap's own loop variable
trap 'for p in $pids; do kill "$p" 2>/dev/null; done; rm -rf "$dir"' EXIT
rc=0
fail() { rc=1; echo "FAILED: $*" >&2; }
# wait_for FILE TEXT SECONDS: until FILE has a line with TEXT (fixed), or fails.
wait_for() {
  i=0
  until grep -qF -- "$2" "$1" 2>/dev/null; do
    i=$((i + 1)); [ $i -lt $(($3 * 20)) ] || { fail "no '$2' in $1 within $3 s"; return 1; }
    sleep 0.05
  done
}
# has FILE REGEX WHAT: FILE has a line matching REGEX (extended), else fails naming WHAT.
has() {
  if grep -qE -- "$2" "$1"; then echo "ok: $3: $(grep -E -- "$2" "$1" | head -1)"; else fail "$3: no line like '$2' in $(basename "$1")"; fi
}
if [ "$transport" = dds ]; then
  status="$ex/dds_status --partition oegw-demo"
  command="$ex/dds_command --partition oegw-demo"
else
  status="$ex/lcm_status --url $url --prefix OEGW_DEMO_"
  command="$ex/lcm_command --url $url --prefix OEGW_DEMO_"
fi
# A file's failed steps (the demo's FAIL lines, wherever they are), then its end.
show() {
  for f in "$@"; do
    echo "--- $f" >&2
    grep -n 'FAIL' "$dir/$f" >&2
    tail -40 "$dir/$f" >&2
  done
}

case $mode in
  status)
    $status --timeout 60 >"$dir/status.out" 2>"$dir/status.err" & pids="$pids $!"; s=$!
    wait_for "$dir/status.out" ready 10 || exit 1
    if [ "$transport" = lcm ]; then
      # The plain subscriber on the status channel decodes it as a status (it printed only "ready").
      "$ex/lcm_subscriber" --url "$url" --channel OEGW_DEMO_STATUS --count 3 --timeout 30 >"$dir/sub.out" 2>"$dir/sub.err" &
      pids="$pids $!"; l=$!
      wait_for "$dir/sub.out" ready 10 || exit 1
    fi
    "$oegw" demo --seconds 1 >"$dir/demo.out" 2>&1 || fail "the demo failed"
    kill -TERM $s; wait $s || fail "the status printer exited $?"
    if [ "$transport" = lcm ]; then
      wait "$l" || fail "lcm_subscriber --channel OEGW_DEMO_STATUS exited $? ($(cat "$dir/sub.err"))"
      has "$dir/sub.out" '^status seq=[0-9]+ upstream=[a-z-]+ subdevices=5 .* rx_us=[0-9]+$' "lcm_subscriber on the status channel"
      has "$dir/sub.out" '^  subdevice cluster node=31h state=' "lcm_subscriber's sub-device lines"
    fi
    has "$dir/status.out" '^upstream state=operational$' "the upstream NMT state"
    has "$dir/status.out" '^subdevice right_grip node=11h state=operational vendor=[0-9A-F]{8}h product=[0-9A-F]{8}h' "the grip operational, with its identity"
    has "$dir/status.out" '^subdevice cluster node=31h state=operational ' "the button cluster operational"
    has "$dir/status.out" '^subdevice right_grip node=11h state=missing ' "the grip missing when its cable is pulled"
    has "$dir/status.out" '^emcy [a-z_]+ node=[0-9A-F]{2}h count=[1-9][0-9]* last=[0-9A-F]{4}h reg=[0-9A-F]{2}h msef=([0-9a-f]{2} ){4}[0-9a-f]{2} ts_us=[1-9]' "a sub-device's EMCY"
    has "$dir/status.out" '^active_emcys 7000h$' "the gateway's EMCY 7000h active"
    has "$dir/status.out" '^active_emcys none$' "no active EMCY after the grip is back"
    has "$dir/status.out" '^refused_commands 1$' "the host's refused write counted"
    # The grip comes back: operational again after missing.
    sed -n '/right_grip node=11h state=missing/,$p' "$dir/status.out" | grep -q '^subdevice right_grip node=11h state=operational ' ||
      fail "the grip not operational again after missing"
    [ $rc -eq 0 ] || show status.out status.err demo.out ;;
  command)
    $status --timeout 60 >"$dir/status.out" 2>"$dir/status.err" & pids="$pids $!"; s=$!
    wait_for "$dir/status.out" ready 10 || exit 1
    "$oegw" demo --seconds 1 >"$dir/demo.out" 2>&1 & pids="$pids $!"; d=$!
    # After the demo's own checks of the cluster's lamps (the refused host write left them off).
    wait_for "$dir/demo.out" "the right grip's cable is pulled" 30 || { show demo.out; exit 1; }
    $command indicators 1 --on 1,3 >"$dir/command.out" 2>&1 || fail "the indicators command failed: $(cat "$dir/command.out")"
    has "$dir/command.out" '^sent indicators\.1 indicators=0x0000000000000005 \(on: 1 3\) on ' "the command sent"
    wait_for "$dir/status.out" "refused_commands 1" 10
    $command display 1 --set 1=5 >"$dir/display.out" 2>&1 || fail "the display command failed: $(cat "$dir/display.out")"
    has "$dir/display.out" '^sent display\.1 parameters=5,0,0,0,0,0,0,0,0,0,0,0 on ' "the display command sent"
    wait $d || fail "the demo failed"
    kill -TERM $s; wait $s
    # The demo's last view of indicators.1: lamps 1 and 3 lit, as commanded.
    last=$(grep -E '^ +indicators\.1 ' "$dir/demo.out" | tail -1)
    echo "demo: $last"
    echo "$last" | grep -qE 'indicator=10100000( |$)' || fail "indicators.1 is not 10100000 at the end of the demo"
    # The display command reached the gateway, which has no display.1: refused and counted.
    has "$dir/status.out" '^refused_commands 2$' "the display command refused (no display.1 in the demo)"
    [ $rc -eq 0 ] || show demo.out status.out ;;
  log)
    "$logger" -q --lcm-url="$url" --channel='OEGW_DEMO_.*' -f --flush-interval=10 "$dir/session.lcmlog" >"$dir/logger.out" 2>&1 &
    pids="$pids $!"; g=$!
    "$oegw" demo --seconds 1 >"$dir/demo.out" 2>&1 & pids="$pids $!"; d=$!
    wait_for "$dir/demo.out" "the right grip's cable is pulled" 30 || { show demo.out; exit 1; }
    $command indicators 1 --on 2 >"$dir/command.out" 2>&1 || fail "the indicators command failed"
    $command display 3 --set 12=-7 >>"$dir/command.out" 2>&1 || fail "the display command failed"
    wait $d || fail "the demo failed"
    kill -INT $g; wait $g
    # As docs/guides/dds-lcm.md#recording-with-lcm-logger says: without a prefix (OEGW_, which the
    # demo's OEGW_DEMO_ channels start with).
    "$ex/lcm_log_decode" "$dir/session.lcmlog" >"$dir/decode.out" 2>"$dir/decode.err" || fail "lcm_log_decode exited $?"
    summary=$(tail -1 "$dir/decode.out")
    echo "lcm_log_decode: $summary"
    for kind in joystick pedal wheel encoder buttons status; do
      n=$(echo "$summary" | sed -n "s/.* $kind=\([0-9]*\).*/\1/p")
      [ "${n:-0}" -ge 5 ] || fail "$kind: ${n:-0} messages decoded (expected at least 5)"
    done
    echo "$summary" | grep -qE ' indicators=1 display=1 status=[0-9]+ other=0 bad=0$' || fail "not every message decoded: $summary"
    [ ! -s "$dir/decode.err" ] || fail "lcm_log_decode said: $(head -3 "$dir/decode.err")"
    has "$dir/decode.out" '^indicators instance=1 indicators=0x0000000000000002$' "the indicators command"
    has "$dir/decode.out" '^display instance=3 parameters=0,0,0,0,0,0,0,0,0,0,0,-7$' "the display command"
    has "$dir/decode.out" '^joystick instance=1 status=valid seq=[0-9]+ ts_us=[0-9]+ x=-?[0-9]+ ' "the joystick"
    has "$dir/decode.out" '^pedal instance=1 status=valid ' "the pedal"
    has "$dir/decode.out" '^encoder instance=1 status=valid ' "the encoder"
    has "$dir/decode.out" '^wheel instance=1 status=valid ' "the wheel"
    has "$dir/decode.out" '^buttons instance=1 status=valid .* switches=0x[0-9a-f]{16}$' "the button cluster"
    has "$dir/decode.out" '^status seq=[0-9]+ upstream=operational subdevices=5 emcys=1 refused=[0-9]+ active=7000h$' "a status with the gateway's EMCY 7000h"
    # The host's SDO write and the display command (the demo has no display.3) refused.
    has "$dir/decode.out" '^status seq=[0-9]+ upstream=operational subdevices=5 emcys=0 refused=2 active=none$' "a status with both refusals"
    has "$dir/decode.out" '^  subdevice [a-z_]+ node=[0-9A-F]{2}h state=operational emcys=[1-9][0-9]* last=[1-9A-F][0-9A-F]{3}h reg=[0-9A-F]{2}h msef=' "a sub-device's EMCY"
    has "$dir/decode.out" '^  subdevice right_grip node=11h state=operational emcys=[0-9]+ last=[0-9A-F]{4}h .* vendor=[0-9A-F]{8}h product=[0-9A-F]{8}h' "the grip's identity"
    has "$dir/decode.out" '^  subdevice right_grip node=11h state=missing ' "the grip missing"
    [ $rc -eq 0 ] || show decode.out decode.err demo.out ;;
  *) fail "no mode $mode"; exit 1 ;;
esac
exit $rc
