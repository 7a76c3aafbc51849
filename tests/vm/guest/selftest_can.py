#!/usr/bin/python3
"""python3-can half of the VM self-test (see selftest.sh).

selftest_can.py recv CHANNEL READY_FILE  -- expect the frames selftest.sh cansends
selftest_can.py send CHANNEL             -- send the frames selftest.sh expects in candump
"""
import sys
import time

import can


def bus(channel):
    return can.interface.Bus(channel=channel, interface="socketcan")


def recv(channel, ready_file):
    expected = [
        (0x321, False, False, bytes(range(1, 9))),
        (0x10000001, True, False, b"\xaa"),
        (0x7E5, False, True, b""),
    ]
    with bus(channel) as b:
        open(ready_file, "w").close()  # the socket is bound: frames are queued from now on
        deadline = time.monotonic() + 20
        for want in expected:
            msg = b.recv(timeout=max(0.0, deadline - time.monotonic()))
            if msg is None:
                print(f"recv: timeout waiting for {want}")
                return 1
            got = (msg.arbitration_id, msg.is_extended_id, msg.is_remote_frame,
                   bytes(msg.data) if not msg.is_remote_frame else b"")
            print(f"recv: {msg}")
            if got != want:
                print(f"recv: MISMATCH got {got} want {want}")
                return 1
        extra = b.recv(timeout=0.2)
        if extra is not None:
            print(f"recv: unexpected extra frame {extra}")
            return 1
    return 0


def send(channel):
    with bus(channel) as b:
        b.send(can.Message(arbitration_id=0x701, is_extended_id=False, data=[0x05]))
        b.send(can.Message(arbitration_id=0x12345678, is_extended_id=True, data=[0xCA, 0xFE]))
        b.send(can.Message(arbitration_id=0x080, is_extended_id=False, data=[]))
    return 0


def main(argv):
    if len(argv) >= 3 and argv[0] == "recv":
        return recv(argv[1], argv[2])
    if len(argv) >= 2 and argv[0] == "send":
        return send(argv[1])
    print(__doc__, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
