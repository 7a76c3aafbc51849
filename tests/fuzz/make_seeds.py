#!/usr/bin/env python3
"""Writes the seed corpora of the frame fuzzers (tests/fuzz/*_fuzz.cpp) into OUT/<target>/: each
seed is a complete SDO conversation (expedited, segmented and block, download and upload, with
the CRC and the ends a mutation alone would almost never produce), so that the fuzzer starts at
the ends of every transfer type and mutates from there. The frames are CiA 301 §7.2.4.3 as a
client sends them; CRC-16 is CiA 301's (polynomial 1021h, initial 0, the XMODEM variant).

Usage: make_seeds.py OUT    (the mapping and EDS fuzzers take config/, tests/fixtures/ and
subdevices/eds/ as their seeds directly)
"""
import os
import struct
import sys


def crc16(data):
    crc = 0
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def pad(b):
    return bytes(b) + bytes(8 - len(b))


def head(cmd, index, sub, payload=b""):
    return pad(bytes([cmd]) + struct.pack("<HB", index, sub) + payload)


def segmented_download(index, sub, data):
    frames = [head(0x21, index, sub, struct.pack("<I", len(data)))]
    toggle = 0
    for i in range(0, len(data), 7):
        part = data[i:i + 7]
        last = i + 7 >= len(data)
        frames.append(pad(bytes([toggle | ((7 - len(part)) << 1) | (1 if last else 0)]) + part))
        toggle ^= 0x10
    return frames


def segmented_upload(index, sub, segments):
    frames = [head(0x40, index, sub)]
    toggle = 0
    for _ in range(segments):
        frames.append(pad([0x60 | toggle]))
        toggle ^= 0x10
    return frames


def block_download(index, sub, data):
    frames = [head(0xC6, index, sub, struct.pack("<I", len(data)))]  # CRC supported, size given
    seq = 0
    for i in range(0, len(data), 7):
        seq += 1
        part = data[i:i + 7]
        last = i + 7 >= len(data)
        frames.append(pad(bytes([(0x80 if last else 0) | seq]) + part))
    unused = (7 - len(data) % 7) % 7
    frames.append(pad(bytes([0xC1 | (unused << 2)]) + struct.pack("<H", crc16(data))))
    return frames


def block_upload(index, sub, segments):
    frames = [head(0xA4, index, sub, bytes([127, 0]))]  # CRC supported, 127 per block, no switch
    frames.append(pad([0xA3]))                          # start
    frames.append(pad([0xA2, segments, 127]))           # every segment acknowledged
    frames.append(pad([0xA1]))                          # end confirmed
    return frames


def sdo_server_chunks(frames):
    # sdo_server_fuzz: byte 0 = DLC 8 with time step 0 (8 % 9 == 8, 8 // 9 == 0), then the data.
    return b"".join(bytes([8]) + f for f in frames)


def oe_device_chunks(frames, selector, step=0):
    # oe_device_fuzz: selector (index into its COB-IDs), time step, DLC, data.
    return b"".join(bytes([selector, step, 8]) + f for f in frames)


def write(out, target, name, blob):
    d = os.path.join(out, target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(blob)


def main():
    out = sys.argv[1]
    ten = bytes(range(1, 11))
    # sdo_server_fuzz's dictionary: 2100h DOMAIN (<= 300), 2101h string (<= 10), 1008h name (12).
    s = "sdo_server_fuzz"
    write(out, s, "expedited", sdo_server_chunks([head(0x23, 0x2002, 0, b"\x01\x02\x03\x04"), head(0x40, 0x2001, 0)]))
    write(out, s, "segmented_download", sdo_server_chunks(segmented_download(0x2100, 0, ten)))
    write(out, s, "segmented_upload", sdo_server_chunks(segmented_upload(0x1008, 0, 2)))
    write(out, s, "block_download", sdo_server_chunks(block_download(0x2100, 0, bytes(range(40)))))
    write(out, s, "block_download_string", sdo_server_chunks(block_download(0x2101, 0, ten)))
    write(out, s, "block_upload", sdo_server_chunks(block_upload(0x1008, 0, 2)))
    # oe_device_fuzz: selector 0 = NMT, 3 = SDO request (600h + node), 5 = a host heartbeat,
    # 9.. = the RPDOs.
    o = "oe_device_fuzz"
    nmt_start = oe_device_chunks([pad([0x01, 0x00])], 0)
    write(out, o, "segmented_upload_name", oe_device_chunks(segmented_upload(0x1008, 0, 4), 3))
    write(out, o, "block_upload_name", oe_device_chunks(block_upload(0x1008, 0, 4), 3))
    write(out, o, "segmented_download_heartbeat", oe_device_chunks(segmented_download(0x1017, 0, b"\x64\x00"), 3))
    write(out, o, "block_download_heartbeat", oe_device_chunks(block_download(0x1017, 0, b"\x64\x00"), 3))
    # Every RPDO is disabled by default (CiA 852 Table 10): enable 1400h.. 1427h on 300h + n.
    enable = [head(0x23, 0x1400 + k, 1, struct.pack("<I", 0x300 + k)) for k in range(40)]
    write(out, o, "operational_rpdos",
          oe_device_chunks(enable, 3) + nmt_start + oe_device_chunks([pad([0x05])], 5, 10) + b"".join(
              oe_device_chunks([bytes([0xFF] * 8)], sel, 5) for sel in range(9, 49)))
    write(out, o, "host_lost", nmt_start + oe_device_chunks([pad([0x05])], 5, 10) + oe_device_chunks([pad([0x05])], 6, 60))

    # network_manager_fuzz: per node (selector 0..3) its boot-up, answers to the boot's SDO
    # requests, heartbeats in operational, an EMCY and each TPDO.
    n = "network_manager_fuzz"

    def nm(node, kind, step, payload, dlc=8):
        return bytes([node, kind, step, dlc]) + pad(payload)

    # Byte 4 below 80h: the fuzzer answers the master's last request itself (see its header).
    for node in range(4):
        blob = nm(node, 0, 0, [0x00], 1)  # boot-up: one byte (CiA 301 §7.2.8.3.2)
        for _ in range(40):
            blob += nm(node, 1, 0, [0x00, 0x00, 0x01, 0x00, 0x00, 0x00])  # answers, identity as expected
        blob += nm(node, 0, 5, [0x05], 1) + nm(node, 0, 10, [0x05], 1)
        blob += nm(node, 2, 1, [0x00, 0x81, 0x11]) + nm(node, 2, 1, [0x00, 0x00, 0x00])
        for tpdo in range(4):
            blob += nm(node, 3 + tpdo, 2, [0x10, 0x20, 0x30, 0x40, 0x50, 0x60, 0x70, 0x80])
        blob += nm(node, 0, 50, [0x05], 1)
        write(out, n, "boot_%d" % node, blob)


if __name__ == "__main__":
    main()
