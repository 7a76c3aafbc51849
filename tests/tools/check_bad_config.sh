#!/bin/sh
# `oegw check` on a file with deliberate errors: exit 1, every error reported as
# file:line:column, the count, and one exact line.
#   check_bad_config.sh OEGW FILE EXPECTED_COUNT EXACT_LINE
oegw=$1 file=$2 count=$3 line=$4
out=$("$oegw" check "$file" 2>&1)
rc=$?
printf '%s\n' "$out"
fail=0
[ "$rc" -eq 1 ] || { echo "FAIL: exit status $rc, expected 1"; fail=1; }
n=$(printf '%s\n' "$out" | grep -c "^$file:[0-9][0-9]*:[0-9][0-9]*: ")
[ "$n" -eq "$count" ] || { echo "FAIL: $n file:line:column lines, expected $count"; fail=1; }
printf '%s\n' "$out" | grep -qxF "$line" || { echo "FAIL: missing line: $line"; fail=1; }
printf '%s\n' "$out" | grep -qxF "$file: $count errors; nothing was started" ||
  { echo "FAIL: missing summary '$file: $count errors; nothing was started'"; fail=1; }
# Nothing but diagnostics and the summary.
other=$(printf '%s\n' "$out" | grep -v "^$file:[0-9][0-9]*:[0-9][0-9]*: " | grep -vxF "$file: $count errors; nothing was started")
[ -z "$other" ] || { echo "FAIL: unexpected output: $other"; fail=1; }
[ "$fail" -eq 0 ] && echo "PASS: $count errors as file:line:column, exit 1"
exit "$fail"
