#!/bin/sh
# /init of the oegw test-VM initramfs (copied there by prepare.sh).
#
# Loads the modules listed in /modules/order, mounts the host root read-only
# (9p tag "hostroot") on /newroot and the host's writable result dir (9p tag
# "out") on /out, gives the chroot a writable /tmp (tmpfs overlay over the
# host's) and tmpfs /run plus /proc,
# /sys, /dev, creates vcan0 and vcan1, then runs /out/job.sh (written by
# run-in-vm.sh) in the chroot. Its output goes to the console and to
# /out/output.log, its exit status to /out/rc. Then the VM powers off.
#
# With oegw.systemd=1 on the kernel command line (run-in-vm.sh --systemd) the
# guest boots the host's real systemd as PID 1 instead: the whole host root
# (read-only 9p) under an overlay with a tmpfs upper layer is the new root, so
# /etc, /var and /usr are writable (writes stay in the guest); the same /run,
# /run/oegw-out and vcan0/vcan1; then units in /etc/systemd/system (written
# here) run the job as oegw-vmtest.service under --unit=oegw-vmtest.target,
# and `exec switch_root` hands PID 1 to /lib/systemd/systemd. The job's
# output and status go to the same places; the unit powers the VM off.
export PATH=/bin

say() { echo "oegw-vm: $*"; }
halt() {
  sync
  umount /newroot/run/oegw-out 2>/dev/null
  umount /out 2>/dev/null
  poweroff -f
  reboot -f
  # Never return: PID 1 exiting panics the kernel (panic=-1 reboots, and
  # -no-reboot turns that into a qemu exit).
  sleep 10; exit 1
}
fail() {
  say "BOOT FAILURE: $*"
  [ -w /out ] && echo "boot failure: $*" >/out/boot-error
  halt
}

/bin/busybox --install -s /bin
mount -t proc proc /proc
mount -t sysfs sysfs /sys
mount -t devtmpfs devtmpfs /dev 2>/dev/null
if grep -q 'oegw.debug=1' /proc/cmdline; then
  set -x
  say "debug boot; uptime $(cut -d' ' -f1 /proc/uptime)s"
else
  echo 1 >/proc/sys/kernel/printk 2>/dev/null  # keep the console for test output
fi

for m in $(cat /modules/order); do
  insmod "/modules/$m" || fail "insmod $m"
done

# virtio devices appear asynchronously; retry the mounts briefly.
mount9p() {  # tag dir options
  i=0
  while ! mount -t 9p -o "trans=virtio,version=9p2000.L,msize=512000,$3" "$1" "$2" 2>/dev/null; do
    i=$((i + 1))
    [ $i -ge 50 ] && return 1
    sleep 0.1
  done
}
mount9p out /out "" || fail "mount 9p 'out' (is -virtfs ...mount_tag=out given?)"
: >/out/booted
systemd=0
grep -q 'oegw.systemd=1' /proc/cmdline && systemd=1
r=/newroot
if [ $systemd = 1 ]; then
  # systemd wants a writable /etc and /var: the whole host root (read-only
  # 9p) under a tmpfs overlay. /tmp is part of it (the host's /tmp shows
  # through, writes stay in the guest), as the chroot's /tmp overlay below.
  mkdir -p /lower /scratch
  mount9p hostroot /lower "ro,cache=loose" || fail "mount 9p 'hostroot'"
  mount -t tmpfs -o mode=755,size=75% tmpfs /scratch || fail "tmpfs on /scratch"
  mkdir -p /scratch/upper /scratch/work
  mount -t overlay -o lowerdir=/lower,upperdir=/scratch/upper,workdir=/scratch/work overlay $r ||
    fail "overlay on / (systemd boot)"
