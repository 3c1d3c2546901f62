#!/usr/bin/env python3
"""Generate the aurora's model atmosphere from NRLMSIS 2.1.

Requires Python 3 with ``pymsis`` (``pip install pymsis``; it brings numpy and the
NRL Fortran model). Run from anywhere:

    python3 tools/gen_atmosphere.py

Writes (paths relative to the repository root):

* ``crates/aurora/data/atmosphere_msis21.csv``: number densities of O, N2 and O2 (m^-3)
  and the neutral temperature (K) from 80 to 500 km at 1 km, header
  ``altitude_km,n_o,n_n2,n_o2,temperature_k``.
* ``crates/aurora/data/atmosphere_msis21_minor.csv``: the minor species the physical
  mode's ion chemistry needs, atomic nitrogen N(4S) and nitric oxide NO
  (m^-3), same altitudes and conditions, header ``altitude_km,n_n,n_no``. NRLMSIS 2.1
  gives no N below about 92 km (NaN): written as 0 there.

The provenance of the crate's tables is in ``crates/aurora/data/README.md``, kept by
hand (it also describes the night ionosphere of ``tools/iri90``).

Conditions (since 2026-12-04): a winter midnight on the auroral oval, 65.0 N
0.0 E, 2017-12-21 00:00 UT (local solar midnight), F10.7 = 100 sfu (daily and 81-day
mean), Ap = 10 for every entry of the ap history (so no space weather file is
downloaded): the conditions at which the project compares the column model with NCAR
GLOW. (Before, the example conditions of shared/aurora-physics.md: 69.6 N 19.0 E,
2024-01-15 22:00 UT, F10.7 = 150, Ap = 15; those tables are kept in
``tests/data/air/tromso/``.)

Other conditions (for ``phenomena export aurora-profile --air DIR``)::

    python3 tools/gen_atmosphere.py --out DIR --date 2024-01-15T22:00 --lat 69.6 \
        --lon 19 --f107 150 --ap 15

writes the two tables (same names and format) and ``conditions.txt`` into DIR and
leaves the crate's data alone; ``tools/iri90/make_table.sh`` writes the third table
(the night ionosphere) for the same conditions. ``--minor-only`` writes the
minor-species table alone.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import pathlib
import sys

import numpy as np
import pymsis

ROOT = pathlib.Path(__file__).resolve().parent.parent
OUT = ROOT / "crates" / "aurora" / "data"
DATE = np.datetime64("2017-12-21T00:00")
LAT, LON = 65.0, 0.0
F107, AP = 100.0, 10.0
ALTITUDES_KM = np.arange(80, 501, 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=pathlib.Path, help="write the tables here (default: the crate's data)")
    parser.add_argument("--date", default=str(DATE), help="UT, ISO 8601 (default %(default)s)")
    parser.add_argument("--lat", type=float, default=LAT, help="geographic latitude, deg N")
    parser.add_argument("--lon", type=float, default=LON, help="geographic longitude, deg E")
    parser.add_argument("--f107", type=float, default=F107, help="F10.7, sfu (daily and 81-day mean)")
    parser.add_argument("--ap", type=float, default=AP, help="Ap (every entry of the ap history)")
    parser.add_argument("--minor-only", action="store_true", help="write the minor-species table alone")
    args = parser.parse_args()
    if not (-90 <= args.lat <= 90) or not (-360 <= args.lon <= 360):
        parser.error(f"--lat {args.lat} must be in [-90, 90] and --lon {args.lon} in [-360, 360]")
    if not (50 <= args.f107 <= 400) or not (0 <= args.ap <= 400):
        parser.error(f"--f107 {args.f107} must be in [50, 400] sfu and --ap {args.ap} in [0, 400]")
    date = np.datetime64(args.date)
    out = args.out if args.out is not None else OUT
    data = pymsis.calculate(
        [date], [args.lon], [args.lat], ALTITUDES_KM, f107s=[args.f107], f107as=[args.f107],
        aps=[[args.ap] * 7], version=2.1
    )
    profile = data[0, 0, 0]  # shape (altitudes, variables)
    var = pymsis.Variable
    out.mkdir(parents=True, exist_ok=True)
    minor = ["altitude_km,n_n,n_no"]
    for alt, v in zip(ALTITUDES_KM, profile):
        n = 0.0 if np.isnan(v[var.N]) else v[var.N]
        minor.append(f"{alt},{n:.6e},{v[var.NO]:.6e}")
    write(out / "atmosphere_msis21_minor.csv", "\n".join(minor) + "\n")
    if args.minor_only:
        return
    rows = ["altitude_km,n_o,n_n2,n_o2,temperature_k"]
    for alt, v in zip(ALTITUDES_KM, profile):
        rows.append(
            f"{alt},{v[var.O]:.6e},{v[var.N2]:.6e},{v[var.O2]:.6e},{v[var.TEMPERATURE]:.3f}"
        )
    write(out / "atmosphere_msis21.csv", "\n".join(rows) + "\n")
    version = importlib.metadata.version("pymsis")
    if args.out is not None:
        write(
            out / "conditions.txt",
            f"NRLMSIS 2.1 through pymsis {version} (tools/gen_atmosphere.py): {args.lat} N {args.lon} E, "
            f"{date} UT, F10.7 = {args.f107:g} sfu daily and 81-day mean, Ap = {args.ap:g}\n",
        )
        return
    print(
        f"wrote {out}; the provenance in crates/aurora/data/README.md (pymsis {version}) is kept by hand",
        file=sys.stderr,
    )


def write(path: pathlib.Path, text: str) -> None:
    """Write through a temporary name and rename: no half-written table."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(path)


if __name__ == "__main__":
    main()
