#!/bin/bash
# Guest test (vm_corners): a cab of `oegw-sim` devices at the corners of their documents opposite to
# the simulators' defaults
# (docs/design/device-documents.md#corners-every-reading-a-document-permits), under `oegw run`
# (tests/fixtures/vm_corners.yaml), judged on candump's recordings of both buses:
#   elobau grip 11h   tpdo=timer (TPDOs on the event timer only), saved=no (4001h 0002h: never
#                     saved; the file lets the gateway save it), buttons=255 (2100h:01h)
#   MCB-402 03h       clear_after_break=none (no 0000h after a mend), power_on_1001h=11h (1001h keeps
#                     the power-on warning's bits); wired by the table's right-end reading
#   encoder 7Fh       error_register_size=2 (1001h UNSIGNED16), emcy_behaviour=3 (2104h stored:
#                     errors suppressed), has_6020h=no, work_area_emcy=enum
#   pedal 30h         (no document: CiA 401)
# Checks, one PASS/FAIL line each:
#   1 every node started (000#01nn on vcan1, then its heartbeat 7nn#05) and operational;
#   2 the grip saved by the gateway (611#2310100173617665 "save"), restarted by it (000#8111), and
#     started after that; the encoder's 1001h answered in two bytes (5FF#4B011000...) and taken;
#     its 6020h entry refused and 6004h mapped instead (67F#23001A0120000460 answered 60h); 2104h
#     written 0 (67F#2F04210000...);
#   3 the FEs live upstream: with the host's TPDOs enabled (cansend: 1800h/1804h/181Bh:01, 6423h
#     TRUE, NMT start), joystick 1 (1A0h), joystick 2 (2A0h) and encoder 1 (2C0h) take several
#     values while the devices move (oegw-sim --motion);
#   4 a fault raised and cleared on the evidence each corner gives: the MCB-402's cable break (EMCY
#     7000h naming 03h upstream), mended without an error reset (no 083#0000 on vcan1), cleared by
#     its 1001h read while the fault lasts (603#40011000 answered 583#4F01100011) and the gateway's
#     error reset upstream; the grip's button timeout 0061h (7000h naming 11h) and its error reset;
#     the encoder's measurement error, which its stored 2104h = 3 would have suppressed, reported
#     (0FF#5150 01...) and cleared by "valid position" (0FF#5150 00...).
# Args: OEGW OEGW_SIM SOURCE_DIR
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
oegw=$1 sim=$2 src=$3
dir=/run/oegw-corners

run_recorded vm_corners.yaml "$src" "$dir" "$oegw"
mkfifo /tmp/dev.cmd
exec 3<>/tmp/dev.cmd
corners_cab "$src"
start_sim "$sim" /tmp/sim.log --motion --commands "${devices[0]},saved=no,store=$dir/grip.store" "${devices[@]:1}"

# in_order FILE A B [C]: a line matching A, then a later one matching B (then C).
in_order() {
  awk -v a="$2" -v b="$3" -v c="${4:-}" '
    s == 0 && $0 ~ a { s = 1; next }
    s == 1 && $0 ~ b { s = 2; if (c == "") exit 0; next }
    s == 2 && c != "" && $0 ~ c { s = 3; exit 0 }
    END { exit !(s == (c == "" ? 2 : 3)) }' "$1"
}
now() { date +%s.%N; }
# after FILE T PATTERN: lines of candump FILE later than T (seconds) matching PATTERN.
after() { awk -v t="$2" -v p="$3" '{ s = substr($1, 2, length($1) - 2) + 0 } s > t && $0 ~ p' "$1"; }
fault_of() { printf 'vcan0 0A0#0070..%s' "$1"; }  # EMCY 7000h naming node $1 (hex)

# 1 every node started and operational.
for n in right_grip left_grip seat_knob pedal; do
  wait_for /tmp/gateway.log "$n: operational" 90 && pass "1: $n operational after $(elapsed) s" || fail "1: $n never operational"
done
for id in 11 03 7F 30; do
  if in_order /tmp/down.dump "vcan1 000#01$id" "vcan1 7$(printf '%02X' $((0x$id)))#05"; then
    pass "1: vcan1 carries 000#01$id (NMT start) then its heartbeat in operational"
  else
    fail "1: no NMT start of $id followed by its heartbeat 05h on vcan1"
  fi
done

# 2 what the corners needed at boot, on the wire.
if in_order /tmp/down.dump 'vcan1 611#2310100173617665' 'vcan1 000#8111' 'vcan1 000#0111'; then
  pass "2: the never-saved grip saved by the gateway (\"save\" on 1010h:01), reset node, then started"
else
  fail "2: no save / reset node / start of the grip on vcan1"
fi
grep -q 'right_grip: refused' /tmp/gateway.log && fail "2: the grip was refused: $(grep 'right_grip: refused' /tmp/gateway.log | head -1)" \
  || pass "2: the grip was not refused (parameter_checksum: save)"
