#!/bin/bash
# Guest test (vm_ctl): `oegw ctl` outside in. `oegw run` with
# tests/fixtures/vm_gateway.yaml (downstream vcan1, its control socket at the default path), the
# cab devices as `oegw-sim` processes on vcan1; `oegw ctl` is a third process that reads 1018h:01
# of the elobau grip, writes an elobau parameter (5001h) and reads it back, and is refused the
# grip's TPDO1 COB-ID (1800h:01: the gateway configured it and its FEs use the grip) with
# 0800 0021h, exiting 1 at that ERROR (--exit). candump on vcan1, an independent peer, judges the
# frames: the values `oegw ctl` printed are those the grip's SDO answers carried, and no request
# for 1800h ever reached the bus. Interactive, on a pseudo-terminal (ctl_pty.py types the lines):
# a prompt per command, `!!`, `history`, a refused `!N`, Ctrl-D. LSS (CiA 305) through the daemon: cansend takes the button
# cluster's node-ID away (as scan.sh does); `oegw ctl` identifies it as non-configured, finds its
# LSS address with `_lss_fastscan`, gives it 31h again with `lss_set_node`, stores (the cluster
# simulator's LSS store file), switches to waiting, and the gateway boots it as its cluster again;
# candump shows the LSS frames of each command. Before that, `oegw scan` runs through the gateway
# (no -i: it asks the control socket) while the cluster has no node-ID. Then: no daemon → exit 3.
# Args: OEGW OEGW_SIM SOURCE_DIR
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1
sim=$2
src=$3
dir=/run/oegw-ctl

prepare_gateway_run vm_gateway.yaml "$src" "$dir" "$oegw"
rc=$?
((rc == 0)) && pass "oegw check: valid" || fail "oegw check exit $rc: $(cat /tmp/check.out)"
start_candump vcan1 /tmp/down.dump || fail "candump vcan1 did not start"
rm -f /tmp/cluster.store /tmp/cluster.store.lss
gateway_cab "$src"
start_gateway_scenario "$oegw" "$dir" 5 "$sim" --motion "${devices[@]:0:4}" "${devices[4]},store=/tmp/cluster.store" \
  novotechnik-406:0x40:name=spare

# ---- Scripted: read the identity, write and read back an allowed object.
printf '%s\n' '[1] set network 2' '[2] set node 17' '[3] r 0x1018 1 u32' '[4] 2 17 w 0x5001 0 u16 30' \
  '[5] 2 17 r 0x5001 0 u16' '[6] info version' | "$oegw" ctl --exit >/tmp/ctl1.out 2>&1
rc=$?
sed 's/^/    ctl: /' /tmp/ctl1.out
((rc == 0)) && pass "oegw ctl --exit: exit 0" || fail "oegw ctl --exit: exit $rc"
grep -qxF '[1] OK' /tmp/ctl1.out && grep -qxF '[2] OK' /tmp/ctl1.out && pass "set network/node: [n] OK" || fail "set network/node answers"
vendor=$(sed -n 's/^\[3\] 0x\([0-9A-F]\{8\}\)$/\1/p' /tmp/ctl1.out)
[[ -n $vendor ]] && pass "1018h:01 = 0x$vendor" || fail "no [3] 0x........ answer"
grep -qxF '[4] OK' /tmp/ctl1.out && pass "write 5001h: [4] OK" || fail "write 5001h not OK"
grep -qxF '[5] 0x001E' /tmp/ctl1.out && pass "5001h read back: [5] 0x001E" || fail "5001h not read back as 0x001E"
grep -qE '^\[6\] 0x[0-9A-F]{8} 0x00000852 0x00010000 0x00000001 3 3\.0 [0-9]+\.[0-9]+$' /tmp/ctl1.out &&
  pass "info version: the gateway's 1018h as r prints it (852h, rev 00010000h, serial 1)" ||
  fail "info version answer"

