#!/bin/bash
# Rebuild crates/aurora/data/ionosphere_iri90.csv: IRI-90's night O+ density (electron
# density times its O+ share, m^-3) at the conditions of the crate's NRLMSIS 2.1 table
# (69.6 N 19.0 E, 2024-01-15 22:00 UT, F10.7 = 150, Ap = 15), 80-500 km at 1 km.
# IRI-90 itself (iri90.f and its ccir/ursi coefficient files) is not in this repository:
# it ships in the PyPI sdist glowpython 4.0.4 (src/GLOW/iri90.f, src/GLOW/data/iri90/).
# Usage: tools/iri90/make_table.sh PATH/TO/glowpython-4.0.4/src/GLOW
set -euo pipefail
GLOW=${1:?path to glowpython-4.0.4/src/GLOW}
HERE=$(cd "$(dirname "$0")" && pwd)
OUT=$(cd "$HERE/../.." && pwd)/crates/aurora/data/ionosphere_iri90.csv
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
FFLAGS="-O2 -ffree-line-length-none -fno-range-check -std=legacy"
nice gfortran $FFLAGS -c "$GLOW/iri90.f" -o "$WORK/iri90.o"
nice gfortran $FFLAGS -c "$HERE/iri_driver.f90" -o "$WORK/driver.o" -J "$WORK"
gfortran -o "$WORK/iri" "$WORK/driver.o" "$WORK/iri90.o"
echo "2024015 79200 69.6 19.0 150 150 15 3" | "$WORK/iri" "$GLOW/data/iri90/" | sed '/^#/!s/ //g' > "$WORK/iri.csv"
python3 - "$WORK/iri.csv" "$OUT" <<'PY'
import csv, sys
rows = [l for l in open(sys.argv[1]) if not l.startswith('#')]
out = ["altitude_km,n_o_plus"]
for r in csv.DictReader(rows):
    f = 0.0 if r['o_plus_fraction'] == 'NaN' else float(r['o_plus_fraction'])
    out.append(f"{float(r['altitude_km']):g},{float(r['ne_cm3']) * f * 1e6:.6e}")
open(sys.argv[2], 'w').write("\n".join(out) + "\n")
PY
echo "wrote $OUT"
