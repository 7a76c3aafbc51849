#!/usr/bin/python3
"""`oegw demo`'s live table as a terminal shows it, judged on the screen alone.

tmux (Debian's) runs `oegw demo` in a detached pane of COLS x ROWS; the test reads the visible
screen with `tmux capture-pane -p` five times a second until the demo has exited, and fails if any
screen shows the table twice (two `joystick.1` rows or two `sub-devices:` rows: copies left behind
by a redraw), a log line below the table (the log goes above it), a table row wider than the
pane, or a row filling all its columns (a line the terminal wrapped, mid-word). At the end the demo must have said "demo complete" and exited 0, and
the table must have been seen on at least three screens (so the test saw it redrawn).
Args: OEGW COLS ROWS
"""
import os
import subprocess
import sys
import time


def tmux(sock, *args, check=True):
    return subprocess.run(["tmux", "-f", "/dev/null", "-L", sock, *args], check=check,
                          capture_output=True, text=True)


def judge(screen, cols):
    """The problems of one screen (a list of rows), or []."""
    rows = screen.split("\n")
    problems = []
    fe = [i for i, r in enumerate(rows) if r.startswith("  joystick.1 ")]
    nodes = [i for i, r in enumerate(rows) if r.startswith("  sub-devices:")]
    if len(fe) > 1:
        problems.append(f"{len(fe)} joystick.1 rows on one screen (rows {fe})")
    if len(nodes) > 1:
        problems.append(f"{len(nodes)} sub-devices rows on one screen (rows {nodes})")
    if fe:
        below = [r for r in rows[fe[0]:] if r.startswith("[")]
        if below:
            problems.append(f"a log line below the table: {below[0]!r}")
    for r in rows:
        if len(r) > cols:
            problems.append(f"a row of {len(r)} columns in a {cols}-column pane")
        elif len(r) == cols:
            # The demo keeps one column spare and breaks its log lines at spaces: a full row is
            # one the terminal wrapped, mid-word.
            problems.append(f"a row the terminal wrapped (all {cols} columns used): {r!r}")
    return problems


def main():
    oegw, cols, lines = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    sock = f"oegw-screen-{os.getpid()}"
    cmd = f"{oegw} demo --seconds 1 --no-publish; echo __EXIT__$?; sleep 120"
    tmux(sock, "new-session", "-d", "-x", str(cols), "-y", str(lines), "-s", "demo", cmd)
    failures, tables, screen = [], 0, ""
    try:
        size = tmux(sock, "display-message", "-p", "-t", "demo", "#{pane_width}x#{pane_height}").stdout.strip()
        if size != f"{cols}x{lines}":
            print(f"FAIL: the pane is {size}, not {cols}x{lines}")
            return 1
        deadline = time.monotonic() + 90
        while time.monotonic() < deadline:
            screen = tmux(sock, "capture-pane", "-p", "-t", "demo").stdout
            problems = judge(screen, cols)
            if any(r.startswith("  joystick.1 ") for r in screen.split("\n")):
                tables += 1
            if problems and not failures:
                print("--- the screen that failed:\n" + screen)
            failures += problems
            if "__EXIT__" in screen:
                break
            time.sleep(0.2)
    finally:
        tmux(sock, "kill-server", check=False)
    print(f"{cols}x{lines}: {tables} screens with the table")
    for p in dict.fromkeys(failures):
        print("FAIL:", p)
    if "demo complete: every step as expected" not in screen or "__EXIT__0" not in screen:
        print("FAIL: the demo did not end with 'demo complete' and exit 0:\n" + screen)
        return 1
    if tables < 3:
        print(f"FAIL: the table was on only {tables} screens")
        return 1
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
