#!/bin/bash
# Guest test (vm_bitrate; run-in-vm.sh --kvaser 2): the bit rate on real CAN controllers. qemu
# emulates two SJA1000 (kvaser_pci) on one bus, can0 and can1; `oegw run` has its upstream on can0
# (tests/fixtures/vm_bitrate.yaml: 250 kbit/s, node 20h, heartbeat 100 ms), the peer is can-utils
# on can1 (cansend, candump), whose rate the script sets with ip. Scenarios, PASS/FAIL lines:
#  1 can0 at 125000 and down: `oegw check` says it will be set; `oegw run` sets 250000 (ip -details
#    says so) and its boot-up and heartbeat are seen on can1;
#  2 LSS from can1: configure bit timing 800 kbit/s (not in the EDS) is refused with error 1,
#    125 kbit/s is taken, store configuration writes it, activate bit timing with 500 ms switch
#    delay moves can0 to 125000, nothing is sent on the bus for twice the delay, the heartbeat comes
#    back once can1 follows;
#  3 restart: the LSS-stored 125000 wins over upstream.bitrate 250000 (logged), can0 at 125000;
#  4 setting fails (oegw run as nobody: no CAP_NET_ADMIN): the error names upstream.bitrate, the
#    exit status is not 0, no frame of the gateway on the bus, can0 unchanged;
#  5 vcan0 (no bit timing): reported once, the gateway works; LSS activate there is reported as not
#    applicable and the heartbeat goes on.
# Args: OEGW SOURCE_DIR
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1
src=$2
dir=/run/oegw-bitrate

# The bit rate ip reports for a CAN interface ("" when none is set).
rate_of() { ip -details link show "$1" | sed -n 's/.*bitrate \([0-9]*\).*/\1/p' | head -n1; }
# set_rate DEV RATE: down, bit rate, up (the peer's side).
set_rate() { ip link set "$1" down && ip link set "$1" type can bitrate "$2" && ip link set "$1" up; }
# wait_grep FILE REGEX [TIMEOUT_S]: until a line of FILE matches.
wait_grep() {
  local i
  for ((i = 0; i < ${3:-20} * 20; i++)); do
    grep -qE "$2" "$1" 2>/dev/null && return 0
    sleep 0.05
  done
  return 1
}
# wait_rate DEV RATE [TIMEOUT_S]
wait_rate() {
  local i
  for ((i = 0; i < ${3:-10} * 20; i++)); do
    [[ $(rate_of "$1") == "$2" ]] && return 0
    sleep 0.05
  done
  return 1
}
stop_gateway() {  # pid: SIGTERM, its exit status in $gw_rc
  kill -TERM "$1" 2>/dev/null
  wait "$1"
  gw_rc=$?
}
expect() {  # condition-status message
  if (($1 == 0)); then pass "$2"; else fail "$2"; fi
}

if [[ ! -e /sys/class/net/can0 || ! -e /sys/class/net/can1 ]]; then
  fail "no can0/can1: the VM needs two emulated controllers (run-in-vm.sh --kvaser 2)"
  exit 1
fi
ip link set can0 type can bitrate 125000  # down, at another rate than the mapping file's
set_rate can1 250000
echo "can0 at $(rate_of can0) (down), can1 at $(rate_of can1) (up)"

# ---- 1: set at start
prepare_gateway_run vm_bitrate.yaml "$src" "$dir" "$oegw"
expect $? "oegw check: valid"
sed 's/^/    check: /' /tmp/check.out | grep -i "bit" | head -8
grep -q "can0 is at 125000 bit/s: oegw run sets it to 250000" /tmp/check.out
expect $? "oegw check says can0 will be set from 125000 to 250000"
start_candump can1 /tmp/can1.dump -D || fail "candump can1 did not start"
dump_pid=$candump_pid
"$oegw" run "$dir/oegw.yaml" >/tmp/gw1.log 2>&1 &
gw=$!
wait_grep /tmp/can1.dump "can1 720#00$" 30
expect $? "boot-up 720#00 of the gateway seen on can1 ($(elapsed s))"
wait_grep /tmp/can1.dump "can1 720#7F$" 10
expect $? "heartbeat 720#7F seen on can1"
[[ $(rate_of can0) == 250000 ]]
expect $? "ip -details link show can0: bitrate $(rate_of can0) (upstream.bitrate 250000)"
grep -q "upstream.bitrate: can0 set from 125000 to 250000 bit/s" /tmp/gw1.log
expect $? "the gateway logs the change of can0"

