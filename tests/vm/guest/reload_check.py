#!/usr/bin/python3
"""reload_check.py UP_DUMP DOWN_DUMP HEARTBEAT_MS: judges vm_reload's two candump -L files
(vcan0, the host's bus; vcan1, the sub-devices') on frames only. The script marks its steps with
a frame 7FF#0n sent on both buses (n = 1 valid reload, 2 invalid file, 3 a setting that needs a
restart, 4 before SIGTERM). One PASS/FAIL line per check; exit 1 if any failed.

Checks (gateway/reload.hpp, docs/guides/install.md#reloading-the-mapping-file):
  * the gateway's heartbeat (720h) never gaps more than 1.5 x 1017h, and it booted once (one
    720#00): the upstream device goes on through every reload;
  * valid reload (1..2): EMCY 6300h (register bit 0) raised, then its error reset; the MCB-402's
    LEDs at their error value (203#0A) before its NMT reset communication (000#8203), and again
    at its start; TPDO 1 (1A0h) at the fault value (x = y = 0) when the grip's first operational
    heartbeat after its boot-up (711#05 after 711#00) comes, and every one from the EMCY until
    then too;
  * refused reloads (2..4): no EMCY 6300h, no NMT frame downstream but the fault policy's reboot
    of a node it lost, after its EMCY 7000h (a guest stall loses nodes), TPDO 1 goes on moving.
"""
import sys

import hostlib
from hostlib import check, read_cobs

def markers(frames):
    return {int(d[:2], 16): t for t, cob, d in frames if cob == 0x7FF and len(d) >= 2}


def between(frames, t0, t1):
    return [f for f in frames if t0 <= f[0] < t1]


up, down = read_cobs(sys.argv[1]), read_cobs(sys.argv[2])
period = int(sys.argv[3]) / 1000.0
mu, md = markers(up), markers(down)
check(all(k in mu and k in md for k in (1, 2, 3, 4)), f"markers 7FF#01..04 on both buses (vcan0 {sorted(mu)}, vcan1 {sorted(md)})")
if hostlib.failures:
    sys.exit(1)
end = mu[4]

# The upstream heartbeat, from the gateway's boot-up to SIGTERM.
hb = [t for t, cob, d in up if cob == 0x720 and t < end]
gaps = [(b - a, a) for a, b in zip(hb, hb[1:] + [end])]  # the last one: until SIGTERM's marker
worst, at = max(gaps) if gaps else (float("inf"), 0.0)
phase = max([n for n in mu if mu[n] <= at], default=0)  # the last marker before the gap
# The count follows from the gaps (every gap bounded from boot-up to SIGTERM); how many frames
# that is depends on how long the guest took, so no fixed count is asked for.
check(len(hb) >= 2 and hb[0] < mu[1] and worst <= 1.5 * period,
      f"upstream heartbeat: {len(hb)} frames, largest gap {worst * 1000:.0f} ms (bound 1.5 x {period * 1000:.0f} ms), "
      + (f"{at - mu[phase]:.2f} s after marker {phase}" if phase else "before the first reload"))
boots = [t for t, cob, d in up if cob == 0x720 and d == "00"]
check(len(boots) == 1 and boots[0] < mu[1], f"one boot-up (720#00), before the first reload: {len(boots)}")

# (1) the valid reload.
valid_up, valid_down = between(up, mu[1], mu[2]), between(down, md[1], md[2])
raised = [t for t, cob, d in valid_up if cob == 0xA0 and d.startswith("006301")]
check(len(raised) == 1, f"valid reload: EMCY 6300h with register 01h once ({len(raised)})")
if raised:
    reset = [t for t, cob, d in valid_up if cob == 0xA0 and d.startswith("0000") and t > raised[0]]
    check(bool(reset), "valid reload: EMCY 0000h (error reset) after 6300h: the sub-devices are back")
seq = [(t, cob, d) for t, cob, d in valid_down if (cob == 0x203) or (cob == 0 and d == "8203")]
leds = [t for t, cob, d in seq if cob == 0x203 and d == "0A"]
nmt = [t for t, cob, d in seq if cob == 0]
check(bool(leds) and bool(nmt) and leds[0] < nmt[0],
      "valid reload: the MCB-402's LEDs at their error value (203#0A) before its NMT reset communication (000#8203)")
mcb_up = [t for t, cob, d in valid_down if cob == 0x703 and d == "05" and nmt and t > nmt[0]]
if mcb_up:
    after = [d for t, cob, d in valid_down if cob == 0x203 and t > mcb_up[0]]
    check(bool(after) and after[0] == "0A", f"valid reload: after the MCB-402's restart its LEDs at 0A again ({after[:1]})")
else:
    check(False, "valid reload: the MCB-402 did not come back (no 703#05 after its reset)")
# The inputs: at their fault values before the EMCY goes up (the TPDO 1 just before it), and
# until the grip's proof of life (the marker precedes the SIGHUP by a few live TPDOs).
grip_boot = [t for t, cob, d in valid_down if cob == 0x711 and d == "00"]
grip_live = [t for t, cob, d in valid_down if cob == 0x711 and d == "05" and grip_boot and t > grip_boot[0]]
if grip_live and raised:
    # (The fault values' TPDO may wait for TPDO 1's inhibit time, and so follow the EMCY.)
    shown = [d for t, cob, d in up if cob == 0x1A0 and mu[1] <= t < grip_live[0]]
    check(bool(shown) and shown[-1][:8] == "00000000",
          f"valid reload: the last TPDO 1 before the grip's proof of life at the fault value, x = y = 0 ({shown[-1:]})")
    tpdo = [d for t, cob, d in up if cob == 0x1A0 and raised[0] <= t < grip_live[0]]
    live = [d for d in tpdo if d[:8] != "00000000"]
    check(not live, f"valid reload: {len(tpdo)} TPDO 1 from EMCY 6300h to the grip's proof of life, all neutral ({live[:3]})")
else:
    check(False, "valid reload: the grip did not come back (no 711#05 after its 711#00), or no EMCY 6300h")

# (2), (3) refused reloads: nothing changes.
refused_up, refused_down = between(up, mu[2], end), between(down, md[2], md[4])
check(not [d for t, cob, d in refused_up if cob == 0xA0 and d.startswith("0063")], "refused reloads: no EMCY 6300h")
# A reload reboots every sub-device at once, and tells the host by EMCY 6300h first; the fault
# policy boots a node it lost again (NMT 82h, 80h, 01h) after EMCY 7000h naming it (a stalled
# guest loses nodes: seen at a load average of 11, all five at once). So each NMT frame here must
# follow a 7000h for its node (byte 3, manufacturer byte 0 = node-ID) since the marker.
def lost_before(node, t):
    return any(cob == 0xA0 and d[:4] == "0070" and int(d[6:8], 16) == node and mu[2] <= u <= t for u, cob, d in up)
nmt = [(t, d) for t, cob, d in refused_down if cob == 0]
unexplained = [d for t, d in nmt if not lost_before(int(d[2:4], 16), t)]
check(not unexplained,
      f"refused reloads: no NMT command downstream but the fault policy's for nodes it lost ({len(nmt)} frames, each "
      f"after EMCY 7000h naming its node; unexplained {unexplained[:5]})")
for n in (2, 3):
    moving = [d for t, cob, d in between(up, mu[n], mu[n + 1]) if cob == 0x1A0 and d[:8] != "00000000"]
    check(len(moving) >= 5, f"after marker {n}: TPDO 1 goes on moving ({len(moving)} frames)")

sys.exit(1 if hostlib.failures else 0)
