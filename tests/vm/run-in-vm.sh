#!/bin/bash
# Boot the oegw test VM (qemu, TCG, no network) and run a script in it.
#
# Usage: tests/vm/run-in-vm.sh [--cwd DIR] [--timeout SECONDS] [--kvaser N] [--systemd] <guest-script> [args...]
#
# The guest sees the host's root file system read-only (as its own root, in a
# chroot), with a writable tmpfs overlay on /tmp (host files show through,
# writes stay in the guest), tmpfs /run, HOME=/tmp, and vcan0 + vcan1 up.
# --kvaser N (or OEGW_VM_KVASER=N) adds N emulated kvaser_pci boards (one
# SJA1000 each) on one emulated CAN bus: the guest gets can0 .. can<N-1>,
# real CAN interfaces with bit timing, down and without a bit rate.
# --systemd (or OEGW_VM_SYSTEMD=1) boots the host's systemd as PID 1 on an
# overlay of the host root (tmpfs upper: /etc, /var, /usr writable in the
# guest) and runs the script as a service of it (init.sh "systemd boot").
# <guest-script> is a path on the host (relative paths are taken from the
# current directory); it runs with cwd = --cwd (default: the current
# directory), under bash if it is not executable. $OEGW_VM_OUT in the guest
# is a writable directory that ends up in this run's out dir on the host.
#
# Exit status: the guest script's; 124 on timeout; 125 if the VM failed to
# boot or never reported a status (messages say which).
#
# Environment:
#   OEGW_VM_CACHE    cache dir of prepare.sh (default ${XDG_CACHE_HOME:-$HOME/.cache}/oegw-vm)
#   OEGW_VM_TIMEOUT  hard limit for the whole VM run in seconds (default 300)
#   OEGW_VM_OUT      out dir to use (default: a new dir under $OEGW_VM_CACHE/runs)
#   OEGW_VM_KEEP=1   keep the out dir after success (it is always kept on failure)
#   OEGW_VM_QUIET=1  do not echo the serial console live (it is still logged)
#   OEGW_VM_MEM      guest memory in MiB (default 1024)
#   OEGW_VM_CPU      qemu -cpu model (default max)
#   OEGW_VM_DEBUG=1  verbose boot: kernel messages and a trace of the guest's init
#   OEGW_VM_KVASER   number of emulated kvaser_pci CAN controllers (default 0; --kvaser)
#   OEGW_VM_SYSTEMD=1  boot systemd as PID 1 (--systemd)
set -uo pipefail

die() { echo "run-in-vm.sh: error: $*" >&2; exit 125; }

cwd=$PWD
timeout_s=${OEGW_VM_TIMEOUT:-300}
kvaser=${OEGW_VM_KVASER:-0}
systemd=${OEGW_VM_SYSTEMD:-0}
while (($#)); do
  case $1 in
    --cwd) cwd=${2:?--cwd needs a dir}; shift 2 ;;
    --timeout) timeout_s=${2:?--timeout needs seconds}; shift 2 ;;
    --kvaser) kvaser=${2:?--kvaser needs a number}; shift 2 ;;
    --systemd) systemd=1; shift ;;
    --) shift; break ;;
    -h|--help) sed -n '2,/^set -u/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    -*) die "unknown option $1" ;;
    *) break ;;
  esac
