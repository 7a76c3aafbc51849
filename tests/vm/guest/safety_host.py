#!/usr/bin/python3
"""The host side of the VM tier's safety test (vm_safety), on python3-can (not our code).

One process for every scenario (each python3-can start costs seconds in the VM). Two buses:
  vcan0  the gateway (`oegw run`, node 20h) as the host sees it: SDO client, NMT master, TPDO
         consumer, EMCY consumer, heartbeat producer (node 01h) for scenario 4;
  vcan1  the sub-devices' bus, read through kernel filters (NMT, the grip's and the MCB-402's
         heartbeats and PDOs): to see what the gateway sends the devices and to inject, once,
         the MCB-402 heartbeat of scenario 2.
A thread per bus records every frame with its kernel timestamp; scenarios wait on conditions with
deadlines (the VM is slow: TCG), never on fixed sleeps alone. A wait for what must come is 10 s
or more (it ends when it comes; a TCG guest stalls for seconds at times); no check bounds a delay
in wall time: the deadlines are judged on simulated time, here by their order or counted in the
grip's heartbeats. The grip (`oegw-sim --commands`)
is driven by writing lines ("right_grip x 50", "right_grip heartbeat off", ...) to a FIFO.

Each scenario prints its checks ("  ok: ..." / "  NOT OK: ...") and one verdict line,
"PASS: scenario N ..." or "FAIL: scenario N ...". The exit status is the number of failed
scenarios. Windows of time in which the MCB-402's RPDO1 (203h) must carry exactly given frames are
written to WINDOWS_FILE for safety.sh to check against candump's own record.
Args: READY_FILE GRIP_FIFO WINDOWS_FILE
"""
import struct
import sys
import threading
import time

import can

import hostlib
from hostlib import log, touch

GW = 0x20          # the gateway upstream
HOST = 0x01        # the host's own node-ID (its heartbeat 701h, scenario 4)
GRIP = 0x11        # elobau MFG, right_grip, joystick 1
MCB = 0x03         # MCB-402, left_grip, joystick 2 and indicators.1 (its LEDs)
EMCY = 0x80 + GW
TPDO1 = 0x1A0      # joystick 1 (the host sets 1800h:01, as gateway_host.py does)
TPDO5 = 0x2A0      # joystick 2 (1804h:01; disabled by default, CiA 852 Table 10)
MCB_RPDO1 = 0x200 + MCB   # 6200h:01, the LEDs


class Recorder:
    """Every data frame of one bus, (kernel timestamp, id, data), in arrival order."""

    def __init__(self, bus, name):
        self.bus, self.name = bus, name
        self.frames = []
        self.cv = threading.Condition()
        self.hooks = []          # called in the reader thread, before the frame is stored
        self.running = True
        self.thread = threading.Thread(target=self._run, name=name, daemon=True)
        self.thread.start()

    def _run(self):
        while self.running:
            msg = self.bus.recv(timeout=0.2)
            if msg is None or msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
                continue
            f = (msg.timestamp, msg.arbitration_id, bytes(msg.data))
            for h in self.hooks:
                h(f)
            with self.cv:
                self.frames.append(f)
                self.cv.notify_all()

    def mark(self):
        with self.cv:
            return len(self.frames)

    def wait(self, pred, timeout, start=0):
        """First frame from index `start` on satisfying pred: (index, frame), or None at the deadline."""
        deadline = time.monotonic() + timeout
        i = start
        with self.cv:
            while True:
                while i < len(self.frames):
                    if pred(self.frames[i]):
                        return i, self.frames[i]
                    i += 1
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self.cv.wait(left)

    def since(self, start, pred=None, end=None):
        with self.cv:
            fs = self.frames[start:end]
        return [f for f in fs if pred is None or pred(f)]

    def stop(self):
        self.running = False
        self.thread.join(1.0)


def is_id(can_id):
    return lambda f: f[1] == can_id


def emcy(f):
    """(code, register, msef) of a gateway EMCY frame, else None."""
    if f[1] != EMCY or len(f[2]) != 8:
        return None
    return struct.unpack_from("<H", f[2])[0], f[2][2], f[2][3:]


def emcy_7000_naming(node):
    def pred(f):
        e = emcy(f)
        return e is not None and e[0] == 0x7000 and e[2][0] == node
    return pred


