#!/usr/bin/python3
"""A small CANopen peer for the VM test tier, on python3-can's socketcan bus.

It plays the other side of the gateway on a real (v)CAN bus: an SDO client
(expedited and segmented upload/download), an NMT master and a heartbeat
watcher. Written from scratch on python3-can's Bus/Message API (CiA 301
framing); it does not use the `canopen` package.

CLI (numbers may be decimal or 0x-hex):
  python_peer.py [--channel vcan0] [--timeout 2] sdo-read NODE INDEX SUB [--format F]
  python_peer.py [--channel vcan0] [--timeout 2] sdo-write NODE INDEX SUB TYPE VALUE
  python_peer.py [--channel vcan0] nmt start|stop|preop|reset|reset-comm NODE
  python_peer.py [--channel vcan0] wait-heartbeat NODE [--state S] [--timeout 5]

  TYPE is u8 u16 u32 u64 i8 i16 i32 i64 (VALUE an integer), hex (VALUE hex
  bytes, e.g. 0102ab) or str (VALUE text). sdo-read --format is one of
  pretty (default: "0x1000:00 len=4 data=91 01 00 00 uint=401"), hex
  ("91010000"), uint, int (little-endian) or str.
  NMT NODE 0 addresses all nodes.

Exit status:
  0 success; 1 protocol error (bad/unexpected response); 2 usage error;
  3 timeout (no answer in time; an SDO client then sends abort 0x05040000);
  4 SDO abort received (the code is printed); 5 CAN interface error.

As a module (saves the ~3 s python3-can import per call inside the TCG VM):
  from python_peer import Peer
  with Peer("vcan0") as p:
      p.nmt("start", 0x20); data = p.sdo_upload(0x20, 0x1000, 0)
"""
import argparse
import struct
import sys
import time

import can

EXIT_OK, EXIT_PROTOCOL, EXIT_USAGE, EXIT_TIMEOUT, EXIT_ABORT, EXIT_BUS = 0, 1, 2, 3, 4, 5

NMT_COMMANDS = {"start": 0x01, "stop": 0x02, "preop": 0x80, "reset": 0x81, "reset-comm": 0x82}
NMT_STATES = {0x00: "boot-up", 0x04: "stopped", 0x05: "operational", 0x7F: "pre-operational"}
ABORT_TIMEOUT = 0x05040000
ABORT_NAMES = {
    0x05030000: "toggle bit not alternated",
    0x05040000: "SDO protocol timed out",
    0x05040001: "client/server command specifier not valid or unknown",
    0x06010000: "unsupported access to an object",
    0x06010001: "attempt to read a write only object",
    0x06010002: "attempt to write a read only object",
    0x06020000: "object does not exist in the object dictionary",
    0x06040041: "object cannot be mapped to the PDO",
    0x06070010: "data type does not match, length of service parameter does not match",
    0x06070012: "data type does not match, length of service parameter too high",
    0x06070013: "data type does not match, length of service parameter too low",
    0x06060000: "access failed due to a hardware error",
    0x06090011: "sub-index does not exist",
    0x06090030: "invalid value for parameter",
    0x06090031: "value of parameter written too high",
    0x06090032: "value of parameter written too low",
    0x060A0023: "resource not available: SDO connection",
    0x08000000: "general error",
    0x08000020: "data cannot be transferred or stored to the application",
    0x08000021: "data cannot be transferred because of local control",
    0x08000022: "data cannot be transferred because of the present device state",
}
INT_TYPES = {"u8": "<B", "u16": "<H", "u32": "<I", "u64": "<Q",
             "i8": "<b", "i16": "<h", "i32": "<i", "i64": "<q"}


class PeerError(Exception):
    exit_code = EXIT_PROTOCOL


class Timeout(PeerError):
    exit_code = EXIT_TIMEOUT


class SdoAbort(PeerError):
    exit_code = EXIT_ABORT

    def __init__(self, index, sub, code):
        self.index, self.sub, self.code = index, sub, code
        super().__init__(f"SDO abort 0x{index:04X}:{sub:02X} code 0x{code:08X} "
                         f"({ABORT_NAMES.get(code, 'unknown abort code')})")


