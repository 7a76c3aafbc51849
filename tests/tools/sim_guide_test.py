#!/usr/bin/python3
"""docs/guides/simulate.md as written: its cab file and fault script, run by the built `oegw sim`.

The page's ```yaml block is saved as cab.yaml (with the pedal's EDS beside it, as the page says),
its ```text block as faults.txt, and each `$ oegw sim ...` line of a ```sh block is run in that
folder; the lines shown after it are the output's excerpt (`...` alone: any lines; `...` inside a
line: any text) and must be found in that order. Then what the page promises besides:
  * the run is the same every time on the simulated clock (--fast): byte for byte;
  * an `expect` that does not hold fails the run (exit 1, "FAILED: expected ...");
  * a script with mistakes is refused before anything starts: exit 1, each mistake as
    file:line:column, no "oegw sim:" banner;
  * in real time the control socket answers `oegw status` while the sim runs, and a line typed
    on standard input is run as a command.
Args: OEGW SOURCE_DIR
"""
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

failures = []


def check(ok, what):
    print(("ok: " if ok else "FAIL: ") + what)
    if not ok:
        failures.append(what)


def excerpt_found(excerpt, output):
    """Every excerpt line found in `output`'s lines in order; `...` alone skips any lines."""
    lines = output.splitlines()
    pos = 0
    skip = False
    for want in excerpt:
        if want.strip() == "...":
            skip = True
            continue
        pattern = "^" + ".*".join(re.escape(p) for p in want.split("...")) + "$"
        while pos < len(lines) and not re.match(pattern, lines[pos]):
            if not skip:
                return f"expected {want!r} at output line {pos + 1}, found {lines[pos]!r}"
            pos += 1
        if pos == len(lines):
            return f"expected {want!r}: not found"
        pos += 1
        skip = False
    return None