def reset_indexes(frames, node):
    """Indexes (into `frames`, the vcan0 record) of the EMCY error resets that end node's sub-device
    fault. The gateway names the node in every such 0000h (the last one too); a generic 0000h
    (empty manufacturer field, as other CiA 301 §7.2.7.2 producers send) is still taken: it
    counts for node only if node's EMCY 7000h was the active fault (the EMCY stream is
    replayed from the start, so that another device's fault and its clearing do not count)."""
    active = set()
    out = []
    for i, f in enumerate(frames):
        e = emcy(f)
        if e is None:
            continue
        code, _, msef = e
        if code == 0x7000:
            active.add(msef[0])
        elif code == 0x0000:
            generic = not any(msef)
            if (msef[0] == node or generic) and node in active:
                out.append(i)
            if generic:
                active.clear()
            else:
                active.discard(msef[0])
    return out


def joy(f):
    """(x, y, z, buttons lo, buttons hi) of a joystick TPDO (CiA 852 Table 12 layout)."""
    return struct.unpack("<hhhBB", f[2]) if len(f[2]) == 8 else None


def hexs(data):
    return data.hex().upper()


def fmt_frame(f):
    return f"{f[1]:03X}#{hexs(f[2])}"


class SdoError(Exception):
    pass


class Host:
    def __init__(self, grip_fifo, windows_file):
        # vcan0: everything (the gateway's frames only). vcan1: kernel filters keep the reader
        # cheap under the simulators' frame load; its own frames are looped back so that the
        # injected heartbeat is recorded in bus order.
        self.up_bus = can.interface.Bus(channel="vcan0", interface="socketcan")
        ids = [0x000, 0x700 + MCB, 0x700 + GRIP, 0x180 + GRIP, 0x280 + GRIP, MCB_RPDO1]
        self.down_bus = can.interface.Bus(channel="vcan1", interface="socketcan", receive_own_messages=True,
                                          can_filters=[{"can_id": i, "can_mask": 0x7FF} for i in ids])
        self.up = Recorder(self.up_bus, "vcan0")
        self.down = Recorder(self.down_bus, "vcan1")
        self.grip_fifo = open(grip_fifo, "w", buffering=1)
        self.windows = open(windows_file, "w", buffering=1)
        self.hb_on = threading.Event()
        self.hb_last = None
        self.hb_sent = []        # time.time() of every heartbeat sent
        self.hb_thread = threading.Thread(target=self._heartbeat, name="heartbeat", daemon=True)
        self.hb_thread.start()
        self.results = []
        self.checks = []

    # --- frames and SDO -----------------------------------------------------------------------
    def send_up(self, can_id, data):
        self.up_bus.send(can.Message(arbitration_id=can_id, is_extended_id=False, data=bytes(data)))

    def _heartbeat(self):
        """The host's heartbeat 701h#05 every 100 ms while hb_on is set."""
        nxt = time.monotonic()
        while True:
            if not self.hb_on.wait(0.05):
                continue
            self.send_up(0x700 + HOST, [0x05])
            self.hb_last = time.time()
            self.hb_sent.append(self.hb_last)
            nxt = max(nxt + 0.1, time.monotonic())
            time.sleep(max(nxt - time.monotonic(), 0))

    def _sdo(self, req, what):
        for attempt in range(2):  # one retry: a TCG hiccup is not what these tests are about
            m = self.up.mark()
            self.send_up(0x600 + GW, req)
            r = self.up.wait(is_id(0x580 + GW), 10.0, m)
            if r is not None:
                d = r[1][2].ljust(8, b"\0")
                if d[0] == 0x80:
                    raise SdoError(f"{what}: abort {struct.unpack_from('<I', d, 4)[0]:08X}h")
                return d
            self.send_up(0x600 + GW, struct.pack("<BHBI", 0x80, *struct.unpack_from("<HB", req, 1), 0x05040000))
        raise SdoError(f"{what}: no answer")

    def download(self, index, sub, data):
        data = bytes(data)
        req = struct.pack("<BHB", 0x23 | (4 - len(data)) << 2, index, sub) + data.ljust(4, b"\0")
        d = self._sdo(req, f"download {index:04X}h:{sub:02X}")
        if d[0] != 0x60:
            raise SdoError(f"download {index:04X}h:{sub:02X}: response {hexs(d)}")

    def upload(self, index, sub):
        d = self._sdo(struct.pack("<BHB4x", 0x40, index, sub), f"upload {index:04X}h:{sub:02X}")
        if d[0] & 0xE3 != 0x43:
            raise SdoError(f"upload {index:04X}h:{sub:02X}: response {hexs(d)}")
        return d[4:8 - ((d[0] >> 2) & 3)]

    def x1(self):
        """Joystick 1 x as the gateway's dictionary holds it (6401h:01)."""
        return struct.unpack("<h", self.upload(0x6401, 1))[0]

    def grip(self, command):
        log(f"grip: {command}")
        self.grip_fifo.write(f"right_grip {command}\n")

    # --- verdicts -----------------------------------------------------------------------------
    def check(self, ok, what):
        print(("  ok: " if ok else "  NOT OK: ") + what, flush=True)
        self.checks.append(ok)
        return ok

    def scenario(self, number, title, fn):
        log(f"== scenario {number}: {title}")
        self.checks = []
        note = ""
        try:
            note = fn() or ""
        except Exception as e:  # noqa: BLE001 - a scenario that breaks is a failed scenario
            self.check(False, f"scenario raised {type(e).__name__}: {e}")
        if note == "SKIP":
            print(f"SKIP: scenario {number} ({title})", flush=True)
            return
        ok = all(self.checks) and bool(self.checks)
        n_bad = sum(1 for c in self.checks if not c)
        print(f"{'PASS' if ok else 'FAIL'}: scenario {number} ({title})"
              + (f": {n_bad} of {len(self.checks)} checks failed" if not ok else f": {len(self.checks)} checks")
              + (f"; {note}" if note else ""), flush=True)
        self.results.append(ok)

    def window(self, name, t_from, t_to, expected):
        self.windows.write(f"{name} {t_from:.6f} {t_to:.6f} {','.join(expected)}\n")

    def resets_since(self, node, start):
        with self.up.cv:
            frames = list(self.up.frames)
        return [frames[i] for i in reset_indexes(frames, node) if i >= start]

    def wait_reset(self, node, timeout, start):
        """First error reset for node from index `start` on (see reset_indexes), or None."""
        deadline = time.monotonic() + timeout
        while True:
            got = self.resets_since(node, start)
            if got:
                return got[0]
            if time.monotonic() >= deadline:
                return None
            self.up.wait(lambda f: f[1] == EMCY, min(0.5, max(deadline - time.monotonic(), 0.01)), self.up.mark())

    # --- joystick 1 helpers -------------------------------------------------------------------
    def wait_x1(self, pred, timeout, start):
        """First TPDO1 from `start` whose x satisfies pred; None at the deadline."""
        r = self.up.wait(lambda f: f[1] == TPDO1 and joy(f) is not None and pred(joy(f)[0]), timeout, start)
        return r

    def follows(self, percent, timeout=10.0):
        """Moves the stick to `percent` and waits for joystick 1 x to follow (same sign, over half)."""
        m = self.up.mark()
        self.grip(f"x {percent}")
        want = percent * 32767 / 100 / 2
        r = self.wait_x1(lambda x: (x > want) if percent > 0 else (x < want), timeout, m)
        if r is None:
            return None, self.x1()
        return r[1], joy(r[1])[0]

    def neutral_for(self, seconds, start, what):
        """Joystick 1 x is 0 in every TPDO1 from `start` and in 6401h:01 read every ~0.4 s for
        `seconds`. Returns (ok, description)."""
        end = time.monotonic() + seconds
        reads = []
        while time.monotonic() < end:
            reads.append(self.x1())
            time.sleep(0.4)
        tpdos = [joy(f)[0] for f in self.up.since(start, is_id(TPDO1)) if joy(f) is not None]
        bad = [x for x in tpdos if x != 0] + [x for x in reads if x != 0]
        desc = (f"{what}: joystick 1 x = 0 in all {len(tpdos)} TPDO1 and {len(reads)} reads of 6401h:01 "
                f"over {seconds:g} s" if not bad else
                f"{what}: joystick 1 x left neutral: TPDO1 x {sorted(set(tpdos))[:8]}, 6401h:01 reads {reads}")
        return not bad, desc