# ---- Refused: the grip's TPDO1 COB-ID; --exit ends at that ERROR with exit 1, the next line unrun.
t_refused=$(date +%s.%N)
printf '%s\n' '[7] 2 17 w 0x1800 1 u32 0x80000191' '[8] 2 17 r 0x1018 2 u32' | "$oegw" ctl --exit >/tmp/ctl2.out 2>&1
rc=$?
t_refused_end=$(date +%s.%N)
sed 's/^/    ctl: /' /tmp/ctl2.out
((rc == 1)) && pass "oegw ctl --exit: exit 1 at the ERROR" || fail "oegw ctl --exit after a refusal: exit $rc"
grep -qE '^\[7\] ERROR: 08000021 \(.+\)$' /tmp/ctl2.out && pass "1800h:01: [7] ERROR: 08000021" || fail "no 0800 0021h refusal"
grep -q '^\[8\]' /tmp/ctl2.out && fail "--exit ran the line after the ERROR" || pass "--exit ran nothing after it"
# Without --exit every line runs, exit 0; a node no sub-device has: 0609 0011h.
printf '%s\n' '[9] 2 5 r 0x1000 0 u32' '[10] 2 17 r 0x1018 2 u32' | "$oegw" ctl >/tmp/ctl3.out 2>&1
rc=$?
((rc == 0)) && grep -qE '^\[9\] ERROR: 06090011 ' /tmp/ctl3.out && grep -qE '^\[10\] 0x[0-9A-F]{8}$' /tmp/ctl3.out &&
  pass "without --exit: [9] ERROR: 06090011, [10] answered, exit 0" || fail "without --exit (exit $rc): $(cat /tmp/ctl3.out)"

# ---- Interactive (a pty, as at a terminal): a prompt per command, `!!` runs the last line again,
# `history` lists the lines run, `!N` of a line not in it is an error; Ctrl-D ends it, exit 0.
"$PY" "$here/ctl_pty.py" "$oegw" '[30] 2 17 r 0x1018 1 u32' '!!' 'history' '!9' >/tmp/ctl4.out 2>&1
rc=$?
sed 's/^/    ctl (pty): /' /tmp/ctl4.out
((rc == 0)) && pass "oegw ctl on a terminal: exit 0 at Ctrl-D" || fail "oegw ctl on a terminal: exit $rc"
n=$(grep -c "^\[30\] 0x$vendor\$" /tmp/ctl4.out)
((n == 2)) && pass "interactive: [30] answered twice (the line and its !!)" || fail "interactive: $n answers [30] 0x$vendor"
grep -qE '^ +1  \[30\] 2 17 r 0x1018 1 u32$' /tmp/ctl4.out && grep -qE '^ +2  \[30\] 2 17 r 0x1018 1 u32$' /tmp/ctl4.out &&
  pass "interactive: history lists both lines" || fail "interactive: no history list"
grep -qF 'oegw ctl: no line 9 in the history' /tmp/ctl4.out && pass "interactive: !9 refused" || fail "interactive: !9 not refused"
[[ $(grep -c '> ' /tmp/ctl4.out) -ge 5 ]] && pass "interactive: a prompt before each line" || fail "interactive: prompts missing"

# ---- LSS: the cluster (button_cluster.eds 1018h: vendor A5Ah, product 402h, revision 00010002h,
# serial 0) loses its node-ID by cansend: switch state selective, configure node-ID FFh, waiting,
# NMT reset communication. The gateway then holds it missing.
for f in 405A0A0000000000 4102040000000000 4202000100000000 4300000000000000 11FF000000000000 \
  0400000000000000; do
  cansend vcan1 "7E5#$f"
done
cansend vcan1 000#8231
if "$PY" "$here/status_wait.py" "$oegw" /tmp/status.json 60 'subs["cluster"]["network_state"] != "operational"'; then
  pass "the cluster without node-ID: no longer operational for the gateway"
else
  fail "the cluster stayed operational after losing its node-ID"
fi

