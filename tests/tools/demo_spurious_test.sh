#!/bin/bash
# `oegw demo` must not say "every step as expected" while its screen shows a fault its story did
# not cause. The demo is held (SIGSTOP) for 1.5 s once every sub-device is up, before the story
# pulls the grip's cable: every sub-device's heartbeat times out, the screen shows them lost and
# the host gets EMCY 7000h. The demo must then fail (exit 1) and name the fault, not only the steps
# it had planned. Then, undisturbed, the same run completes (exit 0): the check is not always-fail.
# Args: OEGW
set -uo pipefail
oegw=$1
out=$(mktemp)
trap 'rm -f "$out"' EXIT
fails=0

"$oegw" demo --seconds 1 --no-publish >"$out" 2>&1 &
pid=$!
for _ in $(seq 1 300); do
  grep -q 'ok: every sub-device configured and operational' "$out" && break
  sleep 0.05
done
kill -STOP "$pid"
sleep 1.5
kill -CONT "$pid"
wait "$pid"
rc=$?
if ((rc == 1)) && grep -q 'FAILED: a fault the story did not cause' "$out" &&
  grep -qE 'FAILED: [0-9]+ fault\(s\) the story did not cause, the first: ' "$out"; then
  echo "PASS: held 1.5 s: exit 1, $(grep -m1 'FAILED: a fault the story did not cause' "$out" | sed 's/^\[[^]]*\] //')"
else
  echo "FAIL: held 1.5 s: exit $rc; the demo's output:"
  cat "$out"
  fails=$((fails + 1))
fi

"$oegw" demo --seconds 1 --no-publish >"$out" 2>&1
rc=$?
if ((rc == 0)) && grep -q 'ok: no fault the story did not cause' "$out"; then
  echo "PASS: undisturbed: exit 0, no fault the story did not cause"
else
  echo "FAIL: undisturbed: exit $rc"
  cat "$out"
  fails=$((fails + 1))
fi
exit $((fails > 0))
