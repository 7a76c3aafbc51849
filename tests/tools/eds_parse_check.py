#!/usr/bin/python3
"""Parses an EDS (CiA 306) with python3's configparser (strict=True) and checks its structure.

  eds_parse_check.py FILE.eds
  eds_parse_check.py --generate EXE   run EXE --gtest_filter=EdsFile.* with OEGW_EDS_OUT set to a
                                      temporary file (eds_writer_test writes the full device's
                                      EDS there), then check that file

Checks: no duplicate sections or keys (strict), the mandatory sections exist, every object named in
[MandatoryObjects]/[OptionalObjects]/[ManufacturerObjects] has a section, SupportedObjects matches
the list, each ARRAY/RECORD's SubNumber equals the number of its [xxxxsubN] sections, every
DataType is a CiA 301 static type, ObjectType/AccessType/PDOMapping are valid, NrOfRXPDO/NrOfTXPDO
match the PDO objects. Exit 0 when all pass, 1 with every problem printed otherwise.
"""
import configparser
import os
import re
import subprocess
import sys
import tempfile

KNOWN_TYPES = {0x0001, 0x0002, 0x0003, 0x0004, 0x0005, 0x0006, 0x0007, 0x0008, 0x0009, 0x000A,
               0x000B, 0x000C, 0x000D, 0x000F, 0x0010, 0x0011, 0x0012, 0x0013, 0x0014, 0x0015,
               0x0016, 0x0018, 0x0019, 0x001A, 0x001B}
ACCESS = {"ro", "wo", "rw", "rwr", "rww", "const"}


def num(text):
    text = text.strip()
    return int(text, 16) if text.lower().startswith("0x") else int(text)


def check(path):
    problems = []
    cp = configparser.ConfigParser(strict=True, interpolation=None)
    cp.optionxform = str  # keep key case
    try:
        with open(path, encoding="ascii") as f:
            cp.read_file(f)
    except (configparser.Error, UnicodeDecodeError) as e:
        return [f"{path}: not parseable: {e}"]

    for s in ("FileInfo", "DeviceInfo", "DummyUsage", "MandatoryObjects", "OptionalObjects"):
        if not cp.has_section(s):
            problems.append(f"missing section [{s}]")

    listed = []
    for s in ("MandatoryObjects", "OptionalObjects", "ManufacturerObjects"):
        if not cp.has_section(s):
            continue
        n = num(cp[s].get("SupportedObjects", "-1"))
        entries = [k for k in cp[s] if k != "SupportedObjects"]
        if n != len(entries):
            problems.append(f"[{s}] SupportedObjects={n} but {len(entries)} entries")
        for i in range(1, n + 1):
            if str(i) not in cp[s]:
                problems.append(f"[{s}] entry {i} missing")
                continue
            listed.append(num(cp[s][str(i)]))
    if len(listed) != len(set(listed)):
        problems.append("an object is listed twice")

    sub_re = re.compile(r"^([0-9A-F]{4})sub([0-9A-F]{1,2})$")
    subs = {}
    for sec in cp.sections():
        m = sub_re.match(sec)
        if m:
            subs.setdefault(int(m.group(1), 16), []).append(int(m.group(2), 16))

    def check_entry(sec):
        e = cp[sec]
        for key in ("ParameterName", "DataType", "AccessType", "PDOMapping"):
            if key not in e:
                problems.append(f"[{sec}] has no {key}")
        if "DataType" in e and num(e["DataType"]) not in KNOWN_TYPES:
            problems.append(f"[{sec}] unknown DataType {e['DataType']}")
        if e.get("AccessType") not in ACCESS:
            problems.append(f"[{sec}] bad AccessType {e.get('AccessType')}")
        if e.get("PDOMapping") not in ("0", "1"):
            problems.append(f"[{sec}] bad PDOMapping {e.get('PDOMapping')}")
        dv = e.get("DefaultValue")
        if dv is not None and dv.startswith("$NODEID"):
            if not re.fullmatch(r"\$NODEID\+0x[0-9A-F]+", dv):
                problems.append(f"[{sec}] bad node-relative DefaultValue {dv}")

    for index in listed:
        sec = f"{index:04X}"
        if not cp.has_section(sec):
            problems.append(f"object {sec} listed but has no section")
            continue
        ot = num(cp[sec].get("ObjectType", "0x7"))
        if ot == 0x7:
            check_entry(sec)
            if index in subs:
                problems.append(f"VAR {sec} has sub-object sections")
        elif ot in (0x8, 0x9):
            n = num(cp[sec].get("SubNumber", "-1"))
            have = sorted(subs.get(index, []))
            if n != len(have):
                problems.append(f"[{sec}] SubNumber={n} but {len(have)} sub-sections")
            if 0 not in have:
                problems.append(f"[{sec}] has no sub-index 0")
            for s in have:
                check_entry(f"{sec}sub{s:X}")
        else:
            problems.append(f"[{sec}] bad ObjectType {ot:#x}")

    # Every object section is listed.
    for sec in cp.sections():
        if re.fullmatch(r"[0-9A-F]{4}", sec) and int(sec, 16) not in listed:
            problems.append(f"section [{sec}] is in no object list")

    # CiA 306 [Comments]: Lines=n and exactly Line1..Linen.
    if cp.has_section("Comments"):
        c = cp["Comments"]
        n = num(c.get("Lines", "-1"))
        keys = sorted(k for k in c if k != "Lines")
        if keys != sorted(f"Line{i}" for i in range(1, n + 1)):
            problems.append(f"[Comments] Lines={n} but keys {keys}")

    if cp.has_section("DeviceInfo"):
        d = cp["DeviceInfo"]
        rx = sum(1 for i in listed if 0x1400 <= i <= 0x15FF)
        tx = sum(1 for i in listed if 0x1800 <= i <= 0x19FF)
        if num(d.get("NrOfRXPDO", "-1")) != rx:
            problems.append(f"NrOfRXPDO={d.get('NrOfRXPDO')} but {rx} RPDOs")
        if num(d.get("NrOfTXPDO", "-1")) != tx:
            problems.append(f"NrOfTXPDO={d.get('NrOfTXPDO')} but {tx} TPDOs")
        for key in ("VendorNumber", "ProductNumber", "LSS_Supported"):
            if key not in d:
                problems.append(f"[DeviceInfo] has no {key}")
    if not problems:
        print(f"{path}: {len(listed)} objects, {sum(len(v) for v in subs.values())} sub-objects: OK")
    return problems


def main(argv):
    if len(argv) == 3 and argv[1] == "--generate":
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "oegw.eds")
            env = dict(os.environ, OEGW_EDS_OUT=path)
            r = subprocess.run([argv[2], "--gtest_filter=EdsFile.*"], env=env, stdout=subprocess.DEVNULL)
            if r.returncode != 0 or not os.path.exists(path):
                print(f"{argv[2]} did not write the EDS (exit {r.returncode})")
                return 1
            problems = check(path)
    elif len(argv) == 2:
        problems = check(argv[1])
    else:
        print(__doc__)
        return 2
    for p in problems:
        print(p)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
