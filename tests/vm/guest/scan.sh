#!/bin/bash
# Guest test: `oegw scan` outside in. `oegw-sim` simulates a cab of every
# family on vcan1 (elobau grip 11h, MCB-402 03h, Novotechnik encoder 7Fh, CiA 401 pedal 30h and
# button cluster 31h); cansend (can-utils) takes the cluster's node-ID away by LSS (CiA 305:
# switch state selective to its 1018h address, configure node-ID FFh, waiting, NMT reset
# communication), so it is a node without node-ID. `oegw scan -i vcan1` as a process must find the
# four nodes by SDO, name their families, read the cluster's LSS address by fastscan, show its
# progress, write nothing to any node (candump), and write a draft that `oegw check` refuses at the
# MCB-402's button_bits placeholder; `oegw signals mcb402 --find-button-bits` then reads the wiring
# off the board while a scripted user presses the buttons it asks for (the simulator's command pipe),
# and the draft with the line it prints is accepted.
# Args: OEGW OEGW_SIM SRC
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1
sim=$2
eds=$3/subdevices/eds

start_candump vcan1 /tmp/scan.dump || fail "candump did not start"
mkfifo /tmp/sim.cmd
exec 3<>/tmp/sim.cmd
"$sim" -i vcan1 --commands elobau-mfg:0x11 mcb402:0x03:name=board novotechnik-406:0x7F \
  "cia401:0x30:eds=$eds/generic_pedal.eds" "cia401:0x31:eds=$eds/button_cluster.eds" <&3 >/tmp/sim.log 2>&1 &
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
grep -q 'button_bits: TODO  # `oegw check` refuses this' /tmp/draft.yaml &&
  pass "MCB-402 button_bits is the placeholder TODO" || fail "no button_bits placeholder"
addr='vendor 0x00000A5A, product 0x00000402, revision 0x00010002, serial 0x00000000'
# (the draft's comment is wrapped: joined again before the search)
sed 's/^# //' /tmp/draft.yaml | tr '\n' ' ' | grep -q "fastscan read its address: $addr" &&
  pass "draft: the cluster's LSS address" ||
  fail "draft lacks the LSS address"
grep -q 'interface: vcan0' /tmp/draft.yaml && grep -q 'interface: vcan1' /tmp/draft.yaml &&
  pass "draft interfaces from the command line" || fail "draft interfaces"
# No draft passes `oegw check` on a guess: refused at the placeholder, saying how to find the
# value; with a value written, accepted.
"$oegw" check /tmp/draft.yaml >/tmp/check.out 2>&1
rc=$?
((rc == 1)) && grep -q "button_bits is still the draft's placeholder TODO.*--find-button-bits" /tmp/check.out &&
  pass "oegw check refuses the draft at button_bits: TODO, naming --find-button-bits" ||
  fail "oegw check exit $rc: $(cat /tmp/check.out)"

# Nothing written: the scan's SDO requests are uploads (40h) and aborts (80h) only; its LSS
# frames identify and fastscan, and one switch back to waiting.
tail -n +"$((mark + 1))" /tmp/scan.dump | frames /dev/stdin >/tmp/scan.frames
bad=$(awk '$2 ~ /^6[0-7][0-9A-F]#/ { b = substr($2, 5, 2); if (b != "40" && b != "80") print }' /tmp/scan.frames | head -3)
[[ -z $bad ]] && pass "SDO: uploads and aborts only" || fail "SDO frames that write: $bad"
bad=$(awk '$2 ~ /^7E5#/ { b = substr($2, 5, 2); if (b != "4C" && b != "51" && b != "04") print }' /tmp/scan.frames | head -3)
[[ -z $bad ]] && pass "LSS: identify, fastscan, switch to waiting only" || fail "other LSS frames: $bad"
grep -q '7E5#51' /tmp/scan.frames && pass "fastscan frames on the bus" || fail "no fastscan frame"

# The value read off the board: `oegw signals mcb402 --find-button-bits` on vcan1 asks for BP1..BP7
# in turn; the simulated user (the board's command pipe) presses and releases each button asked for.
# The board is still pre-operational (the scan started nothing): the aid hears no TPDO1 and sends
# NMT start 000#0103. The line it prints is the board's wiring (the simulator's default, the
# table's right-end reading), and the draft with that line is accepted by `oegw check`.
mark=$(wc -l </tmp/scan.dump)
coproc finder { timeout 120 "$oegw" signals mcb402 --find-button-bits -i vcan1 --node 3 --timeout 30 2>&1; }
# shellcheck disable=SC2154  # coproc sets finder_PID
finder_pid=$finder_PID
exec 4<&"${finder[0]}"
found=""
while IFS= read -r line <&4; do
  echo "    finder: $line"
  if [[ $line =~ ^press\ and\ hold\ BP([1-7]) ]]; then
    echo "board buttons[${BASH_REMATCH[1]}] 1" >&3
  elif [[ $line =~ ^BP([1-7])\ sets\ bit ]]; then
    echo "board buttons[${BASH_REMATCH[1]}] 0" >&3
  elif [[ $line =~ ^button_bits:\ \[.*\]$ ]]; then
    found=$line
  fi
done
wait "$finder_pid"
rc=$?
exec 4<&-
((rc == 0)) && pass "oegw signals mcb402 --find-button-bits exit 0" || fail "--find-button-bits exit $rc"
[[ $found == 'button_bits: [0, 1, 2, 3, 4, 6, 5]' ]] && pass "the aid read the board's wiring: $found" ||
  fail "the aid printed '$found', the board is wired [0, 1, 2, 3, 4, 6, 5]"
tail -n +"$((mark + 1))" /tmp/scan.dump | frames /dev/stdin >/tmp/finder.frames
grep -q '^vcan1 000#0103$' /tmp/finder.frames && pass "the aid started the silent board (000#0103)" ||
  fail "no NMT start of the board by the aid"
# candump: each button's press seen on the wire as one bit of TPDO1 byte 2 (183#xxxxcc...).
presses=$(awk '$2 ~ /^183#/ { print substr($2, 9, 2) }' /tmp/finder.frames | sort -u | tr '\n' ' ')
[[ $presses == *01* && $presses == *40* && $presses == *20* ]] &&
  pass "TPDO1 byte 2 values on the wire: $presses" || fail "TPDO1 byte 2 values on the wire: $presses"
sed -i "s/button_bits: TODO .*/${found:-button_bits: TODO}/" /tmp/draft.yaml
"$oegw" check /tmp/draft.yaml >/tmp/check.out 2>&1
rc=$?
((rc == 0)) && pass "oegw check accepts the draft with the aid's button_bits line" ||
  fail "oegw check exit $rc: $(cat /tmp/check.out)"

# The cluster kept no node-ID (the scan assigns none): it still answers identify non-configured.
mark=$(wc -l </tmp/scan.dump)
cansend vcan1 7E5#4C00000000000000
sleep 0.5
tail -n +"$((mark + 1))" /tmp/scan.dump | grep -q '7E4#5000000000000000' && pass "the cluster is still without node-ID" ||
  fail "the cluster no longer answers identify non-configured"

kill -TERM "$sim_pid"
wait "$sim_pid"
exec 3>&-
stop_candump
echo "$passes passed, $fails failed"
((fails == 0))
