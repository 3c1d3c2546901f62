#!/bin/bash
# Rebuild crates/aurora/data/ionosphere_iri90.csv: IRI-90's night O+ density (electron
# density times its O+ share, m^-3) at the conditions of the crate's NRLMSIS 2.1 table
# (65.0 N 0.0 E, 2017-12-21 00:00 UT, F10.7 = 100, Ap = 10), 80-500 km at 1 km.
# IRI-90 itself (iri90.f and its ccir/ursi coefficient files) is not in this repository:
# it ships in the PyPI sdist glowpython 4.0.4 (src/GLOW/iri90.f, src/GLOW/data/iri90/).
# Usage: tools/iri90/make_table.sh PATH/TO/glowpython-4.0.4/src/GLOW [OUT.csv "CONDITIONS"]
#   CONDITIONS: "yyyyddd ut_s glat glong f107a f107 ap" (default: the crate's, below), e.g.
#   tools/iri90/make_table.sh $GLOW DIR/ionosphere_iri90.csv "2024015 79200 69.6 19.0 150 150 15"
#   next to `tools/gen_atmosphere.py --out DIR` for `phenomena export aurora-profile --air DIR`.
set -euo pipefail
GLOW=${1:?path to glowpython-4.0.4/src/GLOW}
HERE=$(cd "$(dirname "$0")" && pwd)
OUT=${2:-$(cd "$HERE/../.." && pwd)/crates/aurora/data/ionosphere_iri90.csv}
CONDITIONS=${3:-2017355 0 65.0 0.0 100 100 10}
[ "$(echo "$CONDITIONS" | wc -w)" -eq 7 ] || { echo "CONDITIONS needs 7 numbers: yyyyddd ut_s glat glong f107a f107 ap" >&2; exit 2; }
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
FFLAGS="-O2 -ffree-line-length-none -fno-range-check -std=legacy"
nice gfortran $FFLAGS -c "$GLOW/iri90.f" -o "$WORK/iri90.o"
nice gfortran $FFLAGS -c "$HERE/iri_driver.f90" -o "$WORK/driver.o" -J "$WORK"
gfortran -o "$WORK/iri" "$WORK/driver.o" "$WORK/iri90.o"
echo "$CONDITIONS 3" | "$WORK/iri" "$GLOW/data/iri90/" | sed '/^#/!s/ //g' > "$WORK/iri.csv"
python3 - "$WORK/iri.csv" "$OUT" <<'PY'
import csv, sys
rows = [l for l in open(sys.argv[1]) if not l.startswith('#')]
out = ["altitude_km,n_o_plus"]
for r in csv.DictReader(rows):
    f = 0.0 if r['o_plus_fraction'] == 'NaN' else float(r['o_plus_fraction'])
    out.append(f"{float(r['altitude_km']):g},{float(r['ne_cm3']) * f * 1e6:.6e}")
open(sys.argv[2] + '.tmp', 'w').write("\n".join(out) + "\n")
import os
os.replace(sys.argv[2] + '.tmp', sys.argv[2])
PY
echo "wrote $OUT"
