#!/usr/bin/python3
"""The host side of the VM tier's core-device test, on python3-can (not our code).

Talks CiA 301 / CiA 305 to `oegw device` (node 0x20) on a real SocketCAN bus and checks every
answer. One process for the whole sequence: each python3-can start costs seconds in the VM.
Args: CHANNEL READY_FILE. Touches /tmp/check.power-cycle and waits for /tmp/check.powered when
it needs the device restarted (core_device.sh does that).
"""
import struct
import sys
import time

import hostlib
from hostlib import check, touch, u32, wait_file
from python_peer import Peer, SdoAbort

NODE = 0x20


def expect_abort(fn, code, what):
    try:
        fn()
    except SdoAbort as e:
        check(e.code == code, f"{what}: abort {e.code:08X}h (want {code:08X}h)")
        return
    check(False, f"{what}: no abort (want {code:08X}h)")


def lss(p, payload, answer_cs=None, timeout=10.0):
    p.drain()
    p.send(0x7E5, bytes(payload).ljust(8, b"\0"))
    if answer_cs is None:
        return None
    msg = p.recv_id(0x7E4, timeout, f"LSS answer {answer_cs:02X}h")
    return bytes(msg.data)


def main():
    channel, ready = sys.argv[1], sys.argv[2]
    # Every wait 10 s: each ends as soon as its frame comes; a TCG guest stalls for seconds at times.
    with Peer(channel, timeout=10.0) as p:
        touch(ready)
        # CiA 301 §7.2.8.3.2.1: boot-up is the heartbeat frame with state 0.
        check(p.wait_heartbeat(NODE, state=0x00, timeout=30) == 0, "boot-up 720#00")
        check(p.wait_heartbeat(NODE, timeout=10) == 0x7F, "heartbeat: pre-operational")

        check(p.sdo_upload(NODE, 0x1000, 0) == struct.pack("<I", 0x000F0191), "1000h device type 000F0191h")
        check(p.sdo_upload(NODE, 0x1008, 0) == b"oegw demo device", "1008h device name (segmented)")
        ident = [u32(p.sdo_upload(NODE, 0x1018, s)) for s in range(1, 5)]
        check(ident == [0, 0x852, 0x10000, 1], f"1018h identity {ident}")
        p.sdo_download(NODE, 0x1017, 0, struct.pack("<H", 200))
        check(p.sdo_upload(NODE, 0x1017, 0) == struct.pack("<H", 200), "1017h written to 200 ms")
        expect_abort(lambda: p.sdo_download(NODE, 0x1000, 0, struct.pack("<I", 1)), 0x06010002,
                     "write to read-only 1000h")
        expect_abort(lambda: p.sdo_upload(NODE, 0x1234, 0), 0x06020000, "read of a missing object")
        expect_abort(lambda: p.sdo_download(NODE, 0x1017, 0, struct.pack("<I", 1)), 0x06070012,
                     "4 bytes into the UNSIGNED16 1017h")

        p.nmt("start", NODE)
        check(p.wait_heartbeat(NODE, state=0x05, timeout=10) == 0x05, "operational after NMT start")
        tpdo = p.recv_id(0x1A0, 10.0, "TPDO1 (event timer 500 ms)")
        check(len(tpdo.data) == 5, f"TPDO1 has 5 bytes ({bytes(tpdo.data).hex()})")
        p.send(0x220, [0x5A])
        time.sleep(0.1)
        check(p.sdo_upload(NODE, 0x6200, 1) == b"\x5a", "RPDO1 wrote 6200h:01 = 5Ah")
        p.nmt("stop", NODE)
        check(p.wait_heartbeat(NODE, state=0x04, timeout=10) == 0x04, "stopped after NMT stop")
        p.nmt("preop", NODE)
        check(p.wait_heartbeat(NODE, state=0x7F, timeout=10) == 0x7F, "pre-operational again")

        # Novotechnik §7.1: "save" (73 61 76 65) to 1010h:01 stores the parameters atomically.
        p.sdo_download(NODE, 0x1010, 1, b"save")
        touch("/tmp/check.power-cycle")
        check(wait_file("/tmp/check.powered", 30), "device power-cycled")
        check(p.wait_heartbeat(NODE, state=0x00, timeout=30) == 0, "boot-up after power cycle")
        check(p.sdo_upload(NODE, 0x1017, 0) == struct.pack("<H", 200), "1017h = 200 survived the power cycle")

        # CiA 305 / Novotechnik §6: LSS switch global, configure node-ID, store, back to waiting.
        lss(p, [0x04, 0x01])
        check(lss(p, [0x11, 0x21], 0x11)[:2] == b"\x11\x00", "LSS configure node-ID 21h accepted")
        check(lss(p, [0x11, 0x80], 0x11)[:2] == b"\x11\x01", "LSS node-ID 80h refused (out of range)")
        check(lss(p, [0x5E], 0x5E)[:2] == b"\x5e\x20", "LSS inquire node-ID: still 20h until reset")
        check(lss(p, [0x17], 0x17)[:2] == b"\x17\x00", "LSS store configuration")
        lss(p, [0x04, 0x00])
        p.nmt("reset-comm", NODE)
        check(p.wait_heartbeat(0x21, state=0x00, timeout=10) == 0, "boot-up as node 21h after reset communication")
        check(p.sdo_upload(0x21, 0x1000, 0) == struct.pack("<I", 0x000F0191), "SDO on 621h/5A1h")
        check(p.sdo_upload(0x21, 0x1800, 1) == struct.pack("<I", 0x1A1), "TPDO1 COB-ID followed the node-ID")
    print(f"{hostlib.failures} failures", flush=True)
    return 1 if hostlib.failures else 0


if __name__ == "__main__":
    sys.exit(main())