# ------------------------------------------------------------------------------- scenarios

class BootRace:
    """Scenario 2's injector on vcan1: at each NMT start of the MCB-402 by the gateway (000#01 03),
    while armed, send 703#7F at once, as if the device's heartbeat queued before the start went
    out after it. Up to three attempts: if the simulator's own 703#05 came first (its heartbeat
    phase, 100 ms), the 7Fh is a real loss, the gateway restarts the node, and the next start is
    tried again."""

    def __init__(self, host):
        self.host = host
        self.attempts = []       # (index in the vcan1 record, kernel timestamp) of each NMT start
        self.armed = True
        host.down.hooks.append(self.hook)

    def hook(self, f):
        if (self.armed and len(self.attempts) < 3 and f[1] == 0x000 and len(f[2]) == 2 and f[2][0] == 0x01
                and f[2][1] in (MCB, 0)):
            self.host.down_bus.send(can.Message(arbitration_id=0x700 + MCB, is_extended_id=False, data=[0x7F]))
            with self.host.down.cv:
                self.attempts.append((len(self.host.down.frames), f[0]))  # the hook runs before f is stored


def setup(h):
    r = h.up.wait(lambda f: f[1] == 0x700 + GW and f[2] == b"\x00", 60)
    if r is None:
        raise SdoError("no boot-up 720#00 from the gateway")
    log("gateway boot-up")
    h.download(0x1800, 1, struct.pack("<I", TPDO1))
    h.download(0x1804, 1, struct.pack("<I", TPDO5))
    h.download(0x6423, 0, b"\x01")
    h.send_up(0x000, [0x01, GW])
    if h.up.wait(lambda f: f[1] == 0x700 + GW and f[2] == b"\x05", 10) is None:
        raise SdoError("the gateway did not report operational after NMT start")
    log("gateway operational")


