#!/usr/bin/python3
"""Tests of python_peer.py against a fake CANopen node.

Runs on python3-can's "virtual" interface by default, so it needs no
SocketCAN (the host has none); PEER_TEST_INTERFACE=socketcan
PEER_TEST_CHANNEL=vcan0 runs the same tests on a real vcan in the VM.
"""
import os
import struct
import sys
import threading
import time
import unittest

import can

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import python_peer as pp  # noqa: E402

INTERFACE = os.environ.get("PEER_TEST_INTERFACE", "virtual")
CHANNEL = os.environ.get("PEER_TEST_CHANNEL", "peer-test")
NODE = 0x20


class FakeNode(threading.Thread):
    """A minimal SDO server (expedited + segmented) and heartbeat producer."""

    def __init__(self, od):
        super().__init__(daemon=True)
        self.od = od                      # {(index, sub): bytes}
        self.bus = can.interface.Bus(channel=CHANNEL, interface=INTERFACE)
        self.stop = threading.Event()
        self.seen = []                    # every frame received (id, bytes)
        self.abort_next = None            # abort code to answer the next request with
        self.wrong_toggle = False
        self.silent = False

    def send(self, can_id, data):
        self.bus.send(can.Message(arbitration_id=can_id, is_extended_id=False, data=bytes(data)))

    def run(self):
        up = down = None  # segmented transfer state: [mux, data, toggle]
        while not self.stop.is_set():
            m = self.bus.recv(timeout=0.05)
            if m is None:
                continue
            self.seen.append((m.arbitration_id, bytes(m.data)))
            if m.arbitration_id != 0x600 + NODE or self.silent:
                continue
            d = bytes(m.data)
            cs = d[0] >> 5
            mux = struct.unpack_from("<HB", d, 1)
            if self.abort_next is not None and cs in (1, 2):
                self.send(0x580 + NODE, struct.pack("<BHBI", 0x80, *mux, self.abort_next))
                self.abort_next = None
            elif cs == 4:  # abort from the client
                up = down = None
            elif cs == 2:  # upload initiate
                v = self.od.get(mux)
                if v is None:
                    self.send(0x580 + NODE, struct.pack("<BHBI", 0x80, *mux, 0x06020000))
                elif len(v) <= 4:
                    self.send(0x580 + NODE, struct.pack("<BHB", 0x43 | (4 - len(v)) << 2, *mux) + v.ljust(4, b"\0"))
                else:
                    up = [mux, v, 0]
                    self.send(0x580 + NODE, struct.pack("<BHBI", 0x41, *mux, len(v)))
            elif cs == 3 and up:  # upload segment
                t = (d[0] >> 4) & 1
                if self.wrong_toggle:
                    t ^= 1
                chunk, up[1] = up[1][:7], up[1][7:]
                last = not up[1]
                self.send(0x580 + NODE, bytes([t << 4 | (7 - len(chunk)) << 1 | last]) + chunk.ljust(7, b"\0"))
                if last:
                    up = None
            elif cs == 1:  # download initiate
                if d[0] & 0x02:
                    n = (d[0] >> 2) & 3 if d[0] & 1 else 0
                    self.od[mux] = d[4:8 - n]
                else:
                    down = [mux, b"", 0]
                self.send(0x580 + NODE, struct.pack("<BHB4x", 0x60, *mux))
            elif cs == 0 and down:  # download segment
                t = (d[0] >> 4) & 1
                n = (d[0] >> 1) & 7
                down[1] += d[1:8 - n]
                if d[0] & 1:  # store before answering: the client may look at once
                    self.od[down[0]] = down[1]
                self.send(0x580 + NODE, bytes([0x20 | t << 4]) + bytes(7))
                if d[0] & 1:
                    down = None
        self.bus.shutdown()


class PeerTest(unittest.TestCase):
    def setUp(self):
        self.node = FakeNode({(0x1000, 0): struct.pack("<I", 0x191), (0x1001, 0): b"\x00",
                              (0x1008, 0): b"oegw test device name"})
        self.node.start()
        self.peer = pp.Peer(CHANNEL, 10.0, INTERFACE)  # waits end with the answer; a TCG guest stalls at times

    def tearDown(self):
        self.peer.close()
        self.node.stop.set()
        self.node.join()

    def wait_seen(self, n, timeout=10.0):
        """Let the fake node receive at least n frames, then stop it."""
        deadline = time.monotonic() + timeout
        while len(self.node.seen) < n and time.monotonic() < deadline:
            time.sleep(0.01)
        self.node.stop.set()
        self.node.join()

    def test_expedited_upload(self):
        self.assertEqual(self.peer.sdo_upload(NODE, 0x1000, 0), b"\x91\x01\x00\x00")
        self.assertEqual(self.peer.sdo_upload(NODE, 0x1001, 0), b"\x00")

    def test_segmented_upload(self):
        self.assertEqual(self.peer.sdo_upload(NODE, 0x1008, 0), b"oegw test device name")

    def test_upload_abort(self):
        with self.assertRaises(pp.SdoAbort) as cm:
            self.peer.sdo_upload(NODE, 0x2000, 0)
        self.assertEqual(cm.exception.code, 0x06020000)

    def test_toggle_error_aborts(self):
        self.node.wrong_toggle = True
        with self.assertRaises(pp.PeerError):
            self.peer.sdo_upload(NODE, 0x1008, 0)

    def test_expedited_download(self):
        self.peer.sdo_download(NODE, 0x1017, 0, struct.pack("<H", 1000))
        self.assertEqual(self.node.od[(0x1017, 0)], b"\xe8\x03")
        self.assertIn((0x620, bytes.fromhex("2b171000e8030000")), self.node.seen)

    def test_segmented_download(self):
        data = bytes(range(20))
        self.peer.sdo_download(NODE, 0x2001, 3, data)
        self.assertEqual(self.node.od[(0x2001, 3)], data)
        self.assertEqual(self.peer.sdo_upload(NODE, 0x2001, 3), data)

    def test_download_abort(self):
        self.node.abort_next = 0x06010002
        with self.assertRaises(pp.SdoAbort) as cm:
            self.peer.sdo_download(NODE, 0x1000, 0, b"\x01")
        self.assertEqual(cm.exception.code, 0x06010002)

    def test_timeout_sends_abort(self):
        self.node.silent = True
        self.peer.timeout = 0.2
        with self.assertRaises(pp.Timeout):
            self.peer.sdo_upload(NODE, 0x1000, 0)
        self.wait_seen(2)
        self.assertEqual(self.node.seen[-1], (0x620, bytes.fromhex("8000100000000405")))

    def test_nmt(self):
        self.peer.nmt("start", NODE)
        self.peer.nmt("reset-comm", 0)
        self.wait_seen(2)
        self.assertEqual(self.node.seen, [(0x000, b"\x01\x20"), (0x000, b"\x82\x00")])

    def test_heartbeat(self):
        def beat():
            for s in (0x00, 0x7F, 0x05):
                self.node.send(0x700 + NODE, [s])
        threading.Timer(0.1, beat).start()
        self.assertEqual(self.peer.wait_heartbeat(NODE, 0x05, timeout=10), 0x05)
        with self.assertRaises(pp.Timeout):
            self.peer.wait_heartbeat(NODE, 0x04, timeout=0.2)


if __name__ == "__main__":
    unittest.main(verbosity=2)