# ---- `oegw scan` through the running gateway: no -i, so it asks the control
# socket. The gateway's sub-devices are reported as it knows them and never probed (their SDO
# channels are its own clients'), the encoder at 40h that the mapping file does not name is found
# by SDO, and the cluster's LSS address is read by fastscan on the gateway's own LSS master.
t_scan=$(date +%s.%N)
timeout 120 "$oegw" scan --upstream vcan0 --timeout 1000 --lss-timeout 200 -o /tmp/scan_draft.yaml 2>/tmp/scan.err
rc=$?
t_scan_end=$(date +%s.%N)
sed 's/^/    scan: /' /tmp/scan.err
((rc == 0)) && pass "oegw scan through the gateway: exit 0" || fail "oegw scan through the gateway: exit $rc"
grep -q '^scanning vcan1 through the running gateway' /tmp/scan.err && pass "scan: through the gateway on vcan1" ||
  fail "scan: not through the gateway"
grep -q '^probing node 122/122, found ' /tmp/scan.err && pass "scan: progress to 122/122 (127 node-IDs, its 5 not probed)" ||
  fail "scan: no final progress line 122/122"
grep -q "^node 11h: elobau-mfg (the running gateway drives it as right_grip).*the gateway's sub-device right_grip, operational" \
  /tmp/scan.err && pass "scan: the grip as the gateway knows it" || fail "scan: no line for the grip as right_grip"
grep -q '^node 40h: novotechnik-406 (' /tmp/scan.err && pass "scan: the encoder at 40h found by SDO" || fail "scan: 40h not found"
for entry in '  right_grip:' '  left_grip:' '  seat_knob:' '  novotechnik_406_40:'; do
  grep -qxF -- "$entry" /tmp/scan_draft.yaml && pass "draft has '$entry'" || fail "draft lacks '$entry'"
done
addr='vendor 0x00000A5A, product 0x00000402, revision 0x00010002, serial 0x00000000'
sed 's/^# //' /tmp/scan_draft.yaml | tr '\n' ' ' | grep -q "fastscan read its address: $addr" &&
  pass "draft: the cluster's LSS address (fastscan on the gateway's LSS master)" || fail "draft lacks the cluster's LSS address"
# Refused at the MCB-402's placeholder (no draft passes on a guess), accepted with it written.
"$oegw" check /tmp/scan_draft.yaml >/tmp/check2.out 2>&1
(($? == 1)) && grep -q "button_bits is still the draft's placeholder TODO" /tmp/check2.out &&
  pass "oegw check refuses the draft at button_bits: TODO" || fail "oegw check of the draft: $(head -5 /tmp/check2.out)"
sed -i 's/button_bits: TODO .*/button_bits: [1, 2, 3, 4, 5, 7, 6]/' /tmp/scan_draft.yaml
"$oegw" check /tmp/scan_draft.yaml >/tmp/check2.out 2>&1 && pass "oegw check accepts the draft with button_bits written" ||
  fail "oegw check refuses the draft: $(head -5 /tmp/check2.out)"
