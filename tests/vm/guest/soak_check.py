#!/usr/bin/python3
"""Judges soak.sh's upstream candump (-L: "(wall time) vcan0 ID#DATA") from outside:
  * TPDO1 (1A0h, joystick 1, 50 ms event timer) is 8 bytes and never missing for more than
    GAP s of the guest's running time while the gateway is operational (outside the host's NMT
    stop windows + GAP). A TCG guest stalls now and then for hundreds of ms — every process at
    once —, so wall time between two TPDO1 is no measure of the gateway: the running time within
    a gap is the part that cangen's frames on vcan0 (7E4h, soak.sh: one every 50 ms, another
    process) cover with gaps of at most RUNNING s. A gateway that stops while the guest runs
    fails this by the length of its stop; a stall of the whole guest does not;
  * while the grip's simulator is dead (soak.sh's KILLS file: "kill_time restart_time" lines),
    from LOSS s after the kill until its restart, every TPDO1 carries x = y = 0 (the fault value:
    a lost joystick never keeps a machine moving).
Args: DUMP WINDOWS KILLS START_TIME END_TIME
"""
import sys

# s: 20 event-timer periods. 0.5 s failed once with stress-ng --cpu 2 beside the VM: the gateway
# process alone sent nothing for 0.513 s while cangen ran (its heartbeat and an SDO answer late
# too, then a burst): the guest's own scheduling of a loaded vCPU. A stopped loop (the bug) fails
# any such bound by far.
GAP = 1.0
RUNNING = 0.2  # s: cangen's frames this close together show the guest running (4 x its 50 ms)
LOSS = 1.5   # s: the grip's heartbeat time-out is 600 ms, its PDOs stale after 600 ms


def spans(path):
    out = []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if len(parts) == 2:
                out.append((float(parts[0]), float(parts[1])))
    return out


def running(stamps, a, b):
    """The part of (a, b) the stamps cover with gaps of at most RUNNING s."""
    inside = [a] + [t for t in stamps if a < t < b] + [b]
    return sum(y - x for x, y in zip(inside, inside[1:]) if y - x <= RUNNING)


def main():
    dump, windows, kills, start, end = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4]), float(sys.argv[5])
    stops = spans(windows)
    dead = spans(kills)
    times = []
    others = []  # cangen's 7E4h frames: the guest's running time
    bad = 0
    moving_while_dead = 0
    with open(dump) as f:
        for line in f:
            parts = line.split()
            if len(parts) == 3 and parts[2].startswith("7E4#"):
                others.append(float(parts[0].strip("()")))
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
    stalled = 0
    for a, b in zip(times, times[1:]):
        if b - a <= GAP or a < start or b > end:
            continue
        if any(s - GAP <= a and b <= e + GAP for s, e in stops):
            continue
        if running(others, a, b) <= GAP:
            stalled += 1  # the whole guest stood still: no measure of the gateway
            continue
        gaps.append((a, b))
    ok = True
    print(f"TPDO1: {len(times)} frames, {bad} not 8 bytes, {len(gaps)} gaps > {GAP} s of running time outside NMT "
          f"stops ({stalled} longer gaps while the guest stood still), "
          f"{moving_while_dead} non-neutral while the grip was dead ({len(dead)} losses)")
    for a, b in gaps[:5]:
        print(f"  gap {a:.3f} .. {b:.3f} ({b - a:.3f} s, {running(others, a, b):.3f} s of it running)")
    if bad or gaps or moving_while_dead or len(times) < 100 or not dead:
        ok = False
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