else
  mount9p hostroot /newroot "ro,cache=loose" || fail "mount 9p 'hostroot'"
  # /tmp: the host's /tmp (read-only 9p) under a tmpfs overlay, so paths in
  # the host's /tmp (a checkout, a build dir) work unchanged and /tmp is
  # writable; writes stay in the guest.
  mkdir -p /scratch && mount -t tmpfs -o mode=755 tmpfs /scratch || fail "tmpfs on /scratch"
  mkdir -p /scratch/upper /scratch/work && chmod 1777 /scratch/upper
  mount -t overlay -o lowerdir=$r/tmp,upperdir=/scratch/upper,workdir=/scratch/work overlay $r/tmp ||
    fail "overlay on /tmp"
fi
mount -t tmpfs -o mode=755 tmpfs $r/run || fail "tmpfs on /run"
mkdir -p $r/run/oegw-out && mount --bind /out $r/run/oegw-out || fail "bind /out"
mount -t proc proc $r/proc || fail "proc"
mount -t sysfs sysfs $r/sys || fail "sysfs"
mount -t devtmpfs devtmpfs $r/dev || fail "devtmpfs"
mkdir -p $r/dev/pts $r/dev/shm
mount -t devpts devpts $r/dev/pts
mount -t tmpfs -o mode=1777 tmpfs $r/dev/shm

# The systemd boot (oegw.systemd=1): the job runs as a service of the host's
# systemd, PID 1 after switch_root. oegw-vmtest.target (the default unit,
# systemd's --unit=) pulls in basic.target and the job's
# service; what cannot or need not run in this guest is masked: no kernel
# modules of this kernel on the host root (modules-load, kmod-static-nodes),
# no network (timesyncd), nothing to persist (random seed, journal flush,
# machine-id commit, utmp), no first boot, no timers (apt-daily would start
# apt), no binfmt, pstore, repart, TPM (pcrphase), sysusers, no fstab to
# remount, no debug/tracing/config/fuse/hugepage file systems (each a unit
# start: under TCG on a busy host they cost seconds). journald, sysctl,
# tmpfiles and the rest of sysinit.target run as on the cab controller.
boot_systemd() {
  u=$r/etc/systemd/system
  mkdir -p $u $r/run/oegw-vm $r/etc/tmpfiles.d || fail "cannot write units to $u"
  # The host may be a docker container: its /.dockerenv would make systemd take
  # the guest for one too (and then ignore the kernel command line).
  rm -f $r/.dockerenv
  # tmpfiles.d/tmp.conf's "D /tmp" empties /tmp at boot: over 9p, a walk of the
  # host's whole /tmp (tens of seconds), and its files would no longer show.
  : >$r/etc/tmpfiles.d/tmp.conf
  for m in systemd-timesyncd.service systemd-pstore.service systemd-binfmt.service \
           proc-sys-fs-binfmt_misc.automount systemd-firstboot.service systemd-journal-flush.service \
           systemd-machine-id-commit.service systemd-modules-load.service kmod-static-nodes.service \
           systemd-random-seed.service systemd-repart.service systemd-pcrphase.service \
           systemd-pcrphase-sysinit.service systemd-sysusers.service systemd-update-utmp.service \
           ldconfig.service systemd-journal-catalog-update.service systemd-update-done.service \
           timers.target getty.target serial-getty@ttyS0.service systemd-remount-fs.service \
           modprobe@.service dev-hugepages.mount sys-kernel-debug.mount sys-kernel-tracing.mount \
           sys-kernel-config.mount sys-fs-fuse-connections.mount; do
    rm -f $u/$m && ln -s /dev/null $u/$m || fail "mask $m"
  done
  cat >$u/oegw-vmtest.target <<EOT || fail "write oegw-vmtest.target"
[Unit]
Description=oegw VM test (tests/vm/init.sh)
Requires=basic.target
Wants=oegw-vmtest.service
After=basic.target oegw-vmtest.service
AllowIsolate=yes
# A boot that never gets to the job powers off rather than waiting for the VM's time limit.
JobTimeoutSec=180
JobTimeoutAction=poweroff-force
EOT
  cat >$u/oegw-vmtest.service <<EOT || fail "write oegw-vmtest.service"
[Unit]
Description=oegw VM test job (/run/oegw-out/job.sh)
After=basic.target
SuccessAction=poweroff-force
FailureAction=poweroff-force
[Service]
Type=exec
ExecStart=/bin/bash /run/oegw-vm/job-service.sh
StandardInput=null
StandardOutput=tty
StandardError=inherit
TTYPath=/dev/console
EOT
  # The service: the job with the chroot's environment, its output to the
  # console and output.log, its status to rc. What the job leaves running in
  # this service's cgroup is killed once its main process exits (as above).
  cat >$r/run/oegw-vm/job-service.sh <<EOT || fail "write job-service.sh"
cd /
echo "oegw-vm: systemd \$(systemctl --version | head -1 | cut -d' ' -f2) is PID 1: running job (uptime \$(cut -d' ' -f1 /proc/uptime)s)"
mkfifo /run/oegw-vm/joblog
tee /run/oegw-out/output.log </run/oegw-vm/joblog &
teepid=\$!
/usr/bin/env -i $ENV /bin/bash /run/oegw-out/job.sh </dev/null >/run/oegw-vm/joblog 2>&1
rc=\$?
for p in \$(cat "/sys/fs/cgroup\$(cut -d: -f3 /proc/self/cgroup)/cgroup.procs"); do
  [ "\$p" = \$\$ ] || [ "\$p" = "\$teepid" ] || kill -9 "\$p" 2>/dev/null
done
wait \$teepid
[ \$rc = 0 ] || journalctl -b --no-pager -o short-monotonic >/run/oegw-out/journal.log 2>&1
echo \$rc >/run/oegw-out/rc
echo "oegw-vm: job exit status \$rc"
sync
EOT
  say "switching root to systemd (uptime $(cut -d' ' -f1 /proc/uptime)s)"
  # fail speaks only if exec cannot start switch_root.
  # shellcheck disable=SC2093
  exec switch_root $r /lib/systemd/systemd --unit=oegw-vmtest.target
  fail "switch_root to /lib/systemd/systemd"
}