def main():
    oegw, src = os.path.abspath(sys.argv[1]), sys.argv[2]
    page = open(os.path.join(src, "docs/guides/simulate.md"), encoding="utf-8").read()
    blocks = re.findall(r"```(\w+)\n(.*?)```", page, re.S)
    work = tempfile.mkdtemp(prefix="oegw-sim-guide-")
    try:
        yaml = [b for t, b in blocks if t == "yaml"]
        text = [b for t, b in blocks if t == "text"]
        check(len(yaml) == 1 and len(text) == 1, "the page has one cab file and one fault script")
        open(os.path.join(work, "cab.yaml"), "w").write(yaml[0])
        open(os.path.join(work, "faults.txt"), "w").write(text[0])
        shutil.copy(os.path.join(src, "subdevices/eds/generic_pedal.eds"), work)
        # The file uses every family of driver.
        for driver in ("elobau-mfg", "mcb402", "cia401", "novotechnik-406"):
            check(f"driver: {driver}" in yaml[0], f"the page's file has a {driver} sub-device")

        run = lambda args, **kw: subprocess.run([oegw, *args], cwd=work, capture_output=True, text=True,
                                               timeout=120, **kw)
        # Every `$ oegw sim` line of the page with its excerpt (real-time lines without --fast
        # run only with --seconds: they are shown to be run at ^C).
        ran = 0
        for t, b in blocks:
            if t != "sh":
                continue
            lines = b.splitlines()
            for i, line in enumerate(lines):
                if not line.startswith("$ oegw sim"):
                    continue
                args = line[len("$ oegw "):].split()
                if "--fast" not in args:
                    args += ["--seconds", "1"]
                args.append("--no-publish")
                excerpt = []
                for e in lines[i + 1:]:
                    if e.startswith("$ "):
                        break
                    excerpt.append(e)
                r = run(args, stdin=subprocess.DEVNULL)
                ran += 1
                check(r.returncode == 0, f"`{line[2:]}` exits 0 (exit {r.returncode}; stderr {r.stderr.strip()[:300]!r})")
                if excerpt:
                    miss = excerpt_found(excerpt, r.stdout)
                    check(miss is None, f"`{line[2:]}` prints the page's excerpt" + (f": {miss}" if miss else ""))
                if "--script" in args:
                    for want in ("ok: joystick.1 offline", "ok: joystick.1 valid", "ok: joystick.2 error",
                                 "host: EMCY 7000h from the gateway (sub-device 11h failed)",
                                 "host: EMCY 3120h from the gateway"):
                        check(want in r.stdout, f"the fault script's run shows {want!r}")
                    again = run(args, stdin=subprocess.DEVNULL)
                    check(again.stdout == r.stdout, "a second --fast run prints the same, byte for byte")
        check(ran >= 2, f"the page's `$ oegw sim` lines were run ({ran})")

        # An expectation that does not hold fails the run.
        open(os.path.join(work, "wrong.txt"), "w").write("2.0 grip silent on\n3.5 expect joystick.1 valid\n")
        r = run(["sim", "cab.yaml", "--fast", "--no-publish", "--script", "wrong.txt"])
        check(r.returncode == 1 and "FAILED: expected joystick.1 valid, it is offline" in r.stdout,
              f"an expectation that does not hold: exit 1 and FAILED (exit {r.returncode})")

        # A script with mistakes: every one at its place, nothing started.
        open(os.path.join(work, "bad.txt"), "w").write(
            "# every line below is wrong\n"
            "1.0 grib silent on\n"
            "x2 grip silent on\n"
            "2.0 grip x 500\n"
            "3.0 expect joystick.9 valid\n"
            "3.0 expect joystick.1 moving\n"
            "4.0 host rpdo 99 01\n"
            "5.0\n")
        r = run(["sim", "cab.yaml", "--fast", "--no-publish", "--script", "bad.txt"])
        check(r.returncode == 1, f"a bad script: exit 1 ({r.returncode})")
        check("oegw sim:" not in r.stdout and r.stdout.strip() == "", "a bad script: nothing started, nothing on stdout")
        for want in ("bad.txt:2:5: found 'grib silent on'; no device 'grib'",
                     "bad.txt:3:1: found 'x2'; expected the time in seconds",
                     "bad.txt:4:5: found 'grip x 500';",
                     "bad.txt:5:5: found 'expect joystick.9 valid'; expected an FE of the file",
                     "bad.txt:6:5: found 'expect joystick.1 moving'; expected a status",
                     "bad.txt:7:5: found 'host rpdo 99 01'; expected host rpdo N BYTES with an RPDO of this gateway",
                     "bad.txt:8:4: found nothing after the time; expected a command",
                     "7 error(s) in bad.txt; nothing started"):
            check(want in r.stderr, f"a bad script names {want!r}")
        if failures:
            print(r.stderr)

        # Real time: the control socket answers while the sim runs; a typed line is a command.
        p = subprocess.Popen([oegw, "sim", "cab.yaml", "--seconds", "4", "--no-publish"], cwd=work,
                             stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        sock = None
        deadline = time.monotonic() + 30
        banner = ""
        while time.monotonic() < deadline and sock is None:
            line = p.stdout.readline()
            if not line:
                break
            banner += line
            m = re.search(r"oegw status --socket (\S+)", line)
            if m:
                sock = m.group(1)
        check(sock is not None, "the real-time run names its control socket")
        if sock:
            status = None
            for _ in range(50):  # the gateway's sub-devices boot in ~0.1 s; the socket is up at once
                status = subprocess.run([oegw, "status", "--socket", sock], capture_output=True, text=True, timeout=30)
                if status.returncode == 0 and status.stdout.count("operational") >= 5:
                    break
                time.sleep(0.1)
            check(status.returncode == 0 and "grip" in status.stdout and "knob" in status.stdout,
                  f"oegw status --socket answers during the run (exit {status.returncode})")
        p.stdin.write("grip silent on\n")
        p.stdin.flush()
        out, _ = p.communicate(timeout=60)
        check(p.returncode == 0, f"the real-time run exits 0 ({p.returncode})")
        check("ok grip silent on" in out and "grip: missing (heartbeat lost)" in out,
              "a line typed on standard input is run: the grip goes silent and the gateway loses it")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(f"{len(failures)} failure(s)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
