"""What the python hosts and checks of the VM tier share (tests/vm/guest): their verdict lines,
their clock and log, the files they hand over with the shell, the CANopen values they pack, the
gateway's upstream set-up they make as a host would, and the candump -L files the guest scripts
record (start_candump in lib.sh).

It imports no python3-can (the candump checks do without it, and its import costs seconds in the
guest): what talks to a bus takes a python_peer.Peer.

check(ok, what)      a "PASS: what" / "FAIL: what" line; `failures` counts the FAILs
clock_start(), now_s(), log(what)
                     the seconds since clock_start(), and a line "[   1.23 s] what"
touch(path), wait_file(path, timeout)
                     the files a host and its shell script signal each other with
u32(data)            the UNSIGNED32 of an SDO answer (little-endian, shorter data zero-filled)
wait_emcy(p, node, match, timeout=10.0)
                     the next 8-byte EMCY of node (80h + node-ID) for which match(data) holds, each
                     one seen printed ("EMCY 0A0#..."); None when none came within timeout
start_tpdo1(p, node, cob, event_timer_ms=None)
                     TPDO 1 of the gateway on COB (1800h:01; with an event timer: disabled, 1800h:05,
                     valid again), event-driven (6423h TRUE, CiA 852), then NMT start
read_frames(path)    [(time_s, iface, can_id, data)] for every line "(SECONDS.MICROS) IFACE ID#DATA"
                     in file order: time_s the kernel's receive time (CLOCK_REALTIME) as a float,
                     can_id an int, data the payload's hex digits in upper case ("R..." for a
                     remote frame). Other lines (candump's own messages) are skipped.
read_cobs(path)      the same without the interface: [(time_s, can_id, data)]
"""
import os
import struct
import time

failures = 0
T0 = time.monotonic()


def check(ok, what):
    global failures
    print(("PASS: " if ok else "FAIL: ") + what, flush=True)
    if not ok:
        failures += 1
    return ok


def clock_start():
    global T0
    T0 = time.monotonic()


def now_s():
    return time.monotonic() - T0


def log(what):
    print(f"[{now_s():7.2f} s] {what}", flush=True)


def touch(path):
    open(path, "w").close()


def wait_file(path, timeout):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if os.path.exists(path):
            return True
        time.sleep(0.05)
    return False


def u32(data):
    return struct.unpack("<I", bytes(data).ljust(4, b"\0")[:4])[0]


def wait_emcy(p, node, match, timeout=10.0):
    from python_peer import Timeout  # the caller's Peer has imported it (and python3-can)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            msg = p.recv_id(0x80 + node, deadline - time.monotonic(), f"EMCY of node {node:02X}h")
        except Timeout:
            return None
        d = bytes(msg.data)
        print(f"EMCY {0x80 + node:03X}#{d.hex().upper()}", flush=True)
        if len(d) == 8 and match(d):
            return d
    return None


def start_tpdo1(p, node, cob, event_timer_ms=None):
    if event_timer_ms is not None:
        p.sdo_download(node, 0x1800, 1, struct.pack("<I", 0x80000000 | cob))
        p.sdo_download(node, 0x1800, 5, struct.pack("<H", event_timer_ms))
    p.sdo_download(node, 0x1800, 1, struct.pack("<I", cob))
    p.sdo_download(node, 0x6423, 0, b"\x01")
    p.nmt("start", node)


def read_frames(path):
    out = []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if len(parts) < 3 or not parts[0].startswith("(") or "#" not in parts[2]:
                continue
            cob, _, data = parts[2].partition("#")
            out.append((float(parts[0].strip("()")), parts[1], int(cob, 16), data.upper()))
    return out


def read_cobs(path):
    return [(t, cob, data) for t, _, cob, data in read_frames(path)]
