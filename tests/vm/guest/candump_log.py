"""The candump -L files the guest scripts record (start_candump in lib.sh), read once for the
python checks that judge them (abuse_check.py, reload_check.py, sdo_pacing.py).

read_frames(path): [(time_s, iface, can_id, data)] for every line "(SECONDS.MICROS) IFACE ID#DATA"
in file order: time_s the kernel's receive time (CLOCK_REALTIME) as a float, can_id an int,
data the payload's hex digits in upper case ("R..." for a remote frame). Other lines (candump's
own messages) are skipped.
"""


def read_frames(path):
    out = []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if len(parts) < 3 or not parts[0].startswith("(") or "#" not in parts[2]:
                continue
            cob, _, data = parts[2].partition("#")
            out.append((float(parts[0].strip("()")), parts[1], int(cob, 16), data.upper()))
    return out
