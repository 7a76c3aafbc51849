#!/usr/bin/python3
"""in_order.py DUMP PATTERN...: every PATTERN (a regular expression over "ID#DATA", candump
notation) matches a frame of the candump -L file DUMP, in this order. Prints each match with its
timestamp; exits 1 naming the first pattern not found after the previous match."""
import re
import sys

frames = []
with open(sys.argv[1]) as f:
    for line in f:
        parts = line.split()
        if len(parts) >= 3:
            frames.append((parts[0], parts[2]))
pos = 0
for pattern in sys.argv[2:]:
    rx = re.compile(pattern + r"$")
    while pos < len(frames) and not rx.match(frames[pos][1]):
        pos += 1
    if pos == len(frames):
        print(f"not found in order: {pattern}")
        sys.exit(1)
    print(f"  {frames[pos][0]} {frames[pos][1]:<24} matches {pattern}")
    pos += 1
