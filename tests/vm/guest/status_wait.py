#!/usr/bin/python3
"""Waits until `oegw status --json` shows what a guest test expects (vm_gateway).

    status_wait.py OEGW OUT TIMEOUT_S EXPR

Runs `OEGW status --json` (one process per try, 0.5 s apart) until EXPR holds for the answer
(names: a = the answer, s = a["status"], subs = the sub-devices by name), writes that answer to
OUT and exits 0; after TIMEOUT_S exits 1 with the last answer in OUT. python3's json reads the
daemon's text, an independent parser of what the gateway wrote.
"""
import json
import subprocess
import sys
import time


def holds(text, expr):
    try:
        a = json.loads(text)
        s = a["status"]
        subs = {d["name"]: d for d in s["subdevices"]}
        return bool(a["ok"] and a["protocol"] == 1 and eval(expr, {"a": a, "s": s, "subs": subs}))
    except (ValueError, KeyError, TypeError):
        return False


def main():
    oegw, out, timeout, expr = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4]
    deadline = time.monotonic() + timeout
    text = ""
    while True:
        r = subprocess.run([oegw, "status", "--json", "--timeout", "10"], capture_output=True, text=True)
        text = r.stdout if r.returncode == 0 else r.stdout + r.stderr
        if r.returncode == 0 and holds(text, expr):
            break
        if time.monotonic() > deadline:
            break
        time.sleep(0.5)
    with open(out, "w") as f:
        f.write(text)
    sys.exit(0 if holds(text, expr) else 1)


if __name__ == "__main__":
    main()
