#!/bin/sh
# The table of every driver's signals and options in docs/reference/drivers.md is `oegw signals
# --markdown`, between the marker comments below. Without --update: exit 1 (and the diff) when
# the page's copy differs from what the program prints (CTest: signals_readme). With --update:
# rewrite the page's copy.
#   scripts/signals_readme.sh build/programs/oegw [--update]
set -u
oegw=$1 mode=${2:-check}
readme=$(dirname "$0")/../docs/reference/drivers.md
begin='<!-- oegw signals --markdown: begin (generated: scripts/signals_readme.sh OEGW --update) -->'
end='<!-- oegw signals --markdown: end -->'
tmp=$(mktemp -d) || exit 1
trap 'rm -rf "$tmp"' EXIT
"$oegw" signals --markdown >"$tmp/generated" || { echo "FAIL: oegw signals --markdown failed"; exit 1; }
grep -qxF -- "$begin" "$readme" && grep -qxF -- "$end" "$readme" ||
  { echo "FAIL: $readme lacks the marker lines"; exit 1; }
# The page's block, without its markers.
awk -v b="$begin" -v e="$end" '$0 == e { inside = 0 } inside { print } $0 == b { inside = 1 }' "$readme" >"$tmp/readme"
if [ "$mode" = "--update" ]; then
  awk -v b="$begin" -v e="$end" -v gen="$tmp/generated" '
    $0 == b { print; while ((getline line < gen) > 0) print line; skip = 1; next }
    $0 == e { skip = 0 }
    !skip { print }' "$readme" >"$tmp/new" && cat "$tmp/new" >"$readme"
  echo "updated $readme"
  exit 0
fi
if diff -u "$tmp/readme" "$tmp/generated"; then
  echo "PASS: docs/reference/drivers.md has what oegw signals --markdown prints"
  exit 0
fi
echo "FAIL: docs/reference/drivers.md differs from oegw signals --markdown; regenerate: scripts/signals_readme.sh build/programs/oegw --update"
exit 1
