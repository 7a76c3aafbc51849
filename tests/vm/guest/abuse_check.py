#!/usr/bin/python3
"""Judges vm_abuse's wire (tests/vm/guest/abuse.sh) from candump -L logs.

    abuse_check.py UP_DUMP DOWN_DUMP WINDOWS NODE PERIOD_MS [WITNESS_NODE...]

UP_DUMP, DOWN_DUMP: candump -L of vcan0 (the host's bus) and vcan1 (the sub-devices'); each line
"(seconds.micros) IFACE ID#DATA", the kernel's receive time (CLOCK_REALTIME). WINDOWS: lines
"NAME START END" (CLOCK_REALTIME seconds): the whole judged run first ("all"), then one per
scenario. NODE: the gateway's upstream node-ID (hex); PERIOD_MS its heartbeat period (1017h).

Prints, per window, the longest gap between two of the gateway's heartbeats (700h + NODE) that
overlaps it; the EMCY 7000h the gateway sent upstream (80h + NODE, code 7000h: a sub-device's
inputs at their fault values) and the NMT reset commands on vcan1 (a node the gateway boots
again) inside the whole run. Exit 1 when a gap exceeds 1.5 x PERIOD_MS, or any EMCY 7000h or NMT
reset is there, except inside a window whose NAME ends in ".reboot": a reload applied, which boots
the sub-devices again as a start does (their NMT resets, and the EMCYs of inputs at their fault
values meanwhile, are printed there and expected).
"""
import sys

from hostlib import read_cobs

def longest_gap(times, start, end):
    """The longest gap between two of `times` that overlaps start..end, and where it began. A gap
    still open when the log ends (no time after the window: the dump stopped first) counts up to
    the window's end, as far as it is known: a short window at the end of a run may hold none of
    a slow heartbeat and be followed by none in the log, and is then judged by how long it has
    been since the last."""
    before = [t for t in times if t < start]
    after = [t for t in times if t > end]
    seq = ([before[-1]] if before else []) + [t for t in times if start <= t <= end] + ([after[0]] if after else [end])
    gaps = [(b - a, a) for a, b in zip(seq, seq[1:]) if b > start and a < end]
    return max(gaps) if gaps else None


def main():
    up_dump, down_dump, windows_file, node_hex, period_ms = sys.argv[1:6]
    witnesses = [int(n, 16) for n in sys.argv[6:]]
    node = int(node_hex, 16)
    period = float(period_ms) / 1000.0
    bound = 1.5 * period
    windows = []
    with open(windows_file) as f:
        for line in f:
            name, start, end = line.split()
            windows.append((name, float(start), float(end)))
    up = read_cobs(up_dump)
    beats = [t for t, cob, _ in up if cob == 0x700 + node]
    ok = True
    down = read_cobs(down_dump)
    witness_beats = {n: [t for t, cob, _ in down if cob == 0x700 + n] for n in witnesses}
    for name, start, end in windows:
        inside = [t for t in beats if start <= t <= end]
        worst = longest_gap(beats, start, end)
        if worst is None:
            print(f"FAIL {name}: no heartbeat of node {node:02X}h around {start:.1f}..{end:.1f}")
            ok = False
            continue
        gap, at = worst
        verdict = "ok" if gap <= bound else "FAIL"
        ok = ok and gap <= bound
        seen = [longest_gap(witness_beats[n], start, end) for n in witnesses]
        witness = max((g for g in seen if g), default=None)
        also = f"; the sub-devices' heartbeats: longest gap {witness[0] * 1000:.0f} ms" if witness else ""
        print(f"{verdict} {name}: {len(inside)} heartbeats in {end - start:.1f} s, longest gap {gap * 1000:.0f} ms "
              f"(bound {bound * 1000:.0f} ms) at +{at - start:.1f} s{also}")
    _, run_start, run_end = windows[0]
    reboots = [(start, end) for name, start, end in windows if name.endswith(".reboot")]

    def expected(t):
        return any(start <= t <= end for start, end in reboots)

    emcys = [(t, d) for t, cob, d in up if cob == 0x80 + node and d.startswith("0070") and run_start <= t <= run_end]
    resets = [(t, d) for t, cob, d in down if cob == 0 and d[:2] in ("81", "82") and run_start <= t <= run_end]
    for t, d in emcys:
        print(f"{'expected (reload)' if expected(t) else 'FAIL'} EMCY 7000h upstream at +{t - run_start:.1f} s: {d}")
    for t, d in resets:
        print(f"{'expected (reload)' if expected(t) else 'FAIL'} NMT reset on vcan1 at +{t - run_start:.1f} s: 000#{d}")
    emcys = [e for e in emcys if not expected(e[0])]
    resets = [r for r in resets if not expected(r[0])]
    print(f"EMCY 7000h upstream: {len(emcys)}; NMT resets downstream: {len(resets)} (outside a reload)")
    sys.exit(0 if ok and not emcys and not resets else 1)


if __name__ == "__main__":
    main()
