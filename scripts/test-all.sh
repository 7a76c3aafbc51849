#!/usr/bin/env bash
# Builds and runs every test tier: unit, integration (virtual bus), SocketCAN in a qemu VM,
# benchmarks (figures printed, never asserted). Exits non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."

./scripts/install-deps.sh
BUILD=${OEGW_BUILD_DIR:-build}
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build "$BUILD"

# Tiers 1, 2 and 3 (the VM tier is labelled `vm`) through CTest.
ctest --test-dir "$BUILD" --output-on-failure --timeout 900 -j2

# Tier 4: benchmarks print their figures; a crash fails the run, a slow machine does not.
for b in "$BUILD"/tests/bench/oegw_bench_*; do
  [ -x "$b" ] || continue
  echo "== $(basename "$b")"
  "$b" --benchmark_min_time=0.2
done
