#!/usr/bin/env python3
"""Write crates/aurora/data/milky_way.txt from the npm package d3-celestial (BSD-3-Clause,
Olaf Frohn): its data/mw.json outlines the Milky Way at five brightness levels (ol1,
the faintest and widest, to ol5, the brightest star clouds), as polygons in J2000 right
ascension and declination.

    cd /tmp && npm pack d3-celestial@0.7.35 && tar xzf d3-celestial-0.7.35.tgz
    python3 tools/stars/make_milky_way.py /tmp/package > crates/aurora/data/milky_way.txt

The output is a 720 x 360 map of 0.5-degree cells (row 0 at declination +89.75, column 0
at right ascension 0.25 degrees, right ascension growing with the column), each cell the
number of levels whose outline holds the cell's centre (0-5, even-odd rule over each
level's rings, so the holes count as outside), one row per line, run-length coded as
`level*count` pairs separated by spaces.
"""
import json
import sys
from pathlib import Path

W, H = 720, 360
package = Path(sys.argv[1])
features = json.loads((package / "data" / "mw.json").read_text())["features"]
grid = [[0] * W for _ in range(H)]
for feature in features:
    rings = [ring for polygon in
             ([feature["geometry"]["coordinates"]] if feature["geometry"]["type"] == "Polygon"
              else feature["geometry"]["coordinates"])
             for ring in polygon]
    edges = []
    for ring in rings:
        for (x0, y0), (x1, y1) in zip(ring, ring[1:] + ring[:1]):
            # Unwrap across RA 0/360 so an edge never spans more than half the sky.
            x0, x1 = x0 % 360.0, x1 % 360.0
            if x1 - x0 > 180.0:
                x1 -= 360.0
            elif x0 - x1 > 180.0:
                x1 += 360.0
            edges.append((x0, y0, x1, y1))
    # The polygons are bands around the sky, so a row may start inside one: the state at
    # the row's first cell (RA 0.25) comes from the crossings of the meridian there,
    # counted from the north celestial pole (outside every level) down to the row.
    meridian = []
    for x0, y0, x1, y1 in edges:
        lo, hi = min(x0, x1), max(x0, x1)
        for r in (0.25 - 360.0, 0.25, 0.25 + 360.0):
            if lo <= r < hi:
                meridian.append(y0 + (r - x0) * (y1 - y0) / (x1 - x0))
    for row in range(H):
        dec = 89.75 - 0.5 * row
        inside = sum(1 for y in meridian if y > dec) % 2 == 1
        crossings = []
        for x0, y0, x1, y1 in edges:
            if (y0 > dec) != (y1 > dec):
                x = x0 + (dec - y0) * (x1 - x0) / (y1 - y0)
                crossings.append((x - 0.25) % 360.0 + 0.25)
        crossings.sort()
        # Walking east from RA 0.25, each crossing flips the state.
        k = 0
        for col in range(W):
            ra = 0.25 + 0.5 * col
            while k < len(crossings) and crossings[k] < ra:
                inside = not inside
                k += 1
            if inside:
                grid[row][col] += 1
print("# Milky Way levels 0-5 from d3-celestial 0.7.35 (data/mw.json, BSD-3-Clause,")
print("# Copyright (c) 2015, Olaf Frohn); written by tools/stars/make_milky_way.py.")
print(f"# {W} x {H} cells of 0.5 degrees, J2000; row 0 at dec +89.75, column 0 at RA 0.25")
for row in grid:
    runs, last, count = [], row[0], 0
    for v in row:
        if v == last:
            count += 1
        else:
            runs.append(f"{last}*{count}")
            last, count = v, 1
    runs.append(f"{last}*{count}")
    print(" ".join(runs))