grep -q 'vcan1 5FF#4B01100000000000' /tmp/down.dump && pass "2: the encoder's 1001h answered in two bytes (UNSIGNED16) and taken" \
  || fail "2: no two-byte 1001h answer of the encoder"
if in_order /tmp/down.dump 'vcan1 67F#23001A0120012060' 'vcan1 5FF#80001A01' 'vcan1 67F#23001A0120000460'; then
  pass "2: the encoder refused the 6020h entry and got 6004h in its stead"
else
  fail "2: no 6020h refusal followed by the 6004h entry"
fi
grep -q 'vcan1 67F#2F04210000000000' /tmp/down.dump && pass "2: 2104h (EMCY behaviour) written 0" || fail "2: 2104h not written"

# 3 the FEs live upstream: the host (cansend) enables joystick 1, joystick 2 and encoder 1's TPDOs
# (CiA 852 clause 12: 1800h, 1804h, 181Bh disabled by default), 6423h TRUE, NMT start.
for req in 23001801A0010000 23041801A0020000 231B1801C0020000 2F23640001000000; do
  cansend vcan0 "620#$req"
  sleep 0.3
done
cansend vcan0 000#0120
sleep 4
for cob in 1A0 2A0 2C0; do
  values=$(awk -v c="vcan0 $cob#" 'index($0, c) { print $3 }' /tmp/up.dump | sort -u | wc -l)
  ((values >= 3)) && pass "3: upstream $cob (a live FE) took $values values" || fail "3: upstream $cob took $values values"
done

# 4 a fault raised and cleared per corner.
t=$(now)
echo "left_grip cable_break 1 on" >&3
wait_for /tmp/up.dump "$(fault_of 03)" 10 && pass "4: MCB-402 cable break -> EMCY 7000h naming 03h" \
  || fail "4: no 7000h naming 03h after the cable break"
resets=$(count /tmp/up.dump 'vcan0 0A0#0000')
t=$(now)
echo "left_grip cable_break 1 off" >&3
wait_more /tmp/up.dump 'vcan0 0A0#0000' "$resets" 10 && pass "4: mended -> the gateway's error reset" || fail "4: no error reset after the mend"
[[ -z $(after /tmp/down.dump "$t" 'vcan1 083#0000') ]] && pass "4: the board sent no error reset (clear_after_break=none)" \
  || fail "4: the board sent 0000h: not the corner"
[[ -n $(after /tmp/down.dump "$t" 'vcan1 583#4F01100011') ]] && pass "4: cleared on 1001h = 11h read while the fault lasted" \
  || fail "4: no 1001h read answered 11h after the mend"
grep -q 'left_grip: 1001h read 11h: no device error' /tmp/gateway.log && pass "4: the gateway names its evidence" \
  || fail "4: no '1001h read' evidence in the log"

echo "right_grip error 0x61 on" >&3
wait_for /tmp/up.dump "$(fault_of 11)" 10 && pass "4: grip button timeout 0061h -> 7000h naming 11h" \
  || fail "4: no 7000h naming 11h after 0061h"
resets=$(count /tmp/up.dump 'vcan0 0A0#0000')
echo "right_grip error 0x61 off" >&3
wait_more /tmp/up.dump 'vcan0 0A0#0000' "$resets" 10 && pass "4: the grip's 0000h (saved: no 0002h left) -> the gateway's error reset" \
  || fail "4: no error reset after the grip's 0061h ended"

t=$(now)
echo "seat_knob fault measurement" >&3
wait_for /tmp/up.dump "$(fault_of 7F)" 10 && pass "4: encoder measurement error -> 7000h naming 7Fh" \
  || fail "4: no 7000h naming 7Fh (a stored 2104h = 3 would suppress its EMCY)"
[[ -n $(after /tmp/down.dump "$t" 'vcan1 0FF#515001') ]] && pass "4: its EMCY 5051h/1 on vcan1 (2104h pinned to 0)" \
  || fail "4: no EMCY 5051h on vcan1"
resets=$(count /tmp/up.dump 'vcan0 0A0#0000')
echo "seat_knob fault clear" >&3
wait_more /tmp/up.dump 'vcan0 0A0#0000' "$resets" 10 && pass "4: \"valid position\" (5051h/0/0) -> the gateway's error reset" || fail "4: no error reset after valid position"

end_recorded
kill -TERM "$sim_pid" 2>/dev/null
wait "$sim_pid" 2>/dev/null
exec 3>&-

echo "== gateway log"
grep -v 'debug:' /tmp/gateway.log | sed 's/^/    /' | head -150
echo "== simulators"
sed 's/^/    /' /tmp/sim.log | head -40
cp /tmp/up.dump /tmp/down.dump /tmp/gateway.log /tmp/sim.log "${OEGW_VM_OUT:-/tmp}/" 2>/dev/null
echo "total $(elapsed) s; $passes passed, $fails failed"
((fails == 0))
