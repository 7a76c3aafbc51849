#!/bin/sh
# `oegw demo` (publishing by default) watched by the example subscribers in other processes: both see
# joystick.1 valid while the joystick moves, then offline when the device's heartbeat is lost.
#   demo_publish_check.sh OEGW DDS_SUBSCRIBER LCM_SUBSCRIBER   (run inside in_private_net.sh)
set -eu
oegw=$1 dds_sub=$2 lcm_sub=$3
dir=$(mktemp -d)
trap 'kill $d $l 2>/dev/null || true; rm -rf "$dir"' EXIT
# The demo's own names (config/demo.yaml): partition oegw-demo, channels OEGW_DEMO_*.
"$dds_sub" --timeout 60 --partition oegw-demo > "$dir/dds.out" & d=$!
"$lcm_sub" --timeout 60 --channel 'OEGW_DEMO_JOYSTICK_[0-9]+' > "$dir/lcm.out" & l=$!
# Wait (bounded) for both subscribers to be listening.
i=0
until grep -q '^ready$' "$dir/dds.out" 2>/dev/null && grep -q '^ready$' "$dir/lcm.out" 2>/dev/null; do
  i=$((i + 1)); [ $i -lt 200 ] || { echo "subscribers did not start" >&2; exit 1; }
  sleep 0.05
done
"$oegw" demo --seconds 1   # publishes by default (config/demo.yaml)
kill $d $l 2>/dev/null || true
wait $d $l 2>/dev/null || true
rc=0
for t in dds lcm; do
  valid=$(grep -c '^joystick instance=1 status=valid' "$dir/$t.out" || true)
  offline=$(grep -c '^joystick instance=1 status=offline .* x=0 y=0 ' "$dir/$t.out" || true)
  echo "$t: $valid valid samples, $offline offline (neutral) samples"
  [ "$valid" -ge 5 ] && [ "$offline" -ge 1 ] || { rc=1; echo "$t: FAILED" >&2; tail -5 "$dir/$t.out" >&2; }
done
exit $rc
