#!/bin/bash
# Guest test: `oegw scan` outside in (issue 16 item 2). `oegw-sim` simulates a cab of every
# family on vcan1 (elobau grip 11h, MCB-402 03h, Novotechnik encoder 7Fh, CiA 401 pedal 30h and
# button cluster 31h); cansend (can-utils) takes the cluster's node-ID away by LSS (CiA 305:
# switch state selective to its 1018h address, configure node-ID FFh, waiting, NMT reset
# communication), so it is a node without node-ID. `oegw scan -i vcan1` as a process must find the
# four nodes by SDO, name their families, read the cluster's LSS address by fastscan, show its
# progress, write nothing to any node (candump), and write a draft that `oegw check` accepts.
# Args: OEGW OEGW_SIM SRC
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1
sim=$2
eds=$3/subdevices/eds

start_candump vcan1 /tmp/scan.dump || fail "candump did not start"
"$sim" -i vcan1 elobau-mfg:0x11 mcb402:0x03 novotechnik-406:0x7F "cia401:0x30:eds=$eds/generic_pedal.eds" \
  "cia401:0x31:eds=$eds/button_cluster.eds" >/tmp/sim.log 2>&1 &
sim_pid=$!
wait_receivers vcan1 2 || fail "oegw-sim did not bind vcan1"
for _ in $(seq 100); do grep -q ' 731#00$' /tmp/scan.dump && break; sleep 0.1; done

# The cluster (button_cluster.eds 1018h: vendor A5Ah, product 402h, revision 00010002h, serial 0).
for f in 405A0A0000000000 4102040000000000 4202000100000000 4300000000000000 11FF000000000000 \
  0400000000000000; do
  cansend vcan1 "7E5#$f"
done
cansend vcan1 000#8231
sleep 0.5
if grep -q '7E4#4400000000000000' /tmp/scan.dump && grep -q '7E4#1100000000000000' /tmp/scan.dump; then
  pass "cansend: the cluster selected by its LSS address and given node-ID FFh"
else
  fail "LSS set-up of the cluster: $(grep -E '7E[45]#' /tmp/scan.dump)"
fi

mark=$(wc -l </tmp/scan.dump)
# Time-outs for a TCG guest on a busy host (the defaults, 100 ms and 25 ms, are a real bus's).
timeout 120 "$oegw" scan -i vcan1 --upstream vcan0 --store /tmp/upstream.store --timeout 1000 --lss-timeout 200 \
  -o /tmp/draft.yaml 2>/tmp/scan.err
rc=$?
sed 's/^/    scan: /' /tmp/scan.err
((rc == 0)) && pass "oegw scan exit 0" || fail "oegw scan exit $rc"
grep -q '^probing node 127/127, found 4$' /tmp/scan.err && pass "progress: probing node 127/127, found 4" ||
  fail "no final progress line"
grep -Eq '^probing node 16/127, found [0-9]+$' /tmp/scan.err && pass "progress while scanning (16/127)" ||
  fail "no progress line at 16/127"
for entry in '  elobau_mfg_11:' '  mcb402_03:' '  novotechnik_406_7f:' '  # cia401_30:'; do
  grep -qxF -- "$entry" /tmp/draft.yaml && pass "draft has '$entry'" || fail "draft lacks '$entry'"
done
grep -q 'button_bits: \[0, 1, 2, 3, 4, 5, 6\]  # TODO placeholder' /tmp/draft.yaml &&
  pass "MCB-402 button_bits is a marked placeholder" || fail "no button_bits placeholder"
addr='vendor 0x00000A5A, product 0x00000402, revision 0x00010002, serial 0x00000000'
# (the draft's comment is wrapped: joined again before the search)
sed 's/^# //' /tmp/draft.yaml | tr '\n' ' ' | grep -q "fastscan read its address: $addr" &&
  pass "draft: the cluster's LSS address" ||
  fail "draft lacks the LSS address"
grep -q 'interface: vcan0' /tmp/draft.yaml && grep -q 'interface: vcan1' /tmp/draft.yaml &&
  pass "draft interfaces from the command line" || fail "draft interfaces"
"$oegw" check /tmp/draft.yaml >/tmp/check.out 2>&1
rc=$?
((rc == 0)) && pass "oegw check accepts the draft" || fail "oegw check exit $rc: $(cat /tmp/check.out)"

# Nothing written: the scan's SDO requests are uploads (40h) and aborts (80h) only; its LSS
# frames identify and fastscan, and one switch back to waiting.
tail -n +"$((mark + 1))" /tmp/scan.dump | frames /dev/stdin >/tmp/scan.frames
bad=$(awk '$2 ~ /^6[0-7][0-9A-F]#/ { b = substr($2, 5, 2); if (b != "40" && b != "80") print }' /tmp/scan.frames | head -3)
[[ -z $bad ]] && pass "SDO: uploads and aborts only" || fail "SDO frames that write: $bad"
bad=$(awk '$2 ~ /^7E5#/ { b = substr($2, 5, 2); if (b != "4C" && b != "51" && b != "04") print }' /tmp/scan.frames | head -3)
[[ -z $bad ]] && pass "LSS: identify, fastscan, switch to waiting only" || fail "other LSS frames: $bad"
grep -q '7E5#51' /tmp/scan.frames && pass "fastscan frames on the bus" || fail "no fastscan frame"

# The cluster kept no node-ID (the scan assigns none): it still answers identify non-configured.
mark=$(wc -l </tmp/scan.dump)
cansend vcan1 7E5#4C00000000000000
sleep 0.5
tail -n +"$((mark + 1))" /tmp/scan.dump | grep -q '7E4#5000000000000000' && pass "the cluster is still without node-ID" ||
  fail "the cluster no longer answers identify non-configured"

kill -TERM "$sim_pid"
wait "$sim_pid"
stop_candump
echo "$passes passed, $fails failed"
((fails == 0))
