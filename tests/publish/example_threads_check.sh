#!/bin/sh
# The DDS examples end DDS before they exit (examples/dds_options.h, dds_options_close): every
# thread Cyclone DDS started for the program has ended itself before the program's exit_group, so
# exit()'s cleanup never runs beside a DDS thread still at work. Until they did, the examples
# deleted their participant only; the domain dds_create_domain had made for the loopback/interface
# configuration outlived it, its receive thread went on decrypting DDS Security messages while
# exit() ran OpenSSL's cleanup (OPENSSL_cleanup frees its locks), and that thread died of SIGSEGV
# in CRYPTO_THREAD_read_lock. Natively the window is too short to hit; under qemu-user it was hit
# now and then. Judged outside in by strace: each thread the program creates (clone/clone3
# returning its id) makes its own exit() call before the program's exit_group().
#   example_threads_check.sh EXAMPLES_DIR MAKE_DDS_SECURITY
# Run inside in_private_net.sh (the examples' loopback discovery stays in it).
set -u
bin=$1 make=$2
d=$(mktemp -d)
trap 'rm -rf "$d"' EXIT
# The cab's set, and another cab's (its CA did not issue this cab's certificates).
for set in set other; do
  "$make" --partition oegw "$d/$set" >/dev/null || { echo "FAIL: make-dds-security.sh"; exit 1; }
done
s=$d/set
# The security options of identity $1 with identity CA $2 (default: the cab's own).
sec() {
  echo "--identity-ca ${2:-$s/ca.pem} --certificate $s/$1.pem --private-key $s/$1.key --permissions-ca $s/ca.pem" \
       "--governance $s/governance.p7s --permissions $s/permissions.p7s"
}
fails=0
# expect RC WHAT PROGRAM ARG...: the program exits RC, and every thread it made ended before it.
expect() {
  want_rc=$1 what=$2
  shift 2
  strace -f -qq -o "$d/trace" -e trace=clone,clone3,exit,exit_group "$@" >"$d/out" 2>&1
  rc=$?
  # The threads made: a clone's return value (with -f, often on its "resumed" line).
  made=$(grep -E 'clone3?\(|clone3? resumed' "$d/trace" | sed -n 's/.*) = \([0-9][0-9]*\)$/\1/p' | sort -u)
  end=$(grep -n 'exit_group(' "$d/trace" | head -1 | cut -d: -f1)
  running=""
  for t in $made; do
    # strace pads the pid column ("%-5d "): one space after a 5-digit id, two after a 4-digit one.
    at=$(grep -nE "^$t +exit\(" "$d/trace" | head -1 | cut -d: -f1)
    if [ -z "$at" ] || [ -z "$end" ] || [ "$at" -gt "$end" ]; then running="$running $t"; fi
  done
  n=$(echo "$made" | grep -c .)
  if [ "$rc" -ne "$want_rc" ]; then
    echo "FAIL: $what: exit $rc, expected $want_rc"; sed 's/^/  | /' "$d/out"; fails=$((fails + 1))
  elif [ "$n" -eq 0 ]; then
    echo "FAIL: $what: strace saw no thread made (the check would prove nothing)"; fails=$((fails + 1))
  elif [ -n "$running" ]; then
    echo "FAIL: $what: exit_group with $(echo "$running" | wc -w) of its $n threads still running:$running"
    fails=$((fails + 1))
  else
    echo "ok: $what: exit $rc; its $n threads all ended before exit_group"
  fi
}
opts="--network loopback --partition oegw"
# shellcheck disable=SC2046,SC2086 # the options, split on purpose
{
  expect 0 "dds_subscriber at its timeout" "$bin/dds_subscriber" $opts --timeout 1
  expect 0 "dds_subscriber with DDS Security at its timeout" "$bin/dds_subscriber" $opts --timeout 1 $(sec app)
  expect 3 "dds_status, no status within its timeout" "$bin/dds_status" $opts --timeout 1
  expect 3 "dds_command with DDS Security, no reader within its timeout" \
    "$bin/dds_command" $opts --timeout 1 $(sec app) indicators 1 --on 1
  # The read-only identity may not publish: the writer is refused after the domain was made.
  expect 1 "dds_command as the read-only identity (writer refused)" \
    "$bin/dds_command" $opts --timeout 1 $(sec monitor) indicators 1 --on 1
  # A certificate the identity CA did not issue: the participant is refused after the domain was made.
  expect 1 "dds_subscriber with another cab's identity CA (participant refused)" \
    "$bin/dds_subscriber" $opts --timeout 1 $(sec app "$d/other/ca.pem")
}
[ "$fails" -eq 0 ] || { echo "$fails failed"; exit 1; }
