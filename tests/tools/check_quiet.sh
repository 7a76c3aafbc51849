#!/bin/sh
# `oegw check --quiet`: of a valid file only "FILE: valid" and its warnings, this machine's under
# their heading "on this machine (...):" (exit 0); of a bad file every error exactly as without
# --quiet (exit 1).
#   check_quiet.sh OEGW VALID_FILE WARNING_COUNT BAD_FILE
oegw=$1 valid=$2 warnings=$3 bad=$4
fail=0
out=$("$oegw" check --quiet "$valid" 2>&1)
rc=$?
printf '%s\n' "$out"
[ "$rc" -eq 0 ] || { echo "FAIL: exit status $rc for $valid, expected 0"; fail=1; }
first=$(printf '%s\n' "$out" | head -n 1)
[ "$first" = "$valid: valid" ] || { echo "FAIL: first line '$first', expected '$valid: valid'"; fail=1; }
n=$(printf '%s\n' "$out" | sed 1d | grep -c '^warning: ')
[ "$n" -eq "$warnings" ] || { echo "FAIL: $n warnings, expected $warnings"; fail=1; }
other=$(printf '%s\n' "$out" | sed 1d | grep -v '^warning: ' | grep -v '^on this machine (.*):$')
[ -z "$other" ] || { echo "FAIL: more than the verdict and the warnings: $other"; fail=1; }
full=$("$oegw" check "$valid" 2>&1 | wc -l)
[ "$full" -gt $((warnings + 10)) ] || { echo "FAIL: without --quiet only $full lines"; fail=1; }
loud=$("$oegw" check "$bad" 2>&1)
loud_rc=$?
quiet=$("$oegw" check --quiet "$bad" 2>&1)
quiet_rc=$?
[ "$loud_rc" -eq 1 ] && [ "$quiet_rc" -eq 1 ] || { echo "FAIL: $bad exit $loud_rc / $quiet_rc with --quiet, expected 1"; fail=1; }
[ "$loud" = "$quiet" ] || { echo "FAIL: --quiet changed the errors of $bad:"; printf '%s\n' "$quiet"; fail=1; }
[ "$fail" -eq 0 ] && echo "PASS: --quiet prints the verdict and $warnings warning(s); errors unchanged"
exit "$fail"
