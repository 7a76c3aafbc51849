#!/bin/sh
# Loads a page `oegw replay --plot` wrote in headless chromium (Debian's; command 2 installs it)
# and judges what it drew: the page's script finished (Chart.js inlined, no network), each named
# series is a chart's dataset with points (the page's own check text, read from the DOM), then a
# screenshot. Exit 77 (ctest: Skipped) without chromium.
# Args: PAGE.html SCREENSHOT.png EXPECTED... (texts the drawn page's check text must hold)
set -eu
page=$1
png=$2
shift 2
browser=$(command -v chromium || command -v chromium-browser || true)
if [ -z "$browser" ]; then
  echo "SKIP: no chromium (command 2 installs it): $page was not loaded"
  exit 77
fi
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
flags="--headless --no-sandbox --disable-gpu --disable-background-networking --disable-component-update --no-first-run"
# $flags: one word per option.
# shellcheck disable=SC2086
"$browser" $flags --user-data-dir="$dir/profile" --dump-dom "file://$page" >"$dir/dom.html" 2>"$dir/chromium.txt" || {
  echo "FAIL: chromium --dump-dom"; tail -5 "$dir/chromium.txt"; exit 1; }
grep -q 'data-oegw-plot="drawn"' "$dir/dom.html" || { echo "FAIL: the page's script did not finish"; tail -5 "$dir/chromium.txt"; exit 1; }
sed -n '/<pre id="check">/,/<\/pre>/p' "$dir/dom.html"
for want in "$@"; do
  grep -qF "$want" "$dir/dom.html" || { echo "FAIL: '$want' not drawn"; exit 1; }
done
if grep -o '([0-9]* points)' "$dir/dom.html" | grep -q '(0 points)'; then echo "FAIL: an empty series"; exit 1; fi
# shellcheck disable=SC2086
"$browser" $flags --user-data-dir="$dir/profile" --window-size=1400,2600 --screenshot="$png" "file://$page" \
  >/dev/null 2>"$dir/chromium.txt" || { echo "FAIL: chromium --screenshot"; tail -5 "$dir/chromium.txt"; exit 1; }
[ "$(wc -c <"$png")" -gt 20000 ] || { echo "FAIL: the screenshot is (nearly) empty"; exit 1; }
echo "PASS: chromium drew $page; screenshot $png"
