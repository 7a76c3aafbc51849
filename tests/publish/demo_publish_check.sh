#!/bin/sh
# `oegw demo` (publishing by default) watched by the example subscribers in other processes: both see
# joystick.1 valid while the joystick moves, then offline when the device's heartbeat is lost. With
# LCM_LOG_DECODE and LCM_LOGGER, Debian's lcm-logger also records the demo session and the
# project's decoder reads it back with the oegw LCM types.
#   demo_publish_check.sh OEGW DDS_SUBSCRIBER LCM_SUBSCRIBER [LCM_LOG_DECODE LCM_LOGGER]
set -eu
oegw=$1 dds_sub=$2 lcm_sub=$3 decode=${4:-} logger=${5:-}
url='udpm://224.0.0.1:7667?ttl=0'
dir=$(mktemp -d)
d='' l='' g='' one=''
trap 'kill $d $l $g $one 2>/dev/null || true; rm -rf "$dir"' EXIT
# The demo's own names (config/demo.yaml): partition oegw-demo, channels OEGW_DEMO_*.
"$dds_sub" --timeout 60 --partition oegw-demo > "$dir/dds.out" & d=$!
"$lcm_sub" --timeout 60 --url "$url" --channel 'OEGW_DEMO_JOYSTICK_[0-9]+' > "$dir/lcm.out" & l=$!
# --count 1 prints exactly one sample, also when a take returns joystick 1 and 2 written together.
"$dds_sub" --count 1 --timeout 60 --partition oegw-demo > "$dir/one.out" & one=$!
if [ -n "$logger" ]; then
  "$logger" --lcm-url="$url" --channel='OEGW_DEMO_.*' -f "$dir/session.lcmlog" > "$dir/logger.out" 2>&1 & g=$!
fi
# Wait (bounded) for the subscribers to be listening and the logger to have opened its file.
i=0
until grep -q '^ready$' "$dir/dds.out" 2>/dev/null && grep -q '^ready$' "$dir/lcm.out" 2>/dev/null &&
      grep -q '^ready$' "$dir/one.out" 2>/dev/null &&
      { [ -z "$logger" ] || [ -e "$dir/session.lcmlog" ]; }; do
  i=$((i + 1)); [ $i -lt 200 ] || { echo "subscribers or lcm-logger did not start" >&2; exit 1; }
  sleep 0.05
done
"$oegw" demo --seconds 1   # publishes by default (config/demo.yaml)
kill $d $l 2>/dev/null || true
wait $d $l 2>/dev/null || true
rc=0
one_rc=0; wait $one || one_rc=$?; one=
one_lines=$(grep -c '^joystick ' "$dir/one.out" || true)
echo "dds --count 1: exit $one_rc, $one_lines sample line(s)"
[ "$one_rc" -eq 0 ] && [ "$one_lines" -eq 1 ] || { rc=1; echo "dds --count 1: FAILED" >&2; cat "$dir/one.out" >&2; }
for t in dds lcm; do
  valid=$(grep -c '^joystick instance=1 status=valid' "$dir/$t.out" || true)
  offline=$(grep -c '^joystick instance=1 status=offline .* x=0 y=0 ' "$dir/$t.out" || true)
  echo "$t: $valid valid samples, $offline offline (neutral) samples"
  [ "$valid" -ge 5 ] && [ "$offline" -ge 1 ] || { rc=1; echo "$t: FAILED" >&2; tail -5 "$dir/$t.out" >&2; }
done
if [ -n "$logger" ]; then
  kill -INT $g 2>/dev/null || true
  wait $g 2>/dev/null || true
  g=
  # "decoded joystick=N status=M other=K bad=0" — every recorded message decodes with our types.
  summary=$("$decode" "$dir/session.lcmlog" OEGW_DEMO_ | tail -1) || { rc=1; echo "lcm_log_decode failed: $summary" >&2; }
  echo "lcm-logger session: $summary"
  joy=$(echo "$summary" | sed -n 's/.*joystick=\([0-9]*\).*/\1/p')
  st=$(echo "$summary" | sed -n 's/.*status=\([0-9]*\).*/\1/p')
  case "$summary" in
    *" bad=0") [ "${joy:-0}" -ge 20 ] && [ "${st:-0}" -ge 5 ] || { rc=1; echo "lcm-logger session: FAILED" >&2; } ;;
    *) rc=1; echo "lcm-logger session: FAILED (undecodable messages)" >&2 ;;
  esac
fi
exit $rc