# The chroot's /lib/modules is the host's and lacks this kernel: CAN modules
# are already loaded from the initramfs, so nothing needs modprobe later.
ENV="PATH=/usr/local/bin:/usr/bin:/bin:/usr/local/sbin:/usr/sbin:/sbin HOME=/tmp LANG=C.UTF-8 TERM=dumb OEGW_VM=1 OEGW_VM_OUT=/run/oegw-out"
# $ENV is split into its VAR=value words on purpose (env -i takes each); $r and $ip have no blanks.
ip=/bin/ip; [ -x $r/sbin/ip ] && ip=/sbin/ip; [ -x $r/usr/sbin/ip ] && ip=/usr/sbin/ip
# shellcheck disable=SC2086
chroot $r /usr/bin/env -i $ENV $ip link set lo up || fail "ip link set lo up"
# shellcheck disable=SC2086
for d in vcan0 vcan1; do
  chroot $r /usr/bin/env -i $ENV $ip link add dev $d type vcan || fail "ip link add $d type vcan"
  chroot $r /usr/bin/env -i $ENV $ip link set $d up || fail "ip link set $d up"
done
[ -f /out/job.sh ] || fail "no job.sh in the out dir"

if [ $systemd = 1 ]; then
  boot_systemd  # does not return
fi

say "ready: running job (uptime $(cut -d' ' -f1 /proc/uptime)s)"
# Output goes through a fifo to tee, so that processes the job leaves behind
# (e.g. a background candump) cannot keep us waiting: they are killed once
# the job's main process exits.
mkfifo /joblog
tee /out/output.log </joblog &
teepid=$!
# shellcheck disable=SC2086  # $ENV: its words, as above
chroot $r /usr/bin/env -i $ENV /bin/bash /run/oegw-out/job.sh </dev/null >/joblog 2>&1
rc=$?
for p in /proc/[0-9]*; do
  p=${p#/proc/}
  [ "$p" = 1 ] || [ "$p" = $$ ] || [ "$p" = "$teepid" ] || kill -9 "$p" 2>/dev/null
done
wait $teepid
echo $rc >/out/rc
say "job exit status $rc"
halt
