#!/bin/sh
# `oegw demo --dds-security DIR` (docs/guides/secure-dds.md): the demo's participant with the
# gateway's identity of a set scripts/make-dds-security.sh makes here; the example subscriber as the
# application reads the demo's joystick, a subscriber without security at the same time reads
# nothing; a set whose permissions were changed after signing stops the demo (exit 2) naming
# the setting, before it runs; `oegw sim --dds-security` alike. Run inside in_private_net.sh.
#   demo_secure_check.sh OEGW DDS_SUBSCRIBER MAKE_DDS_SECURITY
set -u
oegw=$1 sub=$2 make=$3
d=$(mktemp -d)
demo=
trap '[ -n "$demo" ] && kill "$demo" 2>/dev/null; rm -rf "$d"' EXIT
fail() { echo "FAIL: $*"; for f in "$d"/*.out; do echo "--- $f"; cat "$f"; done; exit 1; }
"$make" --partition oegw-demo "$d/set" >/dev/null || fail "make-dds-security.sh"
s=$d/set
app="--identity-ca $s/ca.pem --certificate $s/app.pem --private-key $s/app.key --permissions-ca $s/ca.pem
     --governance $s/governance.p7s --permissions $s/permissions.p7s"

"$oegw" demo --seconds 6 --dds-security "$s" >"$d/demo.out" 2>&1 &
demo=$!
"$sub" --partition oegw-demo --count 1 --timeout 8 >"$d/plain.out" 2>&1 &
plain=$!
# shellcheck disable=SC2086 # $app: the options, split on purpose
"$sub" --partition oegw-demo --count 3 --timeout 30 $app >"$d/app.out" 2>&1
app_rc=$?
wait "$plain"
plain_rc=$?
wait "$demo"
demo_rc=$?
demo=
[ "$app_rc" -eq 0 ] || fail "the application's subscriber: exit $app_rc"
[ "$(grep -c '^joystick instance=' "$d/app.out")" -eq 3 ] || fail "the application read no 3 joystick samples"
[ "$plain_rc" -eq 3 ] || fail "the subscriber without security: exit $plain_rc, expected 3 (nothing within its timeout)"
! grep -q '^joystick' "$d/plain.out" || fail "the subscriber without security read a sample"
[ "$demo_rc" -eq 0 ] || fail "oegw demo: exit $demo_rc"
grep -q "DDS Security with $s" "$d/demo.out" || fail "the demo did not say it publishes with DDS Security"
echo "ok: the application read 3 samples; without security: nothing (exit 3); the demo passed"

# The permissions changed after signing: refused at start.
sed -i 's|<topic>oegw/display</topic>|<topic>oegw/*</topic>|' "$s/permissions.p7s"
"$oegw" demo --fast --dds-security "$s" >"$d/tampered.out" 2>&1
rc=$?
[ "$rc" -eq 2 ] || fail "a tampered permissions document: exit $rc, expected 2"
grep -q "publish.dds.security.permissions $s/permissions.p7s: is not signed by publish.dds.security.permissions_ca" \
  "$d/tampered.out" || fail "the refusal does not name publish.dds.security.permissions"
echo "ok: a tampered permissions document stops the demo (exit 2): $(grep -o 'publish.dds.security.permissions [^(]*' "$d/tampered.out")"

# `oegw sim --dds-security` (the demo is the sim with a story: the same code) refuses it alike,
# with the user's own file (here config/demo.yaml, beside the script's source tree).
src=$(cd "$(dirname "$0")/../.." && pwd)
"$oegw" sim "$src/config/demo.yaml" --fast --seconds 1 --dds-security "$s" >"$d/sim-tampered.out" 2>&1
rc=$?
[ "$rc" -eq 2 ] || fail "oegw sim with a tampered permissions document: exit $rc, expected 2"
grep -q "^oegw sim: --dds-security $s: publish.dds.security.permissions $s/permissions.p7s: is not signed" \
  "$d/sim-tampered.out" || fail "oegw sim's refusal does not name --dds-security and the setting"
echo "ok: oegw sim --dds-security with the tampered set: exit 2, nothing started"
