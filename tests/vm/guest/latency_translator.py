#!/usr/bin/python3
"""The python translator of vm_latency, on python3-can.

The comparison asks for a python `canopen` translator; python `canopen` is not installable here (no
Debian package, PyPI unreachable), and for this path it would only wrap the same python3-can bus:
it decodes a TPDO with its own PDO map and hands the host's TPDO to python3-can to send. This one
does the translation `oegw run` does for tests/fixtures/vm_syscalls.yaml, by hand:

  in:  the elobau grip's TPDO #0 (180h + node on IN_IF, 8 bytes): x, y as INTEGER8 percent in
       bytes 0, 1, buttons 1..16 in bytes 5, 6 (elobau §14.1)
  out: CiA 852 TPDO 1 (OUT_ID on OUT_IF): joystick 1 x, y, z INTEGER16, memory byte, buttons
       1..8 byte (Table 12), sent when it changes (6423h TRUE, no inhibit time, no event timer)

with the mapping file's pipeline (mapping/translate.hpp): deadband 2 % around neutral, 100 % =
32767 (rounded half away from zero, clamped to ±32767), a value outside ±110 % or the grip's
error/not-available codes 126/127 as the neutral fault value, and the neutral interlock (an axis
stays at neutral until it has been seen inside its deadband). vm_latency checks that its frames
are byte for byte the gateway's for the same input. What the gateway does besides (heartbeats,
the grip's boot, deadlines) is not done here.
Args: IN_IF OUT_IF [NODE] [OUT_ID]
"""
import struct
import sys

import can

DEADBAND = 2
SCALE = 32767 / 100


def axis(raw, locked):
    """The FE value of one axis and whether it stays interlocked."""
    if raw in (126, 127) or abs(raw) > 110:
        return 0, True
    if locked and abs(raw) > DEADBAND:
        return 0, True
    if abs(raw) <= DEADBAND:
        return 0, False
    v = int(abs(raw) * SCALE + 0.5) * (1 if raw > 0 else -1)
    return max(-32767, min(32767, v)), False


def main():
    in_if, out_if = sys.argv[1], sys.argv[2]
    node = int(sys.argv[3], 0) if len(sys.argv) > 3 else 0x11
    out_id = int(sys.argv[4], 0) if len(sys.argv) > 4 else 0x1A0
    # The sending bus first: the test waits for the receiving one's socket to be bound.
    out = can.Bus(channel=out_if, interface="socketcan",
                  can_filters=[{"can_id": 0x7FF, "can_mask": 0x7FF, "extended": True}])
    bus = can.Bus(channel=in_if, interface="socketcan",
                  can_filters=[{"can_id": 0x180 + node, "can_mask": 0x7FF, "extended": False}])
    locked = [True, True]
    last = None
    while True:
        msg = bus.recv()
        if msg is None or msg.dlc != 8:
            continue
        x, y = struct.unpack_from("<bb", msg.data, 0)
        (x, locked[0]), (y, locked[1]) = axis(x, locked[0]), axis(y, locked[1])
        data = struct.pack("<hhhBB", x, y, 0, 0, msg.data[5])
        if data != last:
            out.send(can.Message(arbitration_id=out_id, data=data, is_extended_id=False))
            last = data


if __name__ == "__main__":
    sys.exit(main())
