#!/bin/sh
# Writes the test volumes of crates/core/examples/vdb_sample.rs and reads every one
# back with OpenVDB's own Python module (Debian's python3-openvdb, OpenVDB 10), checking
# it against the expectations written beside it (check.py). Needs
# `apt-get install python3-openvdb`.
#
# If the C++ library's headers are there too (`apt-get install libopenvdb-dev
# libboost-dev libimath-dev`), each file is also read and written again by OpenVDB's
# own writer (rewrite.cpp) and the two compared byte for byte (compare.py).
#
#   tools/vdb-check/run.sh [OUT_DIR]     (default: target/vdb-check)
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
out=${1:-"$root/target/vdb-check"}
python=/usr/bin/python3
if ! "$python" -c "import pyopenvdb" 2>/dev/null; then
    echo "run.sh: $python has no pyopenvdb; install Debian's python3-openvdb" >&2
    exit 2
fi
rm -rf "$out"
mkdir -p "$out"
# VDB_CHECK_PROFILE: the cargo profile to build the sample writer with (CI passes
# `test`, whose dependencies `cargo test` has already built; no `-p`, so the features
# are the workspace's and nothing is compiled again). VDB_CHECK_FEATURES: the features
# that `cargo test` was given (CI's builds the studio in), for the same reason.
(cd "$root" && cargo run --quiet --profile "${VDB_CHECK_PROFILE:-release}" \
    ${VDB_CHECK_FEATURES:+--features "$VDB_CHECK_FEATURES"} --example vdb_sample -- "$out")
set --
for json in "$out"/*.json; do
    set -- "$@" "${json%.json}.vdb" "$json"
done
"$python" "$here/check.py" "$@"

if [ -f /usr/include/openvdb/openvdb.h ] && command -v g++ >/dev/null; then
    g++ -O1 -std=c++17 "$here/rewrite.cpp" -o "$out/rewrite" -lopenvdb -ltbb -lImath-3_1
    for vdb in "$out"/*.vdb; do
        "$out/rewrite" "$vdb" "$out/openvdb.tmp"
        echo "same as OpenVDB's writer: $(basename "$vdb")"
        "$python" "$here/compare.py" "$vdb" "$out/openvdb.tmp"
    done
    rm -f "$out/openvdb.tmp"
else
    echo "run.sh: no /usr/include/openvdb (libopenvdb-dev): skipped the byte comparison with OpenVDB's writer"
fi