class Peer:
    """One socketcan bus; every request filters the answers it waits for."""

    def __init__(self, channel="vcan0", timeout=2.0, interface="socketcan"):
        self.channel, self.timeout = channel, timeout
        # No kernel filters: the ids waited for vary per request, recv_id
        # skips the rest. interface="virtual" runs it without SocketCAN.
        self.bus = can.interface.Bus(channel=channel, interface=interface)

    def close(self):
        self.bus.shutdown()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # --- frames ---------------------------------------------------------------
    def send(self, can_id, data):
        self.bus.send(can.Message(arbitration_id=can_id, is_extended_id=False, data=bytes(data)))

    def drain(self):
        while self.bus.recv(timeout=0) is not None:
            pass

    def recv_id(self, can_id, timeout, what):
        """Next data frame with this standard id, or Timeout."""
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise Timeout(f"timeout after {timeout:g}s waiting for {what} (id 0x{can_id:03X})")
            msg = self.bus.recv(timeout=left)
            if msg is None:
                continue
            if (msg.arbitration_id == can_id and not msg.is_extended_id
                    and not msg.is_remote_frame and not msg.is_error_frame):
                return msg

    # --- NMT --------------------------------------------------------------------
    def nmt(self, command, node):
        cs = NMT_COMMANDS[command] if isinstance(command, str) else command
        check_node(node, allow_broadcast=True)
        self.send(0x000, [cs, node])

    # --- heartbeat --------------------------------------------------------------
    def wait_heartbeat(self, node, state=None, timeout=5.0):
        """Wait for a heartbeat (or boot-up) of node, in state if given; returns the state."""
        check_node(node)
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            what = f"heartbeat of node 0x{node:02X}" + ("" if state is None else f" in state 0x{state:02X}")
            msg = self.recv_id(0x700 + node, max(left, 0), what)
            if len(msg.data) != 1:
                continue
            got = msg.data[0] & 0x7F
            if state is None or got == state:
                return got

    # --- SDO client -------------------------------------------------------------
    # The SDO channel of a request: the server's default one (600h/580h + node-ID, CiA 301
    # §7.3.5), or an explicit (client->server, server->client) COB-ID pair: an additional SDO
    # server channel (1201h..).
    @staticmethod
    def _cobs(node, cobs):
        return cobs if cobs is not None else (0x600 + node, 0x580 + node)

    def _sdo_request(self, node, frame, index, sub, what, cobs=None):
        req, resp = self._cobs(node, cobs)
        self.send(req, frame)
        try:
            msg = self.recv_id(resp, self.timeout, what)
        except Timeout:
            self.sdo_abort(node, index, sub, ABORT_TIMEOUT, cobs)
            raise
        d = bytes(msg.data).ljust(8, b"\0")
        if d[0] == 0x80:
            aidx, asub, code = struct.unpack_from("<HBI", d, 1)
            raise SdoAbort(aidx, asub, code)
        return d

    def sdo_abort(self, node, index, sub, code, cobs=None):
        self.send(self._cobs(node, cobs)[0], struct.pack("<BHBI", 0x80, index, sub, code))

    def network_indication(self, node, network, target, cobs=None):
        """SDO network indication (ccs 7) to the server `node`: from now on its channel's
        requests go to node `target` of `network` (the layout oegw decided:
        canopen/301/sdo_remote.hpp). Returns the answer's 8 bytes; SdoAbort if refused."""
        check_node(node)
        self.drain()
        frame = bytes([0xE0, 0, 0, 0, network, target, 0, 0])
        d = self._sdo_request(node, frame, 0, 0, f"network indication answer from node 0x{node:02X}", cobs)
        if d != frame:
            raise PeerError(f"network indication answered {d.hex()}, expected {frame.hex()}")
        return d

    def _check_mux(self, d, node, index, sub, cobs=None):
        ridx, rsub = struct.unpack_from("<HB", d, 1)
        if (ridx, rsub) != (index, sub):
            self.sdo_abort(node, index, sub, 0x08000000, cobs)
            raise PeerError(f"SDO response for 0x{ridx:04X}:{rsub:02X}, expected 0x{index:04X}:{sub:02X}")

    def sdo_upload(self, node, index, sub, cobs=None):
        """Read an object (expedited or segmented); returns its bytes."""
        check_node(node)
        self.drain()
        what = f"SDO upload response 0x{index:04X}:{sub:02X} from node 0x{node:02X}"
        d = self._sdo_request(node, struct.pack("<BHB4x", 0x40, index, sub), index, sub, what, cobs)
        if d[0] & 0xE0 != 0x40:
            self.sdo_abort(node, index, sub, 0x05040001, cobs)
            raise PeerError(f"unexpected SDO response {d.hex()} to upload initiate")
        self._check_mux(d, node, index, sub, cobs)
        e, s = d[0] & 0x02, d[0] & 0x01
        if e:
            n = (d[0] >> 2) & 0x03 if s else 0
            return d[4:8 - n]
        size = struct.unpack_from("<I", d, 4)[0] if s else None
        data, toggle = bytearray(), 0
        while True:
            seg = self._sdo_request(node, bytes([0x60 | toggle << 4]) + bytes(7), index, sub,
                                    what.replace("upload response", "upload segment"), cobs)
            if seg[0] & 0xE0 != 0x00:
                self.sdo_abort(node, index, sub, 0x05040001, cobs)
                raise PeerError(f"unexpected SDO response {seg.hex()} to upload segment")
            if (seg[0] >> 4) & 1 != toggle:
                self.sdo_abort(node, index, sub, 0x05030000, cobs)
                raise PeerError("SDO upload segment toggle bit not alternated")
            n = (seg[0] >> 1) & 0x07
            data += seg[1:8 - n]
            if seg[0] & 0x01:
                break
            toggle ^= 1
        if size is not None and size != len(data):
            raise PeerError(f"SDO upload: size indicated {size}, received {len(data)}")
        return bytes(data)

    def sdo_download(self, node, index, sub, data, cobs=None):
        """Write an object: expedited up to 4 bytes, segmented beyond."""
        check_node(node)
        self.drain()
        data = bytes(data)
        what = f"SDO download response 0x{index:04X}:{sub:02X} from node 0x{node:02X}"
        if 0 < len(data) <= 4:
            cmd = 0x23 | (4 - len(data)) << 2
            frame = struct.pack("<BHB", cmd, index, sub) + data.ljust(4, b"\0")
        else:
            frame = struct.pack("<BHBI", 0x21, index, sub, len(data))
        d = self._sdo_request(node, frame, index, sub, what, cobs)
        if d[0] != 0x60:
            self.sdo_abort(node, index, sub, 0x05040001, cobs)
            raise PeerError(f"unexpected SDO response {d.hex()} to download initiate")
        self._check_mux(d, node, index, sub, cobs)
        if 0 < len(data) <= 4:
            return
        toggle, pos = 0, 0
        while True:
            chunk = data[pos:pos + 7]
            pos += len(chunk)
            last = pos >= len(data)
            cmd = toggle << 4 | (7 - len(chunk)) << 1 | (1 if last else 0)
            seg = self._sdo_request(node, bytes([cmd]) + chunk.ljust(7, b"\0"), index, sub,
                                    what.replace("download response", "download segment response"), cobs)
            if seg[0] & 0xE0 != 0x20:
                self.sdo_abort(node, index, sub, 0x05040001, cobs)
                raise PeerError(f"unexpected SDO response {seg.hex()} to download segment")
            if (seg[0] >> 4) & 1 != toggle:
                self.sdo_abort(node, index, sub, 0x05030000, cobs)
                raise PeerError("SDO download segment response toggle bit not alternated")
            if last:
                return
            toggle ^= 1


