#!/usr/bin/python3
"""VM host of vm_remote (remote.sh): the host controller on vcan0 reaching the sub-devices on
vcan1 through `oegw run` (remote SDO, remote EMCY), with python_peer.Peer on python3-can: frames
written from CiA 301 §7.2.4 and the network-indication layout oegw documents
(canopen/301/sdo_remote.hpp), nothing of the gateway's code.

Usage: remote_host.py READY_FILE GRIP_FIFO
  READY_FILE  created once the bus is open (the shell then starts the devices and the gateway)
  GRIP_FIFO   oegw-sim --commands input of the MCB-402 left_grip (cable_break -> EMCY 3120h)
Prints one PASS/FAIL line per check; the exit status is the number of failures.
"""
import struct
import sys
import time

import hostlib
from hostlib import check, touch, u32, wait_emcy
from python_peer import Peer, PeerError, SdoAbort, Timeout

GW = 0x20
UP_NET, DOWN_NET = 1, 2  # the mapping file's defaults (upstream.network_id, downstream.network_id)
GRIP, LEFT, KNOB = 0x11, 0x03, 0x7F  # elobau grip, MCB-402, Novotechnik encoder
BOUND = (0x690, 0x6B0)  # upstream.sdo_servers[0]: SDO server 1201h bound to left_grip (remote.sh)

def hx(code):
    return "none" if code is None else f"{code:08X}h"


def abort_code(fn):
    """Runs fn; the SDO abort code it raised, or None when it succeeded."""
    try:
        fn()
        return None
    except SdoAbort as e:
        return e.code


def main():
    ready, fifo = sys.argv[1], sys.argv[2]
    with Peer("vcan0", timeout=10.0) as p:  # 10 s: a TCG guest stalls for seconds at times
        touch(ready)
        p.wait_heartbeat(GW, state=0x00, timeout=90)
        print("gateway boot-up seen", flush=True)

        # 1. The grip through a network indication on the default channel (620h/5A0h): retried
        # while the gateway still boots it (0800 0022h) or has not seen it yet (0606 0000h).
        seen, vendor, deadline = set(), None, time.monotonic() + 90
        while vendor is None and time.monotonic() < deadline:
            try:
                p.network_indication(GW, DOWN_NET, GRIP)
                vendor = u32(p.sdo_upload(GW, 0x1018, 1))
            except SdoAbort as e:
                seen.add(e.code)
                time.sleep(0.5)
            except Timeout:
                seen.add("timeout")
        check(vendor == 0xB4, f"right_grip 1018h:01 through the gateway = {hx(vendor)} (elobau vendor-ID B4h)")
        check(seen <= {0x08000022, 0x06060000}, f"while the grip booted only 0800 0022h / 0606 0000h: {sorted(hx(c) if isinstance(c, int) else c for c in seen)}")

        # 2. Refused and allowed writes on the grip.
        code = abort_code(lambda: p.sdo_download(GW, 0x1800, 1, struct.pack("<I", 0x191)))
        check(code == 0x08000021, f"write of the grip's 1800h:01 refused with 0800 0021h (got {hx(code)})")
        code = abort_code(lambda: p.sdo_download(GW, 0x5001, 0, struct.pack("<H", 30)))
        back = u32(p.sdo_upload(GW, 0x5001, 0)) if code is None else None
        check(code is None and back == 30, f"elobau 5001h written 30 and read back {back!r} (abort {hx(code)})")
        p.sdo_download(GW, 0x5001, 0, struct.pack("<H", 20))

        # 3. A segmented upload (a 20-character 1008h) from the encoder.
        p.network_indication(GW, DOWN_NET, KNOB)
        name = p.sdo_upload(GW, 0x1008, 0)
        check(name == b"MC1-2832-A7F-614-511", f"seat_knob 1008h (segmented) = {name!r}")

        # 4. Refused network indications, then back to the gateway's own dictionary.
        code = abort_code(lambda: p.network_indication(GW, 9, GRIP))
        check(code == 0x06020000, f"network 9 refused with 0602 0000h (got {hx(code)})")
        code = abort_code(lambda: p.network_indication(GW, DOWN_NET, 0x44))
        check(code == 0x06090011, f"node 44h (not configured) refused with 0609 0011h (got {hx(code)})")
        p.network_indication(GW, UP_NET, GW)
        product = u32(p.sdo_upload(GW, 0x1018, 2))
        check(product == 0x852, f"after naming itself, 1018h:02 is the gateway's own: {product:#x}")

        # 5. The channel bound to left_grip, used as a plain SDO client would (no indication).
        vendor = u32(p.sdo_upload(GW, 0x1018, 1, cobs=BOUND))
        check(vendor == 0x58, f"left_grip 1018h:01 on the bound channel 690h/6B0h = {vendor:#x} (MCB-402 58h)")
        code = abort_code(lambda: p.network_indication(GW, DOWN_NET, GRIP, cobs=BOUND))
        check(code == 0x08000021, f"a network indication on the bound channel refused with 0800 0021h ({hx(code)})")

        # 6. Remote EMCY: the MCB-402's cable-break EMCY 3120h (its bytes 20 31 81 00 81 00 00 00)
        # reaches vcan0 as the gateway's EMCY (0A0h) with its code, node-ID 03h, its register 81h
        # and its first manufacturer bytes 00 81 00; its error reset 0000h follows.
        p.drain()
        with open(fifo, "w") as f:
            f.write("left_grip cable_break 1 on\n")
        got = wait_emcy(p, GW, lambda d: d[0:2] == b"\x20\x31")
        check(got is not None and got[3:8] == bytes([LEFT, 0x81, 0x00, 0x81, 0x00]),
              f"EMCY 3120h of left_grip on vcan0: {got.hex() if got else None}")
        with open(fifo, "w") as f:
            f.write("left_grip cable_break 1 off\n")
        got = wait_emcy(p, GW, lambda d: d[0:2] == b"\x00\x00" and d[3] == LEFT)
        check(got is not None, f"left_grip's error reset 0000h on vcan0: {got.hex() if got else None}")
    return hostlib.failures


if __name__ == "__main__":
    try:
        sys.exit(main())
    except (PeerError, OSError) as e:
        print(f"FAIL: {e}", flush=True)
        sys.exit(hostlib.failures + 1)
