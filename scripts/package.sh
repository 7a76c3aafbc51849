#!/usr/bin/env bash
# Builds the Debian package oegw_<version>_<arch>.deb
# (docs/guides/build-and-package.md#building-the-debian-package): the programs stripped (no debug
# information), /etc/oegw/oegw.yaml a conffile, Depends from dpkg-shlibdeps.
#
#   scripts/package.sh                 a release build of its own in build-pkg (-O2, no tests;
#                                      OEGW_PKG_BUILD_DIR overrides the folder), then the package
#   scripts/package.sh --from DIR      the package from an already built tree (the deploy test
#                                      packages CI's RelWithDebInfo build: -O2 -g, stripped at install)
#   --out DIR                          where the .deb goes (default: the build folder)
#
# The last line printed is the .deb's path; everything else goes to stderr.
set -euo pipefail
cd "$(dirname "$0")/.."

from="" out=""
while [[ $# -gt 0 ]]; do
  case $1 in
    --from) from=${2:?--from needs a build folder}; shift 2 ;;
    --out) out=${2:?--out needs a folder}; shift 2 ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    *) echo "package.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done

if [[ -z $from ]]; then
  build=${OEGW_PKG_BUILD_DIR:-build-pkg}
  # Release with Debian's -O2 (CMake's Release says -O3); no test tiers: only what is installed.
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS_RELEASE="-O2 -DNDEBUG" \
        -DCMAKE_C_FLAGS_RELEASE="-O2 -DNDEBUG" -DOEGW_BUILD_TESTS=OFF -DCMAKE_INSTALL_PREFIX=/usr >&2
else
  build=$from
  [[ -f $build/CPackConfig.cmake ]] || { echo "package.sh: $build is not a configured build folder" >&2; exit 2; }
fi
build=$(cd "$build" && pwd)
# Only the installed programs (and the libraries they link): not the test tiers of a CI tree.
cmake --build "$build" -j "${OEGW_PKG_JOBS:-2}" --target oegw_installed >&2
out=${out:-$build}
mkdir -p "$out"
out=$(cd "$out" && pwd)
# CPack builds nothing: it installs the built tree into its staging folder below $out.
cpack --config "$build/CPackConfig.cmake" -B "$out" >&2
rm -rf "$out/_CPack_Packages"
deb=$(ls -t "$out"/oegw_*.deb | head -n1)
echo "package.sh: $deb: $(du -h "$deb" | cut -f1), Depends: $(dpkg-deb -f "$deb" Depends)" >&2
echo "$deb"
