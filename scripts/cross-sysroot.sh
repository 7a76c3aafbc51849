#!/usr/bin/env bash
# Makes (once) the sysroot a cross-build compiles and links against: the target architecture's
# Debian 12 library packages, unpacked by mmdebstrap --variant=extract (no maintainer script runs,
# so no emulation is needed and it takes seconds). A sysroot rather than multiarch packages on
# this machine: liblcm-dev, liblcm1 and libyaml-cpp-dev are not Multi-Arch: same, so their arm64
# and amd64 versions cannot be installed side by side.
# docs/guides/build-and-package.md#building-for-the-cab-controller.
#
#   scripts/cross-sysroot.sh arm64|armhf    prints the sysroot's path (last line)
#
# Cached in $OEGW_CROSS_CACHE (default /var/cache/oegw-cross) as sysroot-<arch>; its recipe (the
# package list, the suite, the sources) is kept beside it and a different recipe makes it anew.
# When the security suite's index cannot be fetched for the architecture, the sysroot is made
# from the suite and its updates alone, with a WARNING (below).
# OEGW_CROSS_MIRROR overrides the mirror (default http://deb.debian.org/debian). Needs root.
#
# Beside the files: sysroot-<arch>/var/lib/oegw-shlibs, a dpkg administrative folder listing each
# unpacked package with its files under the sysroot's path, its symbols and shlibs files, so that
# dpkg-shlibdeps finds which package and version a library of the sysroot comes from (the
# package's Depends, cmake/OegwPackage.cmake); the extract variant writes no dpkg database.
set -euo pipefail

arch=${1:?usage: cross-sysroot.sh arm64|armhf}
case $arch in
  arm64 | armhf) ;;
  *) echo "cross-sysroot: unknown architecture '$arch' (arm64 or armhf)" >&2; exit 2 ;;
