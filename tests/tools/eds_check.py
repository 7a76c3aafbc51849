#!/usr/bin/python3
"""Independent check of EDS files (CiA 306) with Python's configparser.

  eds_check.py FILE...            checks every file; exit 0 if all are well-formed, 1 otherwise
  eds_check.py --summary FILE     prints one line per sub-object, in the format eds_test.cpp
                                  compares with the C++ reader (canopen/306/eds_reader.cpp):
                                  IIII:SS TTTT access pdo default

The checks mirror CiA 306 §4.5/§4.6 as canopen/306/eds_reader.hpp describes them, written separately:
strict INI (no duplicate sections or keys), [MandatoryObjects] present, SupportedObjects=n with
entries 1..n, one section per listed object, ParameterName everywhere, ObjectType 7/8/9,
DataType a CiA 301 static type, AccessType ro/wo/rw/rwr/rww/const, PDOMapping 0/1, SubNumber
equal to the number of [IIIIsubN] sections (with sub0), numeric defaults that fit their type.
"""
import configparser
import re
import sys

TYPES = {  # CiA 301 Table 44: index -> (bits, signed) ; 0 bits = variable size / real
    0x0001: (1, False), 0x0002: (8, True), 0x0003: (16, True), 0x0004: (32, True),
    0x0005: (8, False), 0x0006: (16, False), 0x0007: (32, False), 0x0008: (0, None),
    0x0009: (0, None), 0x000A: (0, None), 0x000B: (0, None), 0x000C: (0, None),
    0x000D: (0, None), 0x000F: (0, None), 0x0010: (24, True), 0x0011: (0, None),
    0x0012: (40, True), 0x0013: (48, True), 0x0014: (56, True), 0x0015: (64, True),
    0x0016: (24, False), 0x0018: (40, False), 0x0019: (48, False), 0x001A: (56, False),
    0x001B: (64, False),
}
ACCESS = {"ro", "wo", "rw", "rwr", "rww", "const"}
LISTS = ("MandatoryObjects", "OptionalObjects", "ManufacturerObjects")


def number(text):
    """CiA 306 §4.5.3 integer: decimal, 0x hex, leading-0 octal, optional sign."""
    t = text.strip()
    sign = 1
    if t[:1] in "+-" and t:
        sign = -1 if t[0] == "-" else 1
        t = t[1:]
    if re.fullmatch(r"0[xX][0-9a-fA-F]+", t):
        return sign * int(t[2:], 16)
    if re.fullmatch(r"0[0-7]+", t):
        return sign * int(t[1:], 8)
    if re.fullmatch(r"[0-9]+", t):
        return sign * int(t, 10)
    raise ValueError("not a number: %r" % text)


def value(text):
    """Returns (number, node_relative) for '$NODEID+0x180', '0x180+$NODEID', '12'."""
    t = text.strip()
    m = re.fullmatch(r"\$NODEID\s*(?:\+\s*(.+))?", t, re.IGNORECASE) or \
        re.fullmatch(r"(.+?)\s*\+\s*\$NODEID", t, re.IGNORECASE)
    if m:
        rest = m.group(1)
        return (number(rest) if rest else 0), True
    return number(t), False


def signed_hex(text, v, bits, signed):
    """A signed type's value written in hex is its two's complement: 0x8000 = -32768 (INTEGER16)."""
    if signed and bits < 64 and "0x" in text.lower() and "-" not in text and (1 << (bits - 1)) <= v < (1 << bits):
        return v - (1 << bits)
    return v


def load(path):
    cp = configparser.ConfigParser(strict=True, interpolation=None, comment_prefixes=(";", "#"),
                                   inline_comment_prefixes=None, empty_lines_in_values=False)
    cp.optionxform = str.lower
    with open(path, encoding="latin-1") as f:
        cp.read_file(f, source=path)
    return cp


def section(cp, name):
    for s in cp.sections():
        if s.upper() == name.upper():
            return cp[s]
    return None


