#!/usr/bin/python3
"""Judges soak.sh's upstream candump (-L: "(wall time) vcan0 ID#DATA") from outside:
  * TPDO1 (1A0h, joystick 1, 50 ms event timer) is 8 bytes and never missing for more than
    GAP s while the gateway is operational (outside the host's NMT stop windows + GAP);
  * while the grip's simulator is dead (soak.sh's KILLS file: "kill_time restart_time" lines),
    from LOSS s after the kill until its restart, every TPDO1 carries x = y = 0 (the fault value:
    a lost joystick never keeps a machine moving).
Args: DUMP WINDOWS KILLS START_TIME END_TIME
"""
import sys

GAP = 0.5    # s: 10 event-timer periods, wide for a TCG guest
LOSS = 1.5   # s: the grip's heartbeat time-out is 600 ms, its PDOs stale after 600 ms


def spans(path):
    out = []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if len(parts) == 2:
                out.append((float(parts[0]), float(parts[1])))
    return out


def main():
    dump, windows, kills, start, end = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4]), float(sys.argv[5])
    stops = spans(windows)
    dead = spans(kills)
    times = []
    bad = 0
    moving_while_dead = 0
    with open(dump) as f:
        for line in f:
            parts = line.split()
            if len(parts) != 3 or not parts[2].startswith("1A0#"):
                continue
            t = float(parts[0].strip("()"))
            data = bytes.fromhex(parts[2][4:])
            if len(data) != 8:
                bad += 1
                continue
            times.append(t)
            x = int.from_bytes(data[0:2], "little", signed=True)
            y = int.from_bytes(data[2:4], "little", signed=True)
            if any(k + LOSS <= t <= r for k, r in dead) and (x != 0 or y != 0):
                moving_while_dead += 1
    gaps = []
    for a, b in zip(times, times[1:]):
        if b - a <= GAP or a < start or b > end:
            continue
        if any(s - GAP <= a and b <= e + GAP for s, e in stops):
            continue
        gaps.append((a, b))
    ok = True
    print(f"TPDO1: {len(times)} frames, {bad} not 8 bytes, {len(gaps)} gaps > {GAP} s outside NMT stops, "
          f"{moving_while_dead} non-neutral while the grip was dead ({len(dead)} losses)")
    for a, b in gaps[:5]:
        print(f"  gap {a:.3f} .. {b:.3f} ({b - a:.3f} s)")
    if bad or gaps or moving_while_dead or len(times) < 100 or not dead:
        ok = False
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
