#!/usr/bin/python3
"""The host of the VM tier's system-call test (syscalls.sh), on python3-can (not our code).

It sets the gateway (node 20h) up as a host would: TPDO1 on 1A0h, event-driven (6423h TRUE) with
a 1 s event timer, so that each change of the grip's axes is one upstream frame; then NMT start.
It touches READY_FILE once the gateway answered everything and exits.
Args: CHANNEL READY_FILE
"""
import os
import struct
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from python_peer import Peer  # noqa: E402

NODE = 0x20


def main():
    channel, ready = sys.argv[1], sys.argv[2]
    with Peer(channel, timeout=10.0) as p:  # SDO answers: 10 s, a TCG guest stalls for seconds at times
        if p.wait_heartbeat(NODE, state=0x7F, timeout=60) != 0x7F:
            print("FAIL: the gateway is not pre-operational", flush=True)
            return 1
        p.sdo_download(NODE, 0x1800, 1, struct.pack("<I", 0x800001A0))
        p.sdo_download(NODE, 0x1800, 5, struct.pack("<H", 1000))
        p.sdo_download(NODE, 0x1800, 1, struct.pack("<I", 0x1A0))
        p.sdo_download(NODE, 0x6423, 0, b"\x01")
        p.nmt("start", NODE)
        open(ready, "w").close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
