#!/bin/bash
# Guest test (run-in-vm.sh --systemd: systemd is PID 1): the project's real unit,
# config/oegw.service, under the host's real systemd (Debian 12's), outside in.
# `cmake --install BUILD --prefix /usr` puts oegw, oegw-sim, the unit and the EDS files where the
# package puts them (the guest's root is an overlay: nothing reaches the host); /etc/oegw/oegw.yaml
# is tests/fixtures/vm_gateway.yaml (upstream vcan0, downstream vcan1, the store in /var/lib/oegw,
# the installed EDS files); the demo cab's five devices run in one `oegw-sim` process on vcan1.
# One drop-in only: WatchdogSec=10s (the unit's 5 s is too tight for a TCG guest on a busy host,
# which stalls for seconds at times; vm_systemd_notify uses 10 s for the same reason).
# Checked with systemctl show / status and systemd's own (debug) log:
#   - `systemctl start oegw` returns with the unit active/running, and systemd changed the unit
#     from start to running only after oegw's READY=1 (Type=notify, NotifyAccess=main);
#   - StatusText: the sub-devices not yet up, then "5/5 sub-devices operational" once the
#     simulator runs; `oegw status` answers on the unit's socket;
#   - the watchdog is fed (WatchdogTimestamp advances, no restart);
#   - a stuck loop (SIGSTOP) is killed by systemd's watchdog and restarted (NRestarts rises, a new
#     main PID becomes ready);
#   - `systemctl reload oegw` (ExecReload= kill -HUP): RELOADING=1 with MONOTONIC_USEC= and then
#     READY=1 from the same main PID, no restart; a valid file applied ("reloaded" in the
#     journal), an invalid one refused with its file:line:column in the journal and the
#     StatusText's "last reload refused" note, which the next good reload removes;
#   - `systemctl stop oegw`: STOPPING=1 reaches systemd, exit 0, Result=success;
#   - a refused mapping file (`oegw run` exits 1) fails the unit and is not restarted
#     (RestartPreventExitStatus=1).
# Args: BUILD_DIR SOURCE_DIR
set -uo pipefail
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=lib.sh
. "$here/lib.sh"
build=$1
src=$2
export SYSTEMD_PAGER='' SYSTEMD_COLORS=0

prop() { systemctl show oegw -p "$1" --value; }
# wait_until TIMEOUT_S COMMAND...: polls (each systemctl call takes a while under TCG) until the
# command holds or TIMEOUT_S seconds of wall time have passed; returns its last status.
wait_until() {
  local end=$((SECONDS + $1))
  shift
  while ((SECONDS < end)); do "$@" && return 0; sleep 0.2; done
  "$@"
}
# unit_log: the unit's journal, the last lines (what `oegw run` said when it failed).
unit_log() { journalctl -q -b --no-pager -o cat -u oegw | tail -"${1:-8}" | sed 's/^/  | /'; }
# PID 1's journal lines about oegw.service since CURSOR (debug level where it was raised).
pid1_log() { journalctl -q -b --no-pager -o cat _PID=1 --after-cursor="$1" | grep '^oegw\.service: '; }
cursor() { journalctl -q -b -n 0 --show-cursor | sed -n 's/^-- cursor: //p'; }
# first_line PATTERN: the number of the first line of stdin matching PATTERN (0: none).
first_line() { grep -n -m1 -e "$1" | cut -d: -f1 | grep . || echo 0; }

# --- systemd is PID 1 ------------------------------------------------------------------------
[[ $(cat /proc/1/comm) == systemd ]] && pass "PID 1 is systemd ($(systemctl --version | head -1))" ||
  { fail "PID 1 is $(cat /proc/1/comm), not systemd"; exit 1; }
echo "system: $(systemctl is-system-running) after $(cut -d' ' -f1 /proc/uptime) s uptime; failed units: $(systemctl --failed --no-legend --plain | awk '{ printf "%s ", $1 }')"
echo "boot: $(systemd-analyze time 2>&1 | head -1)"
systemd-analyze blame --no-pager 2>&1 | head -6 | sed 's/^/  blame: /'

# --- install, configure --------------------------------------------------------------------
t=$(elapsed)
if ! cmake --install "$build" --prefix /usr >/tmp/install.log 2>&1; then
  fail "cmake --install $build --prefix /usr: $(tail -5 /tmp/install.log)"
  exit 1
