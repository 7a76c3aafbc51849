#!/bin/sh
# The examples' command lines (examples/, docs/guides/dds-lcm.md#the-examples): --help prints the
# usage on stdout and exits 0; an unknown option, an option without its value, a value out of range
# or an unexpected argument each says precisely what is wrong, then the usage, on stderr, and exits
# 2 before anything is opened. One program per run:
#   example_args_check.sh PROGRAM
set -u
prog=$1
name=$(basename "$prog")
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
fails=0
# expect RC STDERR_TEXT ARG...: exit status RC; STDERR_TEXT (fixed text, "" for none) on stderr and,
# for RC 2, the usage after it; for RC 0 the usage on stdout and nothing on stderr.
expect() {
  want_rc=$1 want_err=$2
  shift 2
  timeout 10 "$prog" "$@" >"$dir/out" 2>"$dir/err"
  rc=$?
  ok=1
  [ "$rc" -eq "$want_rc" ] || ok=0
  if [ -n "$want_err" ]; then grep -qF -- "$want_err" "$dir/err" || ok=0; fi
  case $want_rc in
    0) grep -q "^usage: $name " "$dir/out" && [ ! -s "$dir/err" ] || ok=0 ;;
    2) grep -q "^usage: $name " "$dir/err" && [ ! -s "$dir/out" ] || ok=0 ;;
  esac
  if [ $ok -eq 1 ]; then
    echo "ok: $name $* -> $rc $(head -1 "$dir/err")"
  else
    fails=$((fails + 1))
    echo "FAILED: $name $* -> exit $rc (expected $want_rc and '$want_err' on stderr); stderr:" >&2
    sed 's/^/    /' "$dir/err" >&2
  fi
}
# Every program.
expect 0 "" --help
expect 2 "$name: unrecognized option '--bogus'" --bogus
case $name in
  dds_subscriber|lcm_subscriber)
    expect 2 "$name: option '--count' requires an argument" --count
    expect 2 "$name: --count: 'abc' is not a whole number from 1 to 1000000000" --count abc
    expect 2 "$name: --count: '0' is not a whole number from 1 to 1000000000" --count 0
    expect 2 "$name: --count: '5x' is not a whole number from 1 to 1000000000" --count 5x
    expect 2 "$name: --timeout: '-1' is not a number of seconds above 0 and at most 86400" --timeout -1
    expect 2 "$name: --timeout: 'soon' is not a number of seconds above 0 and at most 86400" --timeout soon
    expect 2 "$name: unexpected argument 'extra'" --count 1 extra
    expect 2 "$name: option '--timeout' requires an argument" --count 1 --timeout ;;
  dds_status|lcm_status)
    expect 2 "$name: option '--timeout' requires an argument" --timeout
    expect 2 "$name: --timeout: '0' is not a number of seconds above 0 and at most 86400" --timeout 0
    expect 2 "$name: option '--every' doesn't allow an argument" --every=yes
    expect 2 "$name: unexpected argument 'extra'" extra ;;
  dds_command|lcm_command)
    expect 2 "$name: no command: indicators or display"
    expect 2 "$name: 'lamps' is not indicators or display" lamps 1 --on 1
    expect 2 "$name: indicators: no INSTANCE (1..8)" indicators
    expect 2 "$name: indicators INSTANCE: '9' is not a whole number from 1 to 8" indicators 9 --on 1
    expect 2 "$name: indicators INSTANCE: '0' is not a whole number from 1 to 8" indicators 0 --on 1
    expect 2 "$name: indicators needs --on LIST (the indicators to light; none: all off)" indicators 1
    expect 2 "$name: option '--on' requires an argument" indicators 1 --on
    expect 2 "$name: --on: '65' is not a whole number from 1 to 64" indicators 1 --on 1,65
    expect 2 "$name: --on: '3' is not a whole number from 5 to 64" indicators 1 --on 5-3
    expect 2 "$name: --on: 'x' is not a whole number from 1 to 64" indicators 1 --on x
    expect 2 "$name: --on given twice" indicators 1 --on 1 --on 2
    expect 2 "$name: --set is for display" indicators 1 --on 1 --set 1=1
    expect 2 "$name: display needs --set P=V,... (the parameters)" display 1
    expect 2 "$name: --set (parameter): '13' is not a whole number from 1 to 12" display 1 --set 13=1
    expect 2 "$name: --set (value): '40000' is not a whole number from -32768 to 32767" display 1 --set 1=40000
    expect 2 "$name: --set: '7' is not PARAMETER=VALUE" display 1 --set 7
    expect 2 "$name: --set: parameter 2 given twice" display 1 --set 2=1,2=3
    expect 2 "$name: unexpected argument 'more'" display 1 more --set 1=1 ;;
  lcm_log_decode)
    expect 2 "$name: no FILE given"
    expect 2 "$name: unexpected argument 'c'" a b c
    expect 1 "$name: cannot open LCM log $dir/none.lcmlog" "$dir/none.lcmlog" ;;
  *) echo "FAILED: no cases for $name" >&2; exit 1 ;;
esac
case $name in
  dds_*)
    expect 2 "$name: --domain: '233' is not a whole number from 0 to 232" --domain 233
    expect 2 "$name: --network: 'a\"b' is not loopback, default or an interface name" --network 'a"b'
    expect 2 "$name: --partition: the partition name is empty" --partition ''
    expect 2 "$name: a DDS Security file 'a<b': expected a path without < > & or quotes" --certificate 'a<b'
    expect 2 "$name: option '--governance' requires an argument" --governance
    # DDS Security takes all six files: one alone is refused before anything is opened (exit 1).
    [ "$name" = dds_command ] && set -- indicators 1 --on 1 || set --
    expect 1 "$name: DDS Security needs all six files; --identity-ca is missing" --certificate /dev/null "$@"
    expect 1 "$name: --identity-ca $dir/none.pem: No such file or directory" --identity-ca "$dir/none.pem" \
      --certificate x --private-key x --permissions-ca x --governance x --permissions x "$@" ;;
esac
[ $fails -eq 0 ] || { echo "$fails case(s) FAILED" >&2; exit 1; }
