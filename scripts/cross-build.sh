#!/usr/bin/env bash
# Cross-builds oegw for a cab controller and runs its tests under qemu-user
# (docs/guides/build-and-package.md#building-for-the-cab-controller).
#
#   scripts/cross-build.sh [options] arm64|armhf|all
#
# For each architecture, in build-<arch> (OEGW_CROSS_BUILD_PREFIX overrides "build-"):
#   1. this machine's tools (scripts/install-deps.sh: the native build's packages, the cross
#      compilers crossbuild-essential-arm64/-armhf, qemu-user-static, mmdebstrap); qemu registered
#      with binfmt_misc for the target's ELF files (a test that starts oegw itself runs it emulated)
#   2. the sysroot of the target's Debian library packages (scripts/cross-sysroot.sh, cached)
#   3. the build (RelWithDebInfo, the test tiers, no benchmarks) with the toolchain file
#      cmake/toolchains/<triplet>.cmake
#   4. the unit and integration tests under qemu-user: ctest without the labels vm (a kernel with
#      SocketCAN in a VM), deploy (the amd64 package in an amd64 root), bench, fuzz,
#      no-qemu-user (what qemu-user cannot emulate: tests/CMakeLists.txt, OEGW_NO_QEMU_USER) and
#      lint, layers, docs (checks of the sources and documents, run natively); one CTest test per
#      test program there (OEGW_TESTS_PER_EXECUTABLE), all its cases in one process;
#      safety_random_test with its first seed only (OEGW_SAFETY_SEED=1; natively every seed)
#   5. the Debian package oegw_<version>_<arch>.deb from that tree (scripts/package.sh --from):
#      its Architecture and its Depends (dpkg-shlibdeps against the sysroot) checked
#
# Options:
#   --no-tests      skip step 4
#   --install       6. install the package into a fresh Debian root of that architecture
#                   (mmdebstrap, maintainer scripts under qemu) and run `oegw check
#                   /etc/oegw/oegw.yaml`, `oegw demo --fast` there (minutes per architecture)
#   --bench         7. build the benchmarks and run each once under qemu-user (emulated figures:
#                   for regressions between runs of this command only, not the board's speed)
# Needs root (apt-get, mmdebstrap, binfmt_misc). Exits non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."

tests=1 install=0 bench=0 arches=()
while [[ $# -gt 0 ]]; do
  case $1 in
    --no-tests) tests=0 ;;
    --install) install=1 ;;
    --bench) bench=1 ;;
    arm64|armhf) arches+=("$1") ;;
    all) arches+=(arm64 armhf) ;;
    -h|--help) sed -n '2,/^[^#]/p' "$0" | sed '$d'; exit 0 ;;  # the header comment
    *) echo "cross-build: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
  shift
done
[[ ${#arches[@]} -gt 0 ]] || { echo "usage: scripts/cross-build.sh [--no-tests] [--install] [--bench] arm64|armhf|all" >&2; exit 2; }
[[ $(id -u) -eq 0 ]] || { echo "cross-build: needs root (apt-get, mmdebstrap, binfmt_misc)" >&2; exit 1; }

note() { echo "cross-build: $*"; }
die() { echo "cross-build: FAILED: $*" >&2; exit 1; }
start=$SECONDS

triplet_of() { case $1 in arm64) echo aarch64-linux-gnu ;; armhf) echo arm-linux-gnueabihf ;; esac; }
qemu_of() { case $1 in arm64) echo aarch64 ;; armhf) echo arm ;; esac; }

# --- 1. this machine's tools -------------------------------------------------------------------------
# install-deps.sh: the native build's packages, crossbuild-essential-arm64/-armhf, qemu-user-static,
# mmdebstrap, arch-test.
./scripts/install-deps.sh --tests

# binfmt_misc: the kernel starts a target ELF file through qemu-<cpu>-static. qemu-user-static's
# own registration needs systemd-binfmt or binfmt-support running, which a container or CI
# machine may lack; its /usr/lib/binfmt.d files are written here directly. Their flag F opens the
# emulator now, so it also runs inside a chroot that does not contain it.
binfmt=/proc/sys/fs/binfmt_misc
[[ -e $binfmt/register ]] || mount -t binfmt_misc binfmt_misc "$binfmt" ||
  die "cannot mount binfmt_misc on $binfmt (a test that starts a target program needs it)"