done
(($#)) || die "usage: run-in-vm.sh [--cwd DIR] [--timeout S] [--kvaser N] [--systemd] <guest-script> [args...]"
[[ $kvaser =~ ^[0-9]$ ]] || die "--kvaser / OEGW_VM_KVASER must be 0..9, not '$kvaser'"
script=$(realpath -e -- "$1") || die "guest script $1 not found"
shift
cwd=$(realpath -e -- "$cwd") || die "cwd not found"

cache=${OEGW_VM_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/oegw-vm}
kdir="$cache/current"
[[ -e $kdir/ok && -f $kdir/vmlinuz && -f $kdir/initramfs.cpio.gz ]] ||
  die "no prepared kernel in $cache: run tests/vm/prepare.sh${OEGW_VM_CACHE:+ $OEGW_VM_CACHE} first"
command -v qemu-system-x86_64 >/dev/null || die "qemu-system-x86_64 missing (apt-get install qemu-system-x86)"

if [[ -n ${OEGW_VM_OUT:-} ]]; then
  out=$OEGW_VM_OUT
  mkdir -p "$out" || die "cannot create $out"
  rm -f "$out"/{rc,rc.tmp,booted,boot-error,output.log,serial.log,job.sh}
else
  mkdir -p "$cache/runs" || die "cannot create $cache/runs"
  # Old kept runs (failures, OEGW_VM_KEEP) are removed after two days.
  find "$cache/runs" -mindepth 1 -maxdepth 1 -mtime +2 -exec rm -rf {} + 2>/dev/null
  out=$(mktemp -d "$cache/runs/run.XXXXXX") || die "mktemp failed"
fi
out=$(realpath "$out")

# Inside the guest, /tmp is the host's /tmp under a writable tmpfs overlay;
# /run is a fresh tmpfs, so nothing of the host's /run is visible.
for p in "$script" "$cwd"; do
  case $p in /run|/run/*) die "$p: the host's /run is not visible in the guest" ;; esac
done
# The job: cd, then run the script with its arguments. printf %q quoting is
# bash syntax; init.sh runs job.sh with the chroot's (= the host's) bash.
{
  echo "cd $(printf %q "$cwd") || { echo 'run-in-vm.sh: cannot cd to guest cwd' >&2; exit 125; }"
  if [[ -x $script ]]; then
    printf 'exec %q' "$script"
  else
    printf 'exec /bin/bash %q' "$script"
  fi
  for a in "$@"; do printf ' %q' "$a"; done
  echo
} >"$out/job.sh"

serial="$out/serial.log"
# The guest's clock is the emulated HPET, never its TSC. Under TCG the guest's TSC is the host's
# raw rdtsc, and the hosts this runs on are VMs whose own kernel is told tsc=unstable (their TSC
# jumps when the VM is paused or moved; their kvm-clock is what hides that). With tsc=reliable the
# guest once trusted it: its CLOCK_MONOTONIC leapt ~5 h within a 160 s test (vm_ctl in CI: every
# time-out fired at once, `oegw ctl` gave up on a fastscan that had not even finished). QEMU's HPET
# counts QEMU_CLOCK_VIRTUAL, the host's CLOCK_MONOTONIC. selftest.sh checks the choice.
append="console=ttyS0 panic=-1 rdinit=/init mitigations=off clocksource=hpet tsc=unstable no_timer_check i8042.noaux i8042.nokbd nomodeset"
if [[ ${OEGW_VM_DEBUG:-0} == 1 ]]; then
  append+=" loglevel=7 oegw.debug=1"   # kernel messages and init's trace on the console
else
  append+=" quiet loglevel=1"
fi
# systemd as PID 1 (init.sh, which names the test's target as the default unit); a crash of
# PID 1 reboots, which -no-reboot turns into qemu's exit.
[[ $systemd == 1 ]] && append+=" oegw.systemd=1 systemd.crash_reboot=1"
qemu=(qemu-system-x86_64
  -accel tcg -machine q35 -cpu "${OEGW_VM_CPU:-max}" -smp 1 -m "${OEGW_VM_MEM:-1024}"
  -nic none -no-reboot -nodefaults -display none -monitor none
  -chardev "file,id=con,path=$serial,append=on" -serial chardev:con
  -kernel "$kdir/vmlinuz" -initrd "$kdir/initramfs.cpio.gz"
  -append "$append"
  -virtfs "local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap"
  -virtfs "local,path=$out,mount_tag=out,security_model=none,multidevs=remap"
)
# Emulated SJA1000 controllers (kvaser_pci), all on one emulated bus cb0.
# The commas are qemu's own syntax (one argument each), not array separators.
# shellcheck disable=SC2054
if ((kvaser > 0)); then
  qemu+=(-object can-bus,id=cb0)
  for ((i = 0; i < kvaser; i++)); do qemu+=(-device kvaser_pci,canbus=cb0); done
fi

start=$(date +%s.%N)
: >"$serial"
# Echo the console live unless quiet; tail stops when qemu is done.
tail_pid=
if [[ ${OEGW_VM_QUIET:-0} != 1 ]]; then
  tail -n +1 -f --pid=$$ "$serial" 2>/dev/null &   # --pid: ends with us even on SIGKILL
  tail_pid=$!
fi
# qemu under timeout(1), which --kill-after makes sure it dies even if it
# ignores SIGTERM. setpriv --pdeathsig: if this script is killed outright
# (SIGKILL), timeout gets SIGTERM and passes it on to qemu.
pdeath=()
setpriv --help 2>/dev/null | grep pdeathsig >/dev/null && pdeath=(setpriv --pdeathsig TERM)
"${pdeath[@]}" timeout --kill-after=10 "$timeout_s" "${qemu[@]}" </dev/null >"$out/qemu.log" 2>&1 &
qpid=$!
# If we are stopped (ctest timeout, ^C), take qemu with us.
trap 'kill -TERM "$qpid" 2>/dev/null; wait "$qpid" 2>/dev/null; [[ -n $tail_pid ]] && kill "$tail_pid" 2>/dev/null; echo "run-in-vm.sh: interrupted; serial log: $serial" >&2; exit 143' TERM INT HUP
wait "$qpid"
qrc=$?
trap - TERM INT HUP
if [[ -n $tail_pid ]]; then
  sleep 0.2
  kill "$tail_pid" 2>/dev/null
  wait "$tail_pid" 2>/dev/null
fi
elapsed=$(awk -v s="$start" -v e="$(date +%s.%N)" 'BEGIN { printf "%.1f", e - s }')

fail_keep() {  # status message
  echo "run-in-vm.sh: FAIL: $2 (after ${elapsed}s)" >&2
  [[ -s $out/qemu.log ]] && sed 's/^/run-in-vm.sh: qemu: /' "$out/qemu.log" >&2
  echo "run-in-vm.sh: serial log: $serial" >&2
  exit "$1"
}

if ((qrc == 124 || qrc == 137)); then
  fail_keep 124 "VM timed out after ${timeout_s}s (OEGW_VM_TIMEOUT)"
fi
if [[ -f $out/boot-error ]]; then
  fail_keep 125 "VM boot failed: $(cat "$out/boot-error")"
fi
if [[ ! -f $out/rc ]]; then
  if [[ -f $out/booted ]]; then
    fail_keep 125 "VM booted but the job reported no exit status (qemu exit $qrc)"
  fi
  fail_keep 125 "VM never booted far enough to mount the out dir (qemu exit $qrc)"
fi
rc=$(cat "$out/rc")
[[ $rc =~ ^[0-9]+$ ]] || fail_keep 125 "garbage exit status '$rc'"
if ((rc != 0)); then
  fail_keep "$rc" "guest script $script exited $rc"
fi
echo "run-in-vm.sh: guest script exited 0 after ${elapsed}s" >&2
if [[ -z ${OEGW_VM_OUT:-} && ${OEGW_VM_KEEP:-0} != 1 ]]; then
  rm -rf "$out"
else
  echo "run-in-vm.sh: out dir: $out" >&2
fi
exit 0
