#!/usr/bin/python3
"""Clients of the control socket that misbehave, for vm_abuse (tests/vm/guest/abuse.sh).

    abuse_client.py SOCKET pipeline N LIMIT_S        N status requests on one connection, written as
                                                     fast as the socket takes them while the answers
                                                     are read; prints "answered K of N in T s"
    abuse_client.py SOCKET noread SECONDS            writes status requests and never reads; prints
                                                     when the daemon closed it ("closed after T s")
                                                     or "still open after SECONDS s"
    abuse_client.py SOCKET slow COUNT SECONDS GAP_S  COUNT connections, each sending one byte of a
                                                     request every GAP_S seconds; prints how many the
                                                     daemon closed, and the answers they were given
    abuse_client.py SOCKET burst COUNT LIMIT_S       COUNT connections at once, each asking for the
                                                     status once and closing when answered; prints
                                                     "answered K of COUNT in T s"
    abuse_client.py SOCKET probe OUT PERIOD_S        until killed: every PERIOD_S a new connection
                                                     asks for the status once; a line "START END OK"
                                                     (CLOCK_REALTIME s, OK 1 when a whole answer
                                                     came) per request to OUT: the daemon's own
                                                     answer time, without a program's start-up

Standard library only (sockets and selectors): an independent client of the protocol.
Exit status 0 when the client could run (what happened is in the printed line; abuse.sh judges).
"""
import selectors
import socket
import sys
import time

REQUEST = b'{"command":"status"}\n'


def connect(path, blocking=True):
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.connect(path)
    s.setblocking(blocking)
    return s


def pipeline(path, n, limit):
    s = connect(path, blocking=False)
    out = REQUEST * n
    sent = 0
    answered = 0
    start = time.monotonic()
    sel = selectors.DefaultSelector()
    sel.register(s, selectors.EVENT_READ | selectors.EVENT_WRITE)
    while answered < n and time.monotonic() - start < limit:
        for key, ev in sel.select(timeout=1.0):
            if ev & selectors.EVENT_WRITE and sent < len(out):
                try:
                    sent += s.send(out[sent:sent + 65536])
                except BlockingIOError:
                    pass
                if sent == len(out):
                    sel.modify(s, selectors.EVENT_READ)
            if ev & selectors.EVENT_READ:
                data = s.recv(1 << 20)
                if not data:
                    print(f"closed by the daemon after {answered} answers")
                    return
                answered += data.count(b"\n")
    print(f"answered {answered} of {n} in {time.monotonic() - start:.1f} s (sent {sent // len(REQUEST)})")


def noread(path, seconds):
    s = connect(path, blocking=False)
    start = time.monotonic()
    sent = 0
    while time.monotonic() - start < seconds:
        try:
            sent += s.send(REQUEST * 64)
        except BlockingIOError:
            time.sleep(0.05)
        except (BrokenPipeError, ConnectionResetError):
            print(f"closed after {time.monotonic() - start:.1f} s ({sent} bytes sent, none read)")
            return
    print(f"still open after {seconds} s ({sent} bytes sent, none read)")


def slow(path, count, seconds, gap):
    conns = [connect(path, blocking=False) for _ in range(count)]
    closed = {}
    told = {}
    start = time.monotonic()
    request = REQUEST
    at = 0
    while time.monotonic() - start < seconds and len(closed) < count:
        for i, s in enumerate(conns):
            if i in closed:
                continue
            try:
                data = s.recv(4096)
                if data:
                    told[i] = told.get(i, b"") + data
                else:
                    closed[i] = time.monotonic() - start
                    continue
            except BlockingIOError:
                pass
            try:
                s.send(request[at % (len(request) - 1):at % (len(request) - 1) + 1])  # never the newline
            except (BrokenPipeError, ConnectionResetError):
                closed[i] = time.monotonic() - start
        at += 1
        time.sleep(gap)
    codes = sorted({t.split(b'"code":"')[1].split(b'"')[0].decode() for t in told.values() if b'"code":"' in t})
    times = ", ".join(f"{t:.0f}" for t in sorted(closed.values()))
    print(f"closed {len(closed)} of {count} within {seconds} s (at {times} s); answers: {codes or 'none'}")


def burst(path, count, limit):
    sel = selectors.DefaultSelector()
    start = time.monotonic()
    conns = []
    for _ in range(count):
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.setblocking(False)
        try:
            s.connect(path)
        except BlockingIOError:  # the listen queue is full: this one is refused, counted below
            s.close()
            continue
        s.send(REQUEST)
        sel.register(s, selectors.EVENT_READ, bytearray())
        conns.append(s)
    answered = 0
    other = 0
    while sel.get_map() and time.monotonic() - start < limit:
        for key, _ in sel.select(timeout=1.0):
            data = key.fileobj.recv(1 << 16)
            key.data.extend(data)
            if b"\n" in key.data or not data:
                if key.data.startswith(b'{"command":"status"') or b'"ok":true' in key.data:
                    answered += 1
                else:
                    other += 1
                sel.unregister(key.fileobj)
                key.fileobj.close()
    print(f"answered {answered} of {count} in {time.monotonic() - start:.1f} s ({len(conns)} connected, "
          f"{other} other answers; this client's CPU {time.process_time():.2f} s)")


def probe(path, out, period):
    with open(out, "w", buffering=1) as f:
        while True:
            start = time.time()
            ok = 0
            try:
                s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                s.settimeout(60)
                s.connect(path)
                s.sendall(REQUEST)
                got = b""
                while b"\n" not in got:
                    data = s.recv(1 << 16)
                    if not data:
                        break
                    got += data
                ok = 1 if b'"ok":true' in got else 0
                s.close()
            except OSError:
                pass
            f.write(f"{start:.6f} {time.time():.6f} {ok}\n")
            time.sleep(period)


def main():
    path, mode = sys.argv[1], sys.argv[2]
    args = sys.argv[3:]
    if mode == "pipeline":
        pipeline(path, int(args[0]), float(args[1]))
    elif mode == "noread":
        noread(path, float(args[0]))
    elif mode == "slow":
        slow(path, int(args[0]), float(args[1]), float(args[2]))
    elif mode == "burst":
        burst(path, int(args[0]), float(args[1]))
    elif mode == "probe":
        probe(path, args[0], float(args[1]))
    else:
        sys.exit(f"unknown mode {mode}")


if __name__ == "__main__":
    main()