def check_node(node, allow_broadcast=False):
    if not (1 <= node <= 127 or (allow_broadcast and node == 0)):
        raise ValueError(f"node id {node} out of range 1..127" + (" (0 = all)" if allow_broadcast else ""))


def encode(type_, value):
    if type_ in INT_TYPES:
        try:
            return struct.pack(INT_TYPES[type_], int(value, 0))
        except struct.error as e:
            raise ValueError(f"{value} does not fit {type_}: {e}") from None
    if type_ == "hex":
        return bytes.fromhex(value)
    if type_ == "str":
        return value.encode()
    raise ValueError(f"unknown type {type_}")


def fmt(data, form, index, sub):
    u = int.from_bytes(data, "little") if data else 0
    if form == "hex":
        return data.hex()
    if form == "uint":
        return str(u)
    if form == "int":
        return str(int.from_bytes(data, "little", signed=True) if data else 0)
    if form == "str":
        return data.decode(errors="replace")
    return f"0x{index:04X}:{sub:02X} len={len(data)} data={data.hex(' ')} uint={u}"


def anyint(s):
    return int(s, 0)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--channel", default="vcan0")
    ap.add_argument("--interface", default="socketcan", help=argparse.SUPPRESS)
    ap.add_argument("--timeout", type=float, default=None,
                    help="SDO response timeout (default 2 s) / heartbeat wait (default 5 s)")
    sub = ap.add_subparsers(dest="cmd", required=True)
    p = sub.add_parser("sdo-read", help="SDO upload")
    p.add_argument("node", type=anyint)
    p.add_argument("index", type=anyint)
    p.add_argument("subindex", type=anyint)
    p.add_argument("--format", choices=["pretty", "hex", "uint", "int", "str"], default="pretty")
    p.add_argument("--timeout", type=float, default=None, dest="sub_timeout")
    p = sub.add_parser("sdo-write", help="SDO download")
    p.add_argument("node", type=anyint)
    p.add_argument("index", type=anyint)
    p.add_argument("subindex", type=anyint)
    p.add_argument("type", choices=sorted(INT_TYPES) + ["hex", "str"])
    p.add_argument("value")
    p.add_argument("--timeout", type=float, default=None, dest="sub_timeout")
    p = sub.add_parser("nmt", help="send an NMT command")
    p.add_argument("command", choices=list(NMT_COMMANDS))
    p.add_argument("node", type=anyint)
    p = sub.add_parser("wait-heartbeat", help="wait for a heartbeat (optionally in a state)")
    p.add_argument("node", type=anyint)
    p.add_argument("--state", type=anyint, default=None)
    p.add_argument("--timeout", type=float, default=None, dest="sub_timeout")
    a = ap.parse_args(argv)
    timeout = getattr(a, "sub_timeout", None) or a.timeout

    try:
        if a.cmd == "sdo-write":
            data = encode(a.type, a.value)
        peer = Peer(a.channel, timeout or 2.0, a.interface)
    except ValueError as e:
        print(f"python_peer: {e}", file=sys.stderr)
        return EXIT_USAGE
    except (OSError, can.CanError) as e:
        print(f"python_peer: cannot open {a.channel}: {e}", file=sys.stderr)
        return EXIT_BUS
    try:
        with peer:
            if a.cmd == "sdo-read":
                print(fmt(peer.sdo_upload(a.node, a.index, a.subindex), a.format, a.index, a.subindex))
            elif a.cmd == "sdo-write":
                peer.sdo_download(a.node, a.index, a.subindex, data)
                print(f"0x{a.index:04X}:{a.subindex:02X} written ({len(data)} bytes)")
            elif a.cmd == "nmt":
                peer.nmt(a.command, a.node)
                print(f"nmt {a.command} 0x{a.node:02X} sent")
            elif a.cmd == "wait-heartbeat":
                st = peer.wait_heartbeat(a.node, a.state, timeout or 5.0)
                print(f"node 0x{a.node:02X} state 0x{st:02X} ({NMT_STATES.get(st, 'unknown')})")
    except PeerError as e:
        print(f"python_peer: {e}", file=sys.stderr)
        return e.exit_code
    except ValueError as e:
        print(f"python_peer: {e}", file=sys.stderr)
        return EXIT_USAGE
    except (OSError, can.CanError) as e:
        print(f"python_peer: CAN error: {e}", file=sys.stderr)
        return EXIT_BUS
    return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