def scenario_boot_race(h, race):
    # The gateway boots its sub-devices as soon as it runs; the injector was armed before.
    won = None
    for k in range(3):
        deadline = time.monotonic() + (30 if k == 0 else 15)
        while len(race.attempts) <= k and time.monotonic() < deadline:
            time.sleep(0.05)
        if len(race.attempts) <= k:
            break
        start_i, start_t = race.attempts[k]
        # Bus order on vcan1 (receive_own_messages): the first 703h frame after the start must be
        # the injected 7Fh; a 703#05 of the simulator before it would make the 7Fh a real loss.
        first = h.down.wait(is_id(0x700 + MCB), 5, start_i + 1)
        if first is not None and first[1][2] == b"\x7F":
            won = (k, start_t)
            log(f"attempt {k + 1}: 703#7F injected {1000 * (first[1][0] - start_t):.1f} ms after 000#0103 "
                "(bus timestamps), before the simulator's first heartbeat in operational")
            break
        log(f"attempt {k + 1}: race lost: first 703h after the NMT start is {fmt_frame(first[1]) if first else None}")
    race.armed = False
    if won is None:
        if not race.attempts:
            h.check(False, "the gateway NMT-started the MCB-402 (000#0103)")
            return None
        # Let the node recover from the (real) losses before the next scenario uses it.
        h.wait_reset(MCB, 15, 0)
        return "SKIP"
    k, start_t = won
    # Joystick 2 becomes live: TPDO5 x takes several values (the MCB-402 sweeps its axes).
    xs = set()
    deadline = time.monotonic() + 20
    i = 0
    while time.monotonic() < deadline and len(xs) < 5:
        got = h.up.wait(lambda f: f[1] == TPDO5 and f[0] > start_t, max(deadline - time.monotonic(), 0.01), i)
        if got is None:
            break
        i = got[0] + 1
        xs.add(joy(got[1])[0])
    h.check(len(xs) >= 5, f"joystick 2 live: TPDO5 x took {len(xs)} values ({sorted(xs)[:6]}...)")
    time.sleep(1.0)  # a false fault would have come by now (consumer time 400 ms)
    bad = h.up.since(0, lambda f: emcy_7000_naming(MCB)(f) and f[0] > start_t)
    h.check(not bad, f"no EMCY 7000h naming 03h since that NMT start (attempt {k + 1})"
            + (f": got {[fmt_frame(f) for f in bad]}" if bad else ""))
    if k > 0:
        # The earlier attempts were real losses: their fault must clear after this start.
        with h.up.cv:
            frames = list(h.up.frames)
        ok = any(frames[j][0] > start_t for j in reset_indexes(frames, MCB))
        h.check(ok, "the fault of the earlier attempts clears after this NMT start (EMCY 0000h)")
    return f"won at attempt {k + 1}"