fi
echo "cmake --install --prefix /usr: $(awk -v a="$t" -v b="$(elapsed)" 'BEGIN { printf "%.1f", b - a }') s"
installed=$(systemctl show oegw -p FragmentPath --value)
cmp -s "$src/config/oegw.service" "$installed" && pass "the unit systemd loads ($installed) is config/oegw.service" ||
  fail "unit $installed differs from config/oegw.service: $(diff "$src/config/oegw.service" "$installed" | head -5)"
mkdir -p /etc/oegw /etc/systemd/system/oegw.service.d
mapping_fixture vm_gateway.yaml "$src" /var/lib/oegw | sed "s|$src/subdevices/eds|/usr/share/oegw/eds|g" >/etc/oegw/oegw.yaml
printf '[Service]\nWatchdogSec=10s\n' >/etc/systemd/system/oegw.service.d/vm-watchdog.conf
systemctl daemon-reload
/usr/bin/oegw check --here /etc/oegw/oegw.yaml >/tmp/check.out 2>&1 && pass "oegw check --here /etc/oegw/oegw.yaml: valid" ||
  fail "oegw check: $(tail -3 /tmp/check.out)"

# --- start: Type=notify, READY=1 ----------------------------------------------------------------
c=$(cursor)
systemd-analyze log-level debug
t=$(elapsed)
systemctl start oegw
rc=$?
took=$(awk -v a="$t" -v b="$(elapsed)" 'BEGIN { printf "%.1f", b - a }')
systemd-analyze log-level info
((rc == 0)) && pass "systemctl start oegw: returned 0 after $took s" ||
  { fail "systemctl start oegw: exit $rc after $took s; the unit's journal:"; unit_log; }
state="$(prop ActiveState)/$(prop SubState)"
[[ $state == active/running ]] && pass "active/running" || fail "state $state"
settings="Type=$(prop Type) NotifyAccess=$(prop NotifyAccess) WatchdogUSec=$(prop WatchdogUSec)"
[[ $settings == "Type=notify NotifyAccess=main WatchdogUSec=10s" ]] && pass "$settings" || fail "$settings"
pid1_log "$c" >/tmp/start.log
ready=$(first_line 'Got notification message from PID [0-9]* (READY=1' </tmp/start.log)
running=$(first_line 'Changed start -> running' </tmp/start.log)
started=$(first_line 'Changed [a-z-]* -> start$' </tmp/start.log)
if ((ready > 0 && running > ready && started > 0 && started < ready)); then
  pass "systemd: -> start, then READY=1 from the main PID, then start -> running (lines $started, $ready, $running of its log)"
else
  fail "READY=1 not between start and running in systemd's log (start $started, READY $ready, running $running)"
  sed 's/^/  | /' /tmp/start.log | head -30
fi
status=$(prop StatusText)
echo "StatusText at READY: $status"
[[ $status =~ ^upstream\ pre-operational,\ node\ 20h\;\ [0-4]/5\ sub-devices\ operational\;\ .*right_grip ]] &&
  pass "StatusText before the simulator: the sub-devices not up named" || fail "StatusText at READY: '$status'"

# --- the simulated cab: StatusText, oegw status ---------------------------------------------
/usr/bin/oegw-sim -i vcan1 elobau-mfg:0x11:name=right_grip mcb402:0x03:name=left_grip \
  "cia401:0x30:name=pedal,eds=/usr/share/oegw/eds/generic_pedal.eds" novotechnik-406:0x7F:name=seat_knob \
  "cia401:0x31:name=cluster,eds=/usr/share/oegw/eds/button_cluster.eds" >/tmp/sim.log 2>&1 &
sim_pid=$!
all_up() { [[ $(prop StatusText) == 'upstream pre-operational, node 20h; 5/5 sub-devices operational' ]]; }
t=$(elapsed)
if wait_until 120 all_up; then
  pass "StatusText: '$(prop StatusText)' ($(awk -v a="$t" -v b="$(elapsed)" 'BEGIN { printf "%.1f", b - a }') s after the simulator started)"
else
  fail "StatusText '$(prop StatusText)' after 120 s of the simulator (its log: $(tail -2 /tmp/sim.log))"
fi
systemctl status oegw --no-pager -n 0 >/tmp/status.txt 2>&1
cat /tmp/status.txt
# The line as the gateway last sent it: the count may have dropped since StatusText showed 5/5
# (with stress-ng beside the VM a stall lost every sub-device's heartbeat at this very moment).
grep -qE 'Status: "upstream pre-operational, node 20h; [0-5]/5 sub-devices operational' /tmp/status.txt &&
  pass "systemctl status oegw shows the Status line" || fail "no Status line in systemctl status"
