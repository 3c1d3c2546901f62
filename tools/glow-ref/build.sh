#!/bin/bash
# Build GLOW v0.981 (the glowpython-4.0.4 PyPI sdist's src/GLOW) and the glowref driver
# with gfortran, one file at a time. GLOW's source is not in this repository: unpack the
# sdist and point GLOW_SRC at its src/GLOW (see README.md here).
#   GLOW_SRC=/path/to/glowpython-4.0.4/src/GLOW BUILD=/tmp/glow-build tools/glow-ref/build.sh
#   GLOW_NE_TOP_KM=250 GLOW_SRC=... BUILD=/tmp/glow-ne250 tools/glow-ref/build.sh
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
SRC=${GLOW_SRC:?set GLOW_SRC to the unpacked glowpython-4.0.4/src/GLOW}
B=${BUILD:-$HERE/build}
mkdir -p "$B"; cd "$B"
FC=gfortran
FFLAGS="-O2 -ffree-line-length-none -fno-range-check -std=legacy"
# order of dependency (module cglow first), same file set as glowpython meson.build, minus conduct
SOURCES="cglow.f90 glow.f90 bands.f90 egrid.f90 ephoto_init.f90 ephoto.f90 etrans.f90 exsect.f fieldm.f
 gchem.f90 geomag.f90 maxt.f90 mzgrid.f90 qback.f90 rcolum.f90 snoem_init.f90 snoem.f90 snoemint.f90
 solzen.f90 ssflux_init.f90 ssflux.f90 iri90.f nrlmsise00.f"
# GLOW_NE_TOP_KM (optional): the altitude up to which GLOW computes the electron density
# from its chemistry (kchem 4; stock 200 km, IRI above). The build compiles a copy of
# gchem.f90 with that one threshold changed; GLOW's source is left as it is.
NE_TOP=${GLOW_NE_TOP_KM:-}
OBJS=""
for f in $SOURCES; do
  o="${f%.*}.o"
  src="$SRC/$f"
  if [ "$f" = gchem.f90 ] && [ -n "$NE_TOP" ]; then
    case "$NE_TOP" in *[!0-9]*) echo "GLOW_NE_TOP_KM must be whole km, got '$NE_TOP'" >&2; exit 2;; esac
    grep -q 'IF (ZZ(I) .GT. 2.0001E7) J200=I-1' "$src" || { echo "gchem.f90: the 200 km threshold is not where v0.981 has it" >&2; exit 2; }
    sed "s/IF (ZZ(I) .GT. 2.0001E7) J200=I-1/IF (ZZ(I) .GT. ${NE_TOP}.01E5) J200=I-1/" "$src" > gchem_ne_top.f90
    src=gchem_ne_top.f90
  fi
  nice -n 10 $FC $FFLAGS -c "$src" -o "$o"
  OBJS="$OBJS $o"
done
nice -n 10 $FC $FFLAGS -c "$HERE/glowref.f90" -o glowref.o
$FC -o glowref.exe glowref.o $OBJS
ln -sfn "$SRC/data" "$B/data"
echo "built $B/glowref.exe"
