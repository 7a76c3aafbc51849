#!/usr/bin/python3
"""The host side of the VM tier's gateway test, on python3-can (not our code).

The gateway (`oegw run`, node 0x20 on vcan0) is a CiA 852 device: the host waits for its
boot-up, reads 1000h (must equal what `oegw check` printed), enables TPDO1 on 1A0h (clause 12:
disabled by default), sets 6423h TRUE, NMT-starts it and receives joystick 1 (the elobau grip
moving under `oegw-sim --motion`). Then it asks gateway.sh to kill the grip's simulator and
waits for EMCY 7000h naming node 11h, after which joystick 1 must read neutral.
One process for the whole sequence: each python3-can start costs seconds in the VM.
Args: CHANNEL READY_FILE EXPECTED_1000H (hex)
"""
import struct
import sys
import time

import hostlib
from hostlib import check, log, touch, u32, wait_emcy
from python_peer import Peer

NODE = 0x20


def tpdo1(p, timeout):
    """Next TPDO1: (x, y, z, memory, buttons)."""
    msg = p.recv_id(0x1A0, timeout, "TPDO1")
    return struct.unpack("<hhhBB", bytes(msg.data)) if len(msg.data) == 8 else None


def main():
    channel, ready, expected = sys.argv[1], sys.argv[2], int(sys.argv[3], 16)
    hostlib.clock_start()
    with Peer(channel, timeout=10.0) as p:  # SDO answers: 10 s, a TCG guest stalls for seconds at times
        touch(ready)
        check(p.wait_heartbeat(NODE, state=0x00, timeout=60) == 0, "gateway boot-up 720#00")
        log("boot-up")
        dt = u32(p.sdo_upload(NODE, 0x1000, 0))
        check(dt == expected, f"1000h = {dt:08X}h, as `oegw check` printed ({expected:08X}h)")
        # Clause 12: TPDO1 is 8000 0180h + node-ID by default (disabled).
        cob = u32(p.sdo_upload(NODE, 0x1800, 1))
        check(cob == 0x800001A0, f"TPDO1 COB-ID {cob:08X}h: disabled by default")
        p.sdo_download(NODE, 0x1800, 1, struct.pack("<I", 0x1A0))
        p.sdo_download(NODE, 0x6423, 0, b"\x01")
        check(p.sdo_upload(NODE, 0x6423, 0) == b"\x01", "6423h TRUE")
        p.nmt("start", NODE)
        check(p.wait_heartbeat(NODE, state=0x05, timeout=10) == 0x05, "operational after NMT start")
        log("started")
        # The grip sweeps x (sine, 4 s): TPDO1 x must take many values once it is operational
        # downstream (the gateway boots its sub-devices meanwhile).
        xs = set()
        deadline = time.monotonic() + 30
        frames = 0
        while time.monotonic() < deadline and len(xs) < 20:
            try:
                t = tpdo1(p, 2.0)
            except Exception:  # noqa: BLE001 - a timeout here is reported below
                continue
            if t is None:
                check(False, "TPDO1 is not 8 bytes")
                break
            frames += 1
            xs.add(t[0])
        check(len(xs) >= 20, f"TPDO1 x changes: {len(xs)} values in {frames} frames "
                             f"(min {min(xs, default=0)}, max {max(xs, default=0)})")
        log("joystick moving")
        # The grip's cable is pulled: gateway.sh kills its simulator.
        p.drain()
        open("/tmp/gw.kill-grip", "w").close()
        emcy = wait_emcy(p, NODE, lambda d: d[0:2] == b"\x00\x70" and d[3] == 0x11)  # not another node's
        check(emcy is not None and emcy[3] == 0x11 and emcy[2] & 0x01,
              f"EMCY 7000h naming sub-device 11h: {emcy.hex() if emcy else None}")
        log("EMCY 7000h")
        # The last TPDO1 up to here carries the fault value; a later one too.
        last = None
        end = time.monotonic() + 1.0
        while time.monotonic() < end:
            msg = p.bus.recv(timeout=0.2)
            if msg is not None and msg.arbitration_id == 0x1A0 and len(msg.data) == 8:
                last = struct.unpack("<hhhBB", bytes(msg.data))
        if last is None:  # nothing changes any more: ask for nothing, the stored value is read
            x = struct.unpack("<h", p.sdo_upload(NODE, 0x6401, 1))[0]
        else:
            x = last[0]
        check(x == 0, f"joystick 1 x at its fault value after the loss: {x}")
        check(struct.unpack("<h", p.sdo_upload(NODE, 0x6401, 1))[0] == 0, "6401h:01 reads 0")
    print(f"{hostlib.failures} failures", flush=True)
    return 1 if hostlib.failures else 0


if __name__ == "__main__":
    sys.exit(main())
