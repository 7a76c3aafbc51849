#!/usr/bin/env python3
"""Judges an SVG `oegw replay --plot FILE.svg` wrote, as an XML reader sees it: a well-formed SVG
document whose charts (<g class="chart">) hold each expected series as a <polyline> with points,
titled "NAME (N points)", and whose bands and markers are drawn.
Args: FILE.svg EXPECTED... (series or chart names that must be drawn)"""
import re
import sys
import xml.etree.ElementTree as ET

NS = "{http://www.w3.org/2000/svg}"
path, expected = sys.argv[1], sys.argv[2:]
root = ET.parse(path).getroot()  # raises (exit 1) on a document that is not well-formed
fails = []
if root.tag != NS + "svg":
    fails.append(f"root element {root.tag}, expected svg")
charts = [g for g in root.iter(NS + "g") if g.get("class") == "chart"]
drawn = {}
for g in charts:
    heading = g.findtext(NS + "title")
    for line in g.iter(NS + "polyline"):
        m = re.fullmatch(r"(.*) \((\d+) points\)", line.findtext(NS + "title") or "")
        pts = (line.get("points") or "").split()
        if not m:
            fails.append(f"{heading}: a series without its title")
            continue
        drawn[m.group(1)] = len(pts)
        if int(m.group(2)) == 0 or not pts:
            fails.append(f"{heading}: {m.group(1)} has no points")
    drawn[heading] = len(list(g))
bands = [r for r in root.iter(NS + "rect") if r.get("class") == "band"]
markers = [r for r in root.iter(NS + "line") if r.get("class") == "marker"]
for want in expected:
    if want not in drawn:
        fails.append(f"'{want}' not drawn")
if not bands:
    fails.append("no band drawn")
if not markers:
    fails.append("no marker drawn")
print(f"{path}: {len(charts)} charts, {sum(1 for _ in root.iter(NS + 'polyline'))} series, "
      f"{len(bands)} bands, {len(markers)} markers")
for f in fails:
    print("FAIL:", f)
sys.exit(1 if fails else 0)