def scenario_outputs_atomic(h):
    h.download(0x6200, 1, b"\x00")
    time.sleep(0.3)
    notes = []
    for old, new in ((0x00, 0x05), (0x05, 0x0A)):
        m = h.down.mark()
        t_from = time.time()
        h.download(0x6200, 1, bytes([new]))
        got = h.down.wait(lambda f: f[1] == MCB_RPDO1 and f[2] == bytes([new]), 10.0, m)
        time.sleep(0.7)  # anything that follows the wanted frame
        t_to = time.time()
        frames = [fmt_frame(f) for f in h.down.since(m, is_id(MCB_RPDO1))]
        want = f"{MCB_RPDO1:03X}#{new:02X}"
        h.check(got is not None and frames == [want],
                f"6200h:01 {old:02X}h->{new:02X}h by one SDO download: vcan1 carries {frames}, expected [{want}]")
        h.window(f"6200h:01_{old:02X}h->{new:02X}h", t_from, t_to, [want])
        notes.append(" ".join(frames) or "nothing")
    return "frames: " + "; ".join(notes)


def scenario_heartbeat_never_returns(h):
    # The grip live: joystick 1 follows it.
    f, x = h.follows(30, timeout=30)
    if not h.check(f is not None, f"joystick 1 follows the grip at +30 % (x = {x})"):
        return None
    m = h.up.mark()
    h.grip("x 0")
    h.check(h.wait_x1(lambda x: x == 0, 10, m) is not None, "joystick 1 x back at 0")
    # The heartbeat stops (everything else goes on).
    i0 = h.up.mark()
    d0 = h.down.mark()
    t_off = time.time()
    h.grip("heartbeat off")
    r = h.up.wait(emcy_7000_naming(GRIP), 10, i0)
    h.check(r is not None, "EMCY 7000h naming 11h after the heartbeat stopped"
            + (f" ({fmt_frame(r[1])}, {1000 * (r[1][0] - t_off):.0f} ms after the command)" if r else ""))
    h.check(h.x1() == 0, "joystick 1 x at neutral (6401h:01 = 0)")
    # The gateway resets and restarts the grip: its boot-up still comes, its heartbeat does not.
    r = h.down.wait(lambda f: f[1] == 0x000 and f[2] == bytes([0x01, GRIP]), 10, d0)
    h.check(r is not None, "the gateway restarted the grip (000#0111) after the loss")
    time.sleep(1.0)  # past the consumer time (400 ms) counted from that NMT start
    m = h.up.mark()
    h.grip("x 50")
    ok, desc = h.neutral_for(4.0, m, "grip at +50 %, no heartbeat")
    h.check(ok, desc)
    resets = h.resets_since(GRIP, i0)
    h.check(not resets, "no error reset EMCY for 11h while no heartbeat came"
            + (f": got {[fmt_frame(f) for f in resets]}" if resets else ""))
    hbs = h.down.since(r[0] if r else d0, lambda f: f[1] == 0x700 + GRIP and f[2] != b"\x00")
    h.check(not hbs, f"(simulator) since that NMT start no heartbeat of 11h on vcan1: {[fmt_frame(f) for f in hbs][:3]}")
    # The heartbeat comes back: the fault clears by evidence; the stick (still +50 %) must be seen
    # at 0 before joystick 1 follows again.
    i1 = h.up.mark()
    h.grip("heartbeat on")
    r = h.wait_reset(GRIP, 25, i1)
    h.check(r is not None, "the fault clears after the heartbeat returned (EMCY 0000h)"
            + (f": {fmt_frame(r)}" if r else ": no EMCY 0000h within 25 s"))
    ok, desc = h.neutral_for(1.5, i1, "heartbeat back, stick still at +50 %")
    h.check(ok, desc)
    m = h.up.mark()
    h.grip("x 0")
    time.sleep(0.5)
    f, x = h.follows(30)
    h.check(f is not None, f"after the stick was at 0, joystick 1 follows +30 % again (x = {x})")
    return None