/usr/bin/oegw status --config /etc/oegw/oegw.yaml >/tmp/oegw-status.txt 2>&1
rc=$?
((rc == 0)) && grep -q right_grip /tmp/oegw-status.txt && pass "oegw status answers from the unit's daemon" ||
  fail "oegw status exit $rc: $(head -3 /tmp/oegw-status.txt)"

# --- the watchdog is fed ----------------------------------------------------------------------
w1=$(prop WatchdogTimestampMonotonic)
sleep 7  # more than one ping period (5 s, polled each second)
w2=$(prop WatchdogTimestampMonotonic)
((w1 > 0 && w2 > w1)) && pass "WatchdogTimestamp advances (by $(((w2 - w1) / 1000)) ms between two reads 7 s and two systemctl calls apart)" ||
  fail "WatchdogTimestampMonotonic $w1 -> $w2"
n0=$(prop NRestarts)
((n0 == 0)) && pass "no restart so far" || fail "NRestarts $n0 before the stuck-loop test"

# --- a stuck loop: the watchdog kills and restarts it ---------------------------------------
pid=$(prop MainPID)
kill -STOP "$pid"
t=$(elapsed)
restarted() { (($(prop NRestarts) > n0)) && [[ $(prop ActiveState)/$(prop SubState) == active/running ]] && (($(prop MainPID) != pid)); }
if wait_until 150 restarted; then
  pass "SIGSTOP'd main PID $pid: restarted as $(prop MainPID), NRestarts $(prop NRestarts), active again $(awk -v a="$t" -v b="$(elapsed)" 'BEGIN { printf "%.1f", b - a }') s after the stop"
else
  fail "after SIGSTOP of $pid: NRestarts $(prop NRestarts), $(prop ActiveState)/$(prop SubState), MainPID $(prop MainPID)"
  unit_log
fi
kill -0 "$pid" 2>/dev/null && fail "the stuck process $pid is still there" || pass "the stuck process $pid is gone"
journalctl -q -b --no-pager -o cat -u oegw >/tmp/unit.log
grep -q 'Watchdog timeout' /tmp/unit.log && pass "journal: $(grep -m1 'Watchdog timeout' /tmp/unit.log)" ||
  fail "no 'Watchdog timeout' in the unit's journal"
grep -q "Failed with result 'watchdog'" /tmp/unit.log && pass "journal: Failed with result 'watchdog'" ||
  fail "no \"Failed with result 'watchdog'\" in the unit's journal"
wait_until 120 all_up && pass "after the restart: 5/5 sub-devices operational again" || fail "after the restart: '$(prop StatusText)'"

# --- systemctl reload: SIGHUP re-reads the file; RELOADING=1 ... READY=1 ------------------------
pid=$(prop MainPID)
n0=$(prop NRestarts)
cp /etc/oegw/oegw.yaml /tmp/oegw.yaml.orig
# reload_once LABEL: `systemctl reload oegw` (ExecReload= kill -HUP), then waits for oegw's
# outcome in the unit's journal; systemd's debug log of it in /tmp/reload.log.
reload_once() {
  local c
  c=$(cursor)
  systemd-analyze log-level debug
  systemctl reload oegw
  local rc=$?
  outcome() { journalctl -q -b --no-pager -o cat -u oegw --after-cursor="$c" | grep -qE ': reloaded: |reload refused'; }
  wait_until 60 outcome
  sleep 1
  systemd-analyze log-level info
  pid1_log "$c" >/tmp/reload.log
  journalctl -q -b --no-pager -o cat -u oegw --after-cursor="$c" >/tmp/reload-unit.log
  ((rc == 0)) && pass "$1: systemctl reload returned 0" || fail "$1: systemctl reload exit $rc"
  grep -q "Got notification message from PID $pid (RELOADING=1, MONOTONIC_USEC=[0-9]*)" /tmp/reload.log &&
    grep -A100 "(RELOADING=1" /tmp/reload.log | grep -q "Got notification message from PID $pid (READY=1)" &&
    pass "$1: RELOADING=1 (MONOTONIC_USEC=) then READY=1 from main PID $pid" ||
    { fail "$1: no RELOADING=1 then READY=1 from $pid in systemd's log"; sed 's/^/  | /' /tmp/reload.log | head -20; }
  local now
  now="$(prop ActiveState)/$(prop SubState) MainPID=$(prop MainPID) NRestarts=$(prop NRestarts)"
  [[ $now == "active/running MainPID=$pid NRestarts=$n0" ]] && pass "$1: $now" || fail "$1: $now"
}
sed -i 's/deadband: 300, invert: true/deadband: 200, invert: true/' /etc/oegw/oegw.yaml
reload_once "a valid file"
grep -q ': reloaded: 5 sub-devices on vcan1' /tmp/reload-unit.log && pass "journal: $(grep -m1 ': reloaded: ' /tmp/reload-unit.log)" ||
  { fail "no 'reloaded' in the unit's journal"; sed 's/^/  | /' /tmp/reload-unit.log | tail -10; }