esac
cache=${OEGW_CROSS_CACHE:-/var/cache/oegw-cross}
mirror=${OEGW_CROSS_MIRROR:-http://deb.debian.org/debian}
suite=bookworm
root=$cache/sysroot-$arch

# The target's -dev packages of scripts/install-deps.sh (the build's libraries and the test tiers'
# gtest/gmock/benchmark), with the C and C++ runtimes the cross compilers link against. Why each
# library is there: docs/developer/dependencies.md.
PACKAGES=(
  libc6-dev libstdc++-12-dev
  libcli11-dev libspdlog-dev libfmt-dev libyaml-cpp-dev libsocketcan-dev nlohmann-json3-dev
  libsystemd-dev liburing-dev cyclonedds-dev liblcm-dev libglib2.0-dev libssl-dev zlib1g-dev
  libgtest-dev libgmock-dev libbenchmark-dev
)
sources=("deb $mirror $suite main" "deb $mirror $suite-updates main"
         "deb http://deb.debian.org/debian-security $suite-security main")
recipe_of() { echo "extract $arch $suite ${PACKAGES[*]} | $* | shlibs-index 2"; }
recipe=$(recipe_of "${sources[@]}")
# Without the security suite: the fallback when its index for this architecture cannot be fetched
# (seen: a mirror serving an armhf Packages.xz of another size than its Release lists, for days).
# Its libraries then lack the security updates, which the cross tier's compiling, linking and
# testing does not depend on; every run tries the whole recipe first.
base_sources=("${sources[@]:0:2}")
base_recipe=$(recipe_of "${base_sources[@]}")

[[ $(id -u) -eq 0 ]] || { echo "cross-sysroot: needs root (mmdebstrap, /var/cache)" >&2; exit 1; }
command -v mmdebstrap >/dev/null || { echo "cross-sysroot: missing mmdebstrap (scripts/cross-build.sh installs it)" >&2; exit 1; }
mkdir -p "$cache"
exec 9>"$cache/.lock-$arch"
flock 9

if [[ -f $root.recipe && $(cat "$root.recipe") == "$recipe" && -d $root/var/lib/oegw-shlibs ]]; then
  echo "cross-sysroot: $arch sysroot cached" >&2
  echo "$root"
  exit 0
fi

t=$SECONDS
echo "cross-sysroot: making the $arch sysroot in $root (mmdebstrap --variant=extract)" >&2
fresh=$root.tmp
# extract SOURCES...: the packages unpacked into $fresh; the .debs are kept (cleanup/apt/cache
# skipped) for the index below, then removed. Its log: $cache/mmdebstrap-$arch.log.
extract() {
  rm -rf --one-file-system "$fresh"
  mmdebstrap --quiet --variant=extract --arch="$arch" --include="$(IFS=,; echo "${PACKAGES[*]}")" \
    --skip=cleanup/apt/cache "$suite" "$fresh" "$@" >"$cache/mmdebstrap-$arch.log" 2>&1
}
if ! extract "${sources[@]}"; then
  tail -5 "$cache/mmdebstrap-$arch.log" >&2
  echo "cross-sysroot: WARNING: mmdebstrap failed with $suite-security (log: $cache/mmdebstrap-$arch.log)" >&2
  if [[ -f $root.recipe && $(cat "$root.recipe") == "$base_recipe" && -d $root/var/lib/oegw-shlibs ]]; then
    echo "cross-sysroot: WARNING: the $arch sysroot without $suite-security (cached) is used: its libraries lack the security updates" >&2
    rm -rf --one-file-system "$fresh"
    echo "$root"
    exit 0
  fi
  echo "cross-sysroot: WARNING: making the $arch sysroot from $suite and $suite-updates only: its libraries lack the security updates" >&2
  extract "${base_sources[@]}" ||
    { tail -20 "$cache/mmdebstrap-$arch.log" >&2; echo "cross-sysroot: mmdebstrap failed (log: $cache/mmdebstrap-$arch.log)" >&2; exit 1; }
  recipe=$base_recipe
fi
rm -rf --one-file-system "$root" "$root.recipe"

# The dpkg-shlibdeps index: what dpkg would have recorded, with the paths as they are on this
# machine (under $root, where dpkg-shlibdeps -l finds the libraries).
admin=$fresh/var/lib/oegw-shlibs
mkdir -p "$admin/info" "$admin/updates"
printf '%s\n' amd64 "$arch" >"$admin/arch"
# Format 1: the files of a Multi-Arch: same package are <package>:<arch>.*, as dpkg writes them.
echo 1 >"$admin/info/format"
: >"$admin/status"
ctl=$(mktemp -d)
for deb in "$fresh"/var/cache/apt/archives/*.deb; do
  pkg=$(dpkg-deb -f "$deb" Package)
  # dpkg names the files of a Multi-Arch: same package <package>:<arch>.
  name=$pkg
  [[ $(dpkg-deb -f "$deb" Multi-Arch) == same ]] && name=$pkg:$(dpkg-deb -f "$deb" Architecture)
  { dpkg-deb -f "$deb"; echo "Status: install ok installed"; echo; } >>"$admin/status"
  dpkg-deb --fsys-tarfile "$deb" | tar -t | sed -e 's|^\./|/|' -e 's|/$||' -e '/^\/*$/d' -e "s|^|$root|" >"$admin/info/$name.list"
  rm -rf "${ctl:?}"/*
  dpkg-deb -e "$deb" "$ctl"
  for f in symbols shlibs; do
    [[ -f $ctl/$f ]] && cp "$ctl/$f" "$admin/info/$name.$f"
  done
done
rm -rf "$ctl" "$fresh"/var/cache/apt/archives/*.deb
mv "$fresh" "$root"
echo "$recipe" >"$root.recipe"
echo "cross-sysroot: $arch sysroot made ($(du -sh "$root" | cut -f1), $(grep -c '^Package:' "$root/var/lib/oegw-shlibs/status") packages, $((SECONDS - t)) s)" >&2
echo "$root"
