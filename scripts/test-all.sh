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

# Fuzzing smoke runs: the SDO server under libFuzzer + ASan/UBSan (clang), a short bounded run.
FUZZ_BUILD=${OEGW_FUZZ_BUILD_DIR:-build-fuzz}
CXX=clang++ cmake -S . -B "$FUZZ_BUILD" -G Ninja -DOEGW_FUZZ=ON -DOEGW_VM_TESTS=OFF >/dev/null
cmake --build "$FUZZ_BUILD" --target sdo_server_fuzz sdo_remote_fuzz
"$FUZZ_BUILD"/tests/fuzz/sdo_server_fuzz -max_total_time=15 -print_final_stats=1 2>&1 | tail -4
# The same server in its remote (routed) mode, against a fake remote that answers, refuses, is late.
"$FUZZ_BUILD"/tests/fuzz/sdo_remote_fuzz -max_total_time=10 -print_final_stats=1 2>&1 | tail -4

# Tier 4: benchmarks print their figures; a crash fails the run, a slow machine does not.
for b in "$BUILD"/tests/bench/oegw_bench_*; do
  [ -x "$b" ] || continue
  case "$b" in *oegw_bench_rss) continue ;; esac  # not a Google Benchmark: run below
  echo "== $(basename "$b")"
  "$b" --benchmark_min_time=0.2
done
# Resident memory of the gateway with the full FE set (figures; fails only if the set does not boot).
echo "== oegw_bench_rss"
"$BUILD"/tests/bench/oegw_bench_rss
