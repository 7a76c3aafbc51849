#!/bin/sh
# `oegw replay … --plot` on a plain candump log: `oegw demo --frames` (the demo cab through its
# script: the grip's cable pulled and plugged back, the host's commands) replayed on a fresh
# gateway with config/demo.yaml, the decisions printed and drawn into one self-contained page.
# Then the page is loaded in headless chromium (plot_chromium_check.sh; skipped, exit 77, without).
# Args: OEGW SOURCE_DIR OUT_DIR (the page and the screenshot stay there)
set -eu
oegw=$1
src=$2
out=$3
mkdir -p "$out"
rm -f "$out/plot.html" "$out/plot.png" "$out/plot.svg" "$out/plot-svg.png"
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT

"$oegw" demo --fast --seconds 3 --no-publish --frames >"$dir/demo.txt"
"$oegw" replay "$dir/demo.txt" --config "$src/config/demo.yaml" --plot "$out/plot.html" >"$dir/timeline.txt" 2>"$dir/summary.txt" || {
  echo "FAIL: oegw replay exited $?"; cat "$dir/summary.txt"; exit 1; }
cat "$dir/summary.txt"
grep -q "replayed on a fresh gateway" "$dir/summary.txt" || { echo "FAIL: no fresh replay reported"; exit 1; }
for want in "node right_grip operational" "fault right_grip raised" "fault right_grip cleared" "fe joystick.1 offline"; do
  grep -q "$want" "$dir/timeline.txt" || { echo "FAIL: '$want' not on the timeline"; head -40 "$dir/timeline.txt"; exit 1; }
done
grep -q 'Chart.js v3.9.1' "$out/plot.html" || { echo "FAIL: Chart.js is not inside the page"; exit 1; }
if grep -q '<script src=' "$out/plot.html"; then echo "FAIL: the page fetches a script"; exit 1; fi
echo "PASS: timeline ($(wc -l <"$dir/timeline.txt") lines) and $out/plot.html ($(wc -c <"$out/plot.html") bytes)"

# A window (--from/--to in seconds from the log's first frame): only its lines, and some.
"$oegw" replay "$dir/demo.txt" --config "$src/config/demo.yaml" --from 1 --to 2 >"$dir/window.txt" 2>"$dir/summary.txt" || {
  echo "FAIL: oegw replay --from 1 --to 2 exited $?"; cat "$dir/summary.txt"; exit 1; }
awk '{ t = substr($2, 2) + 0; if (t < 1 || t > 2) { print "FAIL: outside the window 1-2 s: " $0; bad = 1 } }
     END { if (NR == 0) { print "FAIL: nothing in the window 1-2 s"; bad = 1 } exit bad }' "$dir/window.txt" || exit 1
[ "$(wc -l <"$dir/window.txt")" -lt "$(wc -l <"$dir/timeline.txt")" ] || { echo "FAIL: the window is the whole timeline"; exit 1; }
echo "PASS: --from 1 --to 2: $(wc -l <"$dir/window.txt") lines, each within the window"

# The same timeline as a static picture, read back by an XML reader, then drawn by chromium.
"$oegw" replay "$dir/demo.txt" --config "$src/config/demo.yaml" -q --plot "$out/plot.svg" 2>"$dir/summary.txt" || {
  echo "FAIL: oegw replay --plot .svg exited $?"; cat "$dir/summary.txt"; exit 1; }
python3 "$src/tests/tools/plot_svg_check.py" "$out/plot.svg" joystick.1.x joystick.1.y joystick.2.x right_grip \
  "sub-devices (node state)" || exit 1
browser=$(command -v chromium || command -v chromium-browser || true)
if [ -n "$browser" ]; then
  "$browser" --headless --no-sandbox --disable-gpu --no-first-run --user-data-dir="$dir/profile" \
    --window-size=1200,1800 --screenshot="$out/plot-svg.png" "file://$out/plot.svg" >/dev/null 2>&1 || {
    echo "FAIL: chromium did not draw $out/plot.svg"; exit 1; }
  [ "$(wc -c <"$out/plot-svg.png")" -gt 20000 ] || { echo "FAIL: the SVG's screenshot is (nearly) empty"; exit 1; }
  echo "PASS: chromium drew $out/plot.svg; screenshot $out/plot-svg.png"
fi

exec sh "$src/tests/tools/plot_chromium_check.sh" "$out/plot.html" "$out/plot.png" \
  "joystick.1.x (" "joystick.1.y (" "joystick.2.x (" "sub-devices (node state): " "right_grip (" "offline"
