#!/usr/bin/env bash
# Installs, from Debian's packages, whatever the programs need and this machine lacks: what command
# 1 builds (the programs, their manual pages) and runs (`oegw demo`). Idempotent: with everything
# present it only checks (dpkg -s) and exits.
# --tests (scripts/test-all.sh, command 2; scripts/cross-build.sh) also installs what only the test
# tiers need: GoogleTest and Google Benchmark, clang (the fuzzers), the independent CAN peers and
# the SocketCAN-in-a-VM tier, the packaging and cross-build tools, node-canopen's node, chromium
# (the replay plot, headless), mkdocs (the documentation site) and man-db (`man -l`).
# Why each package is there: see docs/developer/dependencies.md.
set -euo pipefail

PACKAGES=(
  # build (ccache: fresh clones and the cross builds compile unchanged sources from its cache)
  g++ cmake ninja-build pkg-config ccache
  # the manual pages oegw(1) (help2man, from the --help texts) and oegw.yaml(5) (lowdown, from
  # docs/reference/mapping-file.md), made at build time (cmake/OegwMan.cmake)
  help2man lowdown
  # libraries (libsocketcan-dev: setting the CAN interfaces' bit rate over netlink)
  libcli11-dev libspdlog-dev libfmt-dev libyaml-cpp-dev libsocketcan-dev
  # the control socket's JSON (oegw status)
  nlohmann-json3-dev
  # zlib: the CRC-32 that tells a black box's state line from a torn or damaged one
  zlib1g-dev
  # Chart.js 3.9, inlined into the page `oegw replay --plot` writes (docs/guides/black-box.md)
  libjs-chart.js
  # publishing to the machine application: Cyclone DDS (C library + CMake package) and idlc,
  # which generates the DDS types from publish/oegw.idl at build time
  cyclonedds-dev cyclonedds-tools
  # DDS Security: libssl-dev (publish.dds.security's certificates, key and signed documents
  # checked before Cyclone gets them), openssl (scripts/make-dds-security.sh makes a set)
  libssl-dev openssl
  # LCM: the library and lcm-gen (types from publish/lcm/*.lcm), lcm-logger for the
  # recorded-session test; libglib2.0-dev because liblcm-dev's lcm.pc requires glib-2.0 and
  # gthread-2.0 .pc files that liblcm-dev does not pull in (pkg-config lcm fails without them)
  liblcm-dev liblcm-bin libglib2.0-dev
  # liburing: the event loop waits and reads the buses' frames through io_uring, one system call
  # per wake-up (canopen/io/uring_receiver.hpp; epoll where the kernel refuses io_uring)
  liburing-dev
  # libsystemd: sd_notify / sd_watchdog_enabled for the unit's Type=notify and watchdog (oegw run
  # sends nothing without NOTIFY_SOCKET: systemd is not needed to run it)
  libsystemd-dev
)

# The test tiers only (--tests).
TEST_PACKAGES=(
  # unit and integration tests, benchmarks, the fuzzers (libFuzzer: clang)
  libgtest-dev libgmock-dev libbenchmark-dev clang
  # independent CAN peers and the SocketCAN-in-a-VM tier
  can-utils python3-can qemu-system-x86 busybox-static kmod cpio iproute2
  # make: node-gyp builds the node-canopen peer's native addons (tests/vm/node_peer) with it
  make
  # strace: the VM tier counts the system calls `oegw run` makes per translated frame
  strace
  # tmux: the demo's live table is judged on the screen a terminal shows (capture-pane)
  tmux
  # the tree's lint (CTest label lint, scripts/check.sh): shell scripts, Python, function lengths
  shellcheck pyflakes3 universal-ctags
  # clang-format: the C++ sources as .clang-format says (scripts/format.sh, CTest format_check)
  clang-format-14
  # tcpdump: an independent check that the demo's DDS/LCM traffic never leaves the host
  tcpdump
  # systemd-analyze verify: the unit file's test (systemd need not run)
  systemd
  # the Debian package: dpkg-shlibdeps (dpkg-dev) computes its Depends; the deploy test installs it
  # into a fresh Debian root made by debootstrap and inspects the installed programs (file) and
  # its copyright file with Debian's DEP-5 reader (python3-debian)
  dpkg-dev debootstrap file python3-debian
  # the cross-builds for ARM cab controllers (scripts/cross-build.sh): Debian's cross compilers,
  # qemu-user to run the target's tests and programs here, mmdebstrap for the target's sysroot and
  # fresh roots (arch-test: how mmdebstrap checks that a foreign root can run here)
  crossbuild-essential-arm64 crossbuild-essential-armhf qemu-user-static mmdebstrap arch-test
)

# node-canopen, the VM tier's independent CANopen host (tests/vm/node_peer: its npm packages are
# installed from the lockfile by CTest's vm_node_peer_install, not here): Debian's nodejs and npm,
# and libnode-dev for Node's headers (/usr/include/node), which the addons compile against. A
# node that is already there with npm and its headers (e.g. a nodejs package from elsewhere, which
# conflicts with Debian's npm) is used as it is.
NODE_PACKAGES=()
if ! command -v node >/dev/null || ! command -v npm >/dev/null || [ ! -r /usr/include/node/node.h ]; then
  NODE_PACKAGES=(nodejs npm libnode-dev)
fi

# Command 2's test tiers only: headless chromium loads the replay's plot (tests/tools/plot_chromium_check.sh);
# mkdocs (1.4.2 on Debian 12) builds docs/ as a site, strictly (docs/developer/docs-site.md); man-db's
# `man -l` renders the manual pages.
if [[ ${1:-} == --tests ]]; then
  PACKAGES+=("${TEST_PACKAGES[@]}" "${NODE_PACKAGES[@]}" chromium mkdocs man-db)
fi

missing=()
for p in "${PACKAGES[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} Debian packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: need root (or sudo) to install: ${missing[*]}" >&2; exit 1; }
  SUDO=sudo
fi
echo "install-deps: installing ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
