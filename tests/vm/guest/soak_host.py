#!/usr/bin/python3
"""The host of the VM tier's soak test (soak.sh), on python3-can (not our code).

It sets the gateway (node 20h on the upstream bus) up as a host would (TPDO1 on 1A0h with a
50 ms event timer, 6423h TRUE, NMT start), then for SECONDS keeps SDO and NMT traffic going —
uploads of 1000h, 1018h:01 and 6401h:01, downloads of 1017h, now and then NMT stop/start — and
checks every answer. It writes each NMT stop/start window (wall time, as candump -L stamps its
frames) to WINDOWS, for soak_check.py: TPDO1 is not expected while the gateway is stopped.
Args: CHANNEL READY_FILE EXPECTED_1000H(hex) SECONDS WINDOWS
"""
import struct
import sys
import time

from hostlib import start_tpdo1, touch, u32
from python_peer import Peer

NODE = 0x20


def main():
    channel, ready, expected, seconds, windows = sys.argv[1], sys.argv[2], int(sys.argv[3], 16), float(sys.argv[4]), sys.argv[5]
    failures = 0
    counts = {"sdo": 0, "nmt": 0}
    with Peer(channel, timeout=10.0) as p, open(windows, "w") as w:  # 10 s: a TCG guest stalls for seconds at times
        touch(ready)
        if p.wait_heartbeat(NODE, state=0x00, timeout=60) != 0:
            print("FAIL: no boot-up", flush=True)
            return 1
        start_tpdo1(p, NODE, 0x1A0, event_timer_ms=50)
        print(f"started {time.time():.3f}", flush=True)
        end = time.monotonic() + seconds
        n = 0
        while time.monotonic() < end:
            n += 1
            try:
                dt = u32(p.sdo_upload(NODE, 0x1000, 0))
                vendor = u32(p.sdo_upload(NODE, 0x1018, 1))
                x = struct.unpack("<h", p.sdo_upload(NODE, 0x6401, 1))[0]
                p.sdo_download(NODE, 0x1017, 0, struct.pack("<H", 200))
                hb = struct.unpack("<H", p.sdo_upload(NODE, 0x1017, 0))[0]
                counts["sdo"] += 5
                if dt != expected or vendor != 0 or hb != 200 or not -32768 <= x <= 32767:
                    failures += 1
                    print(f"FAIL: round {n}: 1000h {dt:08X}h 1018h:01 {vendor:08X}h 1017h {hb}", flush=True)
            except Exception as e:  # noqa: BLE001 - every failure counts, the soak goes on
                failures += 1
                print(f"FAIL: round {n}: {e}", flush=True)
            if n % 40 == 0:  # NMT stop, 1 s, start: the TPDOs pause, everything else stays
                w.write(f"{time.time():.3f} ")
                w.flush()
                p.nmt("stop", NODE)
                time.sleep(1.0)
                p.nmt("start", NODE)
                w.write(f"{time.time():.3f}\n")
                w.flush()
                counts["nmt"] += 2
            time.sleep(0.05)
    print(f"host: {counts['sdo']} SDO transfers, {counts['nmt']} NMT commands, {failures} failures", flush=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
