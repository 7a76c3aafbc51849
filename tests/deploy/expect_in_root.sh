# shellcheck shell=bash
# $src and $root are the sourcing script's.
# shellcheck disable=SC2154
# Sourced by the deploy tests (deb_install_test.sh, cross_install_test.sh): runs an installed
# program inside the fresh root $root with chroot, in a network namespace of its own
# (tests/publish/in_private_net.sh: the demo's DDS/LCM traffic meets no other test's subscribers
# on this host), with a clean environment. Needs $src (the source tree), $root, die and note.
expect() {  # name pattern command...: exit 0 and the pattern (grep -E) in the output
  local name=$1 pattern=$2 out rc=0
  shift 2
  out=$("$src/tests/publish/in_private_net.sh" chroot "$root" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin \
        LANG=C.UTF-8 HOME=/root "$@" 2>&1) || rc=$?
  if [[ $rc -ne 0 ]] || ! grep -Eq -- "$pattern" <<<"$out"; then
    printf '%s\n' "$out" | tail -30
    die "$name: exit $rc, expected exit 0 and /$pattern/"
  fi
  note "ok: $name"
}
