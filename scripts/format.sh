#!/usr/bin/env bash
# Formats the C++ and C sources with the repository's .clang-format (clang-format 14, Debian 12),
# in place. With --check it changes nothing: it lists the files clang-format would change and
# exits 1 if there is one (0 when all are formatted). Files: what git tracks (and the untracked
# ones it does not ignore) ending .cpp, .hpp, .c or .h, or the files given after the options.
#   scripts/format.sh [--check] [FILE...]
# CLANG_FORMAT names another binary (default clang-format-14, else clang-format).
set -euo pipefail
cd "$(dirname "$0")/.."

check=0
if [[ ${1:-} == --check ]]; then
  check=1
  shift
fi
case ${1:-} in
  -h | --help) sed -n '2,7p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
  -*) echo "format.sh: unknown option '$1' (--check, or files)" >&2; exit 64 ;;
esac

cf=${CLANG_FORMAT:-}
if [[ -z $cf ]]; then
  cf=$(command -v clang-format-14 || command -v clang-format || true)
fi
if [[ -z $cf ]]; then
  echo "format.sh: clang-format is not installed (Debian: apt install clang-format-14)" >&2
  exit 2
fi

files=()
if (($# > 0)); then
  files=("$@")
else
  while IFS= read -r -d '' f; do files+=("$f"); done < <(
    git ls-files -z --cached --others --exclude-standard -- '*.cpp' '*.hpp' '*.c' '*.h')
fi

if ((check == 0)); then
  printf '%s\0' "${files[@]}" | xargs -0 -r "$cf" -i --style=file
  exit 0
fi
# A .clang-format clang-format cannot read would otherwise pass as "no difference".
"$cf" --style=file --dump-config >/dev/null
# One clang-format per batch of files (a process per file took 40 s over the tree): with
# --dry-run -Werror it names each place it would change as "FILE:LINE:COL: error: ...".
mapfile -t differing < <(printf '%s\0' "${files[@]}" |
  xargs -0 -r -n 64 -P "$(nproc)" "$cf" --style=file --dry-run -Werror 2>&1 >/dev/null |
  sed -n 's/^\(.*\):[0-9][0-9]*:[0-9][0-9]*: error: .*/\1/p' | sort -u)
differ=${#differing[@]}
if ((differ > 0)); then printf '%s\n' "${differing[@]}"; fi
if ((differ > 0)); then
  echo "format.sh: ${differ} of ${#files[@]} files differ from .clang-format (scripts/format.sh formats them)" >&2
  exit 1
fi
echo "format.sh: ${#files[@]} files formatted"