# ---- 2: LSS configure bit timing, store, activate
cansend can1 7E5#0401000000000000  # switch state global: configuration
cansend can1 7E5#1300010000000000  # table 0 index 1: 800 kbit/s, not in the EDS
wait_grep /tmp/can1.dump "can1 7E4#1301000000000000$" 5
expect $? "LSS configure bit timing 800 kbit/s refused with error 1 (7E4#1301...)"
cansend can1 7E5#1300040000000000  # index 4: 125 kbit/s
wait_grep /tmp/can1.dump "can1 7E4#1300000000000000$" 5
expect $? "LSS configure bit timing 125 kbit/s taken (7E4#1300...)"
cansend can1 7E5#1700000000000000  # store configuration
wait_grep /tmp/can1.dump "can1 7E4#1700000000000000$" 5
expect $? "LSS store configuration confirmed (7E4#1700...)"
grep -qx "bit_timing=4" "$dir/upstream.store.lss" 2>/dev/null
expect $? "the store holds bit_timing=4 ($(tr '\n' ' ' <"$dir/upstream.store.lss" 2>/dev/null))"
cansend can1 7E5#15F4010000000000  # activate bit timing, switch delay 500 ms (01F4h, low byte first)
wait_rate can0 125000 10
expect $? "LSS activate bit timing: ip -details link show can0: bitrate $(rate_of can0)"
set_rate can1 125000
cansend can1 7E5#0400000000000000  # back to waiting
# The heartbeat after the activate: the first one at least 2 x 500 ms after it (CiA 305: silent
# for the switch delay, switch, silent again for the switch delay).
wait_grep /tmp/can1.dump "can1 7E5#0400000000000000$" 5
sleep 0.5
gap=$(awk '$3 == "7E5#15F4010000000000" { t = substr($1, 2, length($1) - 2) + 0 }
           t && $3 ~ /^720#/ { printf "%.3f", substr($1, 2, length($1) - 2) - t; exit }' /tmp/can1.dump)
echo "first frame of the gateway ${gap:-never} s after the activate"
[[ -n $gap ]] && awk -v g="$gap" 'BEGIN { exit !(g >= 0.99) }'
expect $? "nothing sent by the gateway for 2 x the switch delay after activate (${gap:-none} s >= 1.0 s)"
grep -q "LSS activate bit timing: can0 switched from 250000 to 125000 bit/s" /tmp/gw1.log
expect $? "the gateway logs the LSS switch of can0"
stop_gateway "$gw"
expect $gw_rc "SIGTERM stops oegw run (exit $gw_rc)"

# ---- 3: the stored rate wins at the next start
ip link set can0 down
ip link set can0 type can bitrate 250000
"$oegw" run "$dir/oegw.yaml" >/tmp/gw3.log 2>&1 &
gw=$!
wait_grep /tmp/gw3.log "oegw: node 20h" 30
expect $? "oegw run starts again"
[[ $(rate_of can0) == 125000 ]]
expect $? "restart: can0 at $(rate_of can0), the LSS-stored rate (the file says 250000)"
grep -q "LSS-stored bit rate 125000 bit/s .* overrides upstream.bitrate 250000" /tmp/gw3.log
expect $? "the gateway logs that the LSS-stored rate wins"
stop_gateway "$gw"

# ---- 4: setting fails
rm -f "$dir/upstream.store.lss"
ip link set can0 down
ip link set can0 type can bitrate 500000
before=$(grep -c "can1 720#" /tmp/can1.dump)
setpriv --reuid=65534 --regid=65534 --clear-groups "$oegw" run "$dir/oegw.yaml" >/tmp/gw4.log 2>&1
rc=$?
sed 's/^/    gateway: /' /tmp/gw4.log | head -5
((rc != 0))
expect $? "oegw run without CAP_NET_ADMIN refuses to start (exit $rc)"
grep -q "upstream.bitrate: cannot set can0 to 250000 bit/s: Operation not permitted" /tmp/gw4.log
expect $? "the error names upstream.bitrate, can0, the rate and the reason"
sleep 0.3
[[ $(grep -c "can1 720#" /tmp/can1.dump) == "$before" ]]
expect $? "nothing half-started: no frame of the gateway on the bus"
[[ $(rate_of can0) == 500000 ]]
expect $? "can0 left at $(rate_of can0)"
stop_candump
candump_pid=$dump_pid
stop_candump

# ---- 5: vcan
sed 's/interface: can0/interface: vcan0/' "$dir/oegw.yaml" >"$dir/vcan.yaml"
start_candump vcan0 /tmp/vcan0.dump || fail "candump vcan0 did not start"
"$oegw" run "$dir/vcan.yaml" >/tmp/gw5.log 2>&1 &
gw=$!
wait_grep /tmp/vcan0.dump "vcan0 720#00$" 30
expect $? "vcan0: boot-up 720#00"
n=$(grep -c "vcan0 has no bit timing (virtual CAN): upstream.bitrate 250000 not applied" /tmp/gw5.log)
((n == 1))
expect $? "vcan0 reported once as without bit timing ($n)"
cansend vcan0 7E5#0401000000000000
cansend vcan0 7E5#1300040000000000
cansend vcan0 7E5#1564000000000000  # 100 ms
wait_grep /tmp/gw5.log "LSS activate bit timing: vcan0 has no bit timing \(virtual CAN\): 125000 bit/s not applicable" 10
expect $? "LSS activate on vcan0 reported as not applicable"
cansend vcan0 7E5#0400000000000000
sleep 0.5
awk 'found && $3 == "720#7F" { ok = 1 } $3 == "7E5#0400000000000000" { found = 1 } END { exit !ok }' /tmp/vcan0.dump
expect $? "vcan0: the heartbeat goes on after the activate"
stop_gateway "$gw"
expect $gw_rc "SIGTERM stops oegw run on vcan0 (exit $gw_rc)"
stop_candump

echo "== gateway logs"
for f in /tmp/gw1.log /tmp/gw3.log /tmp/gw5.log; do sed "s|^|    $(basename "$f" .log): |" "$f" | head -20; done
echo "bitrate: $passes passed, $fails failed ($(elapsed s))"
((fails == 0))
