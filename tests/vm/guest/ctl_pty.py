#!/usr/bin/env python3
"""vm_ctl's interactive part: `oegw ctl` on a pseudo-terminal, as a person at a terminal runs it.

Usage: ctl_pty.py OEGW LINE...  Starts `oegw ctl` with a pty as its standard input and output
(so it is interactive: prompt, history, events between commands), types each LINE after the
prompt came back, then Ctrl-D; prints everything the terminal showed and exits with oegw ctl's
exit status (124 when it does not end)."""
import os
import pty
import select
import subprocess
import sys
import time

oegw, lines = sys.argv[1], sys.argv[2:]
master, slave = pty.openpty()
proc = subprocess.Popen([oegw, "ctl"], stdin=slave, stdout=slave, stderr=slave, close_fds=True)
os.close(slave)
shown = b""


def read_until(done, seconds=30.0):
    """Reads the terminal until done() or the time is up; False if the terminal closed."""
    global shown
    end = time.monotonic() + seconds
    while time.monotonic() < end and not done():
        ready, _, _ = select.select([master], [], [], 0.2)
        if not ready:
            continue
        try:
            data = os.read(master, 4096)
        except OSError:  # EIO: the child closed the pty
            return False
        if not data:
            return False
        shown += data
    return done()


def prompts():
    return shown.count(b"> ")


read_until(lambda: prompts() >= 1)
for line in lines:
    before = prompts()
    os.write(master, (line + "\n").encode())
    read_until(lambda: prompts() > before)
os.write(master, b"\x04")  # Ctrl-D: the end of the session
read_until(lambda: proc.poll() is not None, 10.0)
try:
    rc = proc.wait(timeout=10)
except subprocess.TimeoutExpired:
    proc.kill()
    rc = 124
sys.stdout.write(shown.decode(errors="replace").replace("\r", ""))
sys.exit(rc)
