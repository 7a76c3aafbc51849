#!/usr/bin/python3
"""The systemd side of sd_notify(3) for the VM tier's notify test (systemd_notify.sh): binds a
datagram Unix socket at PATH and writes every message it receives to OUT, one line per state
("READY=1", "STATUS=...", "WATCHDOG=1", "STOPPING=1"), each prefixed by its arrival time in
seconds (time.monotonic). Creates READY_FILE once bound; stops after SECONDS or on SIGTERM.
With TICKS, also writes there the time of each of its own wake-ups, at most TICK s apart while
the guest runs: a gap between them is a stall of the whole guest (systemd_notify.sh tells the
gateway's silence from the guest's by them).

    notify_listen.py PATH OUT READY_FILE SECONDS [TICKS]
"""
import os
import signal
import socket
import sys
import time

TICK = 0.1  # s

def main() -> int:
    path, out, ready_file, seconds = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    if os.path.exists(path):
        os.unlink(path)
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    sock.bind(path)
    open(ready_file, "w").close()
    deadline = time.monotonic() + seconds
    ticks = open(sys.argv[5], "w", buffering=1) if len(sys.argv) > 5 else None
    with open(out, "w", buffering=1) as log:
        while time.monotonic() < deadline:
            sock.settimeout(max(0.01, min(TICK, deadline - time.monotonic())) if ticks else max(0.05, deadline - time.monotonic()))
            try:
                data = sock.recv(4096)
            except socket.timeout:
                data = b""
            now = time.monotonic()
            if ticks:
                ticks.write(f"{now:.3f}\n")
            for line in data.decode("utf-8", "replace").split("\n"):
                if line:
                    log.write(f"{now:.3f} {line}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
