#!/bin/sh
# `oegw check` run from `/` on a copy of a mapping file of the source tree, changed by a sed
# script: the copy sits at the same place in a scratch tree whose subdevices/ is the source's,
# so the file's relative EDS paths hold only if they are taken from its own folder
# (docs/reference/mapping-file.md#paths), never from the working directory.
#   check_variant.sh OEGW SOURCE_DIR FILE SED STATUS TEXT [OPTION...]
# FILE is relative to SOURCE_DIR; passes when the exit status is STATUS and the output has TEXT
# (a fixed string; "-" for none). OPTIONs go to `oegw check` (--here). The output is printed; a
# failure says FAIL:.
oegw=$1 src=$2 file=$3 script=$4 status=$5 text=$6
shift 6
tmp=$(mktemp -d) || exit 1
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/$(dirname "$file")"
ln -s "$src/subdevices" "$tmp/subdevices"
sed -e "$script" "$src/$file" >"$tmp/$file" || exit 1
out=$(cd / && "$oegw" check "$@" "$tmp/$file" 2>&1)
rc=$?
printf '%s\n' "$out" | sed "s|$tmp/||g"
fail=0
[ "$rc" -eq "$status" ] || { echo "FAIL: exit status $rc, expected $status"; fail=1; }
if [ "$text" != "-" ]; then
  printf '%s\n' "$out" | sed "s|$tmp/||g" | grep -qF -- "$text" || { echo "FAIL: no line with: $text"; fail=1; }
fi
[ "$fail" -eq 0 ] && echo "PASS: exit $rc"
exit "$fail"
