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
mount9p hostroot /newroot "ro,cache=loose" || fail "mount 9p 'hostroot'"

r=/newroot
# /tmp: the host's /tmp (read-only 9p) under a tmpfs overlay, so paths in
# the host's /tmp (a checkout, a build dir) work unchanged and /tmp is
# writable; writes stay in the guest.
mkdir -p /scratch && mount -t tmpfs -o mode=755 tmpfs /scratch || fail "tmpfs on /scratch"
mkdir -p /scratch/upper /scratch/work && chmod 1777 /scratch/upper
mount -t overlay -o lowerdir=$r/tmp,upperdir=/scratch/upper,workdir=/scratch/work overlay $r/tmp ||
  fail "overlay on /tmp"
mount -t tmpfs -o mode=755 tmpfs $r/run || fail "tmpfs on /run"
mkdir -p $r/run/oegw-out && mount --bind /out $r/run/oegw-out || fail "bind /out"
mount -t proc proc $r/proc || fail "proc"
mount -t sysfs sysfs $r/sys || fail "sysfs"
mount -t devtmpfs devtmpfs $r/dev || fail "devtmpfs"
mkdir -p $r/dev/pts $r/dev/shm
mount -t devpts devpts $r/dev/pts
mount -t tmpfs -o mode=1777 tmpfs $r/dev/shm

# The chroot's /lib/modules is the host's and lacks this kernel: CAN modules
# are already loaded from the initramfs, so nothing needs modprobe later.
ENV="PATH=/usr/local/bin:/usr/bin:/bin:/usr/local/sbin:/usr/sbin:/sbin HOME=/tmp LANG=C.UTF-8 TERM=dumb OEGW_VM=1 OEGW_VM_OUT=/run/oegw-out"
ip=/bin/ip; [ -x $r/sbin/ip ] && ip=/sbin/ip; [ -x $r/usr/sbin/ip ] && ip=/usr/sbin/ip
chroot $r /usr/bin/env -i $ENV $ip link set lo up || fail "ip link set lo up"
for d in vcan0 vcan1; do
  chroot $r /usr/bin/env -i $ENV $ip link add dev $d type vcan || fail "ip link add $d type vcan"
  chroot $r /usr/bin/env -i $ENV $ip link set $d up || fail "ip link set $d up"
done
[ -f /out/job.sh ] || fail "no job.sh in the out dir"

say "ready: running job (uptime $(cut -d' ' -f1 /proc/uptime)s)"
# Output goes through a fifo to tee, so that processes the job leaves behind
# (e.g. a background candump) cannot keep us waiting: they are killed once
# the job's main process exits.
mkfifo /joblog
tee /out/output.log </joblog &
teepid=$!
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