def scenario_pdos_stop(h):
    f, x = h.follows(40)
    if not h.check(f is not None, f"joystick 1 follows the grip at +40 % (x = {x})"):
        return None
    i0 = h.up.mark()
    d0 = h.down.mark()
    h.grip("pdo off")
    time.sleep(0.3)
    # The last TPDO the grip sent (its TPDO #0 180h+11h carries x): the deadline runs from there.
    last = h.down.since(0, lambda f: f[1] in (0x180 + GRIP, 0x280 + GRIP))
    t_last = last[-1][0] if last else time.time()
    # The deadline (3 x the grip's 100 ms cycle) is judged exactly on simulated time
    # (safety_findings_test: ElobauTpdo1HasTheContractsFreshnessDeadline). Here its clock is the
    # grip's own heartbeat (711#05 every 100 ms, another process, never sent in a burst after a
    # stall): at most HEARTBEATS of them between its last PDO and the fault. A stall of the whole
    # TCG guest holds both back alike, where wall time would count it against the gateway; a
    # gateway that misses the deadline fails by the heartbeats it lets pass (one that never
    # notices, by the wait's 10 s).
    heartbeats = 8  # the 3 of the deadline, 5 of margin for the guest's uneven pace
    r = h.wait_x1(lambda x: x == 0, 10.0, i0)
    e = h.up.wait(emcy_7000_naming(GRIP), 10.0, i0)
    dx = (r[1][0] - t_last) if r else None
    de = (e[1][0] - t_last) if e else None

    def beats(t):
        return len(h.down.since(d0, lambda f: f[1] == 0x700 + GRIP and f[2] == b"\x05" and t_last < f[0] < t))

    h.check(r is not None and beats(r[1][0]) <= heartbeats,
            f"joystick 1 x neutral in a TPDO1 within {heartbeats} grip heartbeats of its last PDO"
            + (f" ({beats(r[1][0])}; {1000 * dx:.0f} ms)" if r else ": none within 10 s"))
    h.check(e is not None and beats(e[1][0]) <= heartbeats,
            f"EMCY 7000h naming 11h within {heartbeats} grip heartbeats of its last PDO"
            + (f" ({beats(e[1][0])}; {1000 * de:.0f} ms)" if e else ": none within 10 s"))
    time.sleep(1.0)
    # The simulator's side: heartbeat went on, PDOs did not.
    pdos = h.down.since(d0, lambda f: f[1] in (0x180 + GRIP, 0x280 + GRIP) and f[0] > t_last)
    hbs = h.down.since(d0, lambda f: f[1] == 0x700 + GRIP and f[2] == b"\x05")
    h.check(not pdos and len(hbs) >= 5, f"(simulator) `pdo off`: {len(hbs)} heartbeats 711#05, {len(pdos)} TPDOs")
    h.check(h.x1() == 0, "6401h:01 = 0 while the PDOs are missing")
    # PDOs back with the stick at 0: the fault clears (fresh PDO); then it follows.
    h.grip("x 0")
    i1 = h.up.mark()
    h.grip("pdo on")
    r = h.wait_reset(GRIP, 10, i1)
    h.check(r is not None, "`pdo on` with the stick at 0 clears the fault (EMCY 0000h)"
            + (f": {fmt_frame(r)}" if r else ": none within 10 s"))
    f, x = h.follows(30)
    h.check(f is not None, f"joystick 1 follows +30 % again (x = {x})")
    return (f"x neutral {1000 * dx:.0f} ms, EMCY {1000 * de:.0f} ms after the last PDO"
            if dx is not None and de is not None else None)


