#!/usr/bin/python3
"""The host of the VM tier's system-call test (syscalls.sh), on python3-can (not our code).

It sets the gateway (node 20h) up as a host would: TPDO1 on 1A0h, event-driven (6423h TRUE) with
a 1 s event timer, so that each change of the grip's axes is one upstream frame; then NMT start.
It touches READY_FILE once the gateway answered everything and exits.
Args: CHANNEL READY_FILE
"""
import sys

from hostlib import start_tpdo1, touch
from python_peer import Peer

NODE = 0x20


def main():
    channel, ready = sys.argv[1], sys.argv[2]
    with Peer(channel, timeout=10.0) as p:  # SDO answers: 10 s, a TCG guest stalls for seconds at times
        if p.wait_heartbeat(NODE, state=0x7F, timeout=60) != 0x7F:
            print("FAIL: the gateway is not pre-operational", flush=True)
            return 1
        start_tpdo1(p, NODE, 0x1A0, event_timer_ms=1000)
        touch(ready)
    return 0


if __name__ == "__main__":
    sys.exit(main())