sleep 0.5  # (candump writes what it received)
# (the cluster at 31h is left out: the gateway itself asks the missing node's 1000h at each retry)
n=$(awk -v a="$t_scan" -v b="$t_scan_end" '{ t = substr($1, 2, length($1) - 2) + 0 }
  t >= a && t <= b && $3 ~ /^6(11|03|30|7F)#/' /tmp/down.dump | wc -l)
((n == 0)) && pass "no SDO request to an operational sub-device during the scan" ||
  fail "$n SDO requests to operational sub-devices during the scan"
n=$(awk -v a="$t_scan" -v b="$t_scan_end" '{ t = substr($1, 2, length($1) - 2) + 0 } t >= a && t <= b && $3 ~ /^640#40/' \
  /tmp/down.dump | wc -l)
((n == 6)) && pass "the encoder at 40h: 6 upload requests (1000h, 1018h:01..04, 1017h)" || fail "40h: $n upload requests"
others='all(d["network_state"] == "operational" for d in s["subdevices"] if d["name"] != "cluster")'
"$PY" "$here/status_wait.py" "$oegw" /tmp/status.json 10 "$others" && pass "the other sub-devices still operational" ||
  fail "a sub-device lost during the scan: $(head -c 2000 /tmp/status.json)"
# lely's commands first (its coctl documentation): identify remote slave over the cluster's vendor
# and product, slowscan over the same range, fastscan with vendor and product known; each leaves
# the cluster selected, so each is followed by a switch back to waiting.
printf '%s\n' '[20] set network 2' '[21] lss_ident_nonconf' '[40] lss_identity 0xA5A 0x402 0 0xFFFFFFFF 0 0xFFFFFFFF' \
  '[41] _lss_slowscan 0xA5A 0x402 0 0xFFFFFFFF 0 0xFFFFFFFF' '[42] lss_switch_glob 0' \
  '[43] _lss_fastscan 0xA5A 0xFFFFFFFF 0x402 0xFFFFFFFF 0 0 0 0' '[44] lss_switch_glob 0' \
  '[22] _lss_fastscan 200' '[23] lss_get_node' \
  '[24] lss_set_node 49' '[25] lss_store' '[26] lss_inquire_addr 3' '[27] lss_switch_glob 0' |
  "$oegw" ctl --exit >/tmp/ctl5.out 2>&1
rc=$?
sed 's/^/    ctl: /' /tmp/ctl5.out
((rc == 0)) && pass "oegw ctl LSS session: exit 0" || fail "oegw ctl LSS session: exit $rc"
grep -qxF '[21] OK' /tmp/ctl5.out && pass "lss_ident_nonconf: a node without node-ID answered" || fail "lss_ident_nonconf"
grep -qxF '[40] OK' /tmp/ctl5.out && pass "lss_identity: the cluster is in the range" || fail "lss_identity"
grep -qxF '[41] 0x00000A5A 0x00000402 0x00010002 0x00000000' /tmp/ctl5.out &&
  pass "_lss_slowscan: the cluster's LSS address" || fail "_lss_slowscan did not answer the cluster's address"
grep -qxF '[43] 0x00000A5A 0x00000402 0x00010002 0x00000000' /tmp/ctl5.out &&
  pass "_lss_fastscan with known vendor and product: the cluster's LSS address" || fail "_lss_fastscan (lely's form)"
grep -qxF '[22] 0x00000A5A 0x00000402 0x00010002 0x00000000' /tmp/ctl5.out &&
  pass "_lss_fastscan: the cluster's LSS address" || fail "_lss_fastscan did not answer the cluster's address"
grep -qxF '[23] 255' /tmp/ctl5.out && pass "lss_get_node: 255 (selected, no node-ID)" || fail "lss_get_node"
grep -qxF '[24] OK' /tmp/ctl5.out && pass "lss_set_node 49: OK" || fail "lss_set_node 49"
grep -qxF '[25] OK' /tmp/ctl5.out && pass "lss_store: OK" || fail "lss_store"
grep -qxF '[26] 0x00000000' /tmp/ctl5.out && pass "lss_inquire_addr 3: its serial" || fail "lss_inquire_addr 3"
grep -qxF '[27] OK' /tmp/ctl5.out && pass "lss_switch_glob 0: OK" || fail "lss_switch_glob 0"
[[ -s /tmp/cluster.store.lss ]] && pass "the cluster's LSS store written ($(tr '\n' ' ' </tmp/cluster.store.lss))" ||
  fail "no LSS store file of the cluster"
if "$PY" "$here/status_wait.py" "$oegw" /tmp/status.json 120 'subs["cluster"]["network_state"] == "operational"'; then
  pass "the gateway booted the cluster at 31h again"
else
  fail "the cluster is not operational again: $(head -c 2000 /tmp/status.json)"
fi
# On the gateway's own bus, LSS is refused (the gateway is no LSS master there).
echo '[28] 1 lss_get_node' | "$oegw" ctl >/tmp/ctl6.out 2>&1
grep -qE '^\[28\] ERROR: 100 ' /tmp/ctl6.out && pass "LSS upstream: ERROR: 100" || fail "LSS upstream: $(cat /tmp/ctl6.out)"

# ---- candump vcan1: the SDO frames of the grip, in order.
stop_candump
got=$(frames /tmp/down.dump)
expect_frame() {
  if grep -qxF "vcan1 $1" <<<"$got"; then pass "candump vcan1: $1 ($2)"; else fail "candump vcan1 lacks $1 ($2)"; fi
}
v=${vendor:-00000000}
expect_frame '611#4018100100000000' "upload request 1018h:01"
expect_frame "591#43181001${v:6:2}${v:4:2}${v:2:2}${v:0:2}" "its answer: the value oegw ctl printed"
expect_frame '611#2B0150001E000000' "download 5001h = 30 (u16)"
expect_frame '591#6001500000000000' "download confirmed"
# The gateway wrote 1800h itself while configuring the grip (before); while `oegw ctl` asked for
# the refused write (and --exit stopped before line 8), no SDO request went to the grip at all.
n=$(awk -v a="$t_refused" -v b="$t_refused_end" '{ t = substr($1, 2, length($1) - 2) + 0 } t >= a && t <= b && $3 ~ /^611#/' /tmp/down.dump | wc -l)
((n == 0)) && pass "no SDO request to the grip while 1800h was refused" || fail "$n SDO requests to the grip while 1800h was refused"
# (outside the scan, which probes every node-ID that is no sub-device)
n=$(awk -v a="$t_scan" -v b="$t_scan_end" '{ t = substr($1, 2, length($1) - 2) + 0 } (t < a || t > b) && $3 ~ /^605#/' \
  /tmp/down.dump | wc -l)
((n == 0)) && pass "nothing sent to node 05h by oegw ctl" || fail "$n requests to node 05h outside the scan"
# The LSS frames of `oegw ctl` (CiA 305 command specifiers): identify non-configured 4Ch / 50h,
# the fastscan reset step (BitChecked 80h) answered 4Fh and its last step (serial 0, bit 0,
# LSSSub 3, LSSNext 0), configure node-ID 31h / error 0, store / error 0, inquire serial 5Dh,
# inquire node-ID 5Eh, waiting; then the cluster's boot-up at 31h.
expect_frame '7E5#4C00000000000000' "identify non-configured"
expect_frame '7E4#5000000000000000' "answered by the cluster"
expect_frame '7E5#5100000000800000' "fastscan reset step"
expect_frame '7E4#4F00000000000000' "fastscan answer"
expect_frame '7E5#5100000000000300' "fastscan: the serial confirmed"
expect_frame '7E5#1131000000000000' "configure node-ID 31h"
expect_frame '7E4#1100000000000000' "node-ID configured"
expect_frame '7E5#1700000000000000' "store configuration"
expect_frame '7E4#1700000000000000' "stored"
expect_frame '7E5#5D00000000000000' "inquire serial"
expect_frame '7E4#5D00000000000000' "its serial 0"
bad=$(grep -E '^vcan1 7E5#' <<<"$got" | awk '{ b = substr($2, 5, 2); if (b !~ /^(40|41|42|43|46|47|48|49|4A|4B|11|04|4C|51|17|5D|5E)$/) print }' | head -3)
[[ -z $bad ]] && pass "LSS: no other command on 7E5h" || fail "other LSS frames: $bad"
awk '$3 ~ /^7E5#1131/ { s = 1 } s && $3 ~ /^731#00$/ { found = 1 } END { exit !found }' /tmp/down.dump &&
  pass "the cluster's boot-up at 31h after its node-ID was configured" || fail "no boot-up 731#00 after lss_set_node"

# ---- The gateway stops: oegw ctl finds no daemon (exit 3, as oegw status).
kill -TERM "$gw_pid"
wait "$gw_pid"
rc=$?
((rc == 0)) && pass "oegw run: SIGTERM, exit 0" || fail "oegw run exit $rc"
echo '[11] 2 17 r 0x1018 1 u32' | "$oegw" ctl >/tmp/ctl4.out 2>&1
rc=$?
((rc == 3)) && pass "no daemon: exit 3 ($(head -1 /tmp/ctl4.out))" || fail "no daemon: exit $rc: $(cat /tmp/ctl4.out)"
kill -TERM "$sim_pid" 2>/dev/null
wait "$sim_pid" 2>/dev/null
cp /tmp/down.dump /tmp/gateway.log /tmp/ctl*.out "${OEGW_VM_OUT:-/tmp}/" 2>/dev/null
echo "total $(elapsed) s; $passes passed, $fails failed"
((fails == 0))
