#!/bin/bash
# The manual pages and the bash completion that scripts/make-man.sh generates (CTest man_pages):
# `man -l` renders oegw(1) with every sub-command's section and its options, and oegw.yaml(5)
# with the mapping file's keys, without an error; the completion offers the sub-commands at the
# first word and a sub-command's options after it.
# Usage: tests/tools/man_check.sh MAN_DIR (the build tree's man/)
set -uo pipefail
dir=${1:?usage: man_check.sh MAN_DIR}
fail=0
bad() { echo "FAIL: $*"; fail=1; }
command -v man >/dev/null || { echo "FAIL: man is not installed (scripts/install-deps.sh --tests installs man-db)"; exit 1; }

page=$(MANWIDTH=100 man -l "$dir/oegw.1.gz" 2>"$dir/oegw.1.err") || bad "man -l oegw.1.gz exited $?: $(cat "$dir/oegw.1.err")"
for want in '^NAME' 'oegw +- +CiA 852 operator-environment gateway' '^COMMANDS' 'oegw run' 'oegw check' \
            'oegw status' 'oegw ctl' '--log-level' '^SEE ALSO' 'oegw.yaml\(5\)'; do
  grep -Eq -- "$want" <<<"$page" || bad "oegw(1) lacks /$want/"
done
# The help texts name flags as they are typed (CLI11's `--no-lss{false}` is a parser detail) and
# say the exit codes once, in `oegw --help` (the page's description), not in every command's section.
grep -Eq -- '\{(true|false)\}' <<<"$page" && bad "oegw(1) names a flag with its parser value: $(grep -E -- '\{(true|false)\}' <<<"$page" | head -1)"
exits=$(grep -c -- 'Exit codes:' <<<"$page")
((exits == 1)) || bad "oegw(1) says 'Exit codes:' $exits times, not once"
# The daily commands come before the bench and test tools (oegw --help's groups, in that order).
run_at=$(grep -n -m1 -E '^ +run +Run the gateway' <<<"$page" | cut -d: -f1)
tool_at=$(grep -n -m1 -E '^ +core-demo( |$)' <<<"$page" | cut -d: -f1)
tools_at=$(grep -n -m1 -E '^ +Bench and test tools:' <<<"$page" | cut -d: -f1)
[[ -n $run_at && -n $tools_at && -n $tool_at && $run_at -lt $tools_at && $tools_at -lt $tool_at ]] ||
  bad "oegw --help does not list run (line ${run_at:-none}) before the tools (line ${tools_at:-none}: core-demo ${tool_at:-none})"
page=$(MANWIDTH=100 man -l "$dir/oegw.yaml.5.gz" 2>"$dir/oegw.yaml.5.err") || bad "man -l oegw.yaml.5.gz exited $?"
for want in '^NAME' 'oegw.yaml +- +the mapping file' 'upstream' 'heartbeat_ms' 'functional_elements' 'Translation'; do
  grep -Eq -- "$want" <<<"$page" || bad "oegw.yaml(5) lacks /$want/"
done

complete_words() {  # the words the completion offers for the command line "$@" (the last: the word completed)
  bash -c 'source "$1"; shift; COMP_WORDS=("$@"); COMP_CWORD=$(($# - 1)); _oegw; printf "%s\n" "${COMPREPLY[@]}"' \
    _ "$dir/oegw.bash" "$@"
}
words=$(complete_words oegw '') || bad "the completion failed"
for want in run check status ctl scan --help; do
  grep -qx -- "$want" <<<"$words" || bad "completing 'oegw ' does not offer $want (offered: $(tr '\n' ' ' <<<"$words"))"
done
words=$(complete_words oegw run --l)
grep -qx -- --log-level <<<"$words" || bad "completing 'oegw run --l' does not offer --log-level (offered: $words)"
words=$(complete_words oegw scan --q)
grep -qx -- --quiet <<<"$words" || bad "completing 'oegw scan --q' does not offer --quiet (offered: $words)"
words=$(complete_words oegw record '')
[[ $words == keep ]] || bad "completing 'oegw record ' offers '$words', not keep"
words=$(complete_words oegw st)
[[ $words == status ]] || bad "completing 'oegw st' offers '$words', not status alone"
((fail)) && exit 1
echo "PASS: oegw(1) and oegw.yaml(5) render; the completion offers the sub-commands and their options"
