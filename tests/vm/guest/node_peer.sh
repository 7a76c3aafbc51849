#!/bin/bash
# Guest test (vm_node_peer): node-canopen (npm `canopen`, pinned with `socketcan` in
# tests/vm/node_peer/package-lock.json, installed into the build tree by vm_node_peer_install), a
# CANopen host this project did not write, as the upstream host of the built `oegw run` on vcan0,
# with `oegw-sim` devices on vcan1. For each cab — the demo cab (tests/fixtures/vm_node_peer.yaml),
# only joystick 2, only pedal 2, the full FE set (tests/fixtures/full_fe_set.yaml on vcan0/vcan1
# with TCG margins) — `oegw check` and `oegw eds` write the mapping file's EDS, which node-canopen
# loads; node_peer_host.js then runs the cab (its comment lists the parts and node-canopen's
# quirks). Afterwards candump's recordings of both buses are judged here: the frames of the
# transfer types, the network indications, the aborts and the peer's echo of them, NMT, EMCY, LSS.
# Args: OEGW OEGW_SIM SOURCE_DIR NODE_MODULES [PART...] (PART: see node_peer_host.js)
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
(($# >= 4)) || { echo "usage: node_peer.sh OEGW OEGW_SIM SOURCE_DIR NODE_MODULES [PART...]" >&2; exit 64; }
oegw=$1 sim=$2 src=$3 modules=$4
shift 4
dir=/run/oegw-node-peer
mkdir -p "$dir"

# The node the addons were built for (install.sh's stamp) must be the one on PATH here: the guest
# runs the host's root, so it is, unless the install is stale.
if ! command -v node >/dev/null; then fail "no node on PATH"; exit 1; fi
installed=$(cat "$modules/../.installed" 2>/dev/null)
if [[ $installed != *"node $(node --version)" ]]; then
  fail "node-canopen install in $modules is not for node $(node --version) ($installed): run ctest -R vm_node_peer_install"
  exit 1
fi

# The mapping files: three fixtures, and the full FE set made real (vcan0/vcan1, a store, TCG
# margins: heartbeats 200 ms with a 1 s consumer, the freshness deadline 1 s of every input sent
# by event timer; the clusters send on change only and keep none).
mapping_fixture vm_node_peer.yaml "$src" "$dir" >"$dir/demo.yaml"
mapping_fixture vm_node_peer_joystick2.yaml "$src" "$dir" >"$dir/joystick2.yaml"
mapping_fixture vm_node_peer_pedal2.yaml "$src" "$dir" >"$dir/pedal2.yaml"
mapping_fixture full_fe_set.yaml "$src" "$dir" | sed -e '0,/interface: virtual/s//interface: vcan0/' \
  -e '0,/interface: virtual/s//interface: vcan1/' -e "s|store: .*|store: $dir/full.store|" \
  -e 's|^  heartbeat_ms: 100$|  heartbeat_ms: 200|' \
  -e 's/heartbeat_ms: 100\([ ,]\)/heartbeat_ms: 200, heartbeat_timeout_ms: 1000\1/' \
  -e '/button_cluster/!s/heartbeat_timeout_ms: 1000/&, pdo_timeout_ms: 1000/' >"$dir/full.yaml"
for cab in demo joystick2 pedal2 full; do
  if "$oegw" check --here "$dir/$cab.yaml" >"$dir/$cab.check" 2>&1; then pass "oegw check $cab.yaml: valid"; else
    fail "oegw check $cab.yaml: $(head -5 "$dir/$cab.check")"
  fi
  if "$oegw" eds "$dir/$cab.yaml" -o "$dir/$cab.eds" >/dev/null 2>&1; then
    pass "oegw eds $cab.yaml: $(grep -c '^\[18[0-9A-F][0-9A-F]\]$' "$dir/$cab.eds") TPDOs declared"
  else fail "oegw eds $cab.yaml failed"; fi
done
# oegw check's device type is the EDS's (the host compares the EDS with the device by SDO).
for cab in demo joystick2 pedal2 full; do
  dt=$(sed -n 's/.*1000h device type = \([0-9A-F]*\)h.*/\1/p' "$dir/$cab.check")
  if sed -n '/^\[1000\]/,/^$/p' "$dir/$cab.eds" | grep -qi "^DefaultValue=0x$dt\$"; then pass "$cab: the EDS's 1000h is oegw check's $dt"; else
    fail "$cab: the EDS's 1000h differs from oegw check's $dt"
  fi
done

echo "mapping files checked and EDS files written after $(elapsed) s"
start_candump vcan0 /tmp/up.dump || fail "candump vcan0 did not start"
up_candump=$candump_pid
start_candump vcan1 /tmp/down.dump || fail "candump vcan1 did not start"

node "$here/node_peer_host.js" "$modules" "$sim" "$src" "$dir" "$@" 2>&1 | sed -u 's/^/    host: /'
host_rc=${PIPESTATUS[0]}
echo "node-canopen host finished after $(elapsed) s"
((host_rc == 0)) && pass "node-canopen host: every check" || fail "node-canopen host: $host_rc failed"
stop_candump
candump_pid=$up_candump
stop_candump

# ---- candump's view. Only the demo cab's parts send these frames.
demo_parts=1
for p in "$@"; do [[ $p == demo || $p == demo:* ]] || demo_parts=0; done
[[ $# -eq 0 ]] && demo_parts=1
# Files, not shell strings: vcan1's record holds the full set's 120,000 frames, and a loaded TCG
# guest takes minutes to pass such a string to grep thirty times. Downstream only what is checked
# (NMT, SDO, LSS, the LEDs' RPDO 203h, the re-addressed cluster's boot-ups) is kept.
up=/tmp/up.frames
down=/tmp/down.frames
frames /tmp/up.dump >"$up"
frames /tmp/down.dump | awk '$2 ~ /^(000|203|5[89A-F].|6..|7E[45]|731|740)#/' >"$down"
expect() {  # FRAMES-FILE REGEX WHAT
  if grep -qE "^$2\$" "$1"; then pass "candump: $2 ($3)"; else fail "candump lacks $2 ($3)"; fi
}
if ((demo_parts)) && [[ $# -eq 0 ]]; then
  # Transfer types on the default channel, as node-canopen put them on the wire (CiA 301 §7.2.4.3).
  expect "$up" 'vcan0 5A0#4108100018000000' "segmented upload of 1008h: size 24 indicated"
  expect "$up" 'vcan0 620#A40810007F000000' "block upload initiate of 1008h: CRC, 127 segments a block, no protocol switch"
  expect "$up" 'vcan0 620#2B17100096000000' "expedited download of 1017h = 150"
  expect "$up" 'vcan0 620#2117100002000000' "segmented download initiate of 1017h, 2 bytes"
  expect "$up" 'vcan0 620#0BAF000000000000' "its one segment: 175, last"
  expect "$up" 'vcan0 620#C617100002000000' "block download initiate of 1017h: CRC, size 2"
  expect "$up" 'vcan0 5A0#A4171000[0-9A-F]{8}' "the gateway takes the block download"
  # The network indications (raw frames) and their answers.
  expect "$up" 'vcan0 620#E000000002110000' "network indication: network 2, node 11h"
  expect "$up" 'vcan0 5A0#E000000002110000' "accepted: echoed"
  expect "$up" 'vcan0 5A0#8000000000000206' "network 9 refused: 0602 0000h"
  expect "$up" 'vcan0 690#E000000002110000' "a network indication on the bound channel"
  expect "$up" 'vcan0 6B0#8000000021000008' "refused there: 0800 0021h"
  expect "$up" 'vcan0 5A0#8018100[12]23000A06' "060A 0023h: a second request while one is in flight"
  # Downstream: what the remote transfers and outputs caused.
  expect "$down" 'vcan1 611#2B0150001E000000' "gateway -> right_grip: 5001h = 30"
  expect "$down" 'vcan1 603#4000200000000000' "gateway -> left_grip: upload 2000h (the bound channel)"
  expect "$down" 'vcan1 203#05' "indicators.2 = 05h: left_grip's LEDs"
  if grep -qE '^vcan1 611#23001801' "$down"; then fail "the refused 1800h:01 write reached right_grip"; else pass "the refused 1800h:01 write never reached vcan1"; fi
  # Remote EMCY and the gateway's own EMCYs as the EMCY consumer read them.
  expect "$up" 'vcan0 0A0#2031[0-9A-F]{2}0381[0-9A-F]{6}' "left_grip's EMCY 3120h forwarded: node 03h, register 81h"
  expect "$up" 'vcan0 0A0#0070[0-9A-F]{2}7F73656174' "EMCY 7000h naming seat_knob 7Fh, \"seat\""
  expect "$up" 'vcan0 0A0#3081[0-9A-F]{12}' "EMCY 8130h: the host's heartbeat lost"
  expect "$up" 'vcan0 080#' "node-canopen's SYNC (1005h bit 30: it produces them, no counter)"
  # NMT from node-canopen.
  for c in 0220 8020 0120 8220 8120; do expect "$up" "vcan0 000#$c" "NMT $c"; done
  # LSS downstream (CiA 305): switch selective, configure node-ID FFh / 40h / 31h, fastscan.
  expect "$down" 'vcan1 7E5#43[0-9A-F]{8}000000' "switch state selective, serial number"
  expect "$down" 'vcan1 7E4#4400000000000000' "the cluster selected"
  expect "$down" 'vcan1 7E5#11FF000000000000' "configure node-ID FFh"
  expect "$down" 'vcan1 7E5#5100000000800000' "fastscan: any slave without node-ID?"
  expect "$down" 'vcan1 7E4#4F00000000000000' "fastscan: one answers"
  expect "$down" 'vcan1 7E5#1140000000000000' "configure node-ID 40h"
  expect "$down" 'vcan1 740#00' "its boot-up at 40h"
  expect "$down" 'vcan1 640#4018100200000000' "node-canopen's SDO upload of 1018h:02 at 40h"
  expect "$down" 'vcan1 731#00' "its boot-up at 31h again"
  # Q4: node-canopen answers an abort with an abort (CiA 301 §7.2.4.3.17 asks none); oegw sends
  # nothing back to an abort frame.
  aborts=$(grep -cE '^vcan0 5A0#80' "$up")
  echoes=$(awk '$1 == "vcan0" && $2 ~ /^5A0#80/ { a = substr($2, 5) } $1 == "vcan0" && $2 ~ /^620#80/ && substr($2, 5) == a { n++ } END { print n + 0 }' "$up")
  echo "the gateway's aborts on 5A0h: $aborts; node-canopen's echoes of them on 620h: $echoes (quirk Q4)"
  if awk '$1 == "vcan0" { if (e && $2 ~ /^5A0#/) bad = 1; e = ($2 ~ /^620#80/) } END { exit !bad }' "$up"; then
    fail "candump: the gateway answered an abort frame"
  else pass "candump: no answer of the gateway right after an abort frame of the host"; fi
fi
if grep -vE '^vcan0 (720|77D|5A0|0A0|080)#' "$up" | grep -qE '^vcan0 (7[0-7][0-9A-F]|5[89A-F][0-9A-F]|0[89A-F][0-9A-F])#'; then
  fail "sub-device frames on vcan0"
else pass "vcan0 carries no sub-device frame"; fi

cp /tmp/up.dump /tmp/down.dump "$dir"/*.log "$dir"/*.eds "${OEGW_VM_OUT:-/tmp}/" 2>/dev/null
echo "total $(elapsed) s; $passes passed, $fails failed"
((fails == 0))
