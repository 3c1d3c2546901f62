#!/usr/bin/env python3
"""Write crates/aurora/data/stars.csv from the npm package d3-celestial (BSD-3-Clause,
Olaf Frohn): its data/stars.6.json is the Hipparcos catalogue's stars down to visual
magnitude 6 with their B-V colour indices (J2000 positions).

    cd /tmp && npm pack d3-celestial@0.7.35
    tar xzf d3-celestial-0.7.35.tgz
    python3 tools/stars/make_catalogue.py /tmp/package > crates/aurora/data/stars.csv

Columns: Hipparcos number, right ascension (degrees, 0-360, J2000), declination
(degrees, J2000), visual magnitude, B-V (empty when the catalogue has none). Rows are
sorted by magnitude, brightest first, so a limiting magnitude cuts the file's tail.
"""
import json
import sys
from pathlib import Path

package = Path(sys.argv[1])
features = json.loads((package / "data" / "stars.6.json").read_text())["features"]
rows = []
for f in features:
    ra, dec = f["geometry"]["coordinates"]
    bv = f["properties"].get("bv")
    rows.append((f["properties"]["mag"], f["id"], ra % 360.0, dec, bv))
rows.sort(key=lambda r: (r[0], r[1]))
print("# Hipparcos stars to V = 6 from d3-celestial 0.7.35 (data/stars.6.json, BSD-3-Clause,")
print("# Copyright (c) 2015, Olaf Frohn); written by tools/stars/make_catalogue.py.")
print("# hip,ra_deg,dec_deg,vmag,bv (J2000)")
for mag, hip, ra, dec, bv in rows:
    bv = "" if bv in (None, "") else f"{float(bv):.3f}"
    print(f"{hip},{ra:.4f},{dec:.4f},{mag:.2f},{bv}")
