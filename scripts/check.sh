#!/usr/bin/env bash
# The fast loop before a commit (CONTRIBUTING.md "Before a commit"): the tree checks, the format,
# the build and tiers 1 and 2 (ctest -L 'unit|integration' -LE vm). Stops at the first step that
# fails, naming it; prints each step's time.
#   scripts/check.sh [--no-build]
#     --no-build  the checks only: no build, no tests
# The build tree is build/ (OEGW_BUILD_DIR), configured with `cmake --preset dev` when missing.
set -euo pipefail
cd "$(dirname "$0")/.."

build=1
for a in "$@"; do
  case $a in
    --no-build) build=0 ;;
    -h | --help) sed -n '2,7p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "check.sh: unknown option '$a' (--no-build)" >&2; exit 64 ;;
  esac
done
BUILD=${OEGW_BUILD_DIR:-build}
t_all=$SECONDS

step() {  # name command...: runs it, prints its time; stops the run if it fails
  local name=$1 t=$SECONDS
  shift
  echo "== $name"
  if ! "$@"; then
    echo "check.sh: FAILED at '$name' ($((SECONDS - t)) s)" >&2
    exit 1
  fi
  echo "   ($((SECONDS - t)) s)"
}

step "layers (tests/tools/check_layers.py)" python3 tests/tools/check_layers.py .
step "docs links and anchors (tests/tools/check_docs.py)" python3 tests/tools/check_docs.py .
step "no issue references (tests/tools/check_no_issue_refs.py)" python3 tests/tools/check_no_issue_refs.py .
step "shellcheck (tests/tools/lint.py shell)" python3 tests/tools/lint.py . shell
step "pyflakes3 (tests/tools/lint.py python)" python3 tests/tools/lint.py . python
step "function length (tests/tools/check_function_length.py)" python3 tests/tools/check_function_length.py .
step "clang-format (scripts/format.sh --check)" scripts/format.sh --check
if ((build == 1)); then
  if [[ ! -f $BUILD/CMakeCache.txt ]]; then
    if [[ $BUILD == build ]]; then
      step "configure (cmake --preset dev)" cmake --preset dev
    else
      step "configure" cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DOEGW_BUILD_TESTS=ON
    fi
  fi
  step "build ($BUILD)" cmake --build "$BUILD"
  step "tiers 1 and 2 (ctest -L 'unit|integration' -LE vm)" \
    ctest --test-dir "$BUILD" -L 'unit|integration' -LE vm -j "${OEGW_CHECK_JOBS:-2}" --output-on-failure --timeout 300
fi
echo "check.sh: all passed ($((SECONDS - t_all)) s)"
