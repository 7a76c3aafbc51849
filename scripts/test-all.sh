#!/usr/bin/env bash
# Builds and runs every test tier: unit, integration (virtual bus), SocketCAN in a qemu VM,
# benchmarks (figures printed, never asserted), and the unit and integration tests cross-built for
# arm64 and armhf under qemu-user. Exits non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."

# Each phase's start and the run's time so far, so that a slow phase shows in CI's log (CI
# allows 90 minutes; the whole run is meant to stay under 50).
phase() { echo "== phase: $* (at $((SECONDS / 60)) min $((SECONDS % 60)) s)"; }
CLEANUP=()
finish() {
  local rc=$?
  ((${#CLEANUP[@]} == 0)) || rm -rf "${CLEANUP[@]}"
  phase "end, exit $rc"
}
trap finish EXIT
phase "dependencies"
./scripts/install-deps.sh --tests
phase "build"
BUILD=${OEGW_BUILD_DIR:-build}
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DOEGW_BUILD_TESTS=ON >/dev/null
cmake --build "$BUILD"

# Tiers 1, 2 and 3 (the VM tier is labelled `vm`) and the Debian package installed into a fresh
# debootstrap root (label `deploy`, tests/deploy) through CTest. The VM tier's node-canopen host
# comes from npm: CTest's vm_node_peer_install runs `npm ci` on tests/vm/node_peer's lockfile into
# the build tree first (the registry only; nodejs, npm and libnode-dev from install-deps.sh).
phase "tiers 1-3 and deploy (ctest)"
ctest --test-dir "$BUILD" --output-on-failure --timeout 900 -j2 || {
  rc=$?
  # A long run's log is read from its end: the failed tests' own failure lines once more there.
  echo "== the failures again (from $BUILD/Testing/Temporary/LastTest.log)"
  grep -E -A3 '^FAIL: |: Failure$|^\[  FAILED  \]' "$BUILD/Testing/Temporary/LastTest.log" | head -80 || true
  exit "$rc"
}

# Fuzzing smoke runs: the SDO server under libFuzzer + ASan/UBSan (clang), a short bounded run.
phase "fuzzers"
FUZZ_BUILD=${OEGW_FUZZ_BUILD_DIR:-build-fuzz}
CXX=clang++ cmake -S . -B "$FUZZ_BUILD" -G Ninja -DOEGW_FUZZ=ON -DOEGW_VM_TESTS=OFF >/dev/null
FUZZERS=(sdo_server_fuzz sdo_remote_fuzz mapping_fuzz eds_fuzz oe_device_fuzz network_manager_fuzz)
cmake --build "$FUZZ_BUILD" --target "${FUZZERS[@]}"
# Each writes what it finds into a fresh corpus directory (the first); the seeds after it are
# only read: SDO conversations of every transfer type run to their ends (make_seeds.py), the
# shipped mapping files and EDS files. A crash or a broken invariant exits non-zero.
CORPUS=$(mktemp -d)
CLEANUP+=("$CORPUS")
python3 tests/fuzz/make_seeds.py "$CORPUS/seeds"
fuzz() {  # target seconds seed-dirs... [-- libFuzzer options]
  local t=$1 s=$2
  shift 2
  local rc=0
  mkdir -p "$CORPUS/$t"
  echo "== $t (${s} s)"
  "$FUZZ_BUILD/tests/fuzz/$t" -max_total_time="$s" -print_final_stats=1 -artifact_prefix="$FUZZ_BUILD/$t-" "$@" \
    >"$CORPUS/$t.log" 2>&1 || rc=$?
  grep -E "^stat::|DONE|ERROR|SUMMARY|Test unit written|deadly signal" "$CORPUS/$t.log" || true
  [ "$rc" -eq 0 ] || { tail -40 "$CORPUS/$t.log"; echo "$t failed (exit $rc)"; }
  return "$rc"
}
fuzz sdo_server_fuzz 15 "$CORPUS/sdo_server_fuzz" "$CORPUS/seeds/sdo_server_fuzz"
# The same server in its remote (routed) mode, against a fake remote that answers, refuses, is late.
fuzz sdo_remote_fuzz 10 "$CORPUS/sdo_remote_fuzz"
# The mapping-file loader with the real drivers, and the device a loaded file builds.
fuzz mapping_fuzz 15 "$CORPUS/mapping_fuzz" config tests/fixtures tests/fuzz/regressions -dict=tests/fuzz/mapping.dict
# The EDS reader, its mapping check, dictionary and write-back.
fuzz eds_fuzz 10 "$CORPUS/eds_fuzz" subdevices/eds -dict=tests/fuzz/eds.dict
# The whole upstream device (every FE kind at its largest instance count), every COB-ID, time running.
fuzz oe_device_fuzz 20 "$CORPUS/oe_device_fuzz" "$CORPUS/seeds/oe_device_fuzz"
# The downstream network manager booting one node of every driver family, SYNC running.
fuzz network_manager_fuzz 20 "$CORPUS/network_manager_fuzz" "$CORPUS/seeds/network_manager_fuzz"

phase "benchmarks"
# Tier 4: benchmarks print their figures; a crash fails the run, a slow machine does not.
for b in "$BUILD"/tests/bench/oegw_bench_*; do
  [ -x "$b" ] || continue
  case "$b" in *oegw_bench_rss|*oegw_bench_cab_timing|*oegw_bench_path) continue ;; esac  # not Google Benchmarks: run below
  echo "== $(basename "$b")"
  "$b" --benchmark_min_time=0.2
done
# Resident memory of the gateway with the full FE set (figures; fails only if the set does not boot).
echo "== oegw_bench_rss"
"$BUILD"/tests/bench/oegw_bench_rss
# Cab boot time against its bound, and bus load predicted against measured, on the timed bus
# (simulated time; figures only, fails only if a cab does not boot).
echo "== oegw_bench_cab_timing"
"$BUILD"/tests/bench/oegw_bench_cab_timing
# The whole path of `oegw run` natively, on socketpairs standing in for CAN, against the floor:
# latency at 1,000 and 8,000 frames/s, CPU and system calls per frame (figures and the targets
# they are read against; fails only if a path does not forward or a cab does not boot).
echo "== oegw_bench_path"
"$BUILD"/tests/bench/oegw_bench_path
# The real SocketCAN path's figures (vm_latency in tier 3: latency of `oegw run` against the floor
# forwarder and a python translator, CPU and resident memory at 8000 frames/s): CTest shows a
# test's output only when it fails, so the figures the test kept in the build tree are shown here.
echo "== vm_latency"
cat "$BUILD/tests/vm/vm_latency.out/figures.txt" 2>/dev/null || echo "(no figures: vm_latency did not run)"
# vm_abuse's figures (CAN first: the control clients' scenarios, the heartbeat's gaps, memory,
# how long a separate `oegw status` waited in each scenario, the kernel's drops).
echo "== vm_abuse"
cat "$BUILD/tests/vm/vm_abuse.out/abuse.figures" 2>/dev/null || echo "(no figures: vm_abuse did not run)"

# The cab controller's processors: the unit and integration tests cross-built for arm64 and armhf
# and run under qemu-user, and each architecture's Debian package with its Depends checked
# (docs/guides/build-and-package.md#building-for-the-cab-controller; build-arm64, build-armhf, the
# sysroots cached in /var/cache/oegw-cross).
phase "cross builds (arm64, armhf)"
./scripts/cross-build.sh all