def scenario_reboot_deflected(h):
    f, x = h.follows(50)
    if not h.check(f is not None, f"joystick 1 follows the grip at +50 % (x = {x})"):
        return None
    i0 = h.up.mark()
    d0 = h.down.mark()
    h.grip("reboot")
    r = h.down.wait(lambda f: f[1] == 0x700 + GRIP and f[2] == b"\x00", 10, d0)
    h.check(r is not None, "the grip rebooted (711#00)")
    start = h.down.wait(lambda f: f[1] == 0x000 and f[2] == bytes([0x01, GRIP]), 15, r[0] if r else d0)
    h.check(start is not None, "the gateway restarted it (000#0111)")
    pdo = h.down.wait(is_id(0x180 + GRIP), 10, start[0] if start else d0)
    # elobau §4: after power on, a deflected axis is sent as zero until it has been at zero.
    h.check(pdo is not None and pdo[1][2][0] == 0,
            f"(simulator, elobau §4) after power-on the grip sends x = 0 while deflected: "
            f"{fmt_frame(pdo[1]) if pdo else None}")
    # Whether or not the reboot raised a fault, its clearing (if any) must come and x stays 0.
    e = h.up.since(i0, emcy_7000_naming(GRIP))
    if e:
        c = h.wait_reset(GRIP, 10, i0)
        h.check(c is not None, "the reboot's fault clears (EMCY 0000h) once the grip is back")
    ok, desc = h.neutral_for(2.5, i0, "rebooted with the stick at +50 %")
    h.check(ok, desc)
    # A stalled guest may lose the grip again here (no heartbeat within its consumer time): the
    # gateway resets it, and with the stick at +40 % the grip then sends x = 0 until it has been at
    # zero (elobau §4) — rightly neutral. Only then is the step tried again (up to three times);
    # x staying neutral without such a reset is a failure.
    for attempt in range(1, 4):
        d1 = h.down.mark()
        h.grip("x 0")
        time.sleep(0.5)
        f, x = h.follows(40)
        reset = h.down.since(d1, lambda fr: (fr[1] == 0x000 and fr[2][1:2] == bytes([GRIP]))
                             or (fr[1] == 0x700 + GRIP and fr[2] == b"\x00"))
        if f is not None or not reset:
            break
        log(f"attempt {attempt}: the grip was reset meanwhile ({fmt_frame(reset[0])}): the stick again")
    h.check(f is not None, f"once the stick was at 0, joystick 1 follows +40 % (x = {x})")
    return "EMCY 7000h on the reboot: " + ("yes" if e else "no")


def host_heartbeat_round(h, n):
    """The host's heartbeat stops once: EMCY 8130h, then the 6207h error values must reach the
    MCB-402 as one frame (203#06). Returns the delay EMCY 8130h -> that RPDO in ms, or None."""
    i_round = h.up.mark()
    m = h.down.mark()
    # 00h then 09h: 09h goes out whatever the dictionary kept through a previous loss.
    h.download(0x6200, 1, b"\x00")
    h.download(0x6200, 1, b"\x09")
    set09 = h.down.wait(lambda f: f[1] == MCB_RPDO1 and f[2] == b"\x09", 10, m)
    h.check(set09 is not None, f"loss {n}: indicators at 09h (203#09)")
    # candump's window opens with 203#09 (its kernel timestamp), not at the host's last heartbeat:
    # a stalled host thread may send its heartbeat late before hb_on is cleared, and the gateway
    # then (rightly) sends the error values before that "last" heartbeat. 0.5 ms after it, so
    # that 203#09 itself is outside at any rounding (the loss is begun 1.2 s later).
    t_from = (set09[1][0] if set09 else time.time()) + 0.0005
    time.sleep(1.2)
    i0 = h.up.mark()
    d0 = h.down.mark()
    pre = h.up.since(i_round, lambda f: emcy(f) is not None and emcy(f)[0] == 0x8130)
    # An EMCY 8130h the host earned: its heartbeat thread stalled (no heartbeat sent for the
    # consumer time, 500 ms, before the EMCY) — a loaded TCG guest does that; the gateway is right.
    def silent_before(f):  # how long the host had sent no heartbeat when frame f came
        return f[0] - max([t for t in h.hb_sent if t < f[0]], default=0.0)
    earned = [f for f in pre if silent_before(f) >= 0.5]
    if earned:
        log(f"loss {n}: EMCY 8130h after a stall of the host's own heartbeat (none sent for "
            f"{1000 * silent_before(earned[0]):.0f} ms): not counted")
    h.check(len(pre) == len(earned), f"loss {n}: no EMCY 8130h while the host's heartbeat runs")
    h.hb_on.clear()
    time.sleep(0.15)
    t_stop = h.hb_last
    e = h.up.wait(lambda f: emcy(f) is not None and emcy(f)[0] == 0x8130, 10, i0)
    h.check(e is not None, f"loss {n}: EMCY 8130h after the host's heartbeat stopped"
            + (f" ({1000 * (e[1][0] - t_stop):.0f} ms after its last heartbeat; consumer time 500 ms)" if e
               else ": none within 10 s"))
    first = h.down.wait(lambda f: f[1] == MCB_RPDO1, 10, d0)
    time.sleep(1.0)
    t_to = time.time()
    frames = h.down.since(d0, is_id(MCB_RPDO1))
    h.check([f[2] for f in frames] == [b"\x06"],
            f"loss {n}: the error values reach the MCB-402 as one frame: {[fmt_frame(f) for f in frames]}, "
            "expected ['203#06']")
    h.window(f"host_heartbeat_loss_{n}", t_from, t_to, ["203#06"])
    delay = None
    if e and first:
        # A figure, not a timed assertion: "in the same call as the EMCY" is judged on simulated
        # time (safety_outputs_test); a stall of the TCG guest between the two writes would be
        # counted against the gateway by any bound in wall time.
        delay = 1000 * (first[1][0] - e[1][0])
        log(f"loss {n}: EMCY 8130h -> {fmt_frame(first[1])}: {delay:.1f} ms")
    # The host comes back, and starts the gateway again: on the heartbeat-consumer time-out it
    # went pre-operational (1029h:01 = 00h, CiA 301 §7.2.8.3.2.3), as a real host would find it.
    h.hb_on.set()
    time.sleep(0.3)
    m = h.up.mark()
    h.send_up(0x000, [0x01, GW])
    h.check(h.up.wait(lambda f: f[1] == 0x700 + GW and f[2] == b"\x05", 10, m) is not None,
            f"loss {n}: heartbeat back and NMT start: the gateway reports operational (720#05)")
    time.sleep(0.3)
    return delay