wait_until 120 all_up && pass "after the reload: '$(prop StatusText)'" || fail "after the reload: '$(prop StatusText)'"
sed -i 's/^  node_id: 0x20$/  node_id: 0x80/' /etc/oegw/oegw.yaml
reload_once "an invalid file"
grep -q 'oegw.yaml:7:12: node_id 0x80 is out of range' /tmp/reload-unit.log && grep -q 'reload refused, 1 error' /tmp/reload-unit.log &&
  pass "journal: $(grep -m1 'oegw.yaml:7:12' /tmp/reload-unit.log)" || { fail "no file:line:column error"; sed 's/^/  | /' /tmp/reload-unit.log | tail -10; }
refused_status() { [[ $(prop StatusText) == *'5/5 sub-devices operational; last reload refused: 1 error (journal)' ]]; }
wait_until 20 refused_status && pass "StatusText: '$(prop StatusText)'" || fail "StatusText after a refused reload: '$(prop StatusText)'"
cp /tmp/oegw.yaml.orig /etc/oegw/oegw.yaml
reload_once "the file restored"
wait_until 120 all_up && pass "after the restored file: '$(prop StatusText)' (the note gone)" || fail "after the restored file: '$(prop StatusText)'"

# --- systemctl stop: STOPPING=1, exit 0 -------------------------------------------------------
pid=$(prop MainPID)
c=$(cursor)
systemd-analyze log-level debug
systemctl stop oegw
rc=$?
systemd-analyze log-level info
main="$(prop ActiveState) Result=$(prop Result)"
pid1_log "$c" >/tmp/stop.log
((rc == 0)) && [[ $main == "inactive Result=success" ]] && pass "systemctl stop: $main" || fail "systemctl stop exit $rc: $main"
grep -q 'Main process exited, code=exited, status=0/SUCCESS' /tmp/stop.log && pass "main process exited 0" ||
  { fail "no 'Main process exited, code=exited, status=0/SUCCESS' in systemd's log"; sed 's/^/  | /' /tmp/stop.log | head -20; }
grep -q "Got notification message from PID $pid (STOPPING=1)" /tmp/stop.log && pass "STOPPING=1 from main PID $pid" ||
  { fail "no STOPPING=1 from $pid in systemd's log"; sed 's/^/  | /' /tmp/stop.log | head -20; }
journalctl -q -b --no-pager -o cat -u oegw | grep -q 'signal 15: stopping' && pass "oegw logged SIGTERM" ||
  fail "no 'signal 15: stopping' in the unit's journal"

# --- a refused mapping file: exit 1, not restarted --------------------------------------------
sed -i 's/^  node_id: 0x20$/  node_id: 0x80/' /etc/oegw/oegw.yaml
grep -q '^  node_id: 0x80$' /etc/oegw/oegw.yaml || fail "could not spoil the mapping file"
c=$(cursor)
systemctl start oegw 2>/tmp/start-bad.err
rc=$?
((rc != 0)) && pass "systemctl start with node_id 0x80: refused (exit $rc)" || fail "systemctl start with a bad file: exit 0"
n1=$(prop NRestarts)
sleep 8  # four times RestartSec=2: a restart would have come
state="$(prop ActiveState)/$(prop SubState) Result=$(prop Result) ExecMainStatus=$(prop ExecMainStatus) NRestarts=$(prop NRestarts)"
[[ $state == "failed/failed Result=exit-code ExecMainStatus=1 NRestarts=$n1" ]] && pass "bad file: $state, not restarted" ||
  fail "bad file: $state (NRestarts was $n1 after the failed start)"
journalctl -q -b --no-pager -o cat -u oegw --after-cursor="$c" >/tmp/bad.log
grep -q 'oegw.yaml:[0-9]*:[0-9]*.*node_id' /tmp/bad.log && pass "journal: $(grep -m1 'oegw.yaml:[0-9]*:[0-9]*.*node_id' /tmp/bad.log)" ||
  fail "no file:line:column error naming node_id in the unit's journal"
echo "--- the unit's journal for the bad file"
head -20 /tmp/bad.log

kill "$sim_pid" 2>/dev/null
echo "$passes passed, $fails failed ($(elapsed) s)"
((fails == 0))