def entries(cp, path):
    """Yields (index, sub, section) for every sub-object of every listed object; raises on error."""
    if section(cp, "MandatoryObjects") is None:
        raise ValueError("%s: no [MandatoryObjects]" % path)
    seen = set()
    for lst in LISTS:
        sec = section(cp, lst)
        if sec is None:
            continue
        n = number(sec["supportedobjects"])
        keys = {k for k in sec.keys() if k != "supportedobjects"}
        if keys != {str(i) for i in range(1, n + 1)}:
            raise ValueError("%s: [%s] entries %s do not match SupportedObjects=%d" % (path, lst, sorted(keys), n))
        for i in range(1, n + 1):
            index = number(sec[str(i)])
            if index in seen:
                raise ValueError("%s: object %04X listed twice" % (path, index))
            seen.add(index)
            obj = section(cp, "%04X" % index)
            if obj is None:
                raise ValueError("%s: no section [%04X]" % (path, index))
            if not obj.get("parametername"):
                raise ValueError("%s: [%04X] has no ParameterName" % (path, index))
            ot = number(obj.get("objecttype", "7"))
            if ot == 7:
                yield index, 0, obj
                continue
            if ot not in (8, 9):
                raise ValueError("%s: [%04X] ObjectType %d" % (path, index, ot))
            subs = []
            for s in cp.sections():
                m = re.fullmatch(r"([0-9A-Fa-f]{1,4})sub([0-9A-Fa-f]{1,2})", s, re.IGNORECASE)
                if m and int(m.group(1), 16) == index:
                    subs.append((int(m.group(2), 16), cp[s]))
            subs.sort(key=lambda x: x[0])
            if len(subs) != number(obj["subnumber"]):
                raise ValueError("%s: [%04X] SubNumber=%s but %d sub sections" % (path, index, obj["subnumber"], len(subs)))
            if not subs or subs[0][0] != 0:
                raise ValueError("%s: [%04X] has no sub0" % (path, index))
            for sub, sec2 in subs:
                yield index, sub, sec2


def check_entry(path, index, sub, sec):
    where = "%s: [%04X] sub %d" % (path, index, sub)
    if not sec.get("parametername"):
        raise ValueError(where + ": no ParameterName")
    dt = number(sec["datatype"])
    if dt not in TYPES:
        raise ValueError(where + ": unknown DataType %04X" % dt)
    acc = sec["accesstype"].strip().lower()
    if acc not in ACCESS:
        raise ValueError(where + ": AccessType %r" % acc)
    pdo = number(sec.get("pdomapping", "0"))
    if pdo not in (0, 1):
        raise ValueError(where + ": PDOMapping %d" % pdo)
    bits, signed = TYPES[dt]
    default = sec.get("defaultvalue", None)
    if default is not None and default.strip() != "" and bits:
        v, _ = value(default)
        v = signed_hex(default, v, bits, signed)
        lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
        if not lo <= v <= hi:
            raise ValueError(where + ": DefaultValue %s does not fit" % default)
    return dt, acc, pdo, default


def summary_line(index, sub, dt, acc, pdo, default):
    bits, _ = TYPES[dt]
    if default is None or (bits and default.strip() == ""):
        shown = "-"
    elif bits:
        v, rel = value(default)
        v = signed_hex(default, v, bits, TYPES[dt][1])
        shown = ("$NODEID+" if rel else "") + str(v)
    else:
        shown = "'" + default.strip() + "'"
    return "%04X:%02X %04X %s %d %s" % (index, sub, dt, acc, pdo, shown)


def main(argv):
    if len(argv) == 3 and argv[1] == "--summary":
        cp = load(argv[2])
        for index, sub, sec in entries(cp, argv[2]):
            print(summary_line(index, sub, *check_entry(argv[2], index, sub, sec)))
        return 0
    if len(argv) < 2:
        print(__doc__)
        return 2
    bad = 0
    for path in argv[1:]:
        try:
            cp = load(path)
            count = 0
            for index, sub, sec in entries(cp, path):
                check_entry(path, index, sub, sec)
                count += 1
            print("%s: ok (%d sub-objects)" % (path, count))
        except (configparser.Error, ValueError, KeyError, OSError) as e:
            print("%s: FAILED: %s" % (path, e))
            bad += 1
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