def scenario_host_heartbeat(h):
    # The host's heartbeat first, then the gateway's consumer of it (1016h:01 = node 01h, 500 ms).
    h.hb_on.set()
    time.sleep(0.3)
    h.download(0x1016, 1, struct.pack("<I", HOST << 16 | 500))
    # Indicators at 09h, error mode all four bits, error value 06h: every bit changes on the loss.
    h.download(0x6206, 1, b"\x0F")
    h.download(0x6207, 1, b"\x06")
    d = host_heartbeat_round(h, 1)
    return f"EMCY 8130h -> error values: {d:.1f} ms" if d is not None else None


def scenario_host_heartbeat_again(h):
    # After the heartbeat came back, a later loss must act the same (CiA 301: the consumer is
    # active again with the next heartbeat).
    figures = [host_heartbeat_round(h, n) for n in (2, 3)]
    return "EMCY 8130h -> error values: " + ", ".join("none" if d is None else f"{d:.1f} ms" for d in figures)


def main():
    ready, grip_fifo, windows = sys.argv[1:4]
    hostlib.clock_start()
    # Hand the GIL over sooner (default 5 ms): the injector thread must answer within a few ms.
    sys.setswitchinterval(0.0005)
    h = Host(grip_fifo, windows)
    race = BootRace(h)
    touch(ready)
    log("host ready: vcan0 and vcan1 recorded")
    try:
        setup(h)
    except Exception as e:  # noqa: BLE001
        print(f"FAIL: scenario 0 (set-up): {e}", flush=True)
        return 1
    h.scenario(2, "boot race: a pre-operational heartbeat after NMT start is no loss",
               lambda: scenario_boot_race(h, race))
    h.scenario(3, "outputs atomic: 6200h 00h->05h->0Ah", lambda: scenario_outputs_atomic(h))
    h.scenario(1, "heartbeat never returns after a reboot", lambda: scenario_heartbeat_never_returns(h))
    h.scenario(5, "PDOs stop while the heartbeat goes on", lambda: scenario_pdos_stop(h))
    h.scenario(6, "reboot with the stick deflected", lambda: scenario_reboot_deflected(h))
    h.scenario(4, "host heartbeat loss under frame load: error values as one frame",
               lambda: scenario_host_heartbeat(h))
    h.scenario("4b", "host heartbeat lost again after it came back", lambda: scenario_host_heartbeat_again(h))
    failed = sum(1 for ok in h.results if not ok)
    log(f"{len(h.results)} scenarios judged, {failed} failed")
    h.up.stop()
    h.down.stop()
    return failed


if __name__ == "__main__":
    sys.exit(main())
