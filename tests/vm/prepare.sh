#!/bin/bash
# Prepare the "real SocketCAN in a VM" test tier: fetch a Debian kernel
# (without installing it on the host), and build a small initramfs that loads
# the virtio/9p and CAN modules, mounts the host root read-only over 9p and
# chroots into it to run a test script (see docs/developer/vm-tier.md).
#
# Usage: tests/vm/prepare.sh [cache_dir]
#   cache_dir defaults to $OEGW_VM_CACHE or ${XDG_CACHE_HOME:-$HOME/.cache}/oegw-vm
#   OEGW_VM_KERNEL_PKG=linux-image-X-amd64 overrides the kernel package.
#
# Idempotent: a second run with a complete cache does nothing but check it.
# On success the cache holds current/vmlinuz and current/initramfs.cpio.gz
# (current -> kernels/<package>_<version>).
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
cache=${1:-${OEGW_VM_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/oegw-vm}}

die() { echo "prepare.sh: error: $*" >&2; exit 1; }
note() { echo "prepare.sh: $*" >&2; }

# --- tools we need on the host --------------------------------------------
missing=()
need() { command -v "$1" >/dev/null 2>&1 || missing+=("$1 (Debian package: $2)"); }
need apt-get apt
need apt-cache apt
need dpkg-deb dpkg
need cpio cpio
need gzip gzip
need depmod kmod
need modprobe kmod
need qemu-system-x86_64 qemu-system-x86
[[ -x /bin/busybox ]] || missing+=("/bin/busybox (Debian package: busybox-static)")
if ((${#missing[@]})); then
  die "missing host tools:$(printf '\n  %s' "${missing[@]}")
  install with: apt-get install qemu-system-x86 busybox-static can-utils python3-can kmod cpio iproute2"
fi
if ! /bin/busybox --list 2>/dev/null | grep -x insmod >/dev/null || ldd /bin/busybox >/dev/null 2>&1; then
  die "/bin/busybox must be a static busybox with insmod (Debian package busybox-static, not busybox)"
fi

mkdir -p "$cache/deb" "$cache/kernels" || die "cannot create cache dir $cache"
cache=$(cd "$cache" && pwd)
# One prepare at a time per cache (parallel ctest runs share it).
exec 9>"$cache/.lock"
flock 9 || die "cannot lock $cache/.lock"

# --- resolve the kernel package -------------------------------------------
pkg=${OEGW_VM_KERNEL_PKG:-}
resolve_kernel_pkg() {
  apt-cache depends linux-image-amd64 2>/dev/null |
    sed -n 's/^ *Depends: *\(linux-image-[0-9][^ ]*-amd64\) *$/\1/p' | head -n1
}
if [[ -z $pkg ]]; then
  pkg=$(resolve_kernel_pkg) || true
  # A fresh machine may have no apt lists yet: as root, fetch them once and ask again.
  if [[ -z $pkg && $(id -u) -eq 0 && ! -e $cache/current/ok ]]; then
    note "apt-cache knows no linux-image-amd64: running apt-get update"
    apt-get update -qq || true
    pkg=$(resolve_kernel_pkg) || true
  fi
fi
if [[ -z $pkg ]]; then
  if [[ -e $cache/current/ok ]]; then
    note "warning: cannot resolve linux-image-amd64 via apt-cache (no apt lists?); reusing cached $(readlink "$cache/current")"
    exit 0
  fi
  die "cannot resolve the kernel package from linux-image-amd64's Depends.
  Run 'apt-get update' first (apt-cache knows no linux-image-amd64), or set OEGW_VM_KERNEL_PKG."
fi

# Package version (for the cache key). apt-cache policy gives the candidate.
ver=$(apt-cache policy "$pkg" 2>/dev/null | sed -n 's/^ *Candidate: *//p' | head -n1) || true
[[ -n $ver && $ver != "(none)" ]] || ver=unknown
key="${pkg}_${ver//:/%3a}"
kdir="$cache/kernels/$key"

# The build depends on this script (its module list included) and init.sh:
# their hash is the stamp, so a changed module list rebuilds a shared cache.
recipe=$(cat "$here/prepare.sh" "$here/init.sh" | sha256sum | cut -d' ' -f1)
if [[ -e $kdir/ok && -e $kdir/initramfs.cpio.gz && -e $kdir/vmlinuz && \
      $(cat "$kdir/ok") == "$recipe" ]]; then
  ln -sfn "kernels/$key" "$cache/current"
  note "up to date: $kdir"
  exit 0
fi

# --- download + extract ------------------------------------------------------
deb=$(ls "$cache/deb/${pkg}_${ver//:/%3a}"_*.deb 2>/dev/null | head -n1 || true)
if [[ -z $deb ]]; then
  note "downloading $pkg ($ver) into $cache/deb"
  # apt-get download writes into the current directory. As root it warns
  # that the _apt sandbox user cannot write there; run it unsandboxed.
  if ! (cd "$cache/deb" && apt-get download -q -o APT::Sandbox::User="$(id -un)" "$pkg"); then
    if [[ -e $cache/current/ok ]]; then
      note "warning: apt-get download $pkg failed (stale apt lists? run 'apt-get update'); reusing cached $(readlink "$cache/current")"
      exit 0
    fi
    die "apt-get download $pkg failed (network? stale apt lists: run 'apt-get update')"
  fi
  deb=$(ls "$cache/deb/${pkg}"_*.deb 2>/dev/null | head -n1 || true)
  [[ -n $deb ]] || die "apt-get download $pkg produced no .deb in $cache/deb"
fi

rm -rf "$kdir.tmp"
mkdir -p "$kdir.tmp/tree"
note "extracting $(basename "$deb")"
dpkg-deb -x "$deb" "$kdir.tmp/tree" || die "dpkg-deb -x $deb failed"
tree="$kdir.tmp/tree"

moddir=$(ls -d "$tree"/lib/modules/*/ "$tree"/usr/lib/modules/*/ 2>/dev/null | head -n1 || true)
[[ -n $moddir ]] || die "no lib/modules/<version> in $deb"
kver=$(basename "$moddir")
# modprobe -d wants <root>/lib/modules/<kver>; newer Debian uses usr/lib.
case $moddir in
  "$tree"/usr/lib/*) modroot="$tree/usr" ;;
  *) modroot="$tree" ;;
esac
vmlinuz=$(ls "$tree"/boot/vmlinuz-* 2>/dev/null | head -n1 || true)
[[ -n $vmlinuz ]] || die "no boot/vmlinuz-* in $deb"

note "kernel $kver: running depmod"
depmod -b "$modroot" "$kver" || die "depmod -b $modroot $kver failed"

# --- module list, in load order ---------------------------------------------
# Each module's dependencies come first (modprobe --show-depends prints the
# chain in insmod order). can-gw is optional. can-dev, sja1000 and kvaser_pci
# drive the SJA1000 controllers qemu emulates (run-in-vm.sh --kvaser N): real
# CAN interfaces with bit timing (can0, can1, ...), absent without the option.
# This list is part of the cache key (the recipe hash below covers this file).
want=(virtio_pci 9pnet_virtio 9p overlay can can-raw vcan can-gw can-dev sja1000 kvaser_pci)
optional=" can-gw "
order=()
for m in "${want[@]}"; do
  if ! out=$(modprobe -d "$modroot" -S "$kver" --show-depends "$m" 2>&1); then
    [[ $optional == *" $m "* ]] && { note "optional module $m not available: skipped"; continue; }
    die "modprobe --show-depends $m failed: $out"
  fi
  while read -r kind path _; do
    [[ $kind == insmod ]] || continue   # 'builtin X' lines need nothing
    order+=("$path")
  done <<<"$out"
done

# --- build the initramfs ----------------------------------------------------
ird="$kdir.tmp/initramfs"
mkdir -p "$ird"/{bin,dev,proc,sys,newroot,out,modules}
cp /bin/busybox "$ird/bin/busybox"
ln -s busybox "$ird/bin/sh"
: >"$ird/modules/order"
declare -A seen=()
for p in "${order[@]}"; do
  [[ -n ${seen[$p]:-} ]] && continue
  seen[$p]=1
  # modprobe prints paths below $modroot (prefixed by it).
  [[ -f $p ]] || p="$modroot/${p#/}"
  [[ -f $p ]] || die "module file $p not found"
  name=$(basename "$p")
  case $name in
    *.ko.xz)  command -v xz >/dev/null || die "xz needed (xz-utils)"; xz -dc "$p" >"$ird/modules/${name%.xz}"; name=${name%.xz} ;;
    *.ko.zst) command -v zstd >/dev/null || die "zstd needed (zstd)"; zstd -qdc "$p" >"$ird/modules/${name%.zst}"; name=${name%.zst} ;;
    *.ko.gz)  gzip -dc "$p" >"$ird/modules/${name%.gz}"; name=${name%.gz} ;;
    *.ko)     cp "$p" "$ird/modules/$name" ;;
    *) die "unexpected module file $p" ;;
  esac
  echo "$name" >>"$ird/modules/order"
done
cp "$here/init.sh" "$ird/init"
chmod 755 "$ird/init"
(cd "$ird" && find . -print0 | LC_ALL=C sort -z | cpio --null -o -H newc --quiet -R 0:0) | gzip -6 >"$kdir.tmp/initramfs.cpio.gz"
cp "$vmlinuz" "$kdir.tmp/vmlinuz"
chmod 644 "$kdir.tmp/vmlinuz"
echo "$kver" >"$kdir.tmp/kver"
tr '\n' ' ' <"$ird/modules/order" >"$kdir.tmp/modules.txt"
rm -rf "$tree" "$ird"   # keep the cache small: vmlinuz + initramfs are all we need
echo "$recipe" >"$kdir.tmp/ok"
rm -rf "$kdir"
mv "$kdir.tmp" "$kdir"
ln -sfn "kernels/$key" "$cache/current"
# Keep only what is current: older kernel packages and their builds go.
find "$cache/kernels" -mindepth 1 -maxdepth 1 ! -name "$key" -exec rm -rf {} +
find "$cache/deb" -mindepth 1 -maxdepth 1 ! -name "$(basename "$deb")" -exec rm -f {} +
note "ready: $kdir (kernel $kver, initramfs $(du -h "$kdir/initramfs.cpio.gz" | cut -f1); modules: $(cat "$kdir/modules.txt"))"
