#!/bin/sh
# `oegw demo --frames` prints every frame in candump's log format (candump -L):
# "(seconds.micros) interface id#data", interfaces `up` and `down`, which canplayer replays
# (`canplayer -I FILE vcan0=up vcan1=down`). Checked by can-utils' own reader of that format:
# log2asc converts every frame line, so the ASC file has as many frames as the log has lines.
# Args: OEGW
set -eu
oegw=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
"$oegw" demo --fast --seconds 1 --no-publish --frames >"$dir/out.txt"
grep -E '^\([0-9]{10}\.[0-9]{6}\) (up|down) ' "$dir/out.txt" >"$dir/frames.log" || true
n=$(wc -l <"$dir/frames.log")
[ "$n" -gt 1000 ] || { echo "FAIL: only $n frame lines"; exit 1; }
bad=$(grep -Evc '^\([0-9]{10}\.[0-9]{6}\) (up|down) ([0-9A-F]{3}|[0-9A-F]{8})#(R[0-8]?|([0-9A-F]{2}){0,8})$' "$dir/frames.log" || true)
[ "$bad" -eq 0 ] || { echo "FAIL: $bad frame lines not in candump -L form"; exit 1; }
grep -q ' down 711#' "$dir/frames.log" || { echo "FAIL: no heartbeat of the grip (711h) on down"; exit 1; }
grep -q ' up 720#00$' "$dir/frames.log" || { echo "FAIL: no boot-up of the gateway (720#00) on up"; exit 1; }
log2asc -I "$dir/frames.log" -O "$dir/frames.asc" up down
asc=$(grep -cE '^ *[0-9]+\.[0-9]+ [12] ' "$dir/frames.asc" || true)
[ "$asc" -eq "$n" ] || { echo "FAIL: log2asc read $asc of $n frames"; head -5 "$dir/frames.asc"; exit 1; }
echo "PASS: $n frames in candump -L form, all read by log2asc"
