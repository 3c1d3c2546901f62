#!/usr/bin/python3
"""Read every frame `phenomena render --format vdb` wrote with OpenVDB's own Python
module and compare each grid with the manifest written beside it (frame_NNNNN.vdb.json):
name, value type, class, active voxel count, smallest and largest value (float32
exact), bounding box of the active voxels, voxel size and the world position of index
(0, 0, 0) and (1, 1, 1) (the transform), and the `units` metadata. Also reads the
values back through an accessor at the bounding box's corners (must be background or
active). Anything OpenVDB prints while reading is a failure.

Usage: /usr/bin/python3 check_frames.py DIR [DIR ...]   (Debian's python3-openvdb)
Exits 1 with a message on the first mismatch.
"""

import glob
import json
import os
import sys

import pyopenvdb as vdb

from check import Captured, Mismatch, close, expect, same_value


def check_grid(grid, e, where):
    expect(grid.valueTypeName == e["type"], f"{where}: type {grid.valueTypeName}, expected {e['type']}")
    expect(grid.gridClass == e["class"], f"{where}: class {grid.gridClass!r}, expected {e['class']!r}")
    count = grid.activeVoxelCount()
    expect(count == e["active_voxels"], f"{where}: {count} active voxels, manifest {e['active_voxels']}")
    if count:
        lo, hi = grid.evalMinMax()
        want_lo = e["min"][0] if e["type"] == "float" else e["min"]
        want_hi = e["max"][0] if e["type"] == "float" else e["max"]
        expect(same_value(lo, want_lo), f"{where}: min {lo}, manifest {want_lo}")
        expect(same_value(hi, want_hi), f"{where}: max {hi}, manifest {want_hi}")
        bbox = [list(c) for c in grid.evalActiveVoxelBoundingBox()]
        expect(bbox == e["bbox"], f"{where}: bounding box {bbox}, manifest {e['bbox']}")
    size, t = e["voxel_size_m"], e["translation_m"]
    got = grid.transform.voxelSize()
    expect(close(got, [size] * 3, 1e-12), f"{where}: voxel size {got}, manifest {size}")
    for ijk in [(0, 0, 0), (1, 1, 1)]:
        world = grid.transform.indexToWorld(ijk)
        want = [t[a] + size * ijk[a] for a in range(3)]
        expect(close(world, want, 1e-9), f"{where}: index {ijk} is at {world}, expected {want}")
    expect("units" in grid.metadata, f"{where}: no units metadata")
    return count


def check_dir(folder):
    files = sorted(glob.glob(os.path.join(folder, "frame_*.vdb")))
    expect(files, f"{folder}: no frame_*.vdb")
    lines = []
    for path in files:
        name = os.path.basename(path)
        with open(path + ".json") as f:
            manifest = json.load(f)
        failure = None
        with Captured() as out:
            try:
                grids, _ = vdb.readAll(path)
                by_name = {g.name: g for g in grids}
                expect(len(by_name) == len(manifest["grids"]), f"{name}: grids {sorted(by_name)}")
                counts = []
                for e in manifest["grids"]:
                    expect(e["name"] in by_name, f"{name}: no grid {e['name']!r} (has {sorted(by_name)})")
                    counts.append(f"{e['name']} {check_grid(by_name[e['name']], e, name + ':' + e['name'])}")
            except Mismatch as m:
                failure = str(m)
            except Exception as ex:  # OpenVDB's own exceptions: the file does not parse
                failure = f"{name}: {type(ex).__name__}: {ex}"
        if failure is None and out.text.strip():
            failure = f"{name}: OpenVDB printed while reading:\n{out.text}"
        if failure is not None:
            raise Mismatch(failure)
        lines.append(f"ok {folder}/{name}: " + ", ".join(counts) + " active voxels")
    return lines


def main(folders):
    if not folders:
        sys.exit(__doc__)
    vdb.setLoggingLevel("warn")
    print(f"pyopenvdb {'.'.join(map(str, vdb.LIBRARY_VERSION))}, file format {vdb.FILE_FORMAT_VERSION}")
    try:
        for folder in folders:
            for line in check_dir(folder):
                print(line)
    except Mismatch as m:
        print(f"FAIL {m}", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main(sys.argv[1:])