for a in "${arches[@]}"; do
  q=qemu-$(qemu_of "$a")
  # An entry without F (registered otherwise) cannot start the emulator inside a chroot: replaced.
  if [[ -e $binfmt/$q ]] && ! grep -q '^flags:.*F' "$binfmt/$q"; then
    echo -1 >"$binfmt/$q"
  fi
  if [[ ! -e $binfmt/$q ]]; then
    cat "/usr/lib/binfmt.d/$q.conf" >"$binfmt/register" || die "cannot register $q with binfmt_misc"
  fi
  grep -qx enabled "$binfmt/$q" || die "$binfmt/$q is disabled"
done

for arch in "${arches[@]}"; do
  t0=$SECONDS
  triplet=$(triplet_of "$arch")
  build=${OEGW_CROSS_BUILD_PREFIX:-build-}$arch
  # --- 2. the sysroot ------------------------------------------------------------------------------
  sysroot=$(./scripts/cross-sysroot.sh "$arch" | tail -n1)
  # Every target program started here, by ctest through the emulator or by a test through
  # binfmt_misc, loads its dynamic loader and libraries from the sysroot.
  export QEMU_LD_PREFIX=$sysroot

  # --- 3. the build ----------------------------------------------------------------------------------
  # ccache, when installed, comes from CMakeLists.txt (OEGW_CCACHE).
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
        -DCMAKE_TOOLCHAIN_FILE="$PWD/cmake/toolchains/$triplet.cmake" -DOEGW_SYSROOT="$sysroot" \
        -DOEGW_VM_TESTS=OFF -DOEGW_BUILD_BENCH="$([[ $bench -eq 1 ]] && echo ON || echo OFF)" \
        >/dev/null
  t=$SECONDS
  cmake --build "$build" -j "${OEGW_CROSS_JOBS:-2}"
  file -b "$build/programs/oegw" | grep -q "$(case $arch in arm64) echo 'ARM aarch64' ;; armhf) echo 'ARM, EABI5' ;; esac)" ||
    die "$build/programs/oegw is not an $arch program: $(file -b "$build/programs/oegw")"
  note "$arch: built in $((SECONDS - t)) s: $(file -b "$build/programs/oegw" | cut -d, -f1-2)"

  # --- 4. the tests under qemu-user ------------------------------------------------------------------
  if [[ $tests -eq 1 ]]; then
    t=$SECONDS
    # The checks of the sources and documents (lint, layers, docs) are the same on every
    # architecture: they run natively only. The seeded random safety scenarios run their first
    # seed here (each seed is minutes under emulation); natively they run every seed.
    OEGW_SAFETY_SEED=${OEGW_SAFETY_SEED:-1} \
      ctest --test-dir "$build" -LE 'vm|deploy|bench|fuzz|no-qemu-user|lint|layers|docs' --output-on-failure \
      --timeout 900 -j "${OEGW_CROSS_JOBS:-2}"
    note "$arch: tests under qemu-user in $((SECONDS - t)) s"
  fi

  # --- 5. the package ----------------------------------------------------------------------------------
  t=$SECONDS
  rm -rf "$build/pkg"
  deb=$(./scripts/package.sh --from "$build" --out "$build/pkg" | tail -n1)
  [[ $(dpkg-deb -f "$deb" Architecture) == "$arch" ]] || die "$deb: Architecture $(dpkg-deb -f "$deb" Architecture), expected $arch"
  depends=$(dpkg-deb -f "$deb" Depends)
  # The libraries the programs link, each as the Debian package that ships its soname.
  names=$(sed -e 's/ ([^)]*)//g' -e 's/, */\n/g' <<<"$depends")
  for lib in libc6 libstdc++6 libddsc0debian liblcm1 libsystemd0 libssl3; do
    grep -Fqx "$lib" <<<"$names" || die "$deb: Depends lacks $lib: $depends"
  done
  note "$arch: $(basename "$deb") ($((SECONDS - t)) s), Depends: $depends"

  # --- 6. installed into a fresh root of the architecture ----------------------------------------------
  if [[ $install -eq 1 ]]; then
    ./tests/deploy/cross_install_test.sh "$arch" "$deb"
  fi

  # --- 7. the benchmarks, once, emulated ---------------------------------------------------------------
  if [[ $bench -eq 1 ]]; then
    for b in "$build"/tests/bench/oegw_bench_*; do
      [[ -x $b ]] || continue
      case $b in *oegw_bench_publish) continue ;; esac  # two processes and a network: native tier only
      echo "== $arch (qemu-user, emulated): $(basename "$b")"
      case $b in
        *oegw_bench_rss | *oegw_bench_cab_timing) "$b" ;;  # not Google Benchmarks (as test-all.sh)
        *) "$b" --benchmark_min_time=0.2 ;;
      esac
    done
  fi
  note "$arch: done in $((SECONDS - t0)) s"
done
note "all done in $((SECONDS - start)) s"
